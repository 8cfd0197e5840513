"""Pickling a compiled env: rebuilt from its constructor's arguments, then its episode state copied in.

An env of the suite steps through a numba ``StructRef``
(:class:`~vcnc_gym.envs.step_kernel.StepData`), which does not pickle, and its
plant's arrays live in records the kernel reads by reference.  ``pickle.dumps(env)``
(Gymnasium's ``AsyncVectorEnv`` and ``copy.deepcopy`` use the same protocol)
therefore stores what makes the env instead of the compiled objects: the
arguments it was constructed with (recorded by :class:`RebuiltOnUnpickle`'s
``__new__``), its random generator, and its episode state, every array the
kernel reads and writes (the plant's state and parameters, the per-env
buffers: step counters, progress, observation, flags) plus the Python-side
fields.  Unpickling constructs a new env from the same arguments (its kernels
come from numba's cache) and copies the saved arrays into the new env's
buffers in place, so the new ``StepData`` reads them: a pickled env,
mid-episode or not, continues the same episode to the bit
(``tests/test_gym_conventions.py``).  The native vector env
(:class:`~vcnc_gym.envs.ContouringVectorEnv`) pickles the same way, with
every env's generator and autoreset state.

An argument that does not pickle (a ``PlantModel`` made at run time, such as
one wrapped by :func:`vcnc_gym.plants.shop_floor.shop_floor` and passed as
``plant=``) makes ``pickle.dumps`` fail with a ``TypeError`` naming it; a
plant model registered under its name (:func:`vcnc_gym.plants.get_plant`) is
saved by name.  The render figure is not saved: an unpickled env draws a new
one.
"""

from __future__ import annotations

import pickle
from typing import Any, Iterator

import numpy as np

__all__ = ["RebuiltOnUnpickle", "batch_arrays", "record_arrays", "restore_arrays"]


def record_arrays(record, prefix: str) -> Iterator[tuple[str, np.ndarray]]:
    """Every numpy array of a (nested) ``NamedTuple`` of arrays, by dotted field name under ``prefix``."""
    for name, value in zip(record._fields, record):
        if isinstance(value, np.ndarray):
            yield f"{prefix}.{name}", value
        elif isinstance(value, tuple) and hasattr(value, "_fields"):
            yield from record_arrays(value, f"{prefix}.{name}")


def batch_arrays(batch) -> dict[str, np.ndarray]:
    """Every array of a :class:`~vcnc_gym.envs.task.ContouringBatch`'s episode state, by name: the plant's
    arrays, the per-env buffers, the parameters in force (the fixed reference and contour are the task's)."""
    arrays = dict(record_arrays(batch.plant_arrays, "plant"))
    arrays.update(record_arrays(batch.buffers, "buffers"))
    arrays["batch.parameters"] = batch.parameters
    return arrays


def restore_arrays(targets: dict[str, np.ndarray], saved: dict[str, np.ndarray]) -> None:
    """Copy each ``saved`` array into the array of the same name in ``targets``, in place.

    ValueError if the names or shapes differ: the env rebuilt from the saved arguments is not the one saved
    (another version of the suite, or of a plant).
    """
    if targets.keys() != saved.keys():
        raise ValueError(
            f"the pickled env's arrays {sorted(saved)} are not the rebuilt env's {sorted(targets)}: "
            f"pickled by another version of vcnc_gym?"
        )
    for name, value in saved.items():
        target = targets[name]
        if target.shape != value.shape:
            raise ValueError(
                f"the pickled env's {name} has shape {value.shape}, the rebuilt env's "
                f"{target.shape}: pickled by another version of vcnc_gym?"
            )
        np.copyto(target, value)


def _picklable_argument(name: str, value: Any) -> Any:
    """``value``, or for a plant model registered under its name, the name; TypeError naming an argument
    that does not pickle."""
    from ..plants import plant_names
    from ..plants.contract import PlantModel

    if isinstance(value, PlantModel):
        from ..plants import get_plant

        if value.name in plant_names() and get_plant(value.name) is value:
            return value.name
    try:
        pickle.dumps(value)
    except Exception as error:
        raise TypeError(
            f"this env cannot be pickled: its argument {name}={value!r} does not pickle ({error}); "
            f"pass it by name or as plain data"
        ) from error
    return value


class RebuiltOnUnpickle:
    """Mixin of an env that pickles as its constructor's arguments plus its episode state.

    A subclass gives :meth:`_episode_state` (a picklable dict) and :meth:`_restore_episode` (which writes it
    into a freshly constructed env); ``__new__`` records the arguments of the construction.
    """

    def __new__(cls, *args, **kwargs):
        self = super().__new__(cls)
        self._arguments = (args, dict(kwargs))
        return self

    def __getstate__(self) -> dict:
        args, kwargs = self._arguments
        args = tuple(_picklable_argument(f"#{i}", a) for i, a in enumerate(args))
        kwargs = {k: _picklable_argument(k, v) for k, v in kwargs.items()}
        return {"arguments": (args, kwargs), "episode": self._episode_state()}

    def __setstate__(self, state: dict) -> None:
        args, kwargs = state["arguments"]
        self._arguments = (args, dict(kwargs))
        type(self).__init__(self, *args, **kwargs)
        self._restore_episode(state["episode"])

    def _episode_state(self) -> dict:  # pragma: no cover - every env class gives its own
        raise NotImplementedError

    def _restore_episode(self, state: dict) -> None:  # pragma: no cover - every env class gives its own
        raise NotImplementedError
