"""ContouringEnv: API conformance, determinism, bad input, physics sanity."""

from __future__ import annotations

import itertools
import warnings

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import vcnc_gym
from vcnc_gym.plants import vcnc_feed_drive as plant

ENV_IDS = list(vcnc_gym.envs.CONTOURING_IDS)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_check_env_without_warnings(env_id):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_check_env_without_warnings(env_id):
    from stable_baselines3.common.env_checker import check_env

    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, warn=True)


def test_pd_controller_keeps_heart_contour_error_in_tens_of_micrometres(pd_episode):
    """A hand-written PD loop on the heart: a sanity check, not a tuned target."""
    env = gym.make("VCNC-Heart-v1")
    infos, term, trunc = pd_episode(env)
    err = np.array([i["contour_error"] for i in infos])
    assert term and not trunc and not infos[-1]["diverged"]
    assert 1e-3 < err.max() < 0.05  # between 1 um and 50 um
    # the reference has reached the end of the contour and the table followed
    end = env.unwrapped.curve.point(env.unwrapped.curve.u_range[1])
    np.testing.assert_array_equal(infos[-1]["reference_position"], env.unwrapped.reference.position[-1])
    np.testing.assert_allclose(infos[-1]["reference_position"], end, atol=1e-12)
    assert np.linalg.norm(infos[-1]["position"] - end) < 0.01
    assert len(infos) == env.unwrapped.episode_steps


def test_pd_controller_completes_omega_without_divergence(pd_episode):
    """The omega's corners exceed the drives' acceleration: mm errors, no divergence."""
    env = gym.make("VCNC-Omega-v1")
    infos, term, trunc = pd_episode(env)
    err = np.array([i["contour_error"] for i in infos])
    assert term and not trunc and not infos[-1]["diverged"]
    assert 0.1 < err.max() < env.unwrapped.divergence_bound


def test_contour_error_is_distance_to_contour_not_to_reference():
    """Standing still at the start, the table stays on the contour: zero contour
    error although the reference runs away (large tracking error)."""
    env = gym.make("VCNC-Heart-v1")
    env.reset(seed=0)
    for _ in range(1000):
        _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["contour_error"] < 1e-9
    assert np.linalg.norm(info["tracking_error"]) > 1.0


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_standing_still_does_not_pay(env_id, pd_episode):
    """A table that never moves stays on the contour, but falls behind the
    reference: the episode ends as diverged with the terminal penalty."""
    env = gym.make(env_id)
    env.reset(seed=0)
    total, steps = 0.0, 0
    while True:
        _, reward, term, trunc, info = env.step(np.zeros(2, dtype=np.float32))
        total += reward
        steps += 1
        if term or trunc:
            break
    assert term and info["diverged"]
    assert np.linalg.norm(info["tracking_error"]) > env.unwrapped.tracking_bound
    assert steps < env.unwrapped.episode_steps
    # worse than a PD controller's whole episode
    pd_return = sum(i["reward_contour"] for i in pd_episode(gym.make(env_id))[0])
    assert total < pd_return


def test_halving_the_substep_changes_the_contour_error_trace_by_under_one_percent(pd_episode):
    traces = []
    for substep in (1e-5, 0.5e-5):
        env = gym.make("VCNC-Heart-v1", plant_options={"substep": substep})
        infos, _, _ = pd_episode(env)
        traces.append(np.array([i["contour_error"] for i in infos]))
    assert len(traces[0]) == len(traces[1])
    assert np.max(np.abs(traces[0] - traces[1])) < 0.01 * traces[0].max()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_same_actions_bit_identical(env_id):
    rng = np.random.default_rng(1)
    actions = rng.uniform(-0.2, 0.2, (300, 2)).astype(np.float32)
    runs = []
    for _ in range(2):
        env = gym.make(env_id, randomize=True)
        obs, info = env.reset(seed=123)
        seq = [obs]
        for a in actions:
            obs, r, term, trunc, _ = env.step(a)
            seq.append(obs)
            if term or trunc:
                break
        runs.append((np.array(seq), info["parameters"]))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1]


def test_randomize_draws_parameters_in_the_seed_intervals():
    env = gym.make("VCNC-Heart-v1", randomize=True)
    drawn = []
    for seed in range(20):
        _, info = env.reset(seed=seed)
        drawn.append(info["parameters"])
        lo, hi = plant.PARAMETER_INTERVALS["r_g"]
        assert lo <= info["parameters"]["r_g"] <= hi
        for name in ("K_a", "B"):
            for (lo, hi), value in zip(plant.PARAMETER_INTERVALS[name], info["parameters"][name]):
                assert lo <= value <= hi
    assert len({d["r_g"] for d in drawn}) == 20
    nominal = gym.make("VCNC-Heart-v1")
    assert nominal.reset(seed=0)[1]["parameters"] == nominal.reset(seed=1)[1]["parameters"]


def test_parameters_option_sets_the_plant():
    vertex = plant.uncertainty_vertices()[63]
    env = gym.make("VCNC-Omega-v1")
    _, info = env.reset(seed=0, options={"parameters": vertex})
    assert info["parameters"] == plant.parameters_to_dict(vertex)
    np.testing.assert_array_equal(env.unwrapped.parameters, vertex)


@pytest.mark.parametrize(
    "action, match",
    [
        (np.zeros(3), "shape"),
        (np.zeros((1, 2)), "shape"),
        (np.array([np.nan, 0.0]), "finite"),
        (np.array([0.0, np.inf]), "finite"),
        ([0.0], "shape"),
    ],
)
def test_bad_actions_raise(action, match):
    env = gym.make("VCNC-Heart-v1")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.unwrapped.step(action)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"dt": 0.0}, "dt"),
        ({"dt": float("nan")}, "dt"),
        ({"feedrate": -1.0}, "feedrate"),
        ({"ramp_time": 0.0}, "ramp_time"),
        ({"action_repeat": 0}, "action_repeat"),
        ({"action_repeat": 1.5}, "action_repeat"),
        ({"contour": "square"}, "contour"),
        ({"divergence_bound": 0.0}, "divergence_bound"),
        ({"tracking_bound": -1.0}, "tracking_bound"),
        ({"render_mode": "ascii"}, "render_mode"),
        ({"parameters": np.ones(3)}, "shape"),
        ({"preview_steps": (0, 5)}, "preview_steps"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        vcnc_gym.ContouringEnv(**kwargs)


def test_out_of_range_actions_are_clipped_like_saturation():
    runs = []
    for scale in (1.0, 7.0):
        env = gym.make("VCNC-Omega-v1")
        env.reset(seed=0)
        obs = [env.step(np.array([scale, -scale], dtype=np.float32))[0] for _ in range(50)]
        runs.append(np.array(obs))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_divergence_terminates_with_flag_and_penalty():
    env = gym.make("VCNC-Heart-v1")
    env.reset(seed=0)
    steps = 0
    while True:
        obs, reward, term, trunc, info = env.step(np.array([1.0, 1.0], dtype=np.float32))
        steps += 1
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        if term or trunc:
            break
    assert term and info["diverged"]
    assert info["contour_error_max"] > env.unwrapped.divergence_bound
    remaining = env.unwrapped.episode_steps - steps
    assert info["reward_divergence"] == pytest.approx(-remaining * 5.0 / 0.01)
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.zeros(2))


def test_action_repeat_runs_the_plant_at_the_control_period():
    base = gym.make("VCNC-Omega-v1")
    rep = gym.make("VCNC-Omega-v1", action_repeat=5)
    base.reset(seed=0)
    rep.reset(seed=0)
    a = np.array([0.3, -0.2], dtype=np.float32)
    for _ in range(5):
        _, _, _, _, info_base = base.step(a)
    _, _, _, _, info_rep = rep.step(a)
    np.testing.assert_array_equal(info_base["position"], info_rep["position"])
    assert rep.unwrapped.decision_period == pytest.approx(5 * base.unwrapped.dt)
    assert rep.unwrapped.episode_steps == -(-(len(base.unwrapped.reference.t) - 1) // 5)


def test_step_info_fields_and_units():
    env = gym.make("VCNC-Heart-v1")
    obs, info = env.reset(seed=0)
    assert set(info["parameters"]) == set(plant.PARAMETER_NAMES)
    obs, reward, _, _, info = env.step(np.array([0.5, 2.0], dtype=np.float32))
    for key in ("tracking_error", "position", "reference_position", "command"):
        assert info[key].shape == (2,)
    np.testing.assert_allclose(info["command"], [2.5, 5.0])  # V, saturated at 5 V
    assert info["contour_error"] >= 0.0
    assert reward == pytest.approx(info["reward_contour"] + info["reward_effort"] + info["reward_divergence"])
    layout = env.unwrapped.layout
    np.testing.assert_allclose(layout.tracking_error(obs), info["tracking_error"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(layout.contour_error(obs)[0], info["contour_error"], rtol=1e-6, atol=1e-12)


def test_effort_term_is_off_by_default_and_in_info_when_on():
    env = gym.make("VCNC-Omega-v1", effort_weight=0.5)
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.array([0.2, 0.4], dtype=np.float32))
    assert info["reward_effort"] == pytest.approx(-0.5 * 0.5 * (0.2**2 + 0.4**2), rel=1e-6)
    env0 = gym.make("VCNC-Omega-v1")
    env0.reset(seed=0)
    assert env0.step(np.array([0.2, 0.4], dtype=np.float32))[4]["reward_effort"] == 0.0


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.sampled_from(ENV_IDS),
    st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3)), min_size=1, max_size=60),
    st.integers(1, 400),
)
def test_random_action_sequences_keep_observations_finite_and_in_space(env_id, actions, hold):
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    for a in actions:
        for _ in range(hold):  # each action held for a while so that the table really moves
            obs, reward, term, trunc, _ = env.step(np.array(a, dtype=np.float32))
            assert env.observation_space.contains(obs) and np.all(np.isfinite(obs))
            assert np.isfinite(reward)
            if term or trunc:
                return


def test_render_rgb_array():
    env = gym.make("VCNC-Omega-v1", render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(100):
        env.step(np.array([0.1, 0.1], dtype=np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert frame.std() > 0
    env.close()


def test_default_control_period_makes_jahanpour_qft_loop_stable_on_every_vertex():
    """Jahanpour et al.'s sec. 2c G(s) with the ZOH plant: stable at the env's dt, not at 1 ms."""
    control = pytest.importorskip("control")
    g = control.tf([22.36, 61.21], [0.0001, 1.326])
    dt = gym.make("VCNC-Heart-v1").unwrapped.dt

    def worst_pole(period):
        worst = 0.0
        for vertex, axis in itertools.product(plant.uncertainty_vertices(), (0, 1)):
            num, den = plant.linear_transfer_function_coefficients(vertex, axis)
            loop = control.c2d(control.tf(num, den), period, "zoh") * control.c2d(g, period, "tustin")
            worst = max(worst, np.abs(control.poles(control.feedback(loop, 1))).max())
        return worst

    assert worst_pole(dt) < 1.0
    assert worst_pole(1e-3) > 5.0  # a closed-loop pole near |z| = 10
