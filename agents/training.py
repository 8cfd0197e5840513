"""Train Stable-Baselines3 PPO on a VCNC env: the Python API behind ``vcnc-train``.

Everything of one run lives in one folder::

    RUN/
      config.yml          env id, env kwargs and signature, seed, n_envs, n_timesteps,
                          checkpoint and evaluation periods, action mode, hyperparameters
      checkpoints/        rl_model_<steps>_steps.zip + rl_model_vecnormalize_<steps>_steps.npz
      best/               model.zip, vecnormalize.npz, config.yml: best deterministic evaluation
      final/              the same three at the end of training
      evaluations.csv     steps, max / mean / RMS contour error (um) of each evaluation (inf when
                          it diverged), score, diverged
      monitor/            SB3 Monitor files of the training envs, one row per episode: return r,
                          length l (agent steps), t (s since the session's start) and
                          steps (the run's agent-step count at the episode's end)
      tb/                 TensorBoard logs (when tensorboard is installed)
      summary.json        wall time, steps per second and status of each training session

``best/`` and ``final/`` are agents: ``vcnc-bench --policy ppo:RUN/best``.
Evaluation runs the agent deterministically on the nominal plant through the
same :func:`vcnc_gym.evaluation.run_episode` as the benchmark and keeps the
model with the lowest ``sqrt(max * RMS)`` contour error, so both figures of
the benchmark count.

What the run folder guarantees
------------------------------
- Nothing is written before every option is checked (:func:`prepare_run`):
  a bad option leaves no folder behind.  A new run that fails before its
  first checkpoint removes what it created; after one, it can be resumed.
- Checkpoints are written between PPO updates, each file atomically (a
  temporary file renamed), the model last.  Every evaluation is taken on a
  checkpoint, so ``best/`` can always be rebuilt from ``checkpoints/``.
- ``--resume`` goes on from the newest *intact* checkpoint (a damaged newer
  one is renamed ``*.damaged`` with a warning), first rolling the logs back
  to it: rows of evaluations.csv and monitor/ past the checkpoint belong to
  training that was lost and are dropped, so every step of the model's history
  is logged exactly once.  Monitor files are appended to, never overwritten.
- SIGINT or SIGTERM stops at the next environment step, saves a checkpoint
  of the model as of its last update and summary.json, and says how to resume.
"""

from __future__ import annotations

import csv
import importlib.util
import io
import json
import math
import multiprocessing
import os
import re
import shutil
import signal
import sys
import threading
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import yaml

import vcnc_gym  # noqa: F401  (registers the VCNC ids with Gymnasium)
from vcnc_gym.envs.registry import suite_env
from vcnc_gym.validation import size

from .action_modes import ActionMode
from .config import (DEFAULT_CONFIG, action_mode_of, count, load_hyperparameters, normalize_kwargs,
                     ppo_arguments, with_action_mode)
from .model_file import check_model_data, check_tensor_files, load_ppo, read_model_data, recorded_shape
from .normalization import NormalizationStats, atomic_write_bytes
from .policy import CONFIG_FILE, MODEL_FILE, NORMALIZATION_FILE, AgentPolicy, check_signature, env_signature

__all__ = ["train", "prepare_run", "learn", "check_training_options", "TrainingResult", "RunWarning",
           "latest_checkpoint", "scan_checkpoints", "check_env_id", "evaluation_score", "make_training_venv",
           "DEFAULT_CHECKPOINT_FREQ", "DEFAULT_EVAL_FREQ"]

CHECKPOINT_PREFIX = "rl_model"
_CHECKPOINT = re.compile(rf"^{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
DEFAULT_CHECKPOINT_FREQ = 50_000
DEFAULT_EVAL_FREQ = 20_000
_SEED_MAX = 2**32 - 1

#: Most agent steps a run may ask for (ours): 20 days at the 5 630 steps/s measured on this project's 2 cores
#: (README, ``benchmarks/train_throughput.py``); a run meant to be longer is resumed with a larger total.
MAX_TIMESTEPS = 10**10

#: Files a training process keeps open besides its envs' Monitor files (torch, numba, tensorboard, the
#: interpreter), subtracted from ``ulimit -n``: the native vector env keeps one Monitor file open per env.
RESERVED_FILES = 256

#: Memory of one training env besides its share of PPO's rollout buffer, bytes: its Monitor file's 8 kB
#: write buffer and its rows of the vector env's arrays (3-4 kB, ``ContouringBatch.bytes_per_env``).
ENV_BYTES = 12_000
#: Entries a run folder may hold; a folder holding others is not ours to clear.
_RUN_ENTRIES = {CONFIG_FILE, "checkpoints", "best", "final", "evaluations.csv", "monitor", "tb", "summary.json",
                ".lock"}
_LOCK = ".lock"
_EVAL_FIELDS = ("steps", "max_um", "mean_um", "rms_um", "score_um", "diverged")


class RunWarning(UserWarning):
    """Something vcnc-train did on its own that the user should know (rounding, fallback, roll-back)."""


def _note(message: str) -> None:
    warnings.warn(message, RunWarning, stacklevel=3)


@dataclass
class TrainingResult:
    """What a call of :func:`train` did.

    Attributes
    ----------
    run_dir : Path
        The run's folder.
    timesteps : int
        Agent steps trained in all (across resumed sessions), as of the last checkpoint.
    session_timesteps : int
        Agent steps trained in this call.
    wall_s : float
        Wall time of this call's training, s (set-up excluded).
    steps_per_s : float
        Agent steps per second of this call.
    control_periods_per_s : float
        Plant control periods simulated per second (agent steps x action repeat).
    best : dict or None
        The best evaluation so far (steps, max/mean/rms um, score), None without evaluation.
    interrupted : str or None
        "SIGINT" or "SIGTERM" when a signal stopped the training (a checkpoint
        was saved; resume with ``vcnc-train --resume RUN``), else None.
    rolled_back : dict or None
        On resume, the rows dropped from the logs because they came after the
        checkpoint resumed from: {"evaluations": n, "episodes": n}.
    """

    run_dir: Path
    timesteps: int
    session_timesteps: int
    wall_s: float
    steps_per_s: float
    control_periods_per_s: float
    best: dict | None
    interrupted: str | None = None
    rolled_back: dict | None = None


# -- checks ------------------------------------------------------------------------
def check_env_id(env_id: str) -> str:
    """``env_id`` if it is a VCNC env (a current id or a v0 id kept for its agents); ValueError naming the current
    ones otherwise."""
    return suite_env(env_id).id


def check_seed(seed) -> int:
    """``seed`` as an int in [0, 2**32 - 1] (what numpy and SB3 accept); ValueError otherwise."""
    v = count("seed", seed, 0)
    if v > _SEED_MAX:
        raise ValueError(f"seed must be an integer in [0, {_SEED_MAX}], got {seed!r}")
    return v


#: The training VecEnvs: the native vector env (one kernel call for all envs), SB3's DummyVecEnv, SubprocVecEnv.
VEC_ENVS = ("native", "dummy", "subproc")


def check_training_options(*, checkpoint_freq, eval_freq, vec_env, tensorboard) -> None:
    """ValueError for a bad training option of :func:`train` (the run-independent ones; None = the run's)."""
    if checkpoint_freq is not None:
        count("checkpoint_freq", checkpoint_freq)
    if eval_freq is not None:
        count("eval_freq", eval_freq, 0)
    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {vec_env!r}")
    if tensorboard and importlib.util.find_spec("tensorboard") is None:
        raise ValueError("tensorboard logging was asked for but tensorboard is not installed")


def evaluation_score(max_um: float, rms_um: float) -> float:
    """Selection score of an evaluation, um: the geometric mean of max and RMS contour error
    (inf if either is not finite; a diverged episode is scored inf by the caller)."""
    return math.sqrt(max_um * rms_um) if math.isfinite(max_um) and math.isfinite(rms_um) else math.inf


# -- checkpoints ------------------------------------------------------------------------
def _checkpoint_files(folder: Path, steps: int) -> tuple[Path, Path]:
    return (folder / f"{CHECKPOINT_PREFIX}_{steps}_steps.zip",
            folder / f"{CHECKPOINT_PREFIX}_vecnormalize_{steps}_steps.npz")


def _check_checkpoint(steps: int, model_zip: Path, norm: Path, n_envs: int | None = None) -> None:
    """ValueError saying what is wrong with a checkpoint pair (nothing is unpickled)."""
    if not norm.is_file():
        raise ValueError(f"{norm.name} is missing")
    data = read_model_data(model_zip)
    check_model_data(data, model_zip.name)
    if data.get("num_timesteps") != steps:
        raise ValueError(f"{model_zip.name} records {data.get('num_timesteps')!r} steps, its name {steps}")
    if n_envs is not None and data.get("n_envs") != n_envs:
        raise ValueError(f"{model_zip.name} was trained with n_envs {data.get('n_envs')!r}, the run has {n_envs}")
    shape = recorded_shape(data, "observation_space", model_zip)
    stats = NormalizationStats.load(norm)
    if (stats.observation_size,) != shape:
        raise ValueError(f"{norm.name} normalises {stats.observation_size} entries, the model observes {shape}")


def scan_checkpoints(run_dir, n_envs: int | None = None) -> tuple[list, list]:
    """(intact, damaged) checkpoints of a run, newest first.

    ``intact``: (steps, model zip, normalisation npz); ``damaged``: (steps,
    model zip, reason) for a pair that is missing its statistics, is
    truncated, empty, garbage or inconsistent.
    """
    folder = Path(run_dir) / "checkpoints"
    found = []
    for p in folder.iterdir() if folder.is_dir() else []:
        m = _CHECKPOINT.match(p.name)
        if m:
            found.append((int(m.group(1)), p))
    intact, damaged = [], []
    for steps, model_zip in sorted(found, reverse=True):
        norm = _checkpoint_files(folder, steps)[1]
        try:
            _check_checkpoint(steps, model_zip, norm, n_envs)
        except ValueError as exc:
            damaged.append((steps, model_zip, str(exc)))
        else:
            intact.append((steps, model_zip, norm))
    return intact, damaged


def latest_checkpoint(run_dir, n_envs: int | None = None) -> tuple[int, Path, Path] | None:
    """(steps, model zip, normalisation npz) of the newest intact checkpoint of a run, or None.

    A damaged checkpoint newer than it is skipped with a :class:`RunWarning`; so is one whose tensor files
    (``policy.pth``, ...) do not read with torch's weights-only reader (a pickled object), the newest being
    read before it is resumed from.
    """
    intact, damaged = scan_checkpoints(run_dir, n_envs)
    newest = None
    for steps, model_zip, norm in intact:
        try:
            check_tensor_files(model_zip)
        except ValueError as exc:
            damaged.append((steps, model_zip, str(exc)))
            continue
        newest = (steps, model_zip, norm)
        break
    for steps, model_zip, reason in damaged:
        if newest is None or steps > newest[0]:
            fallback = f"falling back to the one at {newest[0]} steps" if newest else "no intact checkpoint is left"
            _note(f"checkpoint {model_zip} is damaged ({reason}); {fallback}")
    return newest


# -- environments -------------------------------------------------------------------
class StepStamp(gym.Wrapper):
    """Writes the run's agent-step count into ``info["steps"]`` (a Monitor column).

    The training envs step in lock-step, so after this env's k-th step of a
    session that started at ``start`` steps, the run has counted
    ``start + k * stride`` agent steps (``stride`` = n_envs).
    """

    def __init__(self, env, start: int, stride: int):
        super().__init__(env)
        self._count = int(start)
        self._stride = int(stride)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._count += self._stride
        return obs, reward, terminated, truncated, dict(info, steps=self._count)


def _env_factory(env_id: str, env_kwargs: dict, mode: ActionMode, start: int, stride: int):
    def make():
        if multiprocessing.parent_process() is not None:
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # a subprocess env: the main process handles Ctrl-C
        return StepStamp(mode.wrap(gym.make(env_id, **env_kwargs)), start, stride)

    return make


def make_training_venv(config: dict, run_dir: Path, *, vec_env: str = "native", start_steps: int = 0,
                       append: bool = False):
    """The run's training VecEnv (without normalisation): n_envs envs with their Monitor files.

    Env i is seeded ``seed + start_steps + i`` (a resumed session draws new
    plants); the Monitor files ``monitor/<i>.monitor.csv`` are appended to
    (``append``, a resumed run) or started, and record the run's step count
    at the end of every episode (column ``steps``).
    The one place that builds the training envs: ``vec_env="native"`` (the
    default) steps all envs with one kernel call per control period
    (:class:`agents.vec_env.VcncVecEnv`, the residual baseline batched);
    "dummy" and "subproc" are SB3's per-env VecEnvs over Gymnasium envs.
    """
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    mode = ActionMode(**config["action_mode"])
    env_kwargs = dict(config["hyperparams"].get("env_kwargs") or {})
    (run_dir / "monitor").mkdir(parents=True, exist_ok=True)
    if vec_env == "native" and suite_env(config["env_id"]).vector_entry_point is None:
        _note(f"{config['env_id']} has no native vector env: training on SB3's DummyVecEnv")
        vec_env = "dummy"
    if vec_env == "native":
        from .vec_env import VcncVecEnv

        return VcncVecEnv(config["env_id"], config["n_envs"], mode, env_kwargs, seed=config["seed"] + start_steps,
                          monitor_dir=run_dir / "monitor", start_steps=start_steps, append=append)
    cls = {"dummy": DummyVecEnv, "subproc": SubprocVecEnv}[vec_env]
    return make_vec_env(_env_factory(config["env_id"], env_kwargs, mode, start_steps, config["n_envs"]),
                        n_envs=config["n_envs"], seed=config["seed"] + start_steps, vec_env_cls=cls,
                        monitor_dir=str(run_dir / "monitor"),
                        monitor_kwargs={"info_keywords": ("steps",), "override_existing": not append})


def _eval_kwargs(env_kwargs: dict) -> dict:
    """The task arguments of the plain env of the benchmark (nominal plant, action_repeat=1)."""
    return {k: v for k, v in env_kwargs.items() if k not in ("action_repeat", "randomize", "parameters")}


def _eval_env(config: dict):
    return gym.make(config["env_id"], **_eval_kwargs(config["hyperparams"].get("env_kwargs") or {}))


def _check_envs(env_id: str, hyperparams: dict, mode: ActionMode, ppo_kwargs: dict) -> dict:
    """Build the run's training and evaluation envs and its policy once; the env block of config.yml.

    Raises ValueError naming env_kwargs or policy_kwargs when the env or the
    policy network cannot be built from them.
    """
    env_kwargs = hyperparams.get("env_kwargs") or {}
    if not isinstance(env_kwargs, dict):
        raise ValueError(f"env_kwargs must be a mapping of env arguments, got {env_kwargs!r}")
    try:
        train_env = mode.wrap(gym.make(env_id, **env_kwargs))
        train_env.close()
        eval_env = gym.make(env_id, **_eval_kwargs(env_kwargs))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"env_kwargs {env_kwargs} do not make a {env_id} env for the {mode.mode} action mode: {exc}") from None
    try:
        from stable_baselines3.common.policies import ActorCriticPolicy

        ActorCriticPolicy(eval_env.observation_space, eval_env.action_space, lambda _: 3e-4,
                          **ppo_kwargs.get("policy_kwargs", {}))
    except (TypeError, ValueError, AssertionError, AttributeError, KeyError) as exc:
        raise ValueError(f"policy_kwargs {ppo_kwargs.get('policy_kwargs')} do not make a policy: {exc}") from None
    signature = env_signature(eval_env)
    eval_env.close()
    return {"id": env_id, "kwargs": dict(env_kwargs), "signature": signature}


# -- files ---------------------------------------------------------------------------------
def _write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def _write_yaml(path: Path, data: dict) -> None:
    _write_text(path, yaml.safe_dump(data, sort_keys=False))


def _save_model(model, path: Path) -> None:
    buffer = io.BytesIO()
    model.save(buffer)
    atomic_write_bytes(path, buffer.getvalue())


def _save_agent(folder: Path, model, stats: NormalizationStats, config: dict, steps: int, evaluation=None) -> None:
    """Write an agent folder (model, statistics, config with the agent's step count) as a whole.

    The files are written into a temporary folder that then replaces ``folder``.
    """
    tmp = folder.with_name(f".{folder.name}.tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    _save_model(model, tmp / MODEL_FILE)
    stats.save(tmp / NORMALIZATION_FILE)
    _write_yaml(tmp / CONFIG_FILE, dict(config, agent={"timesteps": int(steps), "evaluation": evaluation}))
    _replace_dir(tmp, folder)


def _replace_dir(new: Path, folder: Path) -> None:
    old = folder.with_name(f".{folder.name}.old")
    if old.exists():
        shutil.rmtree(old)
    if folder.exists():
        folder.rename(old)
    new.rename(folder)
    if old.exists():
        shutil.rmtree(old)


def _read_evaluations(csv_path: Path) -> list[dict]:
    """The complete rows of an evaluations.csv, typed (a torn last line is left out)."""
    if not csv_path.is_file():
        return []
    rows = []
    with open(csv_path, newline="") as f:
        for r in csv.DictReader(f):
            try:
                rows.append({"steps": int(r["steps"]),
                             **{k: float(r[k]) for k in ("max_um", "mean_um", "rms_um", "score_um")},
                             "diverged": {"True": True, "False": False}[r["diverged"]]})
            except (KeyError, TypeError, ValueError):
                continue
    return rows


def _write_evaluations(csv_path: Path, rows: list[dict]) -> None:
    buffer = io.StringIO()
    w = csv.DictWriter(buffer, fieldnames=_EVAL_FIELDS)
    w.writeheader()
    w.writerows(rows)
    _write_text(csv_path, buffer.getvalue())


def _best_of(rows: list[dict]) -> dict | None:
    """The best finite-score row, or None."""
    rows = [r for r in rows if math.isfinite(r["score_um"]) and not r["diverged"]]
    return min(rows, key=lambda r: r["score_um"]) if rows else None


def _roll_back_monitor(path: Path, steps: int) -> int:
    """Drop the episodes of a Monitor file that ended after ``steps``; the number dropped.

    A file without the ``steps`` column (an older vcnc-train) is kept as it
    is under ``<name>.before_resume`` and a new one is started.
    """
    lines = path.read_text().splitlines()
    if len(lines) < 2 or not lines[0].startswith("#"):
        path.rename(path.with_name(path.name + ".before_resume"))
        return 0
    header = next(csv.reader([lines[1]]))
    if "steps" not in header:
        path.rename(path.with_name(path.name + ".before_resume"))
        return 0
    kept, dropped = lines[:2], 0
    for row in csv.reader(lines[2:]):
        try:
            ok = len(row) == len(header) and int(float(row[header.index("steps")])) <= steps
        except ValueError:
            ok = False
        if ok:
            buffer = io.StringIO()
            csv.writer(buffer, lineterminator="").writerow(row)
            kept.append(buffer.getvalue())
        else:
            dropped += 1
    _write_text(path, "\n".join(kept) + "\n")
    return dropped


def _roll_back(run_dir: Path, config: dict, steps: int, damaged: list) -> dict:
    """Bring the run's logs and best/ back to the checkpoint at ``steps`` (see the module docstring)."""
    csv_path = run_dir / "evaluations.csv"
    rows = _read_evaluations(csv_path)
    kept = [r for r in rows if r["steps"] <= steps]
    if csv_path.exists():
        _write_evaluations(csv_path, kept)
    episodes = sum(_roll_back_monitor(p, steps) for p in sorted((run_dir / "monitor").glob("*.monitor.csv")))
    for _, model_zip, _ in damaged:
        if int(_CHECKPOINT.match(model_zip.name).group(1)) > steps:
            for p in _checkpoint_files(model_zip.parent, int(_CHECKPOINT.match(model_zip.name).group(1))):
                if p.exists():
                    p.rename(p.with_name(p.name + ".damaged"))
    _rebuild_best(run_dir, config, kept, steps)
    summary = _read_summary(run_dir)
    for s in summary["sessions"]:
        if s.get("status") == "running":
            s["status"] = "killed"
    summary["best"] = _best_of(kept)
    _write_summary(run_dir, summary)
    return {"evaluations": len(rows) - len(kept), "episodes": episodes}


def _rebuild_best(run_dir: Path, config: dict, rows: list[dict], steps: int) -> None:
    """Make best/ the checkpoint of the best of ``rows`` if it holds a model of lost training (past
    ``steps``) or not that best one, or is missing; a best/ of unknown origin (older runs) is left alone.

    Every evaluated model is a checkpoint, so best/ is copied from ``checkpoints/``.
    """
    best = _best_of(rows)
    folder = run_dir / "best"
    have = None
    if (folder / CONFIG_FILE).is_file():
        try:
            have = (yaml.safe_load((folder / CONFIG_FILE).read_text()).get("agent") or {}).get("timesteps")
        except (yaml.YAMLError, AttributeError):
            have = None
        if have is None:
            return
    if folder.exists() and have is not None and have <= steps and best is not None and have == best["steps"]:
        return
    if not folder.exists() and best is None:
        return
    if best is None:
        if have is not None and have > steps:
            shutil.rmtree(folder)
        return
    model_zip, norm = _checkpoint_files(run_dir / "checkpoints", best["steps"])
    try:
        _check_checkpoint(best["steps"], model_zip, norm)
    except ValueError as exc:
        _note(f"best/ cannot be rebuilt from the checkpoint at {best['steps']} steps ({exc}); removed")
        if folder.exists():
            shutil.rmtree(folder)
        return
    tmp = folder.with_name(".best.tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    shutil.copyfile(model_zip, tmp / MODEL_FILE)
    shutil.copyfile(norm, tmp / NORMALIZATION_FILE)
    _write_yaml(tmp / CONFIG_FILE, dict(config, agent={"timesteps": best["steps"], "evaluation": best}))
    _replace_dir(tmp, folder)


def _read_summary(run_dir: Path) -> dict:
    path = run_dir / "summary.json"
    try:
        summary = json.loads(path.read_text()) if path.is_file() else {}
    except json.JSONDecodeError:
        summary = {}
    summary.setdefault("sessions", [])
    return summary


def _record_session(run_dir: Path, session: dict, best: dict | None) -> None:
    """Write ``session`` (replacing its earlier record) and the best evaluation into summary.json."""
    summary = _read_summary(run_dir)
    summary["sessions"] = [s for s in summary["sessions"] if s.get("id") != session["id"]] + [dict(session)]
    summary["best"] = best
    _write_summary(run_dir, summary)


def _write_summary(run_dir: Path, summary: dict) -> None:
    sessions = summary["sessions"]
    summary["timesteps"] = sessions[-1]["end_timesteps"] if sessions else 0
    summary["wall_s"] = sum(s.get("wall_s", 0.0) for s in sessions)
    _write_text(run_dir / "summary.json", json.dumps(summary, indent=2) + "\n")


# -- the callback ------------------------------------------------------------------------------
def _make_run_callback(config: dict, run_dir: Path, session: dict, stop, verbose: int):
    """The callback that checkpoints and evaluates, both between PPO updates, and stops on a signal.

    SB3 calls ``_on_rollout_start`` after each policy update, so a checkpoint
    or an evaluation there holds the model trained on every step counted in
    ``num_timesteps``; ``_on_training_end`` comes after the last update, or
    after a stop in the middle of a rollout, where the model is still the one
    of the rollout's start: that is what the stop's checkpoint saves.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    from vcnc_gym.evaluation import run_episode

    checkpoint_freq = config["checkpoint_freq"]
    eval_freq = config["eval_freq"]  # 0: only at the end

    class RunCallback(BaseCallback):
        def __init__(self):
            super().__init__(verbose)
            self.env = _eval_env(config)
            self.mode = ActionMode(**config["action_mode"])
            self.csv = run_dir / "evaluations.csv"
            rows = _read_evaluations(self.csv)
            self.best = _best_of(rows)
            self.last_eval_row = max((r["steps"] for r in rows), default=None)
            self.stopped_early = False
            self.t0 = time.perf_counter()

        def stats(self) -> NormalizationStats:
            return NormalizationStats.from_vecnormalize(self.model.get_vec_normalize_env())

        def _on_training_start(self) -> None:
            self.last_checkpoint = self.rollout_start = self.num_timesteps
            self.last_eval = self.last_eval_row if self.last_eval_row is not None else 0
            self.rollout_stats = self.stats()

        def _on_rollout_start(self) -> None:
            n = self.rollout_start = self.num_timesteps
            self.rollout_stats = self.stats()
            # on grids of multiples of the periods (at the first update past each), whatever else was saved
            due_eval = eval_freq > 0 and n // eval_freq > self.last_eval // eval_freq
            if due_eval or n // checkpoint_freq > self.last_checkpoint // checkpoint_freq:
                self.checkpoint(n, self.rollout_stats)
            if due_eval:
                self.evaluate(n, self.rollout_stats)

        def _on_step(self) -> bool:
            if stop.signum is not None:
                self.stopped_early = True
                return False
            return True

        def _on_training_end(self) -> None:
            if self.stopped_early:  # the model is the one of the rollout's start
                self.model.num_timesteps = self.rollout_start
                self.checkpoint(self.rollout_start, self.rollout_stats)
                return
            n = self.num_timesteps
            stats = self.stats()
            self.checkpoint(n, stats)
            if n != self.last_eval:
                self.evaluate(n, stats)

        def checkpoint(self, n: int, stats: NormalizationStats) -> None:
            model_zip, norm = _checkpoint_files(run_dir / "checkpoints", n)
            if n == self.last_checkpoint and model_zip.is_file():
                return
            model_zip.parent.mkdir(parents=True, exist_ok=True)
            stats.save(norm)
            _save_model(self.model, model_zip)  # last: the zip completes the pair
            self.last_checkpoint = n
            session.update(end_timesteps=n, **_rates(session["start_timesteps"], n, time.perf_counter() - self.t0,
                                                     config["action_mode"]["action_repeat"]))
            _record_session(run_dir, session, self.best)

        def evaluate(self, n: int, stats: NormalizationStats) -> None:
            self.last_eval = n
            if n == self.last_eval_row:
                return  # this checkpoint was evaluated before the run was resumed
            policy = AgentPolicy(self.model, stats, self.mode, self.env)
            r = run_episode(policy, self.env, seed=0)
            score = math.inf if r.diverged else evaluation_score(r.max_contour_error_um, r.rms_contour_error_um)
            # a diverged episode's errors cover only the part before it left the bounds (a table that never
            # moved has 0.0 um there): written as inf, the bench's figure for a diverged plant, never as perfect
            figures = ((math.inf,) * 3 if r.diverged else
                       (r.max_contour_error_um, r.mean_contour_error_um, r.rms_contour_error_um))
            row = {"steps": int(n), "max_um": float(figures[0]), "mean_um": float(figures[1]),
                   "rms_um": float(figures[2]), "score_um": float(score), "diverged": bool(r.diverged)}
            new = not self.csv.exists()
            with open(self.csv, "a", newline="") as f:
                w = csv.DictWriter(f, fieldnames=_EVAL_FIELDS)
                if new:
                    w.writeheader()
                w.writerow(row)
            self.last_eval_row = n
            for key in ("max_um", "rms_um", "score_um"):
                self.logger.record(f"eval/contour_{key}", row[key])
            if math.isfinite(score) and (self.best is None or score < self.best["score_um"]):
                self.best = row
                _save_agent(run_dir / "best", self.model, stats, config, n, row)
            if self.verbose:
                best = f"{self.best['score_um']:.2f}" if self.best else "-"
                print(f"eval at {n} steps: " + ("diverged" if r.diverged else
                                                  f"max {r.max_contour_error_um:.2f} um, "
                                                  f"RMS {r.rms_contour_error_um:.2f} um") + f" (best score {best})")

    return RunCallback()


def _rates(start: int, end: int, wall: float, repeat: int) -> dict:
    steps = end - start
    wall = max(wall, 1e-9)
    return {"wall_s": wall, "steps_per_s": steps / wall, "control_periods_per_s": steps * repeat / wall}


@contextmanager
def _run_lock(run_dir: Path, *, probe: bool = False):
    """Hold an exclusive lock on ``run_dir/.lock`` (released by the OS even on SIGKILL).

    ValueError if another process holds it: two sessions must never write one
    run folder.  ``probe`` only checks (the folder must exist).
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    path = run_dir / _LOCK
    if probe and not path.exists():
        yield
        return
    with open(path, "a+") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            owner = f.read().strip() or "?"
            raise ValueError(f"{run_dir} is being trained by another process (pid {owner}); "
                             "wait for it to end or stop it first") from None
        if not probe:
            f.seek(0)
            f.truncate()
            f.write(f"{os.getpid()}\n")
            f.flush()
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


class _Stop:
    """The signal that asked the run to stop, if any."""

    signum: int | None = None


@contextmanager
def _stop_on_signals(stop: _Stop):
    """Turn SIGINT and SIGTERM into ``stop.signum`` (main thread only); a second one acts as usual."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}

    def handler(signum, frame):
        stop.signum = signum
        signal.signal(signum, previous[signum])
        print(f"\nvcnc-train: {signal.Signals(signum).name} received: saving a checkpoint at the last PPO update "
              "(send it again to quit at once)", file=sys.stderr, flush=True)

    for s in (signal.SIGINT, signal.SIGTERM):
        previous[s] = signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


# -- the API -------------------------------------------------------------------------------
def _round_to_rollouts(name: str, n_timesteps: int, rollout: int) -> int:
    total = -(-n_timesteps // rollout) * rollout
    if total != n_timesteps:
        _note(f"{name} {n_timesteps} is rounded up to {total}: PPO trains whole rollouts of n_steps x n_envs = "
              f"{rollout} agent steps")
    return total


def _rollout(config: dict) -> int:
    _, kwargs = ppo_arguments(config["hyperparams"])
    return kwargs.get("n_steps", 2048) * config["n_envs"]


def _check_timesteps(n_timesteps: int) -> int:
    return size("n_timesteps", n_timesteps, ceiling=MAX_TIMESTEPS,
                why="MAX_TIMESTEPS, 20 days at the 5 630 steps/s measured on 2 cores; resume a run to go further")


def _check_n_envs(n_envs: int, n_steps: int | None = None, observation_size: int | None = None) -> int:
    """``n_envs`` within the open-file limit (one Monitor file per env) and, with the rollout's size, memory."""
    import resource

    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    if soft != resource.RLIM_INFINITY:
        size("n_envs", n_envs, ceiling=max(1, soft - RESERVED_FILES),
             why=f"each env keeps its Monitor file open and this process may open {soft} files (ulimit -n), "
                 f"{RESERVED_FILES} kept for the rest")
    if n_steps is not None and observation_size is not None:
        rollout = n_steps * (observation_size + 2 + 6) * 4  # float32 observation, action and 6 scalars per step
        size("n_envs", n_envs, bytes_each=rollout + ENV_BYTES,
             why=f"each env fills n_steps = {n_steps} rows of PPO's rollout buffer ({observation_size} observation "
                 "entries, 2 actions, 6 scalars in float32) and holds its Monitor file and batch rows")
    return n_envs


def _new_config(env_id, *, config_file, n_timesteps, seed, n_envs, action_mode, checkpoint_freq, eval_freq) -> dict:
    h = load_hyperparameters(env_id, config_file)
    ppo_arguments(h)  # refuse a bad entry before anything else
    mode = action_mode if action_mode is not None else action_mode_of(h)
    h = with_action_mode(h, mode)
    n_timesteps = count("n_timesteps", n_timesteps if n_timesteps is not None else h.get("n_timesteps", 0))
    n_envs = _check_n_envs(count("n_envs", n_envs if n_envs is not None else h.get("n_envs", 1)))
    n_timesteps = _check_timesteps(n_timesteps)
    seed = check_seed(seed)
    _, kwargs = ppo_arguments(h)
    rollout = kwargs.get("n_steps", 2048) * n_envs
    if rollout < 2:
        raise ValueError("n_steps x n_envs must be at least 2 (PPO normalises advantages over a rollout)")
    n_timesteps = _round_to_rollouts("n_timesteps", n_timesteps, rollout)
    h["n_timesteps"], h["n_envs"] = n_timesteps, n_envs
    env = _check_envs(env_id, h, mode, kwargs)
    _check_n_envs(n_envs, kwargs.get("n_steps", 2048), math.prod(env["signature"]["observation_shape"]))
    return {"env_id": env_id, "seed": seed, "n_envs": n_envs, "n_timesteps": n_timesteps,
            "checkpoint_freq": DEFAULT_CHECKPOINT_FREQ if checkpoint_freq is None else checkpoint_freq,
            "eval_freq": DEFAULT_EVAL_FREQ if eval_freq is None else eval_freq,
            "action_mode": mode.to_dict(), "env": env, "hyperparams": h,
            "config_file": "agents/hyperparams/ppo.yml" if Path(config_file) == DEFAULT_CONFIG else str(config_file)}


def check_output_folder(run_dir: Path) -> None:
    """ValueError naming ``run_dir`` unless a folder can be made there: a probe folder is made and removed in
    its nearest existing ancestor (``--output /proc/run``: procfs takes no new folder)."""
    import tempfile

    run_dir = Path(run_dir)
    ancestor = run_dir if run_dir.is_dir() else next((p for p in run_dir.absolute().parents if p.exists()), None)
    if ancestor is None or not ancestor.is_dir():
        raise ValueError(f"cannot make the run folder {run_dir}: {ancestor} is not a folder")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".vcnc-train-probe-", dir=ancestor))
    except OSError as exc:
        raise ValueError(f"cannot make the run folder {run_dir}: no folder can be made in {ancestor} "
                         f"({exc.strerror or type(exc).__name__}); choose another --output") from None


def _stale_run(run_dir: Path) -> bool:
    """True for a folder holding a run of ours that never reached an intact checkpoint (safe to start over)."""
    names = {p.name for p in run_dir.iterdir()}
    return (run_dir / CONFIG_FILE).is_file() and names <= _RUN_ENTRIES and not scan_checkpoints(run_dir)[0]


def _read_run_config(run_dir: Path) -> dict:
    path = run_dir / CONFIG_FILE
    if not path.is_file():
        raise FileNotFoundError(f"cannot resume: {run_dir} has no {CONFIG_FILE}; is it a vcnc-train run folder?")
    try:
        config = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot resume: {path} is not valid YAML: {exc}") from None
    if not isinstance(config, dict) or not {"env_id", "n_envs", "seed", "action_mode", "hyperparams"} <= set(config):
        raise ValueError(f"cannot resume: {path} is not the config.yml of a vcnc-train run")
    return config


def prepare_run(env_id: str | None = None, run_dir=None, *, n_timesteps: int | None = None, seed: int = 0,
                n_envs: int | None = None, config_file=DEFAULT_CONFIG, action_mode: ActionMode | None = None,
                resume: bool = False, checkpoint_freq: int | None = None,
                eval_freq: int | None = None) -> tuple[Path, dict, tuple | None]:
    """Check every option and build the run's config; nothing is written.

    Returns (run folder, config, checkpoint to resume from or None).  Raises
    ValueError / FileNotFoundError / FileExistsError with a clear message for
    an unknown env, a bad hyperparameter file or entry, env kwargs that make no
    env, a bad step count or seed, a resume folder without an intact
    checkpoint, or a new run into a folder that holds one.  An ``n_timesteps``
    that is not a whole number of rollouts is rounded up (:class:`RunWarning`).
    """
    check_training_options(checkpoint_freq=checkpoint_freq, eval_freq=eval_freq, vec_env="native", tensorboard=None)
    if resume:
        if run_dir is None:
            raise ValueError("resume needs the run folder")
        run_dir = Path(run_dir)
        config = _read_run_config(run_dir)
        with _run_lock(run_dir, probe=True):
            pass
        if env_id is not None and env_id != config["env_id"]:
            raise ValueError(f"{run_dir} is a run on {config['env_id']}, not {env_id}")
        checkpoint = latest_checkpoint(run_dir, config["n_envs"])
        if checkpoint is None:
            raise FileNotFoundError(
                f"cannot resume: {run_dir / 'checkpoints'} holds no intact checkpoint "
                f"({CHECKPOINT_PREFIX}_<steps>_steps.zip with its vecnormalize .npz); it never reached one or all "
                f"are damaged: "
                f"start it again with vcnc-train --env {config['env_id']} --output {run_dir}")
        config = dict(config)
        config.setdefault("checkpoint_freq", DEFAULT_CHECKPOINT_FREQ)
        config.setdefault("eval_freq", DEFAULT_EVAL_FREQ)
        if checkpoint_freq is not None:
            config["checkpoint_freq"] = checkpoint_freq
        if eval_freq is not None:
            config["eval_freq"] = eval_freq
        _, kwargs = ppo_arguments(config["hyperparams"])
        mode = ActionMode(**config["action_mode"])
        env = _check_envs(config["env_id"], config["hyperparams"], mode, kwargs)
        recorded = (config.get("env") or {}).get("signature")
        if recorded is not None:
            check_signature(recorded, env["signature"], what=f"the run in {run_dir}")
        config["env"] = env
        if n_timesteps is not None:
            total = _round_to_rollouts("n_timesteps", _check_timesteps(count("n_timesteps", n_timesteps)),
                                       _rollout(config))
            config["hyperparams"] = dict(config["hyperparams"], n_timesteps=total)
            config["n_timesteps"] = total
        if checkpoint[0] >= config["n_timesteps"]:
            raise ValueError(f"the run has {checkpoint[0]} steps already, its total is {config['n_timesteps']}: "
                             "pass a larger n_timesteps (--timesteps) to go on")
        return run_dir, config, checkpoint
    check_env_id(env_id)
    config = _new_config(env_id, config_file=config_file, n_timesteps=n_timesteps, seed=seed, n_envs=n_envs,
                         action_mode=action_mode, checkpoint_freq=checkpoint_freq, eval_freq=eval_freq)
    run_dir = Path(run_dir) if run_dir is not None else Path("runs") / f"{env_id}_seed{config['seed']}"
    if run_dir.exists() and not run_dir.is_dir():
        raise FileExistsError(f"{run_dir} is a file, not a run folder")
    check_output_folder(run_dir)
    if run_dir.exists() and any(p.name != _LOCK for p in run_dir.iterdir()):
        with _run_lock(run_dir, probe=True):
            pass
        if not _stale_run(run_dir):
            raise FileExistsError(f"{run_dir} already holds a run (or other files); resume it with "
                                  f"vcnc-train --resume {run_dir}, or choose another output folder")
        _note(f"{run_dir} holds a run without an intact checkpoint (it never reached one, or all are damaged): "
              "starting it over")
    return run_dir, config, None


def train(env_id: str | None = None, run_dir=None, *, n_timesteps: int | None = None, seed: int = 0,
          n_envs: int | None = None, config_file=DEFAULT_CONFIG, action_mode: ActionMode | None = None,
          resume: bool = False, checkpoint_freq: int | None = None, eval_freq: int | None = None,
          progress_bar: bool = True, tensorboard: bool | None = None, vec_env: str = "native",
          device: str = "cpu", verbose: int = 0) -> TrainingResult:
    """Train PPO on ``env_id`` (or resume the run in ``run_dir``) and save everything in the run folder.

    Parameters
    ----------
    env_id : str
        A registered VCNC env ("VCNC-Heart-v0", "VCNC-Omega-v0"); read from
        the run's config when resuming.
    run_dir : path, optional
        The run's folder; default ``runs/<env_id>_seed<seed>``.  A new run
        needs it empty or absent (or holding a run that never reached a checkpoint).
    n_timesteps : int, optional
        Total agent steps (the entry's ``n_timesteps`` by default), rounded up
        to whole rollouts; when resuming, a new total.
    seed : int
        Seed of the envs and of PPO, in [0, 2**32 - 1].
    n_envs : int, optional
        Parallel training envs (the entry's by default).
    config_file : path
        Hyperparameter YAML in RL Zoo's format (:mod:`agents.config`).
    action_mode : ActionMode, optional
        Overrides the entry's action mode.
    resume : bool
        Go on from the newest intact checkpoint in ``run_dir``.
    checkpoint_freq : int, optional
        Agent steps between checkpoints (default 50 000; when resuming, the run's).
    eval_freq : int, optional
        Agent steps between deterministic evaluations, 0 for only at the end
        (default 20 000; when resuming, the run's).
    progress_bar : bool
        SB3's progress bar.
    tensorboard : bool or None
        Log to RUN/tb; None: whenever tensorboard is installed.
    vec_env : str
        "native" (the native vector env: one kernel call steps every env), "dummy" (SB3's
        DummyVecEnv, one Gymnasium env after another) or "subproc" (one process per env).
    device : str
        Torch device.
    verbose : int
        SB3 verbosity.
    """
    check_training_options(checkpoint_freq=checkpoint_freq, eval_freq=eval_freq, vec_env=vec_env,
                           tensorboard=tensorboard)
    run_dir, config, checkpoint = prepare_run(env_id, run_dir, n_timesteps=n_timesteps, seed=seed, n_envs=n_envs,
                                              config_file=config_file, action_mode=action_mode, resume=resume,
                                              checkpoint_freq=checkpoint_freq, eval_freq=eval_freq)
    return learn(run_dir, config, checkpoint, progress_bar=progress_bar, tensorboard=tensorboard, vec_env=vec_env,
                 device=device, verbose=verbose)


def _clear_new_run(run_dir: Path, created: bool) -> None:
    """Remove what a new run wrote (the folder itself if it created it)."""
    if not run_dir.exists():
        return
    if created:
        shutil.rmtree(run_dir)
        return
    for p in run_dir.iterdir():
        if (p.name in _RUN_ENTRIES or p.name.startswith(".")) and p.name != _LOCK:
            shutil.rmtree(p) if p.is_dir() else p.unlink()


def learn(run_dir: Path, config: dict, checkpoint, *, progress_bar: bool = True, tensorboard: bool | None = None,
          vec_env: str = "native", device: str = "cpu", verbose: int = 0) -> TrainingResult:
    """Train the run :func:`prepare_run` set up (from ``checkpoint`` if not None); options as :func:`train`.

    A new run that fails before its first checkpoint removes what it wrote;
    a resume that fails before training starts changes nothing.
    """
    check_training_options(checkpoint_freq=config["checkpoint_freq"], eval_freq=config["eval_freq"],
                           vec_env=vec_env, tensorboard=tensorboard)
    fresh = checkpoint is None
    created = fresh and not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    stop = _Stop()
    with _run_lock(run_dir), _stop_on_signals(stop):
        try:
            return _learn(run_dir, config, checkpoint, stop, progress_bar=progress_bar, tensorboard=tensorboard,
                          vec_env=vec_env, device=device, verbose=verbose)
        except BaseException:
            if fresh and not scan_checkpoints(run_dir)[0]:
                _clear_new_run(run_dir, created)
            raise


def _learn(run_dir, config, checkpoint, stop, *, progress_bar, tensorboard, vec_env, device, verbose):
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed

    h = config["hyperparams"]
    policy, kwargs = ppo_arguments(h)
    use_tb = importlib.util.find_spec("tensorboard") is not None if tensorboard is None else tensorboard
    tb_dir = str(run_dir / "tb") if use_tb else None
    rolled_back = None
    if checkpoint is None:
        if run_dir.exists():
            _clear_new_run(run_dir, created=False)  # a run that never reached a checkpoint
        run_dir.mkdir(parents=True, exist_ok=True)
        _write_yaml(run_dir / CONFIG_FILE, config)
        done = 0
        norm = normalize_kwargs(h)
        if norm is None:
            norm = {"norm_obs": False, "norm_reward": False}  # kept, so every agent folder has the same files
        from stable_baselines3.common.vec_env import VecNormalize

        venv = VecNormalize(make_training_venv(config, run_dir, vec_env=vec_env), **norm)
        model = PPO(policy, venv, seed=config["seed"], tensorboard_log=tb_dir, device=device, verbose=verbose,
                    **kwargs)
    else:
        done, model_zip, norm_file = checkpoint
        stats = NormalizationStats.load(norm_file)
        probe = _eval_env(config)
        model = load_ppo(model_zip, observation_space=probe.observation_space, action_space=probe.action_space,
                         ppo_kwargs=kwargs, device=device, tensorboard_log=tb_dir, verbose=verbose)
        probe.close()
        # the checkpoint loads: from here on the run folder changes
        intact, damaged = scan_checkpoints(run_dir, config["n_envs"])
        damaged += [c for c in intact if c[0] > done]  # passed over by latest_checkpoint: tensors unreadable
        rolled_back = _roll_back(run_dir, config, done, damaged)
        if rolled_back["evaluations"] or rolled_back["episodes"]:
            _note(f"resuming from {done} steps: dropped {rolled_back['evaluations']} evaluation(s) and "
                  f"{rolled_back['episodes']} episode(s) logged after that checkpoint (their training was lost)")
        set_random_seed(config["seed"] + done)
        venv = stats.vecnormalize(make_training_venv(config, run_dir, vec_env=vec_env, start_steps=done,
                                                     append=True))
        model.set_env(venv)
        _write_yaml(run_dir / CONFIG_FILE, config)
    session = {"id": f"{done}@{time.time():.0f}", "start_timesteps": done, "end_timesteps": done, "wall_s": 0.0,
               "steps_per_s": 0.0, "control_periods_per_s": 0.0, "n_envs": config["n_envs"], "vec_env": vec_env,
               "status": "running"}
    if rolled_back is not None:
        session["rolled_back"] = rolled_back
    callback = _make_run_callback(config, run_dir, session, stop, verbose)
    try:
        wall0 = time.perf_counter()
        model.learn(total_timesteps=config["n_timesteps"] - done, callback=callback, progress_bar=progress_bar,
                    reset_num_timesteps=checkpoint is None, tb_log_name="PPO")
        wall = time.perf_counter() - wall0
        end = model.num_timesteps
        interrupted = signal.Signals(stop.signum).name if callback.stopped_early else None
        if interrupted is None:
            _save_agent(run_dir / "final", model, NormalizationStats.from_vecnormalize(venv), config, end)
    finally:
        venv.close()
        callback.env.close()
    session.update(end_timesteps=end, status=f"interrupted ({interrupted})" if interrupted else "finished",
                   **_rates(done, end, wall, config["action_mode"]["action_repeat"]))
    _record_session(run_dir, session, callback.best)
    return TrainingResult(run_dir=run_dir, timesteps=end, session_timesteps=end - done, wall_s=wall,
                          steps_per_s=session["steps_per_s"], control_periods_per_s=session["control_periods_per_s"],
                          best=callback.best, interrupted=interrupted, rolled_back=rolled_back)
