"""Train Stable-Baselines3 PPO on a VCNC env: the Python API behind ``vcnc-train``.

:func:`train` = :func:`prepare_run` (check every option, build the run's config; nothing is written) then
:func:`learn` (train, checkpoint, evaluate; :class:`TrainingResult`).  The parts live in one module each, as
Stable-Baselines3 splits its ``common`` package:

- :mod:`agents.run_config`: the typed run configuration (:class:`agents.run_config.RunConfig`) and the checks
  of the options;
- :mod:`agents.run_folder`: the run folder's layout (``config.yml``, ``checkpoints/``, ``best/``, ``final/``,
  ``evaluations.csv``, ``monitor/``, ``summary.json``), its guarantees and the resume's roll-back;
- :mod:`agents.env_factory`: the training and evaluation envs;
- :mod:`agents.callbacks`: checkpoints and evaluations between PPO updates, the stop on a signal.

The names they export that this module exported before are importable from here too.
"""

from __future__ import annotations

import importlib.util
import signal
import time
from dataclasses import dataclass
from pathlib import Path

from .action_modes import ActionMode
from .callbacks import StopSignal, evaluation_score, make_run_callback, stop_on_signals
from .config import DEFAULT_CONFIG, count, normalize_kwargs, ppo_arguments
from .env_factory import check_envs, make_eval_env, make_training_venv
from .model_file import load_ppo
from .normalization import NormalizationStats
from .policy import CONFIG_FILE, check_signature
from .run_config import (DEFAULT_CHECKPOINT_FREQ, DEFAULT_EVAL_FREQ, VEC_ENVS, check_env_id, check_seed,
                         check_timesteps, check_training_options, new_config, round_to_rollouts, rollout_size)
from .run_folder import (CHECKPOINT_PREFIX, LOCK_FILE, check_output_folder, check_writable, clear_new_run, latest_checkpoint,
                         read_run_config, record_session, roll_back, run_lock, save_agent, scan_checkpoints,
                         session_rates, stale_run, write_yaml)
from .run_warning import RunWarning, note

__all__ = ["train", "prepare_run", "learn", "check_training_options", "TrainingResult", "RunWarning",
           "latest_checkpoint", "scan_checkpoints", "check_env_id", "check_seed", "evaluation_score",
           "make_training_venv", "DEFAULT_CHECKPOINT_FREQ", "DEFAULT_EVAL_FREQ", "VEC_ENVS"]


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
        config = read_run_config(run_dir)
        check_writable(run_dir)
        with run_lock(run_dir, probe=True):
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
        env = check_envs(config["env_id"], config["hyperparams"], mode, kwargs)
        recorded = (config.get("env") or {}).get("signature")
        if recorded is not None:
            check_signature(recorded, env["signature"], what=f"the run in {run_dir}")
        config["env"] = env
        if n_timesteps is not None:
            total = round_to_rollouts("n_timesteps", check_timesteps(count("n_timesteps", n_timesteps)),
                                       rollout_size(config))
            config["hyperparams"] = dict(config["hyperparams"], n_timesteps=total)
            config["n_timesteps"] = total
        if checkpoint[0] >= config["n_timesteps"]:
            raise ValueError(f"the run has {checkpoint[0]} steps already, its total is {config['n_timesteps']}: "
                             "pass a larger n_timesteps (--timesteps) to go on")
        return run_dir, config, checkpoint
    check_env_id(env_id)
    config = new_config(env_id, config_file=config_file, n_timesteps=n_timesteps, seed=seed, n_envs=n_envs,
                         action_mode=action_mode, checkpoint_freq=checkpoint_freq, eval_freq=eval_freq)
    run_dir = Path(run_dir) if run_dir is not None else Path("runs") / f"{env_id}_seed{config['seed']}"
    if run_dir.exists() and not run_dir.is_dir():
        raise FileExistsError(f"{run_dir} is a file, not a run folder")
    check_output_folder(run_dir)
    if run_dir.exists() and any(p.name != LOCK_FILE for p in run_dir.iterdir()):
        with run_lock(run_dir, probe=True):
            pass
        if not stale_run(run_dir):
            raise FileExistsError(f"{run_dir} already holds a run (or other files); resume it with "
                                  f"vcnc-train --resume {run_dir}, or choose another output folder")
        note(f"{run_dir} holds a run without an intact checkpoint (it never reached one, or all are damaged): "
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
    stop = StopSignal()
    with run_lock(run_dir), stop_on_signals(stop):
        try:
            return _learn(run_dir, config, checkpoint, stop, progress_bar=progress_bar, tensorboard=tensorboard,
                          vec_env=vec_env, device=device, verbose=verbose)
        except BaseException:
            if fresh and not scan_checkpoints(run_dir)[0]:
                clear_new_run(run_dir, created)
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
            clear_new_run(run_dir, created=False)  # a run that never reached a checkpoint
        run_dir.mkdir(parents=True, exist_ok=True)
        write_yaml(run_dir / CONFIG_FILE, config)
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
        probe = make_eval_env(config)
        model = load_ppo(model_zip, observation_space=probe.observation_space, action_space=probe.action_space,
                         ppo_kwargs=kwargs, device=device, tensorboard_log=tb_dir, verbose=verbose)
        probe.close()
        # the checkpoint loads: from here on the run folder changes
        intact, damaged = scan_checkpoints(run_dir, config["n_envs"])
        damaged += [c for c in intact if c[0] > done]  # passed over by latest_checkpoint: tensors unreadable
        rolled_back = roll_back(run_dir, config, done, damaged)
        if rolled_back["evaluations"] or rolled_back["episodes"]:
            note(f"resuming from {done} steps: dropped {rolled_back['evaluations']} evaluation(s) and "
                  f"{rolled_back['episodes']} episode(s) logged after that checkpoint (their training was lost)")
        set_random_seed(config["seed"] + done)
        venv = stats.vecnormalize(make_training_venv(config, run_dir, vec_env=vec_env, start_steps=done,
                                                     append=True))
        model.set_env(venv)
        write_yaml(run_dir / CONFIG_FILE, config)
    session = {"id": f"{done}@{time.time():.0f}", "start_timesteps": done, "end_timesteps": done, "wall_s": 0.0,
               "steps_per_s": 0.0, "control_periods_per_s": 0.0, "n_envs": config["n_envs"], "vec_env": vec_env,
               "status": "running"}
    if rolled_back is not None:
        session["rolled_back"] = rolled_back
    callback = make_run_callback(config, run_dir, session, stop, verbose)
    try:
        wall0 = time.perf_counter()
        model.learn(total_timesteps=config["n_timesteps"] - done, callback=callback, progress_bar=progress_bar,
                    reset_num_timesteps=checkpoint is None, tb_log_name="PPO")
        wall = time.perf_counter() - wall0
        end = model.num_timesteps
        interrupted = signal.Signals(stop.signum).name if callback.stopped_early else None
        if interrupted is None:
            save_agent(run_dir / "final", model, NormalizationStats.from_vecnormalize(venv), config, end)
    finally:
        venv.close()
        callback.env.close()
    session.update(end_timesteps=end, status=f"interrupted ({interrupted})" if interrupted else "finished",
                   **session_rates(done, end, wall, config["action_mode"]["action_repeat"]))
    record_session(run_dir, session, callback.best)
    return TrainingResult(run_dir=run_dir, timesteps=end, session_timesteps=end - done, wall_s=wall,
                          steps_per_s=session["steps_per_s"], control_periods_per_s=session["control_periods_per_s"],
                          best=callback.best, interrupted=interrupted, rolled_back=rolled_back)
