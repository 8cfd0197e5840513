"""agents: loading untrusted agent files runs no code, agents check their env, vcnc-train never loses run data.

Issue 9, "Agent files run code when loaded" and "vcnc-train loses or corrupts
run data".  The payloads below would create a marker file if unpickled; each
test first shows that the plain unpickling path does run them (so the test
can fail), then that our loaders refuse or ignore them.

Training runs are tiny (VCNC-Omega-v1 in direct mode deciding every 40
control periods, 161 decisions an episode; n_steps 128 x 2 envs = 256 agent
steps per rollout, a 16-unit network) and shared through module fixtures.
An untrained direct agent does not move the table, so its evaluations
diverge (score inf); where best/ matters, finite scores are written into
evaluations.csv by hand.
"""

from __future__ import annotations

import base64
import contextlib
import csv
import io
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

import vcnc_agents
import vcnc_gym  # noqa: F401
from vcnc_agents import TRAINED, load_agent
from vcnc_agents.cli import main as train_main
from vcnc_agents.config import parse_policy_kwargs
from vcnc_agents.model_file import PPO_DATA_KEYS, read_model_data
from vcnc_agents.normalization import NormalizationStats
from vcnc_agents.training import RunWarning, latest_checkpoint, prepare_run, scan_checkpoints

OMEGA = "VCNC-Omega-v1"
HEART = "VCNC-Heart-v1"
SHIPPED = "VCNC-OmegaLookahead-v1"  # the shipped agent these tests open: a residual over ff-ccc
ROOT = Path(__file__).resolve().parents[1]
ROLLOUT = 256  # n_steps 128 x n_envs 2

TINY = """\
VCNC-Omega-v1:
  n_envs: 2
  n_timesteps: 1024
  policy: MlpPolicy
  normalize: "{'norm_obs': True, 'norm_reward': True}"
  env_kwargs:
    action_repeat: 40
  n_steps: 128
  batch_size: 128
  n_epochs: 1
  gamma: 0.99
  learning_rate: !!float 3e-4
  policy_kwargs: "dict(log_std_init=-1.0, net_arch=dict(pi=[16], vf=[16]))"
"""


#: Every test of this module runs torch on one thread (tests/conftest.py).
pytestmark = pytest.mark.usefixtures("one_torch_thread")


# -- payloads that run code when unpickled ------------------------------------------------------
class Payload:
    """Unpickling this object creates ``marker`` (stands for any code an attacker would run)."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


def payload_bytes(marker: Path) -> bytes:
    return pickle.dumps(Payload(marker))


def test_the_payload_runs_when_unpickled(tmp_path):
    """The control: plain unpickling of the payload runs it."""
    marker = tmp_path / "ran"
    pickle.loads(payload_bytes(marker))
    assert marker.exists()


@pytest.fixture
def omega_agent(tmp_path):
    """A copy of the shipped omega agent folder."""
    folder = tmp_path / "agent"
    shutil.copytree(TRAINED[SHIPPED], folder)
    return folder


# -- 1. safe loading ----------------------------------------------------------------------------
def test_a_crafted_normalisation_file_does_not_run(omega_agent, tmp_path):
    env = gym.make(SHIPPED)
    marker = tmp_path / "ran"
    # (a) an .npz whose obs_mean is an object array: np.savez pickles it
    good = dict(np.load(omega_agent / "vecnormalize.npz"))
    crafted = dict(good, obs_mean=np.array([Payload(marker)], dtype=object))
    np.savez(omega_agent / "vecnormalize.npz", **crafted)
    with pytest.raises(ValueError, match="vecnormalize.npz"):
        load_agent(omega_agent, env)
    assert not marker.exists()
    # (b) only a pickle, as older runs wrote it: refused, with the conversion command
    (omega_agent / "vecnormalize.npz").unlink()
    (omega_agent / "vecnormalize.pkl").write_bytes(payload_bytes(marker))
    with pytest.raises(ValueError, match="convert-trusted-pickle"):
        load_agent(omega_agent, env)
    assert not marker.exists()
    # (c) garbage and an empty file: a clear error
    (omega_agent / "vecnormalize.npz").write_bytes(b"\x00garbage" * 10)
    with pytest.raises(ValueError, match="not a data-only .npz"):
        load_agent(omega_agent, env)
    (omega_agent / "vecnormalize.npz").write_bytes(b"")
    with pytest.raises(ValueError, match="vecnormalize.npz"):
        load_agent(omega_agent, env)


def _rewrite_data(model_zip: Path, change) -> None:
    """Rewrite the ``data`` JSON of a model.zip through ``change(dict)``."""
    with zipfile.ZipFile(model_zip) as z:
        members = {n: z.read(n) for n in z.namelist()}
    data = json.loads(members["data"])
    change(data)
    members["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(model_zip, "w") as z:
        for n, b in members.items():
            z.writestr(n, b)


def _serialized(marker: Path) -> dict:
    return {":type:": "<class 'builtins.object'>", ":serialized:": base64.b64encode(payload_bytes(marker)).decode()}


def test_a_crafted_model_zip_does_not_run(omega_agent, tmp_path):
    from stable_baselines3 import PPO

    env = gym.make(SHIPPED)
    model_zip = omega_agent / "model.zip"
    # a payload in an entry SB3 unpickles (clip_range): SB3's own load runs it ...
    control = tmp_path / "control.zip"
    shutil.copyfile(model_zip, control)
    ran_in_sb3 = tmp_path / "ran_in_sb3"
    _rewrite_data(control, lambda d: d.update(clip_range=_serialized(ran_in_sb3)))
    with contextlib.suppress(Exception):
        PPO.load(control, device="cpu")
    assert ran_in_sb3.exists(), "SB3's PPO.load no longer unpickles clip_range: revisit agents/model_file.py"
    # ... ours replaces it and never unpickles it
    marker = tmp_path / "ran"
    _rewrite_data(model_zip, lambda d: d.update(clip_range=_serialized(marker)))
    policy = load_agent(omega_agent, env)
    assert not marker.exists()
    assert float(policy.model.clip_range(1.0)) == 0.2  # from the agent's config.yml
    # a pickled entry it cannot rebuild, and a key a PPO never saves: refused
    for change, message in [
        (lambda d: d.update(n_steps=_serialized(marker)), "cannot rebuild"),
        (lambda d: d.update(env=_serialized(marker)), "does not save"),
        (lambda d: d.update(env="os:system"), "does not save"),
    ]:
        shutil.copyfile(TRAINED[SHIPPED] / "model.zip", model_zip)
        _rewrite_data(model_zip, change)
        with pytest.raises(ValueError, match=message):
            load_agent(omega_agent, env)
        assert not marker.exists()
    # a tensor file holding a pickle payload: torch's weights-only reader refuses it
    shutil.copyfile(TRAINED[SHIPPED] / "model.zip", model_zip)
    with zipfile.ZipFile(model_zip) as z:
        members = {n: z.read(n) for n in z.namelist()}
    buffer = io.BytesIO()
    torch.save({"x": Payload(marker)}, buffer)
    members["policy.pth"] = buffer.getvalue()
    with zipfile.ZipFile(model_zip, "w") as z:
        for n, b in members.items():
            z.writestr(n, b)
    with pytest.raises(ValueError, match="policy"):
        load_agent(omega_agent, env)
    assert not marker.exists()
    # truncated: a clear error
    model_zip.write_bytes(model_zip.read_bytes()[:500])
    with pytest.raises(ValueError, match="model.zip"):
        load_agent(omega_agent, env)


def test_the_shipped_model_holds_only_known_entries():
    for folder in TRAINED.values():
        assert set(read_model_data(folder / "model.zip")) <= PPO_DATA_KEYS
        assert not (folder / "vecnormalize.pkl").exists()


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os').system('touch ran')",
        "dict(net_arch=[8], activation_fn=__import__('os').system)",
        "().__class__.__bases__[0].__subclasses__()",
        "(lambda: 0)()",
        "dict(**{'net_arch': [8]})",
        "dict(activation_fn=nn.Module)",  # a torch name, not an activation
        "dict(net_arch=[8], optimizer_class=th.load)",
        "dict(net_arc=[8])",  # misspelt key
        "[8, 8]",  # not a dict
        "dict(net_arch=",  # not an expression
    ],
)
def test_policy_kwargs_are_never_evaluated(text):
    with pytest.raises(ValueError, match="policy_kwargs"):
        parse_policy_kwargs(text)


def test_policy_kwargs_parse_the_zoo_literal_subset():
    assert parse_policy_kwargs(
        "dict(log_std_init=-1.5, ortho_init=False, net_arch=dict(pi=[64, 64], vf=[64]), "
        "activation_fn=nn.ReLU, optimizer_class=th.optim.AdamW, "
        "optimizer_kwargs={'eps': 1e-5})"
    ) == {
        "log_std_init": -1.5,
        "ortho_init": False,
        "net_arch": {"pi": [64, 64], "vf": [64]},
        "activation_fn": torch.nn.ReLU,
        "optimizer_class": torch.optim.AdamW,
        "optimizer_kwargs": {"eps": 1e-5},
    }
    assert parse_policy_kwargs({"net_arch": [8], "activation_fn": "nn.Tanh"}) == {
        "net_arch": [8],
        "activation_fn": torch.nn.Tanh,
    }
    with pytest.raises(ValueError, match="did you mean 'net_arch'"):
        parse_policy_kwargs("dict(net_arc=[8])")


# -- 2. an agent checks the env it is given -----------------------------------------------------------
def test_an_agent_refuses_another_env_configuration(omega_agent):
    with pytest.raises(ValueError, match=f"trained on {SHIPPED}, not {HEART}") as exc:
        load_agent(omega_agent, gym.make(HEART))
    assert "contour: trained on omega" in str(exc.value)
    slow = gym.make(SHIPPED, feedrate=50.0)
    with pytest.raises(ValueError, match=r"feedrate: trained on 100.0 mm/s, this env has 50.0 mm/s"):
        load_agent(omega_agent, slow)
    with pytest.warns(UserWarning, match="feedrate"):
        policy = load_agent(omega_agent, slow, allow_mismatch=True)
    assert isinstance(policy, vcnc_agents.AgentPolicy)
    # a normalisation file of another observation size: refused even with allow_mismatch
    stats = NormalizationStats.load(omega_agent / "vecnormalize.npz")
    NormalizationStats(**{**stats.__dict__, "obs_mean": stats.obs_mean[:-1], "obs_var": stats.obs_var[:-1]}).save(
        omega_agent / "vecnormalize.npz"
    )
    with pytest.raises(ValueError, match=f"normalises {stats.obs_mean.size - 1} observation entries"):
        load_agent(omega_agent, gym.make(SHIPPED), allow_mismatch=True)
    with pytest.raises(ValueError, match="empty"):
        load_agent("", gym.make(SHIPPED))


def test_normalisation_round_trip_equals_vecnormalize():
    """The .npz statistics normalise exactly as SB3's VecNormalize does with the same numbers."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    stats = NormalizationStats.load(TRAINED[SHIPPED] / "vecnormalize.npz")
    venv = stats.vecnormalize(DummyVecEnv([lambda: gym.make(SHIPPED)]), training=False)
    obs = (
        np.random.default_rng(0)
        .normal(stats.obs_mean, 3 * np.sqrt(stats.obs_var), (50, stats.obs_mean.size))
        .astype(np.float32)
    )
    np.testing.assert_array_equal(venv.normalize_obs(obs), stats.normalize_obs(obs))
    assert NormalizationStats.from_vecnormalize(venv).__dict__.keys() == stats.__dict__.keys()
    venv.close()


# -- 3. every option is checked before the run folder exists --------------------------------------------
def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _entry(**changes) -> str:
    entry = yaml.safe_load(TINY)[OMEGA]
    for k, v in changes.items():
        if v is None:
            entry.pop(k)
        else:
            entry[k] = v
    return yaml.safe_dump({OMEGA: entry})


#: (case, extra argv, YAML text or None for the tiny file, text the message must hold)
BAD_OPTIONS = [
    ("seed -1", ["--seed", "-1"], None, "seed"),
    ("seed 2**32", ["--seed", str(2**32)], None, "seed"),
    ("action repeat 0", ["--action-repeat", "0"], None, "action_repeat"),
    ("timesteps 0", ["--timesteps", "0"], None, "n_timesteps"),
    ("n-envs 0", ["--n-envs", "0"], None, "n_envs"),
    ("eval-freq -1", ["--eval-freq", "-1"], None, "eval_freq"),
    ("checkpoint-freq 0", ["--checkpoint-freq", "0"], None, "checkpoint_freq"),
    ("correction without residual", ["--action-mode", "direct", "--correction", "0.2"], None, "--correction"),
    ("bad YAML", [], f"{OMEGA}:\n  n_steps: [1, 2\n", "not valid YAML"),
    ("YAML not a mapping", [], "- 1\n- 2\n", "no entry"),
    ("n_steps 0", [], _entry(n_steps=0), "n_steps"),
    ("n_epochs 0", [], _entry(n_epochs=0), "n_epochs"),
    ("gamma 2.0", [], _entry(gamma=2.0), "gamma"),
    ("negative learning rate", [], _entry(learning_rate=-3e-4), "learning_rate"),
    ("NaN learning rate", [], _entry(learning_rate=float("nan")), "learning_rate"),
    ("negative linear schedule", [], _entry(learning_rate="lin_-1"), "learning_rate"),
    ("batch_size 1", [], _entry(batch_size=1), "batch_size"),
    ("clip_range 0", [], _entry(clip_range=0.0), "clip_range"),
    ("misspelt hyperparameter", [], _entry(n_step=128), "did you mean 'n_steps'"),
    ("unsupported Zoo key", [], _entry(frame_stack=4), "frame_stack"),
    ("policy_kwargs code", [], _entry(policy_kwargs="__import__('os').system('touch ran')"), "policy_kwargs"),
    ("policy_kwargs misspelt", [], _entry(policy_kwargs="dict(net_arc=[8])"), "net_arch"),
    ("normalize code", [], _entry(normalize="__import__('os')"), "normalize"),
    ("env kwarg out of range", [], _entry(env_kwargs={"feedrate": -1.0}), "feedrate"),
    ("env kwarg misspelt", [], _entry(env_kwargs={"feedrat": 50.0}), "feedrat"),
    ("n_timesteps NaN", [], _entry(n_timesteps=float("nan")), "n_timesteps"),
]


@pytest.mark.parametrize("case,argv,text,must", BAD_OPTIONS, ids=[c[0] for c in BAD_OPTIONS])
def test_bad_options_exit_2_before_the_run_folder_exists(tmp_path, capsys, case, argv, text, must):
    config = _write(tmp_path / "hp.yml", TINY if text is None else text)
    out = tmp_path / "run"
    t0 = time.perf_counter()
    with pytest.raises(SystemExit) as exc:
        train_main(["--env", OMEGA, "--config", str(config), "--output", str(out), "--no-progress", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert must in err and "Traceback" not in err, err
    assert not out.exists(), "a refused run left its folder behind"
    assert time.perf_counter() - t0 < 5.0
    assert not Path("ran").exists() and not (tmp_path / "ran").exists()


# -- 4. run data --------------------------------------------------------------------------------------
def _cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = train_main([*argv, "--no-progress", "--no-tensorboard"])
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    return _write(tmp_path_factory.mktemp("hp") / "tiny.yml", TINY)


@pytest.fixture(scope="module")
def base_run(tiny, tmp_path_factory):
    """A run of 1000 steps asked for (4 rollouts once rounded), checkpoints every 256, evaluations every 512."""
    run = tmp_path_factory.mktemp("base") / "run"
    code, out, err = _cli(
        [
            "--env",
            OMEGA,
            "--config",
            str(tiny),
            "--output",
            str(run),
            "--timesteps",
            "1000",
            "--checkpoint-freq",
            "256",
            "--eval-freq",
            "512",
        ]
    )
    assert code == 0, err
    return run, out, err


def _copy(run: Path, tmp_path: Path) -> Path:
    new = tmp_path / "run"
    shutil.copytree(run, new)
    return new


def _monitor(run: Path) -> dict[str, list[list[str]]]:
    return {p.name: p.read_text().splitlines() for p in sorted((run / "monitor").glob("*.monitor.csv"))}


def _chain_breaks(run: Path) -> int:
    """Episode rows not accounted for by the steps since the previous row or session start (lost or duplicated)."""
    starts = [s["start_timesteps"] for s in json.loads((run / "summary.json").read_text())["sessions"]]
    breaks = 0
    for lines in _monitor(run).values():
        prev = 0
        for r in csv.DictReader(lines[1:]):
            steps, length = int(r["steps"]), int(r["l"])
            anchor = max([prev] + [s for s in starts if prev <= s < steps])
            breaks += steps - anchor != 2 * length
            prev = steps
    return breaks


def _eval_steps(run: Path) -> list[int]:
    return [int(r["steps"]) for r in csv.DictReader((run / "evaluations.csv").open())]


def test_timesteps_are_rounded_up_with_a_warning(base_run):
    run, out, err = base_run
    assert "n_timesteps 1000 is rounded up to 1024" in err
    config = yaml.safe_load((run / "config.yml").read_text())
    assert config["n_timesteps"] == config["hyperparams"]["n_timesteps"] == 1024
    assert json.loads((run / "summary.json").read_text())["timesteps"] == 1024 and "1024 in all" in out
    assert (config["checkpoint_freq"], config["eval_freq"]) == (256, 512)
    assert config["env"]["signature"]["observation_shape"] == list(gym.make(OMEGA).observation_space.shape)
    assert _eval_steps(run) == [512, 1024] and _chain_breaks(run) == 0
    assert sorted(int(p.name.split("_")[2]) for p in (run / "checkpoints").glob("rl_model_*_steps.zip")) == [
        256,
        512,
        768,
        1024,
    ]
    assert not (run / "best").exists()  # every evaluation of the untrained direct agent diverged
    final = yaml.safe_load((run / "final" / "config.yml").read_text())
    assert final.pop("agent") == {"timesteps": 1024, "evaluation": None} and final == config
    episodes = sum(len(lines) - 2 for lines in _monitor(run).values())
    assert episodes >= 4  # 512 steps per env, 161 an episode


def test_resume_appends_monitors_and_keeps_the_run_s_periods(base_run, tmp_path):
    run = _copy(base_run[0], tmp_path)
    before = _monitor(run)
    code, out, err = _cli(["--resume", str(run), "--timesteps", "1536"])
    assert code == 0, err
    after = _monitor(run)
    for name, lines in before.items():  # appended, not overwritten
        assert after[name][: len(lines)] == lines and len(after[name]) > len(lines)
    assert _eval_steps(run) == [512, 1024, 1536]  # the run's eval_freq (512), no duplicate
    assert {1280, 1536} <= {int(p.name.split("_")[2]) for p in (run / "checkpoints").glob("rl_model_*_steps.zip")}
    config = yaml.safe_load((run / "config.yml").read_text())
    assert (config["checkpoint_freq"], config["eval_freq"], config["n_timesteps"]) == (256, 512, 1536)
    assert _chain_breaks(run) == 0
    sessions = json.loads((run / "summary.json").read_text())["sessions"]
    assert [(s["start_timesteps"], s["end_timesteps"], s["status"]) for s in sessions] == [
        (0, 1024, "finished"),
        (1024, 1536, "finished"),
    ]


@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage", "no statistics", "foreign entry"])
def test_a_damaged_newest_checkpoint_falls_back_to_the_last_intact_one(base_run, tmp_path, damage):
    run = _copy(base_run[0], tmp_path)
    newest = run / "checkpoints" / "rl_model_1024_steps.zip"
    if damage == "truncated":
        newest.write_bytes(newest.read_bytes()[: newest.stat().st_size // 2])
    elif damage == "empty":
        newest.write_bytes(b"")
    elif damage == "garbage":
        newest.write_bytes(os.urandom(4096))
    elif damage == "no statistics":
        (run / "checkpoints" / "rl_model_vecnormalize_1024_steps.npz").unlink()
    else:
        _rewrite_data(newest, lambda d: d.update(evil={":serialized:": "AAAA"}))
    with pytest.warns(RunWarning, match="rl_model_1024_steps.zip is damaged.*falling back to the one at 768 steps"):
        assert latest_checkpoint(run)[0] == 768
    assert [c[0] for c in scan_checkpoints(run)[0]] == [768, 512, 256]


def test_resume_after_a_lost_session_rolls_the_logs_back(base_run, tmp_path):
    """As after a kill: the newest checkpoint (1024) is damaged, so training from 768 on was lost;
    the rows logged past 768 go, best/ is rebuilt from the checkpoints, the damaged pair is renamed."""
    run = _copy(base_run[0], tmp_path)
    # finite scores, the best at 1024 (the untrained agent's own evaluations diverge)
    rows = list(csv.DictReader((run / "evaluations.csv").open()))
    for r, score in zip(rows, ("50.0", "40.0")):
        r.update(max_um=score, mean_um=score, rms_um=score, score_um=score, diverged="False")
    with open(run / "evaluations.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    shutil.copytree(run / "final", run / "best")  # the model at 1024
    (run / "checkpoints" / "rl_model_1024_steps.zip").write_bytes(b"")
    monitor_before = _monitor(run)
    past = sum(int(r["steps"]) > 768 for lines in monitor_before.values() for r in csv.DictReader(lines[1:]))
    assert past > 0
    code, out, err = _cli(["--resume", str(run)])
    assert code == 0, err
    assert "falling back to the one at 768 steps" in err
    assert f"dropped 1 evaluation(s) and {past} episode(s)" in err
    assert _eval_steps(run) == [512, 1024]  # 1024 evaluated again, once
    assert _chain_breaks(run) == 0
    for name, lines in monitor_before.items():  # the rows up to the checkpoint are kept as they were
        kept = [line for line in lines[2:] if int(line.rsplit(",", 1)[1]) <= 768]
        assert _monitor(run)[name][2 : 2 + len(kept)] == kept
    assert (run / "checkpoints" / "rl_model_1024_steps.zip.damaged").exists()
    assert (run / "checkpoints" / "rl_model_1024_steps.zip").stat().st_size > 0  # trained again
    summary = json.loads((run / "summary.json").read_text())
    assert summary["sessions"][-1]["rolled_back"] == {"evaluations": 1, "episodes": past}
    # best/ was the lost model at 1024: now the checkpoint at 512, the best evaluation kept
    best = yaml.safe_load((run / "best" / "config.yml").read_text())["agent"]
    assert best["timesteps"] == summary["best"]["steps"] == 512
    assert (run / "best" / "model.zip").read_bytes() == (run / "checkpoints" / "rl_model_512_steps.zip").read_bytes()
    load_agent(run / "best", gym.make(OMEGA))


def test_a_failed_resume_leaves_config_yml_alone(base_run, tmp_path, capsys):
    run = _copy(base_run[0], tmp_path)
    config = (run / "config.yml").read_bytes()
    with pytest.raises(SystemExit) as exc:
        train_main(["--resume", str(run), "--timesteps", "512", "--no-progress"])
    assert exc.value.code == 2 and "has 1024 steps already" in capsys.readouterr().err
    assert (run / "config.yml").read_bytes() == config
    for p in (run / "checkpoints").glob("*.zip"):
        p.write_bytes(b"garbage")
    with pytest.raises(SystemExit) as exc:
        train_main(["--resume", str(run), "--timesteps", "2048", "--no-progress"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "no intact checkpoint" in err and f"--output {run}" in err
    assert (run / "config.yml").read_bytes() == config
    with pytest.raises(SystemExit) as exc:
        train_main(["--resume", str(run), "--seed", "3", "--no-progress"])
    assert exc.value.code == 2 and "--seed" in capsys.readouterr().err


def test_a_failed_fresh_start_never_blocks_a_retry(tiny, base_run, tmp_path, monkeypatch):
    import vcnc_agents.training as training

    run = tmp_path / "run"

    def broken(*args, **kwargs):
        raise RuntimeError("the envs could not start")

    monkeypatch.setattr(training, "make_training_venv", broken)
    with pytest.raises(RuntimeError):
        vcnc_agents.train(OMEGA, run, config_file=tiny, n_timesteps=512, progress_bar=False, tensorboard=False)
    assert not run.exists()
    run.mkdir()  # a folder that existed (empty) before the start stays, empty
    with pytest.raises(RuntimeError):
        vcnc_agents.train(OMEGA, run, config_file=tiny, n_timesteps=512, progress_bar=False, tensorboard=False)
    assert [p.name for p in run.iterdir() if p.name != ".lock"] == []
    monkeypatch.undo()
    # a run killed before its first checkpoint (config.yml and monitor/ only) is started over
    stale = tmp_path / "stale"
    stale.mkdir()
    (stale / "monitor").mkdir()
    shutil.copyfile(base_run[0] / "config.yml", stale / "config.yml")
    with pytest.raises(FileNotFoundError, match="start it again"):
        prepare_run(run_dir=stale, resume=True)
    with pytest.warns(RunWarning, match="without an intact checkpoint .* starting it over"):
        prepare_run(OMEGA, stale, config_file=tiny, n_timesteps=512)
    # a failure after the first checkpoint leaves a resumable run
    import vcnc_gym.evaluation

    def failing_episode(*args, **kwargs):
        raise RuntimeError("evaluation failed")

    monkeypatch.setattr(vcnc_gym.evaluation, "run_episode", failing_episode)
    with pytest.raises(RuntimeError, match="evaluation failed"):
        vcnc_agents.train(
            OMEGA,
            run,
            config_file=tiny,
            n_timesteps=1024,
            eval_freq=512,
            checkpoint_freq=256,
            progress_bar=False,
            tensorboard=False,
        )
    assert latest_checkpoint(run)[0] == 512
    monkeypatch.undo()
    result = vcnc_agents.train(run_dir=run, resume=True, progress_bar=False, tensorboard=False)
    assert result.timesteps == 1024 and _eval_steps(run) == [512, 1024] and _chain_breaks(run) == 0


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["SIGINT", "SIGTERM"])
def test_a_signal_saves_a_checkpoint_and_says_how_to_resume(tiny, tmp_path, sig, code):
    run = tmp_path / "run"
    before = signal.getsignal(sig)  # SIG_IGN for SIGINT under nohup or a shell's background job

    def send_after_first_checkpoint():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not list((run / "checkpoints").glob("*.zip")):
            time.sleep(0.01)
        time.sleep(0.2)
        os.kill(os.getpid(), sig)

    thread = threading.Thread(target=send_after_first_checkpoint, daemon=True)
    thread.start()
    rc, out, err = _cli(
        [
            "--env",
            OMEGA,
            "--config",
            str(tiny),
            "--output",
            str(run),
            "--timesteps",
            "25600",
            "--checkpoint-freq",
            "256",
            "--eval-freq",
            "0",
        ]
    )
    thread.join()
    assert rc == code, err
    assert f"Resume with: vcnc-train --resume {run}" in err and "Traceback" not in err
    steps = latest_checkpoint(run)[0]
    assert steps > 0 and steps % ROLLOUT == 0 and steps < 25600
    sessions = json.loads((run / "summary.json").read_text())["sessions"]
    assert sessions[-1]["status"] == f"interrupted ({sig.name})" and sessions[-1]["end_timesteps"] == steps
    assert not (run / "final").exists()
    assert signal.getsignal(sig) == before  # handlers restored


def test_two_sessions_never_write_one_run_folder(base_run, tmp_path):
    """The run lock: a resume while another process trains the folder exits 2 with its pid."""
    run = _copy(base_run[0], tmp_path)
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            (
                "import fcntl, sys, time; f = open(sys.argv[1], 'a+'); fcntl.flock(f, fcntl.LOCK_EX); "
                "f.seek(0); f.truncate(); f.write('4242'); f.flush(); print('locked', flush=True); time.sleep(30)"
            ),
            str(run / ".lock"),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(ValueError, match=r"being trained by another process \(pid 4242\)"):
            prepare_run(run_dir=run, resume=True, n_timesteps=2048)
    finally:
        holder.kill()
        holder.wait()
    prepare_run(run_dir=run, resume=True, n_timesteps=2048)


# -- 5. SIGKILL mid-run and resume, in subprocesses --------------------------------------------------
@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
def test_kill_and_resume_loses_and_duplicates_no_row(tmp_path):
    from benchmark_script import probe_script

    module = probe_script("kill_and_resume")
    report = module.kill_and_resume(tmp_path, timesteps=4096, kill_after=1024)
    audit, naive = report["audit"], report["naive_merge_audit"]
    assert report["pre_checkpoint_rows_unchanged"]
    assert all(m["chain_breaks"] == 0 and m["duplicates"] == 0 for m in audit["monitor"].values()), audit
    e = audit["evaluations"]
    assert e["increasing"] and e["duplicates"] == 0 and e["steps"][-1] == 4096
    assert [s[2] for s in audit["sessions"]] == ["killed", "finished"]
    # the check can fail: keeping the killed session's rows past the checkpoint breaks it
    if any(report["rows_past_checkpoint"].values()):
        assert any(m["chain_breaks"] or m["duplicates"] for m in naive["monitor"].values())


def test_the_bench_runs_the_shipped_agent_only_on_its_own_configuration(capsys):
    import vcnc_bench
    from vcnc_bench.policies import default_specs

    from vcnc_agents.policy import agent_mismatch

    assert "ppo" in default_specs(gym.make(SHIPPED))
    slow = gym.make(SHIPPED, feedrate=20.0)
    assert "feedrate" in agent_mismatch(TRAINED[SHIPPED], slow)
    assert "ppo" not in default_specs(slow)  # vcnc-bench --feedrate 20 runs the baselines only
    with pytest.raises(SystemExit) as exc:
        vcnc_bench.main(["--env", SHIPPED, "--feedrate", "20", "--policy", "ppo", "--no-progress"])
    assert exc.value.code == 2 and "feedrate: trained on 100.0 mm/s" in capsys.readouterr().err
