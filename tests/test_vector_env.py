"""The native vector env: one kernel call over N envs, the same numbers as N single envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import vcnc_gym
from vcnc_gym.envs import ContouringVectorEnv

IDS = list(vcnc_gym.envs.VECTOR_IDS)


def _make_vec(env_id, n, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_gives_the_native_vector_env(env_id):
    envs = _make_vec(env_id, 3)
    assert isinstance(envs.unwrapped, ContouringVectorEnv)
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, info = envs.reset(seed=1)
    assert obs.shape == (3, envs.unwrapped.layout.size) and obs.dtype == np.float32
    assert envs.single_observation_space.contains(obs[0])
    obs, rew, term, trunc, info = envs.step(np.zeros((3, 2), dtype=np.float32))
    assert rew.shape == term.shape == trunc.shape == (3,)
    assert info["contour_error"].shape == (3,) and info["_contour_error"].all()
    assert info["position"].shape == (3, 2)
    envs.close()


def _rollout_single(env_id, seed, n_steps, actions_of, **kwargs):
    """A single env driven like env i of a NEXT_STEP vector env: the call after an episode's end resets."""
    env = gym.make(env_id, **kwargs)
    obs, _ = env.reset(seed=seed)
    out = {"obs": [obs], "rew": [], "term": [], "trunc": [], "params": [env.unwrapped.parameters.copy()]}
    done = False
    for t in range(n_steps):
        if done:
            obs, _ = env.reset()
            r, te, tr = 0.0, False, False
            out["params"].append(env.unwrapped.parameters.copy())
        else:
            obs, r, te, tr, _ = env.step(actions_of(obs, t))
        done = te or tr
        out["obs"].append(obs)
        out["rew"].append(r)
        out["term"].append(te)
        out["trunc"].append(tr)
    return out


@pytest.mark.parametrize("parallel", [False, True])
def test_env_i_is_bit_identical_to_a_single_env_with_randomization(parallel, pd_action):
    """Same seeds: env i of the vector env gives the single env's observations, rewards, flags, plants.

    Randomized plants, a different seed per env, and episodes short enough
    (max_episode_steps) that every env goes through an autoreset."""
    n, steps, seed = 4, 60, 7
    kwargs = dict(randomize=True, max_episode_steps=25)
    layout = gym.make("VCNC-Omega-v1").unwrapped.layout

    def acts(obs, t):  # the same deterministic policy in both: PD plus a time-dependent dither
        return pd_action(layout, obs) + 0.1 * np.sin(0.3 * t)

    envs = ContouringVectorEnv(n, contour="omega", parallel=parallel, **kwargs)
    obs, _ = envs.reset(seed=seed)
    vec = {"obs": [obs], "rew": [], "term": [], "trunc": []}
    plants = [[envs.parameters[i]] for i in range(n)]
    for t in range(steps):
        obs, r, te, tr, _ = envs.step(acts(obs, t))
        for i in range(n):
            if t > 0 and (vec["term"][-1][i] or vec["trunc"][-1][i]):
                plants[i].append(envs.parameters[i])
        vec["obs"].append(obs)
        vec["rew"].append(r)
        vec["term"].append(te)
        vec["trunc"].append(tr)
    assert np.any(vec["trunc"]), "the test should exercise an autoreset"
    for i in range(n):
        single = _rollout_single("VCNC-Omega-v1", seed + i, steps, acts, **kwargs)
        k = len(vec["rew"])
        np.testing.assert_array_equal(np.array(single["obs"][: k + 1]), np.array(vec["obs"])[:, i])
        np.testing.assert_array_equal(np.array(single["rew"][:k]), np.array(vec["rew"])[:, i])
        np.testing.assert_array_equal(np.array(single["term"][:k]), np.array(vec["term"])[:, i])
        np.testing.assert_array_equal(np.array(single["trunc"][:k]), np.array(vec["trunc"])[:, i])
        np.testing.assert_array_equal(np.array(single["params"][: len(plants[i])]), np.array(plants[i]))
    # the plants differ between envs (their own generators)
    assert not np.array_equal(plants[0][0], plants[1][0])


def test_next_step_autoreset_returns_the_first_observation_with_zero_reward():
    envs = ContouringVectorEnv(2, contour="omega", max_episode_steps=30)
    obs0, _ = envs.reset(seed=0)
    for _ in range(30):
        obs, r, te, tr, info = envs.step(np.ones((2, 2)))
    assert tr.all() and not te.any()
    obs, r, te, tr, info = envs.step(np.ones((2, 2)))
    np.testing.assert_array_equal(obs, obs0)  # nominal plant, back at the start
    assert (r == 0).all() and not te.any() and not tr.any()
    assert not info["_contour_error"].any()
    for _ in range(30):  # past the 3 um backlash gap
        obs, r, te, tr, info = envs.step(np.ones((2, 2)))
    assert (r < 0).all() and info["_contour_error"].all()


def test_same_step_autoreset_puts_the_final_observation_in_info():
    envs = ContouringVectorEnv(2, contour="omega", max_episode_steps=30, autoreset_mode="SameStep")
    assert envs.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    obs0, _ = envs.reset(seed=0)
    for _ in range(30):
        obs, r, te, tr, info = envs.step(np.ones((2, 2)))
    assert tr.all()
    np.testing.assert_array_equal(obs, obs0)
    assert info["_final_obs"].all()
    assert not np.array_equal(info["final_obs"][0], obs0[0])
    assert info["final_info"]["contour_error"].shape == (2,)


def test_disabled_autoreset_waits_for_a_masked_reset():
    envs = ContouringVectorEnv(2, contour="omega", max_episode_steps=30, autoreset_mode=AutoresetMode.DISABLED)
    envs.reset(seed=0)
    for _ in range(30):
        _, _, _, tr, _ = envs.step(np.ones((2, 2)))
    assert tr.all()
    _, r, te, tr, _ = envs.step(np.ones((2, 2)))  # finished envs stay idle
    assert (r == 0).all() and not te.any() and not tr.any()
    obs, _ = envs.reset(options={"reset_mask": np.array([True, False])})
    for _ in range(30):
        _, r, _, _, _ = envs.step(np.ones((2, 2)))
    assert r[0] < 0 and r[1] == 0


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.zeros((3, 2)), "shape"),
        (np.zeros(2), "shape"),
        (np.array([[0.0, np.nan], [0.0, 0.0]]), "finite"),
        (np.array([[0.0, np.inf], [0.0, 0.0]]), "finite"),
        (np.array([["a", "b"], ["c", "d"]]), "real"),
        (np.zeros((2, 2), dtype=complex), "real"),
    ],
)
def test_bad_actions_raise(bad, message):
    envs = ContouringVectorEnv(2, contour="omega")
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        envs.step(bad)


@pytest.mark.parametrize("num_envs", [0, -1, 1.5, True, "2"])
def test_bad_num_envs_raise(num_envs):
    with pytest.raises(ValueError, match="num_envs"):
        ContouringVectorEnv(num_envs, contour="omega")


def test_reset_options_per_env_parameters_and_unknown_options():
    envs = ContouringVectorEnv(2, contour="omega")
    plant = envs.unwrapped.plant
    p = plant.vertices()[[0, 63]]
    envs.reset(seed=0, options={"parameters": p})
    np.testing.assert_array_equal(envs.parameters, p)
    with pytest.raises(ValueError, match="unknown reset option"):
        envs.reset(options={"paramters": p[0]})
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"reset_mask": np.array([1, 0])})


def test_step_before_reset_raises():
    envs = ContouringVectorEnv(2, contour="omega")
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.zeros((2, 2)))
