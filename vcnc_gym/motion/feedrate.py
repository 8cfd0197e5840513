"""The cubic S-curve feedrate profile of Jahanpour et al. (2014) (section 2b, refs. [22, 24]).

Jahanpour et al. (2014) plan the feed along the tool path with "the cubic time-dependent
feedrate" of their refs. [22, 24]: an acceleration phase, a constant-feed phase
and a symmetric deceleration phase. Each ramp of duration T_a follows the
smoothstep cubic

    V(t) = V_peak (3 tau^2 - 2 tau^3),    tau = t / T_a in [0, 1],

so the feed acceleration dV/dt = 6 V_peak (tau - tau^2) / T_a is zero at both
ends of the ramp and peaks at 1.5 V_peak / T_a in the middle, and the jerk
6 V_peak (1 - 2 tau) / T_a^2 is finite (piecewise linear in t; it steps at the
phase boundaries, so V and dV/dt are continuous and the jerk is bounded).
Each ramp covers V_peak T_a / 2 of path.

Section 3 of the paper uses V = 100 mm/s and T_a = 0.12 s for both contours;
those are the defaults here.

The profile is split in two parts that follow the numba conventions of the
package: :class:`SCurveFeedrate` validates and plans, the module-level
kernels :func:`scurve_velocity`, :func:`scurve_acceleration` and
:func:`scurve_distance` evaluate a plan from its three numbers
(``FeedratePlan.kernel_args``) inside compiled loops.

Examples
--------
>>> profile = SCurveFeedrate(feedrate=100.0, ramp_time=0.12)
>>> plan = profile.plan(310.0)
>>> round(plan.duration, 6)       # 2 * 0.12 + (310 - 12) / 100
3.22
>>> float(plan.velocity(0.06))    # half-way up the first ramp
50.0
>>> float(plan.acceleration(0.06))  # 1.5 V / T_a, mm/s^2
1250.0
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..validation import positive

__all__ = [
    "FeedratePlan",
    "SCurveFeedrate",
    "scurve_acceleration",
    "scurve_distance",
    "scurve_velocity",
]


# --------------------------------------------------------------------------
# kernels: plain floats in, plain floats out, no validation
# --------------------------------------------------------------------------


@njit(cache=True)
def scurve_velocity(t, v_peak, ramp_time, cruise_time):
    """Commanded feed V(t) in mm/s of a planned S-curve, 0 outside [0, duration].

    Parameters
    ----------
    t : float
        Time since the start of the motion, s.
    v_peak : float
        Feed of the constant phase V_peak, mm/s.
    ramp_time : float
        Duration T_a of each ramp, s.
    cruise_time : float
        Duration T_c of the constant-feed phase, s (may be 0).
    """
    if t <= 0.0:
        return 0.0
    if t < ramp_time:
        tau = t / ramp_time
        return v_peak * tau * tau * (3.0 - 2.0 * tau)
    t_dec = ramp_time + cruise_time
    if t <= t_dec:
        return v_peak
    if t < t_dec + ramp_time:
        sig = (t - t_dec) / ramp_time
        return v_peak * (1.0 - sig * sig * (3.0 - 2.0 * sig))
    return 0.0


@njit(cache=True)
def scurve_acceleration(t, v_peak, ramp_time, cruise_time):
    """Feed acceleration dV/dt in mm/s^2 of a planned S-curve (arguments as
    :func:`scurve_velocity`); 0 outside the ramps."""
    if t <= 0.0:
        return 0.0
    if t < ramp_time:
        tau = t / ramp_time
        return 6.0 * v_peak * tau * (1.0 - tau) / ramp_time
    t_dec = ramp_time + cruise_time
    if t <= t_dec:
        return 0.0
    if t < t_dec + ramp_time:
        sig = (t - t_dec) / ramp_time
        return -6.0 * v_peak * sig * (1.0 - sig) / ramp_time
    return 0.0


@njit(cache=True)
def scurve_distance(t, v_peak, ramp_time, cruise_time):
    """Planned path distance S(t) = integral of V from 0 to t, in mm
    (arguments as :func:`scurve_velocity`); constant after the motion."""
    if t <= 0.0:
        return 0.0
    ramp = 0.5 * v_peak * ramp_time
    if t < ramp_time:
        tau = t / ramp_time
        return v_peak * ramp_time * tau * tau * tau * (1.0 - 0.5 * tau)
    t_dec = ramp_time + cruise_time
    if t <= t_dec:
        return ramp + v_peak * (t - ramp_time)
    if t < t_dec + ramp_time:
        sig = (t - t_dec) / ramp_time
        return ramp + v_peak * cruise_time + v_peak * ramp_time * sig * (1.0 - sig * sig * (1.0 - 0.5 * sig))
    return 2.0 * ramp + v_peak * cruise_time


@njit(cache=True)
def _scurve_batch(ts, v_peak, ramp_time, cruise_time, which, out):
    """Vectorised kernels: which = 0 velocity, 1 acceleration, 2 distance."""
    for i in range(ts.shape[0]):
        if which == 0:
            out[i] = scurve_velocity(ts[i], v_peak, ramp_time, cruise_time)
        elif which == 1:
            out[i] = scurve_acceleration(ts[i], v_peak, ramp_time, cruise_time)
        else:
            out[i] = scurve_distance(ts[i], v_peak, ramp_time, cruise_time)


# --------------------------------------------------------------------------
# the plan of one motion and the profile that makes it
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class FeedratePlan:
    """The S-curve planned for one path length: numbers and evaluators.

    Made by :meth:`SCurveFeedrate.plan`; not validated again here.

    Attributes
    ----------
    length : float
        Path length L the plan covers, mm.
    v_peak : float
        Feed of the constant phase, mm/s: the requested feedrate, or
        L / T_a if the path is too short to reach it.
    ramp_time : float
        Duration T_a of the acceleration and of the deceleration ramp, s.
    cruise_time : float
        Duration T_c of the constant-feed phase, s (0 on a short path).
    """

    length: float
    v_peak: float
    ramp_time: float
    cruise_time: float

    @property
    def duration(self) -> float:
        """Total motion time 2 T_a + T_c, s."""
        return 2.0 * self.ramp_time + self.cruise_time

    @property
    def kernel_args(self) -> tuple[np.ndarray, np.ndarray]:
        """``(breaks, coeffs)``: S(t) as the piecewise quartic of :mod:`vcnc_gym.motion.profile`.

        Ramp up ``S = V_p (tau^3 / T_a^2 - tau^4 / (2 T_a^3))`` (the integral of
        the smoothstep), cruise ``S = S_1 + V_p tau``, ramp down
        ``S = S_2 + V_p tau - V_p (tau^3 / T_a^2 - tau^4 / (2 T_a^3))``.
        """
        vp, ta, tc = self.v_peak, self.ramp_time, self.cruise_time
        c3, c4 = vp / ta**2, -vp / (2.0 * ta**3)
        s1 = 0.5 * vp * ta
        s2 = s1 + vp * tc
        rows = [[0.0, 0.0, 0.0, c3, c4]]
        breaks = [0.0, ta]
        if tc > 0.0:
            rows.append([s1, vp, 0.0, 0.0, 0.0])
            breaks.append(ta + tc)
        rows.append([s2, vp, 0.0, -c3, -c4])
        breaks.append(2.0 * ta + tc)
        rows.append([self.length, 0.0, 0.0, 0.0, 0.0])
        return np.array(breaks), np.array(rows)

    def _evaluate(self, t, which: int):
        ts = np.asarray(t, dtype=np.float64)
        flat = np.ascontiguousarray(ts.reshape(-1))
        out = np.empty_like(flat)
        _scurve_batch(flat, self.v_peak, self.ramp_time, self.cruise_time, which, out)
        if ts.ndim == 0:
            return float(out[0])
        return out.reshape(ts.shape)

    def velocity(self, t):
        """Commanded feed V(t), mm/s, for t in s (scalar or array); 0 outside the motion."""
        return self._evaluate(t, 0)

    def acceleration(self, t):
        """Feed acceleration dV/dt, mm/s^2, for t in s (scalar or array)."""
        return self._evaluate(t, 1)

    def distance(self, t):
        """Planned distance along the path S(t) = int_0^t V, mm, for t in s."""
        return self._evaluate(t, 2)


class SCurveFeedrate:
    """Cubic S-curve feedrate profile, Jahanpour et al.'s section 2b (refs. [22, 24]).

    Three phases: acceleration V(t) = V_peak (3 tau^2 - 2 tau^3) with
    tau = t / T_a, constant feed V_peak, and the mirror-image deceleration.
    The feed acceleration is zero at both ends of each ramp and peaks at
    1.5 V_peak / T_a; each ramp covers V_peak T_a / 2 of path.

    For a path of length L:

    * if L >= V T_a the feedrate is reached: V_peak = V and the constant
      phase lasts T_c = (L - V T_a) / V;
    * otherwise the path is too short to reach it; the ramp time is kept and
      the peak lowered to V_peak = L / T_a (T_c = 0), so the motion still
      takes 2 T_a and never exceeds the requested feedrate or the
      acceleration 1.5 V / T_a.

    Parameters
    ----------
    feedrate : float, default 100.0
        Requested feed V along the path, mm/s (Jahanpour et al. (2014), section 3: 100 mm/s).
    ramp_time : float, default 0.12
        Acceleration / deceleration time T_a, s (Jahanpour et al. (2014), section 3: 0.12 s).

    Raises
    ------
    ValueError
        If ``feedrate`` or ``ramp_time`` is not a finite real number > 0
        (booleans, strings and complex numbers are refused); the message
        names the argument and its unit (``vcnc_gym.validation.positive``).

    Examples
    --------
    >>> profile = SCurveFeedrate()
    >>> profile.duration(51.1)        # omega: 2 * 0.12 + (51.1 - 12) / 100, s
    0.631
    >>> profile.plan(6.0).v_peak      # too short for 100 mm/s: 6 / 0.12, mm/s
    50.0
    """

    def __init__(self, feedrate: float = 100.0, ramp_time: float = 0.12):
        self.feedrate = positive("feedrate", feedrate, "mm/s")
        self.ramp_time = positive("ramp_time", ramp_time, "s")

    def plan(self, length: float) -> FeedratePlan:
        """Plan the motion over a path of ``length`` mm.

        Raises
        ------
        ValueError
            If ``length`` is not a positive finite number.
        """
        L = positive("length", length, "mm")
        v, ta = self.feedrate, self.ramp_time
        if L >= v * ta:
            return FeedratePlan(length=L, v_peak=v, ramp_time=ta, cruise_time=(L - v * ta) / v)
        return FeedratePlan(length=L, v_peak=L / ta, ramp_time=ta, cruise_time=0.0)

    def duration(self, length: float) -> float:
        """Total motion time over a path of ``length`` mm, s."""
        return self.plan(length).duration

    def velocity(self, t, length: float):
        """Commanded feed V(t), mm/s, of the motion over ``length`` mm; t in s."""
        return self.plan(length).velocity(t)

    def acceleration(self, t, length: float):
        """Feed acceleration dV/dt, mm/s^2, of the motion over ``length`` mm; t in s."""
        return self.plan(length).acceleration(t)

    def distance(self, t, length: float):
        """Planned distance S(t), mm, of the motion over ``length`` mm; t in s."""
        return self.plan(length).distance(t)

    def __repr__(self) -> str:
        return f"SCurveFeedrate(feedrate={self.feedrate:g}, ramp_time={self.ramp_time:g})"
