"""Jerk-limited feedrate planning, Simba et al.'s section III (vcnc_gym.motion.jlap).

Oracle that is not the code under test: ruckig, whose 1-DoF time-optimal
jerk-limited trajectories (position and velocity interfaces) give the
duration and the path of every straight section and feed change.  Also the
parameter table of Simba et al.'s plant (the limits' derivation) and the paper's
Table I gain k_P.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit
from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory

from vcnc_gym.geometry.corners import blend_curvature, smooth_polyline
from vcnc_gym.geometry.shapes import corners_vertices
from vcnc_bench.reports.simba import corners_cycle_times
from vcnc_gym.motion.jlap import (
    SIMBA_A_MAX,
    SIMBA_FEEDRATE,
    SIMBA_J_MAX,
    JlapFeedrate,
    constant_feedrate,
    jlap_state,
    transition_time,
)

F, A, J = SIMBA_FEEDRATE, SIMBA_A_MAX, SIMBA_J_MAX
TOL_T = 1e-9  # s: our durations against ruckig's
TOL_S = 1e-9  # mm: our positions against ruckig's along a section


@pytest.fixture(scope="module")
def path():
    return smooth_polyline(corners_vertices(), 0.05, A, J)


@pytest.fixture(scope="module")
def plan(path):
    return JlapFeedrate().plan_path(path)


def ruckig_1dof(v0, v1, a_max, j_max, v_max, distance=None):
    """ruckig's time-optimal trajectory from (0, v0, 0) to (distance, v1, 0); velocity interface if distance is None."""
    inp = InputParameter(1)
    inp.current_position = [0.0]
    inp.current_velocity = [v0]
    inp.current_acceleration = [0.0]
    inp.target_position = [0.0 if distance is None else distance]
    inp.target_velocity = [v1]
    inp.target_acceleration = [0.0]
    inp.max_velocity = [v_max]
    inp.max_acceleration = [a_max]
    inp.max_jerk = [j_max]
    if distance is None:
        inp.control_interface = ControlInterface.Velocity
    traj = Trajectory(1)
    assert Ruckig(1).calculate(inp, traj) == Result.Working
    return traj


def check_limits(plan, feedrate, a_max, j_max):
    t = np.linspace(-0.01, plan.duration + 0.01, 100001)
    t = np.concatenate([t, plan.breaks, plan.breaks - 1e-12])
    st = plan.state(t)
    assert st[:, 1].max() <= feedrate * (1 + 1e-12) and st[:, 1].min() >= -1e-9
    assert np.abs(st[:, 2]).max() <= a_max * (1 + 1e-12)
    assert np.abs(st[:, 3]).max() <= j_max * (1 + 1e-12)
    assert np.all(np.diff(plan.distance(np.sort(t))) >= -1e-12)
    # s, V and dV/dt continuous across every break: each piece's cubic at its end meets the next row
    breaks, coeffs = plan.kernel_args
    tau = np.diff(breaks)[:-1, None]
    c = coeffs[:-2]
    ends = np.hstack(
        [
            c[:, :1] + tau * (c[:, 1:2] + tau * (c[:, 2:3] + tau * c[:, 3:4])),
            c[:, 1:2] + tau * (2 * c[:, 2:3] + 3 * tau * c[:, 3:4]),
            2 * c[:, 2:3] + 6 * tau * c[:, 3:4],
        ]
    )
    starts = coeffs[1:-1, :3] * [1, 1, 2]
    assert np.all(np.abs(ends - starts) <= [1e-9 * plan.length, 1e-9 * feedrate, 1e-9 * a_max])
    assert plan.distance(plan.duration) == plan.length
    assert plan.velocity(plan.duration + 1.0) == 0.0 and plan.distance(-1.0) == 0.0


def check_against_ruckig(plan, feedrate, a_max, j_max):
    """Every straight section is ruckig's time-optimal trajectory: same duration, same path."""
    straights = [s for s in plan.sections if s.kind == "straight"]
    for s in straights:
        traj = ruckig_1dof(s.v_start, s.v_end, a_max, j_max, feedrate, s.s_end - s.s_start)
        assert abs(traj.duration - s.duration) < TOL_T
        ts = np.linspace(0, s.duration, 201)
        ours = plan.state(s.t_start + ts)
        ref = np.array([traj.at_time(x) for x in ts])[:, :, 0]  # (position, velocity, acceleration)
        assert np.abs(ours[:, 0] - s.s_start - ref[:, 0]).max() < TOL_S
        assert np.abs(ours[:, 1] - ref[:, 1]).max() < 1e-6
        # each feed change against ruckig's velocity interface
        for v0, v1 in ((s.v_start, s.v_peak), (s.v_peak, s.v_end)):
            change = ruckig_1dof(v0, v1, a_max, j_max, feedrate)
            assert abs(change.duration - transition_time(v1 - v0, a_max, j_max)) < TOL_T
    return straights


# --------------------------------------------------------------------------
# Simba et al.'s smoothed path
# --------------------------------------------------------------------------


def test_corners_plan_respects_the_limits(plan):
    check_limits(plan, F, A, J)


def test_corners_plan_is_time_optimal_per_section(plan):
    straights = check_against_ruckig(plan, F, A, J)
    assert len(straights) == 4 and all(s.v_peak == F for s in straights)


def test_corner_speed_held_over_each_corner_segment(path, plan):
    corners = [s for s in plan.sections if s.kind == "corner"]
    assert len(corners) == 3
    for c, zone, v, blend in zip(corners, path.zones, path.corner_speeds, path.blends):
        assert (c.s_start, c.s_end) == tuple(zone) and c.v_start == v
        st = plan.state(np.linspace(c.t_start, c.t_end, 101, endpoint=False))
        np.testing.assert_allclose(st[:, 1], v, rtol=1e-12)
        assert np.abs(st[:, 2]).max() < 1e-9
        # on the blend the path acceleration is v^2 kappa and the jerk v^3 varkappa (eqs. (14), (17))
        kappa, varkappa = blend_curvature(blend, np.linspace(0, 1, 20001))
        assert v**2 * kappa.max() <= A * (1 + 1e-6)
        assert v**3 * varkappa.max() <= J * (1 + 1e-6)
    # the plan ends where the path ends, at rest
    assert plan.length == path.length and plan.sections[-1].v_end == 0.0


def test_cycle_time_against_the_linear_path(path, plan):
    """Simba et al.'s section IV-C: the smoothed path takes longer than the sharp one at a constant 50 mm/s.

    The duration is also rebuilt from ruckig's section durations and the corner segments' times.
    """
    times = corners_cycle_times()
    assert times["linear_time"] == 200.0 / F == constant_feedrate(200.0).duration
    rebuilt = sum(
        ruckig_1dof(s.v_start, s.v_end, A, J, F, s.s_end - s.s_start).duration
        for s in plan.sections
        if s.kind == "straight"
    ) + sum(d / v for d, v in zip(np.diff(path.zones, axis=1)[:, 0], path.corner_speeds))
    assert abs(times["smooth_time"] - rebuilt) < 1e-8
    assert times["smooth_time"] == plan.duration
    assert 0.0 < times["increase"] < 0.1


# --------------------------------------------------------------------------
# other plans: acceleration-limited changes, short sections, lowered corner speeds
# --------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(6))
def test_random_plans_against_ruckig(seed):
    rng = np.random.default_rng(seed)
    feedrate = rng.uniform(20, 120)
    a_max = rng.uniform(300, 5000)
    j_max = rng.uniform(1e4, 5e5)
    n = int(rng.integers(0, 5))
    length = rng.uniform(5, 60)
    cuts = np.sort(rng.uniform(0.05, 0.95, 2 * n)) * length
    corners = [(cuts[2 * k], cuts[2 * k + 1], rng.uniform(0.5, 1.5 * feedrate)) for k in range(n)]
    planner = JlapFeedrate(feedrate, a_max, j_max)
    plan = planner.plan(length, corners)
    check_limits(plan, feedrate, a_max, j_max)
    check_against_ruckig(plan, feedrate, a_max, j_max)
    held = [s for s in plan.sections if s.kind == "corner"]
    for c, (s0, s1, v) in zip(held, corners):
        assert c.v_start <= min(v, feedrate) * (1 + 1e-12) and (c.s_start, c.s_end) == (s0, s1)


def test_acceleration_limited_change_reaches_a_max():
    plan = JlapFeedrate(100.0, 1000.0, 1e5).plan(50.0)  # a^2 / j = 10 mm/s < 100 mm/s
    assert math.isclose(np.abs(plan.acceleration(np.linspace(0, plan.duration, 20001))).max(), 1000.0, rel_tol=1e-12)
    assert math.isclose(plan.duration, 50.0 / 100.0 + 100.0 / 1000.0 + 1000.0 / 1e5, rel_tol=1e-12)
    check_against_ruckig(plan, 100.0, 1000.0, 1e5)


def test_unreachable_corner_speed_is_lowered():
    """A corner 0.5 mm from the start cannot be met at 50 mm/s (0.88 mm needed): the forward pass lowers it."""
    plan = JlapFeedrate(50.0, 4000.0, 1.6e5).plan(10.0, [(0.5, 1.5, 50.0)])
    corner = [s for s in plan.sections if s.kind == "corner"][0]
    assert corner.v_start < 50.0
    # the first section is exactly the fastest rise within 1 mm: ruckig to that speed covers 1 mm
    traj = ruckig_1dof(0.0, corner.v_start, 4000.0, 1.6e5, 50.0)
    assert abs(traj.at_time(traj.duration)[0][0] - 0.5) < 1e-9
    check_against_ruckig(plan, 50.0, 4000.0, 1.6e5)
    # and the backward pass: a corner 0.5 mm before the end
    plan = JlapFeedrate(50.0, 4000.0, 1.6e5).plan(10.0, [(8.5, 9.5, 50.0)])
    corner = [s for s in plan.sections if s.kind == "corner"][0]
    assert corner.v_end < 50.0 and plan.sections[-1].v_peak == corner.v_end
    check_against_ruckig(plan, 50.0, 4000.0, 1.6e5)


# --------------------------------------------------------------------------
# the sharp path, the kernels, the limits' derivation
# --------------------------------------------------------------------------


def test_constant_feedrate_plan():
    plan = constant_feedrate(200.0)
    assert plan.duration == 4.0
    assert plan.velocity(0.0) == 50.0 and plan.velocity(3.999) == 50.0 and plan.velocity(4.0) == 0.0
    np.testing.assert_allclose(plan.distance([0.0, 1.0, 2.5, 4.0, 9.0]), [0.0, 50.0, 125.0, 200.0, 200.0])
    assert np.all(plan.acceleration(np.linspace(0, 4, 11)) == 0.0)


@njit(cache=True)
def _sum_in_a_kernel(ts, breaks, coeffs):
    out = np.empty(4)
    total = np.zeros(4)
    for t in ts:
        jlap_state(t, breaks, coeffs, out)
        total += out
    return total


def test_numba_kernel_evaluates_the_plan(plan):
    ts = np.linspace(-0.1, plan.duration + 0.1, 3001)
    np.testing.assert_allclose(_sum_in_a_kernel(ts, *plan.kernel_args), plan.state(ts).sum(axis=0), rtol=1e-12)
    # the piecewise-polynomial form: row k is [s, V, A/2, J/6] at breaks[k], row K the rest at the end
    breaks, coeffs = plan.kernel_args
    st = plan.state(breaks[:-1])
    np.testing.assert_allclose(coeffs[:-1], st * [1, 1, 0.5, 1 / 6], atol=1e-9)
    np.testing.assert_array_equal(coeffs[-1], [plan.length, 0, 0, 0])
    # V integrates to S (trapezoid on a fine grid)
    t = np.linspace(0, plan.duration, 400001)
    v = plan.velocity(t)
    assert abs(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t)) - plan.length) < 1e-6


def test_limits_come_from_simba_drives():
    """a_max <= 50 % of the weakest axis's worst-case acceleration at 50 mm/s; j_max ramps a_max in
    no less than one natural period of the eq. (7) loop (k_P = 70 000 s^-2, Simba et al.'s Table I)."""
    from vcnc_gym.plants.current_feed_drive import PARAMETERS

    p = {q.name: q for q in PARAMETERS}
    worst = min(
        (p["k_f"].interval[i][0] * p["i_max"].nominal[i] - p["f_c"].interval[i][1] - p["c"].interval[i][1] * F)
        / p["m"].interval[i][1]
        for i in range(2)
    )
    assert 9900 < worst < 10100  # the 9.98e3 mm/s^2 of the module docstring
    assert A <= 0.5 * worst
    omega_n = math.sqrt(70000.0)
    assert A / J >= 2 * math.pi / omega_n


# --------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(feedrate=0.0), "feedrate must be"),
        (dict(a_max=-1.0), r"a_max must be"),
        (dict(j_max=float("nan")), r"j_max must be"),
        (dict(j_max="fast"), "j_max"),
    ],
)
def test_bad_limits(kwargs, match):
    with pytest.raises(ValueError, match=match):
        JlapFeedrate(**kwargs)


@pytest.mark.parametrize(
    "length, corners, match",
    [
        (0.0, [], "length must be"),
        (10.0, [(5.0, 4.0, 3.0)], r"corners\[0\] spans"),
        (10.0, [(0.0, 1.0, 3.0)], r"corners\[0\] spans"),
        (10.0, [(9.0, 10.0, 3.0)], r"corners\[0\] spans"),
        (10.0, [(2.0, 4.0, 3.0), (3.0, 5.0, 3.0)], r"corners\[1\] spans"),
        (10.0, [(2.0, 4.0, 0.0)], r"corners\[0\] speed limit must be"),
        (10.0, [(2.0, 4.0)], r"corners\[0\] must be"),
    ],
)
def test_bad_plans(length, corners, match):
    with pytest.raises(ValueError, match=match):
        JlapFeedrate().plan(length, corners)


def test_bad_constant_plan_and_mismatched_path(path):
    with pytest.raises(ValueError, match="length"):
        constant_feedrate(-1.0)
    with pytest.raises(ValueError, match="feedrate"):
        constant_feedrate(10.0, 0.0)
    with pytest.raises(ValueError, match="designed for"):
        JlapFeedrate(a_max=1000.0).plan_path(path)
    with pytest.raises(ValueError, match="t must be finite"):
        constant_feedrate(10.0).velocity(np.nan)
