"""Tests of vcnc_gym.motion.lookahead: the curvature-limited, jerk-limited look-ahead feedrate.

Oracles that are not the code under test: the reference the interpolator
makes from the plan (its velocity, acceleration and tangent at every sample,
finite differences of its feed), the curvature from the NURBS evaluator at
the reference's own parameters and on a dense grid of u with the arc length
by the trapezoid rule (not the planner's grid or quadrature), geomdl and
scipy's bounded minimisation for the omega's sharpest curvature, ruckig's
time-optimal jerk-limited trajectories (straight line, circle, every section
of the omega's plan), closed-form lower bounds on the cycle time, and Jahanpour
et al.'s plant table for the default limits.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from geomdl import NURBS
from ruckig import InputParameter, Result, Ruckig, Trajectory
from scipy.optimize import minimize_scalar

from vcnc_gym.geometry import SHAPES, NurbsCurve, polyline, smooth_polyline
from vcnc_gym.geometry.shapes import circle, corners_vertices
from vcnc_gym.motion import (
    JlapFeedrate,
    LookaheadFeedrate,
    LookaheadPlan,
    SCurveFeedrate,
    interpolate,
)
from vcnc_gym.motion.lookahead import JAHANPOUR2014_FEEDRATE, JAHANPOUR2014_PATH_ACCELERATION, JAHANPOUR2014_PATH_JERK

F, A, J = JAHANPOUR2014_FEEDRATE, JAHANPOUR2014_PATH_ACCELERATION, JAHANPOUR2014_PATH_JERK
DT = 1e-4  # s, the envs' control period
# relative, on every limit at the reference's samples: eq. (8) puts C(u_k) within the step error
# (< 0.002 V_peak dt here, a few nm) of where S(t_k) is along the path, so V(t_k) meets the curvature
# of a point a few nm from the one it was planned for (1e-6 at a 0.07 mm radius of a random curve)
TOL = 1e-5


@functools.lru_cache(maxsize=None)
def profile(name: str) -> LookaheadFeedrate:
    return LookaheadFeedrate(SHAPES[name]())


@functools.lru_cache(maxsize=None)
def reference(name: str):
    return interpolate(profile(name).curve, profile(name), DT)


def curvature(curve: NurbsCurve, u) -> np.ndarray:
    d = curve.derivatives_array(u, 2)
    return np.abs(d[:, 1, 0] * d[:, 2, 1] - d[:, 1, 1] * d[:, 2, 0]) / np.hypot(d[:, 1, 0], d[:, 1, 1]) ** 3


def ruckig_rest_to_rest(distance, v_max, a_max, j_max, v0=0.0, v1=0.0):
    """ruckig's time-optimal trajectory from (0, v0, 0) to (distance, v1, 0)."""
    inp = InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v0], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [distance], [v1], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v_max], [a_max], [j_max]
    traj = Trajectory(1)
    assert Ruckig(1).calculate(inp, traj) == Result.Working
    return traj


def check_reference(curve: NurbsCurve, ref, feedrate, a_n, j_n, a_t, j_t):
    """Every sample of the reference within the limits; from rest to rest; to the end of the curve."""
    kappa = curvature(curve, ref.u)
    speed = np.linalg.norm(ref.velocity, axis=1)
    tan, acc = ref.tangent, ref.acceleration
    assert np.all(speed <= feedrate * (1 + 1e-12))
    assert np.all(speed**2 * kappa <= a_n * (1 + TOL))
    assert np.all(np.abs(acc[:, 0] * tan[:, 1] - acc[:, 1] * tan[:, 0]) <= a_n * (1 + TOL))  # normal part
    assert np.all(kappa**2 * speed**3 <= j_n * (1 + TOL))
    assert np.all(np.abs(np.sum(acc * tan, axis=1)) <= a_t * (1 + TOL))  # tangential part, dV/dt
    # finite differences of the commanded feed: means of dV/dt and d2V/dt2 over one and two steps
    assert np.all(np.abs(np.diff(ref.feedrate)) / ref.dt <= a_t * (1 + TOL))
    assert np.all(np.abs(np.diff(ref.feedrate, 2)) / ref.dt**2 <= j_t * (1 + TOL))
    # rest to rest, the whole curve
    lo, hi = curve.u_range
    assert ref.feedrate[0] == 0.0 and ref.u[0] == lo
    assert ref.u[-1] == hi and np.all(ref.velocity[-1] == 0.0)
    np.testing.assert_allclose(ref.position[-1], curve.point(hi), atol=1e-12)
    assert abs(ref.end_gap) < 1e-4
    plan = ref.plan
    assert plan.velocity(plan.duration) == 0.0 and plan.acceleration(0.0) == 0.0
    assert abs(plan.distance(plan.duration) - ref.length) <= 1e-9 * ref.length


# --------------------------------------------------------------------------
# the paper's contours
# --------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["omega", "heart"])
def test_reference_within_the_limits(name):
    check_reference(profile(name).curve, reference(name), F, A, J, A, J)


@pytest.mark.parametrize("name", ["omega", "heart"])
def test_below_the_limit_between_the_samples(name):
    """V(s)^2 kappa(s) <= A_n on a grid of 10^6 u (about 10 times the planner's), the arc length by
    the trapezoid rule on |C'(u)|: the maxima of kappa are not missed between the planner's samples."""
    curve = profile(name).curve
    plan = profile(name).plan(curve.arc_length())
    u = np.linspace(*curve.u_range, 1_000_001)
    d = curve.derivatives_array(u, 2)
    speed = np.hypot(d[:, 1, 0], d[:, 1, 1])
    s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(u))])
    assert abs(s[-1] - plan.length) < 1e-8 * plan.length
    v = plan.feed_at(s * plan.length / s[-1])
    kappa = np.abs(d[:, 1, 0] * d[:, 2, 1] - d[:, 1, 1] * d[:, 2, 0]) / speed**3
    assert np.max(v**2 * kappa) <= A * (1 + 1e-9)
    assert np.max(kappa**2 * v**3) <= J * (1 + 1e-9)


def omega_peak_curvature() -> tuple[float, float]:
    """The omega's largest curvature (1/mm) and its u, from geomdl's derivatives and scipy."""
    g = NURBS.Curve()
    c = SHAPES["omega"]()
    g.degree = c.degree
    g.ctrlptsw = [[x * w, y * w, w] for (x, y), w in zip(c.control_points.tolist(), c.weights.tolist())]
    g.knotvector = c.knots.tolist()

    def minus_kappa(u):
        _, (x1, y1), (x2, y2) = g.derivatives(u, order=2)
        return -abs(x1 * y2 - y1 * x2) / math.hypot(x1, y1) ** 3

    us = np.linspace(0.0, 1.0, 4001)
    u0 = us[np.argmin([minus_kappa(u) for u in us])]
    best = minimize_scalar(minus_kappa, bounds=(u0 - 1e-3, u0 + 1e-3), method="bounded", options={"xatol": 1e-12})
    return -best.fun, best.x


@pytest.mark.parametrize("normal_jerk", [J, 1e9])
def test_omega_corners_pass_at_their_feasible_speed(normal_jerk):
    """At the sharpest point of each 0.19 mm corner the feed is min(sqrt(A_n / kappa), (J_n / kappa^2)^(1/3)):
    the jerk bound with the defaults (10.1 mm/s), the acceleration bound when J_n is out of the way (13.7)."""
    kappa_max, u_max = omega_peak_curvature()
    expected = min(math.sqrt(A / kappa_max), (normal_jerk / kappa_max**2) ** (1 / 3))
    assert math.isclose(expected, 10.137 if normal_jerk == J else 13.650, rel_tol=1e-4)
    curve = SHAPES["omega"]()
    la = LookaheadFeedrate(curve, normal_jerk=normal_jerk)
    plan = la.plan(curve.arc_length())
    for u in (u_max, 1.0 - u_max):  # the omega is symmetric
        s = curve.arc_length(0.0, u)
        assert math.isclose(float(plan.feed_at(np.array([s]))[0]), expected, rel_tol=1e-6)
    assert math.isclose(float(plan.limit_speed.min()), expected, rel_tol=1e-9)
    check_reference(curve, interpolate(curve, la, DT), F, A, normal_jerk, A, J)


def test_cycle_times_against_the_s_curve_and_lower_bounds():
    """The look-ahead is slower than Jahanpour et al.'s S-curve (which ignores the curvature), and no faster
    than two bounds any feed below v_lim must respect: int ds / v_lim, and the bidirectional
    acceleration-only scan (v^2 changes by at most 2 A_t ds)."""
    expected = {"omega": 0.986, "heart": 3.286}  # s, with the default limits (the S-curve: 0.631, 3.221)
    for name, duration in expected.items():
        curve = profile(name).curve
        plan = profile(name).plan(curve.arc_length())
        s_curve = SCurveFeedrate().plan(curve.arc_length()).duration
        assert abs(plan.duration - duration) < 5e-4
        assert plan.duration > s_curve
        s, v_lim = plan.limit_arc, plan.limit_speed
        ds = np.diff(s)
        assert plan.duration >= np.sum(ds / np.maximum(v_lim[1:], v_lim[:-1]))
        w = v_lim**2
        w[0] = w[-1] = 0.0
        for i in range(ds.size):
            w[i + 1] = min(w[i + 1], w[i] + 2 * A * ds[i])
        for i in reversed(range(ds.size)):
            w[i] = min(w[i], w[i + 1] + 2 * A * ds[i])
        bound = np.sum(2 * ds / np.maximum(np.sqrt(w[1:]) + np.sqrt(w[:-1]), 1e-300))
        assert bound < plan.duration < 1.2 * bound


def test_every_section_is_time_optimal():
    """Each section of the omega's plan is ruckig's time-optimal trajectory between its end feeds
    (acceleration zero at both) with the section's peak as the speed limit."""
    plan = profile("omega").plan(profile("omega").curve.arc_length())
    assert isinstance(plan, LookaheadPlan) and len(plan.sections) > 2
    for sec in plan.sections:
        traj = ruckig_rest_to_rest(sec.s_end - sec.s_start, sec.v_peak, A, J, sec.v_start, sec.v_end)
        assert abs(traj.duration - sec.duration) < 1e-9


# --------------------------------------------------------------------------
# curves whose answer is known
# --------------------------------------------------------------------------


@pytest.mark.parametrize("length", [100.0, 5.0])
def test_straight_line_is_the_plain_jerk_limited_profile(length):
    """kappa = 0: the rest-to-rest JLAP, ruckig's time-optimal trajectory (100 mm reaches the feed, 5 mm does not)."""
    line = NurbsCurve([[0, 0], [length * 0.6, length * 0.8]], [1, 1], [0, 0, 1, 1], 1)
    plan = LookaheadFeedrate(line).plan(line.arc_length())
    traj = ruckig_rest_to_rest(length, F, A, J)
    assert abs(plan.duration - traj.duration) < 1e-9
    ts = np.linspace(0.0, traj.duration, 501)
    ours = np.stack([plan.distance(ts), plan.velocity(ts), plan.acceleration(ts)], axis=1)
    theirs = np.array([np.ravel(traj.at_time(t)) for t in ts])
    np.testing.assert_allclose(ours, theirs, atol=1e-8)
    jlap = JlapFeedrate(F, A, J).plan(length)
    np.testing.assert_allclose(plan.breaks, jlap.breaks, rtol=1e-12)
    np.testing.assert_allclose(plan.coeffs, jlap.coeffs, rtol=1e-12, atol=1e-12)
    check_reference(line, interpolate(line, LookaheadFeedrate(line), DT), F, A, J, A, J)


def test_circle_runs_at_its_constant_limit():
    """Purtojo et al.'s 1 mm circle: kappa = 1/mm everywhere, v_lim = min(F, sqrt(A_n R), (J_n R^2)^(1/3)) =
    31.07 mm/s, one rest-to-rest section below it (its rounding noise is not a string of minima)."""
    curve = circle(1.0)
    la = LookaheadFeedrate(curve)
    plan = la.plan(curve.arc_length())
    v_c = min(F, math.sqrt(A), J ** (1 / 3))
    assert len(plan.sections) <= 2 and math.isclose(plan.v_peak, v_c, rel_tol=1e-9)
    traj = ruckig_rest_to_rest(2 * math.pi, v_c, A, J)
    assert abs(plan.duration - traj.duration) < 1e-8
    check_reference(curve, interpolate(curve, la, DT), F, A, J, A, J)


def test_random_curves_within_the_limits():
    rng = np.random.default_rng(7)
    for _ in range(4):
        n, p = int(rng.integers(4, 9)), int(rng.integers(2, 4))
        points = np.cumsum(rng.normal(size=(n, 2)) * 10.0, axis=0)
        knots = np.r_[[0.0] * (p + 1), np.sort(rng.uniform(0, 1, n - p - 1)), [1.0] * (p + 1)]
        curve = NurbsCurve(points, rng.uniform(0.3, 3.0, n), knots, p)
        la = LookaheadFeedrate(curve, 60.0, 800.0, 2e4, 1500.0, 5e4)
        check_reference(curve, interpolate(curve, la, DT), 60.0, 800.0, 2e4, 1500.0, 5e4)


def test_smoothed_corners_with_simba_limits():
    """Simba et al.'s blended test path (accepted as its SmoothedPolyline) at Simba et al.'s limits."""
    path = smooth_polyline(corners_vertices(), 0.05, 4000.0, 1.6e5)
    la = LookaheadFeedrate(path, 50.0, 4000.0, 1.6e5, 4000.0, 1.6e5)
    assert la.curve is path.curve
    check_reference(path.curve, interpolate(path.curve, la, DT), 50.0, 4000.0, 1.6e5, 4000.0, 1.6e5)


# --------------------------------------------------------------------------
# the default limits and the arguments
# --------------------------------------------------------------------------


def test_default_limits_from_jahanpour_drive():
    """A: below what 5 V gives the weaker axis at 100 mm/s against friction at the worst vertex of the
    box (1262 mm/s^2), about half its nominal (2105); the braking deceleration (friction helping) gives
    the issue's 1.9 mm stop from 100 mm/s.  J: A lambda / (2 pi), lambda of the SMC in Jahanpour et al.'s Table 2."""
    from vcnc_baselines.feedback.smc import SMC_TABLE2
    from vcnc_gym.plants import vcnc_feed_drive as fd

    def capability(p, v, braking):
        friction = np.maximum(p[:, fd.IDX_T_COUL_POS], -p[:, fd.IDX_T_COUL_NEG])
        if braking:
            friction = np.minimum(p[:, fd.IDX_T_COUL_POS], -p[:, fd.IDX_T_COUL_NEG])
        torque = p[:, fd.IDX_K_T] * p[:, fd.IDX_K_A] * p[:, fd.IDX_U_MAX]
        viscous = p[:, fd.IDX_B] * v / p[:, fd.IDX_R_G]
        sign = 1.0 if braking else -1.0
        return p[:, fd.IDX_R_G] * (torque + sign * (friction + viscous)) / p[:, fd.IDX_J]

    nominal = capability(fd.nominal_parameters(), F, False)
    worst = min(capability(v, F, False).min() for v in fd.uncertainty_vertices())
    braking = min(capability(v, F, True).min() for v in fd.uncertainty_vertices())
    assert round(nominal.min()) == 2105 and round(worst) == 1262
    assert 0.75 * worst < A < 0.8 * worst and 0.45 * nominal.min() < A < 0.5 * nominal.min()
    assert round(F**2 / (2 * braking), 2) == 1.97
    assert 0.9 * A * SMC_TABLE2["lam"] / (2 * math.pi) < J <= A * SMC_TABLE2["lam"] / (2 * math.pi)


@pytest.mark.parametrize(
    "name", ["feedrate", "normal_acceleration", "normal_jerk", "tangential_acceleration", "tangential_jerk", "spacing"]
)
@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan, True, "100", 1j])
def test_bad_arguments_are_refused(name, value):
    with pytest.raises(ValueError, match=name):
        LookaheadFeedrate(SHAPES["omega"](), **{name: value})


def test_bad_curves_are_refused():
    with pytest.raises(TypeError, match="NurbsCurve"):
        LookaheadFeedrate([[0, 0], [1, 0]])
    with pytest.raises(ValueError, match="corner"):
        LookaheadFeedrate(polyline(corners_vertices()))
    with pytest.raises(ValueError, match="own curve"):
        profile("omega").plan(10.0)
    with pytest.raises(ValueError, match="spacing"):
        LookaheadFeedrate(SHAPES["heart"](), spacing=1e-5).plan(310.0)
