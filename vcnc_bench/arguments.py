"""The options of ``vcnc-bench`` (:func:`bench_parser`) and their checks before anything runs.

:func:`check_arguments` checks the values and combinations before any env is built, :func:`check_writable` the
output paths, and :func:`check_sizes` ``--plants`` and ``--trials`` against this machine's memory once the envs
are built; each exits 2 through the parser with a message naming the option.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from vcnc_gym.envs import ENV_IDS
from vcnc_gym.validation import size

from . import robust
from .options import check_program_options
from .recipes import DEFAULT_IDS

__all__ = [
    "DEFAULT_TRIALS",
    "MAX_TRIALS",
    "bench_parser",
    "check_arguments",
    "check_sizes",
    "check_writable",
    "check_outputs",
]


def bench_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vcnc-bench",
        description="Run every policy on the vcnc-gym envs (nominal plant, one deterministic episode each) "
        "and compare with the source papers' figures.",
    )
    p.add_argument(
        "--env",
        action="append",
        metavar="ID",
        help="env id, repeatable (default: the ids with a shipped agent and one of every other kind, "
        f"{', '.join(DEFAULT_IDS)}; --all: every id; the v0 ids when named)",
    )
    p.add_argument(
        "--all",
        action="store_true",
        help=f"every id ({', '.join(ENV_IDS)}) with every policy that applies, those that learn across "
        "episodes (ILC) included",
    )
    p.add_argument(
        "--jobs",
        type=int,
        metavar="J",
        help="processes that run the envs (default: the cores other processes leave idle, at least 1)",
    )
    p.add_argument(
        "--policy",
        action="append",
        metavar="SPEC",
        help="a baseline name, 'ppo' (the agent shipped for the env) or KIND:ARGUMENT such as "
        "ppo:RUN/best, repeatable (default: every policy that applies to each env's plant)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed passed to env.reset, >= 0 (default 0)")
    p.add_argument(
        "--feedrate",
        type=float,
        metavar="MM_PER_S",
        help="feedrate in mm/s (default: each env's own); with another value the paper's columns stay empty",
    )
    p.add_argument(
        "--plant",
        metavar="NAME",
        help="run every env on this plant instead of its own (a name of vcnc_gym.plants.plant_names(), such as "
        "current_feed_drive: a generalist's machine on the test pieces); the papers' columns stay "
        "empty",
    )
    p.add_argument(
        "--shop-floor",
        action="store_true",
        help="run every env on its plant's shop floor (encoder, noise, delays, the mode, cutting force and "
        "friction: vcnc_gym.plants.shop_floor), such as the G-code test pieces for a shop-floor "
        "generalist; the papers' columns stay empty",
    )
    p.add_argument(
        "--trials",
        type=int,
        metavar="K",
        help="episodes run by a policy that learns across episodes (ILC); the table shows the first "
        "and the last, the JSON every one (default 10; with --plants 1, the last scored); such "
        "policies run by default only with --all",
    )
    p.add_argument(
        "--plants",
        type=int,
        metavar="N",
        help="robust evaluation instead: every policy on the nominal plant, N plants drawn uniformly "
        "from the env's uncertainty box and the box's vertices when it has at most "
        f"{robust.MAX_VERTICES}; median, p95 and worst of max and RMS contour error, cycle time, "
        "divergences",
    )
    p.add_argument(
        "--plant-seed", type=int, default=0, metavar="S", help="seed of the plants drawn by --plants, >= 0 (default 0)"
    )
    p.add_argument(
        "--noise-seeds",
        type=int,
        default=1,
        metavar="K",
        help="with --plants: every plant of an id with a noisy sensor (the shop-floor ids) over K "
        "sensor-noise seeds, their distribution reported and paired in the verdicts (default 1)",
    )
    p.add_argument(
        "--parallel",
        action="store_true",
        help="with --plants: spread each batch of plants over numba's threads (faster on idle cores, "
        "far slower on cores other processes use; default one thread)",
    )
    p.add_argument(
        "--program",
        action="append",
        metavar="PART",
        help="a G-code part program (a file, a test piece of vcnc_gym.gcode.pieces.PIECES, or "
        "'iso230-4': the circular test both ways) run as VCNC-GCode-v1, repeatable; with no --env "
        "only the programs run (vcnc_bench.programs)",
    )
    p.add_argument(
        "--tolerance",
        metavar="MM",
        default=None,
        help="with --program: corner blending tolerance in mm, or 'sharp' (exact stops; default 0.01)",
    )
    p.add_argument(
        "--circle",
        nargs=2,
        type=float,
        metavar=("D_MM", "F_MM_PER_MIN"),
        help="with --program iso230-4: the circle's diameter (mm) and feed (mm/min)",
    )
    p.add_argument("--json", metavar="PATH", type=Path, help="write one record per run to this JSON file")
    p.add_argument(
        "--leaderboard",
        metavar="PAGE",
        type=Path,
        help="add this run's rows to the leaderboard page PAGE (docs/leaderboard.md; its rows are kept "
        "beside it in PAGE's .json), ranked by the normalised score: vcnc_bench.leaderboard",
    )
    p.add_argument(
        "--plots",
        metavar="DIR",
        type=Path,
        help="write ENV_contour.png, ENV_error.png and ENV_deviation.png (the deviation magnified along "
        "the contour's normal, an inset at every corner) per env into this directory",
    )
    p.add_argument(
        "--plot-all",
        action="store_true",
        help="with --plots: every policy in each env's plots (default: the paper's controllers, the "
        "strongest causal one, the agent and the floor)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")
    return p


def check_writable(path: Path, parser, what: str, option: str = "--json") -> None:
    """Fail before any episode runs if ``path`` (a file, or a directory for plots) cannot be written; the message
    names ``option``."""
    if what == "file" and path.is_dir():
        parser.error(f"{option} {path} is a directory; give a file name")
    target = path if what == "directory" else path.parent
    try:
        target.mkdir(parents=True, exist_ok=True)
        probe = target / ".vcnc-bench-write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        parser.error(f"{option}: cannot write the {what} {path}: {exc}")


def check_outputs(args, parser) -> None:
    """``--json``, ``--leaderboard`` and ``--plots`` before any episode runs: each can be written, the leaderboard
    page's files are regular files apart from ``--json`` and its rows are a leaderboard's (a malformed one is
    refused now, not after the run); each message names the option."""
    if args.json is not None:
        check_writable(args.json, parser, "file", "--json")
    if args.leaderboard is not None:
        from .leaderboard import board_rows, page_files

        try:
            files = page_files(args.leaderboard)
            board_rows(args.leaderboard)
        except ValueError as exc:
            parser.error(f"--leaderboard {exc}")
        if args.json is not None and args.json.resolve() in {f.resolve() for f in files}:
            parser.error(
                f"--json {args.json} is one of the leaderboard's files ({', '.join(map(str, files))}): the run would "
                "write over it; give --json another name"
            )
        check_writable(args.leaderboard, parser, "file", "--leaderboard")
    if args.plots is not None:
        check_writable(args.plots, parser, "directory", "--plots")


#: Most trials (--trials) of a policy that learns across episodes (ours): such controllers converge within tens
#: of trials, and 10 000 trials of one episode each are hours of wall time at the bench's ~1 s per episode.
MAX_TRIALS = 10_000

#: Bytes a single episode's traces take per decision step (vcnc_gym.evaluation.run_episode: time, contour error,
#: position, reference and command, 8 float64); the bench keeps every trial's.
TRACE_BYTES_PER_STEP = 64


def _check_plants(args, env) -> None:
    """The runs of ``--plants N`` (and ``--noise-seeds K`` on a noisy sensor) on ``env`` against this machine's
    memory: the nominal plant, N samples and the box's vertices, each K times; the message counts them."""
    plant = env.unwrapped.plant
    box = getattr(plant, "box", None)
    d = box()[0].size if box is not None else 0
    vertices = 2**d if 0 < d and 2**d <= robust.MAX_VERTICES else 0
    plants = f"the nominal one, {args.plants:,} sampled and {vertices} vertices"
    if not robust.noisy(plant):
        robust.check_plants(1 + args.plants + vertices, env, f"the plants of --plants {args.plants} ({plants})")
        return
    robust.check_plants(
        (1 + args.plants + vertices) * args.noise_seeds,
        env,
        f"the runs of --plants {args.plants} x --noise-seeds {args.noise_seeds} (the plants: {plants}; each over "
        f"{args.noise_seeds:,} noise seeds)",
    )


def check_sizes(args, envs: dict, parser) -> None:
    """--plants and --trials against this machine's memory and MAX_TRIALS, before any episode runs."""
    try:
        if args.plants is not None:
            for env in envs.values():
                _check_plants(args, env)
        if args.trials is not None:
            steps = max(int(env.unwrapped.episode_steps) for env in envs.values())
            size(
                "--trials",
                args.trials,
                ceiling=MAX_TRIALS,
                why="a learning controller converges within tens of trials; 10 000 episodes are hours",
            )
            if args.plants is None:
                size(
                    "--trials",
                    args.trials,
                    bytes_each=2 * steps * TRACE_BYTES_PER_STEP,
                    why=f"every trial's traces are kept, {steps} steps of the longest env's episode (twice, "
                    "for one that runs to its time limit)",
                )
    except ValueError as exc:
        parser.error(str(exc))


#: Trials of a policy that learns across episodes (ILC) when it runs and ``--trials`` is not given.
DEFAULT_TRIALS = 10


def check_arguments(args, parser) -> None:
    """The options' values and combinations, before anything is built."""
    if args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    if args.trials is not None and args.trials < 1:
        parser.error(f"--trials must be >= 1, got {args.trials}")
    if args.plants is not None and args.plants < 1:
        parser.error(f"--plants must be >= 1, got {args.plants}")
    if args.plant_seed < 0:
        parser.error(f"--plant-seed must be >= 0, got {args.plant_seed}")
    if args.noise_seeds < 1:
        parser.error(f"--noise-seeds must be >= 1, got {args.noise_seeds}")
    if args.noise_seeds > 1 and args.plants is None:
        parser.error("--noise-seeds K runs every plant of --plants N over K sensor-noise seeds: add --plants N")
    if args.jobs is not None and args.jobs < 1:
        parser.error(f"--jobs must be >= 1, got {args.jobs}")
    if args.parallel and args.plants is None:
        parser.error(
            "--parallel spreads the batch of --plants N over threads; without --plants each episode "
            "runs on one env and there is nothing to spread: add --plants N or drop --parallel"
        )
    if args.all and (args.env or args.program):
        parser.error("--all runs every id with every policy; it does not combine with --env or --program")
    if args.program and args.feedrate is not None:
        parser.error("--feedrate does not apply to --program: a program's F words set its feeds")
    try:
        check_program_options(args)
    except ValueError as exc:
        parser.error(str(exc))
