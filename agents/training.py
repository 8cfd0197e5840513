"""Train Stable-Baselines3 PPO on a VCNC env: the Python API behind ``vcnc-train``.

Everything of one run lives in one folder::

    RUN/
      config.yml          env id, seed, n_envs, n_timesteps, action mode, hyperparameters
      checkpoints/        rl_model_<steps>_steps.zip + rl_model_vecnormalize_<steps>_steps.pkl
      best/               model.zip, vecnormalize.pkl, config.yml: best deterministic evaluation
      final/              the same three at the end of training
      evaluations.csv     steps, max / mean / RMS contour error (um) of each evaluation
      monitor/            SB3 Monitor files of the training envs
      tb/                 TensorBoard logs (when tensorboard is installed)
      summary.json        wall time and steps per second of each training session

``best/`` and ``final/`` are agents: ``vcnc-bench --policy ppo:RUN/best``.
Evaluation runs the agent deterministically on the nominal plant through the
same :func:`vcnc_gym.evaluation.run_episode` as the benchmark and keeps the
model with the lowest ``sqrt(max * RMS)`` contour error, so both figures of
the benchmark count.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import re
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import yaml

import vcnc_gym

from .action_modes import ActionMode
from .config import DEFAULT_CONFIG, action_mode_of, load_hyperparameters, normalize_kwargs, ppo_arguments, with_action_mode
from .policy import CONFIG_FILE, MODEL_FILE, NORMALIZATION_FILE, AgentPolicy

__all__ = ["train", "prepare_run", "learn", "check_training_options", "TrainingResult", "latest_checkpoint", "check_env_id", "evaluation_score"]

CHECKPOINT_PREFIX = "rl_model"
_CHECKPOINT = re.compile(rf"^{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")


@dataclass
class TrainingResult:
    """What a call of :func:`train` did.

    Attributes
    ----------
    run_dir : Path
        The run's folder.
    timesteps : int
        Agent steps trained in all (across resumed sessions).
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
    """

    run_dir: Path
    timesteps: int
    session_timesteps: int
    wall_s: float
    steps_per_s: float
    control_periods_per_s: float
    best: dict | None


# -- checks ------------------------------------------------------------------------
def check_env_id(env_id: str) -> str:
    """``env_id`` if it is a registered VCNC env; ValueError naming the valid ones otherwise."""
    if env_id not in vcnc_gym.ENV_IDS:
        raise ValueError(f"unknown env {env_id!r}; the VCNC envs are {', '.join(vcnc_gym.ENV_IDS)}")
    return env_id


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer, float)) or value != int(value) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def latest_checkpoint(run_dir) -> tuple[int, Path, Path] | None:
    """(steps, model zip, VecNormalize pkl) of the newest complete checkpoint of a run, or None."""
    folder = Path(run_dir) / "checkpoints"
    found = []
    for p in folder.glob(f"{CHECKPOINT_PREFIX}_*_steps.zip") if folder.is_dir() else []:
        m = _CHECKPOINT.match(p.name)
        norm = folder / f"{CHECKPOINT_PREFIX}_vecnormalize_{m.group(1)}_steps.pkl" if m else None
        if m and norm.is_file():
            found.append((int(m.group(1)), p, norm))
    return max(found) if found else None


def evaluation_score(max_um: float, rms_um: float) -> float:
    """Selection score of an evaluation, um: the geometric mean of max and RMS contour error
    (inf if either is not finite; a diverged episode is scored inf by the caller)."""
    return math.sqrt(max_um * rms_um) if math.isfinite(max_um) and math.isfinite(rms_um) else math.inf


# -- environments -------------------------------------------------------------------
def _env_factory(env_id: str, env_kwargs: dict, mode: ActionMode):
    def make():
        from stable_baselines3.common.monitor import Monitor

        return Monitor(mode.wrap(gym.make(env_id, **env_kwargs)))

    return make


def _vec_env(config: dict, run_dir: Path, vec_env: str):
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    h = config["hyperparams"]
    mode = ActionMode(**config["action_mode"])
    env_kwargs = dict(h.get("env_kwargs") or {})
    cls = {"dummy": DummyVecEnv, "subproc": SubprocVecEnv}[vec_env]
    return make_vec_env(_env_factory(config["env_id"], env_kwargs, mode), n_envs=config["n_envs"],
                        seed=config["seed"], vec_env_cls=cls,
                        monitor_dir=str(run_dir / "monitor"))


def _eval_env(config: dict):
    """The plain env of the benchmark (nominal plant, action_repeat=1) with the run's task arguments."""
    env_kwargs = {k: v for k, v in (config["hyperparams"].get("env_kwargs") or {}).items()
                  if k not in ("action_repeat", "randomize", "parameters")}
    return gym.make(config["env_id"], **env_kwargs)


# -- callbacks -------------------------------------------------------------------------
def _save_agent(folder: Path, model, venv, config_file: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / MODEL_FILE)
    venv.save(str(folder / NORMALIZATION_FILE))
    shutil.copyfile(config_file, folder / CONFIG_FILE)


def _make_run_callback(config: dict, run_dir: Path, *, eval_freq: int, checkpoint_freq: int, verbose: int):
    """The callback that checkpoints and evaluates, both between PPO updates.

    SB3 calls ``_on_rollout_start`` after each policy update, so a checkpoint
    or an evaluation there holds the model trained on every step counted in
    ``num_timesteps``; ``_on_training_end`` comes after the last update.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    from vcnc_gym.evaluation import run_episode

    class RunCallback(BaseCallback):
        def __init__(self):
            super().__init__(verbose)
            self.env = _eval_env(config)
            self.mode = ActionMode(**config["action_mode"])
            self.csv = run_dir / "evaluations.csv"
            self.best = _best_of(self.csv)

        def _on_training_start(self) -> None:
            self.last_eval = self.last_checkpoint = self.num_timesteps

        def _on_step(self) -> bool:
            return True

        def _on_rollout_start(self) -> None:
            if self.num_timesteps - self.last_checkpoint >= checkpoint_freq:
                self.checkpoint()
            if self.num_timesteps - self.last_eval >= eval_freq:
                self.evaluate()

        def _on_training_end(self) -> None:
            if self.num_timesteps != self.last_checkpoint:
                self.checkpoint()
            if self.num_timesteps != self.last_eval:
                self.evaluate()

        def checkpoint(self) -> None:
            self.last_checkpoint = n = self.num_timesteps
            folder = run_dir / "checkpoints"
            folder.mkdir(parents=True, exist_ok=True)
            self.model.get_vec_normalize_env().save(str(folder / f"{CHECKPOINT_PREFIX}_vecnormalize_{n}_steps.pkl"))
            self.model.save(folder / f"{CHECKPOINT_PREFIX}_{n}_steps.zip")  # last: a zip means a complete pair

        def evaluate(self) -> None:
            self.last_eval = self.num_timesteps
            policy = AgentPolicy(self.model, self.model.get_vec_normalize_env(), self.mode, self.env)
            r = run_episode(policy, self.env, seed=0)
            score = math.inf if r.diverged else evaluation_score(r.max_contour_error_um, r.rms_contour_error_um)
            row = {"steps": self.num_timesteps, "max_um": r.max_contour_error_um,
                   "mean_um": r.mean_contour_error_um, "rms_um": r.rms_contour_error_um,
                   "score_um": score, "diverged": r.diverged}
            new = not self.csv.exists()
            with open(self.csv, "a", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(row))
                if new:
                    w.writeheader()
                w.writerow(row)
            for key in ("max_um", "rms_um", "score_um"):
                self.logger.record(f"eval/contour_{key}", row[key])
            if math.isfinite(score) and (self.best is None or score < self.best["score_um"]):
                self.best = row
                _save_agent(run_dir / "best", self.model, self.model.get_vec_normalize_env(), run_dir / CONFIG_FILE)
            if self.verbose:
                best = f"{self.best['score_um']:.2f}" if self.best else "-"
                print(f"eval at {self.num_timesteps} steps: max {r.max_contour_error_um:.2f} um, "
                      f"RMS {r.rms_contour_error_um:.2f} um, diverged {r.diverged} (best score {best})")

    return RunCallback()


def _best_of(csv_path: Path) -> dict | None:
    """The best finite-score row of an evaluations.csv, typed, or None."""
    if not csv_path.is_file():
        return None
    with open(csv_path) as f:
        rows = [{"steps": int(r["steps"]), **{k: float(r[k]) for k in ("max_um", "mean_um", "rms_um", "score_um")},
                 "diverged": r["diverged"] == "True"} for r in csv.DictReader(f)]
    rows = [r for r in rows if math.isfinite(r["score_um"])]
    return min(rows, key=lambda r: r["score_um"]) if rows else None


# -- the API -------------------------------------------------------------------------------
def _new_config(env_id, *, config_file, n_timesteps, seed, n_envs, action_mode) -> dict:
    h = load_hyperparameters(env_id, config_file)
    mode = action_mode if action_mode is not None else action_mode_of(h)
    h = with_action_mode(h, mode)
    n_timesteps = _positive_int("n_timesteps", n_timesteps if n_timesteps is not None else h.get("n_timesteps", 0))
    n_envs = _positive_int("n_envs", n_envs if n_envs is not None else h.get("n_envs", 1))
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be an integer, got {seed!r}")
    h["n_timesteps"], h["n_envs"] = n_timesteps, n_envs
    ppo_arguments(h)  # fail now on a bad entry
    normalize_kwargs(h)
    return {"env_id": env_id, "seed": int(seed), "n_envs": n_envs, "n_timesteps": n_timesteps,
            "action_mode": mode.to_dict(), "hyperparams": h,
            "config_file": "agents/hyperparams/ppo.yml" if Path(config_file) == DEFAULT_CONFIG else str(config_file)}


def prepare_run(env_id: str | None = None, run_dir=None, *, n_timesteps: int | None = None, seed: int = 0,
                n_envs: int | None = None, config_file=DEFAULT_CONFIG, action_mode: ActionMode | None = None,
                resume: bool = False) -> tuple[Path, dict, tuple | None]:
    """Check every option and write or read the run's config.yml; no training.

    Returns (run folder, config, checkpoint to resume from or None).  Raises
    ValueError / FileNotFoundError / FileExistsError with a clear message for
    an unknown env, a non-positive step count, a resume folder without a
    checkpoint or a new run into a folder that already holds one.
    """
    if resume:
        if run_dir is None:
            raise ValueError("resume needs the run folder")
        run_dir = Path(run_dir)
        config_path = run_dir / CONFIG_FILE
        if not config_path.is_file():
            raise FileNotFoundError(f"cannot resume: {run_dir} has no {CONFIG_FILE}; is it a vcnc-train run folder?")
        checkpoint = latest_checkpoint(run_dir)
        if checkpoint is None:
            raise FileNotFoundError(f"cannot resume: {run_dir / 'checkpoints'} holds no complete checkpoint "
                                    f"({CHECKPOINT_PREFIX}_<steps>_steps.zip with its vecnormalize .pkl)")
        config = yaml.safe_load(config_path.read_text())
        if env_id is not None and env_id != config["env_id"]:
            raise ValueError(f"{run_dir} is a run on {config['env_id']}, not {env_id}")
        if n_timesteps is not None:
            config["n_timesteps"] = config["hyperparams"]["n_timesteps"] = _positive_int("n_timesteps", n_timesteps)
        if checkpoint[0] >= config["n_timesteps"]:
            raise ValueError(f"the run has {checkpoint[0]} steps already, its total is {config['n_timesteps']}: "
                             "pass a larger n_timesteps to go on")
        config_path.write_text(yaml.safe_dump(config, sort_keys=False))
        return run_dir, config, checkpoint
    check_env_id(env_id)
    config = _new_config(env_id, config_file=config_file, n_timesteps=n_timesteps, seed=seed, n_envs=n_envs,
                         action_mode=action_mode)
    run_dir = Path(run_dir) if run_dir is not None else Path("runs") / f"{env_id}_seed{config['seed']}"
    if run_dir.exists() and any(run_dir.iterdir()):
        raise FileExistsError(f"{run_dir} already holds a run; resume it or choose another output folder")
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / CONFIG_FILE).write_text(yaml.safe_dump(config, sort_keys=False))
    return run_dir, config, None


def train(env_id: str | None = None, run_dir=None, *, n_timesteps: int | None = None, seed: int = 0,
          n_envs: int | None = None, config_file=DEFAULT_CONFIG, action_mode: ActionMode | None = None,
          resume: bool = False, checkpoint_freq: int = 50_000, eval_freq: int | None = 20_000,
          progress_bar: bool = True, tensorboard: bool | None = None, vec_env: str = "dummy",
          device: str = "cpu", verbose: int = 0) -> TrainingResult:
    """Train PPO on ``env_id`` (or resume the run in ``run_dir``) and save everything in the run folder.

    Parameters
    ----------
    env_id : str
        A registered VCNC env ("VCNC-Heart-v0", "VCNC-Omega-v0"); read from
        the run's config when resuming.
    run_dir : path, optional
        The run's folder; default ``runs/<env_id>_seed<seed>``.  A new run
        needs it empty or absent.
    n_timesteps : int, optional
        Total agent steps (the entry's ``n_timesteps`` by default); when
        resuming, a new total.
    seed, n_envs : int
        Seed of the envs and of PPO; parallel training envs (the entry's by default).
    config_file : path
        Hyperparameter YAML in RL Zoo's format (:mod:`agents.config`).
    action_mode : ActionMode, optional
        Overrides the entry's action mode.
    resume : bool
        Go on from the newest checkpoint in ``run_dir``.
    checkpoint_freq : int
        Agent steps between checkpoints.
    eval_freq : int or None
        Agent steps between deterministic evaluations (None: only at the end).
    progress_bar : bool
        SB3's progress bar.
    tensorboard : bool or None
        Log to RUN/tb; None: whenever tensorboard is installed.
    vec_env : str
        "dummy" (one process) or "subproc" (one process per env).
    device : str
        Torch device.
    verbose : int
        SB3 verbosity.
    """
    check_training_options(checkpoint_freq=checkpoint_freq, eval_freq=eval_freq, vec_env=vec_env,
                           tensorboard=tensorboard)
    run_dir, config, checkpoint = prepare_run(env_id, run_dir, n_timesteps=n_timesteps, seed=seed, n_envs=n_envs,
                                              config_file=config_file, action_mode=action_mode, resume=resume)
    return learn(run_dir, config, checkpoint, checkpoint_freq=checkpoint_freq, eval_freq=eval_freq,
                 progress_bar=progress_bar, tensorboard=tensorboard, vec_env=vec_env, device=device, verbose=verbose)


def check_training_options(*, checkpoint_freq, eval_freq, vec_env, tensorboard) -> None:
    """ValueError for a bad training option of :func:`train` (the run-independent ones)."""
    _positive_int("checkpoint_freq", checkpoint_freq)
    if eval_freq is not None:
        _positive_int("eval_freq", eval_freq)
    if vec_env not in ("dummy", "subproc"):
        raise ValueError(f"vec_env must be 'dummy' or 'subproc', got {vec_env!r}")
    if tensorboard and importlib.util.find_spec("tensorboard") is None:
        raise ValueError("tensorboard logging was asked for but tensorboard is not installed")


def learn(run_dir: Path, config: dict, checkpoint, *, checkpoint_freq: int = 50_000, eval_freq: int | None = 20_000,
          progress_bar: bool = True, tensorboard: bool | None = None, vec_env: str = "dummy", device: str = "cpu",
          verbose: int = 0) -> TrainingResult:
    """Train the run :func:`prepare_run` set up (from ``checkpoint`` if not None); options as :func:`train`."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    h = config["hyperparams"]
    policy, kwargs = ppo_arguments(h)
    norm = normalize_kwargs(h)
    if norm is None:
        norm = {"norm_obs": False, "norm_reward": False}  # kept, so every agent folder has the same files
    venv = _vec_env(config, run_dir, vec_env)
    use_tb = importlib.util.find_spec("tensorboard") is not None if tensorboard is None else tensorboard
    tb_dir = str(run_dir / "tb") if use_tb else None
    if checkpoint is None:
        venv = VecNormalize(venv, **norm)
        model = PPO(policy, venv, seed=config["seed"], tensorboard_log=tb_dir, device=device, verbose=verbose,
                    **kwargs)
        done = 0
    else:
        done, model_zip, norm_pkl = checkpoint
        venv = VecNormalize.load(str(norm_pkl), venv)
        venv.training = True
        model = PPO.load(model_zip, env=venv, device=device, tensorboard_log=tb_dir, verbose=verbose,
                         custom_objects={k: kwargs[k] for k in ("learning_rate", "clip_range") if k in kwargs})
        done = model.num_timesteps
    n_envs = config["n_envs"]
    evaluator = _make_run_callback(config, run_dir, eval_freq=eval_freq or config["n_timesteps"],
                                   checkpoint_freq=checkpoint_freq, verbose=verbose)

    remaining = config["n_timesteps"] - done
    wall0 = time.perf_counter()
    model.learn(total_timesteps=remaining, callback=evaluator, progress_bar=progress_bar,
                reset_num_timesteps=checkpoint is None, tb_log_name="PPO")
    wall = time.perf_counter() - wall0
    _save_agent(run_dir / "final", model, venv, run_dir / CONFIG_FILE)
    venv.close()
    evaluator.env.close()

    trained = model.num_timesteps - done
    repeat = config["action_mode"]["action_repeat"]
    session = {"start_timesteps": done, "end_timesteps": model.num_timesteps, "wall_s": wall,
               "steps_per_s": trained / wall, "control_periods_per_s": trained * repeat / wall,
               "n_envs": n_envs, "vec_env": vec_env}
    summary_path = run_dir / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {"sessions": []}
    summary["sessions"].append(session)
    summary["timesteps"] = model.num_timesteps
    summary["wall_s"] = sum(s["wall_s"] for s in summary["sessions"])
    summary["best"] = evaluator.best
    summary_path.write_text(json.dumps(summary, indent=2) + "\n")
    return TrainingResult(run_dir=run_dir, timesteps=model.num_timesteps, session_timesteps=trained, wall_s=wall,
                          steps_per_s=session["steps_per_s"], control_periods_per_s=session["control_periods_per_s"],
                          best=evaluator.best)
