"""Gymnasium's conventions (issue 36, item 4): vector envs of the single env, ``gym.make(env.spec)``, pickling.

The reference every vector env is held against is the single env itself, stepped here by hand with the
documented semantics of Gymnasium's autoreset modes (``gymnasium.vector.AutoresetMode``): env i of a vector
env reset with ``seed=s`` is the single env reset with ``seed=s + i``, and after an episode's end

- NEXT_STEP: the next ``step`` resets that env (``reset()`` without a seed) and returns its first observation,
  reward 0, both flags False, ignoring the action;
- SAME_STEP: the ending ``step`` returns the end's reward and flags, the first observation of the next episode
  (reset without a seed), and the last observation in ``info["final_obs"]``.

The episodes are made short (action_repeat = 10, a constant command that drives the table off the contour)
and end differently in the two envs: one terminated by divergence, one truncated by ``max_episode_steps``.
"""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs import ContouringEnv
from vcnc_gym.envs.registry import ENV_IDS, suite_env
from vcnc_gym.motion import SCurveFeedrate

MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
SEED = 7

#: One id of every kind of single env, with the arguments that make its episodes short and seed-dependent, and
#: the constant command (per env) that ends them at different steps.
KINDS = {
    "VCNC-Heart-v1": ({"action_repeat": 10, "randomize": True, "max_episode_steps": 70}, (1.0, 0.5)),
    "VCNC-HeartShop-v1": ({"action_repeat": 10, "randomize": True, "max_episode_steps": 70}, (1.0, 0.5)),
    "VCNC-GCode-v1": ({"action_repeat": 10, "randomize": True, "max_episode_steps": 90}, (1.0, 0.5)),
    "VCNC-RandomContour-v1": ({"action_repeat": 10, "max_episode_steps": 70}, (1.0, 0.5)),
    "VCNC-OmegaOverride-v1": ({"action_repeat": 10, "randomize": True, "max_episode_steps": 100}, (1.0, 0.5)),
    "VCNC-Step-v0": ({"action_repeat": 10, "randomize": True, "max_episode_steps": 40}, (0.05, 0.0)),
}


def steps_of(env_id: str) -> int:
    """Steps the test runs: every env ends twice (diverged or truncated) and starts again."""
    return 2 * KINDS[env_id][0]["max_episode_steps"] + 10


def actions_of(env_id: str, n_actions: int) -> np.ndarray:
    """The (2, n_actions) constant commands of env 0 and env 1."""
    return np.array([np.full(n_actions, c, dtype=np.float32) for c in KINDS[env_id][1]])


def expected(env_id: str, i: int, mode: AutoresetMode) -> dict:
    """What env i of a 2-env vector env in ``mode`` must return, from the single env stepped by hand."""
    kwargs, _ = KINDS[env_id]
    env = gym.make(env_id, **kwargs)
    action = actions_of(env_id, env.action_space.shape[0])[i]
    obs, _ = env.reset(seed=SEED + i)
    out = {"reset": obs, "obs": [], "reward": [], "terminated": [], "truncated": [], "final_obs": {}}
    ended = False
    for t in range(steps_of(env_id)):
        if ended and mode == AutoresetMode.NEXT_STEP:
            obs, _ = env.reset()
            r, te, tr, ended = 0.0, False, False, False
        else:
            obs, r, te, tr, _ = env.step(action)
            ended = te or tr
            if ended and mode == AutoresetMode.SAME_STEP:
                out["final_obs"][t] = obs
                obs, _ = env.reset()
        for key, value in (("obs", obs), ("reward", r), ("terminated", te), ("truncated", tr)):
            out[key].append(value)
    env.close()
    return {k: (np.array(v) if isinstance(v, list) else v) for k, v in out.items()}


def run_vector(envs, env_id: str) -> dict:
    """The vector env's outputs over :func:`steps_of` steps from ``reset(seed=SEED)``."""
    actions = actions_of(env_id, envs.single_action_space.shape[0])
    obs, _ = envs.reset(seed=SEED)
    out = {"reset": obs, "obs": [], "reward": [], "terminated": [], "truncated": [], "final_obs": {}}
    for t in range(steps_of(env_id)):
        obs, r, te, tr, info = envs.step(actions)
        for key, value in (("obs", obs), ("reward", r), ("terminated", te), ("truncated", tr)):
            out[key].append(np.array(value))
        if "final_obs" in info:
            for i in np.flatnonzero(info["_final_obs"]):
                out["final_obs"][(t, int(i))] = info["final_obs"][i]
    envs.close()
    return {k: (np.array(v) if isinstance(v, list) else v) for k, v in out.items()}


def check_against_single(got: dict, env_id: str, mode: AutoresetMode) -> None:
    flags = set()
    for i in range(2):
        want = expected(env_id, i, mode)
        np.testing.assert_array_equal(got["reset"][i], want["reset"])
        for key in ("obs", "reward", "terminated", "truncated"):
            np.testing.assert_array_equal(got[key][:, i], want[key], err_msg=f"{env_id} env {i} {key} ({mode})")
        ends = np.flatnonzero(want["terminated"] | want["truncated"])
        assert len(ends) >= 2, f"{env_id} env {i}: the test's episodes must end, and start again"
        flags.update(k for k in ("terminated", "truncated") if want[k].any())
        finals = {t: o for (t, j), o in got["final_obs"].items() if j == i}
        assert finals.keys() == want["final_obs"].keys(), f"{env_id} env {i}: final_obs at the wrong steps"
        for t, o in finals.items():
            np.testing.assert_array_equal(o, want["final_obs"][t])
    assert flags == {"terminated", "truncated"}, f"{env_id}: the test's episodes should end both ways, got {flags}"


def make_vec(env_id: str, vectorization: str, mode: AutoresetMode, **vector_kwargs):
    kwargs, _ = KINDS[env_id]
    if vectorization == "vector_entry_point":
        return gym.make_vec(env_id, num_envs=2, vectorization_mode=vectorization, autoreset_mode=mode, **kwargs)
    return gym.make_vec(
        env_id,
        num_envs=2,
        vectorization_mode=vectorization,
        vector_kwargs={"autoreset_mode": mode, **vector_kwargs},
        **kwargs,
    )


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.value)
def test_sync_vector_env_gives_the_single_envs_episodes(mode):
    check_against_single(run_vector(make_vec("VCNC-Heart-v1", "sync", mode), "VCNC-Heart-v1"), "VCNC-Heart-v1", mode)


@pytest.mark.slow
@pytest.mark.parametrize("vectorization", ("sync", "async"))
@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.value)
@pytest.mark.parametrize("env_id", tuple(KINDS))
def test_every_kind_of_env_under_sync_and_async_vector_envs(env_id, mode, vectorization):
    check_against_single(run_vector(make_vec(env_id, vectorization, mode), env_id), env_id, mode)


@pytest.mark.slow
@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.value)
@pytest.mark.parametrize("env_id", [e for e in KINDS if suite_env(e).vector_entry_point is not None])
def test_native_vector_env_gives_what_the_sync_one_gives(env_id, mode):
    native = make_vec(env_id, "vector_entry_point", mode)
    assert native.metadata["autoreset_mode"] == mode
    got = run_vector(native, env_id)
    sync = run_vector(make_vec(env_id, "sync", mode), env_id)
    for key in ("reset", "obs", "reward", "terminated", "truncated"):
        np.testing.assert_array_equal(got[key], sync[key], err_msg=f"{env_id} {key} ({mode})")
    assert got["final_obs"].keys() == sync["final_obs"].keys()
    for key, o in got["final_obs"].items():
        np.testing.assert_array_equal(o, sync["final_obs"][key])
    check_against_single(got, env_id, mode)


@pytest.mark.slow
def test_async_vector_env_spawns_its_workers():
    """A spawned worker imports vcnc_gym afresh (no fork): the env is made there from its pickled recipe."""
    env_id = "VCNC-Heart-v1"
    envs = make_vec(env_id, "async", AutoresetMode.NEXT_STEP, context="spawn")
    check_against_single(run_vector(envs, env_id), env_id, AutoresetMode.NEXT_STEP)


# -- gym.make(env.spec) ---------------------------------------------------------------------------------------
def check_spec_round_trip(env_id: str, **kwargs) -> None:
    env = gym.make(env_id, **kwargs)
    assert {**suite_env(env_id).kwargs, **kwargs}.items() <= env.spec.kwargs.items()
    again = gym.make(env.spec)
    assert again.spec.kwargs == env.spec.kwargs
    first, _ = env.reset(seed=0)
    second, _ = again.reset(seed=0)
    np.testing.assert_array_equal(first, second)
    # and the episode: the same first step
    action = np.full(env.action_space.shape, 0.3, dtype=np.float32)
    np.testing.assert_array_equal(env.step(action)[0], again.step(action)[0])


def test_make_spec_round_trips_an_ids_arguments():
    check_spec_round_trip("VCNC-Heart-v1", randomize=True, action_repeat=3, contour_ahead=(0.5, 1.0))


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_make_spec_round_trips_every_current_id(env_id):
    check_spec_round_trip(env_id)
    check_spec_round_trip(
        env_id, randomize=True, action_repeat=2
    ) if env_id != "VCNC-RandomContour-v1" else check_spec_round_trip(env_id, randomize=True, tolerance=0.02)


# -- pickling -------------------------------------------------------------------------------------------------
def check_pickle_continues_the_episode(env_id: str, **kwargs) -> None:
    """Pickled mid-episode, the copy steps to the same end as the original, then resets alike (the generator)."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=3)
    actions = np.random.default_rng(1).uniform(-0.3, 0.3, (400, env.action_space.shape[0])).astype(np.float32)
    for a in actions[:5]:  # mid-episode (some ids' episodes end within 20 steps of these commands)
        assert not any(env.step(a)[2:4])
    fresh = pickle.loads(pickle.dumps(gym.make(env_id, **kwargs)))  # never reset: it must reset alike too
    copies = [pickle.loads(pickle.dumps(env)), copy.deepcopy(env)]
    for copied in copies:
        assert type(copied.unwrapped) is type(env.unwrapped)
    ended = False
    for a in actions[5:]:
        result = env.step(a)
        for copied in copies:
            twin = copied.step(a)
            np.testing.assert_array_equal(twin[0], result[0])
            assert twin[1:4] == result[1:4]
        if result[2] or result[3]:
            ended = True
            break
    assert ended, "the episode should end within the test's steps"
    obs, _ = env.reset()
    for copied in copies:
        np.testing.assert_array_equal(copied.reset()[0], obs)
    np.testing.assert_array_equal(fresh.reset(seed=5)[0], gym.make(env_id, **kwargs).reset(seed=5)[0])


def test_a_pickled_env_continues_its_episode():
    check_pickle_continues_the_episode("VCNC-Heart-v1", randomize=True, action_repeat=50)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_current_id_pickles_mid_episode(env_id):
    # the step response's axes leave its bound within 5 decisions of 5 periods under these commands
    repeat = 1 if env_id == "VCNC-Step-v0" else 20
    kwargs = (
        {"action_repeat": repeat} if env_id == "VCNC-RandomContour-v1" else {"action_repeat": repeat, "randomize": True}
    )
    check_pickle_continues_the_episode(env_id, **kwargs)


def test_an_argument_that_does_not_pickle_is_named():
    class Profile(SCurveFeedrate):  # a local class: pickle cannot find it by name
        pass

    env = ContouringEnv(contour="circle", plant="nct_xy_table", profile=Profile(1.0, 0.1), dt=1e-3)
    with pytest.raises(TypeError, match="argument profile="):
        pickle.dumps(env)


def test_a_registered_plant_model_is_saved_by_name():
    from vcnc_gym.plants import get_plant

    env = ContouringEnv(contour="heart", plant=get_plant("vcnc_feed_drive"), action_repeat=50)
    copied = pickle.loads(pickle.dumps(env))
    assert copied.plant is get_plant("vcnc_feed_drive")
    np.testing.assert_array_equal(copied.reset(seed=1)[0], env.reset(seed=1)[0])


@pytest.mark.parametrize("env_id", ["VCNC-Heart-v1", pytest.param("VCNC-GCode-v1", marks=pytest.mark.slow)])
def test_a_pickled_native_vector_env_continues_its_episodes(env_id):
    kwargs, commands = KINDS[env_id]
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    envs.reset(seed=SEED)
    actions = actions_of(env_id, 2)
    for _ in range(30):
        envs.step(actions)
    copied = pickle.loads(pickle.dumps(envs))
    assert copied.spec == envs.spec and copied.num_envs == 2
    for _ in range(steps_of(env_id)):  # through both envs' ends and resets (autoreset from their generators)
        result, twin = envs.step(actions), copied.step(actions)
        for got, want in zip(twin[:4], result[:4]):
            np.testing.assert_array_equal(got, want)
