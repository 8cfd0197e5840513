"""The command line of ``vcnc-train``: its parser and the action mode its options ask for.

One home for both, read by :mod:`vcnc_agents.cli` (the command) and :mod:`vcnc_agents.sweep` (each trial runs what the
parser makes of its command line), so that neither imports the other.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .action_modes import RESIDUAL_OPTIONS

__all__ = ["parser", "action_mode", "MODE_OPTIONS"]

MODE_OPTIONS = ("action_mode", "action_repeat", *RESIDUAL_OPTIONS)


def parser() -> argparse.ArgumentParser:
    from vcnc_gym import ENV_IDS

    from .action_modes import ACTION_MODES
    from .run_config import OPTION_FIELDS

    p = argparse.ArgumentParser(prog="vcnc-train", description="Train Stable-Baselines3 PPO on a VCNC env.")
    p.add_argument("--env", metavar="ID", help=f"env id: {', '.join(ENV_IDS)}")
    p.add_argument("--output", metavar="DIR", type=Path, help="run folder (default runs/ENV_seedSEED)")
    p.add_argument("--resume", metavar="DIR", type=Path, help="resume the run in DIR from its newest intact checkpoint")
    p.add_argument(
        "--sweep",
        metavar="FILE",
        type=Path,
        help="run the Ray Tune sweep of a sweep file (agents/sweeps/README.md); --output: the sweep's "
        "folder (default runs/sweep_NAME); needs pip install 'vcnc-gym[sweep]'",
    )
    p.add_argument(
        "--ray-address",
        metavar="ADDR",
        help="with --sweep or --seeds: the address of an existing Ray cluster (auto, HOST:PORT, "
        "ray://HOST:10001); default: --sweep a local Ray sized to this machine, --seeds local processes",
    )
    p.add_argument(
        "--seeds",
        type=int,
        metavar="K",
        help="train K seeds (--seed S, S+1, ..., default from 0) with the same options, one run folder "
        "each (OUTPUT/seedS, default runs/ENV_seedS), on --jobs local processes (vcnc_agents.seeds)",
    )
    p.add_argument(
        "--jobs",
        type=int,
        metavar="J",
        help="with --seeds: seeds trained at a time (default: the idle cores, at least 1)",
    )
    p.add_argument(
        "--timesteps",
        type=int,
        metavar="N",
        help="total agent steps, rounded up to whole PPO rollouts (default: the config entry's)",
    )
    p.add_argument("--seed", type=int, help="seed of the envs and of PPO, in [0, 2**32 - 1] (default 0)")
    p.add_argument("--n-envs", type=int, metavar="N", help="parallel training envs (default: the config entry's)")
    p.add_argument(
        "--config",
        type=Path,
        metavar="YAML",
        help="hyperparameters in RL Zoo's format (default: the shipped agents/hyperparams/ppo.yml)",
    )
    g = p.add_argument_group("action mode (default: the config entry's)")
    g.add_argument(
        "--action-mode", choices=sorted(ACTION_MODES), help="; ".join(f"{k}: {v}" for k, v in ACTION_MODES.items())
    )
    g.add_argument("--baseline", help="residual mode: the baseline corrected (e.g. smc, qft)")
    g.add_argument("--correction", type=float, help="residual mode: largest correction, fraction of u_max")
    g.add_argument("--action-repeat", type=int, metavar="K", help="control periods per agent decision (>= 1)")
    g.add_argument(
        "--history",
        type=int,
        metavar="K",
        help="residual mode: past decisions the agent remembers (vcnc_gym.envs.history; 0: none)",
    )
    g.add_argument(
        "--peak-weight",
        type=float,
        metavar="W",
        help="residual mode, training: the episode's largest contour error priced as W decisions of the "
        "reward (vcnc_agents.action_modes.PeakPrice; 0: none)",
    )
    g.add_argument(
        "--dial-rate",
        type=float,
        metavar="R",
        help="residual mode on a feed-override id: the agent's dial (-1 to 1) moves at most R per second "
        "(vcnc_agents.action_modes.DialSlew; 0: at once)",
    )
    p.add_argument(
        "--init-from",
        metavar="AGENT",
        help="start a new run from a trained agent's weights and normalisation (an agent folder, RUN/final "
        "or RUN/best; with --seeds, {seed} is each seed's number; the lean trainer; "
        "vcnc_agents.warm_start)",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        metavar="MM",
        help="the tolerance task: the contour tolerance T in mm (FeedOverrideEnv's tolerance: the reward is "
        "the cycle time and the excess over T; set in the entry's env_kwargs; a feed-override id)",
    )
    for name, f in OPTION_FIELDS.items():  # the training options: one field of RunConfig each
        p.add_argument(
            f"--{name.replace('_', '-')}",
            type=int,
            metavar="N",
            help=f"{f.metadata['help']} (default {f.metadata['default']}; resume: the run's)",
        )
    p.add_argument(
        "--vec-env",
        choices=("native", "dummy", "subproc"),
        default="native",
        help="native: the vector env steps every env in one compiled call (default); dummy: SB3's "
        "DummyVecEnv, one env after another; subproc: one process per env (dummy and subproc: SB3's "
        "trainer)",
    )
    p.add_argument("--threads", type=int, metavar="N", help="torch threads (default: torch's; the lean trainer: 1)")
    p.add_argument(
        "--trainer",
        choices=("sb3", "lean"),
        help="lean (default): Stable-Baselines3's PPO and agent files without SB3's per-step work, over "
        "the native vector env where the id has one (vcnc_agents.lean_ppo; no TensorBoard logs: "
        "evaluations.csv and the monitor files); sb3: Stable-Baselines3's own trainer (the default "
        "where the run needs it: --vec-env dummy/subproc, a policy other than MlpPolicy, use_sde); "
        "--resume: the run's",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--no-tensorboard", action="store_true", help="no TensorBoard logs even if it is installed (SB3's trainer)"
    )
    p.add_argument("-v", "--verbose", action="count", default=0, help="SB3 verbosity and evaluation lines")
    return p


def action_mode(args, config_file):
    """The action mode the options ask for (None: the entry's); ValueError for a bad combination."""
    from .action_modes import ActionMode
    from .config import action_mode_of, load_hyperparameters

    given = {k: getattr(args, k) for k in MODE_OPTIONS}
    if all(v is None for v in given.values()):
        return None
    # start from the config entry's mode and change what the options name
    base = action_mode_of(load_hyperparameters(args.env, config_file))
    mode = given["action_mode"] or base.mode
    d = {
        "mode": mode,
        "action_repeat": given["action_repeat"] if given["action_repeat"] is not None else base.action_repeat,
    }
    if mode == "residual":
        d["baseline"] = given["baseline"] or base.baseline or "smc"
        if d["baseline"] == base.baseline:  # the entry's baseline: its arguments too
            d["baseline_params"] = dict(base.baseline_params)
        elif base.baseline_params:
            from .run_warning import note

            note(
                f"--baseline {d['baseline']}: the entry's arguments of {base.baseline} "
                f"({', '.join(sorted(base.baseline_params))}) do not apply to it and are dropped"
            )
        d["correction"] = next(c for c in (given["correction"], base.correction, 0.2) if c is not None)
        for k in ("history", "peak_weight", "dial_rate"):
            d[k] = given[k] if given[k] is not None else getattr(base, k)
    elif any(given[k] is not None for k in RESIDUAL_OPTIONS):
        raise ValueError(
            "--baseline, --correction, --history, --peak-weight and --dial-rate apply to --action-mode residual"
        )
    return ActionMode(**d)
