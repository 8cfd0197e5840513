"""vcnc_gym.envs.history: the agent's memory of its last decisions (issue 37), the same in training and in the bench.

The remembered fields are checked against the env's own observations, picked by hand with the layout's slices;
the lean trainer's envs (the native vector env), the residual's Gymnasium wrapper (the per-env path, RL Zoo's) and
the bench's :class:`vcnc_agents.policy.AgentPolicy` must all show an agent the same thing.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import vcnc_gym  # noqa: F401
from vcnc_agents.action_modes import ActionMode, ResidualAction
from vcnc_agents.config import action_mode_of, with_action_mode
from vcnc_gym.envs.history import HISTORY_FIELDS, DecisionHistory, agent_space
from vcnc_agents.lean_ppo import DecisionEnv

HEART = "VCNC-Heart-v1"
K = 3


def _by_hand(layout, observations: list[np.ndarray], t: int, k: int = K) -> np.ndarray:
    """The past an agent should see at decision t: the fields of decisions t-1 .. t-k, newest first, the first
    observation standing in before the episode's start."""
    rows = []
    for j in range(1, k + 1):
        o = observations[max(t - j, 0)]
        rows.append(np.concatenate([o[layout.slice(name)] for name in HISTORY_FIELDS]))
    return np.concatenate(rows).astype(np.float32)


@pytest.fixture(scope="module")
def layout():
    env = gym.make(HEART)
    yield env.unwrapped.layout
    env.close()


def test_history_remembers_the_decisions_newest_first(layout):
    n, size = 3, layout.size
    h = DecisionHistory(K, layout, n)
    assert h.size == K * sum(layout.slice(name).stop - layout.slice(name).start for name in HISTORY_FIELDS)
    seq = [np.random.default_rng(i).normal(size=(n, size)).astype(np.float32) for i in range(5)]
    h.start(seq[0])
    for t in range(1, 5):
        h.push(seq[t - 1])
        for i in range(n):
            np.testing.assert_array_equal(h.past()[i], _by_hand(layout, [s[i] for s in seq], t))
    # a restart of one env refills its past only; a push of some rows leaves the others alone
    before = h.past()
    h.start(seq[4], np.array([False, True, False]))
    np.testing.assert_array_equal(h.past(np.array([0, 2])), before[[0, 2]])
    np.testing.assert_array_equal(h.past()[1], _by_hand(layout, [seq[4][1]], 0))
    h.push(seq[0], np.array([True, False, False]))
    np.testing.assert_array_equal(h.past()[2], before[2])
    seen = h.seen(seq[1], np.array([1]))
    np.testing.assert_array_equal(seen[0], np.concatenate([seq[1][1], h.past()[1]]))


def test_bad_history_is_refused_by_name(layout):
    with pytest.raises(ValueError, match="history"):
        DecisionHistory(0, layout, 2)
    with pytest.raises(ValueError, match="observations must have shape"):
        DecisionHistory(2, layout, 2).start(np.zeros((3, layout.size)))
    for bad in (-1, 1.5, True, "8"):
        with pytest.raises(ValueError, match="history"):
            ActionMode("residual", 10, "ff-pid", 0.2, history=bad)
    with pytest.raises(ValueError, match="residual mode only"):
        ActionMode("direct", 10, history=4)


def test_history_round_trips_through_a_config_entry():
    mode = ActionMode("residual", 10, "ff-pid", 0.2, history=8)
    assert mode.to_dict()["history"] == 8 and "history" not in ActionMode("residual", 10, "ff-pid", 0.2).to_dict()
    assert ActionMode(**mode.to_dict()) == mode
    assert action_mode_of(with_action_mode({"n_envs": 4}, mode)) == mode


@pytest.mark.filterwarnings("ignore:.*is different from the unwrapped version")  # the wrapper is what is checked
def test_the_wrapper_shows_the_past_and_passes_gymnasium_s_checker(layout):
    env = ResidualAction(
        gym.make(HEART, action_repeat=1), baseline="ff-pid", correction=0.2, action_repeat=10, history=K
    )
    check_env(env, skip_render_check=True)
    assert env.observation_space.shape == (layout.size + DecisionHistory(K, layout, 1).size,)
    obs, _ = env.reset(seed=3)
    plain = [obs[: layout.size]]
    np.testing.assert_array_equal(obs[layout.size :], _by_hand(layout, plain, 0))
    rng = np.random.default_rng(0)
    for t in range(1, 8):
        obs, *_ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        plain.append(obs[: layout.size])
        np.testing.assert_array_equal(obs[layout.size :], _by_hand(layout, plain, t))
    assert env.observation_space.contains(obs)
    env.close()


def test_the_lean_trainer_s_envs_show_what_the_wrapper_shows(layout):
    """The native vector env (one kernel call per decision, the compiled baseline) and the residual wrapper on a
    Gymnasium env of the same seed show the same past, decision by decision, up to the compiled baseline's
    rounding; an env reset in the batch starts its past again."""
    mode = ActionMode("residual", 10, "ff-pid", 0.2, history=K)
    batch = DecisionEnv(HEART, 2, mode, {}, seed=5)
    assert batch.observation_space == agent_space(batch.venv.single_observation_space, K, layout)
    wrapped = [mode.wrap(gym.make(HEART, action_repeat=1)) for _ in range(2)]
    obs = batch.reset()
    own = np.stack([w.reset(seed=5 + i)[0] for i, w in enumerate(wrapped)])
    np.testing.assert_allclose(obs, own, rtol=1e-6, atol=1e-9)
    rng = np.random.default_rng(2)
    plain = [obs[:, : layout.size]]
    for t in range(1, 12):
        a = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        obs, *_ = batch.step(a)
        own = np.stack([w.step(a[i])[0] for i, w in enumerate(wrapped)])
        np.testing.assert_allclose(obs, own, rtol=1e-5, atol=1e-9)
        plain.append(obs[:, : layout.size])
        for i in range(2):
            np.testing.assert_array_equal(obs[i, layout.size :], _by_hand(layout, [p[i] for p in plain], t))
    batch.close()
    # staggered starts: env i's baseline runs k_i decisions alone, which its past remembers (env 0 runs none)
    batch = DecisionEnv(HEART, 2, mode, {}, seed=5)
    first = batch.reset()
    obs = batch.stagger(first)
    assert obs.shape == (2, batch.observation_space.shape[0])
    np.testing.assert_array_equal(obs[0], first[0])
    assert not np.array_equal(obs[1, layout.size :], _by_hand(layout, [obs[1, : layout.size]], 0))
    batch.close()


def test_the_bench_s_agent_sees_the_same_past(layout):
    """:class:`AgentPolicy` (what ``vcnc-bench --policy ppo:PATH`` runs, one call per control period) builds, at
    each decision, the observation the lean trainer's envs built: the same past of the same fields."""
    from stable_baselines3 import PPO

    from vcnc_agents.lean_ppo import _spaces_only
    from vcnc_agents.policy import AgentPolicy
    from vcnc_gym.evaluation import run_episode

    mode = ActionMode("residual", 10, "ff-pid", 0.2, history=K)
    env = gym.make(HEART)
    space = agent_space(env.observation_space, K, layout)
    model = PPO("MlpPolicy", _spaces_only(space, env.action_space, 1), n_steps=8, batch_size=8, seed=0)
    policy = AgentPolicy(model, None, mode, env)
    seen = []
    actor = policy._actor
    policy._actor = lambda x: (seen.append(x.copy()), actor(x))[1]
    env = gym.wrappers.TimeLimit(env.unwrapped, max_episode_steps=200)
    run_episode(policy, env, seed=0)
    assert len(seen) == 20
    plain = [s[0, : layout.size] for s in seen]
    for t, s in enumerate(seen):
        np.testing.assert_array_equal(s[0, layout.size :], _by_hand(layout, plain, t))
    env.close()


@pytest.mark.slow  # a training run and a bench run (the pieces above run in make test)
def test_an_agent_with_history_trains_loads_and_scores_its_evaluation_in_the_bench(tmp_path, short_run_in_the_bench):
    """``history`` in the residual wrapper's entry: the lean trainer trains on the longer observation, the agent
    folder records it, and ``vcnc-bench`` (:func:`vcnc_agents.load_agent`) scores what the run's evaluation scored."""
    import math

    from vcnc_agents import load_agent

    def change(entry):
        entry.update(n_envs=4, n_steps=32, batch_size=64, n_epochs=1)
        entry["env_wrapper"][0]["vcnc_agents.action_modes.ResidualAction"]["history"] = K

    run, recorded, record = short_run_in_the_bench(tmp_path, HEART, change, 128)
    assert recorded["action_mode"]["history"] == K and recorded["trainer"] == "lean"
    env = gym.make(HEART)
    policy = load_agent(run / "best", env)
    assert policy.action_mode.history == K
    assert policy.model.observation_space.shape == agent_space(env.observation_space, K, env.unwrapped.layout).shape
    assert math.isfinite(record["max_contour_error_um"])
    assert record["max_contour_error_um"] == pytest.approx(recorded["agent"]["evaluation"]["max_um"], rel=1e-9)


def test_vcnc_train_history_changes_the_entry_s_memory_only():
    """``vcnc-train --history K`` over an entry keeps its baseline, correction and decision period; on a direct mode
    it is refused by name."""
    from pathlib import Path

    from vcnc_agents.arguments import action_mode, parser

    root = Path(__file__).resolve().parents[1]
    adaptive = root / "experiments" / "adaptive" / "recipes" / "adaptive.yml"
    args = parser().parse_args(["--env", "VCNC-HeartShop-v1", "--config", str(adaptive), "--history", "64"])
    assert action_mode(args, adaptive) == ActionMode("residual", 5, "ff-ccc", 0.3, history=64)
    args = parser().parse_args(["--env", "VCNC-HeartShop-v1", "--config", str(adaptive), "--action-repeat", "10"])
    assert action_mode(args, adaptive).history == 16  # the entry's memory, unchanged by another option
    args = parser().parse_args(["--env", HEART, "--action-mode", "direct", "--history", "4"])
    with pytest.raises(ValueError, match="--peak-weight and --dial-rate apply to --action-mode residual"):
        action_mode(args, root / "agents" / "hyperparams" / "ppo.yml")


def test_an_ended_episode_s_last_observation_keeps_its_past_and_the_next_starts_afresh():
    """The lean trainer's terminal observation (its value bootstraps a cut-off episode) is the ended episode's last
    observation with that episode's past; the env reset in its place starts from its own first observation."""
    mode = ActionMode("residual", 50, "ff-pid", 0.2, history=K)
    batch = DecisionEnv("VCNC-GCode-v1", 1, mode, {"program": "G01 X5 F6000\n"}, seed=0)
    size = batch.venv.layout.size
    obs = batch.reset()
    plain = [obs[0, :size]]
    zero = np.zeros((1, 2), dtype=np.float32)
    for t in range(1, 500):
        obs, _, te, tr, terminal = batch.step(zero)
        if te[0] or tr[0]:
            break
        plain.append(obs[0, :size])
    assert terminal is not None and terminal.shape == (1, batch.observation_space.shape[0])
    np.testing.assert_array_equal(terminal[0, size:], _by_hand(batch.venv.layout, plain + [terminal[0, :size]], t))
    np.testing.assert_array_equal(obs[0, size:], _by_hand(batch.venv.layout, [obs[0, :size]], 0))
    batch.close()
