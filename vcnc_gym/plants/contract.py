"""The plant contract: what a plant module declares, and the two kernels the env calls.

A plant is one module of :mod:`vcnc_gym.plants` (Jahanpour et al. (2014)'s feed drive is
:mod:`~vcnc_gym.plants.vcnc_feed_drive`).  It declares, in one place:

- ``MODEL``, a :class:`PlantModel`: the parameters (name, unit, nominal
  value per axis, uncertainty interval and the paper's table each comes from),
  the state entries per axis, the input (name, unit, the parameter that is
  its limit), and how to build, reset and describe the plant's arrays;
- a ``namedtuple`` class holding the arrays of N machines (at least
  ``state`` (N, 2, S) and ``params`` (N, 2, P)), built by
  :meth:`PlantModel.make_arrays`;
- numba overloads of the two generic kernels below for that namedtuple
  class, so that the env's step kernel (:mod:`vcnc_gym.envs.step_kernel`)
  advances and reads any plant without naming it::

      @overload(contract.advance, jit_options={"cache": True})
      def _advance(plant, k, command):
          if contract.is_plant(plant, MyArrays):
              return lambda plant, k, command: _advance_machine(...)

The env, the step kernel and the baselines reach a plant only through this
contract.  Adding a plant means adding one module (it is found by
:func:`vcnc_gym.plants.get_plant`) plus its tests.

Kernels
-------
``advance(plant, k, command)``
    Advance both axes of machine ``k`` by one control period (the ``dt``
    the arrays were made for), the command ``command`` ((2,) float64, in
    the input's unit, e.g. V) held constant; the plant applies its own
    saturation.
``sense(plant, k, out)``
    Write what machine ``k``'s sensors and the scorer need into ``out``
    (float64, at least ``SENSE_SIZE``), at the ``SENSE_*`` offsets.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from numba import types
from ..validation import integer, positive

__all__ = [
    "Parameter",
    "ParameterWarning",
    "PlantModel",
    "InverseDynamics",
    "INVERSE_ORDER",
    "advance",
    "sense",
    "is_plant",
    "SENSE_POSITION",
    "SENSE_MEASURED",
    "SENSE_VELOCITY",
    "SENSE_SIZE",
    "AXES",
]

#: Axis order of axis 1 of every plant array (a plant is biaxial).
AXES = ("x", "y")

#: ``out`` offsets of :func:`sense`: true table position (x, y) in mm, the
#: one the contour error is measured on.
SENSE_POSITION = 0
#: Position as the position sensor reports it (x, y), mm (the true one for a
#: perfect sensor; quantised for Purtojo et al.'s 1 um encoder).
SENSE_MEASURED = 2
#: Table velocity (x, y), mm/s.
SENSE_VELOCITY = 4
SENSE_SIZE = 6


def advance(plant, k, command):  # pragma: no cover - compiled per plant through numba overloads
    """Advance machine ``k`` of ``plant`` by one control period; see the module docstring."""
    raise NotImplementedError("advance() runs in numba code, implemented by each plant module's overload")


def sense(plant, k, out):  # pragma: no cover - compiled per plant through numba overloads
    """Write machine ``k``'s sensed quantities into ``out``; see the module docstring."""
    raise NotImplementedError("sense() runs in numba code, implemented by each plant module's overload")


def is_plant(numba_type, arrays_class) -> bool:
    """True if ``numba_type`` (an overload's argument type) is ``arrays_class``, a plant's namedtuple."""
    return isinstance(numba_type, types.BaseNamedTuple) and numba_type.instance_class is arrays_class


@dataclass(frozen=True)
class Parameter:
    """One per-axis parameter of a plant.

    Attributes
    ----------
    name, unit : str
        E.g. ``"K_a"`` and ``"A/V"``.
    nominal : (float, float)
        Nominal value on the x and y axes.  ``None`` with an ``interval``:
        the interval midpoints.
    interval : ((lo, hi), (lo, hi)) or None
        Uncertainty interval per axis; None for a fixed parameter.
    shared : bool
        One value per machine for both axes (drawn once from the x interval).
    source : str
        Where the numbers come from ("Jahanpour et al. (2014), section 2c").
    sign : str
        ``"positive"``, ``"nonnegative"``, ``"nonpositive"`` or ``"any"``:
        what :meth:`PlantModel.validate` requires.
    description : str
        What it is.
    physical_range : (lo, hi) or None
        The values a machine of this kind can physically have, on both axes
        (containing the nominal values and the interval): outside it
        :meth:`PlantModel.validate` refuses a value (e.g. an inertia of
        1e-300 kg m^2); outside the interval but inside the range it warns
        (:class:`ParameterWarning`).  None: the sign rule only.
    range_source : str
        Why the range is what it is.
    """

    name: str
    unit: str
    nominal: tuple = None  # pyright: ignore[reportAssignmentType]  (None: the interval's midpoints, __post_init__)
    interval: tuple | None = None
    shared: bool = False
    source: str = ""
    sign: str = "positive"
    description: str = ""
    physical_range: tuple | None = None
    range_source: str = ""

    def __post_init__(self):
        if self.sign not in ("positive", "nonnegative", "nonpositive", "any"):
            raise ValueError(f"parameter {self.name}: unknown sign rule {self.sign!r}")
        if self.nominal is None:
            if self.interval is None:
                raise ValueError(f"parameter {self.name} needs a nominal value or an interval")
            object.__setattr__(self, "nominal", tuple(0.5 * (lo + hi) for lo, hi in self.interval))
        if self.interval is not None:
            for lo, hi in self.interval:
                if not lo <= hi:
                    raise ValueError(f"parameter {self.name}: interval ({lo}, {hi}) is empty")
            if self.shared and tuple(self.interval[0]) != tuple(self.interval[1]):
                raise ValueError(f"shared parameter {self.name} needs the same interval on both axes")
        if self.physical_range is not None:
            lo, hi = self.physical_range
            inside = list(self.nominal) + [v for iv in (self.interval or ()) for v in iv]
            if not (lo < hi and all(lo <= v <= hi for v in inside)):
                raise ValueError(
                    f"parameter {self.name}: physical range ({lo}, {hi}) must hold its nominal values and its interval"
                )

    @property
    def uncertain(self) -> bool:
        return self.interval is not None


class ParameterWarning(UserWarning):
    """A plant parameter outside its uncertainty interval but inside its physical range: accepted, said."""


@dataclass(frozen=True)
class PlantModel:
    """What a plant module declares: parameters, state, input, arrays.

    The generic parts (nominal values, the uncertainty box, sampling,
    vertices, validation, the input limit) are computed here from
    ``parameters``; the plant-specific parts are the callables it is given.

    Parameters
    ----------
    name : str
        The module's short name (``"vcnc_feed_drive"``), as ``plant=`` of the envs takes it.
    source : str
        The paper and equation of the model ("Jahanpour et al. (2014), eq. (1)").
    parameters : tuple of Parameter
        In the order of the last axis of a parameter array.
    state_names : tuple of str
        Per-axis state entries with units, in the order of the last axis of
        ``state`` (e.g. ``("x_m [mm]", "w [rad/s]", "x_t [mm]")``).
    input_name, input_unit : str
        What the action drives (``"amplifier voltage"``, ``"V"``).
    input_limit : str
        Name of the parameter that is the input's saturation limit; action
        1.0 maps to it.
    make_arrays : callable (n_machines, dt, options...) -> namedtuple
        The plant's arrays for N machines at control period ``dt`` s, state
        at rest at the origin, parameters nominal; ``options`` (keyword arguments) are the
        plant's own settings (e.g. Jahanpour et al. (2014)'s integration ``substep``), the
        envs' ``plant_options``.
    reset_machine : callable (arrays, k, position) -> None
        Put machine ``k`` at rest at ``position`` ((2,) mm).
    check : callable (params (N, 2, P)) -> None, optional
        Plant-specific consistency checks beyond the sign rules (raise ValueError).
    linear_coefficients : callable (params (2, P), axis) -> (num, den), optional
        Input-to-position transfer function, descending powers of s, where
        the plant's paper gives one.
    delay : callable (params (2, P), axis) -> float, optional
        Input dead time in s of the linear model (``exp(-delay s)``), if any.
    inverse_dynamics : callable (params (2, P)) -> InverseDynamics, optional
        The plant's inverse dynamics (:class:`InverseDynamics`): the input
        that makes the model with these parameters follow a given motion,
        friction and backlash included; what model-based feedforward
        controllers read (with the nominal parameters, never the true ones).
    force_gain : callable (params (2, P)) -> ndarray (2,), optional
        The input, per axis, equivalent to a force of 1 N on the table (input
        unit per N): how a process force enters as an input disturbance
        (:mod:`vcnc_gym.plants.shop_floor`).
    seed_machine : callable (arrays, k, rng) -> None, optional
        Draw machine ``k``'s random state (sensor noise) from the env's
        ``numpy.random.Generator``; the envs call it after ``reset_machine``.
    servo_bandwidth : float, optional
        The highest position-loop bandwidth the drive supports, rad/s: the
        ceiling below which commissioning's design rule
        (:mod:`vcnc_baselines.commissioning.design`) searches; the margins, a
        mode and the delays it identifies lower it.
    friction_time : float
        s, the duration over which a model-based feedforward changes the
        Coulomb level at a velocity reversal of the reference (0: at the
        reversal); default 1 ms.
    path_limits : (float, float), optional
        The path acceleration (mm/s^2) and jerk (mm/s^3) a CNC plans this
        machine's moves with: the G-code ids' corner blends and look-ahead
        and the random contours (:func:`vcnc_gym.gcode.path_limits`); None:
        those ids need them given.
    random_contour : dict, optional
        Fields of :class:`vcnc_gym.gcode.random_contour.RandomContourSpec`
        that set this machine's scale of random contours over the defaults
        (5-30 mm lines at 33-100 mm/s, a ball-screw drive's); empty: the
        defaults.
    """

    name: str
    source: str
    parameters: tuple
    state_names: tuple
    input_name: str
    input_unit: str
    input_limit: str
    make_arrays: Callable
    reset_machine: Callable
    check: Callable | None = None
    linear_coefficients: Callable | None = None
    delay: Callable | None = None
    inverse_dynamics: Callable | None = None
    force_gain: Callable | None = None
    seed_machine: Callable | None = None
    servo_bandwidth: float | None = None
    friction_time: float = 1e-3
    path_limits: tuple | None = None
    random_contour: dict = field(default_factory=dict)
    _index: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        index = {p.name: j for j, p in enumerate(self.parameters)}
        if len(index) != len(self.parameters):
            raise ValueError(f"plant {self.name}: duplicate parameter names")
        if self.input_limit not in index:
            raise ValueError(f"plant {self.name}: input limit {self.input_limit!r} is not a parameter")
        object.__setattr__(self, "_index", index)

    # -- names ---------------------------------------------------------------
    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def n_parameters(self) -> int:
        return len(self.parameters)

    @property
    def state_size(self) -> int:
        """State entries per axis."""
        return len(self.state_names)

    def index(self, name: str) -> int:
        """Column of parameter ``name`` in a parameter array."""
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"plant {self.name} has no parameter {name!r}; it has {list(self._index)}") from None

    # -- parameter sets ------------------------------------------------------
    def nominal(self) -> np.ndarray:
        """Nominal parameters, (2, P) float64 (rows x, y)."""
        return np.array([[p.nominal[a] for p in self.parameters] for a in range(2)], dtype=np.float64)

    def box(self) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        """The uncertainty box: lower and upper corners and the coordinate names.

        A shared parameter is one coordinate, a per-axis one two (``_x``,
        ``_y``), in the order of ``parameters``.
        """
        lo, hi, names = [], [], []
        for p in self.parameters:
            if not p.uncertain:
                continue
            axes = ((0, p.name),) if p.shared else ((0, p.name + "_x"), (1, p.name + "_y"))
            for a, coordinate in axes:
                lo.append(p.interval[a][0])
                hi.append(p.interval[a][1])
                names.append(coordinate)
        return np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64), tuple(names)

    def from_box_point(self, v) -> np.ndarray:
        """The (2, P) parameters at point ``v`` of :meth:`box`, fixed ones nominal."""
        out = self.nominal()
        c = 0
        for j, p in enumerate(self.parameters):
            if not p.uncertain:
                continue
            if p.shared:
                out[:, j] = v[c]
                c += 1
            else:
                out[0, j], out[1, j] = v[c], v[c + 1]
                c += 2
        return out

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """One machine drawn uniformly from the box (one ``rng.uniform`` call), (2, P)."""
        lo, hi, _ = self.box()
        return self.from_box_point(rng.uniform(lo, hi))

    def vertices(self) -> np.ndarray:
        """All 2^d corners of the box, (2^d, 2, P); vertex m takes coordinate c's upper bound if bit c is set."""
        lo, hi, _ = self.box()
        d = lo.size
        out = np.empty((2**d, 2, self.n_parameters), dtype=np.float64)
        for m in range(2**d):
            bits = np.array([(m >> c) & 1 for c in range(d)], dtype=bool)
            out[m] = self.from_box_point(np.where(bits, hi, lo))
        return out

    def validate(self, params, n_machines: int | None = None, *, allow_infinite_limit: bool = False) -> np.ndarray:
        """Check a parameter array and return it as C-contiguous (N, 2, P) float64.

        Parameters
        ----------
        params : array_like
            (2, P) for one machine or (N, 2, P).
        n_machines : int, optional
            Required N; a (2, P) array is broadcast to it.
        allow_infinite_limit : bool
            Accept an infinite input limit (a linear analysis without
            saturation); the envs do not.

        Raises
        ------
        ValueError
            On a wrong shape or dtype, a non-finite entry, a sign rule of
            :class:`Parameter` broken, shared parameters that differ between
            the axes, a value outside its parameter's ``physical_range``, or
            the plant's own checks.

        Warns
        -----
        ParameterWarning
            For a value outside its parameter's uncertainty interval but
            inside its physical range.
        """
        raw = np.asarray(params)
        if raw.dtype.kind not in "iuf" or raw.dtype == bool:
            raise ValueError(f"{self.name} parameters must be real numbers, got dtype {raw.dtype}")
        p = raw.astype(np.float64)
        P = self.n_parameters
        if p.ndim == 2:
            p = p[None]
        if p.ndim != 3 or p.shape[1:] != (2, P):
            raise ValueError(
                f"{self.name} parameters must have shape (2, {P}) or (N, 2, {P}) "
                f"(columns {list(self.parameter_names)}), got {raw.shape}"
            )
        if n_machines is not None:
            if p.shape[0] == 1 and n_machines != 1:
                p = np.broadcast_to(p, (n_machines, 2, P))
            elif p.shape[0] != n_machines:
                raise ValueError(f"parameters are for {p.shape[0]} machines, expected {n_machines}")
        p = np.ascontiguousarray(p)
        lim = self.index(self.input_limit)
        finite = np.isfinite(p)
        if allow_infinite_limit:
            finite[..., lim] |= np.isposinf(p[..., lim])
        if not finite.all():
            bad = sorted({self.parameter_names[j] for j in np.nonzero(~finite)[2]})
            raise ValueError(f"{self.name} parameters must be finite; not finite: {bad}")
        rules = {
            "positive": lambda v: v > 0,
            "nonnegative": lambda v: v >= 0,
            "nonpositive": lambda v: v <= 0,
            "any": lambda v: np.ones_like(v, dtype=bool),
        }
        for j, par in enumerate(self.parameters):
            if not np.all(rules[par.sign](p[..., j])):
                raise ValueError(
                    f"{self.name} parameter {par.name} [{par.unit}] must be {par.sign}, got {np.unique(p[..., j])}"
                )
            if par.shared and np.any(p[:, 0, j] != p[:, 1, j]):
                raise ValueError(f"{par.name} is shared by both axes of a machine ({par.source})")
        self._check_ranges(p, lim if allow_infinite_limit else None)
        if self.check is not None:
            self.check(p)
        return p

    def _check_ranges(self, p: np.ndarray, infinite_column: int | None) -> None:
        """ValueError for a value outside its parameter's physical range; ParameterWarning for one outside
        its uncertainty interval but inside the range (``infinite_column``: an input limit allowed to be +inf)."""
        for j, par in enumerate(self.parameters):
            v = p[..., j]
            if j == infinite_column:
                v = np.where(np.isposinf(v), par.nominal[0], v)
            if par.physical_range is not None:
                lo, hi = par.physical_range
                bad = (v < lo) | (v > hi)
                if bad.any():
                    raise ValueError(
                        f"{self.name} parameter {par.name} must lie in its physical range [{lo:g}, {hi:g}] "
                        f"{par.unit} ({par.range_source or 'the plant module'}), got {np.unique(v[bad])[:4]}"
                    )
            if par.uncertain:
                for a in range(2):
                    ilo, ihi = par.interval[a]
                    slack = 1e-12 * max(abs(ilo), abs(ihi))
                    out = (v[:, a] < ilo - slack) | (v[:, a] > ihi + slack)
                    if out.any():
                        warnings.warn(
                            f"{self.name} parameter {par.name} = {np.unique(v[:, a][out])[:4]} {par.unit} on the "
                            f"{AXES[a]} axis is outside its uncertainty interval [{ilo:g}, {ihi:g}] ({par.source}) "
                            f"but inside its physical range: accepted",
                            ParameterWarning,
                            stacklevel=3,
                        )
                        break

    def to_dict(self, params) -> dict:
        """One machine's parameters as plain Python: shared ones floats, others (x, y) tuples."""
        p = self.validate(params, allow_infinite_limit=True)
        if p.shape[0] != 1:
            raise ValueError("to_dict takes one machine's (2, P) parameters")
        p = p[0]
        return {
            par.name: float(p[0, j]) if par.shared else (float(p[0, j]), float(p[1, j]))
            for j, par in enumerate(self.parameters)
        }

    def input_limits(self, params) -> np.ndarray:
        """The input limit per axis (..., 2) in ``input_unit``, from a (..., 2, P) array."""
        return np.asarray(params, dtype=np.float64)[..., self.index(self.input_limit)]

    # -- linear model ----------------------------------------------------------
    def linear_model(self, params=None, axis: int = 0):
        """The paper's linear input-to-position model of one axis as a python-control object.

        Parameters
        ----------
        params : array_like, optional
            (2, P) parameters; default nominal.
        axis : int
            0 (x) or 1 (y).

        Returns
        -------
        control.TransferFunction
            mm per input unit; with a dead time the plant declares, the
            delay is returned separately by :meth:`dead_time` (python-control
            has no exact delay element; use ``control.pade`` if needed).

        Raises
        ------
        NotImplementedError
            If the plant's paper gives it no linear model.
        """
        if self.linear_coefficients is None:
            raise NotImplementedError(f"plant {self.name} has no linear model")
        if axis not in (0, 1):
            raise ValueError(f"axis must be 0 (x) or 1 (y), got {axis!r}")
        import control

        p = self.nominal() if params is None else self.validate(params, allow_infinite_limit=True)[0]
        num, den = self.linear_coefficients(p, axis)
        return control.tf(num, den)

    def dead_time(self, params=None, axis: int = 0) -> float:
        """Input dead time of the linear model in s (0 for none)."""
        if self.delay is None:
            return 0.0
        p = self.nominal() if params is None else self.validate(params, allow_infinite_limit=True)[0]
        return float(self.delay(p, axis))

    def inverse(self, params=None) -> "InverseDynamics":
        """The plant's inverse dynamics (:class:`InverseDynamics`) at ``params`` ((2, P), default nominal).

        Raises NotImplementedError for a plant that declares none."""
        if self.inverse_dynamics is None:
            raise NotImplementedError(f"plant {self.name} declares no inverse dynamics")
        p = self.nominal() if params is None else self.validate(params, allow_infinite_limit=True)[0]
        return self.inverse_dynamics(p)

    # -- arrays ----------------------------------------------------------------
    def arrays(self, n_machines: int, dt: float, params=None, **options):
        """The plant's arrays for ``n_machines`` at ``dt`` s, with ``params`` ((2, P) or (N, 2, P)) set.

        ``options`` go to the plant's ``make_arrays`` (its own settings); an
        unknown one is a ValueError naming those it takes.
        """
        n_machines = integer("n_machines", n_machines, 1)
        dt = positive("dt", dt, "s")
        import inspect

        accepted = [p for p in inspect.signature(self.make_arrays).parameters][2:]
        unknown = sorted(set(options) - set(accepted))
        if unknown:
            raise ValueError(f"unknown option(s) {unknown} for plant {self.name}; it takes {accepted}")
        arrays = self.make_arrays(int(n_machines), float(dt), **options)
        if params is not None:
            arrays.params[...] = self.validate(params, int(n_machines))
        return arrays

    def describe(self) -> str:
        """A Markdown table of the parameters: name, unit, nominal (x, y), interval, source."""
        rows = ["| parameter | unit | nominal x, y | interval x; y | source |", "|---|---|---|---|---|"]
        for p in self.parameters:
            iv = (
                "fixed"
                if not p.uncertain
                else (
                    f"[{p.interval[0][0]:g}, {p.interval[0][1]:g}] (shared)"
                    if p.shared
                    else "; ".join(f"[{lo:g}, {hi:g}]" for lo, hi in p.interval)
                )
            )
            rows.append(f"| {p.name} | {p.unit} | {p.nominal[0]:g}, {p.nominal[1]:g} | {iv} | {p.source} |")
        return "\n".join(rows)


#: Highest derivative of the position an :class:`InverseDynamics` weighs (1 velocity ... 4 snap).
INVERSE_ORDER = 4


@dataclass(frozen=True)
class InverseDynamics:
    """A plant's inverse dynamics for one machine: the input that makes its model follow a motion.

    Every plant of the suite, per axis, is a linear part plus the
    nonlinearities that a CNC's feedforward pre-compensates:

    .. math::

        u(t) = \\sum_{n=1}^{4} c_n \\, x^{(n)}(t + T_d)
               + f^{+} \\text{ if } \\dot x > 0, \\; f^{-} \\text{ if } \\dot x < 0
               + F_s e^{-(\\dot x / v_s)^2} \\, \\mathrm{sgn}\\, \\dot x,

    with ``x`` the table position (mm) the input must produce, ``T_d`` the
    input dead time, ``f`` the Coulomb friction levels in input units,
    ``F_s`` and ``v_s`` a Stribeck curve (Armstrong-Helouvry, Dupont &
    Canudas de Wit 1994: the excess of static friction decaying with
    speed; none where ``F_s = 0``, the declared models' case), and
    a backlash of width ``D_b`` (mm) between the drive and the table: the
    drive runs ``D_b / 2`` ahead of the table in the direction of motion and
    crosses the gap at a reversal (``backlash``).  The linear part is the
    inverse of the plant's linear model ``num / den`` with a constant
    numerator, ``c_n = den_n / num`` (a check against python-control's
    ``forced_response`` is in ``tests/test_feedforward.py``).

    Attributes
    ----------
    coefficients : ndarray, (2, 4)
        ``c_1 .. c_4`` per axis, input unit per mm/s, mm/s^2, mm/s^3, mm/s^4.
    coulomb : ndarray, (2, 2)
        ``(f+, f-)`` per axis in input units, ``f- <= 0 <= f+``.
    backlash : ndarray, (2,)
        ``D_b`` per axis, mm (0 for none).
    delay : ndarray, (2,)
        ``T_d`` per axis, s (0 for none).
    stribeck : ndarray, (2, 2)
        ``(F_s, v_s)`` per axis, input unit and mm/s (default none: zeros); ``F_s >= 0``, ``v_s > 0`` where
        ``F_s > 0``.
    """

    coefficients: np.ndarray
    coulomb: np.ndarray
    backlash: np.ndarray
    delay: np.ndarray
    stribeck: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))

    def __post_init__(self):
        shapes = {
            "coefficients": (2, INVERSE_ORDER),
            "coulomb": (2, 2),
            "backlash": (2,),
            "delay": (2,),
            "stribeck": (2, 2),
        }
        for name, shape in shapes.items():
            value = np.array(getattr(self, name), dtype=np.float64)
            if value.shape != shape or not np.all(np.isfinite(value)):
                raise ValueError(f"InverseDynamics.{name} must be finite with shape {shape}, got {value!r}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if np.any(self.coulomb[:, 0] < 0) or np.any(self.coulomb[:, 1] > 0):
            raise ValueError(f"InverseDynamics.coulomb must be (f+ >= 0, f- <= 0) per axis, got {self.coulomb}")
        if np.any(self.backlash < 0) or np.any(self.delay < 0):
            raise ValueError("InverseDynamics.backlash and delay must be >= 0")
        if np.any(self.stribeck[:, 0] < 0) or np.any((self.stribeck[:, 0] > 0) & (self.stribeck[:, 1] <= 0)):
            raise ValueError(
                f"InverseDynamics.stribeck must be (F_s >= 0, v_s > 0 where F_s > 0) per axis, got {self.stribeck}"
            )

    @classmethod
    def from_linear(cls, plant: "PlantModel", params, coulomb=((0.0, 0.0), (0.0, 0.0)), backlash=(0.0, 0.0)):
        """The inverse of ``plant``'s linear model at ``params`` (2, P) (constant numerator, denominator of
        degree <= 4, ``den[-1] = 0``: an integrator to position), its dead time, plus the given friction
        and backlash."""
        linear = plant.linear_coefficients
        if linear is None:
            raise ValueError(f"plant {plant.name} declares no linear_coefficients: no linear inverse")
        rows = []
        for axis in (0, 1):
            num, den = (np.atleast_1d(np.asarray(c, dtype=np.float64)) for c in linear(params, axis))
            num = np.trim_zeros(num, "f")
            if num.size != 1 or den.size - 1 > INVERSE_ORDER or den[-1] != 0.0:
                raise ValueError(
                    f"plant {plant.name}: InverseDynamics.from_linear needs a constant numerator and "
                    f"a denominator s (...) of degree <= {INVERSE_ORDER}, got {num}, {den}"
                )
            row = np.zeros(INVERSE_ORDER)
            ascending = den[::-1] / num[0]  # coefficient of s^n at n
            row[: ascending.size - 1] = ascending[1:]
            rows.append(row)
        delay = [plant.delay(params, a) if plant.delay is not None else 0.0 for a in (0, 1)]
        return cls(
            np.array(rows),
            np.array(coulomb, dtype=np.float64),
            np.array(backlash, dtype=np.float64),
            np.array(delay, dtype=np.float64),
        )

    @property
    def mass(self) -> np.ndarray:
        """``c_2`` per axis (input unit per mm/s^2): the equivalent mass of the pole-placement rules."""
        return self.coefficients[:, 1]

    @property
    def damping(self) -> np.ndarray:
        """``c_1`` per axis (input unit per mm/s)."""
        return self.coefficients[:, 0]
