"""Second-order Taylor NURBS interpolator, seed 000 section 2b, eqs. (6)-(10).

Given a curve C(u) and a feedrate profile V(t), the interpolator finds the
parameter u_k at every sampling instant t_k = k T so that the tool moves
along the curve at the commanded feed. The feed relation (seed 000 eq. (6))

    V(t) = ds/dt = |C'(u)| du/dt

has no closed-form solution for u(t) (eq. (7)), so u is advanced with its
second-order Taylor expansion around t_k (eq. (8)):

    u_{k+1} = u_k + T du/dt + T^2 / 2 d2u/dt2,
    du/dt   = V / |C'|                                   (eq. (9))
    d2u/dt2 = (dV/dt) / |C'| - V^2 (C' . C'') / |C'|^4   (eq. (10))

with C' = dC/du and C'' = d2C/du2 from the NURBS kernel (seed 000 eq. (5)).
The positions are C(u_k) (eq. (2)); the velocity and acceleration commands
follow by the chain rule, v = C' du/dt and a = C'' (du/dt)^2 + C' d2u/dt2.

The loop is the numba kernel :func:`taylor_interpolate_kernel`, which calls
:func:`vcnc_gym.geometry.nurbs.curve_derivatives` once per sample;
:func:`interpolate` validates, plans the feedrate over the curve's length,
runs the kernel and packs the result in a read-only :class:`Reference`.

Ending the motion
-----------------
The Taylor expansion is truncated, so the integrated u does not land on
u_end exactly when the profile ends. The reference always ends exactly at
the end of the curve, with no u beyond it:

* if the Taylor step would carry u to or past u_end before the profile has
  ended, that step is clamped: its sample is u_end;
* if the profile ends (the next sampling instant is at or after the planned
  duration) while u is still short of u_end, that next sample is placed at
  u_end.

In both cases the final sample has zero velocity and acceleration. The signed
gap between where the Taylor integration stood and u_end is reported as
``Reference.end_gap`` (mm) and ``Reference.end_gap_u``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..geometry.nurbs import curve_derivatives
from .feedrate import (
    FeedratePlan,
    _positive_finite,
    scurve_acceleration,
    scurve_distance,
    scurve_velocity,
)

__all__ = ["Reference", "interpolate", "taylor_interpolate_kernel"]

# end codes written by the kernel into info[0]
_END_PROFILE = 0.0  # profile ended first: next sample placed at u_end
_END_CLAMPED = 1.0  # u reached u_end before the profile ended: step clamped
_END_SINGULAR = 2.0  # |C'(u)| = 0 met: the curve has a cusp, eq. (9) undefined


@njit(cache=True)
def taylor_interpolate_kernel(
    control_points,
    weights,
    knots,
    degree,
    u_start,
    u_end,
    dt,
    v_peak,
    ramp_time,
    cruise_time,
    t_out,
    u_out,
    pos_out,
    vel_out,
    acc_out,
    feed_out,
    info,
):
    """Seed 000 eqs. (8)-(10) from t = 0 to the end of the curve.

    Parameters
    ----------
    control_points, weights, knots, degree
        The curve, as ``NurbsCurve.kernel_args``.
    u_start, u_end : float
        Parameter range of the curve.
    dt : float
        Sampling period T, s.
    v_peak, ramp_time, cruise_time : float
        The feedrate plan, as ``FeedratePlan.kernel_args`` (mm/s, s, s).
    t_out, u_out, feed_out : (K_max,) float64 arrays
        Written with t_k (s), u_k and the commanded V(t_k) (mm/s).
    pos_out, vel_out, acc_out : (K_max, 2) float64 arrays
        Written with C(u_k) (mm), velocity (mm/s), acceleration (mm/s^2).
        K_max must be at least ceil(duration / dt) + 1.
    info : (4,) float64 array
        Written with [end code, u where the Taylor integration stood at the
        end (see :func:`interpolate`), time of that u (s), planned distance
        S at that time (mm)].

    Returns
    -------
    int
        Number K of samples written.
    """
    duration = 2.0 * ramp_time + cruise_time
    ders = np.empty((3, 2))
    u = u_start
    k = 0
    while True:
        t = k * dt
        curve_derivatives(control_points, weights, knots, degree, u, 2, ders)
        c1x = ders[1, 0]
        c1y = ders[1, 1]
        speed2 = c1x * c1x + c1y * c1y
        v = scurve_velocity(t, v_peak, ramp_time, cruise_time)
        a = scurve_acceleration(t, v_peak, ramp_time, cruise_time)
        t_out[k] = t
        u_out[k] = u
        pos_out[k, 0] = ders[0, 0]
        pos_out[k, 1] = ders[0, 1]
        feed_out[k] = v
        if speed2 == 0.0:
            info[0] = _END_SINGULAR
            info[1] = u
            return k + 1
        speed = math.sqrt(speed2)
        du = v / speed  # eq. (9)
        ddu = a / speed - v * v * (c1x * ders[2, 0] + c1y * ders[2, 1]) / (speed2 * speed2)  # eq. (10)
        vel_out[k, 0] = c1x * du
        vel_out[k, 1] = c1y * du
        acc_out[k, 0] = ders[2, 0] * du * du + c1x * ddu
        acc_out[k, 1] = ders[2, 1] * du * du + c1y * ddu
        t_next = (k + 1) * dt
        end = -1.0
        if t_next >= duration:
            # the profile ends within this step: where does eq. (8) stand at
            # t = duration (partial step h = duration - t)?
            h = duration - t
            info[1] = u + h * du + 0.5 * h * h * ddu
            info[2] = duration
            info[3] = scurve_distance(duration, v_peak, ramp_time, cruise_time)
            end = _END_PROFILE
        else:
            u_next = u + dt * du + 0.5 * dt * dt * ddu  # eq. (8)
            if u_next < u:  # never step backwards along the path
                u_next = u
            if u_next >= u_end:
                info[1] = u_next
                info[2] = t_next
                info[3] = scurve_distance(t_next, v_peak, ramp_time, cruise_time)
                end = _END_CLAMPED
        if end >= 0.0:
            info[0] = end
            k += 1
            curve_derivatives(control_points, weights, knots, degree, u_end, 0, ders)
            t_out[k] = t_next
            u_out[k] = u_end
            pos_out[k, 0] = ders[0, 0]
            pos_out[k, 1] = ders[0, 1]
            vel_out[k, 0] = 0.0
            vel_out[k, 1] = 0.0
            acc_out[k, 0] = 0.0
            acc_out[k, 1] = 0.0
            feed_out[k] = scurve_velocity(t_next, v_peak, ramp_time, cruise_time)
            return k + 1
        u = u_next
        k += 1


@dataclass(frozen=True, eq=False)
class Reference:
    """The reference motion along one contour, sampled every ``dt`` from t = 0.

    Made by :func:`interpolate`. All arrays are read-only and share their
    first axis (K samples); sample k is at t_k = k dt, except that the last
    sample is always at the end of the curve (u = u_end) with zero velocity
    and acceleration (see :func:`interpolate`).

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sampling instants t_k = k dt, s.
    u : ndarray, shape (K,)
        Curve parameter u_k from seed 000 eq. (8); non-decreasing, from
        u_start to exactly u_end.
    position : ndarray, shape (K, 2)
        Position command C(u_k) (seed 000 eq. (2)), mm.
    velocity : ndarray, shape (K, 2)
        Velocity command C'(u_k) du/dt (eq. (9)), mm/s; its norm is the
        commanded feed V(t_k). Zero at the last sample.
    acceleration : ndarray, shape (K, 2)
        Acceleration command C''(u_k) (du/dt)^2 + C'(u_k) d2u/dt2 (eqs. (9),
        (10)), mm/s^2: tangential part dV/dt, normal part kappa V^2. Zero at
        the last sample.
    feedrate : ndarray, shape (K,)
        Commanded feed V(t_k) of the S-curve profile, mm/s (0 at the last
        sample unless eq. (8) reached u_end before the profile ended).
    dt : float
        Sampling (interpolation) period T, s.
    length : float
        Arc length of the curve from u_start to u_end, mm (the length the
        feedrate was planned over).
    plan : FeedratePlan
        The S-curve planned over ``length`` (V_peak in mm/s, T_a and T_c in s).
    end_gap : float
        Signed distance along the path, mm, by which the Taylor-integrated
        position trailed the planned distance S(t_e) when the interpolation
        ended at t_e; the final sample closes this gap. Positive: eq. (8)
        fell short of u_end when the profile ended (t_e = planned duration)
        and the last sample was placed at u_end. Negative: eq. (8) reached
        u_end early, at t_e < planned duration, and its step was clamped
        (the overshoot past u_end is estimated to first order).
    end_gap_u : float
        The same gap in the parameter, u_end minus the Taylor-integrated u
        at t_e (negative when clamped).
    feedrate_fluctuation : float
        max_k |V_act,k - V_cmd,k| / V_peak over the steps made by eq. (8)
        (every step but the final one onto u_end, which ``end_gap``
        describes), dimensionless (multiply by 100 for %). Here
        V_act,k = |C(u_{k+1}) - C(u_k)| / dt is the chord feed of step k and
        V_cmd,k = (S(t_{k+1}) - S(t_k)) / dt the commanded feed averaged over
        the step (S = integral of V, exact for the cubic). The step average
        is used rather than V(t_k) because a chord covers the whole step:
        against V(t_k) even an exact interpolator would show the first-order
        offset (dV/dt) dt / 2 (0.6 % of 100 mm/s at dt = 1 ms on the ramps).
        NaN if there is no such step.
    cruise_fluctuation_percent : float
        100 max_k |V_act,k - V_peak| / V_peak over the steps lying wholly in
        the constant-feed phase, %. NaN if that phase holds no whole step.
    """

    t: np.ndarray
    u: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    feedrate: np.ndarray
    dt: float
    length: float
    plan: FeedratePlan
    end_gap: float
    end_gap_u: float
    feedrate_fluctuation: float
    cruise_fluctuation_percent: float

    def __post_init__(self):
        for name in ("t", "u", "position", "velocity", "acceleration", "feedrate"):
            getattr(self, name).flags.writeable = False

    def __len__(self) -> int:
        return self.t.shape[0]

    @property
    def duration(self) -> float:
        """Time of the last sample, s (within one ``dt`` of ``plan.duration``)."""
        return float(self.t[-1])

    @property
    def chord_lengths(self) -> np.ndarray:
        """|C(u_{k+1}) - C(u_k)| for every step, shape (K-1,), mm."""
        return np.linalg.norm(np.diff(self.position, axis=0), axis=1)

    @property
    def traversed_length(self) -> float:
        """Traversed arc length as the sum of the chord lengths of the samples, mm.

        Shorter than ``length`` by about sum kappa^2 c^3 / 24 over the chords c
        (kappa the curvature, 1/mm): 2.5e-4 mm for the heart and 6.4e-3 mm for
        the omega at dt = 1 ms, 1e-4 as small at dt = 0.1 ms.
        """
        return float(np.sum(self.chord_lengths))

    @property
    def actual_feedrate(self) -> np.ndarray:
        """Chord feed V_act,k = |C(u_{k+1}) - C(u_k)| / dt of every step, shape (K-1,), mm/s."""
        return self.chord_lengths / self.dt

    @property
    def commanded_step_feedrate(self) -> np.ndarray:
        """Commanded feed averaged over every step, (S(t_{k+1}) - S(t_k)) / dt, shape (K-1,), mm/s."""
        return np.diff(self.plan.distance(self.t)) / self.dt


def interpolate(curve, profile, dt: float) -> Reference:
    """Interpolate a curve with a feedrate profile, seed 000 eqs. (8)-(10).

    Plans ``profile`` over the curve's arc length, then advances the
    parameter with the second-order Taylor expansion u_{k+1} = u_k + T du/dt
    + T^2/2 d2u/dt2 (eq. (8)), du/dt = V / |C'| (eq. (9)) and d2u/dt2 =
    (dV/dt) / |C'| - V^2 (C' . C'') / |C'|^4 (eq. (10)), sampling every
    ``dt`` from t = 0.

    The reference ends exactly at the end of the curve, never past it:

    * a step that would carry u to or past u_end before the profile has
      ended is clamped to u_end;
    * if the profile ends (the next sampling instant t_{k+1} is at or after
      the planned duration) with u still short of u_end, the sample at
      t_{k+1} is placed at u_end.

    The last sample has zero velocity and acceleration; the signed gap it
    closes is ``Reference.end_gap``. With the seed settings (100 mm/s,
    0.12 s ramps) eq. (8) falls short, by 6.1e-4 mm (heart) and 6.0e-3 mm
    (omega) at dt = 1 ms and by 6.1e-6 mm and 1.4e-4 mm at dt = 0.1 ms.
    A step is never allowed to move u backwards.

    Parameters
    ----------
    curve : NurbsCurve
        The path (mm). Needs ``kernel_args``, ``u_range`` and
        ``arc_length()``.
    profile : SCurveFeedrate
        The feedrate profile; anything with ``plan(length) -> FeedratePlan``.
    dt : float
        Interpolation (sampling) period T, s. Seed 000 uses 1e-3 s; the envs
        use their control period (default 1e-4 s).

    Returns
    -------
    Reference
        Time, parameter, position, velocity, acceleration and commanded feed
        at every sample, with the plan, the end gap and the feedrate
        fluctuation.

    Raises
    ------
    TypeError
        If ``curve`` has no ``kernel_args`` (or ``u_range``, ``arc_length``)
        or ``profile`` has no ``plan``.
    ValueError
        If ``dt`` is not a positive finite number, or the curve has a point
        with C'(u) = 0 on the way (eq. (9) is undefined there).

    Examples
    --------
    >>> from vcnc_gym.geometry import heart
    >>> from vcnc_gym.motion import SCurveFeedrate, interpolate
    >>> ref = interpolate(heart(), SCurveFeedrate(100.0, 0.12), dt=1e-3)
    >>> len(ref), float(ref.u[-1]), ref.position[-1].tolist()
    (3223, 6.0, [0.0, 0.0])
    >>> round(ref.end_gap * 1e3, 2)   # eq. (8) fell short of u_end by this, um
    0.61
    """
    for attr in ("kernel_args", "u_range", "arc_length"):
        if not hasattr(curve, attr):
            raise TypeError(
                f"curve must be a NurbsCurve-like object with kernel_args, u_range and "
                f"arc_length(); got {type(curve).__name__} without {attr!r}"
            )
    if not callable(getattr(profile, "plan", None)):
        raise TypeError(
            f"profile must be a feedrate profile with plan(length), e.g. SCurveFeedrate; "
            f"got {type(profile).__name__}"
        )
    dt = _positive_finite("dt", dt)
    u_start, u_end = (float(x) for x in curve.u_range)
    length = float(curve.arc_length())
    plan = profile.plan(length)

    k_max = int(math.ceil(plan.duration / dt)) + 2
    t = np.empty(k_max)
    u = np.empty(k_max)
    pos = np.empty((k_max, 2))
    vel = np.empty((k_max, 2))
    acc = np.empty((k_max, 2))
    feed = np.empty(k_max)
    info = np.zeros(4)
    n = taylor_interpolate_kernel(
        *curve.kernel_args, u_start, u_end, dt, *plan.kernel_args, t, u, pos, vel, acc, feed, info
    )
    if info[0] == _END_SINGULAR:
        raise ValueError(
            f"curve has C'(u) = 0 at u = {info[1]!r}: the feed relation of seed 000 eq. (9) "
            "is undefined there"
        )
    u_taylor, t_e, s_planned = float(info[1]), float(info[2]), float(info[3])
    end_gap_u = u_end - u_taylor
    if info[0] == _END_PROFILE and u_taylor < u_end:
        travelled_left = float(curve.arc_length(max(u_taylor, u_start), u_end))
    else:  # at or past u_end: overshoot to first order, |C'(u_end)| (u - u_end)
        speed_end = float(np.linalg.norm(curve.derivatives(u_end, 1)[1]))
        travelled_left = -speed_end * (u_taylor - u_end)
    end_gap = travelled_left - (plan.length - s_planned)

    t, u, pos, vel, acc, feed = (a[:n].copy() for a in (t, u, pos, vel, acc, feed))

    # feedrate fluctuation over the steps made by eq. (8): all but the last
    v_act = np.linalg.norm(np.diff(pos, axis=0), axis=1)[:-1] / dt
    v_cmd = np.diff(plan.distance(t))[:-1] / dt
    if v_act.size:
        fluctuation = float(np.max(np.abs(v_act - v_cmd)) / plan.v_peak)
    else:
        fluctuation = float("nan")
    t0, t1 = t[:-2], t[1:-1]
    cruise = (t0 >= plan.ramp_time) & (t1 <= plan.ramp_time + plan.cruise_time)
    if np.any(cruise):
        cruise_pct = float(100.0 * np.max(np.abs(v_act[cruise] - plan.v_peak)) / plan.v_peak)
    else:
        cruise_pct = float("nan")

    return Reference(
        t=t,
        u=u,
        position=pos,
        velocity=vel,
        acceleration=acc,
        feedrate=feed,
        dt=dt,
        length=length,
        plan=plan,
        end_gap=float(end_gap),
        end_gap_u=float(end_gap_u),
        feedrate_fluctuation=fluctuation,
        cruise_fluctuation_percent=cruise_pct,
    )
