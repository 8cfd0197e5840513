"""Train Stable-Baselines3 PPO on a VCNC env: the Python API behind ``vcnc-train``.

:func:`train` = :func:`prepare_run` (check every option, build the run's config; nothing is written) then
:func:`learn` (train, checkpoint, evaluate; :class:`TrainingResult`).  The parts live in one module each, as
Stable-Baselines3 splits its ``common`` package:

- :mod:`vcnc_agents.run_config`: the typed run configuration (:class:`vcnc_agents.run_config.RunConfig`, what travels
  between the modules) and the checks of the options;
- :mod:`vcnc_agents.run_folder`: the run folder's layout (``config.yml``, ``checkpoints/``, ``best/``, ``final/``,
  ``evaluations.csv``, ``monitor/``, ``summary.json``), its guarantees and the resume's roll-back;
- :mod:`vcnc_agents.env_factory`: the training and evaluation envs;
- :mod:`vcnc_agents.run_session`: the scaffolding this trainer shares with the lean one (:mod:`vcnc_agents.lean_ppo`):
  :func:`prepare_run`, the lock, signals and clean-up, the session's record;
- :mod:`vcnc_agents.callbacks`: checkpoints and evaluations between PPO updates, the stop on a signal.

The names they export that this module exported before are importable from here too.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from vcnc_gym.envs.history import agent_space

from .action_modes import ActionMode
from .callbacks import make_run_callback
from .config import DEFAULT_CONFIG, normalize_kwargs
from .env_factory import make_eval_env, make_training_venv
from .model_file import algorithm, load_ppo
from .normalization import NormalizationStats
from .run_config import (
    DEFAULT_CHECKPOINT_FREQ,
    DEFAULT_EVAL_FREQ,
    VEC_ENVS,
    RunConfig,
    check_env_id,
    check_seed,
    check_training_options,
)
from .run_folder import evaluation_score, latest_checkpoint, save_agent, scan_checkpoints
from .run_session import Session, TrainingResult, open_run, prepare_run, roll_back_to, start_folder
from .run_warning import RunWarning

__all__ = [
    "train",
    "prepare_run",
    "learn",
    "check_training_options",
    "TrainingResult",
    "RunWarning",
    "latest_checkpoint",
    "scan_checkpoints",
    "check_env_id",
    "check_seed",
    "evaluation_score",
    "make_training_venv",
    "DEFAULT_CHECKPOINT_FREQ",
    "DEFAULT_EVAL_FREQ",
    "VEC_ENVS",
]


def train(
    env_id: str | None = None,
    run_dir=None,
    *,
    n_timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    config_file=DEFAULT_CONFIG,
    action_mode: ActionMode | None = None,
    resume: bool = False,
    progress_bar: bool = True,
    tensorboard: bool | None = None,
    vec_env: str = "native",
    device: str = "cpu",
    verbose: int = 0,
    **options,
) -> TrainingResult:
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
        Hyperparameter YAML in RL Zoo's format (:mod:`vcnc_agents.config`).
    action_mode : ActionMode, optional
        Overrides the entry's action mode.
    resume : bool
        Go on from the newest intact checkpoint in ``run_dir``.
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
    **options
        The training options, each a field of :class:`vcnc_agents.run_config.RunConfig`
        (:data:`vcnc_agents.run_config.TRAINING_OPTIONS`; None or left out: its default, or when resuming the run's):

        - ``checkpoint_freq`` (int): agent steps between checkpoints (default 50 000);
        - ``eval_freq`` (int): agent steps between deterministic evaluations, 0 for only at the end
          (default 20 000).
    """
    check_training_options(vec_env=vec_env, tensorboard=tensorboard, **options)
    run_dir, config, checkpoint = prepare_run(
        env_id,
        run_dir,
        n_timesteps=n_timesteps,
        seed=seed,
        n_envs=n_envs,
        config_file=config_file,
        action_mode=action_mode,
        resume=resume,
        **options,
    )
    return learn(
        run_dir,
        config,
        checkpoint,
        progress_bar=progress_bar,
        tensorboard=tensorboard,
        vec_env=vec_env,
        device=device,
        verbose=verbose,
    )


def learn(
    run_dir: Path,
    config: RunConfig,
    checkpoint,
    *,
    progress_bar: bool = True,
    tensorboard: bool | None = None,
    vec_env: str = "native",
    device: str = "cpu",
    verbose: int = 0,
) -> TrainingResult:
    """Train the run :func:`prepare_run` set up (from ``checkpoint`` if not None); options as :func:`train`.

    A new run that fails before its first checkpoint removes what it wrote;
    a resume that fails before training starts changes nothing (:func:`vcnc_agents.run_session.open_run`).
    """
    check_training_options(vec_env=vec_env, tensorboard=tensorboard)
    if checkpoint is None and config.init_from is not None:
        raise ValueError(
            f"init_from ({config.init_from}): a warm start is the lean trainer's "
            "(vcnc_agents.warm_start); train with --trainer lean"
        )
    with open_run(run_dir, checkpoint) as stop:
        model, venv, session = _model_and_envs(
            run_dir, config, checkpoint, tensorboard=tensorboard, vec_env=vec_env, device=device, verbose=verbose
        )
        callback = make_run_callback(config, run_dir, session, stop, verbose)
        end, interrupted = session.start, None
        try:
            session.start_clock()
            model.learn(
                total_timesteps=config.n_timesteps - session.start,
                callback=callback,
                progress_bar=progress_bar,
                reset_num_timesteps=checkpoint is None,
                tb_log_name="PPO",
            )
            end = model.num_timesteps
            interrupted = stop.name if callback.stopped_early else None
            if interrupted is None:
                save_agent(run_dir / "final", model, NormalizationStats.from_vecnormalize(venv), config, end)
        finally:
            venv.close()
            callback.env.close()
        return session.end(end, callback.best, interrupted)


def _model_and_envs(run_dir, config: RunConfig, checkpoint, *, tensorboard, vec_env, device, verbose):
    """(PPO model, its normalised training VecEnv, the :class:`vcnc_agents.run_session.Session`): a new one, or the
    checkpoint's with the run folder rolled back to it."""
    from stable_baselines3.common.vec_env import VecNormalize

    policy, kwargs = config.ppo_arguments()
    use_tb = importlib.util.find_spec("tensorboard") is not None if tensorboard is None else tensorboard
    tb_dir = str(run_dir / "tb") if use_tb else None
    if checkpoint is None:
        done = start_folder(run_dir, config)
        norm = normalize_kwargs(config.hyperparams)
        if norm is None:
            norm = {"norm_obs": False, "norm_reward": False}  # kept, so every agent folder has the same files
        venv = VecNormalize(make_training_venv(config, run_dir, vec_env=vec_env), **norm)
        model = algorithm(policy)(
            policy, venv, seed=config.seed, tensorboard_log=tb_dir, device=device, verbose=verbose, **kwargs
        )
        return model, venv, Session(run_dir, config, done, vec_env=vec_env)
    done, model_zip, norm_file = checkpoint
    stats = NormalizationStats.load(norm_file)
    probe = make_eval_env(config)
    space = agent_space(probe.observation_space, config.mode.history, probe.unwrapped.layout)
    model = load_ppo(
        model_zip,
        observation_space=space,
        action_space=probe.action_space,
        ppo_kwargs=kwargs,
        device=device,
        policy=policy,
        tensorboard_log=tb_dir,
        verbose=verbose,
    )
    probe.close()
    # the checkpoint loads: from here on the run folder changes
    rolled_back = roll_back_to(run_dir, config, done)
    venv = stats.vecnormalize(make_training_venv(config, run_dir, vec_env=vec_env, start_steps=done, append=True))
    model.set_env(venv)
    return model, venv, Session(run_dir, config, done, vec_env=vec_env, rolled_back=rolled_back)
