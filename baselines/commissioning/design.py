"""Design rules from an identified axis: the loop's bandwidth from its margins, a notch at the mode, the velocity
filter, the feedforward's model; written once for every plant.

The loop analysed is the servo law of :mod:`vcnc_baselines.servo` as it runs, per axis, in discrete time at the
control period ``T`` (:func:`loop_response`):

.. math::

    L(z) = N(z) \\Big(K_p + K_i \\frac{T z^{-1}}{1 - z^{-1}} + K_d F(z) \\frac{1 - z^{-1}}{T}\\Big) P(z)

with ``P`` the identified axis (:class:`~vcnc_baselines.commissioning.identify.AxisModel`: rigid body, first mode,
dead time) under zero-order hold, ``F(z) = (1 - a) / (1 - a z^{-1})`` the velocity low-pass, ``N`` the notch.
The PID gains are the pole placement of :func:`pid_gains` (a triple closed-loop pole at the
bandwidth ``w_b`` on the identified ``m s^2 + c s``).  The rules (:func:`design_axis`):

- **velocity filter**: where the sensor is quantised or noisy (the experiment measured velocity noise above
  ``EXACT_VELOCITY_NOISE``), a first-order low-pass of the count difference with cutoff ``w_v = r w_b``
  (``r`` of ``VELOCITY_FILTER_RATIOS``, at most a third of the Nyquist frequency); with an exact sensor none;
- **notch**: at the identified mode (where one was found), ``(s^2 + w_m^2) / (s^2 + (w_m / Q) s + w_m^2)``
  discretised with its band prewarped (:func:`notch_coefficients`, the coefficients of :func:`scipy.signal.iirnotch`),
  ``Q`` of ``NOTCH_QS``;
- **bandwidth**: the largest ``w_b`` of a geometric grid up to the ``ceiling`` at which the closed loop is
  stable, its gain crossover is at most ``MODE_FRACTION`` of the mode, and it meets phase margin >=
  ``PHASE_MARGIN`` deg, gain margin >= ``GAIN_MARGIN`` dB and sensitivity peak <= ``SENSITIVITY_PEAK`` dB (every
  crossing on a dense frequency grid, :func:`margins`);
- **feedforward**: the identified inverse with the mode in it (the drive must run ahead of the table by the
  mode's inverse ``1 + s^2 / w_m^2``, to second order: :func:`inverse_dynamics`), or a ZV / ZVD input shaper
  (Singer & Seering 1990) at the identified mode (:func:`shaper`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vcnc_gym.plants.contract import INVERSE_ORDER, InverseDynamics
from .identify import AxisModel

__all__ = [
    "NO_NOTCH",
    "pid_gains",
    "PHASE_MARGIN",
    "GAIN_MARGIN",
    "SENSITIVITY_PEAK",
    "MODE_FRACTION",
    "NOTCH_QS",
    "VELOCITY_FILTER_RATIOS",
    "AxisDesign",
    "Margins",
    "notch_coefficients",
    "loop_response",
    "margins",
    "design_axis",
    "inverse_dynamics",
    "shaper",
    "discrete_plant",
    "loop_tf",
    "closed_loop_poles",
]

#: The coefficients of a notch (b0, b1, b2, a1, a2 of ``(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)``) that
#: passes its input unchanged: no notch.
NO_NOTCH = (1.0, 0.0, 0.0, 0.0, 0.0)


def pid_gains(mass, damping, bandwidth, integral: bool = True):
    """Pole placement on the nominal axis ``m s^2 + c s`` (input unit per mm/s^2 and mm/s).

    PID: the closed loop ``m s^3 + (c + K_d) s^2 + K_p s + K_i`` with a triple pole at ``-bandwidth``:
    ``K_d = 3 m w - c``, ``K_p = 3 m w^2``, ``K_i = m w^3``.  PD (``integral=False``): a double pole,
    ``K_d = 2 m w - c``, ``K_p = m w^2``, ``K_i = 0``.  ``K_d`` is floored at 0 (a plant damped beyond the
    bandwidth needs no damping).

    Returns
    -------
    (kp, kd, ki) : ndarrays, (2,)
    """
    m, c, w = (np.asarray(v, dtype=np.float64) for v in (mass, damping, bandwidth))
    if integral:
        return 3.0 * m * w**2, np.maximum(3.0 * m * w - c, 0.0), m * w**3
    return m * w**2, np.maximum(2.0 * m * w - c, 0.0), np.zeros_like(m * w)


#: Minimum phase margin, deg.
PHASE_MARGIN = 45.0
#: Minimum gain margin, dB.
GAIN_MARGIN = 6.0
#: Maximum sensitivity peak (the largest magnitude of 1 / (1 + L)), dB.
SENSITIVITY_PEAK = 6.0
#: The bandwidth is at most this fraction of the first mode (servo tuners' half of the first resonance).
MODE_FRACTION = 0.5
#: Quality factors the rule tries for the notch (its -3 dB width is w_m / Q), the narrowest first.
NOTCH_QS = (4.0, 2.0, 1.0)
#: The velocity filter's cutoffs the rule tries, in bandwidths, the lowest (least noise) first.
VELOCITY_FILTER_RATIOS = (10.0, 20.0, 40.0)
#: Velocity noise (mm/s, standard deviation of the count difference) below which the sensor counts as exact.
EXACT_VELOCITY_NOISE = 1e-2


@dataclass(frozen=True)
class Margins:
    """Stability margins of a loop: gain margin (dB, inf without a phase crossover), phase margin (deg), the
    sensitivity peak (dB), the gain crossover frequency (rad/s)."""

    gain_db: float
    phase_deg: float
    sensitivity_db: float
    crossover: float

    def meets(self) -> bool:
        """True if the rules' bounds hold."""
        return (
            self.gain_db >= GAIN_MARGIN and self.phase_deg >= PHASE_MARGIN and self.sensitivity_db <= SENSITIVITY_PEAK
        )


@dataclass(frozen=True)
class AxisDesign:
    """One axis' design: bandwidth (rad/s), PID gains (input unit per mm, per mm/s, per mm s), the velocity
    filter's cutoff (rad/s, 0: none) and pole, the notch (frequency Hz, 0: none; Q; coefficients), the margins."""

    bandwidth: float
    kp: float
    kd: float
    ki: float
    velocity_cutoff: float
    velocity_pole: float
    notch_frequency: float
    notch_q: float
    notch: tuple
    margins: Margins


def notch_coefficients(frequency_hz: float, q: float, dt: float) -> tuple:
    """``(b0, b1, b2, a1, a2)`` of a second-order digital notch at ``w0 = 2 pi frequency_hz dt`` rad/sample whose
    -3 dB band is ``w0 / Q`` wide: ``g (1 - 2 cos(w0) z^-1 + z^-2) / (1 - 2 g cos(w0) z^-1 + (2 g - 1) z^-2)``,
    ``g = 1 / (1 + tan(w0 / (2 Q)))`` (the bilinear transform of ``(s^2 + w^2) / (s^2 + (w / Q) s + w^2)`` with
    its band edges prewarped; Orfanidis, *Introduction to Signal Processing*, 1996, sec. 11.3): unit gain at 0 and
    Nyquist, zero at ``w0``.  ``frequency_hz <= 0``: no notch."""
    if frequency_hz <= 0.0:
        return NO_NOTCH
    w0 = 2.0 * math.pi * frequency_hz * dt
    if w0 >= math.pi:
        raise ValueError(f"notch frequency {frequency_hz} Hz is at or beyond the Nyquist frequency {0.5 / dt} Hz")
    g = 1.0 / (1.0 + math.tan(w0 / (2.0 * q)))
    return (g, -2.0 * g * math.cos(w0), g, -2.0 * g * math.cos(w0), 2.0 * g - 1.0)


def discrete_plant(model: AxisModel, dt: float, omega: np.ndarray) -> np.ndarray:
    """The identified axis from command to measured position under zero-order hold, at ``omega`` rad/s: the
    continuous response times the hold's ``sinc`` gain (its half-period lag is in the fitted dead time), complex,
    mm per input unit."""
    from .identify import model_response

    f = omega / (2 * np.pi)
    return model_response(model, f) * np.sinc(f * dt)


def loop_response(model: AxisModel, dt: float, omega, kp, kd, ki, pole=0.0, notch=NO_NOTCH) -> np.ndarray:
    """``L(e^{j w T})`` of the module docstring at ``omega`` rad/s."""
    z1 = np.exp(-1j * np.asarray(omega) * dt)  # z^-1
    F = (1.0 - pole) / (1.0 - pole * z1)
    b0, b1, b2, a1, a2 = notch
    N = (b0 + b1 * z1 + b2 * z1**2) / (1.0 + a1 * z1 + a2 * z1**2)
    C = kp + ki * dt * z1 / (1.0 - z1) + kd * F * (1.0 - z1) / dt
    return N * C * discrete_plant(model, dt, np.asarray(omega))


def margins(L: np.ndarray, omega: np.ndarray) -> Margins:
    """Gain and phase margins and the sensitivity peak of a loop sampled at ``omega`` (rad/s, increasing), with
    the crossings interpolated between grid points.

    The phase margin is the smallest over every gain crossover (a resonance can cross 0 dB more than once) of
    ``180 deg - |phase|``, the phase wrapped to (-180, 180].  The gain margin is the smallest over every
    -180 deg crossing of ``|20 log10 |L||``: the gain increase to instability where ``|L| < 1`` there, the
    reduction where ``|L| > 1`` (a PID around a double integrator crosses -180 deg below its crossover: a
    conditionally stable loop).  Stability itself is :func:`closed_loop_poles`'."""
    mag = np.maximum(np.abs(L), 1e-300)  # a notch's zero may fall on a grid point
    phase = np.unwrap(np.angle(L))
    pm = math.inf
    crossover = math.nan
    for i in np.flatnonzero(np.diff(np.sign(mag - 1.0)) != 0):
        t = (1.0 - mag[i]) / (mag[i + 1] - mag[i])
        ph = math.degrees(phase[i] + t * (phase[i + 1] - phase[i]))
        wrapped = (ph + 180.0) % 360.0 - 180.0
        margin = 180.0 - abs(wrapped)
        if margin < pm:
            pm, crossover = margin, omega[i] + t * (omega[i + 1] - omega[i])
    gm = math.inf
    shifted = (phase + np.pi) / (2 * np.pi)  # crossings of -180 deg (mod 360) are integer crossings of this
    for i in np.flatnonzero(np.floor(shifted[1:]) != np.floor(shifted[:-1])):
        level = np.floor(max(shifted[i], shifted[i + 1]))
        t = (level - shifted[i]) / (shifted[i + 1] - shifted[i])
        g = math.exp(math.log(mag[i]) + t * (math.log(mag[i + 1]) - math.log(mag[i])))
        gm = min(gm, abs(20.0 * math.log10(g)))
    ms = 20.0 * math.log10(float(np.max(1.0 / np.abs(1.0 + L))))
    return Margins(float(gm), float(pm), ms, float(crossover))


def loop_tf(model: AxisModel, dt: float, kp, kd, ki, pole=0.0, notch=NO_NOTCH):
    """The loop ``L(z)`` as a python-control discrete transfer function: the identified axis (rigid body and
    mode, ``control.c2d`` with a zero-order hold) with its whole periods of delay ``round(delay / dt - 1/2)``,
    the PID with its velocity filter, the notch."""
    import control

    m, c = model.mass, model.damping
    plant = control.tf([1.0], [m, c, 0.0])
    if model.mode_frequency > 0:
        w = 2 * math.pi * model.mode_frequency
        z = model.mode_damping
        plant = plant * control.tf([2 * z * w, w * w], [1.0, 2 * z * w, w * w])
    d = int(max(0, round(model.delay / dt - 0.5)))
    P = control.c2d(plant, dt, "zoh") * control.tf([1.0], [1.0] + [0.0] * d, dt)
    zi = control.tf([1.0], [1.0, 0.0], dt)  # z^-1
    one = control.tf([1.0], [1.0], dt)
    C = kp * one + ki * dt * zi / (one - zi) + kd * ((1.0 - pole) / (one - pole * zi)) * (one - zi) / dt
    b0, b1, b2, a1, a2 = notch
    N = control.tf([b0, b1, b2], [1.0, a1, a2], dt)
    return control.minreal(N * C * P, verbose=False)


def closed_loop_poles(L) -> np.ndarray:
    """The poles of ``L / (1 + L)`` (a discrete loop from :func:`loop_tf`)."""
    import control

    return control.poles(control.feedback(L, 1))


def _grid(dt: float) -> np.ndarray:
    return np.logspace(-1, math.log10(0.999 * math.pi / dt), 4000)


def design_axis(model: AxisModel, dt: float, velocity_noise: float, ceiling: float) -> AxisDesign:
    """The rules of the module docstring for one identified axis.

    Parameters
    ----------
    model : AxisModel
    dt : float
        Control period, s.
    velocity_noise : float
        Standard deviation of the measured velocity's noise (mm/s) the experiment saw.
    ceiling : float
        Bandwidth above which the rule does not search, rad/s (the plant's declared servo-rate limit).

    Notes
    -----
    From the highest bandwidth of a geometric grid down (a coarse grid over three decades below the ceiling,
    then a fine one above its first success), the first at which some velocity-filter ratio of
    :data:`VELOCITY_FILTER_RATIOS` and notch quality of :data:`NOTCH_QS` (the lowest cutoff and then the
    narrowest notch first) gives a closed loop that is stable (:func:`closed_loop_poles`), meets the margins and
    crosses over below :data:`MODE_FRACTION` of the mode.
    """
    omega = _grid(dt)
    has_mode = model.mode_frequency > 0.0
    w_mode = 2 * math.pi * model.mode_frequency
    filtered = velocity_noise > EXACT_VELOCITY_NOISE
    ratios = VELOCITY_FILTER_RATIOS if filtered else (0.0,)
    qs = NOTCH_QS if has_mode else (0.0,)

    def attempt(w):
        kp, kd, ki = (float(v) for v in pid_gains(model.mass, model.damping, w))
        for ratio in ratios:
            cutoff = min(ratio * w, math.pi / (3 * dt)) if filtered else 0.0
            pole = math.exp(-cutoff * dt) if filtered else 0.0
            for q in qs:
                notch = notch_coefficients(model.mode_frequency, q, dt) if has_mode else NO_NOTCH
                m = margins(loop_response(model, dt, omega, kp, kd, ki, pole, notch), omega)
                if not m.meets() or (has_mode and m.crossover > MODE_FRACTION * w_mode):
                    continue
                if np.all(np.abs(closed_loop_poles(loop_tf(model, dt, kp, kd, ki, pole, notch))) < 1.0):
                    return AxisDesign(
                        float(w),
                        kp,
                        kd,
                        ki,
                        float(cutoff),
                        float(pole),
                        model.mode_frequency if has_mode else 0.0,
                        float(q),
                        tuple(notch),
                        m,
                    )
        return None

    # down a coarse geometric grid (3 decades, 31 points) to the first bandwidth that passes, then down a fine
    # one (30 points) from the coarse point above it
    coarse = np.geomspace(ceiling / 1000.0, ceiling, 31)[::-1]
    for i, w in enumerate(coarse):
        found = attempt(w)
        if found is not None:
            if i == 0:
                return found
            for w_fine in np.geomspace(w, coarse[i - 1], 31)[-2:0:-1]:
                better = attempt(w_fine)
                if better is not None:
                    return better
            return found
    raise ValueError(f"no bandwidth up to {ceiling:g} rad/s meets the margins on the identified axis {model}")


def inverse_dynamics(models, backlash, with_mode: bool = True) -> InverseDynamics:
    """The identified axes' inverse dynamics (per axis ``c_1 = c`` (the reversal legs' viscous coefficient), ``c_2 = m``, and with the mode
    ``c_3 = c / w_m^2``, ``c_4 = m / w_m^2``: ``(m s^2 + c s)(1 + s^2 / w_m^2)``, the mode's inverse
    ``(s^2 + 2 zeta w s + w^2) / (2 zeta w s + w^2)`` to second order), the identified Coulomb levels and Stribeck curve,
    the given backlash (mm) and the dead time of the command's whole delay periods."""
    rows, coulomb, delay, stribeck = [], [], [], []
    for a in models:
        row = np.zeros(INVERSE_ORDER)
        c = a.viscous if a.viscous > 0.0 else a.damping  # the steady state's, where the legs measured it
        row[0], row[1] = c, a.mass
        if with_mode and a.mode_frequency > 0.0:
            w2 = (2 * math.pi * a.mode_frequency) ** 2
            row[2], row[3] = c / w2, a.mass / w2
        rows.append(row)
        coulomb.append((max(a.coulomb[0], 0.0), min(a.coulomb[1], 0.0)))
        delay.append(a.command_delay)
        stribeck.append(tuple(a.stribeck) if a.stribeck[0] > 0.0 else (0.0, 0.0))
    return InverseDynamics(
        np.array(rows), np.array(coulomb), np.asarray(backlash, dtype=np.float64), np.array(delay), np.array(stribeck)
    )


def shaper(model: AxisModel, kind: str = "zv") -> tuple[np.ndarray, np.ndarray]:
    """The ZV or ZVD input shaper (Singer & Seering 1990) of the identified mode: impulse times (s) and
    amplitudes (summing to 1).  ``K = exp(-zeta pi / sqrt(1 - zeta^2))``, half damped period
    ``t_2 = pi / (w sqrt(1 - zeta^2))``; ZV: ``(1, K) / (1 + K)`` at ``(0, t_2)``; ZVD: ``(1, 2K, K^2) / (1 + K)^2``
    at ``(0, t_2, 2 t_2)``."""
    if model.mode_frequency <= 0.0:
        return np.zeros(1), np.ones(1)
    z = min(model.mode_damping, 0.99)
    w = 2 * math.pi * model.mode_frequency
    K = math.exp(-z * math.pi / math.sqrt(1 - z * z))
    t2 = math.pi / (w * math.sqrt(1 - z * z))
    if kind == "zv":
        return np.array([0.0, t2]), np.array([1.0, K]) / (1 + K)
    if kind == "zvd":
        return np.array([0.0, t2, 2 * t2]), np.array([1.0, 2 * K, K * K]) / (1 + K) ** 2
    raise ValueError(f"shaper kind must be 'zv' or 'zvd', got {kind!r}")
