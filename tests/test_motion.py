"""Tests of vcnc_gym.motion: the S-curve feedrate and the Taylor interpolator.

Oracles that are not the code under test: scipy.integrate.quad (integrals of
the feed and of |C'(u)| over the knot spans), scipy.optimize (peak
acceleration), geomdl (NURBS points and derivatives, hence curvature), and
finite differences of the reference's own positions.
"""

from __future__ import annotations

import functools
import math
import time

import numpy as np

from vcnc_gym.motion.profile import plan_state
import pytest
from geomdl import NURBS
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.optimize import minimize_scalar

from vcnc_gym.geometry import NurbsCurve, heart, omega
from vcnc_gym.motion import Reference, SCurveFeedrate, interpolate
from vcnc_gym.motion.feedrate import scurve_acceleration, scurve_distance, scurve_velocity

V_PAPER = 100.0  # mm/s, Jahanpour et al.'s section 3
TA_PAPER = 0.12  # s, Jahanpour et al.'s section 3
SHAPES = {"heart": heart, "omega": omega}
CASES = [(s, dt) for s in SHAPES for dt in (1e-3, 1e-4)]


# --------------------------------------------------------------------------
# oracles and cached references
# --------------------------------------------------------------------------


@functools.lru_cache(maxsize=None)
def curve(name: str) -> NurbsCurve:
    return SHAPES[name]()


@functools.lru_cache(maxsize=None)
def reference(name: str, dt: float) -> Reference:
    return interpolate(curve(name), SCurveFeedrate(V_PAPER, TA_PAPER), dt)


@functools.lru_cache(maxsize=None)
def quad_length(name: str) -> float:
    """Arc length by adaptive quadrature of |C'(u)| span by span (C' from geomdl)."""
    g = geomdl_curve(name)
    knots = np.unique(curve(name).knots)

    def speed(u):
        return math.hypot(*g.derivatives(u, order=1)[1])

    return sum(quad(speed, a, b, epsabs=1e-12, epsrel=1e-13, limit=200)[0] for a, b in zip(knots[:-1], knots[1:]))


@functools.lru_cache(maxsize=None)
def geomdl_curve(name: str):
    c = curve(name)
    g = NURBS.Curve(normalize_kv=False)
    g.degree = c.degree
    g.ctrlptsw = [[x * w, y * w, w] for (x, y), w in zip(c.control_points.tolist(), c.weights.tolist())]
    g.knotvector = c.knots.tolist()
    return g


def geomdl_derivatives(name: str, us) -> np.ndarray:
    g = geomdl_curve(name)
    return np.array([g.derivatives(float(u), order=2) for u in us])


# --------------------------------------------------------------------------
# S-curve feedrate profile
# --------------------------------------------------------------------------


def test_paper_plan_numbers():
    plan = SCurveFeedrate(V_PAPER, TA_PAPER).plan(310.0)
    assert plan.v_peak == V_PAPER
    assert plan.cruise_time == pytest.approx((310.0 - V_PAPER * TA_PAPER) / V_PAPER, rel=1e-15)
    assert plan.duration == pytest.approx(2 * TA_PAPER + 2.98, rel=1e-15)


@pytest.mark.parametrize("length", [310.0, 12.0, 5.0])
def test_velocity_and_acceleration_continuous_at_phase_boundaries(length):
    plan = SCurveFeedrate(V_PAPER, TA_PAPER).plan(length)
    ta, tc = plan.ramp_time, plan.cruise_time
    eps = 1e-9  # s
    for tb in (0.0, ta, ta + tc, 2 * ta + tc):
        left, right = plan.velocity(tb - eps), plan.velocity(tb + eps)
        assert abs(right - left) < 1e-6, f"V jumps at t = {tb}"
        left, right = plan.acceleration(tb - eps), plan.acceleration(tb + eps)
        # |d2V/dt2| <= 6 V / T_a^2 ~ 4.2e4 mm/s^3, so 2 eps of it is ~1e-4
        assert abs(right - left) < 1e-3, f"dV/dt jumps at t = {tb}"
    assert plan.acceleration(ta / 2) > 0.0 and plan.acceleration(ta + tc + ta / 2) < 0.0


@pytest.mark.parametrize("length", [310.1146, 51.1434, 12.0, 5.0, 0.3])
def test_integral_of_feed_is_length(length):
    plan = SCurveFeedrate(V_PAPER, TA_PAPER).plan(length)
    ta, tc = plan.ramp_time, plan.cruise_time
    integral, _ = quad(plan.velocity, 0.0, plan.duration, points=[ta, ta + tc], epsabs=1e-12, limit=200)
    assert integral == pytest.approx(length, rel=1e-10)
    # S(t) against quad at a few interior times, and its end value
    for t in np.linspace(0.0, plan.duration, 7)[1:-1]:
        expected, _ = quad(plan.velocity, 0.0, t, epsabs=1e-12, limit=200)
        assert plan.distance(t) == pytest.approx(expected, rel=1e-10, abs=1e-12)
    assert plan.distance(plan.duration + 1.0) == pytest.approx(length, rel=1e-14)


@settings(max_examples=60, deadline=None)
@given(
    feedrate=st.floats(1.0, 500.0),
    ramp_time=st.floats(0.01, 1.0),
    length=st.floats(0.01, 1000.0),
)
def test_integral_of_feed_is_length_any_plan(feedrate, ramp_time, length):
    plan = SCurveFeedrate(feedrate, ramp_time).plan(length)
    ta, tc = plan.ramp_time, plan.cruise_time
    integral, _ = quad(plan.velocity, 0.0, plan.duration, points=[ta, ta + tc], epsabs=0.0, epsrel=1e-12)
    assert integral == pytest.approx(length, rel=1e-9)
    assert plan.v_peak <= feedrate * (1 + 1e-15)


@pytest.mark.parametrize("length", [310.0, 5.0])
def test_peak_acceleration_is_one_and_a_half_v_over_ta(length):
    plan = SCurveFeedrate(V_PAPER, TA_PAPER).plan(length)
    res = minimize_scalar(
        lambda t: -plan.acceleration(t), bounds=(0.0, plan.ramp_time), method="bounded", options={"xatol": 1e-10}
    )
    assert -res.fun == pytest.approx(1.5 * plan.v_peak / plan.ramp_time, rel=1e-9)
    assert res.x == pytest.approx(plan.ramp_time / 2, abs=1e-6)
    grid = np.linspace(-0.1, plan.duration + 0.1, 20001)
    assert np.max(np.abs(plan.acceleration(grid))) <= 1.5 * plan.v_peak / plan.ramp_time * (1 + 1e-12)
    # dV/dt is the derivative of V (central differences away from the boundaries)
    t = np.linspace(0.01, plan.duration - 0.01, 1001)
    h = 1e-6
    fd = (plan.velocity(t + h) - plan.velocity(t - h)) / (2 * h)
    np.testing.assert_allclose(plan.acceleration(t), fd, atol=1e-3)


def test_ramps_are_zero_acceleration_at_ends_and_cover_half_vta():
    plan = SCurveFeedrate(V_PAPER, TA_PAPER).plan(310.0)
    for tb in (0.0, plan.ramp_time, plan.ramp_time + plan.cruise_time, plan.duration):
        assert plan.acceleration(tb) == pytest.approx(0.0, abs=1e-9)
    assert plan.distance(plan.ramp_time) == pytest.approx(V_PAPER * TA_PAPER / 2, rel=1e-14)
    assert plan.velocity(plan.ramp_time / 2) == pytest.approx(V_PAPER / 2, rel=1e-14)
    assert plan.velocity(-1.0) == 0.0 and plan.velocity(plan.duration + 1e-9) == 0.0


def test_short_path_lowers_peak_feed():
    length = 6.0  # mm < V T_a = 12 mm
    profile = SCurveFeedrate(V_PAPER, TA_PAPER)
    plan = profile.plan(length)
    assert plan.v_peak == pytest.approx(length / TA_PAPER, rel=1e-15)
    assert plan.cruise_time == 0.0
    assert profile.duration(length) == pytest.approx(2 * TA_PAPER, rel=1e-15)
    t = np.linspace(0.0, plan.duration, 10001)
    assert np.max(plan.velocity(t)) == pytest.approx(length / TA_PAPER, rel=1e-6)
    # the long-path branch at exactly V T_a has no cruise and the full feed
    edge = profile.plan(V_PAPER * TA_PAPER)
    assert edge.v_peak == V_PAPER and edge.cruise_time == 0.0


def test_vectorised_equals_scalar_kernels():
    profile = SCurveFeedrate(80.0, 0.05)
    plan = profile.plan(40.0)
    t = np.linspace(-0.1, plan.duration + 0.1, 97).reshape(97, 1)
    v = profile.velocity(t, 40.0)
    assert v.shape == t.shape
    scalars = (plan.v_peak, plan.ramp_time, plan.cruise_time)
    for ti, vi, ai, si in zip(t.ravel(), v.ravel(), plan.acceleration(t).ravel(), plan.distance(t).ravel()):
        assert vi == scurve_velocity(ti, *scalars)
        assert ai == scurve_acceleration(ti, *scalars)
        assert si == scurve_distance(ti, *scalars)
        # the interpolator's piecewise quartic form of the same plan
        s_pp, v_pp, a_pp = plan_state(ti, *plan.kernel_args)
        assert abs(v_pp - vi) <= 1e-12 * 80.0 and abs(a_pp - ai) <= 1e-9 * 80.0 / 0.05
        assert abs(s_pp - si) <= 1e-12 * 40.0
    assert isinstance(plan.velocity(0.01), float)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), "fast", None, True])
@pytest.mark.parametrize("argument", ["feedrate", "ramp_time"])
def test_bad_profile_arguments_raise(argument, bad):
    with pytest.raises(ValueError, match=argument):
        SCurveFeedrate(**{argument: bad})


@pytest.mark.parametrize("bad", [0.0, -3.0, float("nan"), float("inf"), None])
def test_bad_length_raises(bad):
    with pytest.raises(ValueError, match="length"):
        SCurveFeedrate().plan(bad)
    with pytest.raises(ValueError, match="length"):
        SCurveFeedrate().velocity(0.1, bad)


# --------------------------------------------------------------------------
# interpolator: heart and omega at 1 ms and 0.1 ms
# --------------------------------------------------------------------------


@pytest.mark.parametrize("name,dt", CASES)
def test_traversed_length_matches_quadrature(name, dt):
    """Chord sum plus the chord-to-arc correction equals the quad arc length.

    A chord c of an arc s with curvature kappa is c = s - kappa^2 s^3 / 24
    + O(s^4) (circle: c = 2 sin(kappa s / 2) / kappa); with kappa taken at
    the middle of the step the O(s^4) term (kappa kappa' s^4 / 24) cancels,
    so sum (c + kappa^2 c^3 / 24) leaves O(s^5) per step: 1e-5 mm in total
    for the omega at 1 ms (kappa up to 5.4 / mm, c up to 0.1 mm).
    """
    ref = reference(name, dt)
    c = ref.chord_lengths
    assert ref.traversed_length == pytest.approx(np.sum(c), rel=1e-15)
    u_mid = 0.5 * (ref.u[1:] + ref.u[:-1])
    d = curve(name).derivatives_array(u_mid, 2)
    speed = np.hypot(d[:, 1, 0], d[:, 1, 1])
    kappa = np.abs(d[:, 1, 0] * d[:, 2, 1] - d[:, 1, 1] * d[:, 2, 0]) / speed**3
    corrected = ref.traversed_length + np.sum(kappa**2 * c**3 / 24.0)
    L = quad_length(name)
    assert abs(corrected - L) < 1e-3
    assert ref.traversed_length < L  # chords are shorter than arcs
    assert ref.length == pytest.approx(L, abs=1e-9)


@pytest.mark.parametrize("name,dt", CASES)
def test_parameter_runs_from_start_to_exactly_the_end(name, dt):
    ref = reference(name, dt)
    u_start, u_end = curve(name).u_range
    assert ref.u[0] == u_start
    assert ref.u[-1] == u_end
    assert np.all(ref.u <= u_end)
    assert np.all(np.diff(ref.u) >= 0.0)
    assert np.count_nonzero(ref.u == u_end) == 1
    np.testing.assert_array_equal(ref.t, np.arange(len(ref)) * dt)
    np.testing.assert_array_equal(ref.velocity[-1], 0.0)
    np.testing.assert_array_equal(ref.acceleration[-1], 0.0)


@pytest.mark.parametrize("name,dt", CASES)
def test_positions_are_curve_points(name, dt):
    ref = reference(name, dt)
    np.testing.assert_allclose(ref.position, curve(name).points(ref.u), rtol=0, atol=1e-12)
    idx = np.unique(np.r_[np.arange(0, len(ref), 97), len(ref) - 1])
    np.testing.assert_allclose(ref.position[idx], geomdl_derivatives(name, ref.u[idx])[:, 0], atol=1e-9)
    np.testing.assert_allclose(ref.position[-1], curve(name).point(curve(name).u_range[1]), atol=0)


# observed max |central difference - velocity| in mm/s, excluding the last
# two samples: heart 5.3e-3 / 5.3e-5, omega 4.4 / 0.39 (dt = 1e-3 / 1e-4).
# Both the finite difference (dt^2 / 6 |x'''|, |x'''| ~ kappa^2 V^3 = 2.9e7
# mm/s^3 on the omega) and eq. (8) (O(dt^2), larger where C'' jumps at the
# omega's knots) are second order in dt.
VELOCITY_FD_TOL = {("heart", 1e-3): 2e-2, ("heart", 1e-4): 2e-4, ("omega", 1e-3): 10.0, ("omega", 1e-4): 1.0}


@pytest.mark.parametrize("name,dt", CASES)
def test_velocity_matches_finite_differences(name, dt):
    ref = reference(name, dt)
    fd = (ref.position[2:] - ref.position[:-2]) / (2 * dt)
    err = np.linalg.norm(fd - ref.velocity[1:-1], axis=1)[:-1]  # the last step closes end_gap
    assert np.max(err) < VELOCITY_FD_TOL[(name, dt)]
    # eq. (9): the velocity command has the commanded feed as its norm
    np.testing.assert_allclose(np.linalg.norm(ref.velocity[:-1], axis=1), ref.feedrate[:-1], rtol=1e-12, atol=1e-12)
    # the interpolator evaluates the plan in its piecewise-quartic form: equal up to rounding
    np.testing.assert_allclose(ref.feedrate[:-1], ref.plan.velocity(ref.t[:-1]), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name,dt", CASES)
def test_acceleration_is_dvdt_along_and_kappa_v2_across(name, dt):
    """Eq. (10) makes the tangential acceleration dV/dt and the normal one kappa V^2."""
    ref = reference(name, dt)
    idx = np.arange(1, len(ref) - 1, max(1, len(ref) // 600))
    d = geomdl_derivatives(name, ref.u[idx])
    c1, c2 = d[:, 1], d[:, 2]
    speed = np.linalg.norm(c1, axis=1)
    tangent = c1 / speed[:, None]
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    kappa = (c1[:, 0] * c2[:, 1] - c1[:, 1] * c2[:, 0]) / speed**3  # signed, 1/mm
    a = ref.acceleration[idx]
    v = ref.feedrate[idx]
    scale = np.max(np.abs(kappa)) * V_PAPER**2 + 1.5 * V_PAPER / TA_PAPER
    np.testing.assert_allclose(np.sum(a * tangent, axis=1), ref.plan.acceleration(ref.t[idx]), atol=1e-9 * scale)
    np.testing.assert_allclose(np.sum(a * normal, axis=1), kappa * v**2, atol=1e-9 * scale)


# observed (fraction of V_peak): heart 6.9e-5 / 6.9e-7, omega 2.9e-2 / 5.2e-3;
# the omega's come from steps across knots where its C'' jumps (degree 2).
FLUCTUATION_TOL = {("heart", 1e-3): 2e-4, ("heart", 1e-4): 2e-6, ("omega", 1e-3): 0.05, ("omega", 1e-4): 0.01}


@pytest.mark.parametrize("name,dt", CASES)
def test_feedrate_fluctuation_small(name, dt):
    ref = reference(name, dt)
    v_act = ref.actual_feedrate[:-1]
    v_cmd = ref.commanded_step_feedrate[:-1]
    expected = np.max(np.abs(v_act - v_cmd)) / ref.plan.v_peak
    assert ref.feedrate_fluctuation == pytest.approx(expected, rel=1e-12)
    assert ref.feedrate_fluctuation < FLUCTUATION_TOL[(name, dt)]
    assert ref.cruise_fluctuation_percent <= 100 * ref.feedrate_fluctuation * (1 + 1e-12)
    print(
        f"{name} dt={dt:g}: fluctuation {ref.feedrate_fluctuation:.3e} of V_peak, "
        f"cruise {ref.cruise_fluctuation_percent:.4f} %, end gap {ref.end_gap:.3e} mm"
    )


@pytest.mark.parametrize("name", SHAPES)
def test_duration_and_end_gap(name):
    plan = SCurveFeedrate(V_PAPER, TA_PAPER).plan(quad_length(name))
    gaps = []
    for dt in (1e-3, 1e-4):
        ref = reference(name, dt)
        assert ref.plan.duration == pytest.approx(plan.duration, rel=1e-12)
        assert 0.0 <= ref.duration - plan.duration < dt
        # eq. (8) falls short of u_end at the end of the profile: the final
        # sample closes a small positive gap, measured along the path
        assert ref.end_gap > 0.0 and ref.end_gap_u > 0.0
        u_taylor = curve(name).u_range[1] - ref.end_gap_u
        arc, _ = quad(lambda u: np.linalg.norm(curve(name).derivatives(u, 1)[1]), u_taylor, curve(name).u_range[1])
        assert ref.end_gap == pytest.approx(arc, rel=1e-9)
        gaps.append(ref.end_gap)
    assert gaps[0] < 1e-2  # mm at 1 ms
    assert gaps[1] < gaps[0] / 20  # second order (x100 heart, x42 omega)


def test_interpolation_speed_heart_at_0p1_ms():
    c, profile = curve("heart"), SCurveFeedrate(V_PAPER, TA_PAPER)
    interpolate(c, profile, 1e-4)  # compiled / loaded from cache
    best = min(_timed(lambda: interpolate(c, profile, 1e-4)) for _ in range(5))
    assert best < 0.1


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def test_short_straight_path():
    line = NurbsCurve([[0.0, 0.0], [3.0, 4.0]], [1.0, 1.0], [0.0, 0.0, 1.0, 1.0], 1)
    ref = interpolate(line, SCurveFeedrate(V_PAPER, TA_PAPER), 1e-4)
    assert ref.plan.v_peak == pytest.approx(5.0 / TA_PAPER, rel=1e-12)
    assert ref.u[-1] == 1.0
    np.testing.assert_allclose(ref.position[-1], [3.0, 4.0], atol=0)
    assert abs(ref.end_gap) < 1e-6
    assert np.isnan(ref.cruise_fluctuation_percent)
    # along a straight line eq. (10) is exact in the geometry: the motion is the plan
    np.testing.assert_allclose(np.linalg.norm(ref.position, axis=1)[:-1], ref.plan.distance(ref.t[:-1]), atol=1e-6)


def test_step_past_the_end_is_clamped():
    """The kernel with a plan 1 % longer than the curve: eq. (8) reaches u_end early and its step is clamped.

    (``interpolate`` refuses such a plan; the kernel's clamping is what keeps a
    reference from passing u_end when eq. (8) runs ahead at the end.)
    """
    from vcnc_gym.motion import interpolator as I
    from vcnc_gym.motion.profile import plan_arrays

    c = curve("omega")
    plan = SCurveFeedrate(V_PAPER, TA_PAPER).plan(1.01 * c.arc_length())
    dt = 1e-4
    k_max = int(math.ceil(plan.duration / dt)) + 2
    t, u, feed = (np.empty(k_max) for _ in range(3))
    pos, vel, acc, tan = (np.empty((k_max, 2)) for _ in range(4))
    info = np.zeros(I.INFO_SIZE)
    u_start, u_end = c.u_range
    n = I.taylor_interpolate_kernel(
        c.kernel_args,
        plan_arrays(plan),
        I.InterpolationSettings(u_start, u_end, dt, plan.v_peak, 0.1),
        I.ReferenceBuffers(t, u, pos, vel, acc, tan, feed),
        info,
    )
    assert info[I.INFO_END_CODE] == I.END_CLAMPED
    u = u[:n]
    assert u[-1] == u_end and np.all(u <= u_end) and np.all(np.diff(u) >= 0)
    assert t[n - 1] < plan.duration - 0.001
    # ahead of the plan by about the 1 % of path it still had to go
    assert plan.length - plan.distance(t[n - 1]) == pytest.approx(0.01 * c.arc_length(), rel=0.1)
    np.testing.assert_array_equal(vel[n - 1], 0.0)
    np.testing.assert_array_equal(acc[n - 1], 0.0)


def test_reference_arrays_are_read_only():
    ref = reference("omega", 1e-3)
    for name in ("t", "u", "position", "velocity", "acceleration", "tangent", "feedrate"):
        with pytest.raises(ValueError):
            getattr(ref, name)[0] = 1.0
    with pytest.raises(AttributeError):
        ref.dt = 1.0


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan"), float("inf"), None, "1ms", "1e-3", True, 1e-3j])
def test_bad_dt_raises(bad):
    with pytest.raises(ValueError, match="dt"):
        interpolate(curve("omega"), SCurveFeedrate(), bad)


def test_bad_curve_and_profile_raise():
    with pytest.raises(TypeError, match="curve must be a NurbsCurve"):
        interpolate(np.zeros((5, 2)), SCurveFeedrate(), 1e-3)
    with pytest.raises(TypeError, match="profile"):
        interpolate(curve("omega"), 100.0, 1e-3)


def test_singular_curve_raises():
    # repeated first control point: C'(0) = 0, eq. (9) undefined
    cusp = NurbsCurve([[0.0, 0.0], [0.0, 0.0], [10.0, 0.0]], [1, 1, 1], [0, 0, 0, 1, 1, 1], 2)
    with pytest.raises(ValueError, match=r"near-zero derivative C'\(u\) at its start, u = 0: \|C'\(u\)\| = 0 mm"):
        interpolate(cusp, SCurveFeedrate(), 1e-3)


@pytest.mark.parametrize("name,dt", CASES)
def test_tangent_is_the_unit_derivative(name, dt):
    ref = reference(name, dt)
    idx = np.unique(np.r_[np.arange(0, len(ref), 211), len(ref) - 1])
    d1 = geomdl_derivatives(name, ref.u[idx])[:, 1]
    np.testing.assert_allclose(ref.tangent[idx], d1 / np.linalg.norm(d1, axis=1, keepdims=True), atol=1e-12)
    # and the velocity command points along it
    np.testing.assert_allclose(ref.velocity[:-1], ref.tangent[:-1] * ref.feedrate[:-1, None], atol=1e-9)
