"""The machine as it is on the shop floor: any plant with a real sensor, delays, a structural mode and process forces.

:func:`shop_floor` wraps a plant of :mod:`vcnc_gym.plants` (its
:class:`~vcnc_gym.plants.contract.PlantModel`) into another plant: the same
drive, with the effects the source papers leave out, each with its units, a
physical default and its source, and each a :class:`Parameter` appended to
the inner plant's (so ``randomize`` draws them from their intervals, and
``vcnc-bench --plants`` samples them with the rest).  An effect whose
switch parameters are 0 is off; with every effect off the wrapped plant gives
the inner plant's observations to the bit (``tests/test_shop_floor.py``).  The
papers' ids do not use the wrapper at all.

Effects
-------
An effect is one declaration, a subclass of :class:`Effect` (its docstring
the physics, its source and units): its ``parameters``, its per-machine
``state`` arrays, its ``reset`` and its numba steps, one per stage of the
control period it acts in.  :data:`EFFECTS` are the shop floor's, in the
order of their parameters (appended to the inner plant's in this order):

- :class:`PositionSensor`: quantisation and white noise of the position reading;
- :class:`CommandDelay`: the computation / transport delay of the command;
- :class:`SensorDelay`: the reading's transmission delay;
- :class:`StructuralMode`: the first structural mode between drive and table;
- :class:`CuttingForce`: the milling force and its tooth-passing component;
- :class:`StribeckFriction`: the guideways' Stribeck effect.

``shop_floor(plant, settings, effects=...)`` composes any tuple of effects
(the add-a-shop-floor-effect guide, ``docs/guides/add-a-shop-floor-effect.md``,
adds one in its own module); the kernel is compiled per composition.

The control period
------------------
Per control period ``dt`` of machine ``k`` (:func:`contract.advance`), the
stages in this order, each running the hooks of the effects that have one,
in the order of the composition's effects:

1. ``command``: the command ``x`` ((2,), input units) may be changed (the
   command delay's FIFO).
2. ``force``: the effects add their force ``x`` ((2,) N, it starts at 0)
   on the table; the force enters as the input the plant declares
   equivalent (``PlantModel.force_gain``, input unit per N), added to the
   command before the inner plant's amplifier saturation (so a saturated
   command also clips the disturbance: the disturbance of an amplifier
   model, not of a force on the table).
3. The inner plant advances (:func:`contract.advance` on its own arrays).
4. ``table``: from the drive's position (the inner plant's table position,
   rigid) the effects may move the table: ``x`` (2, A_SIZE), per axis the
   drive's position ``A_DRIVE``, the table's position and velocity
   (``A_TABLE``, ``A_TABLE_VELOCITY``, by default the drive's) and the
   reading (``A_READING``, by default the inner plant's own sensor).  The
   contour error is measured on ``A_TABLE``.
5. ``reading``: the effects may replace the reading and the velocity read
   (``A_READING_VELOCITY``, by default the table's).
6. ``sense`` (in :func:`contract.sense`): ``x`` the contract's ``out``, the
   table, the reading and its velocity written; the effects may replace what
   the controller sees (the sensor delay's FIFO).

Every hook is ``hook(s, plant, k, x)``: ``s`` the effect's columns (its
``Arrays`` record of integers: ``s.params`` the column of its first
parameter in ``plant.params``, each state array's first column in
``plant.fstate`` (float64) or ``plant.istate`` (int64), row-major),
``plant`` the :data:`ShopFloorArrays`, whose ``memory`` holds the last
period's table (``M_*`` columns), ``dt`` and ``rng`` (the machine's
splitmix64 noise generator, seeded from the env's generator at every reset:
``PlantModel.seed_machine``).  The effects' state lives in the plant's two
state arrays, not in arrays of their own: a record of arrays taken from a
tuple inside the env's kernel would be reference-counted (atomic
operations) at every use, which costs more than the effects themselves.

The observation therefore shows the quantised, noisy, delayed measurement;
the exact contour error (on the true table position) stays in ``info``.

The wrapped model keeps the inner plant's ``name`` (it is the same machine,
and every controller designed for that machine runs on it), its input, its
linear model, dead time and inverse dynamics (the *nominal* model a
controller is designed from: the effects are what the nominal model lacks);
``model.inner`` is the inner model and ``model.effects`` the composed
effects (:class:`Effect` subclasses).

Arrays
------
:data:`ShopFloorArrays`: ``inner`` (the inner plant's namedtuple; its
``params`` a view of the first P columns of ``params``), ``state`` (the
inner plant's state array itself, so a NaN written there diverges the
episode), ``params`` (N, 2, P + E), ``dt``, the force gain, the table's
memory, scratch, the noise generators, the effects' state ``fstate`` and
``istate`` and ``effects``, the tuple of the effects' column records.
"""

from __future__ import annotations

import inspect
import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit, types
from numba.extending import overload

from . import contract
from .contract import Parameter, PlantModel

__all__ = [
    "Effect",
    "EFFECTS",
    "EFFECT_PARAMETERS",
    "EFFECT_NAMES",
    "OFF",
    "MAX_DELAY",
    "ShopFloorArrays",
    "ShopFloorModel",
    "shop_floor",
    "PositionSensor",
    "CommandDelay",
    "SensorDelay",
    "StructuralMode",
    "CuttingForce",
    "StribeckFriction",
    "mode_response",
    "mode_transition",
    "splitmix64",
    "normal_pair",
]

#: Longest delay, control periods (command or sensor): the FIFOs hold this many entries plus one.
MAX_DELAY = 8

#: The feedforward's Coulomb transition on the shop floor, s: the Stribeck friction spreads the reversal, which a
#: switch at the reversal itself does not model (Simba et al.'s drive: ff-ccc 166 um with 1 ms against 181 um with 0
#: on the shop-floor smoothed corners, ``python benchmarks/tune_servo.py --shop-floor``).
SHOP_FRICTION_TIME = 1e-3

#: Width of the Stribeck term's smooth sign, as a fraction of ``stribeck_velocity`` (ours).
STRIBECK_SIGN_WIDTH = 0.1

_ALTINTAS = "Altintas, Manufacturing Automation, 2nd ed. 2012"

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

#: The stages of a control period, in order (module docstring).
STAGES = ("command", "force", "table", "reading", "sense")


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
        The effect's step in each stage (module docstring); ``njit(cache=True)``
        (``inline="always"`` keeps the composed kernel one function).
    """

    parameters: tuple = ()
    switches: tuple = ()
    counts: tuple = ()
    state: dict = {}
    reset = None
    command = force = table = reading = sense = None
    Arrays = None

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
        arrays.effect = cls
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


# --------------------------------------------------------------------------
# The noise generator
# --------------------------------------------------------------------------

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_ONE = np.uint64(1)


@njit(cache=True, _nrt=False)
def splitmix64(rng, k):
    """Next 64-bit output of machine ``k``'s splitmix64 generator (Steele, Lea & Flood 2014), state
    ``rng[k]`` advanced."""
    s = rng[k] + _GOLDEN
    rng[k] = s
    z = (s ^ (s >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@njit(cache=True, _nrt=False)
def normal_pair(rng, k):
    """Two independent standard normal numbers from machine ``k``'s generator (Box-Muller on two uniforms
    in (0, 1])."""
    u1 = float((splitmix64(rng, k) >> _S11) + _ONE) * 2.0**-53
    u2 = float((splitmix64(rng, k) >> _S11) + _ONE) * 2.0**-53
    r = math.sqrt(-2.0 * math.log(u1))
    t = 2.0 * math.pi * u2
    return r * math.cos(t), r * math.sin(t)


# --------------------------------------------------------------------------
# The effects
# --------------------------------------------------------------------------

_FIFO = MAX_DELAY + 1


class PositionSensor(Effect):
    """The position sensor (replacing the inner plant's own, e.g. Purtojo et al.'s 1 um encoder, unless both its
    settings are 0): the table position plus white Gaussian noise of standard deviation ``noise_std`` mm (the
    machine's splitmix64 generator), quantised to ``encoder_resolution`` mm (the nearest count).  With a noisy or
    quantised sensor the velocity the controller sees is the backward difference of two readings over ``dt`` (what
    a CNC's position loop computes); with a perfect one the table's velocity."""

    parameters = (
        Parameter(
            "encoder_resolution",
            "mm",
            nominal=(1e-4, 1e-4),
            interval=((5e-5, 2e-4), (5e-5, 2e-4)),
            shared=True,
            sign="nonnegative",
            source="the CNC increment system IS-C, 0.1 um (FANUC; IS-B is 1 um); 0: exact",
            description="position sensor's quantisation step (nearest count)",
            physical_range=(0.0, 0.01),
            range_source="ours: 10 um, a coarse rotary encoder on a 10 mm lead",
        ),
        Parameter(
            "noise_std",
            "mm",
            nominal=(5e-5, 5e-5),
            interval=((0.0, 1e-4), (0.0, 1e-4)),
            shared=True,
            sign="nonnegative",
            source="ours: a quarter of the +-0.2 um interpolation error of a 20 um grating (+-1 % of the "
            "signal period, optical linear encoders' data sheets), as white noise; 0: none",
            description="standard deviation of the position reading's white Gaussian noise",
            physical_range=(0.0, 0.01),
            range_source="ours: 10 um, a noisy analogue transducer",
        ),
    )
    switches = ("encoder_resolution", "noise_std")

    @staticmethod
    def reset(v, plant, k):
        """At rest the reading is the true position's count, the velocity read 0."""
        r, sigma = v.params[k, 0, 0], v.params[k, 0, 1]
        if r > 0.0 or sigma > 0.0:
            x = plant.memory[k, :, M_TABLE]
            plant.memory[k, :, M_READING] = r * np.floor(x / r + 0.5) if r > 0.0 else x
            plant.memory[k, :, M_READING_VELOCITY] = 0.0

    @staticmethod
    @njit(cache=True, _nrt=False, inline="always")
    def reading(s, plant, k, x):
        r = plant.params[k, 0, s.params]
        sigma = plant.params[k, 0, s.params + 1]
        if r == 0.0 and sigma == 0.0:
            return
        n0 = 0.0
        n1 = 0.0
        if sigma > 0.0:
            n0, n1 = normal_pair(plant.rng, k)
        for i in range(2):
            reading = x[i, A_TABLE]
            if sigma > 0.0:
                reading += sigma * (n0 if i == 0 else n1)
            if r > 0.0:
                reading = r * math.floor(reading / r + 0.5)
            x[i, A_READING] = reading
            x[i, A_READING_VELOCITY] = (reading - plant.memory[k, i, M_READING]) / plant.dt


class CommandDelay(Effect):
    """Computation / transport delay of ``command_delay`` whole control periods: the command applied is the one
    given ``d`` periods earlier (a FIFO of the last commands, zero before the first), the one-sample computation
    delay of a digital position loop and the drive's transmission delay (Altintas, *Manufacturing Automation*, 2nd
    ed. 2012, ch. 6: the ZOH and computation delay of a CNC's sampled loop)."""

    parameters = (
        Parameter(
            "command_delay",
            "periods",
            nominal=(1.0, 1.0),
            interval=((1.0, 2.0), (1.0, 2.0)),
            shared=True,
            sign="nonnegative",
            source=f"{_ALTINTAS}, ch. 6: one sample of computation delay; rounded to whole control periods",
            description="delay of the command, whole control periods (rounded)",
            physical_range=(0.0, float(MAX_DELAY)),
            range_source=f"the FIFO's length, MAX_DELAY = {MAX_DELAY}",
        ),
    )
    switches = counts = ("command_delay",)
    state = {"commands": ((_FIFO, 2), np.float64), "delay": ((), np.int64), "head": ((), np.int64)}

    @staticmethod
    def reset(v, plant, k):
        v.delay[k] = int(math.floor(v.params[k, 0, 0] + 0.5))
        v.commands[k] = 0.0
        v.head[k] = 0

    @staticmethod
    @njit(cache=True, _nrt=False, inline="always")
    def command(s, plant, k, x):
        f = plant.fstate
        head = plant.istate[k, s.head]
        f[k, s.commands + 2 * head] = x[0]
        f[k, s.commands + 2 * head + 1] = x[1]
        slot = head - plant.istate[k, s.delay]  # the ring's index arithmetic without a modulo (a division)
        if slot < 0:
            slot += _FIFO
        x[0] = f[k, s.commands + 2 * slot]
        x[1] = f[k, s.commands + 2 * slot + 1]
        head += 1
        if head == _FIFO:
            head = 0
        plant.istate[k, s.head] = head


class SensorDelay(Effect):
    """The reading seen ``sensor_delay`` whole control periods late (a FIFO of the readings and velocities read,
    every entry the rest reading after a reset)."""

    parameters = (
        Parameter(
            "sensor_delay",
            "periods",
            nominal=(0.0, 0.0),
            interval=((0.0, 1.0), (0.0, 1.0)),
            shared=True,
            sign="nonnegative",
            source="ours: a serial encoder's transmission, up to one period; rounded to whole control periods",
            description="delay of the position reading, whole control periods (rounded)",
            physical_range=(0.0, float(MAX_DELAY)),
            range_source=f"the FIFO's length, MAX_DELAY = {MAX_DELAY}",
        ),
    )
    switches = counts = ("sensor_delay",)
    state = {"readings": ((_FIFO, 4), np.float64), "delay": ((), np.int64), "head": ((), np.int64)}

    @staticmethod
    def reset(v, plant, k):
        v.delay[k] = int(math.floor(v.params[k, 0, 0] + 0.5))
        v.readings[k, :, 0:2] = plant.memory[k, :, M_READING]
        v.readings[k, :, 2:4] = plant.memory[k, :, M_READING_VELOCITY]
        v.head[k] = 0

    @staticmethod
    @njit(cache=True, _nrt=False, inline="always")
    def reading(s, plant, k, x):
        head = plant.istate[k, s.head] + 1
        if head == _FIFO:
            head = 0
        plant.istate[k, s.head] = head
        row = s.readings + 4 * head
        for i in range(2):
            plant.fstate[k, row + i] = x[i, A_READING]
            plant.fstate[k, row + 2 + i] = x[i, A_READING_VELOCITY]

    @staticmethod
    @njit(cache=True, _nrt=False, inline="always")
    def sense(s, plant, k, x):
        slot = plant.istate[k, s.head] - plant.istate[k, s.delay]
        if slot < 0:
            slot += _FIFO
        row = s.readings + 4 * slot
        for i in range(2):
            x[contract.SENSE_MEASURED + i] = plant.fstate[k, row + i]
            x[contract.SENSE_VELOCITY + i] = plant.fstate[k, row + 2 + i]


def mode_transition(frequency: float, damping: float, dt: float) -> np.ndarray:
    """Transition matrix over ``dt`` s of ``e'' = -w^2 e - 2 zeta w e'`` (w = 2 pi ``frequency``), (2, 2), exact
    (the matrix exponential of [[0, 1], [-w^2, -2 zeta w]] dt)."""
    w = 2.0 * math.pi * frequency
    a = np.array([[0.0, 1.0], [-w * w, -2.0 * damping * w]])
    from scipy.linalg import expm

    return expm(a * dt)


def mode_response(frequency: float, damping: float):
    """The structural mode's drive-to-table transfer function ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``
    as a python-control object (w = 2 pi ``frequency`` rad/s)."""
    import control

    w = 2.0 * math.pi * frequency
    return control.tf([2.0 * damping * w, w * w], [1.0, 2.0 * damping * w, w * w])


class StructuralMode(Effect):
    """First structural mode between the drive and the table: the table follows the drive's position ``x_d`` (the
    inner plant's table position, rigid) through a spring and damper,
    ``x_t'' = w^2 (x_d - x_t) + 2 zeta w (x_d' - x_t')``, ``w = 2 pi mode_frequency``, ``zeta = mode_damping``;
    integrated exactly for a drive position that ramps linearly over the period (a first-order hold,
    ``control.c2d(M, dt, "foh")`` of ``M(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``, tested; the
    deviation ``e = x_t - x_d`` advanced by :func:`mode_transition`).  The table's reaction on the drive is
    neglected (the mode as the command-to-table response shows it: a resonance of the loop the position sensor
    closes on the table, which is what limits a feed drive's bandwidth; Erkorkmaz & Altintas 2001, Part II, and
    Altintas 2012, ch. 6, model the first axial mode of a ball-screw drive this way as a second-order lightly
    damped mode in series with the rigid body).  The reading moves with the table."""

    parameters = (
        Parameter(
            "mode_frequency",
            "Hz",
            nominal=(150.0, 150.0),
            interval=((100.0, 200.0), (100.0, 200.0)),
            sign="nonnegative",
            source=f"ours, a ball-screw drive's first axial mode (Erkorkmaz & Altintas 2001, Part II; "
            f"{_ALTINTAS}, ch. 6); 0: rigid",
            description="natural frequency of the first structural mode between drive and table",
            physical_range=(0.0, 5000.0),
            range_source="ours: a direct drive's stiff table, kHz",
        ),
        Parameter(
            "mode_damping",
            "1",
            nominal=(0.05, 0.05),
            interval=((0.02, 0.1), (0.02, 0.1)),
            sign="nonnegative",
            source="ours: lightly damped structural modes, 2-10 % of critical",
            description="its damping ratio",
            physical_range=(0.0, 2.0),
            range_source="ours: beyond 1 the mode is overdamped",
        ),
    )
    switches = ("mode_frequency",)
    #: ``phi`` (2, 4) per machine: per axis the transition matrix over dt, row-major
    state = {"phi": ((2, 4), np.float64)}

    @staticmethod
    def reset(v, plant, k):
        for i in range(2):
            f = v.params[k, i, 0]
            phi = mode_transition(f, v.params[k, i, 1], plant.dt) if f > 0 else np.eye(2)
            v.phi[k, i] = phi.ravel()

    @staticmethod
    @njit(cache=True, _nrt=False, inline="always")
    def table(s, plant, k, x):
        m = plant.memory
        f = plant.fstate
        dt = plant.dt
        for i in range(2):
            if plant.params[k, i, s.params] > 0.0:
                x_d = x[i, A_DRIVE]
                x_d0 = m[k, i, M_DRIVE]
                slope = (x_d - x_d0) / dt
                e = m[k, i, M_TABLE] - x_d0
                de = m[k, i, M_TABLE_VELOCITY] - slope
                phi = s.phi + 4 * i
                e1 = f[k, phi] * e + f[k, phi + 1] * de
                de1 = f[k, phi + 2] * e + f[k, phi + 3] * de
                x[i, A_TABLE] = x_d + e1
                x[i, A_TABLE_VELOCITY] = slope + de1
                x[i, A_READING] += e1


class CuttingForce(Effect):
    """Process forces as an equivalent input disturbance: a milling force against the direction of motion, a mean
    ``cutting_force`` plus a tooth-passing component ``cutting_ripple cos(phi)`` whose phase advances at the
    tooth-passing frequency ``spindle_speed teeth / 60`` Hz (Altintas 2012, ch. 2: the periodic milling force at the
    tooth-passing frequency), along the table's mean velocity over the previous period."""

    parameters = (
        Parameter(
            "cutting_force",
            "N",
            nominal=(100.0, 100.0),
            interval=((50.0, 150.0), (50.0, 150.0)),
            shared=True,
            sign="nonnegative",
            source=f"ours: a light finishing cut ({_ALTINTAS}, ch. 2); 0: air cutting",
            description="mean cutting force against the direction of motion",
            physical_range=(0.0, 1e4),
            range_source="ours: 10 kN, heavy roughing",
        ),
        Parameter(
            "cutting_ripple",
            "N",
            nominal=(50.0, 50.0),
            interval=((25.0, 75.0), (25.0, 75.0)),
            shared=True,
            sign="nonnegative",
            source=f"ours: half the mean, the first tooth-passing harmonic ({_ALTINTAS}, ch. 2)",
            description="amplitude of the cutting force's tooth-passing component",
            physical_range=(0.0, 1e4),
            range_source="ours: 10 kN",
        ),
        Parameter(
            "spindle_speed",
            "rpm",
            nominal=(6000.0, 6000.0),
            interval=((5000.0, 7000.0), (5000.0, 7000.0)),
            shared=True,
            sign="nonnegative",
            source="ours: a machining centre's spindle",
            description="spindle speed",
            physical_range=(0.0, 1e5),
            range_source="ours: high-speed spindles",
        ),
        Parameter(
            "teeth",
            "1",
            nominal=(4.0, 4.0),
            shared=True,
            source="ours: a four-flute end mill",
            description="cutter teeth (the tooth-passing frequency is spindle_speed teeth / 60 Hz)",
            physical_range=(1.0, 64.0),
            range_source="ours: face mills have tens of inserts",
        ),
    )
    switches = ("cutting_force", "cutting_ripple")
    counts = ("teeth",)
    #: the cutter's phase, rad, and its advance per period, rad
    state = {"phase": ((), np.float64), "phase_step": ((), np.float64)}

    @staticmethod
    def reset(v, plant, k):
        e = v.params[k]
        v.phase[k] = 0.0
        v.phase_step[k] = 2.0 * math.pi * e[0, 2] * e[0, 3] / 60.0 * plant.dt

    @staticmethod
    @njit(cache=True, _nrt=False, inline="always")
    def force(s, plant, k, x):
        f_cut = plant.params[k, 0, s.params]
        f_rip = plant.params[k, 0, s.params + 1]
        if f_cut > 0.0 or f_rip > 0.0:
            m = plant.memory
            speed = math.hypot(m[k, 0, M_MEAN_VELOCITY], m[k, 1, M_MEAN_VELOCITY])
            if speed > 0.0:
                cutting = (f_cut + f_rip * math.cos(plant.fstate[k, s.phase])) / speed
                for i in range(2):
                    x[i] -= cutting * m[k, i, M_MEAN_VELOCITY]
            plant.fstate[k, s.phase] += plant.fstate[k, s.phase_step]


class StribeckFriction(Effect):
    """The Stribeck effect of the guideways, the excess of static over Coulomb friction decaying with speed,
    ``-stribeck_force exp(-(v / stribeck_velocity)^2) tanh(v / (0.1 stribeck_velocity))`` N (Armstrong-Helouvry,
    Dupont & Canudas de Wit 1994; the Coulomb level is the inner plant's own, the tanh a smooth sign, ours), ``v``
    the table's mean velocity over the previous period."""

    parameters = (
        Parameter(
            "stribeck_force",
            "N",
            nominal=(30.0, 30.0),
            interval=((15.0, 45.0), (15.0, 45.0)),
            sign="nonnegative",
            source="ours: excess of static over Coulomb friction of linear guides (Armstrong-Helouvry, Dupont "
            "& Canudas de Wit 1994); 0: none",
            description="Stribeck friction at rest beyond the inner plant's Coulomb level",
            physical_range=(0.0, 1e4),
            range_source="ours: 10 kN, a heavy gantry's guides",
        ),
        Parameter(
            "stribeck_velocity",
            "mm/s",
            nominal=(1.0, 1.0),
            interval=((0.5, 2.0), (0.5, 2.0)),
            source="ours: Stribeck velocities of lubricated guides, 0.1-100 mm/s (Armstrong-Helouvry et al. 1994)",
            description="speed over which the Stribeck friction decays",
            physical_range=(1e-3, 1e3),
            range_source="Armstrong-Helouvry et al. 1994's span, widened",
        ),
    )
    switches = ("stribeck_force",)

    @staticmethod
    @njit(cache=True, _nrt=False, inline="always")
    def force(s, plant, k, x):
        for i in range(2):
            f = plant.params[k, i, s.params]
            if f > 0.0:
                vs = plant.params[k, i, s.params + 1]
                v = plant.memory[k, i, M_MEAN_VELOCITY]
                x[i] -= f * math.exp(-((v / vs) ** 2)) * math.tanh(v / (STRIBECK_SIGN_WIDTH * vs))


#: The shop floor's effects, in the order of their parameters.
EFFECTS = (PositionSensor, CommandDelay, SensorDelay, StructuralMode, CuttingForce, StribeckFriction)

#: Their parameters, appended to the inner plant's in this order.  Physical defaults are ours, each within the range
#: the cited source describes for machine-tool feed drives (see each ``source``).
EFFECT_PARAMETERS = tuple(p for effect in EFFECTS for p in effect.parameters)
EFFECT_NAMES = tuple(p.name for p in EFFECT_PARAMETERS)

#: Every effect off (their switches at 0): the wrapped plant is the inner one (bit-identical observations).
OFF = {name: 0.0 for effect in EFFECTS for name in effect.switches}


# --------------------------------------------------------------------------
# The composition
# --------------------------------------------------------------------------

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


def _stage(name: str):
    """The kernel of stage ``name``: ``run(effects, plant, k, x)`` calls ``hook(effects[j], plant, k, x)`` of every
    effect of the tuple ``effects`` that has one, in order, as straight-line code generated for the tuple's type
    (the effects' classes are read from their ``Arrays`` types; nothing is looked up at run time)."""

    def run(effects, plant, k, x):  # pragma: no cover - compiled through the overload below
        raise NotImplementedError("the shop floor's stages run in numba code")

    run.__name__ = run.__qualname__ = f"{name}_stage"

    @overload(run, inline="always")
    def _run(effects, plant, k, x):
        if not isinstance(effects, types.BaseTuple):
            return None
        namespace, lines = {}, []
        for j, t in enumerate(effects.types):
            hook = getattr(t.instance_class.effect, name)
            if hook is not None:
                namespace[f"hook{j}"] = hook
                lines.append(f"    hook{j}(effects[{j}], plant, k, x)")
        exec(f"def impl(effects, plant, k, x):\n{chr(10).join(lines) or '    pass'}\n", namespace)
        return namespace["impl"]

    return run


command_stage, force_stage, table_stage, reading_stage, sense_stage = (_stage(name) for name in STAGES)


@dataclass(frozen=True, eq=False)
class ShopFloorModel(PlantModel):
    """A :class:`PlantModel` wrapped by :func:`shop_floor`; ``inner`` the wrapped model, ``effects`` the composed
    :class:`Effect` classes."""

    inner: PlantModel | None = None
    effects: tuple = ()


def _setting(p: Parameter, value, counted: bool) -> tuple:
    """The (x, y) pair of a shop-floor setting, each through :mod:`vcnc_gym.validation` (a count an integer)."""
    from ..validation import integer, per_axis

    name = f"shop-floor setting {p.name}"
    if counted:
        items = value if isinstance(value, (tuple, list)) else (value, value)
        if len(items) != 2:
            raise ValueError(f"{name} must be an integer or an (x, y) pair of them ({p.unit}), got {value!r}")
        whole = [int(v) if isinstance(v, float) and v.is_integer() else v for v in items]  # 4.0 (YAML) is 4
        return tuple(float(integer(f"{name} ({p.unit})", v, minimum=0)) for v in whole)
    return tuple(float(v) for v in per_axis(name, value, p.unit))


def _set(p: Parameter, value, counted: bool) -> Parameter:
    """Parameter ``p`` with the nominal value ``value``: outside the interval, the default's relative spread
    around it (none around 0, off, or a default of 0)."""
    pair = _setting(p, value, counted)
    if p.physical_range is not None and not all(p.physical_range[0] <= v <= p.physical_range[1] for v in pair):
        raise ValueError(
            f"shop-floor setting {p.name} = {value!r} {p.unit} is outside its physical range "
            f"[{p.physical_range[0]:g}, {p.physical_range[1]:g}] ({p.range_source})"
        )
    interval = p.interval
    if interval is not None and not all(lo <= v <= hi for v, (lo, hi) in zip(pair, interval)):
        top = math.inf if p.physical_range is None else p.physical_range[1]  # within the physical range
        interval = (
            None
            if min(pair) <= 0 or min(p.nominal) <= 0
            else tuple((v * lo / n, min(v * hi / n, max(v, top))) for v, n, (lo, hi) in zip(pair, p.nominal, interval))
        )
    return Parameter(
        p.name,
        p.unit,
        nominal=pair,
        interval=interval,
        shared=p.shared,
        source=p.source,
        sign=p.sign,
        description=p.description,
        physical_range=p.physical_range,
        range_source=p.range_source,
    )


def shop_floor(plant, settings: dict | bool | None = True, effects: tuple = EFFECTS) -> ShopFloorModel:
    """The plant ``plant`` (a name of :mod:`vcnc_gym.plants` or a PlantModel) on the shop floor.

    Parameters
    ----------
    plant : str or PlantModel
    settings : dict or True
        Nominal values of effect parameters, ``{name: value}`` (one value for
        both axes, or a pair (x, y)), over the defaults of the effects'
        parameters; a parameter set outside its interval keeps the default's
        relative spread around it (0, off, is fixed).  True: the defaults.
    effects : tuple of Effect subclasses
        The effects composed, in order (default :data:`EFFECTS`, the shop
        floor's; the shop ids use those).

    Raises
    ------
    ValueError
        For an unknown setting (the message lists the effects' parameters), a
        value the parameter's rules refuse, effects that are not
        :class:`Effect` subclasses or share a parameter name, or force
        effects on a plant that declares no ``force_gain``.
    """
    from . import get_plant

    inner = get_plant(plant)
    if isinstance(inner, ShopFloorModel):
        raise ValueError(f"plant {inner.name!r} is already on the shop floor")
    effects = tuple(effects) if isinstance(effects, (tuple, list)) else effects
    if not isinstance(effects, tuple) or not all(
        isinstance(e, type) and issubclass(e, Effect) and e is not Effect for e in effects
    ):
        raise ValueError(f"effects must be a tuple of Effect subclasses, got {effects!r}")
    names = [p.name for e in effects for p in e.parameters]
    clash = sorted({n for n in names if names.count(n) > 1} | (set(names) & {p.name for p in inner.parameters}))
    if clash:
        raise ValueError(f"effects {[e.__name__ for e in effects]}: parameter names {clash} appear twice")
    if settings is True or settings is None:
        settings = {}
    if not isinstance(settings, dict):
        raise ValueError(f"shop_floor settings must be a dict {{effect parameter: value}} or True, got {settings!r}")
    unknown = sorted(set(settings) - set(names))
    if unknown:
        raise ValueError(f"unknown shop-floor setting(s) {unknown}; the effects' parameters are {names}")
    parameters = tuple(
        _set(p, settings[p.name], p.name in e.counts) if p.name in settings else p
        for e in effects
        for p in e.parameters
    )
    on = {
        p.name
        for p in parameters
        if max(p.nominal) > 0 or (p.interval is not None and max(hi for _, hi in p.interval) > 0)
    }
    forces = [name for e in effects if e.uses_force_gain() for name in e.switches if name in on]
    if forces and inner.force_gain is None:
        raise ValueError(
            f"plant {inner.name} declares no force_gain (input per N): the effects "
            f"{forces} cannot act on it; set them to 0"
        )
    n_inner = inner.n_parameters

    def inner_part(params):
        return np.asarray(params)[..., :n_inner]

    def check(p):  # the effects' own rules are their Parameters' (sign, physical range)
        if inner.check is not None:
            inner.check(p[..., :n_inner])

    def make_arrays(n_machines, dt, **options):
        return _make_arrays(model, n_machines, dt, **options)

    make_arrays.__signature__ = inspect.signature(inner.make_arrays)  # its options are the inner plant's

    model = ShopFloorModel(
        name=inner.name,
        source=f"{inner.source}; on the shop floor (vcnc_gym.plants.shop_floor)",
        parameters=inner.parameters + parameters,
        state_names=inner.state_names,
        input_name=inner.input_name,
        input_unit=inner.input_unit,
        input_limit=inner.input_limit,
        make_arrays=make_arrays,
        reset_machine=lambda arrays, k, position: _reset_machine(model, arrays, k, position),
        check=check,
        linear_coefficients=(
            None
            if inner.linear_coefficients is None
            else lambda params, axis: inner.linear_coefficients(inner_part(params), axis)
        ),
        delay=None if inner.delay is None else lambda params, axis: inner.delay(inner_part(params), axis),
        inverse_dynamics=(
            None if inner.inverse_dynamics is None else lambda params: inner.inverse_dynamics(inner_part(params))
        ),
        force_gain=None if inner.force_gain is None else lambda params: inner.force_gain(inner_part(params)),
        seed_machine=_seed_machine,
        servo_bandwidth=inner.servo_bandwidth,
        friction_time=SHOP_FRICTION_TIME,
        path_limits=inner.path_limits,
        random_contour=dict(inner.random_contour),
        inner=inner,
        effects=effects,
    )
    return model


def _make_arrays(model: ShopFloorModel, n_machines: int, dt: float, **options) -> ShopFloorArrays:
    inner = model.inner
    arrays = inner.make_arrays(n_machines, dt, **options)
    P = inner.n_parameters
    params = np.repeat(model.nominal()[None], n_machines, axis=0)
    params[:, :, :P] = arrays.params
    arrays = arrays._replace(params=params[:, :, :P])
    n = n_machines
    effects, column, fcol, icol = [], P, 0, 0
    for effect in model.effects:
        effects.append(effect.columns(column, fcol, icol))
        column += len(effect.parameters)
        fcol, icol = fcol + effect.sizes()[0], icol + effect.sizes()[1]
    out = ShopFloorArrays(
        inner=arrays,
        state=arrays.state,
        params=params,
        dt=float(dt),
        n_inner=P,
        gain=np.zeros((n, 2)),
        memory=np.zeros((n, 2, M_SIZE)),
        rng=np.zeros(n, dtype=np.uint64),
        applied=np.zeros((n, 2)),
        force=np.zeros((n, 2)),
        table=np.zeros((n, 2, A_SIZE)),
        sensed=np.zeros((n, contract.SENSE_SIZE)),
        fstate=np.zeros((n, fcol)),
        istate=np.zeros((n, icol), dtype=np.int64),
        effects=tuple(effects),
    )
    for k in range(n):
        _reset_machine(model, out, k, np.zeros(2))
    return out


def _reset_machine(model: ShopFloorModel, arrays: ShopFloorArrays, k: int, position) -> None:
    """Machine ``k`` at rest at ``position`` (2,) mm: the inner plant reset, the table on the drive, the reading
    the inner plant's, the noise generator at seed ``k`` (the envs then draw it from their generator:
    ``seed_machine``); then each effect's ``reset``, in order."""
    inner = model.inner
    P = arrays.n_inner
    inner.reset_machine(arrays.inner, k, position)
    arrays.gain[k] = inner.force_gain(arrays.params[k, :, :P]) if inner.force_gain is not None else 0.0
    sensed = arrays.sensed[k]
    _sense_inner(arrays.inner, k, sensed)
    memory = arrays.memory[k]
    memory[:] = 0.0
    memory[:, M_DRIVE] = sensed[contract.SENSE_POSITION : contract.SENSE_POSITION + 2]
    memory[:, M_TABLE] = sensed[contract.SENSE_POSITION : contract.SENSE_POSITION + 2]
    memory[:, M_READING] = sensed[contract.SENSE_MEASURED : contract.SENSE_MEASURED + 2]
    memory[:, M_READING_VELOCITY] = sensed[contract.SENSE_VELOCITY : contract.SENSE_VELOCITY + 2]
    arrays.rng[k] = np.uint64(k)
    for effect, s in zip(model.effects, arrays.effects):
        if effect.reset is not None:
            effect.reset(effect.views(arrays, s), arrays, k)


def _seed_machine(arrays: ShopFloorArrays, k: int, rng: np.random.Generator) -> None:
    """Machine ``k``'s noise generator seeded from the env's generator (one ``integers`` draw)."""
    arrays.rng[k] = rng.integers(0, 2**63, dtype=np.uint64)


# --------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------


@njit(cache=True)
def _sense_inner(inner, k, out):
    contract.sense(inner, k, out)


@njit(cache=True, _nrt=False)
def _advance_shop(plant, k, command):
    """One control period of shop-floor machine ``k``: the stages of the module docstring.

    Compiled on its own, without numba's reference counting, and called: inlined into the env's kernel (which
    counts references), every hook's copy of ``plant`` would count each of its arrays twice (atomic operations,
    ~20 ns per effect and period), more than this call costs."""
    effects = plant.effects
    memory = plant.memory
    applied = plant.applied[k]
    applied[0] = command[0]
    applied[1] = command[1]
    command_stage(effects, plant, k, applied)
    force = plant.force[k]
    force[0] = -0.0  # -0.0 - f is -f to the bit, and x + -0.0 is x: no force effect, no change
    force[1] = -0.0
    force_stage(effects, plant, k, force)
    for i in range(2):
        d = plant.gain[k, i] * force[i]
        memory[k, i, M_DISTURBANCE] = d
        applied[i] += d
    contract.advance(plant.inner, k, applied)
    sensed = plant.sensed[k]
    contract.sense(plant.inner, k, sensed)
    x = plant.table[k]
    for i in range(2):
        x[i, A_DRIVE] = sensed[contract.SENSE_POSITION + i]
        x[i, A_TABLE] = sensed[contract.SENSE_POSITION + i]
        x[i, A_TABLE_VELOCITY] = sensed[contract.SENSE_VELOCITY + i]
        x[i, A_READING] = sensed[contract.SENSE_MEASURED + i]
    table_stage(effects, plant, k, x)
    inv_dt = 1.0 / plant.dt
    for i in range(2):
        x_t = x[i, A_TABLE]
        memory[k, i, M_MEAN_VELOCITY] = (x_t - memory[k, i, M_TABLE]) * inv_dt
        memory[k, i, M_DRIVE] = x[i, A_DRIVE]
        memory[k, i, M_TABLE] = x_t
        memory[k, i, M_TABLE_VELOCITY] = x[i, A_TABLE_VELOCITY]
        x[i, A_READING_VELOCITY] = x[i, A_TABLE_VELOCITY]
    reading_stage(effects, plant, k, x)
    for i in range(2):
        memory[k, i, M_READING] = x[i, A_READING]
        memory[k, i, M_READING_VELOCITY] = x[i, A_READING_VELOCITY]


@njit(cache=True, _nrt=False)
def _sense_shop(plant, k, out):
    """What machine ``k``'s sensors give (``contract.sense``): the table, the reading, then the ``sense`` stage
    (compiled on its own, as :func:`_advance_shop`)."""
    for i in range(2):
        out[contract.SENSE_POSITION + i] = plant.memory[k, i, M_TABLE]
        out[contract.SENSE_MEASURED + i] = plant.memory[k, i, M_READING]
        out[contract.SENSE_VELOCITY + i] = plant.memory[k, i, M_READING_VELOCITY]
    sense_stage(plant.effects, plant, k, out)


@overload(contract.advance, inline="always", jit_options={"cache": True})
def _advance(plant, k, command):
    if contract.is_plant(plant, ShopFloorArrays):

        def impl(plant, k, command):
            _advance_shop(plant, k, command)

        return impl


@overload(contract.sense, inline="always", jit_options={"cache": True})
def _sense(plant, k, out):
    if contract.is_plant(plant, ShopFloorArrays):

        def impl(plant, k, out):
            _sense_shop(plant, k, out)

        return impl
