"""``vcnc-train``: train PPO on a VCNC env, or resume a run.

    vcnc-train --env VCNC-Heart-v0                       # runs/VCNC-Heart-v0_seed0
    vcnc-train --env VCNC-Omega-v0 --seed 3 --n-envs 4 --timesteps 200000 --output runs/omega3
    vcnc-train --env VCNC-Heart-v0 --action-mode residual --baseline qft --correction 0.3 --action-repeat 5
    vcnc-train --resume runs/omega3                      # from its newest intact checkpoint
    vcnc-train --resume runs/omega3 --timesteps 400000   # ... to a new total
    vcnc-train --sweep agents/sweeps/omega.yml           # a Ray Tune sweep (runs/sweep_omega), local Ray
    vcnc-train --sweep agents/sweeps/omega.yml --ray-address auto   # ... on an existing Ray cluster
    vcnc-train --env VCNC-Heart-v1 --seeds 5 --output runs/heart   # seeds 0-4: runs/heart/seed0 ... (vcnc_agents.seeds)

Every option, the hyperparameter file and the env arguments are checked
before the run folder is created; a bad one exits with status 2 and a
message.  Ctrl-C (SIGINT) or SIGTERM saves a checkpoint and exits with
status 130 or 143, printing the command that resumes the run.
"""

from __future__ import annotations

import signal
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path

from .arguments import MODE_OPTIONS, action_mode
from .arguments import parser as make_parser

__all__ = ["main"]


@contextmanager
def _print_run_warnings():
    """Show the trainer's RunWarnings as one plain line each on stderr."""
    from .run_warning import RunWarning

    show = warnings.showwarning

    def showwarning(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, RunWarning):
            print(f"vcnc-train: warning: {message}", file=sys.stderr, flush=True)
        else:
            show(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.simplefilter("always", RunWarning)
        warnings.showwarning = showwarning
        yield


def _after_failure(run_dir: Path, checkpoint) -> str:
    """What a failed or aborted session left: a resumable run or nothing."""
    from .run_folder import latest_checkpoint

    if run_dir.is_dir() and latest_checkpoint(run_dir) is not None:
        return f"resume from the last checkpoint with: vcnc-train --resume {run_dir}"
    return f"{run_dir} holds no checkpoint and was cleared: start again with the same command"


def _training_options(args) -> dict:
    """The training options of the command line (:data:`vcnc_agents.run_config.TRAINING_OPTIONS`), None where not
    given."""
    from .run_config import TRAINING_OPTIONS

    return {name: getattr(args, name) for name in TRAINING_OPTIONS}


def _sweep_conflict(args) -> str | None:
    """What is wrong with combining ``--sweep`` with the other options, or None."""
    if args.sweep is None:
        if args.ray_address is not None and args.seeds is None:
            return "--ray-address applies to --sweep FILE or --seeds K"
        return "--jobs applies to --seeds K" if args.jobs is not None and args.seeds is None else None
    if args.seeds is not None:
        return "the sweep file sets every trial's seed; drop --seeds"
    given = [
        f"--{k.replace('_', '-')}"
        for k in (
            "env",
            "resume",
            "timesteps",
            "seed",
            "n_envs",
            "config",
            *MODE_OPTIONS,
            *_training_options(args),
            "threads",
            "tolerance",
            "init_from",
        )
        if getattr(args, k) is not None
    ]
    given += ["--vec-env"] * (args.vec_env != "native") + ["--trainer"] * (args.trainer is not None)
    return f"the sweep file sets every trial's options; drop {', '.join(given)}" if given else None


def _sweep_main(parser, args) -> int:
    """``vcnc-train --sweep FILE``: 0 done (a trial finished), 1 no trial finished, 2 bad options (nothing written)."""
    from .sweep import check_output, import_ray, load_sweep, run_sweep

    with _print_run_warnings():
        try:  # every check, before anything is written
            import_ray()
            spec = load_sweep(args.sweep)
            if args.output is not None:
                check_output(args.output)
            print(f"vcnc-train: sweep {args.sweep}: {spec.n_trials} trials on {spec.env_id}", flush=True)
            result = run_sweep(spec, args.output, ray_address=args.ray_address, verbose=args.verbose)
        except (ImportError, ValueError, FileNotFoundError, FileExistsError, ConnectionError) as exc:
            parser.error(str(exc))
    finished = sum(r["status"] == "finished" for r in result.rows)
    print(f"{len(result.rows)} trials ({finished} finished) in {result.wall_s:.0f} s on {result.where}")
    if result.best is not None:
        b = result.best
        print(f"best: {b['trial']}: max {b['max_um']:.2f} um, RMS {b['rms_um']:.2f} um, score {b['score_um']:.2f} um")
        print(f"retrain it with: {b['command']}")
    print(f"results: {result.sweep_dir / 'sweep_results.md'}, {result.sweep_dir / 'sweep_results.csv'}")
    return 0 if result.best is not None else 1


def _seeds_main(parser, args, argv: list[str]) -> int:
    """``vcnc-train --seeds K``: 0 every seed done, else the first seed's failing exit code; 2 bad options."""
    from .run_config import check_env_id
    from .seeds import run_seeds

    if args.resume is not None:
        parser.error("--seeds starts new runs; resume each seed's folder on its own (--resume DIR)")
    if args.seeds < 1 or (args.jobs is not None and args.jobs < 1):
        parser.error(f"--seeds and --jobs must be positive, got {args.seeds} and {args.jobs}")
    try:
        check_env_id(args.env)
        runs = run_seeds(
            argv,
            args.env,
            0 if args.seed is None else args.seed,
            args.seeds,
            args.output,
            jobs=args.jobs,
            ray_address=args.ray_address,
        )
    except (ValueError, ImportError) as exc:
        parser.error(str(exc))
    return next((r.code for r in runs if r.code != 0), 0)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vcnc-train``: 0 done, 1 the run folder could not be written (disk full, permissions), 2 bad
    options (nothing written), 130/143 stopped by SIGINT/SIGTERM."""
    parser = make_parser()
    args = parser.parse_args(argv)
    conflict = _sweep_conflict(args)
    if conflict is not None:
        parser.error(conflict)
    if args.sweep is not None:
        return _sweep_main(parser, args)
    _check_run_options(parser, args)
    if args.seeds is not None:
        return _seeds_main(parser, args, sys.argv[1:] if argv is None else list(argv))
    tensorboard = False if args.no_tensorboard else None
    with _print_run_warnings():
        run_dir, config, checkpoint, trainer = _prepare(parser, args, tensorboard)
        if args.threads is not None or trainer == "lean":
            import torch

            torch.set_num_threads(args.threads or 1)
        result = _train(args, trainer, run_dir, config, checkpoint, tensorboard)
        if isinstance(result, int):
            return result
    return _report(result)


def _check_run_options(parser, args) -> None:
    """The options of a new or resumed run that need no file (parser.error: exit 2)."""
    if args.resume is None and args.env is None:
        parser.error("give --env ID for a new run, --resume DIR, or --sweep FILE")
    if args.resume is not None:
        if args.output is not None and args.output != args.resume:
            parser.error("--resume DIR is the run folder; --output does not apply")
        fixed = [
            f"--{k.replace('_', '-')}"
            for k in (*MODE_OPTIONS, "n_envs", "seed", "config", "tolerance", "init_from")
            if getattr(args, k) is not None
        ]
        if fixed:
            parser.error(
                f"a resumed run keeps its action mode, n_envs, seed and hyperparameters (see its config.yml); "
                f"drop {', '.join(fixed)}"
            )
    if args.threads is not None and args.threads < 1:
        parser.error(f"--threads must be positive, got {args.threads}")


def _prepare(parser, args, tensorboard):
    """Every check, before anything is written, then the run folder prepared: (run_dir, config, checkpoint,
    trainer)."""
    from .config import DEFAULT_CONFIG
    from .lean_ppo import check_trainer, sb3_only
    from .run_config import check_env_id, check_training_options
    from .run_session import prepare_run

    try:
        options = _training_options(args)
        check_training_options(vec_env=args.vec_env, tensorboard=tensorboard, **options)
        if args.resume is None:
            check_env_id(args.env)
            config_file = args.config if args.config is not None else DEFAULT_CONFIG
            run_dir, config, checkpoint = prepare_run(
                args.env,
                args.output,
                n_timesteps=args.timesteps,
                seed=0 if args.seed is None else args.seed,
                n_envs=args.n_envs,
                config_file=config_file,
                action_mode=action_mode(args, config_file),
                tolerance=args.tolerance,
                init_from=args.init_from,
                **options,
            )
        else:
            run_dir, config, checkpoint = prepare_run(
                args.env, args.resume, resume=True, n_timesteps=args.timesteps, **options
            )
        trainer = check_trainer(
            args.trainer,
            config.env_id,
            config.trainer,
            resumed=args.resume is not None,
            needs_sb3=sb3_only(config, args.vec_env),
        )
        if trainer == "sb3" and checkpoint is None and config.init_from is not None:
            raise ValueError(
                "--init-from: a warm start is the lean trainer's; this run needs SB3's "
                f"({sb3_only(config, args.vec_env) or '--trainer sb3'})"
            )
    except (ValueError, FileNotFoundError, FileExistsError) as exc:
        parser.error(str(exc))
    return run_dir, config, checkpoint, trainer


def _train(args, trainer: str, run_dir, config, checkpoint, tensorboard):
    """The training's result, or the exit code of a failure (its one line printed)."""
    from .run_folder import RunLocked
    from .training import learn

    try:
        if trainer == "lean":
            from .lean_ppo import learn as learn_lean

            return learn_lean(run_dir, config, checkpoint, progress_bar=not args.no_progress, verbose=args.verbose)
        return learn(
            run_dir,
            config,
            checkpoint,
            progress_bar=not args.no_progress,
            tensorboard=tensorboard,
            vec_env=args.vec_env,
            verbose=args.verbose,
        )
    except RunLocked as exc:  # another trainer took the folder since the checks: it is its, untouched here
        print(f"vcnc-train: error: {exc}; this session wrote nothing", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # a second Ctrl-C
        print(f"vcnc-train: stopped at once; {_after_failure(run_dir, checkpoint)}", file=sys.stderr)
        return 130
    except OSError as exc:  # disk full, a folder made read-only during the run: one line, no traceback
        where = f" {exc.filename}" if exc.filename else ""
        print(
            f"vcnc-train: training failed: cannot write{where}: {exc.strerror or exc}; "
            f"{_after_failure(run_dir, checkpoint)}",
            file=sys.stderr,
        )
        return 1
    except Exception:
        print(f"vcnc-train: training failed; {_after_failure(run_dir, checkpoint)}", file=sys.stderr)
        raise


def _report(result) -> int:
    """The session's summary printed; the exit code (128 + the signal of a stopped run)."""
    resume = f"vcnc-train --resume {result.run_dir}"
    if result.interrupted is not None:
        print(
            f"vcnc-train: stopped by {result.interrupted} after {result.session_timesteps} agent steps of this "
            f"session; checkpoint at {result.timesteps} steps saved. Resume with: {resume}",
            file=sys.stderr,
        )
        return 128 + int(getattr(signal, result.interrupted))
    print(
        f"trained {result.session_timesteps} agent steps in {result.wall_s:.1f} s: "
        f"{result.steps_per_s:.0f} steps/s ({result.control_periods_per_s:.0f} control periods/s); "
        f"{result.timesteps} in all"
    )
    if result.best is not None:
        b = result.best
        print(f"best evaluation at {int(b['steps'])} steps: max {b['max_um']:.2f} um, RMS {b['rms_um']:.2f} um")
    agents = [str(result.run_dir / name) for name in ("best", "final") if (result.run_dir / name).is_dir()]
    if result.best is None:
        agents.append(
            "no best/: "
            + ("every evaluation diverged" if (result.run_dir / "evaluations.csv").is_file() else "no evaluation ran")
        )
    print(f"run folder: {result.run_dir}  (agents: {', '.join(agents) or 'none'})")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
