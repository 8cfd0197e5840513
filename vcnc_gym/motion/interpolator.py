"""Second-order Taylor NURBS interpolator, Jahanpour et al. (2014), section 2b, eqs. (6)-(10).

Given a curve C(u) and a feedrate profile V(t), the interpolator finds the
parameter u_k at every sampling instant t_k = k T so that the tool moves
along the curve at the commanded feed. The feed relation (eq. (6)),

::

    V(t) = ds/dt = |C'(u)| du/dt

has no closed-form solution for u(t) (eq. (7)), so u is advanced with its
second-order Taylor expansion around t_k (eq. (8))::

    u_{k+1} = u_k + T du/dt + T^2 / 2 d2u/dt2,
    du/dt   = V / |C'|                                   (eq. (9))
    d2u/dt2 = (dV/dt) / |C'| - V^2 (C' . C'') / |C'|^4   (eq. (10))

with C' = dC/du and C'' = d2C/du2 from the NURBS kernel (eq. (5)).
The positions are C(u_k) (eq. (2)); the velocity and acceleration commands
follow by the chain rule, v = C' du/dt and a = C'' (du/dt)^2 + C' d2u/dt2.

The loop is the numba kernel :func:`taylor_interpolate_kernel`, which
evaluates the curve (:func:`vcnc_gym.geometry.nurbs.curve_derivatives_into`)
once per sample; :func:`interpolate` validates, plans the feedrate over the
curve's length, runs the kernel, checks the result and packs it in a
read-only :class:`Reference`.

Step control (not in the paper)
-------------------------------
Eq. (8) is a truncated expansion: where ``|C'|`` changes fast compared with a
step (large weight ratios, knots where C'' jumps, corners of a polyline)
its step can be several times too long or stall.  Every step's arc length
is therefore compared with the distance the profile commands over it, and
a step that misses by more than ``step_tolerance`` x V_peak x dt (default
``STEP_TOLERANCE`` = 0.1), or lets the distance travelled drift from the
plan by more than 0.9 of that, is replaced by the u solved from the arc
length (Newton on arc(u_k, u) = S(t_{k+1}) - s_k; see
:func:`taylor_interpolate_kernel`).  Steps within the tolerance are eq. (8)
unchanged: on the paper's heart and omega none is corrected, so the paper's
figures are those of eq. (8) alone.  A curve whose tangent is undefined
somewhere (a cusp, coincident control points) is refused before
(:meth:`NurbsCurve.check_regular`), and a reference that would exceed
``MAX_REFERENCE_SAMPLES`` samples is refused before it is allocated.

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
from typing import NamedTuple

import numpy as np
from numba import njit

from ..geometry.arclength import ARC_STACK, arc_between, curve_curvature, curve_speed
from ..geometry.nurbs import FIRST, SECOND, NurbsCurve, curve_derivatives_into, find_span, workspace_size
from ..validation import integer, positive, real
from .feedrate import FeedratePlan
from .profile import plan_arrays, plan_state

__all__ = [
    "MAX_REFERENCE_SAMPLES",
    "STEP_TOLERANCE",
    "END_CLAMPED",
    "END_FAILED",
    "END_PROFILE",
    "END_SINGULAR",
    "END_UNRESOLVED",
    "INFO_CORRECTED",
    "INFO_END_CODE",
    "INFO_SIZE",
    "INFO_S_END",
    "INFO_STEP_ERROR",
    "INFO_T_END",
    "INFO_U_END",
    "INFO_WORST_K",
    "INFO_WORST_U",
    "InterpolationSettings",
    "Reference",
    "ReferenceBuffers",
    "interpolate",
    "reference_samples",
    "taylor_interpolate_kernel",
]

#: Default ``step_tolerance`` of :func:`interpolate`: every step of a reference
#: moves along the curve within this fraction of V_peak dt of the distance the
#: profile commands over it.  The paper's own figures stay inside it untouched:
#: the largest step error of eq. (8) on the heart and the omega is 0.06 V_peak dt
#: (the omega's last step at dt = 1 ms), so no step of theirs is corrected.
STEP_TOLERANCE = 0.1

#: Default ``max_samples`` of :func:`interpolate`: the most samples a reference
#: may have.  A sample holds 11 float64 (t, u, V and the x, y of position,
#: velocity, acceleration and tangent), so 2e6 samples are 0.16 GiB and take
#: about 1.5 s to build; they are 200 s of motion at dt = 0.1 ms (the heart at
#: 1.6 mm/s; the paper's 100 mm/s makes 32 213), 60 times the paper's episodes.
MAX_REFERENCE_SAMPLES = 2_000_000

_BYTES_PER_SAMPLE = 11 * 8

# The kernel corrects a step when the distance travelled drifts from the plan
# by more than this share of the tolerance; the corrected step's error is that
# drift plus the solver's (at most half a floating-point step of u, which must
# then stay below the remaining share).
_DRIFT_SHARE = 0.9

# No sample is placed where one floating-point step of u moves more than this
# share of the tolerance (a knot span squeezed in u: arc lengths there are only
# as good as the resolution of u; ~1e-13 mm on ordinary curves).
_RESOLUTION_SHARE = 1e-3

# A step made by eq. (8) is kept when its arc length is within (1 - _ARC_SLACK)
# of the tolerance: the arc lengths themselves are good to ~1e-6 of the
# tolerance, to ~1e-3 of it where u resolves the curve only just
# (_RESOLUTION_SHARE), so the promise holds whatever the quadrature's error.
_ARC_SLACK = 2e-3

# slots of the kernel's status array info (INFO_SIZE,), float64
INFO_END_CODE = 0  # how the interpolation ended, END_* (-1 while it runs)
INFO_U_END = 1  # u where eq. (8) stood at the end; for END_SINGULAR and END_UNRESOLVED the u it stopped at
INFO_T_END = 2  # time of that u, s
INFO_S_END = 3  # planned distance S at that time, mm
INFO_CORRECTED = 4  # steps solved from the arc length instead of eq. (8)
INFO_STEP_ERROR = 5  # largest |a_k - dS_k| over the steps, mm (the last step onto u_end included)
INFO_WORST_U = 6  # u_k of that step
INFO_WORST_K = 7  # k of that step
INFO_SIZE = 8

# end codes, info[INFO_END_CODE]
END_PROFILE = 0.0  # profile ended first: next sample placed at u_end
END_CLAMPED = 1.0  # u reached u_end before the profile ended: step clamped
END_SINGULAR = 2.0  # |C'(u)| = 0 (or not finite) met: eq. (9) undefined
END_FAILED = 3.0  # a corrected step still missed the tolerance: stopped after it
END_UNRESOLVED = 4.0  # one floating-point step of u moves too far at a sample: stopped there


class InterpolationSettings(NamedTuple):
    """The scalars of one run of :func:`taylor_interpolate_kernel`."""

    u_start: float  #: the curve's parameter range, ``NurbsCurve.u_range``
    u_end: float
    dt: float  #: sampling period T, s
    v_peak: float  #: the plan's largest feed, mm/s (the step tolerance's scale)
    step_tolerance: float  #: the allowed error of a step's arc length and of the distance run, a fraction of v_peak dt


class ReferenceBuffers(NamedTuple):
    """The arrays :func:`taylor_interpolate_kernel` writes, named as :class:`Reference`'s fields.

    K_max rows each, at least ceil(duration / dt) + 2.
    """

    t: np.ndarray  #: (K_max,) t_k, s
    u: np.ndarray  #: (K_max,) u_k
    position: np.ndarray  #: (K_max, 2) C(u_k), mm
    velocity: np.ndarray  #: (K_max, 2) mm/s
    acceleration: np.ndarray  #: (K_max, 2) mm/s^2
    tangent: np.ndarray  #: (K_max, 2) unit tangent C'(u_k) / ``|C'(u_k)|``
    feedrate: np.ndarray  #: (K_max,) commanded V(t_k), mm/s


class _ArcWorkspace(NamedTuple):
    """Scratch of the arc-length helpers, made by the kernel."""

    ders: np.ndarray  #: (3, 2) derivatives of the last evaluation
    work: np.ndarray  #: (workspace_size(degree, SECOND),) for curve_derivatives_into
    stack: np.ndarray  #: (3, ARC_STACK) for arc_between


# --------------------------------------------------------------------------
# kernels
# --------------------------------------------------------------------------


@njit(cache=True)
def _step_arc(curve, u0, u1, d0, d1, tol, ws):
    """Arc length of the step u0 -> u1 (derivatives d0, d1 of order 2 at its ends), mm.

    Within one knot span, where ``|C'|`` is smooth, the corrected trapezoid rule
    h/2 (f0 + f1) + h^2/12 (f0' - f1') on f = ``|C'|`` (f' = C'.C''/``|C'|``, error
    O(h^5)) needs no new evaluation; it is used when it agrees with the
    chord-and-curvature estimate c (1 + kappa^2 c^2 / 24) (c the chord,
    kappa the mean curvature of the ends) to within ``tol`` mm: the step then
    resolves the curve.  Otherwise (a knot inside, or a step that does not
    resolve the curve) the arc is integrated (:func:`arc_between`).  ``curve`` is a
    :class:`~vcnc_gym.geometry.nurbs.NurbsArrays`, ``ws`` an :class:`_ArcWorkspace`.
    """
    control_points, weights, knots, degree = curve
    n = control_points.shape[0] - 1
    if u1 <= u0:
        return 0.0
    span = find_span(n, degree, u0, knots)
    if u1 < knots[span + 1]:
        s0 = curve_speed(d0)
        s1 = curve_speed(d1)
        if s0 > 0.0 and s1 > 0.0:
            h = u1 - u0
            g0 = (d0[1, 0] * d0[2, 0] + d0[1, 1] * d0[2, 1]) / s0
            g1 = (d1[1, 0] * d1[2, 0] + d1[1, 1] * d1[2, 1]) / s1
            trapezoid = 0.5 * h * (s0 + s1) + h * h * (g0 - g1) / 12.0
            dx = d1[0, 0] - d0[0, 0]
            dy = d1[0, 1] - d0[0, 1]
            c = math.sqrt(dx * dx + dy * dy)
            kappa = 0.5 * (curve_curvature(d0, s0) + curve_curvature(d1, s1))
            chordal = c * (1.0 + kappa * kappa * c * c / 24.0)
            if abs(trapezoid - chordal) <= tol:
                return trapezoid
    return arc_between(control_points, weights, knots, degree, u0, u1, 1e-3 * tol, ws.ders, ws.work, ws.stack)


@njit(cache=True)
def _arc_step(curve, u0, speed0, target, u_end, tol, ws, result):
    """The u > u0 at which the arc from u0 is ``target`` mm (to ``tol`` mm).

    The arc length is increasing in u with slope ``|C'(u)|``, so the root is
    unique: bracketed by marching from u0 with doubling steps (the first
    target / ``|C'(u0)|``), then Newton's method safeguarded by bisection.

    Writes ``result`` = [u, arc from u0 to u (mm), 1.0 if the curve ends
    (u = u_end) before the target is reached else 0.0].  ``curve`` is a
    :class:`~vcnc_gym.geometry.nurbs.NurbsArrays`, ``ws`` an :class:`_ArcWorkspace`.
    """
    control_points, weights, knots, degree = curve
    ders, work, stack = ws
    result[2] = 0.0
    if target <= 0.0:
        result[0] = u0
        result[1] = 0.0
        return
    lo = u0
    arc_lo = 0.0
    h = target / speed0
    while True:
        hi = lo + h
        if not hi < u_end:
            hi = u_end
        if not hi > lo:
            hi = np.nextafter(lo, np.inf)
        arc_hi = arc_lo + arc_between(control_points, weights, knots, degree, lo, hi, 1e-3 * tol, ders, work, stack)
        if arc_hi >= target:
            break
        if hi >= u_end:
            result[0] = u_end
            result[1] = arc_hi
            result[2] = 1.0
            return
        lo = hi
        arc_lo = arc_hi
        h *= 2.0
    # F(u) = arc(u0, u) - target: F(lo) < 0 <= F(hi); secant start, then Newton
    u = lo + (hi - lo) * (target - arc_lo) / (arc_hi - arc_lo)
    best_u = hi
    best_arc = arc_hi
    for _ in range(200):
        if not (lo < u < hi):
            u = 0.5 * (lo + hi)
            if not (lo < u < hi):
                break
        arc_u = arc_lo + arc_between(control_points, weights, knots, degree, lo, u, 1e-3 * tol, ders, work, stack)
        f = arc_u - target
        if abs(f) < abs(best_arc - target):
            best_u = u
            best_arc = arc_u
        if abs(f) <= tol:
            break
        if f < 0.0:
            lo = u
            arc_lo = arc_u
        else:
            hi = u
            arc_hi = arc_u
        curve_derivatives_into(control_points, weights, knots, degree, u, FIRST, ders, work)
        speed = curve_speed(ders)
        u = u - f / speed if speed > 0.0 else 0.5 * (lo + hi)
    if abs(arc_lo - target) < abs(best_arc - target):
        best_u = lo
        best_arc = arc_lo
    result[0] = best_u
    result[1] = best_arc


@njit(cache=True)
def taylor_interpolate_kernel(curve, plan, settings, out, info):
    """Jahanpour et al. (2014), eqs. (8)-(10), from t = 0 to the end of the curve, with step control.

    Every step is first made by eq. (8).  Its arc length a_k along the curve
    (:func:`_step_arc`) is compared with the distance the profile commands,
    dS_k = S(t_{k+1}) - S(t_k), and the running sum s_{k+1} = sum a_j with
    S(t_{k+1}).  If a_k misses dS_k by more than (1 - 2e-3) tol, tol =
    ``step_tolerance`` x v_peak x dt (the 2e-3 covers the error of the arc
    lengths themselves), or s_{k+1} misses S(t_{k+1}) by more than 0.9 tol,
    the step is replaced: u_{k+1} is solved from arc(u_k, u_{k+1}) = S(t_{k+1}) - s_k
    (:func:`_arc_step`), which brings s back onto the plan; its error
    against dS_k is then the drift s_k - S(t_k) the previous steps left
    (at most 0.9 tol) plus the solver's (1e-6 tol, or half a floating-point
    step of u where that moves farther).

    Parameters
    ----------
    curve : NurbsArrays
        The curve, ``NurbsCurve.kernel_args``.
    plan : PlanArrays
        The feedrate plan S(t) as a piecewise quartic, ``plan_arrays(plan)``
        (:mod:`vcnc_gym.motion.profile`: s; mm, mm/s, ...).
    settings : InterpolationSettings
        The parameter range u_start, u_end, the sampling period dt (s), the
        plan's v_peak (mm/s) and the step tolerance (a fraction of v_peak dt).
    out : ReferenceBuffers
        Written with t_k (s), u_k, C(u_k) (mm), velocity (mm/s), acceleration
        (mm/s^2), the unit tangent C'(u_k) / ``|C'(u_k)|`` and the commanded V(t_k)
        (mm/s); K_max rows, at least ceil(duration / dt) + 2.
    info : (INFO_SIZE,) float64 array
        Written with the status, at the slots ``INFO_*``: the end code
        (``INFO_END_CODE``), u where eq. (8) stood at the end (``INFO_U_END``,
        see :func:`interpolate`), the time of that u (s) and the planned
        distance S then (mm), the number of corrected steps, the largest
        ``|a_k - dS_k|`` (mm, the last step onto u_end included) and u_k and k of
        that step.  End codes: ``END_PROFILE`` the profile ended,
        ``END_CLAMPED`` u reached u_end first, ``END_SINGULAR`` ``|C'(u)|`` = 0
        met at u = info[INFO_U_END] (stopped there), ``END_FAILED`` a corrected
        step k = info[INFO_WORST_K] still missed the tolerance (stopped after
        its sample k + 1: no u can meet it), ``END_UNRESOLVED`` one
        floating-point step of u moves more than 1e-3 tol at
        u = info[INFO_U_END] (stopped there).

    Returns
    -------
    int
        Number K of samples written.
    """
    control_points, weights, knots, degree = curve
    breaks, coeffs = plan
    u_start, u_end, dt, v_peak, step_tolerance = settings
    t_out = out.t
    u_out = out.u
    pos_out = out.position
    vel_out = out.velocity
    acc_out = out.acceleration
    tan_out = out.tangent
    feed_out = out.feedrate
    duration = breaks[breaks.shape[0] - 1]
    tol = step_tolerance * v_peak * dt
    ders = np.empty((3, 2))
    nxt = np.empty((3, 2))
    ws = _ArcWorkspace(np.empty((3, 2)), np.empty(workspace_size(degree, SECOND)), np.empty((3, ARC_STACK)))
    scratch = ws.ders
    work = ws.work
    stack = ws.stack
    result = np.empty(3)
    info[INFO_END_CODE] = -1.0  # no end yet
    info[INFO_CORRECTED] = 0.0
    info[INFO_STEP_ERROR] = 0.0
    info[INFO_WORST_U] = u_start
    info[INFO_WORST_K] = 0.0
    u = u_start
    s = 0.0  # arc length travelled, mm
    k = 0
    curve_derivatives_into(control_points, weights, knots, degree, u, SECOND, ders, work)
    while True:
        t = k * dt
        c1x = ders[1, 0]
        c1y = ders[1, 1]
        speed2 = c1x * c1x + c1y * c1y
        _s, v, a = plan_state(t, breaks, coeffs)
        t_out[k] = t
        u_out[k] = u
        pos_out[k, 0] = ders[0, 0]
        pos_out[k, 1] = ders[0, 1]
        feed_out[k] = v
        if not (speed2 > 0.0 and speed2 < np.inf):
            info[INFO_END_CODE] = END_SINGULAR
            info[INFO_U_END] = u
            return k + 1
        speed = math.sqrt(speed2)
        if speed * (np.nextafter(abs(u), np.inf) - abs(u)) > _RESOLUTION_SHARE * tol:
            info[INFO_END_CODE] = END_UNRESOLVED
            info[INFO_U_END] = u
            return k + 1
        tan_out[k, 0] = c1x / speed
        tan_out[k, 1] = c1y / speed
        du = v / speed  # eq. (9)
        ddu = a / speed - v * v * ((c1x * ders[2, 0] + c1y * ders[2, 1]) / speed2) / speed2  # eq. (10)
        vel_out[k, 0] = c1x * du
        vel_out[k, 1] = c1y * du
        acc_out[k, 0] = ders[2, 0] * du * du + c1x * ddu
        acc_out[k, 1] = ders[2, 1] * du * du + c1y * ddu
        t_next = (k + 1) * dt
        s_now = plan_state(t, breaks, coeffs)[0]
        s_next = plan_state(t_next, breaks, coeffs)[0]
        if t_next >= duration:
            # the profile ends within this step: where does eq. (8) stand at
            # t = duration (partial step h = duration - t)?
            h = duration - t
            info[INFO_END_CODE] = END_PROFILE
            info[INFO_U_END] = u + h * du + 0.5 * h * h * ddu
            info[INFO_T_END] = duration
            info[INFO_S_END] = plan_state(duration, breaks, coeffs)[0]
            step = arc_between(control_points, weights, knots, degree, u, u_end, 1e-9 * tol, scratch, work, stack)
        else:
            u_next = u + dt * du + 0.5 * dt * dt * ddu  # eq. (8)
            if not u_next >= u:  # never step backwards along the path (nor to NaN)
                u_next = u
            u_taylor = u_next
            if u_next > u_end:
                u_next = u_end
            curve_derivatives_into(control_points, weights, knots, degree, u_next, SECOND, nxt, work)
            step = _step_arc(curve, u, u_next, ders, nxt, 1e-6 * tol, ws)
            kept = abs(step - (s_next - s_now)) <= (1.0 - _ARC_SLACK) * tol
            if not (kept and abs(s + step - s_next) <= _DRIFT_SHARE * tol):
                _arc_step(curve, u, speed, s_next - s, u_end, 1e-6 * tol, ws, result)
                u_next = result[0]
                step = result[1]
                u_taylor = u_next
                info[INFO_CORRECTED] += 1.0
                curve_derivatives_into(control_points, weights, knots, degree, u_next, SECOND, nxt, work)
                if abs(step - (s_next - s_now)) > (1.0 - _ARC_SLACK) * tol and result[2] == 0.0:
                    # no u meets the tolerance (u cannot resolve the step): stop here
                    info[INFO_END_CODE] = END_FAILED
                    info[INFO_STEP_ERROR] = abs(step - (s_next - s_now))
                    info[INFO_WORST_U] = u
                    info[INFO_WORST_K] = k
                    t_out[k + 1] = t_next
                    u_out[k + 1] = u_next
                    return k + 2
            if u_next >= u_end:
                info[INFO_END_CODE] = END_CLAMPED
                info[INFO_U_END] = u_taylor
                info[INFO_T_END] = t_next
                info[INFO_S_END] = s_next
        error = abs(step - (s_next - s_now))
        if error > info[INFO_STEP_ERROR]:
            info[INFO_STEP_ERROR] = error
            info[INFO_WORST_U] = u
            info[INFO_WORST_K] = k
        s += step
        if info[INFO_END_CODE] >= 0.0:  # the end: the next sample is u_end
            k += 1
            curve_derivatives_into(control_points, weights, knots, degree, u_end, FIRST, scratch, work)
            sp = curve_speed(scratch)
            t_out[k] = t_next
            u_out[k] = u_end
            pos_out[k, 0] = scratch[0, 0]
            pos_out[k, 1] = scratch[0, 1]
            tan_out[k, 0] = scratch[1, 0] / sp
            tan_out[k, 1] = scratch[1, 1] / sp
            vel_out[k, 0] = 0.0
            vel_out[k, 1] = 0.0
            acc_out[k, 0] = 0.0
            acc_out[k, 1] = 0.0
            feed_out[k] = plan_state(t_next, breaks, coeffs)[1]
            return k + 1
        u = u_next
        ders, nxt = nxt, ders
        k += 1


@dataclass(frozen=True, eq=False)
class Reference:
    """The reference motion along one contour, sampled every ``dt`` from t = 0.

    Made by :func:`interpolate`, which checks what it states here before
    returning it. All arrays are read-only and share their first axis (K
    samples); sample k is at t_k = k dt, except that the last sample is
    always at the end of the curve (u = u_end) with zero velocity and
    acceleration (see :func:`interpolate`).

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sampling instants t_k = k dt, s.
    u : ndarray, shape (K,)
        Curve parameter u_k from Jahanpour et al. (2014), eq. (8); non-decreasing, from
        u_start to exactly u_end.
    position : ndarray, shape (K, 2)
        Position command C(u_k) (eq. (2)), mm.
    velocity : ndarray, shape (K, 2)
        Velocity command C'(u_k) du/dt (eq. (9)), mm/s; its norm is the
        commanded feed V(t_k). Zero at the last sample.
    acceleration : ndarray, shape (K, 2)
        Acceleration command C''(u_k) (du/dt)^2 + C'(u_k) d2u/dt2 (eqs. (9),
        (10)), mm/s^2: tangential part dV/dt, normal part kappa V^2. Zero at
        the last sample.
    tangent : ndarray, shape (K, 2)
        Unit tangent C'(u_k) / ``|C'(u_k)|`` of the curve at every sample (also
        the last), dimensionless; finite.
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
    step_tolerance : float
        The guarantee this reference was checked against: every step k, the
        last one onto u_end included, moves along the curve (arc length
        from u_k to u_{k+1}) within ``step_tolerance`` x V_peak x dt of the
        commanded distance S(t_{k+1}) - S(t_k); dimensionless.
    step_error : float
        The largest such ``|arc - commanded|`` over the steps, as a fraction of
        V_peak dt (at most ``step_tolerance``).
    corrected_steps : int
        Steps where eq. (8) was off by more than the tolerance and u_{k+1}
        was solved from the arc length instead (0 on the heart and the omega).
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
        max_k ``|V_act,k - V_cmd,k|`` / V_peak over the steps made by eq. (8)
        or its correction (every step but the final one onto u_end, which
        ``end_gap`` describes), dimensionless (multiply by 100 for %). Here
        V_act,k = ``|C(u_{k+1}) - C(u_k)|`` / dt is the chord feed of step k and
        V_cmd,k = (S(t_{k+1}) - S(t_k)) / dt the commanded feed averaged over
        the step (S = integral of V, exact for the cubic). The step average
        is used rather than V(t_k) because a chord covers the whole step:
        against V(t_k) even an exact interpolator would show the first-order
        offset (dV/dt) dt / 2 (0.6 % of 100 mm/s at dt = 1 ms on the ramps).
        NaN if there is no such step.
    cruise_fluctuation_percent : float
        100 max_k ``|V_act,k - V_peak|`` / V_peak over the steps lying wholly in
        the constant-feed phase, %. NaN if that phase holds no whole step.
    """

    t: np.ndarray
    u: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    tangent: np.ndarray
    feedrate: np.ndarray
    dt: float
    length: float
    plan: FeedratePlan
    step_tolerance: float
    step_error: float
    corrected_steps: int
    end_gap: float
    end_gap_u: float
    feedrate_fluctuation: float
    cruise_fluctuation_percent: float

    def __post_init__(self):
        for name in _ARRAYS:
            getattr(self, name).flags.writeable = False

    def __len__(self) -> int:
        return self.t.shape[0]

    @property
    def duration(self) -> float:
        """Time of the last sample, s (within one ``dt`` of ``plan.duration``)."""
        return float(self.t[-1])

    @property
    def chord_lengths(self) -> np.ndarray:
        """``|C(u_{k+1}) - C(u_k)|`` for every step, shape (K-1,), mm."""
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
        """Chord feed V_act,k = ``|C(u_{k+1}) - C(u_k)|`` / dt of every step, shape (K-1,), mm/s."""
        return self.chord_lengths / self.dt

    @property
    def commanded_step_feedrate(self) -> np.ndarray:
        """Commanded feed averaged over every step, (S(t_{k+1}) - S(t_k)) / dt, shape (K-1,), mm/s."""
        return np.diff(self.plan.distance(self.t)) / self.dt


_ARRAYS = ReferenceBuffers._fields


# --------------------------------------------------------------------------
# what a reference costs, and the checks of the arguments
# --------------------------------------------------------------------------


def _check_profile(profile):
    if not callable(getattr(profile, "plan", None)):
        raise TypeError(
            f"profile must be a feedrate profile with plan(length), e.g. SCurveFeedrate; got {type(profile).__name__}"
        )


def _describe(profile) -> str:
    """'feedrate=... mm/s, ramp_time=... s' for an S-curve, else its repr."""
    if hasattr(profile, "feedrate") and hasattr(profile, "ramp_time"):
        return f"feedrate={profile.feedrate!r} mm/s, ramp_time={profile.ramp_time!r} s"
    return repr(profile)


def _sample_count(duration: float, dt: float) -> float:
    """Samples over ``duration`` s at ``dt`` s: n + 1 with n the first step count such that
    n dt >= duration in floating point, as the kernel tests it (a float: may be huge)."""
    ratio = duration / dt
    if not math.isfinite(ratio):
        return math.inf
    if ratio > 2.0**52:
        return float(math.ceil(ratio)) + 1.0
    n = max(1, math.ceil(ratio))
    while n * dt < duration:
        n += 1
    while n > 1 and (n - 1) * dt >= duration:
        n -= 1
    return float(n) + 1.0


def reference_samples(length: float, profile, dt: float) -> int:
    """How many samples the reference of a ``length`` mm contour will have, before building it.

    The reference samples t_k = k dt until the planned motion ends, plus the
    final sample on u_end: n + 1 samples, n = ceil(duration / dt) (the first
    n with n dt >= duration in floating point), with the duration 2 T_a + T_c
    of ``profile.plan(length)``.  :func:`interpolate` makes exactly
    this many, or fewer when eq. (8) reaches the end of the curve early
    (a few samples at most, its step error being bounded).  Each sample
    takes 88 bytes (11 float64).

    Parameters
    ----------
    length : float
        Arc length of the contour, mm (``NurbsCurve.arc_length()``).
    profile : SCurveFeedrate
        The feedrate profile (anything with ``plan(length)``).
    dt : float
        Sampling period, s.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        If ``length`` or ``dt`` is not a finite real number > 0.

    Examples
    --------
    >>> from vcnc_gym.motion import SCurveFeedrate
    >>> reference_samples(310.1146, SCurveFeedrate(100.0, 0.12), 1e-4)
    32213
    >>> reference_samples(310.1146, SCurveFeedrate(0.001, 0.12), 1e-4)   # 88 bytes each: 254 GiB
    3101147201
    """
    length = positive("length", length, "mm")
    dt = positive("dt", dt, "s")
    _check_profile(profile)
    count = _sample_count(profile.plan(length).duration, dt)
    if not math.isfinite(count):
        raise ValueError(f"the motion over {length!r} mm with dt={dt!r} s has more samples than a float can count")
    return int(count)


def _check_cost(length: float, profile, plan, dt: float, max_samples: int) -> int:
    """The sample count of the reference (:func:`reference_samples`); ValueError beyond ``max_samples``."""
    count = _sample_count(plan.duration, dt)
    if count > max_samples:
        gib = count * _BYTES_PER_SAMPLE / 2**30
        limit_gib = max_samples * _BYTES_PER_SAMPLE / 2**30
        raise ValueError(
            f"{_describe(profile)} over the {length:.6g} mm contour lasts {plan.duration:.4g} s: with "
            f"dt={dt!r} s that would make {count:.3g} reference samples ({gib:.3g} GiB); the limit is "
            f"max_samples={max_samples} ({limit_gib:.2g} GiB; default MAX_REFERENCE_SAMPLES = "
            f"{MAX_REFERENCE_SAMPLES:.0e}). Raise the feedrate (mm/s) or dt (s), shorten ramp_time (s), or pass "
            "a larger max_samples"
        )
    return int(count)


# --------------------------------------------------------------------------
# the interpolator
# --------------------------------------------------------------------------


def interpolate(
    curve,
    profile,
    dt: float,
    *,
    step_tolerance: float = STEP_TOLERANCE,
    max_samples: int = MAX_REFERENCE_SAMPLES,
) -> Reference:
    """Interpolate a curve with a feedrate profile, Jahanpour et al. (2014), eqs. (8)-(10).

    Plans ``profile`` over the curve's arc length, then advances the
    parameter with the second-order Taylor expansion u_{k+1} = u_k + T du/dt
    + T^2/2 d2u/dt2 (eq. (8)), du/dt = V / ``|C'|`` (eq. (9)) and d2u/dt2 =
    (dV/dt) / ``|C'|`` - V^2 (C' . C'') / ``|C'|^4`` (eq. (10)), sampling every
    ``dt`` from t = 0.

    What the reference guarantees (checked before it is returned; a curve or
    setting that cannot meet it is refused with a ``ValueError``):

    * **Every step moves as commanded.**  For every step k, the last one
      onto u_end included, the arc length of the curve from u_k to u_{k+1}
      is within ``step_tolerance`` x V_peak x dt (default 0.1 V_peak dt) of
      the commanded distance S(t_{k+1}) - S(t_k) (S the integral of the
      feed); so is the arc length travelled since t = 0 of S(t_k).  Where
      eq. (8) misses by more (large parametric accelerations, steps across
      knots where C'' jumps, corners), u_{k+1} is solved from the arc length
      instead (``Reference.corrected_steps``).  The paper's contours need no
      correction: their largest eq. (8) error is 0.06 V_peak dt (the
      omega's last step at dt = 1 ms).
    * **The end is reached, never passed.**  u runs non-decreasing from
      u_start to exactly u_end.  A step that would carry u to or past u_end
      before the profile has ended is clamped to u_end; if the profile ends
      (the next sampling instant t_{k+1} is at or after the planned
      duration) with u still short of u_end, the sample at t_{k+1} is
      placed at u_end.  The last sample has zero velocity and acceleration;
      the signed gap it closes is ``Reference.end_gap``.  With the paper's
      settings (100 mm/s, 0.12 s ramps) eq. (8) falls short, by 6.1e-4 mm
      (heart) and 6.0e-3 mm (omega) at dt = 1 ms and by 6.1e-6 mm and
      1.4e-4 mm at dt = 0.1 ms.
    * **Everything is finite**, the unit tangent included: the curve must be
      regular (``NurbsCurve.check_regular``: no cusp, no near-zero C'(u),
      no zero-length knot span), checked once per curve.

    Parameters
    ----------
    curve : NurbsCurve
        The path (mm).
    profile : SCurveFeedrate
        The feedrate profile; anything with ``plan(length) -> FeedratePlan``
        whose plan covers exactly ``length``.
    dt : float
        Interpolation (sampling) period T, s. Jahanpour et al. use 1e-3 s; the envs
        use their control period (default 1e-4 s).
    step_tolerance : float, default STEP_TOLERANCE = 0.1
        The guarantee above, as a fraction of V_peak dt; in [1e-6, 1].
    max_samples : int, default MAX_REFERENCE_SAMPLES = 2e6
        Refuse a reference of more samples (:func:`reference_samples`,
        88 bytes each) before allocating it.

    Returns
    -------
    Reference
        Time, parameter, position, velocity, acceleration, tangent and
        commanded feed at every sample, with the plan, the step error, the
        end gap and the feedrate fluctuation.

    Raises
    ------
    TypeError
        If ``curve`` is not a ``NurbsCurve`` or ``profile`` has no ``plan``.
    ValueError
        If ``dt`` is not a finite real number > 0 (s); ``step_tolerance`` or
        ``max_samples`` is out of range; the profile's plan does not cover
        the curve's length; the reference would have more than
        ``max_samples`` samples (the message names the feedrate, ramp time,
        dt and the memory it would take); the curve is not regular (the
        message names the defect and its u); or the curve cannot be followed
        within the tolerance at this feed and dt (the message names u).

    Examples
    --------
    >>> from vcnc_gym.geometry import heart
    >>> from vcnc_gym.motion import SCurveFeedrate, interpolate
    >>> ref = interpolate(heart(), SCurveFeedrate(100.0, 0.12), dt=1e-3)
    >>> len(ref), float(ref.u[-1]), ref.position[-1].tolist()
    (3223, 6.0, [0.0, 0.0])
    >>> round(ref.end_gap * 1e3, 2)   # eq. (8) fell short of u_end by this, um
    0.61
    >>> ref.corrected_steps, ref.step_error < ref.step_tolerance
    (0, True)
    """
    if not isinstance(curve, NurbsCurve):
        raise TypeError(f"curve must be a NurbsCurve, got {type(curve).__name__}")
    _check_profile(profile)
    dt = positive("dt", dt, "s")
    step_tolerance = real("step_tolerance", step_tolerance, "fraction of feedrate x dt")
    if not 1e-6 <= step_tolerance <= 1.0:
        raise ValueError(f"step_tolerance must be in [1e-6, 1] (fraction of feedrate x dt), got {step_tolerance!r}")
    max_samples = integer("max_samples", max_samples, 2)
    curve.check_regular()
    u_start, u_end = curve.u_range
    length = float(curve.arc_length())
    plan = profile.plan(length)
    covered = float(plan.distance(plan.duration))
    if not abs(covered - length) <= 1e-9 * length:
        raise ValueError(
            f"profile.plan({length!r}) returned a plan covering {covered!r} mm, not the curve's {length!r} mm"
        )
    k_max = _check_cost(length, profile, plan, dt, max_samples) + 1

    out = ReferenceBuffers(
        t=np.empty(k_max),
        u=np.empty(k_max),
        position=np.empty((k_max, 2)),
        velocity=np.empty((k_max, 2)),
        acceleration=np.empty((k_max, 2)),
        tangent=np.empty((k_max, 2)),
        feedrate=np.empty(k_max),
    )
    t, u, pos, vel, acc, tan, feed = out
    info = np.zeros(INFO_SIZE)
    settings = InterpolationSettings(u_start, u_end, dt, plan.v_peak, step_tolerance)
    n = taylor_interpolate_kernel(curve.kernel_args, plan_arrays(plan), settings, out, info)
    end = info[INFO_END_CODE]
    _check_end(end, info, n, t, u, curve, plan, dt, step_tolerance)
    t, u, pos, vel, acc, tan, feed = (a[:n].copy() for a in (t, u, pos, vel, acc, tan, feed))
    _verify(curve, plan, dt, step_tolerance, info, t, u, pos, vel, acc, tan, feed)

    end_gap, end_gap_u = _end_gap(curve, plan, info, end)
    fluctuation, cruise_pct = _fluctuations(pos, t, plan, dt)

    return Reference(
        t=t,
        u=u,
        position=pos,
        velocity=vel,
        acceleration=acc,
        tangent=tan,
        feedrate=feed,
        dt=dt,
        length=length,
        plan=plan,
        step_tolerance=step_tolerance,
        step_error=float(info[INFO_STEP_ERROR] / (plan.v_peak * dt)),
        corrected_steps=int(info[INFO_CORRECTED]),
        end_gap=float(end_gap),
        end_gap_u=float(end_gap_u),
        feedrate_fluctuation=fluctuation,
        cruise_fluctuation_percent=cruise_pct,
    )


def _check_end(end, info, n: int, t, u, curve, plan, dt: float, step_tolerance: float) -> None:
    """ValueError for a kernel run that ended on a singular point, an unresolved step or a failed one."""
    if end == END_SINGULAR:
        raise ValueError(
            f"curve has C'(u) = 0 (or not finite) at u = {float(info[INFO_U_END])!r}: the feed relation of "
            "Jahanpour et al. (2014), eq. (9), is undefined there"
        )
    if end == END_UNRESOLVED:
        raise ValueError(_unresolved(curve, plan, dt, step_tolerance, float(info[INFO_U_END]), float(t[n - 1])))
    if end == END_FAILED:
        k = int(info[INFO_WORST_K])
        raise ValueError(
            _cannot_follow(curve, plan, dt, step_tolerance, k, u[: k + 2], np.diff(plan.distance(t[: k + 2])))
        )


def _end_gap(curve, plan, info, end) -> tuple[float, float]:
    """The signed arc length (mm) and parameter gap the last sample closes (``Reference.end_gap``,
    ``end_gap_u``)."""
    u_start, u_end = curve.u_range
    u_taylor, s_planned = float(info[INFO_U_END]), float(info[INFO_S_END])
    end_gap_u = u_end - u_taylor
    if end == END_PROFILE and u_taylor < u_end:
        travelled_left = float(curve.arc_length(max(u_taylor, u_start), u_end))
    else:  # at or past u_end: overshoot to first order, |C'(u_end)| (u - u_end)
        speed_end = float(np.linalg.norm(curve.derivatives(u_end, 1)[1]))
        travelled_left = -speed_end * (u_taylor - u_end)
    end_gap = travelled_left - (plan.length - s_planned)
    return end_gap, end_gap_u


def _fluctuations(pos, t, plan, dt: float) -> tuple[float, float]:
    """The feedrate fluctuation (fraction of V_peak) and the cruise's (percent); NaN where there is none."""
    # feedrate fluctuation over the steps made by eq. (8): all but the last
    v_act = np.linalg.norm(np.diff(pos, axis=0), axis=1)[:-1] / dt
    v_cmd = np.diff(plan.distance(t))[:-1] / dt
    if v_act.size:
        fluctuation = float(np.max(np.abs(v_act - v_cmd)) / plan.v_peak)
    else:
        fluctuation = float("nan")
    t0, t1 = t[:-2], t[1:-1]
    cruise = (np.abs(plan.velocity(t0) - plan.v_peak) <= 1e-12 * plan.v_peak) & (
        np.abs(plan.velocity(t1) - plan.v_peak) <= 1e-12 * plan.v_peak
    )
    if np.any(cruise):
        cruise_pct = float(100.0 * np.max(np.abs(v_act[cruise] - plan.v_peak)) / plan.v_peak)
    else:
        cruise_pct = float("nan")
    return fluctuation, cruise_pct


def _verify(curve, plan, dt, step_tolerance, info, t, u, pos, vel, acc, tan, feed) -> None:
    """Check the finished reference against what :func:`interpolate` promises; ValueError if it fails.

    Independent of the kernel's bookkeeping where it can be: finiteness,
    u from u_start to exactly u_end without going back, no chord longer than
    the commanded distance plus the tolerance (a chord is never longer than
    its arc); and the kernel's own arc-length error of every step.
    """
    u_start, u_end = curve.u_range
    tol = step_tolerance * plan.v_peak * dt
    for name, a in zip(_ARRAYS, (t, u, pos, vel, acc, tan, feed)):
        if not np.all(np.isfinite(a)):
            k = int(np.flatnonzero(~np.isfinite(a.reshape(len(t), -1)).all(axis=1))[0])
            raise ValueError(
                f"the reference's {name} is not finite at sample {k} (u = {u[k]!r}): "
                f"the curve's derivatives overflow there"
            )
    if u[0] != u_start or u[-1] != u_end or np.any(np.diff(u) < 0.0):
        raise ValueError("internal error: the reference's u does not run from u_start to u_end")
    chords = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    commanded = np.diff(plan.distance(t))
    excess = chords - commanded
    worst = int(np.argmax(excess)) if excess.size else 0
    kernel_error = float(info[INFO_STEP_ERROR])
    step_error = max(kernel_error, float(excess[worst]) if excess.size else 0.0)
    if not step_error <= tol * (1.0 + 1e-9):
        k = int(info[INFO_WORST_K]) if kernel_error >= (excess[worst] if excess.size else 0.0) else worst
        raise ValueError(_cannot_follow(curve, plan, dt, step_tolerance, k, u, commanded))


def _cannot_follow(curve, plan, dt, step_tolerance, k, u, commanded) -> str:
    """Why step k of the reference misses the tolerance, naming its u."""
    uk, uk1 = float(u[k]), float(u[k + 1])
    tol = step_tolerance * plan.v_peak * dt
    text = (
        f"the reference cannot follow the curve near u = {uk:.10g} (t = {k * dt:.6g} s): step {k} moves "
        f"{curve.arc_length(uk, uk1):.3g} mm along it for a commanded {commanded[k]:.3g} mm, off by more than "
        f"step_tolerance x V_peak x dt = {step_tolerance:g} x {plan.v_peak:.4g} mm/s x {dt!r} s = {tol:.3g} mm"
    )
    ends = np.array([uk, uk1])
    moves = _resolution(curve, ends)
    j = int(np.argmax(moves))
    if moves[j] > _RESOLUTION_SHARE * tol:
        return text + ": " + _squeezed(curve, float(ends[j]), float(moves[j]))
    return text + "; a smaller dt or feedrate may resolve it"


def _unresolved(curve, plan, dt, step_tolerance, u, t) -> str:
    """The message for a sample at u where one floating-point step of u moves too far."""
    tol = step_tolerance * plan.v_peak * dt
    move = float(_resolution(curve, np.array([u]))[0])
    return (
        f"the reference cannot follow the curve at u = {u!r} (t = {t:.6g} s): {_squeezed(curve, u, move)}. "
        f"Arc lengths there resolve no better than {move:.3g} mm, more than {_RESOLUTION_SHARE:g} x "
        f"step_tolerance x V_peak x dt = {_RESOLUTION_SHARE * tol:.3g} mm"
    )


def _resolution(curve, us: np.ndarray) -> np.ndarray:
    """How far one floating-point step of u moves along the curve at each u, mm."""
    speeds = np.linalg.norm(curve.derivatives_array(us, 1)[:, 1, :], axis=1)
    return speeds * np.spacing(np.maximum(np.abs(us), 1e-300))


def _squeezed(curve, u: float, move: float) -> str:
    """'``|C'(u)|`` = ..., so one floating-point step of u moves ... mm; the knot span [a, b] ...'."""
    knots = curve.knots
    i = min(int(np.searchsorted(knots, u, side="right")), len(knots) - 1)
    a, b = float(knots[i - 1]), float(knots[i])
    if not b > a:  # u_end itself: the last non-empty span
        a = float(knots[knots < b][-1])
    speed = float(np.linalg.norm(curve.derivatives(u, 1)[1]))
    return (
        f"|C'(u)| = {speed:.3g} mm per unit of u at u = {u!r}, so one floating-point step of u moves "
        f"{move:.3g} mm; the knot span [{a!r}, {b!r}] is too short in u for its {curve.arc_length(a, b):.3g} mm"
    )
