"""The machine as it is on the shop floor: any plant with a real sensor, delays, a structural mode and process forces.

:func:`shop_floor` wraps a plant of :mod:`vcnc_gym.plants` (its
:class:`~vcnc_gym.plants.contract.PlantModel`) into another plant: the same
drive, with the effects the source papers leave out, each with its units, a
physical default and its source, and each a :class:`Parameter` appended to
the inner plant's (so ``randomize`` draws them from their intervals, and
``vcnc-bench --plants`` samples them with the rest).  An effect whose
parameter is 0 is off; with every effect off the wrapped plant gives the
inner plant's observations to the bit (``tests/test_shop_floor.py``).  The
papers' ids do not use the wrapper at all.

Per control period ``dt`` of machine ``k`` (:func:`contract.advance`):

1. **Computation / transport delay** of ``command_delay`` whole control
   periods: the command applied is the one given ``d`` periods earlier (a
   FIFO of the last commands, zero before the first), the one-sample
   computation delay of a digital position loop and the drive's
   transmission delay (Altintas, *Manufacturing Automation*, 2nd ed. 2012,
   ch. 6: the ZOH and computation delay of a CNC's sampled loop).
2. **Process forces as an equivalent input disturbance**: a milling force
   against the direction of motion, a mean ``cutting_force`` plus a
   tooth-passing component ``cutting_ripple cos(phi)`` whose phase advances
   at the tooth-passing frequency ``spindle_speed teeth / 60`` Hz (Altintas
   2012, ch. 2: the periodic milling force at the tooth-passing frequency);
   and the **Stribeck effect** of the guideways, the excess of static over
   Coulomb friction decaying with speed,
   ``-stribeck_force exp(-(v / stribeck_velocity)^2) tanh(v / (0.1 stribeck_velocity))``
   (Armstrong-Helouvry, Dupont & Canudas de Wit 1994; the Coulomb level is
   the inner plant's own, the tanh a smooth sign, ours).  ``v`` is the
   table's mean velocity over the previous period.  The force, N per axis,
   enters as the input the plant declares equivalent
   (``PlantModel.force_gain``, input unit per N), added to the delayed
   command before the inner plant's amplifier saturation (so a saturated
   command also clips the disturbance: the disturbance of an amplifier
   model, not of a force on the table).
3. The inner plant advances (:func:`contract.advance` on its own arrays).
4. **First structural mode** between the drive and the table: the table
   follows the drive's position ``x_d`` (the inner plant's table position,
   rigid) through a spring and damper,
   ``x_t'' = w^2 (x_d - x_t) + 2 zeta w (x_d' - x_t')``, ``w = 2 pi
   mode_frequency``, ``zeta = mode_damping``; integrated exactly for a drive
   position that ramps linearly over the period (a first-order hold,
   ``control.c2d(M, dt, "foh")`` of ``M(s) = (2 zeta w s + w^2) / (s^2 + 2
   zeta w s + w^2)``, tested).  The table's reaction on the drive is
   neglected (the mode as the command-to-table response shows it: a
   resonance of the loop the position sensor closes on the table, which is
   what limits a feed drive's bandwidth; Erkorkmaz & Altintas 2001, Part II,
   and Altintas 2012, ch. 6, model the first axial mode of a ball-screw drive
   this way as a second-order lightly damped mode in series with the rigid
   body).  The contour error is measured on this table position.
5. **The position sensor** (replacing the inner plant's own, e.g. Purtojo
   et al.'s 1 um encoder, unless both its settings are 0): the table position plus white Gaussian noise of
   standard deviation ``noise_std`` (a per-machine splitmix64 generator,
   seeded from the env's generator at every reset:
   ``PlantModel.seed_machine``), quantised to ``encoder_resolution`` (the
   nearest count), and seen ``sensor_delay`` periods late.  With a noisy or
   quantised sensor the velocity the controller sees is the backward
   difference of two readings over ``dt`` (what a CNC's position loop
   computes); with a perfect one the table's velocity.

The observation therefore shows the quantised, noisy, delayed measurement;
the exact contour error (on the true table position) stays in ``info``.

The wrapped model keeps the inner plant's ``name`` (it is the same machine,
and every controller designed for that machine runs on it), its input, its
linear model, dead time and inverse dynamics (the *nominal* model a
controller is designed from: the effects are what the nominal model lacks);
``model.inner`` is the inner model and ``model.effects`` the settings.

Arrays
------
:data:`ShopFloorArrays`: ``inner`` (the inner plant's namedtuple; its
``params`` a view of the first P columns of ``params``), ``state`` (the
inner plant's state array itself, so a NaN written there diverges the
episode), ``params`` (N, 2, P + E), ``dt``, and the effects' per-machine
derived constants (set by ``reset_machine`` from ``params``) and memory.
"""

from __future__ import annotations

import inspect
import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit
from numba.extending import overload

from . import contract
from .contract import Parameter, PlantModel

__all__ = ["EFFECT_PARAMETERS", "EFFECT_NAMES", "MAX_DELAY", "ShopFloorArrays", "ShopFloorModel", "shop_floor",
           "mode_response", "splitmix64", "normal_pair"]

#: Longest delay, control periods (command or sensor): the FIFOs hold this many entries plus one.
MAX_DELAY = 8

#: The feedforward's Coulomb transition on the shop floor, s: the Stribeck friction spreads the reversal, which a
#: switch at the reversal itself does not model (Simba et al.'s drive: ff-ccc 166 um with 1 ms against 181 um with 0
#: on the shop-floor smoothed corners, ``python benchmarks/tune_servo.py --shop-floor``).
SHOP_FRICTION_TIME = 1e-3

#: Width of the Stribeck term's smooth sign, as a fraction of ``stribeck_velocity`` (ours).
STRIBECK_SIGN_WIDTH = 0.1

_ALTINTAS = "Altintas, Manufacturing Automation, 2nd ed. 2012"
_OURS = "ours"

#: The effects' parameters, appended to the inner plant's in this order.  Physical defaults are ours, each
#: within the range the cited source describes for machine-tool feed drives (see each ``source``).
EFFECT_PARAMETERS = (
    Parameter("encoder_resolution", "mm", nominal=(1e-4, 1e-4), interval=((5e-5, 2e-4), (5e-5, 2e-4)), shared=True,
              sign="nonnegative", source="the CNC increment system IS-C, 0.1 um (FANUC; IS-B is 1 um); 0: exact",
              description="position sensor's quantisation step (nearest count)",
              physical_range=(0.0, 0.01), range_source="ours: 10 um, a coarse rotary encoder on a 10 mm lead"),
    Parameter("noise_std", "mm", nominal=(5e-5, 5e-5), interval=((0.0, 1e-4), (0.0, 1e-4)), shared=True,
              sign="nonnegative",
              source="ours: a quarter of the +-0.2 um interpolation error of a 20 um grating (+-1 % of the signal "
                     "period, optical linear encoders' data sheets), as white noise; 0: none",
              description="standard deviation of the position reading's white Gaussian noise",
              physical_range=(0.0, 0.01), range_source="ours: 10 um, a noisy analogue transducer"),
    Parameter("command_delay", "periods", nominal=(1.0, 1.0), interval=((1.0, 2.0), (1.0, 2.0)), shared=True,
              sign="nonnegative",
              source=f"{_ALTINTAS}, ch. 6: one sample of computation delay; rounded to whole control periods",
              description="delay of the command, whole control periods (rounded)",
              physical_range=(0.0, float(MAX_DELAY)), range_source=f"the FIFO's length, MAX_DELAY = {MAX_DELAY}"),
    Parameter("sensor_delay", "periods", nominal=(0.0, 0.0), interval=((0.0, 1.0), (0.0, 1.0)), shared=True,
              sign="nonnegative",
              source="ours: a serial encoder's transmission, up to one period; rounded to whole control periods",
              description="delay of the position reading, whole control periods (rounded)",
              physical_range=(0.0, float(MAX_DELAY)), range_source=f"the FIFO's length, MAX_DELAY = {MAX_DELAY}"),
    Parameter("mode_frequency", "Hz", nominal=(150.0, 150.0), interval=((100.0, 200.0), (100.0, 200.0)),
              sign="nonnegative",
              source=f"ours, a ball-screw drive's first axial mode (Erkorkmaz & Altintas 2001, Part II; {_ALTINTAS}, "
                     "ch. 6); 0: rigid",
              description="natural frequency of the first structural mode between drive and table",
              physical_range=(0.0, 5000.0), range_source="ours: a direct drive's stiff table, kHz"),
    Parameter("mode_damping", "1", nominal=(0.05, 0.05), interval=((0.02, 0.1), (0.02, 0.1)), sign="nonnegative",
              source="ours: lightly damped structural modes, 2-10 % of critical", description="its damping ratio",
              physical_range=(0.0, 2.0), range_source="ours: beyond 1 the mode is overdamped"),
    Parameter("cutting_force", "N", nominal=(100.0, 100.0), interval=((50.0, 150.0), (50.0, 150.0)), shared=True,
              sign="nonnegative", source=f"ours: a light finishing cut ({_ALTINTAS}, ch. 2); 0: air cutting",
              description="mean cutting force against the direction of motion",
              physical_range=(0.0, 1e4), range_source="ours: 10 kN, heavy roughing"),
    Parameter("cutting_ripple", "N", nominal=(50.0, 50.0), interval=((25.0, 75.0), (25.0, 75.0)), shared=True,
              sign="nonnegative", source=f"ours: half the mean, the first tooth-passing harmonic ({_ALTINTAS}, ch. 2)",
              description="amplitude of the cutting force's tooth-passing component",
              physical_range=(0.0, 1e4), range_source="ours: 10 kN"),
    Parameter("spindle_speed", "rpm", nominal=(6000.0, 6000.0), interval=((5000.0, 7000.0), (5000.0, 7000.0)),
              shared=True, sign="nonnegative", source="ours: a machining centre's spindle",
              description="spindle speed", physical_range=(0.0, 1e5), range_source="ours: high-speed spindles"),
    Parameter("teeth", "1", nominal=(4.0, 4.0), shared=True, source="ours: a four-flute end mill",
              description="cutter teeth (the tooth-passing frequency is spindle_speed teeth / 60 Hz)",
              physical_range=(1.0, 64.0), range_source="ours: face mills have tens of inserts"),
    Parameter("stribeck_force", "N", nominal=(30.0, 30.0), interval=((15.0, 45.0), (15.0, 45.0)), sign="nonnegative",
              source="ours: excess of static over Coulomb friction of linear guides (Armstrong-Helouvry, Dupont & "
                     "Canudas de Wit 1994); 0: none",
              description="Stribeck friction at rest beyond the inner plant's Coulomb level",
              physical_range=(0.0, 1e4), range_source="ours: 10 kN, a heavy gantry's guides"),
    Parameter("stribeck_velocity", "mm/s", nominal=(1.0, 1.0), interval=((0.5, 2.0), (0.5, 2.0)),
              source="ours: Stribeck velocities of lubricated guides, 0.1-100 mm/s (Armstrong-Helouvry et al. 1994)",
              description="speed over which the Stribeck friction decays",
              physical_range=(1e-3, 1e3), range_source="Armstrong-Helouvry et al. 1994's span, widened"),
)
EFFECT_NAMES = tuple(p.name for p in EFFECT_PARAMETERS)
(E_RESOLUTION, E_NOISE, E_COMMAND_DELAY, E_SENSOR_DELAY, E_MODE_FREQUENCY, E_MODE_DAMPING, E_CUTTING_FORCE,
 E_CUTTING_RIPPLE, E_SPINDLE_SPEED, E_TEETH, E_STRIBECK_FORCE, E_STRIBECK_VELOCITY) = range(len(EFFECT_NAMES))

#: Every effect off: the wrapped plant is the inner one (bit-identical observations).
OFF = {"encoder_resolution": 0.0, "noise_std": 0.0, "command_delay": 0.0, "sensor_delay": 0.0,
       "mode_frequency": 0.0, "cutting_force": 0.0, "cutting_ripple": 0.0, "stribeck_force": 0.0}

#: Columns of ``ShopFloorArrays.derived`` (N, 2, D): per machine and axis, from the parameters at reset.
D_GAIN = 0  # input per N (the plant's force_gain)
D_PHI = 1  # the mode's transition matrix over dt (4 entries, row-major), for the deviation e = x_t - x_d
D_PHASE_STEP = 5  # tooth-passing phase advance per period, rad
D_SIZE = 6

#: Columns of ``ShopFloorArrays.memory`` (N, 2, M): per machine and axis.
M_DRIVE = 0  # the drive's (inner plant's) table position at the end of the last period, mm
M_TABLE = 1  # the table position, mm
M_TABLE_VELOCITY = 2  # the table velocity, mm/s
M_MEAN_VELOCITY = 3  # the table's mean velocity over the last period, mm/s
M_DISTURBANCE = 4  # the input disturbance of the last period, input units
M_SIZE = 5

#: The arrays of N shop-floor machines (the contract's plant namedtuple): ``inner`` (the inner plant's arrays),
#: ``state`` (= ``inner.state``), ``params`` (N, 2, P + E), ``dt`` (s), ``n_inner`` (P), ``delays`` (N, 3) int64
#: (command, sensor delay in periods; 1 if a process force acts), ``derived`` (N, 2, D_SIZE), ``memory`` (N, 2, M_SIZE), ``commands`` (N,
#: MAX_DELAY + 1, 2) and ``readings`` (N, MAX_DELAY + 1, 4) (position x, y and velocity x, y as read) ring
#: buffers, ``heads`` (N,) int64 (their write position), ``rng`` (N,) uint64 (the noise generators' states),
#: ``phase`` (N,) rad, scratch ``applied`` (N, 2) and ``sensed`` (N, SENSE_SIZE).
ShopFloorArrays = namedtuple("ShopFloorArrays", [
    "inner", "state", "params", "dt", "n_inner", "delays", "derived", "memory", "commands", "readings", "heads",
    "rng", "phase", "applied", "sensed"])


@dataclass(frozen=True, eq=False)
class ShopFloorModel(PlantModel):
    """A :class:`PlantModel` wrapped by :func:`shop_floor`; ``inner`` the wrapped model."""

    inner: PlantModel | None = None


#: The effects counted in whole numbers: their settings must be whole numbers (``command_delay=1`` or 1.0; not 1.5
#: or True).
COUNTS = ("command_delay", "sensor_delay", "teeth")


def _setting(p: Parameter, value) -> tuple:
    """The (x, y) pair of a shop-floor setting, each through :mod:`vcnc_gym.validation` (a count an integer)."""
    from ..validation import integer, per_axis

    name = f"shop-floor setting {p.name}"
    if p.name in COUNTS:
        items = value if isinstance(value, (tuple, list)) else (value, value)
        if len(items) != 2:
            raise ValueError(f"{name} must be an integer or an (x, y) pair of them ({p.unit}), got {value!r}")
        whole = [int(v) if isinstance(v, float) and v.is_integer() else v for v in items]  # 4.0 (YAML) is 4
        return tuple(float(integer(f"{name} ({p.unit})", v, minimum=0)) for v in whole)
    return tuple(float(v) for v in per_axis(name, value, p.unit))


def shop_floor(plant, settings: dict | bool | None = True) -> ShopFloorModel:
    """The plant ``plant`` (a name of :mod:`vcnc_gym.plants` or a PlantModel) on the shop floor.

    Parameters
    ----------
    plant : str or PlantModel
    settings : dict or True
        Nominal values of effect parameters, ``{name: value}`` (one value for
        both axes, or a pair (x, y)), over the defaults of
        :data:`EFFECT_PARAMETERS`; a parameter set outside its interval
        keeps the default's relative spread around it (0, off, is fixed).
        True: the defaults.

    Raises
    ------
    ValueError
        For an unknown setting (the message lists the effects), a value the
        parameter's rules refuse, or cutting or Stribeck forces on a plant
        that declares no ``force_gain``.
    """
    from . import get_plant

    inner = get_plant(plant)
    if isinstance(inner, ShopFloorModel):
        raise ValueError(f"plant {inner.name!r} is already on the shop floor")
    if settings is True or settings is None:
        settings = {}
    if not isinstance(settings, dict):
        raise ValueError(f"shop_floor settings must be a dict {{effect parameter: value}} or True, got {settings!r}")
    unknown = sorted(set(settings) - set(EFFECT_NAMES))
    if unknown:
        raise ValueError(f"unknown shop-floor setting(s) {unknown}; the effects' parameters are {list(EFFECT_NAMES)}")
    effects = []
    for p in EFFECT_PARAMETERS:
        if p.name in settings:
            value = settings[p.name]
            pair = _setting(p, value)
            if p.physical_range is not None and not all(p.physical_range[0] <= v <= p.physical_range[1]
                                                        for v in pair):
                raise ValueError(f"shop-floor setting {p.name} = {value!r} {p.unit} is outside its physical range "
                                 f"[{p.physical_range[0]:g}, {p.physical_range[1]:g}] ({p.range_source})")
            interval = p.interval
            if interval is not None and not all(lo <= v <= hi for v, (lo, hi) in zip(pair, interval)):
                # the default's relative spread around the new value; none around 0 (off) or a default of 0
                # (within the physical range)
                top = math.inf if p.physical_range is None else p.physical_range[1]
                interval = (None if min(pair) <= 0 or min(p.nominal) <= 0 else
                            tuple((v * lo / n, min(v * hi / n, max(v, top)))
                                  for v, n, (lo, hi) in zip(pair, p.nominal, interval)))
            p = Parameter(p.name, p.unit, nominal=pair, interval=interval,
                          shared=p.shared, source=p.source, sign=p.sign, description=p.description,
                          physical_range=p.physical_range, range_source=p.range_source)
        effects.append(p)
    effects = tuple(effects)
    forces = [p for p in effects if p.name in ("cutting_force", "cutting_ripple", "stribeck_force")
              and (max(p.nominal) > 0 or (p.interval is not None and max(hi for _, hi in p.interval) > 0))]
    if forces and inner.force_gain is None:
        raise ValueError(f"plant {inner.name} declares no force_gain (input per N): the effects "
                         f"{[p.name for p in forces]} cannot act on it; set them to 0")
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
        parameters=inner.parameters + effects,
        state_names=inner.state_names,
        input_name=inner.input_name,
        input_unit=inner.input_unit,
        input_limit=inner.input_limit,
        make_arrays=make_arrays,
        reset_machine=lambda arrays, k, position: _reset_machine(model, arrays, k, position),
        check=check,
        linear_coefficients=(None if inner.linear_coefficients is None else
                             lambda params, axis: inner.linear_coefficients(inner_part(params), axis)),
        delay=None if inner.delay is None else lambda params, axis: inner.delay(inner_part(params), axis),
        inverse_dynamics=(None if inner.inverse_dynamics is None else
                          lambda params: inner.inverse_dynamics(inner_part(params))),
        force_gain=None if inner.force_gain is None else lambda params: inner.force_gain(inner_part(params)),
        seed_machine=_seed_machine,
        servo_bandwidth=inner.servo_bandwidth,
        friction_time=SHOP_FRICTION_TIME,
        path_limits=inner.path_limits,
        random_contour=dict(inner.random_contour),
        inner=inner,
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
    out = ShopFloorArrays(
        inner=arrays, state=arrays.state, params=params, dt=float(dt), n_inner=P,
        delays=np.zeros((n, 3), dtype=np.int64), derived=np.zeros((n, 2, D_SIZE)), memory=np.zeros((n, 2, M_SIZE)),
        commands=np.zeros((n, MAX_DELAY + 1, 2)), readings=np.zeros((n, MAX_DELAY + 1, 4)),
        heads=np.zeros(n, dtype=np.int64), rng=np.zeros(n, dtype=np.uint64), phase=np.zeros(n),
        applied=np.zeros((n, 2)), sensed=np.zeros((n, contract.SENSE_SIZE)))
    for k in range(n):
        _reset_machine(model, out, k, np.zeros(2))
    return out


def mode_transition(frequency: float, damping: float, dt: float) -> np.ndarray:
    """Transition matrix over ``dt`` s of ``e'' = -w^2 e - 2 zeta w e'`` (w = 2 pi ``frequency``), (2, 2), exact
    (the matrix exponential of [[0, 1], [-w^2, -2 zeta w]] dt)."""
    w = 2.0 * math.pi * frequency
    a = np.array([[0.0, 1.0], [-w * w, -2.0 * damping * w]])
    from scipy.linalg import expm

    return expm(a * dt)


def _reset_machine(model: ShopFloorModel, arrays: ShopFloorArrays, k: int, position) -> None:
    """Machine ``k`` at rest at ``position`` (2,) mm: the inner plant reset, the FIFOs emptied (no command yet,
    every reading the rest position), the table on the drive, the cutter at phase 0, the noise generator at
    seed ``k`` (the envs then draw it from their generator: ``seed_machine``); the effects' constants derived
    from ``arrays.params[k]``."""
    inner = model.inner
    P = arrays.n_inner
    model.inner.reset_machine(arrays.inner, k, position)
    e = arrays.params[k, :, P:]
    gain = inner.force_gain(arrays.params[k, :, :P]) if inner.force_gain is not None else np.zeros(2)
    arrays.delays[k, 0] = int(math.floor(e[0, E_COMMAND_DELAY] + 0.5))
    arrays.delays[k, 1] = int(math.floor(e[0, E_SENSOR_DELAY] + 0.5))
    arrays.delays[k, 2] = int(max(e[0, E_CUTTING_FORCE], e[0, E_CUTTING_RIPPLE], *e[:, E_STRIBECK_FORCE]) > 0.0)
    for i in range(2):
        arrays.derived[k, i, D_GAIN] = gain[i]
        f = e[i, E_MODE_FREQUENCY]
        phi = mode_transition(f, e[i, E_MODE_DAMPING], arrays.dt) if f > 0 else np.eye(2)
        arrays.derived[k, i, D_PHI:D_PHI + 4] = phi.ravel()
        arrays.derived[k, i, D_PHASE_STEP] = 2.0 * math.pi * e[0, E_SPINDLE_SPEED] * e[0, E_TEETH] / 60.0 * arrays.dt
    sensed = arrays.sensed[k]
    _sense_inner(arrays.inner, k, sensed)
    arrays.memory[k] = 0.0
    arrays.memory[k, :, M_DRIVE] = sensed[contract.SENSE_POSITION:contract.SENSE_POSITION + 2]
    arrays.memory[k, :, M_TABLE] = sensed[contract.SENSE_POSITION:contract.SENSE_POSITION + 2]
    arrays.commands[k] = 0.0
    arrays.readings[k, :, 0:2] = sensed[contract.SENSE_MEASURED:contract.SENSE_MEASURED + 2]
    arrays.readings[k, :, 2:4] = sensed[contract.SENSE_VELOCITY:contract.SENSE_VELOCITY + 2]
    if e[0, E_RESOLUTION] > 0.0 or e[0, E_NOISE] > 0.0:  # this sensor, at rest: the true position's count
        r = e[0, E_RESOLUTION]
        x = sensed[contract.SENSE_POSITION:contract.SENSE_POSITION + 2]
        arrays.readings[k, :, 0:2] = r * np.floor(x / r + 0.5) if r > 0.0 else x
        arrays.readings[k, :, 2:4] = 0.0
    arrays.heads[k] = 0
    arrays.rng[k] = np.uint64(k)
    arrays.phase[k] = 0.0


def _seed_machine(arrays: ShopFloorArrays, k: int, rng: np.random.Generator) -> None:
    """Machine ``k``'s noise generator seeded from the env's generator (one ``integers`` draw)."""
    arrays.rng[k] = rng.integers(0, 2**63, dtype=np.uint64)


# --------------------------------------------------------------------------
# Kernels
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
    u1 = float((splitmix64(rng, k) >> _S11) + _ONE) * 2.0 ** -53
    u2 = float((splitmix64(rng, k) >> _S11) + _ONE) * 2.0 ** -53
    r = math.sqrt(-2.0 * math.log(u1))
    t = 2.0 * math.pi * u2
    return r * math.cos(t), r * math.sin(t)


@njit(cache=True)
def _sense_inner(inner, k, out):
    contract.sense(inner, k, out)


@njit(cache=True, _nrt=False, inline="always")
def _advance_shop(plant, k, command):
    """One control period of shop-floor machine ``k`` (module docstring, steps 1-5)."""
    P = plant.n_inner
    params = plant.params
    dt = plant.dt
    inv_dt = 1.0 / dt
    L = MAX_DELAY + 1
    head = plant.heads[k]
    memory = plant.memory
    applied = plant.applied[k]
    # 1. the command FIFO
    plant.commands[k, head, 0] = command[0]
    plant.commands[k, head, 1] = command[1]
    slot = head - plant.delays[k, 0]  # the ring's index arithmetic without a modulo (a division)
    if slot < 0:
        slot += L
    applied[0] = plant.commands[k, slot, 0]
    applied[1] = plant.commands[k, slot, 1]
    # 2. process forces, N, as input
    if plant.delays[k, 2]:
        f_cut = params[k, 0, P + E_CUTTING_FORCE]
        f_rip = params[k, 0, P + E_CUTTING_RIPPLE]
        speed = math.hypot(memory[k, 0, M_MEAN_VELOCITY], memory[k, 1, M_MEAN_VELOCITY])
        cutting = 0.0
        if (f_cut > 0.0 or f_rip > 0.0) and speed > 0.0:
            cutting = (f_cut + f_rip * math.cos(plant.phase[k])) / speed
        plant.phase[k] += plant.derived[k, 0, D_PHASE_STEP]
        for i in range(2):
            v = memory[k, i, M_MEAN_VELOCITY]
            force = -cutting * v
            s = params[k, i, P + E_STRIBECK_FORCE]
            if s > 0.0:
                vs = params[k, i, P + E_STRIBECK_VELOCITY]
                force -= s * math.exp(-(v / vs) ** 2) * math.tanh(v / (STRIBECK_SIGN_WIDTH * vs))
            d = plant.derived[k, i, D_GAIN] * force
            memory[k, i, M_DISTURBANCE] = d
            applied[i] += d
    # 3. the drive
    contract.advance(plant.inner, k, applied)
    sensed = plant.sensed[k]
    contract.sense(plant.inner, k, sensed)
    # 4. the structural mode; 5. the sensor
    head += 1
    if head == L:
        head = 0
    plant.heads[k] = head
    r = params[k, 0, P + E_RESOLUTION]
    sigma = params[k, 0, P + E_NOISE]
    perfect = r == 0.0 and sigma == 0.0
    n0 = 0.0
    n1 = 0.0
    if sigma > 0.0:
        n0, n1 = normal_pair(plant.rng, k)
    previous = head - 1 if head > 0 else L - 1
    for i in range(2):
        x_d = sensed[contract.SENSE_POSITION + i]
        x_d0 = memory[k, i, M_DRIVE]
        x_t0 = memory[k, i, M_TABLE]
        if params[k, i, P + E_MODE_FREQUENCY] > 0.0:
            slope = (x_d - x_d0) / dt
            e = x_t0 - x_d0
            de = memory[k, i, M_TABLE_VELOCITY] - slope
            phi = plant.derived[k, i]
            e1 = phi[D_PHI] * e + phi[D_PHI + 1] * de
            de1 = phi[D_PHI + 2] * e + phi[D_PHI + 3] * de
            x_t = x_d + e1
            v_t = slope + de1
            reading = sensed[contract.SENSE_MEASURED + i] + e1
        else:
            x_t = x_d
            v_t = sensed[contract.SENSE_VELOCITY + i]
            reading = sensed[contract.SENSE_MEASURED + i]
        memory[k, i, M_MEAN_VELOCITY] = (x_t - x_t0) * inv_dt
        memory[k, i, M_DRIVE] = x_d
        memory[k, i, M_TABLE] = x_t
        memory[k, i, M_TABLE_VELOCITY] = v_t
        if not perfect:  # this sensor replaces the plant's own
            reading = x_t
            if sigma > 0.0:
                reading += sigma * (n0 if i == 0 else n1)
            if r > 0.0:
                reading = r * math.floor(reading / r + 0.5)
            v_t = (reading - plant.readings[k, previous, i]) / dt
        plant.readings[k, head, i] = reading
        plant.readings[k, head, 2 + i] = v_t


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
            slot = plant.heads[k] - plant.delays[k, 1]
            if slot < 0:
                slot += MAX_DELAY + 1
            for i in range(2):
                out[contract.SENSE_POSITION + i] = plant.memory[k, i, M_TABLE]
                out[contract.SENSE_MEASURED + i] = plant.readings[k, slot, i]
                out[contract.SENSE_VELOCITY + i] = plant.readings[k, slot, 2 + i]
        return impl


def mode_response(frequency: float, damping: float):
    """The structural mode's drive-to-table transfer function ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``
    as a python-control object (w = 2 pi ``frequency`` rad/s)."""
    import control

    w = 2.0 * math.pi * frequency
    return control.tf([2.0 * damping * w, w * w], [1.0, 2.0 * damping * w, w * w])
