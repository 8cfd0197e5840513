"""``vcnc-train``: train PPO on a VCNC env, or resume a run.

    vcnc-train --env VCNC-Heart-v0                       # runs/VCNC-Heart-v0_seed0
    vcnc-train --env VCNC-Omega-v0 --seed 3 --n-envs 4 --timesteps 200000 --output runs/omega3
    vcnc-train --env VCNC-Heart-v0 --action-mode residual --baseline qft --correction 0.3 --action-repeat 5
    vcnc-train --resume runs/omega3                      # from its newest checkpoint
    vcnc-train --resume runs/omega3 --timesteps 400000   # ... to a new total

Every option is checked before any training starts.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    from vcnc_gym import ENV_IDS

    from .action_modes import ACTION_MODES
    from .config import DEFAULT_CONFIG

    p = argparse.ArgumentParser(prog="vcnc-train", description="Train Stable-Baselines3 PPO on a VCNC env.")
    p.add_argument("--env", metavar="ID", help=f"env id: {', '.join(ENV_IDS)}")
    p.add_argument("--output", metavar="DIR", type=Path, help="run folder (default runs/ENV_seedSEED)")
    p.add_argument("--resume", metavar="DIR", type=Path, help="resume the run in DIR from its newest checkpoint")
    p.add_argument("--timesteps", type=int, metavar="N", help="total agent steps (default: the config entry's)")
    p.add_argument("--seed", type=int, default=0, help="seed of the envs and of PPO (default 0)")
    p.add_argument("--n-envs", type=int, metavar="N", help="parallel training envs (default: the config entry's)")
    p.add_argument("--config", type=Path, default=DEFAULT_CONFIG, metavar="YAML",
                   help="hyperparameters in RL Zoo's format (default: the shipped agents/hyperparams/ppo.yml)")
    g = p.add_argument_group("action mode (default: the config entry's)")
    g.add_argument("--action-mode", choices=sorted(ACTION_MODES),
                   help="; ".join(f"{k}: {v}" for k, v in ACTION_MODES.items()))
    g.add_argument("--baseline", help="residual mode: the baseline corrected (e.g. smc, qft)")
    g.add_argument("--correction", type=float, help="residual mode: largest correction, fraction of u_max")
    g.add_argument("--action-repeat", type=int, metavar="K", help="control periods per agent decision")
    p.add_argument("--checkpoint-freq", type=int, default=50_000, metavar="N", help="agent steps between checkpoints")
    p.add_argument("--eval-freq", type=int, default=20_000, metavar="N",
                   help="agent steps between deterministic evaluations on the nominal plant")
    p.add_argument("--vec-env", choices=("dummy", "subproc"), default="dummy",
                   help="run the envs in this process or one process each")
    p.add_argument("--threads", type=int, metavar="N", help="torch threads (default: torch's)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-tensorboard", action="store_true", help="no TensorBoard logs even if it is installed")
    p.add_argument("-v", "--verbose", action="count", default=0, help="SB3 verbosity and evaluation lines")
    return p


def _action_mode(args, parser):
    from .action_modes import ActionMode
    from .config import action_mode_of, load_hyperparameters

    given = {k: getattr(args, k) for k in ("action_mode", "baseline", "correction", "action_repeat")}
    if all(v is None for v in given.values()):
        return None
    # start from the config entry's mode and change what the options name
    base = action_mode_of(load_hyperparameters(args.env, args.config)).to_dict()
    mode = given["action_mode"] or base["mode"]
    d = {"mode": mode, "action_repeat": given["action_repeat"] or base["action_repeat"]}
    if mode == "residual":
        d["baseline"] = given["baseline"] or base.get("baseline", "smc")
        d["correction"] = given["correction"] if given["correction"] is not None else base.get("correction", 0.2)
    elif given["baseline"] is not None or given["correction"] is not None:
        parser.error("--baseline and --correction apply to --action-mode residual")
    return ActionMode(**d)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vcnc-train``; argument errors exit with status 2 before any training."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.resume is None and args.env is None:
        parser.error("give --env ID for a new run, or --resume DIR")
    if args.resume is not None and args.output is not None and args.output != args.resume:
        parser.error("--resume DIR is the run folder; --output does not apply")
    if args.resume is not None and any(getattr(args, k) is not None for k in
                                       ("action_mode", "baseline", "correction", "action_repeat", "n_envs")):
        parser.error("a resumed run keeps its action mode and n_envs (see its config.yml)")
    if args.threads is not None and args.threads < 1:
        parser.error(f"--threads must be positive, got {args.threads}")

    from .training import check_training_options, learn, prepare_run

    tensorboard = False if args.no_tensorboard else None
    try:  # every check, before anything is trained
        check_training_options(checkpoint_freq=args.checkpoint_freq, eval_freq=args.eval_freq,
                               vec_env=args.vec_env, tensorboard=tensorboard)
        if args.resume is None:
            from .training import check_env_id

            check_env_id(args.env)
            run_dir, config, checkpoint = prepare_run(
                args.env, args.output, n_timesteps=args.timesteps, seed=args.seed, n_envs=args.n_envs,
                config_file=args.config, action_mode=_action_mode(args, parser))
        else:
            run_dir, config, checkpoint = prepare_run(args.env, args.resume, resume=True, n_timesteps=args.timesteps)
    except (ValueError, FileNotFoundError, FileExistsError) as exc:
        parser.error(str(exc))

    if args.threads is not None:
        import torch

        torch.set_num_threads(args.threads)
    result = learn(run_dir, config, checkpoint, checkpoint_freq=args.checkpoint_freq, eval_freq=args.eval_freq,
                   progress_bar=not args.no_progress, tensorboard=tensorboard, vec_env=args.vec_env,
                   verbose=args.verbose)
    print(f"trained {result.session_timesteps} agent steps in {result.wall_s:.1f} s: "
          f"{result.steps_per_s:.0f} steps/s ({result.control_periods_per_s:.0f} control periods/s); "
          f"{result.timesteps} in all")
    if result.best is not None:
        b = result.best
        print(f"best evaluation at {int(b['steps'])} steps: max {b['max_um']:.2f} um, RMS {b['rms_um']:.2f} um")
    print(f"run folder: {result.run_dir}  (agents: {result.run_dir / 'best'}, {result.run_dir / 'final'})")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
