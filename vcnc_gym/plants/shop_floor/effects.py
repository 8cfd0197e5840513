"""The shop floor's effects, one :class:`~vcnc_gym.plants.shop_floor.effect.Effect` subclass each: the position sensor, the command
and sensor delays, the first structural mode, the cutting force and the Stribeck friction.

:data:`EFFECTS` are composed in this order by default; their parameters (:data:`EFFECT_PARAMETERS`) are appended to
the inner plant's in the same order, and :data:`OFF` switches every one off.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import contract
from ..contract import Parameter
from .effect import (
    A_DRIVE,
    A_READING,
    A_READING_VELOCITY,
    A_TABLE,
    A_TABLE_VELOCITY,
    M_DRIVE,
    M_MEAN_VELOCITY,
    M_READING,
    M_READING_VELOCITY,
    M_TABLE,
    M_TABLE_VELOCITY,
    MAX_DELAY,
    Effect,
)
from .noise import normal_pair

__all__ = [
    "EFFECTS",
    "EFFECT_PARAMETERS",
    "EFFECT_NAMES",
    "OFF",
    "PositionSensor",
    "CommandDelay",
    "SensorDelay",
    "StructuralMode",
    "CuttingForce",
    "StribeckFriction",
    "mode_response",
    "mode_transition",
]

#: Width of the Stribeck term's smooth sign, as a fraction of ``stribeck_velocity`` (ours).
STRIBECK_SIGN_WIDTH = 0.1

_ALTINTAS = "Altintas, Manufacturing Automation, 2nd ed. 2012"

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
