"""Purtojo et al.'s fuzzy NCTF controller (baselines/feedback/nctf.py): the NCT from the plant's own open-loop
response, the membership design of eqs. (1)-(2), Table I's inference against scikit-fuzzy, the policy."""

from __future__ import annotations

import numpy as np
import pytest

import vcnc_baselines
from vcnc_baselines.feedback import nctf
from vcnc_baselines.feedback.nctf import NCTFPolicy
from vcnc_gym.envs.layout import ObservationLayout
from vcnc_gym.plants import get_plant
from vcnc_gym.plants import nct_xy_table as nt

MODEL = get_plant("nct_xy_table")
LAYOUT = ObservationLayout()
DT = 1e-3


@pytest.fixture(scope="module")
def policy():
    return NCTFPolicy(LAYOUT, DT, MODEL.nominal())


# --------------------------------------------------------------------------
# The experiment and the NCT
# --------------------------------------------------------------------------
def test_stepwise_experiment_is_the_quantised_step_response():
    ex = nctf.stepwise_experiment(dt=DT)
    p = MODEL.nominal()
    t = ex.time[: ex.switch_index + 1]
    for axis in (0, 1):
        K, a = p[axis, nt.IDX_K], p[axis, nt.IDX_ALPHA]
        exact = K * (t - (1 - np.exp(-a * t)) / a)  # step response of eq. (3) to u_r = 1
        got = ex.position[: ex.switch_index + 1, axis]
        assert np.all(np.abs(got - exact) <= 0.5e-3 + 1e-9)  # the 1 um sensor's reading
    np.testing.assert_array_equal(ex.input[: ex.switch_index], 1.0)
    np.testing.assert_array_equal(ex.input[ex.switch_index :], 0.0)


@pytest.mark.parametrize("vertex", [None, 0, 15])
def test_nct_from_the_deceleration_gives_back_the_plant(vertex):
    params = MODEL.nominal() if vertex is None else MODEL.vertices()[vertex]
    ex = nctf.stepwise_experiment(params, dt=DT)
    for axis in (0, 1):
        K, a = params[axis, nt.IDX_K], params[axis, nt.IDX_ALPHA]
        nct = nctf.construct_nct(ex, axis)
        np.testing.assert_allclose(nct.h_max, K, rtol=1e-3)  # h_max = K u_r
        np.testing.assert_allclose(nct.A, K / a, rtol=1e-3)  # coasting distance of eq. (3)
        np.testing.assert_allclose(nct.m, -a, rtol=5e-3)
        K_id, a_id = nct.model()  # eq. (3): the model the NCT gives
        np.testing.assert_allclose([K_id, a_id], [K, a], rtol=5e-3)
        # the NCT's data are the line through the origin (this plant's deceleration) up to the sensor
        np.testing.assert_allclose(nct.error_rate, nct.rate(nct.error), atol=0.25)
        assert nct.error.max() == pytest.approx(nct.A, rel=1e-3)


def test_nct_of_eq_4_reads_the_papers_model(policy):
    # Purtojo et al. derive eq. (4) from the NCT through eq. (3): the construction closes the loop
    (Kx, ax), (Ky, ay) = (n.model() for n in policy.nct)
    np.testing.assert_allclose([Kx, ax, Ky, ay], [50.7, 1.475, 53.1, 3.156], rtol=5e-3)


def test_membership_design_follows_eqs_1_and_2(policy):
    for nct, comp in zip(policy.nct, policy.compensators):
        a = 0.001
        assert comp.a_s_res == a
        assert comp.h_max == nct.h_max
        assert comp.h_s_res == pytest.approx(-nct.m * a)  # the NCT's error rate at the resolution
        assert comp.u_i_max == pytest.approx(0.5 * nct.A * nct.h_max)  # eq. (1)
        assert comp.u_i_s_res == pytest.approx(4 * a * comp.h_s_res)  # eq. (2)
        assert comp.integral_gain == nct.h_max
        assert comp.u_r == 1.0
    other = NCTFPolicy(LAYOUT, DT, MODEL.nominal(), zero_rate="sample", integral_gain=2.0)
    assert other.compensators[0].h_s_res == pytest.approx(0.001 / DT)
    assert other.compensators[1].integral_gain == 2.0


# --------------------------------------------------------------------------
# The fuzzy compensator against scikit-fuzzy
# --------------------------------------------------------------------------
def test_rule_table_is_table_1():
    table = {
        ("N", "N"): "N",
        ("N", "Z"): "N",
        ("N", "P"): "Z",
        ("Z", "N"): "N",
        ("Z", "Z"): "Z",
        ("Z", "P"): "P",
        ("P", "N"): "Z",
        ("P", "Z"): "P",
        ("P", "P"): "P",
    }
    for (up, ui), out in table.items():
        assert nctf.LABELS[nctf.RULE_TABLE[nctf.LABELS.index(up), nctf.LABELS.index(ui)]] == out


def _skfuzzy_system(comp):
    skf = pytest.importorskip("skfuzzy")
    from skfuzzy import control as ctrl

    def universe(span, zero):
        return np.union1d(np.linspace(-span, span, 201), [-zero, 0.0, zero])

    up_u = universe(comp.h_max, comp.h_s_res)
    ui_u = universe(comp.u_i_max, comp.u_i_s_res)
    up = ctrl.Antecedent(up_u, "u_p")
    ui = ctrl.Antecedent(ui_u, "u_i")
    grid = comp.output_grid
    out = ctrl.Consequent(grid, "u", defuzzify_method="centroid")
    for var, x, span, zero in ((up, up_u, comp.h_max, comp.h_s_res), (ui, ui_u, comp.u_i_max, comp.u_i_s_res)):
        var["N"] = skf.trimf(x, [-span, -span, 0.0])
        var["Z"] = skf.trimf(x, [-zero, 0.0, zero])
        var["P"] = skf.trimf(x, [0.0, span, span])
    out["N"] = skf.zmf(grid, -comp.u_r, 0.0)
    out["Z"] = skf.trimf(grid, [0.0, 0.0, 0.0])  # the singleton
    out["P"] = skf.smf(grid, 0.0, comp.u_r)
    np.testing.assert_allclose(nctf.output_memberships(grid), [out[t].mf for t in ("N", "Z", "P")], atol=1e-15)
    rules = [
        ctrl.Rule(up[a] & ui[b], out[nctf.LABELS[nctf.RULE_TABLE[i, j]]])
        for i, a in enumerate(nctf.LABELS)
        for j, b in enumerate(nctf.LABELS)
    ]
    return ctrl.ControlSystemSimulation(ctrl.ControlSystem(rules))


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("axis", [0, 1])
def test_fuzzy_inference_matches_skfuzzy(policy, axis):
    comp = policy.compensators[axis]
    sim = _skfuzzy_system(comp)
    # inside and around both Z sets, across the ranges and beyond them (clipped)
    rel = np.array([0.0, 0.3, 1.0, 1.7, 40.0, 3e3, 1e5])
    up_values = np.concatenate([-rel[::-1], rel[1:]]) * comp.h_s_res
    up_values = np.concatenate([up_values, [-1.3 * comp.h_max, -0.6 * comp.h_max, 0.25 * comp.h_max, comp.h_max]])
    ui_values = np.concatenate([-rel[::-1], rel[1:]]) * comp.u_i_s_res
    ui_values = np.concatenate(
        [ui_values, [-comp.u_i_max, -0.2 * comp.u_i_max, 0.7 * comp.u_i_max, 2.0 * comp.u_i_max]]
    )
    UP, UI = np.meshgrid(up_values, ui_values, indexing="ij")
    ours = comp.infer(UP, UI)
    ref = np.empty_like(ours)
    for i in range(UP.shape[0]):
        for j in range(UP.shape[1]):
            sim.input["u_p"] = float(np.clip(UP[i, j], -comp.h_max, comp.h_max))
            sim.input["u_i"] = float(np.clip(UI[i, j], -comp.u_i_max, comp.u_i_max))
            sim.compute()
            ref[i, j] = sim.output["u"]
    np.testing.assert_allclose(ours, ref, atol=1e-9)
    assert ref.max() > 0.5 and ref.min() < -0.5 and np.any(np.abs(ref) < 0.05)  # the grid spans the surface


def test_fuzzy_surface_shape(policy):
    comp = policy.compensators[0]
    assert comp.infer(0.0, 0.0) == 0.0
    up = np.linspace(-1.2, 1.2, 41) * comp.h_max
    ui = np.linspace(-1.2, 1.2, 37)[:, None] * comp.u_i_max
    u = comp.infer(up[None, :] + 0 * ui, ui + 0 * up[None, :])
    np.testing.assert_allclose(comp.infer(-up[None, :] + 0 * ui, -ui + 0 * up[None, :]), -u, atol=1e-12)  # odd
    assert np.all(np.abs(u) <= comp.u_r)
    # opposite signs: only the rules (P, N) and (N, P) fire -> the singleton Z -> 0
    assert comp.infer(0.5 * comp.h_max, -0.5 * comp.u_i_max) == pytest.approx(0.0, abs=1e-12)
    # both P and saturated: the centroid of the whole s-shaped P
    skf = pytest.importorskip("skfuzzy")
    grid = comp.output_grid
    full = skf.defuzz(grid, skf.smf(grid, 0.0, comp.u_r), "centroid")
    assert full > 0.7
    assert comp.infer(comp.h_max, comp.u_i_max) == pytest.approx(full, rel=1e-12)


# --------------------------------------------------------------------------
# The policy
# --------------------------------------------------------------------------
def make_obs(e, v_ref=(0.0, 0.0), v=(0.0, 0.0)):
    obs = np.zeros(LAYOUT.size, dtype=np.float32)
    obs[LAYOUT.slice("tracking_error")] = e
    obs[LAYOUT.slice("reference_velocity")] = v_ref
    obs[LAYOUT.slice("velocity")] = v
    return obs


def test_policy_step_by_hand(policy):
    policy.reset(n_envs=1)
    e0 = np.array([0.004, -0.002], dtype=np.float32)
    a0, _ = policy.predict(make_obs(e0, v_ref=(1.0, 0.0), v=(0.0, 0.0)), episode_start=True)
    e0 = e0.astype(float)
    rate0 = np.array([1.0, 0.0])  # first step: v_d - v
    m = np.array([n.m for n in policy.nct])
    up0 = rate0 - m * e0
    integral0 = up0 * DT
    for axis in (0, 1):
        c = policy.compensators[axis]
        expected = c.infer(up0[axis], c.integral_gain * integral0[axis])
        assert a0[axis] == pytest.approx(expected, rel=1e-6)
    e1 = np.array([0.003, -0.002], dtype=np.float32)
    a1, _ = policy.predict(make_obs(e1, v_ref=(5.0, 5.0), v=(9.0, 9.0)))  # velocities unused after the first step
    rate1 = (e1.astype(float) - e0) / DT
    up1 = rate1 - m * e1.astype(float)
    for axis in (0, 1):
        c = policy.compensators[axis]
        expected = c.infer(up1[axis], c.integral_gain * (integral0[axis] + up1[axis] * DT))
        assert a1[axis] == pytest.approx(expected, rel=1e-6)
    np.testing.assert_allclose(policy.controller_state[0, 1], e1, rtol=1e-7)


def test_integral_is_clamped_at_the_universe(policy):
    policy.reset(n_envs=1)
    for k in range(400):  # u_p = h_max (the NCT saturates at a 100 mm error): 0.05 mm per period
        policy.predict(make_obs((100.0, -100.0)), episode_start=(k == 0))
    limit = np.array([c.u_i_max / c.integral_gain for c in policy.compensators])
    np.testing.assert_allclose(policy.controller_state[0, 0], [limit[0], -limit[1]])


def test_episode_start_resets_only_that_env(policy):
    obs = np.stack([make_obs((0.003, 0.001)), make_obs((-0.002, 0.004))])
    policy.predict(obs, episode_start=np.array([True, True]))
    policy.predict(obs)
    before = policy.controller_state.copy()
    policy.predict(obs, episode_start=np.array([False, True]))
    fresh = NCTFPolicy(LAYOUT, DT, MODEL.nominal())
    fresh.predict(obs[1:], episode_start=True)
    np.testing.assert_allclose(policy.controller_state[1], fresh.controller_state[0])
    assert not np.allclose(policy.controller_state[0], before[0])  # env 0 went on integrating


def test_registered_and_built_from_an_env():
    from vcnc_gym.envs import ContouringEnv

    env = ContouringEnv(contour="circle", plant="nct_xy_table", feedrate=1.0, ramp_time=0.05, dt=DT)
    pol = vcnc_baselines.make("nctf", env)
    assert isinstance(pol, NCTFPolicy) and pol.decision_period == DT
    assert "nctf" in vcnc_baselines.names()
    jahanpour_env = ContouringEnv(contour="omega", plant="vcnc_feed_drive")
    with pytest.raises(ValueError, match="nct_xy_table"):
        vcnc_baselines.make("nctf", jahanpour_env)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(integral_gain=-1.0), "integral_gain"),
        (dict(zero_rate="tachometer"), "zero_rate"),
        (dict(fit_fraction=1.5), "fit_fraction"),
        (dict(on_time=0.0), "on_time"),
        (dict(off_time=0.002), "too short"),
        (dict(velocity_window=float("nan")), "velocity_window"),
    ],
)
def test_bad_parameters_raise_value_error(kwargs, words):
    with pytest.raises(ValueError, match=words):
        NCTFPolicy(LAYOUT, DT, MODEL.nominal(), **kwargs)


def test_construct_nct_rejects_a_table_that_does_not_move():
    ex = nctf.stepwise_experiment(dt=DT)
    still = nctf.StepwiseExperiment(
        ex.time, np.zeros_like(ex.position), ex.input, ex.switch_index, ex.dt, ex.u_r, ex.resolution
    )
    with pytest.raises(ValueError, match="did not move"):
        nctf.construct_nct(still, 0)
    with pytest.raises(ValueError, match="axis"):
        nctf.construct_nct(ex, 2)


def test_main_prints_the_design_and_the_figures(capsys, tmp_path):
    from vcnc_bench.reports.circle import nctf_main

    assert nctf_main(["--dt", "0.002", "--plot", str(tmp_path / "r.png")]) == 0
    out = capsys.readouterr().out
    assert "h_max 50.7" in out and "h_max 53.1" in out and "RMS radial error" in out
    assert (tmp_path / "r.png").exists()
