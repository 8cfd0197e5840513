"""What a shop-floor effect declares and what its steps see: :class:`Effect`, the plant's arrays and their columns.

An effect's numba steps receive the :data:`ShopFloorArrays` of the machines, whose ``memory`` holds the last
period's table (the ``M_*`` columns), and the stage's array ``x`` (the ``A_*`` columns in the ``table`` and
``reading`` stages); :data:`STAGES` are the stages of a control period, in order (:mod:`vcnc_gym.plants.shop_floor`).
"""

from __future__ import annotations

import math
from collections import namedtuple
from typing import Any

import numpy as np

__all__ = ["Effect", "MAX_DELAY", "STAGES", "ShopFloorArrays"]

#: Longest delay, control periods (command or sensor): the FIFOs hold this many entries plus one.
MAX_DELAY = 8

#: Columns of ``ShopFloorArrays.memory`` (N, 2, M_SIZE): per machine and axis, at the end of the last period.
M_DRIVE = 0  # the drive's (inner plant's) table position, mm
M_TABLE = 1  # the table position, mm
M_TABLE_VELOCITY = 2  # the table velocity, mm/s
M_MEAN_VELOCITY = 3  # the table's mean velocity over the last period, mm/s
M_DISTURBANCE = 4  # the input disturbance of the last period (the force stage's), input units
M_READING = 5  # the position read (before any sensor delay), mm
M_READING_VELOCITY = 6  # the velocity read, mm/s
M_SIZE = 7

#: Columns of the ``table`` and ``reading`` stages' ``x`` (2, A_SIZE): per axis, this period.
A_DRIVE = 0  # the drive's position, mm
A_TABLE = 1  # the table's position, mm
A_TABLE_VELOCITY = 2  # the table's velocity, mm/s
A_READING = 3  # the position read, mm
A_READING_VELOCITY = 4  # the velocity read, mm/s
A_SIZE = 5

#: The stages of a control period, in order (:mod:`vcnc_gym.plants.shop_floor`).
STAGES = ("command", "force", "table", "reading", "sense")

#: The arrays of N shop-floor machines (the contract's plant namedtuple): ``inner`` (the inner plant's arrays),
#: ``state`` (= ``inner.state``), ``params`` (N, 2, P + E), ``dt`` (s), ``n_inner`` (P), ``gain`` (N, 2) (the
#: plant's force gain, input per N), ``memory`` (N, 2, M_SIZE), ``rng`` (N,) uint64 (the noise generators' states),
#: scratch ``applied`` (N, 2), ``force`` (N, 2), ``table`` (N, 2, A_SIZE) and ``sensed`` (N, SENSE_SIZE), the
#: effects' state ``fstate`` (N, F) float64 and ``istate`` (N, I) int64, and ``effects`` (the tuple of the effects'
#: ``Arrays`` records of columns, in the composition's order).
ShopFloorArrays = namedtuple(
    "ShopFloorArrays",
    [
        "inner",
        "state",
        "params",
        "dt",
        "n_inner",
        "gain",
        "memory",
        "rng",
        "applied",
        "force",
        "table",
        "sensed",
        "fstate",
        "istate",
        "effects",
    ],
)


class Effect:
    """One shop-floor effect, declared in one place: subclass it (the class is the declaration, never instantiated).

    The kernel calls the hooks through the ``Arrays`` class, a module-level
    name (``Effect.Arrays``) that pickles by reference, so the composed
    kernel caches across processes (jitted functions passed as arguments
    would not: ``docs/architecture.md``, the plant contract).  In numba an
    ``Arrays`` record holds the effect's columns (integers, module
    docstring); in Python (``reset``, tests) :meth:`views` gives the same
    record holding numpy views: ``params`` (N, 2, E) and each state array
    ``(N, *shape)``.

    Attributes
    ----------
    parameters : tuple of Parameter
        Appended to the inner plant's, in this order (so ``randomize`` and
        ``--plants`` draw them).
    switches : tuple of str
        The parameters whose value 0 turns the effect off (:data:`OFF` sets
        them); the effect must then leave the period untouched.
    counts : tuple of str
        The parameters counted in whole numbers (a setting must be an integer).
    state : dict
        ``{name: (shape, dtype)}``: per-machine arrays, dtype ``np.float64``
        or ``np.int64``, zeroed at creation; with ``params`` the fields of
        the effect's namedtuple ``Arrays`` (made by the subclass statement).
    reset : staticmethod (v, plant, k) -> None, optional
        Python: machine ``k`` reset (the inner plant and the table's memory
        already at rest: ``plant.memory[k]``), ``v`` the effect's
        :meth:`views`; derive constants from ``v.params[k]`` (2, E) here.
    command, force, table, reading, sense : numba functions (s, plant, k, x) -> None, optional
        The effect's step in each stage (:mod:`vcnc_gym.plants.shop_floor`); ``njit(cache=True)``
        (``inline="always"`` keeps the composed kernel one function).
    """

    parameters: tuple = ()
    switches: tuple = ()
    counts: tuple = ()
    state: dict = {}
    reset = None
    command = force = table = reading = sense = None
    Arrays: Any = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        names = [p.name for p in cls.parameters]
        unknown = sorted(set(cls.switches + cls.counts) - set(names))
        if unknown:
            raise ValueError(f"effect {cls.__name__}: switches/counts {unknown} are not among its parameters {names}")
        for name, (_, dtype) in cls.state.items():
            if np.dtype(dtype) not in (np.dtype(np.float64), np.dtype(np.int64)):
                raise ValueError(f"effect {cls.__name__}: state {name} must be float64 or int64, got {dtype}")
        arrays = namedtuple(f"{cls.__name__}Arrays", ["params", *cls.state])
        arrays.__module__ = cls.__module__
        arrays.__qualname__ = f"{cls.__qualname__}.Arrays"
        setattr(arrays, "effect", cls)  # the stages read an effect's class from its record's type
        cls.Arrays = arrays

    @classmethod
    def uses_force_gain(cls) -> bool:
        """True if the effect needs the plant's ``force_gain`` when switched on (it has a ``force`` step)."""
        return cls.force is not None

    @classmethod
    def sizes(cls) -> tuple[int, int]:
        """Columns the effect's state takes in ``fstate`` and in ``istate``."""
        sizes = {np.dtype(np.float64): 0, np.dtype(np.int64): 0}
        for shape, dtype in cls.state.values():
            sizes[np.dtype(dtype)] += math.prod(shape)
        return sizes[np.dtype(np.float64)], sizes[np.dtype(np.int64)]

    @classmethod
    def columns(cls, param: int, fcol: int, icol: int):
        """The effect's ``Arrays`` record of columns: its first parameter at ``param``, its state from ``fcol``
        in ``fstate`` and ``icol`` in ``istate``."""
        starts = [param]
        for shape, dtype in cls.state.values():
            if np.dtype(dtype) == np.dtype(np.float64):
                starts.append(fcol)
                fcol += math.prod(shape)
            else:
                starts.append(icol)
                icol += math.prod(shape)
        return cls.Arrays(*starts)

    @classmethod
    def views(cls, plant, s):
        """The ``Arrays`` record of numpy views of the plant's arrays ``plant`` for the columns ``s``: ``params``
        (N, 2, E) and each state array ``(N, *shape)``; writing them writes the plant's."""
        n = plant.params.shape[0]
        views = [plant.params[:, :, s.params : s.params + len(cls.parameters)]]
        for (shape, dtype), start in zip(cls.state.values(), s[1:]):
            pool = plant.fstate if np.dtype(dtype) == np.dtype(np.float64) else plant.istate
            view = pool[:, start : start + math.prod(shape)].reshape((n, *shape))
            assert np.shares_memory(view, pool)
            views.append(view)
        return cls.Arrays(*views)
