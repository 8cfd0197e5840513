"""agents: PPO training and resume, fail-fast checks, action modes, AgentPolicy, and ppo: agents in vcnc-bench.

Everything that trains or runs episodes uses the omega (7000 control
periods).  One short training run (one PPO rollout: the entry's n_steps 1024
x 2 envs) is shared by most tests through a module-scoped fixture.
"""

from __future__ import annotations

import importlib.util
import json
import csv
import math
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path

import vcnc_baselines
import gymnasium as gym
import numpy as np
import pytest
import stable_baselines3  # noqa: F401  (imported here so the fail-fast timings below do not count it)
import torch
import yaml

import vcnc_agents
import vcnc_gym
from vcnc_agents import ActionMode, ResidualAction, load_agent
from vcnc_agents.cli import main as train_main
from vcnc_agents.config import action_mode_of, load_hyperparameters, normalize_kwargs, ppo_arguments, with_action_mode
import vcnc_bench as bench
from vcnc_gym.evaluation import run_episode

OMEGA = "VCNC-Omega-v1"
HEART = "VCNC-Heart-v1"
CORNERS = "VCNC-Corners-v1"
CORNERS_SMOOTH = "VCNC-CornersSmooth-v1"
ROOT = Path(__file__).resolve().parents[1]
OMEGA_ENTRY = load_hyperparameters(OMEGA)
OMEGA_MODE = action_mode_of(OMEGA_ENTRY)
ROLLOUT = OMEGA_ENTRY["n_steps"] * 2  # agent steps of one PPO rollout of the Omega entry with n_envs 2
AGENT_FILES = ("model.zip", "vecnormalize.npz", "config.yml")


#: Every test of this module runs torch on one thread (tests/conftest.py).
pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def omega_run(tmp_path_factory):
    """One PPO rollout on the omega with the shipped entry; a checkpoint asked for every half rollout."""
    run_dir = tmp_path_factory.mktemp("omega") / "run"
    result = vcnc_agents.train(
        OMEGA,
        run_dir,
        n_timesteps=ROLLOUT,
        n_envs=2,
        eval_freq=ROLLOUT,
        checkpoint_freq=ROLLOUT // 2,
        progress_bar=False,
    )
    return result


def model_timesteps(zip_path) -> int:
    from vcnc_agents.model_file import model_timesteps as recorded

    return recorded(zip_path)


def sessions(run_dir) -> list[dict]:
    return json.loads((Path(run_dir) / "summary.json").read_text())["sessions"]


def assert_finished_episode(res):
    """A whole episode on the nominal plant: terminated at the contour's end, not diverged, finite errors."""
    assert res.terminated and not res.truncated and not res.diverged
    assert np.all(np.isfinite(res.contour_error)) and np.all(np.isfinite(res.position))
    assert math.isfinite(res.max_contour_error_um) and math.isfinite(res.rms_contour_error_um)


# -- 1. a short training run ------------------------------------------------------------
def test_short_run_writes_agents_checkpoints_and_logs(omega_run):
    d = omega_run.run_dir
    assert omega_run.timesteps == omega_run.session_timesteps == ROLLOUT
    for agent in ("best", "final"):
        for name in AGENT_FILES:
            assert (d / agent / name).is_file(), f"{agent}/{name} missing"
    # checkpoints are written between PPO updates only: at the end of the one rollout
    assert sorted(p.name for p in (d / "checkpoints").iterdir()) == [
        f"rl_model_{ROLLOUT}_steps.zip",
        f"rl_model_vecnormalize_{ROLLOUT}_steps.npz",
    ]
    config = yaml.safe_load((d / "config.yml").read_text())
    assert config["env_id"] == OMEGA and config["n_timesteps"] == ROLLOUT and config["n_envs"] == 2
    assert config["action_mode"] == OMEGA_MODE.to_dict() and OMEGA_MODE.mode == "residual"
    final = yaml.safe_load((d / "final" / "config.yml").read_text())
    assert final.pop("agent") == {"timesteps": ROLLOUT, "evaluation": None} and final == config
    rows = (d / "evaluations.csv").read_text().splitlines()
    assert rows[0] == "steps,max_um,mean_um,rms_um,score_um,diverged" and len(rows) == 2
    summary = json.loads((d / "summary.json").read_text())
    assert summary["timesteps"] == ROLLOUT and len(summary["sessions"]) == 1
    s = summary["sessions"][0]
    assert (s["start_timesteps"], s["end_timesteps"]) == (0, ROLLOUT) and s["steps_per_s"] > 0
    assert summary["best"]["steps"] == ROLLOUT and math.isfinite(summary["best"]["score_um"])
    assert omega_run.best == summary["best"]


@pytest.fixture(scope="module")
def omega_episodes(omega_run):
    """best/ and final/ of the shared run, loaded on the plain env, one benchmark episode each."""
    env = gym.make(OMEGA)
    policies = {agent: load_agent(omega_run.run_dir / agent, env) for agent in ("best", "final")}
    return env, {agent: run_episode(policy, env, seed=0) for agent, policy in policies.items()}


def test_trained_agents_run_a_benchmark_episode(omega_run, omega_episodes):
    """best/ and final/ load on the plain env; best/ scores what its evaluation in training recorded."""
    env, results = omega_episodes
    for res in results.values():
        assert_finished_episode(res)
        assert res.completed and res.cycle_time_s >= env.unwrapped.reference.duration
    # training evaluates through the benchmark's run_episode
    assert results["best"].max_contour_error_um == pytest.approx(omega_run.best["max_um"], rel=1e-9)
    assert results["best"].rms_contour_error_um == pytest.approx(omega_run.best["rms_um"], rel=1e-9)
    # load_agent also takes the model.zip itself
    policy = load_agent(omega_run.run_dir / "final" / "model.zip", env)
    assert isinstance(policy, vcnc_agents.AgentPolicy) and policy.action_mode.mode == "residual"


def test_the_final_model_is_evaluated(omega_run, omega_episodes):
    _, results = omega_episodes
    rows = (omega_run.run_dir / "evaluations.csv").read_text().splitlines()[1:]
    maxima = [float(r.split(",")[1]) for r in rows]
    assert results["final"].max_contour_error_um == pytest.approx(maxima[-1], rel=1e-9)


def test_the_newest_checkpoint_is_the_final_model(omega_run):
    from vcnc_agents.model_file import read_model_data

    d = omega_run.run_dir
    final = read_model_data(d / "final" / "model.zip")
    newest = read_model_data(d / "checkpoints" / f"rl_model_{ROLLOUT}_steps.zip")
    assert newest["num_timesteps"] == final["num_timesteps"] == ROLLOUT
    assert newest["_n_updates"] == final["_n_updates"] > 0


# -- 2. resume ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def resumed_run(omega_run, tmp_path_factory):
    """A copy of the shared run resumed through the Python API to two rollouts (checkpoint at the end)."""
    run_dir = tmp_path_factory.mktemp("resume") / "run"
    shutil.copytree(omega_run.run_dir, run_dir)
    result = vcnc_agents.train(
        run_dir=run_dir,
        resume=True,
        n_timesteps=2 * ROLLOUT,
        eval_freq=0,
        checkpoint_freq=ROLLOUT,
        progress_bar=False,
        tensorboard=False,
    )
    return result


def test_resume_goes_on_from_the_newest_checkpoint(resumed_run):
    d = resumed_run.run_dir
    assert resumed_run.timesteps == 2 * ROLLOUT and resumed_run.session_timesteps == ROLLOUT
    assert model_timesteps(d / "final" / "model.zip") == 2 * ROLLOUT
    first, second = sessions(d)
    assert first["end_timesteps"] == second["start_timesteps"] == ROLLOUT
    assert second["end_timesteps"] == 2 * ROLLOUT
    assert json.loads((d / "summary.json").read_text())["timesteps"] == 2 * ROLLOUT
    assert yaml.safe_load((d / "config.yml").read_text())["n_timesteps"] == 2 * ROLLOUT
    assert (d / "checkpoints" / f"rl_model_{2 * ROLLOUT}_steps.zip").is_file()


def test_cli_resume_goes_on_to_a_new_total(resumed_run, capsys):
    d = resumed_run.run_dir
    assert train_main(["--resume", str(d), "--timesteps", str(3 * ROLLOUT), "--no-progress"]) == 0
    assert f"{3 * ROLLOUT} in all" in capsys.readouterr().out
    assert model_timesteps(d / "final" / "model.zip") == 3 * ROLLOUT
    s = sessions(d)
    assert [(x["start_timesteps"], x["end_timesteps"]) for x in s] == [
        (0, ROLLOUT),
        (ROLLOUT, 2 * ROLLOUT),
        (2 * ROLLOUT, 3 * ROLLOUT),
    ]


# -- 3. fail-fast errors ---------------------------------------------------------------------
def _dir_with_config_only(tmp_path, omega_run):
    d = tmp_path / "no_checkpoint"
    d.mkdir()
    shutil.copyfile(omega_run.run_dir / "config.yml", d / "config.yml")
    return d


def _bad_runs(tmp_path, omega_run):
    """(name, CLI argv, train() kwargs, exception of train(), text the message must hold, folder)."""
    out = tmp_path / "out"
    empty = tmp_path / "empty"
    empty.mkdir()
    config_only = _dir_with_config_only(tmp_path, omega_run)
    existing = omega_run.run_dir
    return [
        (
            "unknown env",
            ["--env", "VCNC-Nope-v0", "--output", str(out)],
            dict(env_id="VCNC-Nope-v0", run_dir=out),
            ValueError,
            [HEART, OMEGA],
            out,
        ),
        (
            "zero steps",
            ["--env", OMEGA, "--output", str(out), "--timesteps", "0"],
            dict(env_id=OMEGA, run_dir=out, n_timesteps=0),
            ValueError,
            ["n_timesteps"],
            out,
        ),
        (
            "negative steps",
            ["--env", OMEGA, "--output", str(out), "--timesteps", "-5"],
            dict(env_id=OMEGA, run_dir=out, n_timesteps=-5),
            ValueError,
            ["n_timesteps", "-5"],
            out,
        ),
        (
            "resume empty",
            ["--resume", str(empty)],
            dict(run_dir=empty, resume=True),
            FileNotFoundError,
            ["config.yml"],
            empty,
        ),
        (
            "resume without checkpoint",
            ["--resume", str(config_only)],
            dict(run_dir=config_only, resume=True),
            FileNotFoundError,
            ["checkpoint"],
            config_only,
        ),
        (
            "existing run",
            ["--env", OMEGA, "--output", str(existing)],
            dict(env_id=OMEGA, run_dir=existing),
            FileExistsError,
            ["already holds a run"],
            existing,
        ),
    ]


def _snapshot(folder: Path) -> dict:
    return {p: p.stat().st_mtime_ns for p in folder.rglob("*")} if folder.exists() else {}


def _assert_nothing_trained(folder: Path, before: dict, started: float):
    assert time.perf_counter() - started < 5.0, "the check came after some work"
    assert _snapshot(folder) == before, "the failed call wrote into the run folder"
    if not before:  # a new run: nothing at all was created
        assert not folder.exists() or not any(folder.iterdir())


def test_cli_refuses_bad_runs_before_training(tmp_path, omega_run, capsys):
    for name, argv, _, _, must_name, folder in _bad_runs(tmp_path, omega_run):
        before = _snapshot(folder)
        t0 = time.perf_counter()
        with pytest.raises(SystemExit) as exc:
            train_main(argv + ["--no-progress"])
        assert exc.value.code == 2, name
        err = capsys.readouterr().err
        for text in must_name:
            assert text in err, f"{name}: {text!r} not in {err!r}"
        _assert_nothing_trained(folder, before, t0)


def test_train_api_refuses_bad_runs_before_training(tmp_path, omega_run):
    for name, _, kwargs, exc_type, must_name, folder in _bad_runs(tmp_path, omega_run):
        before = _snapshot(folder)
        t0 = time.perf_counter()
        with pytest.raises(exc_type) as exc:
            vcnc_agents.train(progress_bar=False, **kwargs)
        for text in must_name:
            assert text in str(exc.value), f"{name}: {text!r} not in {exc.value}"
        _assert_nothing_trained(folder, before, t0)


# -- 4. action modes --------------------------------------------------------------------------
def residual_smc(**kwargs):
    return ResidualAction(gym.make(OMEGA), baseline="smc", correction=0.3, action_repeat=5, **kwargs)


def test_residual_with_zero_action_is_the_baseline_every_fifth_period():
    env = gym.make(OMEGA)
    res = run_episode(vcnc_baselines.make("smc", env), env, seed=0)
    w = residual_smc()
    w.reset(seed=0)
    positions = []
    while True:
        _, _, term, trunc, info = w.step(np.zeros(2, dtype=np.float32))
        positions.append(info["position"].copy())
        if term or trunc:
            break
    assert term and not trunc and len(positions) == w.episode_steps == math.ceil(res.episode_steps / 5)
    idx = np.minimum(np.arange(len(positions)) * 5 + 4, res.episode_steps - 1)
    np.testing.assert_allclose(positions, res.position[idx], rtol=0, atol=1e-12)


def test_residual_command_and_reward_against_a_hand_written_loop():
    """command = clip(baseline + 0.3 a) x 5 V; reward = mean of the control periods'; same trajectory."""
    w = residual_smc()
    plain = gym.make(OMEGA)
    base = vcnc_baselines.make("smc", plain)
    obs_w, _ = w.reset(seed=0)
    obs, _ = plain.reset(seed=0)
    start = np.array([True])
    rng = np.random.default_rng(0)
    for _ in range(60):
        a = rng.uniform(-1, 1, size=2).astype(np.float32)  # the action space's dtype: what the command computes in
        obs_w, reward, term, trunc, info = w.step(a)
        rewards, peaks = [], []
        for _ in range(5):
            b, _ = base.predict(obs, episode_start=start)
            start = np.array([False])
            obs, r, t, _, inner = plain.step(np.clip(b + 0.3 * a, -1, 1).astype(np.float32))
            rewards.append(r)
            peaks.append(inner["contour_error_max"])
        np.testing.assert_allclose(
            info["command"], 5.0 * np.clip(b.astype(np.float64) + 0.3 * a, -1, 1), rtol=0, atol=1e-5
        )
        assert reward == pytest.approx(np.mean(rewards), rel=1e-12)
        assert info["contour_error_max"] == max(peaks)
        np.testing.assert_array_equal(info["position"], inner["position"])
        np.testing.assert_array_equal(obs_w, obs)
        assert term == t and not trunc
    assert w.decision_period == pytest.approx(5 * plain.unwrapped.dt)


def test_residual_refuses_bad_actions_and_a_repeating_env():
    w = residual_smc()
    with pytest.raises(RuntimeError):
        w.step(np.zeros(2))  # before reset
    w.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        w.step(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        w.step(np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="action_repeat=1"):
        ResidualAction(gym.make(OMEGA, action_repeat=2), baseline="smc", correction=0.3, action_repeat=5)


def test_residual_wrapper_passes_the_env_checkers():
    from gymnasium.utils.env_checker import check_env as gym_check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        # gymnasium notes that a wrapper is not its unwrapped env; that is the point here
        warnings.filterwarnings("ignore", message=".*unwrapped.*")
        gym_check_env(residual_smc(), skip_render_check=True)
    sb3_check_env(residual_smc(), warn=True, skip_render_check=True)


def test_residual_wrapper_can_be_remade_from_its_spec():
    remade = residual_smc().spec.make()
    assert isinstance(remade, ResidualAction) and remade.action_repeat == 5


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(mode="hybrid"),
        dict(mode="residual", correction=0.3),  # no baseline
        dict(mode="residual", baseline="nope", correction=0.3),
        dict(mode="residual", baseline="smc", correction=0),
        dict(mode="residual", baseline="smc", correction=3),
        dict(mode="residual", baseline="smc", correction=float("nan")),
        dict(mode="residual", baseline="smc"),  # no correction
        dict(mode="direct", action_repeat=0),
        dict(mode="direct", action_repeat=2.5),
        dict(mode="direct", baseline="smc"),  # residual-only options
    ],
)
def test_action_mode_refuses_bad_arguments(kwargs):
    with pytest.raises(ValueError):
        ActionMode(**kwargs)


def test_action_mode_command_and_dict_round_trip():
    mode = ActionMode("residual", action_repeat=5, baseline="smc", correction=0.3)
    c = mode.command(np.array([0.9, -0.5]), np.array([2.0, 0.5]))  # the agent's action is clipped first
    assert c.dtype == np.float32
    np.testing.assert_allclose(c, [1.0, -0.35], rtol=1e-6)
    assert ActionMode(**mode.to_dict()) == mode
    direct = ActionMode("direct", action_repeat=4)
    np.testing.assert_array_equal(direct.command(None, np.array([1.5, -0.25])), np.float32([1.0, -0.25]))
    assert ActionMode(**direct.to_dict()) == direct
    with pytest.raises(ValueError, match="action_repeat=4"):
        direct.wrap(gym.make(OMEGA))


# -- 5. AgentPolicy on the plain env = the model on its training env --------------------------
@pytest.fixture(scope="module")
def direct_run(tmp_path_factory):
    """A tiny direct-mode agent deciding every 4 control periods (1024 steps, 1 env)."""
    run_dir = tmp_path_factory.mktemp("direct") / "run"
    return vcnc_agents.train(
        OMEGA,
        run_dir,
        n_timesteps=1024,
        n_envs=1,
        action_mode=ActionMode("direct", action_repeat=4),
        eval_freq=0,
        checkpoint_freq=10**6,
        progress_bar=False,
        tensorboard=False,
    )


def model_positions(policy, env) -> list[np.ndarray]:
    """Positions after each step of ``env`` (the training form) driven by the bare model and its normalisation."""
    obs, _ = env.reset(seed=0)
    positions = []
    while True:
        action, _ = policy.model.predict(policy.normalization.normalize_obs(obs[None]), deterministic=True)
        obs, _, term, trunc, info = env.step(action[0])
        positions.append(info["position"].copy())
        if term or trunc:
            return positions


def test_direct_agent_on_the_plain_env_matches_its_repeating_env(direct_run):
    """Every 4th control period of load_agent's policy on the plain env = the model on the action_repeat=4 env.

    The tiny agent's deterministic commands (~0.4 V) do not overcome the plant's friction, so its
    action head is scaled by 30 (in both runs: one model object) to make the table move.
    """
    config = yaml.safe_load((direct_run.run_dir / "final" / "config.yml").read_text())
    assert config["action_mode"] == {"mode": "direct", "action_repeat": 4}
    env = gym.make(OMEGA)
    policy = load_agent(direct_run.run_dir / "final", env)
    with torch.no_grad():
        policy.model.policy.action_net.weight.mul_(30.0)
        policy.model.policy.action_net.bias.mul_(30.0)
    res = run_episode(policy, env, seed=0)
    assert np.ptp(res.position[:, 1]) > 1.0  # mm: the table moved
    positions = model_positions(policy, gym.make(OMEGA, action_repeat=4))
    n = min(len(positions), res.episode_steps // 4)  # the repeating env runs whole steps past the end
    assert n >= len(positions) - 1 and n > 100
    np.testing.assert_array_equal(np.array(positions[:n]), res.position[3 : 4 * n : 4])


def test_a_diverged_evaluation_is_never_the_best(direct_run):
    """A table that never moves has contour error 0 but diverges on the tracking bound: score inf, never best."""
    rows = list(csv.DictReader(open(direct_run.run_dir / "evaluations.csv")))
    diverged = [r for r in rows if r["diverged"] == "True"]
    if not diverged:
        pytest.skip("the tiny direct agent did not diverge")
    assert all(float(r["score_um"]) == math.inf for r in diverged)
    assert direct_run.best is None or not direct_run.best["diverged"]


def test_residual_agent_on_the_plain_env_matches_its_wrapper(omega_run):
    env = gym.make(OMEGA)
    policy = load_agent(omega_run.run_dir / "final", env)
    assert policy.action_mode == OMEGA_MODE
    res = run_episode(policy, env, seed=0)
    k = OMEGA_MODE.action_repeat
    positions = model_positions(policy, OMEGA_MODE.wrap(gym.make(OMEGA)))
    assert len(positions) == math.ceil(res.episode_steps / k)
    idx = np.minimum(np.arange(len(positions)) * k + k - 1, res.episode_steps - 1)
    np.testing.assert_array_equal(np.array(positions), res.position[idx])


# -- 6. the bench ---------------------------------------------------------------------------------
def test_bench_evaluates_a_ppo_agent(omega_run, tmp_path, capsys):
    out = tmp_path / "bench.json"
    spec = f"ppo:{omega_run.run_dir / 'best'}"
    assert bench.main(["--env", OMEGA, "--policy", spec, "--policy", "smc", "--no-progress", "--json", str(out)]) == 0
    records = {r["policy"]: r for r in json.loads(out.read_text())["records"]}
    assert set(records) == {spec, "smc"}
    agent = records[spec]
    assert agent["env"] == OMEGA and agent["diverged"] is False
    assert math.isfinite(agent["max_contour_error_um"]) and math.isfinite(agent["rms_contour_error_um"])
    assert agent["paper_max_contour_error_um"] is None  # the paper has no row for an agent
    assert agent["max_contour_error_um"] == pytest.approx(omega_run.best["max_um"], rel=1e-9)
    assert spec in capsys.readouterr().out


def test_bench_refuses_a_missing_or_mismatched_agent(omega_run, tmp_path, capsys):
    missing = tmp_path / "no_such_agent"
    with pytest.raises(SystemExit) as exc:
        bench.main(["--env", OMEGA, "--policy", f"ppo:{missing}", "--no-progress"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert str(missing) in err and "no agent" in err
    with pytest.raises(SystemExit) as exc:
        bench.main(["--env", HEART, "--policy", f"ppo:{omega_run.run_dir / 'best'}", "--no-progress"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"trained on {OMEGA}" in err and HEART in err


# -- 7. the shipped agents --------------------------------------------------------------------------
@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
@pytest.mark.parametrize("env_id", sorted(vcnc_agents.TRAINED))
def test_shipped_agent_completes_its_contour(env_id):
    folder = vcnc_agents.TRAINED[env_id]
    assert sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()) < 5 * 2**20
    for name in AGENT_FILES:
        assert (folder / name).is_file()
    env = gym.make(env_id)
    res = run_episode(load_agent(folder, env), env, seed=0)
    assert_finished_episode(res)


def test_the_agents_deterministic_actor_is_sb3s_predict_to_the_bit():
    """AgentPolicy's deterministic actor (no eval-mode walk, no distribution object per call) gives SB3's own
    ``model.predict(x, deterministic=True)``, for a batch and a single row, on observations beyond the clip."""
    env = gym.make(HEART)
    policy = load_agent(vcnc_agents.TRAINED[HEART], env)
    assert policy._actor is not None
    x = np.random.default_rng(3).normal(scale=3.0, size=(257, env.observation_space.shape[0])).astype(np.float32)
    expected, _ = policy.model.predict(x, deterministic=True)
    assert np.array_equal(policy._actor(x), expected)
    assert np.array_equal(policy._actor(x[:1]), policy.model.predict(x[:1], deterministic=True)[0])


# -- 8. hyperparameters -----------------------------------------------------------------------------
@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
def test_every_env_has_an_entry_that_prepares_a_run(tmp_path):
    """vcnc-train --env ID works for every registered id: its entry passes every check (env, action mode,
    baseline, policy network) and nothing is written before training."""
    entries = yaml.safe_load((ROOT / "agents" / "hyperparams" / "ppo.yml").read_text())
    assert set(entries) == set(vcnc_gym.ENV_IDS)
    for env_id in vcnc_gym.ENV_IDS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", vcnc_agents.RunWarning)  # n_timesteps rounded up to whole rollouts
            run_dir, config, checkpoint = vcnc_agents.training.prepare_run(env_id, tmp_path / env_id)
        assert checkpoint is None and not run_dir.exists()
        mode = config.mode
        assert mode.mode == "residual" and mode.baseline in vcnc_baselines.names()
        assert config.n_timesteps % (config.hyperparams["n_steps"] * config.n_envs) == 0
    # Yadav et al.'s positioning entry, as its helper proposed it
    step = load_hyperparameters("VCNC-Step-v0")
    assert action_mode_of(step) == ActionMode("residual", action_repeat=1, baseline="hinf-reduced", correction=0.05)
    assert (step["n_envs"], step["n_steps"], step["batch_size"], step["gamma"]) == (4, 512, 256, 0.99)


def test_an_env_without_a_native_vector_env_trains_on_sb3s(tmp_path):
    """VCNC-Step-v0 (a positioning env) has no native vector env: the default --vec-env native falls back to
    SB3's DummyVecEnv, says so, and trains."""
    assert "VCNC-Step-v0" not in vcnc_gym.envs.VECTOR_IDS
    entry = load_hyperparameters("VCNC-Step-v0")
    rollout = entry["n_steps"] * entry["n_envs"]
    with pytest.warns(vcnc_agents.RunWarning, match="no native vector env"):
        result = vcnc_agents.train(
            "VCNC-Step-v0", tmp_path / "run", n_timesteps=rollout, progress_bar=False, tensorboard=False
        )
    assert result.timesteps == rollout and result.best is not None
    assert sessions(result.run_dir)[-1]["status"] == "finished"


def test_hyperparameters_of_both_envs_load_and_describe_their_action_mode():
    expected = {
        HEART: ActionMode("residual", action_repeat=10, baseline="smc", correction=0.2),
        OMEGA: ActionMode("residual", action_repeat=10, baseline="qft", correction=1.0),
    }
    for env_id in (HEART, OMEGA):
        h = load_hyperparameters(env_id)
        assert h["n_envs"] >= 1 and h["n_timesteps"] > 0 and h["policy"] == "MlpPolicy"
        assert action_mode_of(h) == expected[env_id]
        policy, kwargs = ppo_arguments(h)
        assert policy == "MlpPolicy"
        assert not {"n_timesteps", "n_envs", "policy", "normalize", "env_kwargs", "env_wrapper"} & set(kwargs)
        assert kwargs["policy_kwargs"]["net_arch"] == {"pi": [64, 64], "vf": [64, 64]}
        assert normalize_kwargs(h) == {"norm_obs": True, "norm_reward": True, "gamma": h["gamma"]}
    with pytest.raises(ValueError) as exc:
        load_hyperparameters("VCNC-Nope-v0")
    assert HEART in str(exc.value) and OMEGA in str(exc.value)


def test_with_action_mode_round_trips_both_modes():
    h = load_hyperparameters(OMEGA)
    direct = ActionMode("direct", action_repeat=4)
    hd = with_action_mode(h, direct)
    assert "env_wrapper" not in hd and hd["env_kwargs"] == {"action_repeat": 4}
    assert action_mode_of(hd) == direct
    residual = ActionMode("residual", action_repeat=5, baseline="smc", correction=0.3, baseline_params={"rho": 2.0})
    hr = with_action_mode(hd, residual)
    assert "env_kwargs" not in hr
    assert action_mode_of(hr) == residual
    assert action_mode_of(with_action_mode(hr, direct)) == direct
    assert h == load_hyperparameters(OMEGA)  # the input is not changed


def test_ppo_arguments_evaluate_schedules_and_policy_kwargs():
    _, kwargs = ppo_arguments(
        {
            "learning_rate": "lin_3e-4",
            "clip_range": 0.2,
            "n_timesteps": 10,
            "policy_kwargs": "dict(log_std_init=-1.0, net_arch=[32, 32], activation_fn=nn.Tanh)",
        }
    )
    assert callable(kwargs["learning_rate"])
    assert kwargs["learning_rate"](1.0) == pytest.approx(3e-4) and kwargs["learning_rate"](0.5) == pytest.approx(1.5e-4)
    assert kwargs["clip_range"] == 0.2 and "n_timesteps" not in kwargs
    assert kwargs["policy_kwargs"] == {"log_std_init": -1.0, "net_arch": [32, 32], "activation_fn": torch.nn.Tanh}
    with pytest.raises(ValueError):
        ppo_arguments({"learning_rate": "lin_-1"})
    with pytest.raises(ValueError):
        ppo_arguments({"policy_kwargs": "dict(net_arch="})
    assert normalize_kwargs({"normalize": False, "gamma": 0.9}) is None
    assert normalize_kwargs({"normalize": True, "gamma": 0.9}) == {"gamma": 0.9}
    assert normalize_kwargs({"normalize": "{'norm_obs': True, 'norm_reward': False}"}) == {
        "norm_obs": True,
        "norm_reward": False,
    }


# -- 9. RL Zoo ---------------------------------------------------------------------------------------
@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
@pytest.mark.skipif(importlib.util.find_spec("rl_zoo3") is None, reason="rl_zoo3 is not installed")
def test_rl_zoo_trains_with_the_shipped_hyperparameters(tmp_path):
    """The YAML is in the Zoo's format: its train script runs one rollout and saves model and VecNormalize."""
    cmd = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        "ppo",
        "--env",
        OMEGA,
        "--gym-packages",
        "vcnc_gym",
        "--conf-file",
        str(ROOT / "agents" / "hyperparams" / "ppo.yml"),
        "-n",
        str(ROLLOUT),
        "-f",
        str(tmp_path),
        "--eval-freq",
        "-1",
        "--save-freq",
        "-1",
        "--seed",
        "0",
        "--num-threads",
        "1",
    ]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert list(tmp_path.rglob(f"{OMEGA}.zip")), "no model saved"
    assert list(tmp_path.rglob("vecnormalize.pkl")), "no VecNormalize saved"
