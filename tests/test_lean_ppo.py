"""vcnc_agents.lean_ppo: the lean PPO's pieces against Stable-Baselines3's own, and a short run that vcnc-bench loads.

The pieces are checked against SB3 (which no one here wrote): the advantage
estimate against ``RolloutBuffer.compute_returns_and_advantage``, the
normalisation against ``VecNormalize`` on the same stream, the written-out
log-probability against ``ActorCriticPolicy.evaluate_actions``.  One short
run through ``vcnc-train --trainer lean`` on the heart (a few hundred agent
steps) is shared by the rest.
"""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

import vcnc_bench as bench
import vcnc_gym  # noqa: F401
from vcnc_agents import load_agent
from vcnc_agents.cli import main as train_main
from vcnc_agents.config import load_hyperparameters
from vcnc_agents.lean_ppo import DecisionEnv, LeanPPO, PhaseClock, RunningNormalizer, _gae
from vcnc_agents.action_modes import ActionMode
from vcnc_agents.model_file import model_timesteps

HEART = "VCNC-Heart-v1"
N_ENVS, N_STEPS = 4, 32
ROLLOUT = N_ENVS * N_STEPS


#: Every test of this module runs torch on one thread (tests/conftest.py).
pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def small_entry(tmp_path_factory):
    """The shipped heart entry with rollouts of 4 envs x 32 decisions, minibatches of 64, 2 epochs."""
    entry = load_hyperparameters(HEART)
    entry.update(n_envs=N_ENVS, n_steps=N_STEPS, batch_size=64, n_epochs=2)
    path = tmp_path_factory.mktemp("lean_cfg") / "ppo.yml"
    path.write_text(yaml.safe_dump({HEART: entry}, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def lean_run(tmp_path_factory, small_entry):
    run_dir = tmp_path_factory.mktemp("lean") / "run"
    assert (
        train_main(
            [
                "--env",
                HEART,
                "--trainer",
                "lean",
                "--config",
                str(small_entry),
                "--timesteps",
                str(3 * ROLLOUT),
                "--eval-freq",
                "0",
                "--checkpoint-freq",
                str(ROLLOUT),
                "--output",
                str(run_dir),
                "--no-progress",
            ]
        )
        == 0
    )
    return run_dir


# -- the pieces against SB3 ------------------------------------------------------------------------------------
def test_advantages_and_returns_equal_sb3_rollout_buffer():
    from stable_baselines3.common.buffers import RolloutBuffer

    rng = np.random.default_rng(0)
    t_len, n, gamma, lam = 7, 3, 0.98, 0.95
    rewards = rng.normal(size=(t_len, n)).astype(np.float32)
    values = rng.normal(size=(t_len, n)).astype(np.float32)
    starts = (rng.random((t_len, n)) < 0.25).astype(np.float32)
    last_values = rng.normal(size=n).astype(np.float32)
    last_done = np.array([1.0, 0.0, 0.0], dtype=np.float32)
    space = gym.spaces.Box(-1, 1, (1,))
    buf = RolloutBuffer(t_len, space, space, n_envs=n, gamma=gamma, gae_lambda=lam)
    for t in range(t_len):
        buf.add(np.zeros((n, 1)), np.zeros((n, 1)), rewards[t], starts[t], torch.tensor(values[t]), torch.zeros(n))
    buf.compute_returns_and_advantage(torch.tensor(last_values), last_done)
    adv, ret = _gae(rewards, values, starts, last_values, last_done, gamma, lam)
    np.testing.assert_allclose(adv, buf.advantages, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(ret, buf.returns, rtol=1e-5, atol=1e-6)


def test_normalizer_equals_vecnormalize_on_the_same_stream():
    from stable_baselines3.common.vec_env import VecNormalize
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    rng = np.random.default_rng(1)
    n, d = 3, 5
    stream = [(rng.normal(3.0, 2.0, (n, d)), rng.normal(size=n), rng.random(n) < 0.2) for _ in range(30)]

    class Replay(VecEnv):  # replays the stream: what VecNormalize wraps
        def __init__(self):
            super().__init__(n, gym.spaces.Box(-np.inf, np.inf, (d,)), gym.spaces.Box(-1, 1, (1,)))
            self.k = 0

        def reset(self):
            return stream[0][0]

        def step_async(self, actions):
            pass

        def step_wait(self):
            self.k += 1
            obs, r, done = stream[self.k]
            return obs, r, done, [{} for _ in range(n)]

        def close(self):
            pass

        get_attr = set_attr = env_method = env_is_wrapped = lambda self, *a, **k: [None] * n

    vec = VecNormalize(Replay(), gamma=0.9)
    ours = RunningNormalizer.fresh({"normalize": True, "gamma": 0.9}, d, n)
    np.testing.assert_allclose(ours.observe(stream[0][0]), vec.reset(), rtol=1e-6)
    for k in range(1, len(stream) - 1):
        obs, r, done, _ = vec.step(np.zeros((n, 1)))
        np.testing.assert_allclose(ours.observe(stream[k][0]), obs, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(ours.reward(stream[k][1], stream[k][2]), r, rtol=1e-6, atol=1e-6)
    stats = ours.stats()
    np.testing.assert_allclose(stats.obs_mean, vec.obs_rms.mean)
    assert stats.ret_var == pytest.approx(float(vec.ret_rms.var))


def test_written_out_log_probability_equals_the_policy_s(small_entry):
    """The rollout's actions and log-probabilities are those of SB3's Gaussian policy on the same draws."""
    env = DecisionEnv(HEART, 3, ActionMode("residual", 10, "smc", 0.2), {}, seed=0)
    from stable_baselines3 import PPO

    from vcnc_agents.lean_ppo import _spaces_only

    model = PPO(
        "MlpPolicy",
        _spaces_only(env.observation_space, env.action_space, 3),
        n_steps=4,
        batch_size=6,
        policy_kwargs=dict(log_std_init=-1.5),
        seed=0,
    )
    ppo = LeanPPO(
        model, env, RunningNormalizer.fresh({"normalize": True}, env.observation_space.shape[0], 3), 100, PhaseClock()
    )
    ppo.start(env.reset())
    ppo.collect()
    b = ppo.buf
    with torch.no_grad():
        values, logp, _ = model.policy.evaluate_actions(b.obs.reshape(12, -1), b.actions.reshape(12, -1))
    np.testing.assert_allclose(b.logp.reshape(12).numpy(), logp.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(b.values.reshape(12).numpy(), values.flatten().numpy(), rtol=1e-6, atol=1e-6)
    # the update's written-out form, on other actions, gradients included
    actions = torch.randn(12, 2, generator=torch.Generator().manual_seed(0))
    v1, l1, e1 = model.policy.evaluate_actions(b.obs.reshape(12, -1), actions)
    v2, l2, e2 = ppo.evaluate(b.obs.reshape(12, -1), actions)
    for x, y in ((v1.flatten(), v2), (l1, l2), (e1, e2)):
        torch.testing.assert_close(x, y, rtol=1e-5, atol=1e-5)
    g1 = torch.autograd.grad(l1.sum() + e1.sum(), model.policy.log_std)[0]
    g2 = torch.autograd.grad(l2.sum() + e2.sum(), model.policy.log_std)[0]
    torch.testing.assert_close(g1, g2, rtol=1e-5, atol=1e-5)
    env.close()


def test_stagger_spreads_the_envs_along_the_episode():
    n = 4
    env = DecisionEnv(HEART, n, ActionMode("residual", 10, "smc", 0.2), {}, seed=0)
    obs = env.stagger(env.reset())
    length = env.decisions_per_episode
    assert length == env.venv.episode_steps // 10
    expected = (np.arange(n) * length // n) * 10 * env.venv.dt  # s: k_i decisions of 10 control periods
    np.testing.assert_allclose(env.venv._buffers.k * env.venv.dt, expected, atol=1e-12)
    assert obs.shape == (n, env.observation_space.shape[0])
    env.close()


# -- a run ------------------------------------------------------------------------------------------------------
def test_a_lean_run_writes_the_run_folder_of_vcnc_train(lean_run):
    for folder in ("best", "final"):
        for name in ("model.zip", "vecnormalize.npz", "config.yml"):
            assert (lean_run / folder / name).is_file()
    assert model_timesteps(lean_run / "final" / "model.zip") == 3 * ROLLOUT
    config = yaml.safe_load((lean_run / "config.yml").read_text())
    assert config["trainer"] == "lean" and config["n_envs"] == N_ENVS
    summary = json.loads((lean_run / "summary.json").read_text())
    s = summary["sessions"][-1]
    assert s["status"] == "finished" and s["trainer"] == "lean" and s["end_timesteps"] == 3 * ROLLOUT
    assert set(s["time_shares"]) == {"env", "forward", "update", "other"}
    assert sum(s["time_shares"].values()) == pytest.approx(1.0, abs=1e-3)
    rows = (lean_run / "evaluations.csv").read_text().splitlines()
    assert [int(r.split(",")[0]) for r in rows[1:]] == [3 * ROLLOUT]  # --eval-freq 0: at the end only
    assert sorted(p.name for p in (lean_run / "checkpoints").glob("*.zip")) == [
        f"rl_model_{k * ROLLOUT}_steps.zip" for k in (1, 2, 3)
    ]
    monitor = list((lean_run / "monitor").glob("*.monitor.csv"))
    assert len(monitor) == N_ENVS


def test_the_agent_loads_as_data_and_runs_in_vcnc_bench(lean_run, tmp_path):
    env = gym.make(HEART)
    policy = load_agent(lean_run / "best", env)  # no unpickling: vcnc_agents.model_file.load_ppo
    assert policy.action_mode == ActionMode("residual", 10, "smc", 0.2)
    out = tmp_path / "bench.json"
    spec = f"ppo:{lean_run / 'best'}"
    assert bench.main(["--env", HEART, "--policy", spec, "--no-progress", "--json", str(out)]) == 0
    record = json.loads(out.read_text())["records"][0]
    best = yaml.safe_load((lean_run / "best" / "config.yml").read_text())["agent"]["evaluation"]
    assert record["diverged"] is False and math.isfinite(record["max_contour_error_um"])
    assert record["max_contour_error_um"] == pytest.approx(best["max_um"], rel=1e-9)


@pytest.mark.slow  # a training run and a bench run (tests/test_observation.py checks the picking in make test)
def test_an_agent_trained_without_the_preview_runs_on_the_full_observation(small_entry, tmp_path):
    """The ablation's agent (issue 33): trained with ``preview_steps: []`` and one contour-preview point, it loads
    on the id's own env, sees its own entries of the full observation, and scores there what its run's evaluation
    on its own env scored."""
    entry = yaml.safe_load(small_entry.read_text())[HEART]
    entry["env_kwargs"] = {**(entry.get("env_kwargs") or {}), "preview_steps": [], "contour_ahead": [0.5]}
    config = tmp_path / "no_preview.yml"
    config.write_text(yaml.safe_dump({HEART: entry}, sort_keys=False))
    run_dir = tmp_path / "run"
    assert (
        train_main(
            [
                "--env",
                HEART,
                "--trainer",
                "lean",
                "--config",
                str(config),
                "--timesteps",
                str(ROLLOUT),
                "--eval-freq",
                "0",
                "--output",
                str(run_dir),
                "--no-progress",
            ]
        )
        == 0
    )
    recorded = yaml.safe_load((run_dir / "best" / "config.yml").read_text())
    assert recorded["env"]["signature"]["preview_steps"] == []
    assert recorded["env"]["signature"]["contour_ahead"] == [0.5]
    env = gym.make(HEART)
    policy = load_agent(run_dir / "best", env)
    lay = env.unwrapped.layout
    start = lay.offset("contour_preview")
    assert policy.pick.tolist() == (
        list(range(lay.offset("preview")))
        + [start + 2, start + 3]
        + [lay.offset("contour_curvature") + 1, lay.offset("previous_action"), lay.offset("previous_action") + 1]
    )
    out = tmp_path / "bench.json"
    assert bench.main(["--env", HEART, "--policy", f"ppo:{run_dir / 'best'}", "--no-progress", "--json", str(out)]) == 0
    record = json.loads(out.read_text())["records"][0]
    assert record["max_contour_error_um"] == pytest.approx(recorded["agent"]["evaluation"]["max_um"], rel=1e-9)


def test_a_lean_run_resumes_from_its_last_checkpoint(lean_run, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(lean_run, run)
    assert train_main(["--resume", str(run), "--timesteps", str(4 * ROLLOUT), "--no-progress"]) == 0
    assert model_timesteps(run / "final" / "model.zip") == 4 * ROLLOUT
    sessions = json.loads((run / "summary.json").read_text())["sessions"]
    assert [s["trainer"] for s in sessions] == ["lean", "lean"]
    assert sessions[-1]["start_timesteps"] == 3 * ROLLOUT


def test_the_lean_entries_are_valid_hyperparameters():
    from vcnc_agents.config import DEFAULT_CONFIG, ppo_arguments

    lean = DEFAULT_CONFIG.with_name("ppo_lean.yml")
    for env_id in ("VCNC-Heart-v1", "VCNC-HeartLookahead-v1"):
        h = load_hyperparameters(env_id, lean)
        _, kwargs = ppo_arguments(h)
        assert (kwargs["n_steps"] * h["n_envs"]) % kwargs["batch_size"] == 0  # whole minibatches per rollout


# -- resumes keep the SB3 trainer's promises -------------------------------------------------------------------
#: A 5 mm line at 100 mm/s, 50 control periods per decision: 36-decision episodes, so a rollout of 32 decisions
#: of 2 envs ends episodes in every session.
_SHORT = """\
VCNC-GCode-v1:
  n_envs: 2
  n_timesteps: 128
  policy: MlpPolicy
  normalize: "{'norm_obs': True, 'norm_reward': True}"
  env_kwargs:
    program: "G01 X5 F6000\\n"
    action_repeat: 50
  n_steps: 32
  batch_size: 64
  n_epochs: 1
  policy_kwargs: "dict(log_std_init=-1.0, net_arch=dict(pi=[16], vf=[16]))"
"""
SHORT_ROLLOUT = 64


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """A lean run of 2 rollouts on a short program: checkpoints and evaluations at 64 and 128 steps."""
    folder = tmp_path_factory.mktemp("lean_short")
    config = folder / "short.yml"
    config.write_text(_SHORT)
    run_dir = folder / "run"
    assert (
        train_main(
            [
                "--env",
                "VCNC-GCode-v1",
                "--trainer",
                "lean",
                "--config",
                str(config),
                "--eval-freq",
                str(SHORT_ROLLOUT),
                "--checkpoint-freq",
                str(SHORT_ROLLOUT),
                "--output",
                str(run_dir),
                "--no-progress",
            ]
        )
        == 0
    )
    return run_dir


def _monitor_steps(run_dir) -> dict:
    import csv

    out = {}
    for p in sorted((run_dir / "monitor").glob("*.monitor.csv")):
        lines = p.read_text().splitlines()
        out[p.name] = [int(r["steps"]) for r in csv.DictReader(lines[1:])]
    return out


def _eval_steps(run_dir) -> list:
    import csv

    return [int(r["steps"]) for r in csv.DictReader((run_dir / "evaluations.csv").open())]


@pytest.mark.slow  # a ~20 s run shared by the four (the G-code env's compile)
def test_a_resumed_lean_run_appends_monitor_rows_and_keeps_the_old_ones(short_run, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(short_run, run)
    before = _monitor_steps(run)
    assert all(before.values())  # episodes ended in the first session
    assert train_main(["--resume", str(run), "--timesteps", str(4 * SHORT_ROLLOUT), "--no-progress"]) == 0
    after = _monitor_steps(run)
    for name, steps in after.items():
        assert steps[: len(before[name])] == before[name]  # kept as they were
        new = steps[len(before[name]) :]
        assert new and all(s > 2 * SHORT_ROLLOUT for s in new)  # the resumed session's episodes, logged
        assert len(set(steps)) == len(steps) and steps == sorted(steps)  # none duplicated


@pytest.mark.slow  # a ~20 s run shared by the four (the G-code env's compile)
def test_a_lean_evaluation_cut_short_by_a_kill_is_made_up_on_resume(short_run, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(short_run, run)
    assert _eval_steps(run) == [SHORT_ROLLOUT, 2 * SHORT_ROLLOUT]
    lines = (run / "evaluations.csv").read_text().splitlines()
    (run / "evaluations.csv").write_text("\n".join(lines[:-1]) + "\n")  # killed while evaluating at 128
    assert train_main(["--resume", str(run), "--timesteps", str(3 * SHORT_ROLLOUT), "--no-progress"]) == 0
    assert _eval_steps(run) == [SHORT_ROLLOUT, 2 * SHORT_ROLLOUT, 3 * SHORT_ROLLOUT]  # the grid kept


@pytest.mark.slow  # a ~20 s run shared by the four (the G-code env's compile)
def test_a_lean_diverged_evaluation_is_written_as_inf(short_run, tmp_path, monkeypatch):
    import shutil
    from types import SimpleNamespace

    import vcnc_gym.evaluation

    run = tmp_path / "run"
    shutil.copytree(short_run, run)
    diverged = SimpleNamespace(
        diverged=True, completed=False, max_contour_error_um=0.0, mean_contour_error_um=0.0, rms_contour_error_um=0.0
    )
    monkeypatch.setattr(vcnc_gym.evaluation, "run_episode", lambda *a, **k: diverged)
    assert train_main(["--resume", str(run), "--timesteps", str(3 * SHORT_ROLLOUT), "--no-progress"]) == 0
    import csv

    last = list(csv.DictReader((run / "evaluations.csv").open()))[-1]
    assert int(last["steps"]) == 3 * SHORT_ROLLOUT
    assert [float(last[k]) for k in ("max_um", "mean_um", "rms_um", "score_um")] == [math.inf] * 4


@pytest.mark.slow  # a ~20 s run shared by the four (the G-code env's compile)
def test_a_lean_resume_renames_a_checkpoint_with_a_poisoned_policy_file(short_run, tmp_path):
    import io
    import shutil
    import zipfile

    run = tmp_path / "run"
    shutil.copytree(short_run, run)
    newest = run / "checkpoints" / f"rl_model_{2 * SHORT_ROLLOUT}_steps.zip"
    with zipfile.ZipFile(newest) as z:
        members = {n: z.read(n) for n in z.namelist()}
    buffer = io.BytesIO()
    torch.save({"x": _Pickled()}, buffer)  # a pickled object: torch's weights-only reader refuses it
    members["policy.pth"] = buffer.getvalue()
    with zipfile.ZipFile(newest, "w") as z:
        for n, b in members.items():
            z.writestr(n, b)
    assert train_main(["--resume", str(run), "--timesteps", str(3 * SHORT_ROLLOUT), "--no-progress"]) == 0
    assert (run / "checkpoints" / f"rl_model_{2 * SHORT_ROLLOUT}_steps.zip.damaged").exists()
    assert _eval_steps(run) == [SHORT_ROLLOUT, 2 * SHORT_ROLLOUT, 3 * SHORT_ROLLOUT]  # 128 trained again


class _Pickled:
    """An object torch.save can only pickle."""


@pytest.mark.parametrize("env_id", ["VCNC-OmegaOverride-v1", "VCNC-RandomContour-v1"])
def test_an_id_without_a_native_vector_env_steps_as_its_wrapped_envs(env_id):
    """The lean trainer's envs for an id without a native vector env are N Gymnasium envs, each wrapped by the
    action mode: a decision of the batch is, to the bit, a step of each env made and wrapped on its own (the SB3
    trainer's DummyVecEnv path), with the same seeds and actions; an ended env is reset at once."""
    from vcnc_agents.config import action_mode_of

    entry = load_hyperparameters(
        env_id, "agents/hyperparams/override.yml" if "Override" in env_id else "agents/hyperparams/generalists.yml"
    )
    mode, kwargs = action_mode_of(entry), dict(entry.get("env_kwargs") or {})
    batch = DecisionEnv(env_id, 2, mode, kwargs, seed=7)
    own = []
    for i in range(2):
        env = mode.wrap(
            gym.make(env_id, **{**kwargs, "action_repeat": 1 if mode.mode == "residual" else mode.action_repeat})
        )
        own.append((env, env.reset(seed=7 + i)[0]))
    obs = batch.stagger(batch.reset())
    np.testing.assert_array_equal(obs, np.stack([o for _, o in own]))
    rng = np.random.default_rng(1)
    for _ in range(30):
        a = rng.uniform(-1.5, 1.5, (2,) + batch.action_space.shape).astype(np.float32)  # beyond the bounds too
        obs, rewards, te, tr, _ = batch.step(a)
        for i, (env, _) in enumerate(own):
            o, r, t1, t2, _ = env.step(a[i])
            assert np.float32(r) == rewards[i] and (t1, t2) == (te[i], tr[i])
            if not (t1 or t2):
                np.testing.assert_array_equal(obs[i], o)
    batch.close()


def _lean_envs(mode):
    return DecisionEnv("VCNC-HeartShop-v1", 2, mode, {"randomize": True}, seed=3)


def _sb3_envs(mode):
    from vcnc_agents.vec_env import VcncVecEnv

    return VcncVecEnv("VCNC-HeartShop-v1", 2, mode, {"randomize": True}, seed=3)


@pytest.mark.parametrize("make_envs", [_lean_envs, _sb3_envs], ids=["lean", "sb3-vecenv"])
def test_a_residual_over_a_per_machine_commissioning_is_commissioned_for_each_plant_drawn(make_envs):
    """``ff-pid@machine`` identifies the machine it runs on.  On plants drawn at every reset the trainers' native
    envs (the lean trainer's, and SB3's ``VecEnv`` of them, where a recurrent policy trains) commission, before
    the next decision, the plants the reset envs drew, and only those: after the first reset every env's record is
    the one ``commission`` gives for its plant (run here on that plant alone); after one env's reset its record is
    new, the others' are the same objects, and the kernel steps the law built from them."""
    from vcnc_baselines.commissioning.record import commission

    mode = ActionMode("residual", action_repeat=5, baseline="ff-pid@machine", correction=0.3)
    batch = make_envs(mode)
    batch.reset()
    batch.step(np.zeros((2, 2), dtype=np.float32))
    u, base = batch.venv, batch.baseline
    params = np.array(u.parameters)
    for i in range(2):
        assert not np.array_equal(params[i], u.nominal_parameters)  # a plant of the box, not the nominal one
        own = commission(u.task, "machine", params[i : i + 1])[0]
        np.testing.assert_array_equal(base.records[i].gains()["kp"], own.gains()["kp"])
    kept = base.records[1]
    u.reset(options={"reset_mask": np.array([True, False])})
    batch._start[0] = True
    batch.step(np.zeros((2, 2), dtype=np.float32))
    assert not np.array_equal(u.parameters[0], params[0]) and base.records[1] is kept
    own = commission(u.task, "machine", np.array(u.parameters)[:1])[0]
    np.testing.assert_array_equal(base.records[0].gains()["kp"], own.gains()["kp"])
    np.testing.assert_array_equal(batch.controller.kp, base.gains.kp)
    batch.close()


def test_the_lean_trainer_is_the_default_and_trains_the_feed_override(tmp_path):
    """No --trainer: the lean one, on an id without a native vector env too; its agent loads in the bench."""
    entry = load_hyperparameters("VCNC-OmegaOverride-v1", "agents/hyperparams/override.yml")
    entry.update(n_envs=2, n_steps=16, batch_size=32, n_epochs=1)
    config = tmp_path / "override.yml"
    config.write_text(yaml.safe_dump({"VCNC-OmegaOverride-v1": entry}, sort_keys=False))
    run = tmp_path / "run"
    assert (
        train_main(
            [
                "--env",
                "VCNC-OmegaOverride-v1",
                "--config",
                str(config),
                "--timesteps",
                "32",
                "--eval-freq",
                "0",
                "--output",
                str(run),
                "--no-progress",
            ]
        )
        == 0
    )
    assert yaml.safe_load((run / "final" / "config.yml").read_text())["trainer"] == "lean"


def test_the_default_trainer_is_sb3_where_the_run_needs_it(small_entry, tmp_path):
    entry = yaml.safe_load(small_entry.read_text())[HEART]
    entry["use_sde"] = True
    config = tmp_path / "sde.yml"
    config.write_text(yaml.safe_dump({HEART: entry}, sort_keys=False))
    with pytest.raises(SystemExit) as exc:
        train_main(
            [
                "--env",
                HEART,
                "--config",
                str(config),
                "--trainer",
                "lean",
                "--output",
                str(tmp_path / "r"),
                "--no-progress",
            ]
        )
    assert exc.value.code == 2
    from vcnc_agents.lean_ppo import check_trainer

    with pytest.warns(UserWarning, match="SB3's PPO: use_sde"):
        assert check_trainer(None, HEART, needs_sb3="use_sde (...)") == "sb3"
    assert check_trainer(None, HEART) == "lean" and check_trainer(None, HEART, "sb3") == "sb3"
    # a resumed run goes on with its own trainer: SB3's records none
    assert check_trainer(None, HEART, None, resumed=True) == "sb3"
    assert check_trainer(None, HEART, "lean", resumed=True) == "lean"
    with pytest.raises(ValueError, match="goes on with it"):
        check_trainer("lean", HEART, None, resumed=True)


@pytest.mark.slow  # the short run's fixture
def test_a_read_only_run_folder_is_refused_on_resume_before_anything_is_written(
    short_run, tmp_path, monkeypatch, capsys
):
    import os
    import shutil

    run = tmp_path / "run"
    shutil.copytree(short_run, run)
    before = {p: p.stat().st_mtime_ns for p in run.rglob("*")}
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(run) else real_access(p, mode))
    with pytest.raises(SystemExit) as exc:  # root writes anywhere: the permission as os.access reports it
        train_main(["--resume", str(run), "--timesteps", str(3 * SHORT_ROLLOUT), "--no-progress"])
    assert exc.value.code == 2
    assert f"{run} is not writable" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in run.rglob("*")} == before


@pytest.mark.slow  # a run of its own
@pytest.mark.parametrize("trainer", ["lean", "sb3"])
def test_a_full_disk_ends_the_run_with_one_line_naming_the_file(trainer, tmp_path, monkeypatch, capsys):
    import errno

    import vcnc_agents.callbacks
    import vcnc_agents.lean_ppo
    import vcnc_agents.run_folder

    config = tmp_path / "short.yml"
    config.write_text(_SHORT)
    original, calls = vcnc_agents.run_folder.save_model, []

    def full(model, path):
        calls.append(path)
        if len(calls) >= 2:  # the first checkpoint is written, the second finds the disk full
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return original(model, path)

    for module in (vcnc_agents.run_folder, vcnc_agents.lean_ppo, vcnc_agents.callbacks):
        monkeypatch.setattr(module, "save_model", full)
    run = tmp_path / "run"
    code = train_main(
        [
            "--env",
            "VCNC-GCode-v1",
            "--trainer",
            trainer,
            "--config",
            str(config),
            "--output",
            str(run),
            "--checkpoint-freq",
            str(SHORT_ROLLOUT),
            "--eval-freq",
            "0",
            "--no-progress",
            "--no-tensorboard",
        ]
    )
    err = capsys.readouterr().err
    assert code == 1
    assert "Traceback" not in err
    line = [x for x in err.splitlines() if "training failed" in x]
    assert len(line) == 1 and "No space left on device" in line[0] and "rl_model_128_steps.zip" in line[0]
    assert f"vcnc-train --resume {run}" in line[0]


# -- a warm start (vcnc_agents.warm_start) ----------------------------------------------------------------------
def _weights(folder):
    policy = load_agent(folder, gym.make(HEART))
    return {k: v.clone() for k, v in policy.model.policy.state_dict().items()}


def test_a_warm_start_begins_from_the_agent_s_weights_and_normalisation(lean_run, small_entry, tmp_path):
    """With a learning rate of 1e-30 a warm-started run's final agent has its source's weights (to 1e-25), and its
    normalisation starts from the source's counts (a fresh run's differ); it counts its own steps from 0 and
    records where it started."""
    from vcnc_agents.normalization import NormalizationStats

    entry = yaml.safe_load(small_entry.read_text())[HEART]
    entry["learning_rate"] = 1e-30  # > 0, as the entry's check asks; a step of Adam moves a weight by ~1e-30
    config = tmp_path / "frozen.yml"
    config.write_text(yaml.safe_dump({HEART: entry}, sort_keys=False))
    source, run = lean_run / "final", tmp_path / "warm"
    assert (
        train_main(
            [
                "--env",
                HEART,
                "--config",
                str(config),
                "--timesteps",
                str(ROLLOUT),
                "--eval-freq",
                "0",
                "--seed",
                "5",
                "--init-from",
                str(source),
                "--output",
                str(run),
                "--no-progress",
            ]
        )
        == 0
    )
    theirs, ours = _weights(source), _weights(run / "final")
    assert theirs.keys() == ours.keys() and all(
        torch.allclose(theirs[k], ours[k], rtol=0.0, atol=1e-25) for k in theirs
    )
    assert model_timesteps(run / "final" / "model.zip") == ROLLOUT
    assert yaml.safe_load((run / "config.yml").read_text())["init_from"] == str(source)
    before = NormalizationStats.load(source / "vecnormalize.npz")
    after = NormalizationStats.load(run / "final" / "vecnormalize.npz")
    # the running mean's count goes on from the source's: then this run's first observations and its one rollout
    assert after.obs_count == pytest.approx(before.obs_count + N_ENVS + ROLLOUT)


@pytest.mark.parametrize(
    "change, named",
    [
        (["--correction", "0.3"], "correction: the agent's 0.2, the run's 0.3"),
        (["--n-envs", "8"], None),  # the batch may differ: n_envs is the run's
    ],
)
def test_init_from_refuses_an_agent_that_does_not_fit_before_writing(
    lean_run, small_entry, tmp_path, capsys, change, named
):
    run = tmp_path / "warm"
    argv = [
        "--env",
        HEART,
        "--config",
        str(small_entry),
        "--timesteps",
        str(ROLLOUT),
        "--eval-freq",
        "0",
        "--init-from",
        str(lean_run / "final"),
        "--output",
        str(run),
        "--no-progress",
        *change,
    ]
    if named is None:
        assert train_main(argv) == 0
        return
    with pytest.raises(SystemExit) as exc:
        train_main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "init_from" in err and named in err and not run.exists()


def test_a_grown_memory_starts_from_the_agent_s_actions_and_values(lean_run, small_entry, tmp_path):
    """grow_agent (a memory of 2 decisions added to an agent without one): on any observation and any remembered
    past, the grown agent's deterministic action and value are the source's on the observation alone, computed by
    the source's own network; the new inputs are normalised as the present fields they remember; a run with
    --history 2 starts from it."""
    from vcnc_gym.envs.history import agent_space, history_columns

    from vcnc_agents.config import ppo_arguments
    from vcnc_agents.model_file import load_ppo
    from vcnc_agents.normalization import NormalizationStats
    from vcnc_agents.warm_start import grow_agent

    env = gym.make(HEART)
    layout, space = env.unwrapped.layout, env.observation_space
    files = lean_run / "final"
    kwargs = ppo_arguments(yaml.safe_load(small_entry.read_text())[HEART])[1]  # the run's network
    source = load_ppo(files / "model.zip", observation_space=space, action_space=env.action_space, ppo_kwargs=kwargs)
    grown = load_ppo(files / "model.zip", observation_space=space, action_space=env.action_space, ppo_kwargs=kwargs)
    stats = NormalizationStats.load(files / "vecnormalize.npz")
    big = agent_space(space, 2, layout)
    grown, grown_stats = grow_agent(grown, stats, layout, 0, 2, big)
    columns = history_columns(layout)
    n = space.shape[0]
    assert big.shape[0] == n + 2 * columns.size and grown.observation_space.shape == big.shape
    assert np.array_equal(grown_stats.obs_mean[:n], stats.obs_mean)
    assert np.array_equal(grown_stats.obs_mean[n + columns.size :], stats.obs_mean[columns])
    assert np.array_equal(grown_stats.obs_var[n : n + columns.size], stats.obs_var[columns])
    rng = np.random.default_rng(0)
    x = rng.normal(size=(16, big.shape[0])).astype(np.float32)  # normalised observations and pasts
    with torch.no_grad():
        a_source = source.policy.predict(x[:, :n], deterministic=True)[0]
        a_grown = grown.policy.predict(x, deterministic=True)[0]
        v_source = source.policy.predict_values(torch.as_tensor(x[:, :n]))
        v_grown = grown.policy.predict_values(torch.as_tensor(x))
    assert np.array_equal(a_source, a_grown) and torch.equal(v_source, v_grown)
    with pytest.raises(ValueError, match="the run's observation has"):  # 2 decisions more, the space of 3 more
        grow_agent(grown, grown_stats, layout, 2, 4, agent_space(space, 5, layout))
    run = tmp_path / "warm"
    assert (
        train_main(
            [
                "--env",
                HEART,
                "--config",
                str(small_entry),
                "--timesteps",
                str(ROLLOUT),
                "--eval-freq",
                "0",
                "--history",
                "2",
                "--init-from",
                str(files),
                "--output",
                str(run),
                "--no-progress",
            ]
        )
        == 0
    )
    assert load_agent(run / "final", env).model.observation_space.shape == big.shape


def test_init_from_refuses_a_memory_that_would_shrink(lean_run, small_entry, tmp_path, capsys):
    """An agent that remembers 4 decisions (its config.yml says so) cannot start a run that remembers 2."""
    import shutil

    agent = tmp_path / "agent"
    shutil.copytree(lean_run / "final", agent)
    config = yaml.safe_load((agent / "config.yml").read_text())
    config["action_mode"]["history"] = 4
    (agent / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
    with pytest.raises(SystemExit) as exc:
        train_main(
            [
                "--env",
                HEART,
                "--config",
                str(small_entry),
                "--history",
                "2",
                "--init-from",
                str(agent),
                "--output",
                str(tmp_path / "warm"),
                "--no-progress",
            ]
        )
    assert exc.value.code == 2 and "remembers 4 decisions, the run 2" in capsys.readouterr().err
    assert not (tmp_path / "warm").exists()


@pytest.mark.parametrize("theirs, named", [("ff-pid@machine", None), ("zpetc", "baseline: the agent's 'zpetc'")])
def test_init_from_takes_the_same_law_commissioned_another_way(lean_run, small_entry, tmp_path, capsys, theirs, named):
    """An agent over a baseline commissioned per machine starts a run over the same law on the nominal record (and
    the other way: ``ff-pid-online`` to ``ff-pid-online@machine``); over another law it is refused by name."""
    import shutil

    agent = tmp_path / "agent"
    shutil.copytree(lean_run / "final", agent)
    config = yaml.safe_load((agent / "config.yml").read_text())
    config["action_mode"]["baseline"] = theirs
    (agent / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
    entry = yaml.safe_load(small_entry.read_text())[HEART]
    (wrapper,) = entry["env_wrapper"]
    wrapper["vcnc_agents.action_modes.ResidualAction"]["baseline"] = "ff-pid"
    run_config = tmp_path / "ff-pid.yml"
    run_config.write_text(yaml.safe_dump({HEART: entry}, sort_keys=False))
    argv = [
        "--env",
        HEART,
        "--config",
        str(run_config),
        "--timesteps",
        str(ROLLOUT),
        "--eval-freq",
        "0",
        "--init-from",
        str(agent),
        "--output",
        str(tmp_path / "warm"),
        "--no-progress",
    ]
    if named is None:
        assert train_main(argv) == 0
        return
    with pytest.raises(SystemExit) as exc:
        train_main(argv)
    assert exc.value.code == 2 and named in capsys.readouterr().err and not (tmp_path / "warm").exists()


def test_init_from_names_what_is_missing_or_different(lean_run, small_entry, tmp_path, capsys):
    from vcnc_agents.warm_start import init_agent_path

    assert init_agent_path("runs/x/seed{seed}/final", 7) == __import__("pathlib").Path("runs/x/seed7/final")
    entry = yaml.safe_load(small_entry.read_text())[HEART]
    entry["n_epochs"] = 3
    config = tmp_path / "epochs.yml"
    config.write_text(yaml.safe_dump({HEART: entry}, sort_keys=False))
    cases = [
        (["--config", str(config), "--init-from", str(lean_run / "final")], "n_epochs: the agent's 2, the run's 3"),
        (["--config", str(small_entry), "--init-from", str(tmp_path / "nowhere")], "nowhere"),
        (["--config", str(small_entry), "--init-from", str(lean_run / "final"), "--trainer", "sb3"], "lean trainer"),
    ]
    for extra, named in cases:
        with pytest.raises(SystemExit) as exc:
            train_main(["--env", HEART, "--output", str(tmp_path / "warm"), "--no-progress", *extra])
        assert exc.value.code == 2 and named in capsys.readouterr().err
    assert not (tmp_path / "warm").exists()
