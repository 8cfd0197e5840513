"""The scaffolding of a training session, one for both trainers (SB3's :mod:`vcnc_agents.training` and
:mod:`vcnc_agents.lean_ppo`): set-up, lock, signals, clean-up, roll-back and the session's record.

A session runs in five steps, each a name here:

1. :func:`prepare_run`: every option checked and the run's :class:`vcnc_agents.run_config.RunConfig` built (a new
   run, or the one in ``RUN/config.yml`` to resume, with the checkpoint it goes on from); nothing is written.
2. :func:`open_run`: the run folder made and locked (:func:`vcnc_agents.run_folder.run_lock`), SIGINT and SIGTERM
   turned into a :class:`StopSignal`, and a new run that fails before its first checkpoint cleared.
3. :func:`start_folder` (a new run: config.yml written) or :func:`roll_back_to` (a resumed run: the logs
   brought back to its checkpoint, the seeds set, config.yml written).
4. :class:`Session`: the session's row of ``summary.json`` (steps, wall time, rates, status), recorded at every
   checkpoint and at the end.
5. :meth:`Session.end`: the last record and the :class:`TrainingResult`.

What the trainers differ in (the model, the envs, the loop) stays in their modules.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .action_modes import ActionMode
from .config import DEFAULT_CONFIG
from .env_factory import check_envs
from .run_config import RunConfig, check_env_id, check_memory, check_training_options, new_config
from .run_folder import (
    CHECKPOINT_PREFIX,
    LOCK_FILE,
    check_output_folder,
    check_writable,
    clear_new_run,
    latest_checkpoint,
    record_session,
    roll_back,
    run_lock,
    scan_checkpoints,
    set_aside,
    stale_run,
    write_config,
)
from .run_warning import note
from .signature import check_signature

__all__ = [
    "prepare_run",
    "open_run",
    "start_folder",
    "roll_back_to",
    "Session",
    "TrainingResult",
    "StopSignal",
    "stop_on_signals",
]


@dataclass
class TrainingResult:
    """What a training session did.

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


# -- 1. the run's configuration ------------------------------------------------------------------------------------
def prepare_run(
    env_id: str | None = None,
    run_dir=None,
    *,
    n_timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    config_file=DEFAULT_CONFIG,
    action_mode: ActionMode | None = None,
    resume: bool = False,
    tolerance: float | None = None,
    init_from=None,
    **options,
) -> tuple[Path, RunConfig, tuple | None]:
    """Check every option and build the run's config; nothing is written.

    ``options`` are the training options (:data:`vcnc_agents.run_config.TRAINING_OPTIONS`: ``checkpoint_freq``,
    ``eval_freq``; None or left out: the default, or on resume the run's).  ``tolerance`` (mm) sets the entry's
    env_kwargs ``tolerance`` (``--tolerance``: a feed-override env's tolerance task).  ``init_from`` (an agent
    folder; ``{seed}`` in it is the run's seed number) starts the new run from that agent
    (:mod:`vcnc_agents.warm_start`).

    Returns (run folder, :class:`vcnc_agents.run_config.RunConfig`, checkpoint to resume from or None).  Raises
    ValueError / FileNotFoundError / FileExistsError with a clear message for
    an unknown env, a bad hyperparameter file or entry, env kwargs that make no
    env, a bad step count or seed, a resume folder without an intact
    checkpoint, or a new run into a folder that holds one.  An ``n_timesteps``
    that is not a whole number of rollouts is rounded up (:class:`vcnc_agents.run_warning.RunWarning`).
    """
    check_training_options(vec_env="native", tensorboard=None, **options)
    if resume:
        return _prepare_resume(env_id, run_dir, n_timesteps, options)
    check_env_id(env_id)
    config = new_config(
        env_id,
        config_file=config_file,
        n_timesteps=n_timesteps,
        seed=seed,
        n_envs=n_envs,
        action_mode=action_mode,
        tolerance=tolerance,
        **options,
    )
    config = config.with_env(check_envs(config))
    if init_from is not None:
        from .warm_start import check_init_agent

        config = check_init_agent(init_from, config)
    check_memory(config)
    run_dir = Path(run_dir) if run_dir is not None else Path("runs") / f"{env_id}_seed{config.seed}"
    if run_dir.exists() and not run_dir.is_dir():
        raise FileExistsError(f"{run_dir} is a file, not a run folder")
    check_output_folder(run_dir)
    if run_dir.exists() and any(p.name != LOCK_FILE for p in run_dir.iterdir()):
        with run_lock(run_dir, probe=True):
            pass
        if not stale_run(run_dir):
            raise FileExistsError(
                f"{run_dir} already holds a run (or other files); resume it with "
                f"vcnc-train --resume {run_dir}, or choose another output folder"
            )
        note(
            f"{run_dir} holds a run without an intact checkpoint (it never reached one, or all are damaged): "
            "starting it over"
        )
    return run_dir, config, None


def _prepare_resume(env_id, run_dir, n_timesteps, options: dict):
    """:func:`prepare_run` of a resumed run: its config.yml read back, its newest intact checkpoint found, the
    options it may change applied and its envs built again against the recorded signature."""
    if run_dir is None:
        raise ValueError("resume needs the run folder")
    run_dir = Path(run_dir)
    config = RunConfig.read(run_dir)
    check_writable(run_dir)
    with run_lock(run_dir, probe=True):
        pass
    if env_id is not None and env_id != config.env_id:
        raise ValueError(f"{run_dir} is a run on {config.env_id}, not {env_id}")
    checkpoint = latest_checkpoint(run_dir, config.n_envs)
    if checkpoint is None:
        intact, damaged = scan_checkpoints(run_dir, config.n_envs)
        renamed = set_aside([c[1] for c in intact + damaged])  # every one failed a check: none can be resumed
        aside = f"; the damaged ones are set aside as *.damaged ({len(renamed)} files)" if renamed else ""
        raise FileNotFoundError(
            f"cannot resume: {run_dir / 'checkpoints'} holds no intact checkpoint "
            f"({CHECKPOINT_PREFIX}_<steps>_steps.zip with its vecnormalize .npz); it never reached one or all "
            f"are damaged{aside}: start it again with vcnc-train --env {config.env_id} --output {run_dir}"
        )
    config = config.with_options(**options)
    env = check_envs(config)
    recorded = (config.env or {}).get("signature")
    if recorded is not None:
        check_signature(recorded, env["signature"], what=f"the run in {run_dir}")
    config = config.with_env(env)
    if n_timesteps is not None:
        config = config.with_total(n_timesteps)
    if checkpoint[0] >= config.n_timesteps:
        raise ValueError(
            f"the run has {checkpoint[0]} steps already, its total is {config.n_timesteps}: "
            "pass a larger n_timesteps (--timesteps) to go on"
        )
    return run_dir, config, checkpoint


# -- 2. lock, signals, clean-up ------------------------------------------------------------------------------------
class StopSignal:
    """The signal that asked the run to stop, if any."""

    signum: int | None = None

    @property
    def name(self) -> str | None:
        """ "SIGINT" or "SIGTERM", None before a signal came."""
        return None if self.signum is None else signal.Signals(self.signum).name


@contextmanager
def stop_on_signals(stop: StopSignal):
    """Turn SIGINT and SIGTERM into ``stop.signum`` (main thread only); a second one acts as usual."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}

    def handler(signum, frame):
        stop.signum = signum
        signal.signal(signum, previous[signum])
        print(
            f"\nvcnc-train: {signal.Signals(signum).name} received: saving a checkpoint at the last PPO update "
            "(send it again to quit at once)",
            file=sys.stderr,
            flush=True,
        )

    for s in (signal.SIGINT, signal.SIGTERM):
        previous[s] = signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


@contextmanager
def open_run(run_dir: Path, checkpoint):
    """The run folder made and locked, signals turned into a :class:`StopSignal` (yielded); a new run
    (``checkpoint`` None) that fails before its first checkpoint removes what it wrote (the folder too if it made
    it); a resume that fails before training starts changes nothing."""
    fresh = checkpoint is None
    created = fresh and not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    stop = StopSignal()
    with run_lock(run_dir), stop_on_signals(stop):
        try:
            yield stop
        except BaseException:
            if fresh and not scan_checkpoints(run_dir)[0]:
                clear_new_run(run_dir, created)
            raise


# -- 3. the folder at the session's start ---------------------------------------------------------------------------
def start_folder(run_dir: Path, config: RunConfig) -> int:
    """A new run's folder: what a run that never reached a checkpoint left cleared, config.yml written; 0 steps."""
    if run_dir.exists():
        clear_new_run(run_dir, created=False)
    run_dir.mkdir(parents=True, exist_ok=True)
    write_config(run_dir, config)
    return 0


def roll_back_to(run_dir: Path, config: RunConfig, done: int) -> dict:
    """A resumed run's folder, once its checkpoint at ``done`` steps has loaded: the logs and best/ rolled back to
    it (:func:`vcnc_agents.run_folder.roll_back`, with a :class:`RunWarning` for what was dropped), the damaged or
    unreadable newer checkpoints set aside, the seeds set to ``seed + done`` and config.yml written.

    The monitor files must be opened (for appending) only after this: roll_back replaces them.  Returns
    {"evaluations": n, "episodes": n} dropped.
    """
    from stable_baselines3.common.utils import set_random_seed

    intact, damaged = scan_checkpoints(run_dir, config.n_envs)
    damaged += [c for c in intact if c[0] > done]  # passed over by latest_checkpoint: tensors unreadable
    rolled_back = roll_back(run_dir, config, done, damaged)
    if rolled_back["evaluations"] or rolled_back["episodes"]:
        note(
            f"resuming from {done} steps: dropped {rolled_back['evaluations']} evaluation(s) and "
            f"{rolled_back['episodes']} episode(s) logged after that checkpoint (their training was lost)"
        )
    set_random_seed(config.seed + done)
    write_config(run_dir, config)
    return rolled_back


# -- 4. and 5. the session's record -------------------------------------------------------------------------------
class Session:
    """One session's row of ``summary.json`` and its clock.

    Parameters
    ----------
    run_dir : Path
        The run's folder.
    config : RunConfig
        The run's configuration (n_envs, action repeat).
    done : int
        The run's agent steps at the session's start.
    vec_env : str
        The training envs ("native", "dummy", "subproc").
    rolled_back : dict or None
        What :func:`roll_back_to` dropped (a resumed session).
    clock : optional
        A phase clock (``seconds``, ``shares(wall)``; the lean trainer's): its shares are recorded too.
    """

    def __init__(self, run_dir: Path, config: RunConfig, done: int, *, vec_env: str, rolled_back=None, clock=None):
        self.run_dir, self.start, self.repeat, self.clock = run_dir, done, config.action_repeat, clock
        self.row = {
            "id": f"{done}@{time.time():.0f}",
            "start_timesteps": done,
            "end_timesteps": done,
            "wall_s": 0.0,
            "steps_per_s": 0.0,
            "control_periods_per_s": 0.0,
            "n_envs": config.n_envs,
            "vec_env": vec_env,
        }
        if config.trainer is not None:
            self.row["trainer"] = config.trainer
        self.row["status"] = "running"
        if rolled_back is not None:
            self.row["rolled_back"] = rolled_back
        self.rolled_back = rolled_back
        self.t0 = time.perf_counter()

    def start_clock(self) -> None:
        """The training starts: wall time counts from here (set-up excluded)."""
        self.t0 = time.perf_counter()

    def _rates(self, n: int) -> dict:
        wall = max(time.perf_counter() - self.t0, 1e-9)
        steps = n - self.start
        rates = {"wall_s": wall, "steps_per_s": steps / wall, "control_periods_per_s": steps * self.repeat / wall}
        if self.clock is not None:
            rates["time_shares"] = self.clock.shares(wall)
            rates["phase_s"] = {k: round(v, 3) for k, v in self.clock.seconds.items() if k != "other"}
        return rates

    def checkpointed(self, n: int, best: dict | None) -> None:
        """A checkpoint at ``n`` steps was written: the row and the best evaluation recorded."""
        self.row.update(end_timesteps=n, **self._rates(n))
        record_session(self.run_dir, self.row, best)

    def end(self, n: int, best: dict | None, interrupted: str | None) -> TrainingResult:
        """The session ended at ``n`` steps (finished, or stopped by the signal named ``interrupted``): its last
        record, and the result."""
        self.row.update(
            end_timesteps=n, status=f"interrupted ({interrupted})" if interrupted else "finished", **self._rates(n)
        )
        record_session(self.run_dir, self.row, best)
        return TrainingResult(
            run_dir=self.run_dir,
            timesteps=n,
            session_timesteps=n - self.start,
            wall_s=self.row["wall_s"],
            steps_per_s=self.row["steps_per_s"],
            control_periods_per_s=self.row["control_periods_per_s"],
            best=best,
            interrupted=interrupted,
            rolled_back=self.rolled_back,
        )
