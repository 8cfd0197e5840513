"""``vcnc-bench --policy zoo:FOLDER`` (vcnc_bench/kinds/zoo.py): an agent trained by RL Baselines3 Zoo, read from the
folder rl_zoo3 writes.

The fast tests write a run folder with rl_zoo3's own save code (``ExperimentManager.save_trained_model`` and
``_save_config``) around an untrained PPO and compare the kind's actions with SB3's own loading of the same files
(``VecNormalize.load``, ``PPO.load``); the slow one trains with ``python -m rl_zoo3.train`` for 2 048 steps and runs
the result through ``vcnc-bench``.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("rl_zoo3")
pytest.importorskip("stable_baselines3")

import vcnc_gym  # noqa: E402,F401
from vcnc_bench.kinds import zoo  # noqa: E402
from vcnc_bench.policies import resolve_policy  # noqa: E402

ENV = "VCNC-Circle-v2"
POLICY_KWARGS = "dict(net_arch=[16, 16], activation_fn=nn.ReLU)"


@pytest.fixture(autouse=True)
def _one_torch_thread():
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # two shared cores: torch's second thread waits for the other processes
    yield
    torch.set_num_threads(threads)


def _write_run(log_folder: Path, hyperparams: dict | None = None, env_kwargs=None) -> Path:
    """A run folder as ``rl_zoo3.train --algo ppo --env VCNC-Circle-v2 -f LOG_FOLDER`` writes it, by rl_zoo3's own
    save code, around an untrained PPO whose VecNormalize saw a few steps."""
    import torch.nn as nn
    from rl_zoo3.exp_manager import ExperimentManager
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    venv = VecNormalize(make_vec_env(ENV, n_envs=1, seed=0, env_kwargs=env_kwargs))
    venv.reset()
    for _ in range(20):
        venv.step(np.full((1, 2), 0.3, dtype=np.float32))
    model = PPO("MlpPolicy", venv, seed=0, policy_kwargs={"net_arch": [16, 16], "activation_fn": nn.ReLU})
    save_path = log_folder / "ppo" / f"{ENV}_1"
    manager = SimpleNamespace(
        save_path=str(save_path),
        params_path=str(save_path / ENV),
        env_name=ENV,
        normalize=True,
        save_replay_buffer=False,
        args=SimpleNamespace(algo="ppo", env=ENV, env_kwargs=env_kwargs, seed=0, n_timesteps=0),
    )
    os.makedirs(manager.params_path)
    hp = {"n_envs": 1, "normalize": True, "policy": "MlpPolicy", "policy_kwargs": POLICY_KWARGS}
    ExperimentManager._save_config(manager, dict(hp, **(hyperparams or {})))
    ExperimentManager.save_trained_model(manager, model)
    return save_path


def _sb3_actions(run: Path, observations: np.ndarray) -> np.ndarray:
    """The actions SB3's own loading of the run gives (as rl_zoo3's enjoy: the statistics frozen)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    stats = VecNormalize.load(str(run / ENV / "vecnormalize.pkl"), DummyVecEnv([lambda: gym.make(ENV)]))
    stats.training = False
    model = PPO.load(run / f"{ENV}.zip", device="cpu")
    return model.predict(stats.normalize_obs(observations), deterministic=True)[0]


def test_the_folder_rl_zoo3_writes_runs_as_a_policy(tmp_path):
    run = _write_run(tmp_path / "logs")
    assert {p.name for p in (run / ENV).iterdir()} >= {"vecnormalize.pkl", "config.yml", "args.yml"}
    env = gym.make(ENV)
    obs = np.stack([env.reset(seed=s)[0] for s in range(3)] + [env.observation_space.sample() for _ in range(3)])
    expected = _sb3_actions(run, obs)
    for spec in (f"zoo:{run}", f"zoo:{run}/{ENV}.zip", f"zoo:{tmp_path / 'logs'}", f"zoo:{tmp_path / 'logs' / 'ppo'}"):
        agent = resolve_policy(spec, env)
        np.testing.assert_array_equal(agent.predict(obs, deterministic=True)[0], expected)
        np.testing.assert_allclose(agent.predict(obs[0], deterministic=True)[0], expected[0], rtol=1e-5, atol=1e-6)
    from vcnc_gym.evaluation import run_episode

    result = run_episode(agent, env)
    assert result.episode_steps > 0 and np.isfinite(result.max_contour_error_um)


def test_an_agent_runs_only_on_the_env_it_trained_on(tmp_path):
    run = _write_run(tmp_path / "logs", env_kwargs={"randomize": True})
    with pytest.raises(ValueError, match="--env VCNC-Circle-v2"):
        resolve_policy(f"zoo:{run}", gym.make("VCNC-CircleShop-v2"))
    with pytest.raises(ValueError, match="randomize"):
        resolve_policy(f"zoo:{run}", gym.make(ENV))
    assert resolve_policy(f"zoo:{run}", gym.make(ENV, randomize=True)) is not None
    wrapped = _write_run(
        tmp_path / "wrapped", hyperparams={"env_wrapper": "sb3_contrib.common.wrappers.TimeFeatureWrapper"}
    )
    with pytest.raises(ValueError, match="env_wrapper"):
        resolve_policy(f"zoo:{wrapped}", gym.make(ENV))
    with pytest.raises(ValueError, match="no run of VCNC-Heart-v2"):
        resolve_policy(f"zoo:{tmp_path / 'logs'}", gym.make("VCNC-Heart-v2"))
    with pytest.raises(FileNotFoundError):
        resolve_policy(f"zoo:{tmp_path / 'nowhere'}", gym.make(ENV))


class _Payload:
    def __reduce__(self):
        return (os.system, ("echo pwned > pwned.txt",))


def test_loading_runs_no_code_from_the_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run = _write_run(tmp_path / "logs")
    stats = run / ENV / "vecnormalize.pkl"
    stats.write_bytes(pickle.dumps({"obs_rms": _Payload()}))
    with pytest.raises(ValueError, match="posix.system|os.system|nt.system"):
        resolve_policy(f"zoo:{run}", gym.make(ENV))
    assert not (tmp_path / "pwned.txt").exists()
    for text in ("__import__('os').system('x')", "dict(net_arch=open('x'))", "nn.Module"):
        with pytest.raises(ValueError, match="policy_kwargs"):
            zoo.policy_kwargs_of(text)
    import torch.nn as nn

    assert zoo.policy_kwargs_of("dict(log_std_init=-1.5, net_arch=dict(pi=[64, 64]), activation_fn=nn.Tanh)") == {
        "log_std_init": -1.5,
        "net_arch": {"pi": [64, 64]},
        "activation_fn": nn.Tanh,
    }
    with pytest.raises(ValueError, match="JSON"):
        zoo.policy_kwargs_of("dict(n_critics=2)", "sac", "MlpPolicy")


@pytest.mark.slow  # a real rl_zoo3 training run (2 048 steps) and a bench run: ~30 s on 2 loaded cores
def test_a_real_rl_zoo3_run_is_benchmarked(tmp_path):
    conf = tmp_path / "conf.yml"
    conf.write_text(
        f"{ENV}:\n  n_envs: 2\n  n_timesteps: 2048\n  policy: MlpPolicy\n  normalize: true\n  n_steps: 512\n"
    )
    command = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", ENV, "-n", "2048"]
    command += ["--gym-packages", "vcnc_gym", "--conf-file", str(conf), "-f", str(tmp_path / "logs"), "--seed", "0"]
    command += ["--num-threads", "1", "--eval-freq", "-1"]
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    run = tmp_path / "logs" / "ppo" / f"{ENV}_1"
    assert (run / f"{ENV}.zip").is_file() and (run / ENV / "vecnormalize.pkl").is_file()
    from vcnc_bench.cli import main

    out = tmp_path / "bench.json"
    assert main(["--env", ENV, "--policy", f"zoo:{tmp_path / 'logs'}", "--json", str(out), "--no-progress"]) == 0
    (record,) = json.loads(out.read_text())["records"]
    assert record["env"] == ENV and record["policy"] == f"zoo:{tmp_path / 'logs'}"
    env = gym.make(ENV)
    obs = np.stack([env.observation_space.sample() for _ in range(4)])
    agent = resolve_policy(f"zoo:{run}", env)
    np.testing.assert_array_equal(agent.predict(obs)[0], _sb3_actions(run, obs))
