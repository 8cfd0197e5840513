"""``vcnc-bench``: every policy on every env of the suite, in one table, JSON and plots.

Runs each policy for one deterministic episode on the nominal plant of each
env and prints max, mean and RMS contour error (um) with the paper's
figures beside ours (:mod:`vcnc_bench.papers`)::

    vcnc-bench                                  # the default table: DEFAULT_IDS, every policy that applies
    vcnc-bench --all                            # every id, every policy (ILC's trials included)
    vcnc-bench --env VCNC-Omega-v0 --policy qft --policy smc
    vcnc-bench --json bench.json --plots bench-plots

The default table (:data:`DEFAULT_IDS`) is the ids that carry a verdict (a
shipped agent) and Yadav et al. (2020)'s step response; the policies that learn across episodes (ILC)
run only with ``--all`` or when named.  The run's first lines say what the
default left out.  The envs are spread over ``--jobs`` processes (default:
the cores other processes leave idle; :mod:`vcnc_bench.runner`), one
progress line per finished env on stderr.  ``--json`` writes
``{"settings", "plan" (every env's policy labels), "records" (one per
episode, and the ISO 230-4 rows with "table")}``; ``python -m
vcnc_bench.check FILE`` says whether it is complete.  ``--plots`` writes
ENV_contour.png, ENV_error.png and ENV_deviation.png per contouring env,
with the runs :func:`vcnc_bench.plots.shown_labels` chooses (``--plot-all``:
every one), and the reports' plots.

With ``--plants N`` every policy runs instead on N plants drawn uniformly
from the env's uncertainty box (``--plant-seed S``, default 0), plus the
box's vertices when it has at most 64 (Jahanpour et al.'s feed drive: 64,
Yadav et al.'s and Purtojo et al.'s tables: 16; Simba et al.'s drive has 256: none), all plants of
an env in one batch: one call of the env's compiled vector kernel and one
batched ``predict`` per step (the positioning env, which has no vector env:
a batch of single envs; :mod:`vcnc_bench.robust`).  The table gives per env
and policy the nominal plant's max and RMS contour error (the ordinary
table's figure), their median and 95th percentile over the N samples and
their worst over samples and vertices (a diverged plant counts as an
infinite error), the nominal, median and worst cycle time, and how many
plants diverged or, without diverging, did not complete::

    vcnc-bench --plants 100                     # every policy of the default table's ids: 100 plants (+ vertices)
    vcnc-bench --env VCNC-Omega-v1 --plants 100 --plant-seed 1 --json robust.json --plots robust-plots

Every env's records also get the normalised contour score (:mod:`vcnc_bench.score`: 0 = the reference PD
``pd-ref``, 1 = the non-causal floor; on the nominal plant, and per plant where the floor ran on them): the bench
adds ``pd-ref`` to an env's runs, and the floor's replay on the nominal plant where the floor is not among them.
Where a ``ppo`` agent ran, its **verdict** against the strongest causal controller (per figure, max and RMS) is
printed with the IQMs over the sampled plants, the paired-bootstrap 95 % interval of their difference and
P(X < Y) (:mod:`vcnc_bench.verdicts`): "wins" only when the interval lies below zero.  ``--noise-seeds K`` runs
every plant of an id with a noisy sensor (the shop-floor ids) over K sensor-noise seeds and reports their
distribution; the verdicts then pair plants and noise seeds::

    vcnc-bench --env VCNC-HeartShop-v1 --plants 20 --noise-seeds 5 --policy ff-pid --policy ppo

There ``--json`` writes ``{"settings": {...}, "robust": [one record per env
and policy, with every plant's figures], "verdicts": [...]}`` and ``--plots`` one
``ENV_robust.png`` per env (box plots of max and RMS over the samples, the
vertices and the nominal plant marked, log scale).  A policy that learns
across episodes (ILC) runs its first trial unless ``--trials K`` is given
(then K trials per plant, the last scored).  The kernel runs on one thread
unless ``--parallel`` (on cores other processes share, a parallel step
waits for both threads and is many times slower).  The papers' reports,
which need the single episodes, are not printed.

A policy is named by a spec (:mod:`vcnc_bench.policies`): a bare name such
as ``qft``, or ``KIND:ARGUMENT`` such as ``ppo:runs/x/best``.  The kinds
are found through entry points (the suite's own two in
:mod:`vcnc_bench.kinds`, another package's alike); this module names none.
By default each env runs the policies that apply to its plant (every kind's
``defaults``).

This package is the top layer: it imports ``vcnc_gym``, ``vcnc_baselines`` and
``vcnc_agents`` (through its kinds and the papers' reports), and nothing imports
it back (``tests/test_layers.py``).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import threading
import time
from pathlib import Path


import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs import ENV_IDS
from vcnc_gym.envs.registry import LEGACY
from vcnc_gym.evaluation import EpisodeResult, plot_trials
from vcnc_gym.validation import size

from .options import check_program_options, program_tolerance
from .papers import paper_figures
from . import programs, robust, score, verdicts
from .plots import shown_labels
from .headroom import NON_CAUSAL, headroom
from .provenance import provenance
from .policies import (
    BenchContext,
    check_policy_spec,
    default_specs,
    expand_spec,
    policy_choices,
    policy_kinds,
    policy_label,
    resolve_policy,
    split_spec,
)
from .runner import BuildError, EnvRecipe, EnvRuns, idle_cores, label_of, run_table

#: The v0 ids, kept for agents trained on them: benchmarked when named.
LEGACY_IDS = tuple(e.id for e in LEGACY)

#: The default table (``vcnc-bench`` with no ``--env``): the ids that carry a verdict, those with a shipped agent
#: (``agents/trained``) to be set against the strongest causal controller and the floor, and Yadav et al. (2020)'s
#: step response (the fourth paper's reproduction; a second).  Between them they hold every paper's machine, the
#: shop floor and the feed override.  ``--all`` runs every id of ``ENV_IDS``: the papers' tasks without an agent
#: (the S-curve omega, the look-ahead heart), the G-code ids (the ISO 230-4 and NAS 979 test pieces, a part
#: program) and the random contour.  Grouped by machine (Jahanpour et al. (2014)'s drive, Simba et al.'s, Purtojo
#: et al.'s table, Yadav et al. (2020)'s axis); the worker pool takes the longest first.
DEFAULT_IDS = (
    "VCNC-Heart-v1",
    "VCNC-HeartShop-v1",
    "VCNC-OmegaLookahead-v1",
    "VCNC-OmegaLookaheadShop-v1",
    "VCNC-OmegaOverride-v1",
    "VCNC-Corners-v1",
    "VCNC-CornersSmooth-v1",
    "VCNC-CornersSmoothShop-v1",
    "VCNC-Circle-v1",
    "VCNC-CircleShop-v1",
    "VCNC-Step-v0",
)

__all__ = ["DEFAULT_IDS", "format_table", "main"]


# -- the table -------------------------------------------------------------------------
_COLUMNS = [
    # header, width, record key, format
    ("env", 14, "env", "{}"),
    ("policy", 10, "policy", "{}"),
    ("max_um", 10, "max_contour_error_um", "{:.2f}"),
    ("mean_um", 10, "mean_contour_error_um", "{:.2f}"),
    ("rms_um", 10, "rms_contour_error_um", "{:.2f}"),
    ("paper_max_um", 12, "paper_max_contour_error_um", "{:.2f}"),
    ("ours/paper", 10, "ratio_to_paper", "{:.2f}"),
    ("cycle_s", 7, "cycle_time_s", "{:.4f}"),
    ("steps", 7, "episode_steps", "{:d}"),
    ("wall_s", 7, "wall_s", "{:.2f}"),
    ("diverged", 8, "diverged", "{}"),
    ("complete", 8, "completed", "{}"),
]


def _cell(value, fmt: str) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    return fmt.format(value)


def format_table(records: list[dict], columns: list | None = None) -> str:
    """The records as a fixed-width table in the shape of Jahanpour et al.'s Table 4 (errors in um); ``columns``
    (header, width, record key, format) default to the ordinary bench's."""
    columns = [
        (h, max([w] + [len(str(r.get(key))) for r in records]) if key in ("env", "policy") else w, key, fmt)
        for h, w, key, fmt in (columns or _COLUMNS)
    ]
    lines = [" ".join(f"{h:>{w}}" if i > 1 else f"{h:<{w}}" for i, (h, w, _, _) in enumerate(columns))]
    lines.append("-" * len(lines[0]))
    previous_env = None
    for rec in records:
        if previous_env is not None and rec["env"] != previous_env:
            lines.append("")
        previous_env = rec["env"]
        cells = []
        for i, (_, w, key, fmt) in enumerate(columns):
            c = _cell(rec.get(key), fmt)
            cells.append(f"{c:>{w}}" if i > 1 else f"{c:<{w}}")
        lines.append(" ".join(cells))
    return "\n".join(lines)


def _record(
    env_id: str,
    label: str,
    result: EpisodeResult,
    compare: bool = True,
    trial: int | None = None,
    kind: str | None = None,
) -> dict:
    paper = paper_figures(env_id, label).get("max_contour_error_um") if compare else None
    ratio = result.max_contour_error_um / paper if paper else None
    return {
        "env": env_id,
        "policy": label if trial is None else f"{label} (trial {trial})",
        "kind": kind,
        "trial": trial,
        "max_contour_error_um": result.max_contour_error_um,
        "mean_contour_error_um": result.mean_contour_error_um,
        "rms_contour_error_um": result.rms_contour_error_um,
        "paper_max_contour_error_um": paper,
        "ratio_to_paper": ratio,
        "episode_steps": result.episode_steps,
        "wall_s": result.wall_s,
        "diverged": result.diverged,
        "completed": result.completed,
        "cycle_time_s": None if math.isnan(result.cycle_time_s) else result.cycle_time_s,
        "max_tracking_error_um": result.max_tracking_error_um,
    }


def _json_safe(rec):
    """``rec`` with every non-finite float (at any depth) as None: strict JSON."""
    if isinstance(rec, dict):
        return {k: _json_safe(v) for k, v in rec.items()}
    if isinstance(rec, (list, tuple)):
        return [_json_safe(v) for v in rec]
    return None if isinstance(rec, float) and not math.isfinite(rec) else rec


# -- command line -------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
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


def _env_kwargs(args) -> dict:
    """The arguments every env is made with: ``feedrate``, ``plant`` and ``shop_floor`` when given."""
    kwargs = {} if args.feedrate is None else {"feedrate": args.feedrate}
    if args.plant is not None:
        kwargs["plant"] = args.plant
    if args.shop_floor:
        kwargs["shop_floor"] = True
    return kwargs


def _unique(items):
    return list(dict.fromkeys(items))


def _check_writable(path: Path, parser, what: str) -> None:
    """Fail before any episode runs if ``path`` (a file, or a directory for plots) cannot be written."""
    target = path if what == "directory" else path.parent
    try:
        target.mkdir(parents=True, exist_ok=True)
        probe = target / ".vcnc-bench-write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        parser.error(f"cannot write the {what} {path}: {exc}")
    if what == "file" and path.is_dir():
        parser.error(f"--json {path} is a directory; give a file name")


#: Most trials (--trials) of a policy that learns across episodes (ours): such controllers converge within tens
#: of trials, and 10 000 trials of one episode each are hours of wall time at the bench's ~1 s per episode.
MAX_TRIALS = 10_000

#: Bytes a single episode's traces take per decision step (vcnc_gym.evaluation.run_episode: time, contour error,
#: position, reference and command, 8 float64); the bench keeps every trial's.
TRACE_BYTES_PER_STEP = 64


def _check_sizes(args, envs: dict, parser) -> None:
    """--plants and --trials against this machine's memory and MAX_TRIALS, before any episode runs."""
    try:
        if args.plants is not None:
            for env in envs.values():
                copies = args.noise_seeds if robust.noisy(env.unwrapped.plant) else 1
                robust.check_plants(
                    (args.plants + 1) * copies, env, "--plants" if copies == 1 else "--plants x --noise-seeds"
                )
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


def _check_arguments(args, parser) -> None:
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


def _env_ids(args, parser) -> list[str]:
    """The ids run: those named, else every id (``--all``) or :data:`DEFAULT_IDS` (none with only ``--program``)."""
    if args.env:
        env_ids = _unique(args.env)
    elif args.program:
        env_ids = []
    else:
        env_ids = list(ENV_IDS if args.all else DEFAULT_IDS)
    unknown = [e for e in env_ids if e not in ENV_IDS + LEGACY_IDS]
    if unknown:
        parser.error(f"unknown env id(s) {', '.join(map(repr, unknown))}; valid ids are {', '.join(ENV_IDS)}")
    return env_ids


def _recipes(args, parser) -> list[EnvRecipe]:
    """One :class:`~vcnc_bench.runner.EnvRecipe` per env of the table: its id and arguments, the policies named by
    ``--policy`` (none: the defaults of every kind; those that learn across episodes and the kinds' extras only
    with ``--all``)."""
    for spec in _unique(args.policy or []):
        try:
            check_policy_spec(spec)
        except ValueError as exc:
            parser.error(str(exc))
    try:
        specs = tuple(_unique(m for spec in args.policy or [] for m in expand_spec(spec)))
    except (ValueError, OSError, KeyError) as exc:
        parser.error(f"--policy: {exc}")
    everything = bool(args.all)
    kwargs = _env_kwargs(args)
    recipes = [EnvRecipe(e, e, kwargs, specs, everything) for e in _env_ids(args, parser)]
    if args.program:
        try:
            tolerance = program_tolerance(args.tolerance)
            pieces = programs.expand_programs(args.program, args.circle)
        except ValueError as exc:
            parser.error(str(exc))
        recipes += [
            EnvRecipe(key, env_id, kw, specs, everything)
            for key, env_id, kw in programs.program_recipes(
                pieces, tolerance, plant=args.plant, shop_floor=args.shop_floor
            )
        ]
    return recipes


def _build_envs(recipes: list[EnvRecipe], parser, built: dict | None = None) -> dict:
    """{key: env} of the recipes (those in ``built`` taken from it); a bad argument (``--plant``, ``--feedrate``, a
    program) exits 2 naming the env."""
    envs = {}
    for r in recipes:
        if built is not None and r.key in built:
            envs[r.key] = built[r.key]
            continue
        try:
            envs[r.key] = r.make()
        except (ValueError, TypeError) as exc:
            parser.error(f"{r.key}: {exc}")
    return envs


def _build_quietly(recipes: list[EnvRecipe], built: dict) -> None:
    """Build the recipes' envs into ``built``, stopping at the first that fails (:func:`_build_envs` then says
    why, if the workers did not)."""
    for r in recipes:
        try:
            built[r.key] = r.make()
        except Exception:  # noqa: BLE001  (reported by _build_envs on the main thread)
            return


#: The default table's envs, the longest run first (as measured on 2 cores: the hearts about 45 s each, the corners
#: 35, the S-curve omegas 15, the step response 15 with Yadav et al. (2020)'s Table 2, the circles 10, the
#: override 4): the pool's order when the workers build the envs (:func:`_cost`), so that no long env starts last
#: while the other core idles.
LONGEST_FIRST = (
    "VCNC-Heart-v1",
    "VCNC-HeartShop-v1",
    "VCNC-CornersSmoothShop-v1",
    "VCNC-CornersSmooth-v1",
    "VCNC-Corners-v1",
    "VCNC-OmegaLookaheadShop-v1",
    "VCNC-Step-v0",
    "VCNC-OmegaLookahead-v1",
    "VCNC-Circle-v1",
    "VCNC-CircleShop-v1",
    "VCNC-OmegaOverride-v1",
)


def _cost(envs: dict | None):
    """A recipe's run time estimate for the pool's order: its episode steps; without the envs, the default table's
    measured order (:data:`LONGEST_FIRST`), an env outside it first."""
    if envs is None:
        return lambda r: float(-LONGEST_FIRST.index(r.key)) if r.key in LONGEST_FIRST else 1.0
    return lambda r: float(getattr(envs[r.key].unwrapped, "episode_steps", 0))


def _print_plan(args, recipes: list[EnvRecipe], jobs: int) -> None:
    """The run's first lines: what runs, on how many processes, and what the default leaves out."""
    keys = [r.key for r in recipes]
    policies = "the policies named" if args.policy else "every policy that applies"
    print(
        f"vcnc-bench: {policies} on {len(keys)} env(s), one deterministic episode each on the nominal plant "
        f"(seed {args.seed}), on {jobs} process(es) (--jobs)",
        flush=True,
    )
    if not (args.env or args.program or args.all):
        left = [e for e in ENV_IDS if e not in DEFAULT_IDS]
        print(
            f"  the default table: the ids with a shipped agent and Yadav et al. (2020)'s step response; left out: "
            f"{', '.join(left)} (--all runs every id, --env ID one)",
            flush=True,
        )
    if not (args.all or args.policy):
        print(
            "  left out: the policies that learn across episodes (ILC, 10 trials each) and those whose episode "
            "costs minutes (mpc, mpcc: a QP per period in Python); --all, or --policy NAME",
            flush=True,
        )
    print(
        "  more: --plants N (the uncertainty box: median and worst over N plants), --program PART (your G-code), "
        "--help",
        flush=True,
    )


def _progress(wall0: float):
    """One line per finished env on stderr: its policies, its own wall time and the run's so far."""

    def line(result: EnvRuns, done: int, total: int) -> None:
        print(
            f"  [{done:>{len(str(total))}}/{total}] {result.key}: {len(result.runs)} policies in "
            f"{result.wall_s:.1f} s (run so far {time.perf_counter() - wall0:.0f} s)",
            file=sys.stderr,
            flush=True,
        )

    return line


def _run(args, recipes: list[EnvRecipe], envs: dict | None, parser, jobs: int, wall0: float) -> dict:
    """{key: EnvRuns} of every recipe; an env or a policy that cannot be built exits 2 naming it."""
    try:
        return run_table(
            recipes,
            seed=args.seed,
            trials=args.trials or DEFAULT_TRIALS,
            jobs=jobs,
            envs=envs,
            cost=_cost(envs),
            on_env_done=None if args.no_progress else _progress(wall0),
            plots=args.plots,
            plot_all=args.plot_all,
            prepare=True,
        )
    except BuildError as exc:
        parser.error(str(exc))


def _context(args, envs: dict, results: dict) -> BenchContext:
    """The reports' view of the run: every policy's last trial, every trial of those that learn across episodes,
    and the labels each env's plots show."""
    ctx = BenchContext(env_ids=list(results), envs=envs, plots=args.plots, trials=args.trials or DEFAULT_TRIALS)
    for key, env_runs in results.items():
        for run in env_runs.runs:
            ctx.results.setdefault(key, {})[run.label] = run.trials[-1]
            if len(run.trials) > 1:
                ctx.trials_of[(key, run.label)] = run.trials
        ctx.shown[key] = shown_labels(key, env_runs.runs, everything=args.plot_all)
        ctx.plots_written.extend(env_runs.plots)
        ctx.prepared[key] = dict(env_runs.prepared)
    return ctx


def _table_records(args, ctx: BenchContext, results: dict) -> list[dict]:
    """One record per episode (every trial), in the table's order."""
    compare = args.feedrate is None and args.plant is None and not args.shop_floor
    records = []
    for key, env_runs in results.items():
        for run in env_runs.runs:
            k = len(run.trials)
            for trial, result in enumerate(run.trials, start=1):
                records.append(
                    _record(
                        key,
                        run.label,
                        result,
                        compare and trial == k,
                        trial if k > 1 else None,
                        split_spec(run.spec)[0],
                    )
                )
    ctx.records = records
    return records


def _print_table(args, ctx: BenchContext, records: list[dict]) -> None:
    feeds = sorted(
        {
            env.unwrapped.feedrate_profile.feedrate
            for env in ctx.envs.values()
            if hasattr(env.unwrapped, "feedrate_profile")
        }
    )
    print()
    print(
        f"Error of every policy on the nominal plant, one deterministic episode each (seed {args.seed}"
        + (f"; policies that learn across episodes: {ctx.trials} trials, first and last shown" if ctx.trials_of else "")
        + ")"
        + (f"; contours at {', '.join(f'{f:g}' for f in feeds)} mm/s" if feeds else "")
    )
    print(
        "max/mean/rms_um: the contour error (the distance from the table to the whole contour) on contouring envs, "
        "the distance to the set-point on positioning envs; paper_max_um: the source paper's figure, ours/paper "
        "their ratio; cycle_s: when the table reached the contour's end; wall_s: the episode's wall time; "
        "'(non-causal)': a floor that reads the exact plant, never a controller"
    )
    shown = [r for r in records if r.get("trial") in (None, 1, ctx.trials)]
    print(format_table(shown))
    incomplete = [f"{r['env']} {r['policy']}" for r in shown if not r["completed"]]
    if incomplete:
        print(
            f"\nNOT COMPLETE (diverged, or cut short before the end of its contour or step-response window; "
            f"its errors cover only the part it ran): {', '.join(incomplete)}"
        )


def _print_headroom(results: dict, records: list[dict]) -> None:
    """Per env with a floor: the strongest causal classical controller (agents aside: the headroom is the room
    they can still win), the floor, and their ratio (:mod:`vcnc_bench.headroom`); also as JSON rows."""
    rows = []
    for key, env_runs in results.items():
        classical = {r.label: r.trials[-1] for r in env_runs.runs if split_spec(r.spec)[0] != "ppo"}
        h = headroom(classical)
        if h is not None:
            rows.append((key, h))
    if not rows:
        return
    print(
        "\nHeadroom: the strongest causal classical controller's max contour error over the non-causal floor's "
        "(the room a learned controller can still win)"
    )
    width = max(len(k) for k, _ in rows)
    for key, h in rows:
        print(
            f"  {key:<{width}} {h.strongest:>14} {h.strongest_max_um:10.4g} um / floor {h.floor_max_um:10.4g} um"
            f" = {h.ratio:.3f}"
        )
        records.append(
            {
                "table": "headroom",
                "env": key,
                "strongest": h.strongest,
                "strongest_max_um": h.strongest_max_um,
                "floor_max_um": h.floor_max_um,
                "headroom": h.ratio,
            }
        )


def _print_reports(ctx: BenchContext, records: list[dict]) -> None:
    """The kinds' reports (the papers' own tables) and the ISO 230-4 figures of every full circle."""
    for kind in policy_kinds().values():
        if kind.report is not None:
            lines = kind.report(ctx)
            if lines:
                print()
                print("\n".join(lines))
    circular_lines, circular_rows = programs.circular_report(ctx.results, ctx.envs)
    if circular_lines:
        print()
        print("\n".join(circular_lines))
        records += [{"table": "iso230-4", **r} for r in circular_rows]


def _bench_json(args, results: dict, records: list[dict], jobs: int) -> dict:
    """What ``--json`` writes: the settings, the plan (every env's policy labels) and the records."""
    settings = {
        "command": args.command,
        "seed": args.seed,
        "trials": args.trials or DEFAULT_TRIALS,
        "feedrate": args.feedrate,
        "plant": args.plant,
        "shop_floor": args.shop_floor,
        "all": args.all,
        "jobs": jobs,
        "default_ids": list(DEFAULT_IDS) if not (args.env or args.program or args.all) else None,
        "provenance": provenance(),
    }
    plan = {key: [run.label for run in env_runs.runs] for key, env_runs in results.items()}
    return {"settings": settings, "plan": plan, "records": [_json_safe(r) for r in records]}


def _write_trial_plots(ctx: BenchContext) -> None:
    for (env_id, label), trials in ctx.trials_of.items():
        path = ctx.plots / f"{env_id}_{label}_trials.png"
        plot_trials(trials, path, title=f"{env_id}: {label}, max contour error per trial")
        ctx.plots_written.append(path)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vcnc-bench``; returns the exit code (argument errors exit with 2)."""
    wall0 = time.perf_counter()
    parser = _parser()
    args = parser.parse_args(argv)
    args.command = "vcnc-bench " + shlex.join(sys.argv[1:] if argv is None else argv)
    _check_arguments(args, parser)
    recipes = _recipes(args, parser)
    if args.json is not None:
        _check_writable(args.json, parser, "file")
    if args.leaderboard is not None:
        _check_writable(args.leaderboard, parser, "file")
    if args.plots is not None:
        _check_writable(args.plots, parser, "directory")
    if args.plants is not None:
        return _robust_main(args, recipes, parser, wall0)

    jobs = min(args.jobs or idle_cores(), len(recipes))
    _print_plan(args, recipes, jobs)
    if jobs == 1 or args.trials is not None:  # the runs use these envs, or --trials is checked against them
        envs = _build_envs(recipes, parser)
        _check_sizes(args, envs, parser)
        results = _run(args, recipes, envs, parser, jobs, wall0)
    else:  # the workers build their own: this process builds the reports' envs while they run
        built: dict = {}
        builder = threading.Thread(target=_build_quietly, args=(recipes, built), daemon=True)
        builder.start()
        results = _run(args, recipes, None, parser, jobs, wall0)
        builder.join()
        envs = _build_envs(recipes, parser, built)
    if not any(env_runs.runs for env_runs in results.values()):
        parser.error(f"no policies to run: {policy_choices()}")
    ctx = _context(args, envs, results)
    records = _table_records(args, ctx, results)
    _print_table(args, ctx, records)
    _print_headroom(results, records)
    _print_reports(ctx, records)
    if args.plots is not None:
        _write_trial_plots(ctx)
    out = _bench_json(args, results, records, jobs)
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=2) + "\n")
        print(
            f"\nwrote {len(records)} records ({sum(map(len, (r.runs for r in results.values())))} env x policy "
            f"runs) to {args.json}"
        )
    if args.plots is not None:
        print(
            f"wrote {len(ctx.plots_written)} plots to {args.plots} (each env's: the paper's controllers, the "
            f"strongest causal one, the agent and the floor; --plot-all: every policy)"
        )
    _add_to_leaderboard(args, out)
    for env in envs.values():
        env.close()
    print(f"total wall time {time.perf_counter() - wall0:.1f} s")
    return 0


def _add_to_leaderboard(args, out: dict) -> None:
    """``--leaderboard PAGE``: this run's rows added to the board (:mod:`vcnc_bench.leaderboard`)."""
    if args.leaderboard is None:
        return
    from . import leaderboard

    rows = leaderboard.rows_of(out)
    page = leaderboard.write(args.leaderboard, rows)
    print(f"added {len(rows)} rows to the leaderboard {page}")


def _robust_main(args, recipes: list[EnvRecipe], parser, wall0: float) -> int:
    """``--plants N``: every policy of every env built here, then :func:`_robust`."""
    envs = _build_envs(recipes, parser)
    _check_sizes(args, envs, parser)
    runs = []
    for r in recipes:
        specs = r.specs or tuple(s for s in default_specs(envs[r.key]))
        for spec in specs:
            try:
                runs.append((r.key, spec, resolve_policy(spec, envs[r.key])))
            except (ValueError, OSError) as exc:
                parser.error(f"cannot build policy {spec!r} for {r.key}: {exc}")
    if not runs:
        parser.error(f"no policies to run: {policy_choices()}")
    runs = _with_reference(runs, envs)
    code = _robust(args, envs, runs)
    for env in envs.values():
        env.close()
    print(f"total wall time {time.perf_counter() - wall0:.1f} s")
    return code


def _with_reference(runs: list, envs: dict) -> list:
    """``runs`` with the normalised score's reference PD (:data:`vcnc_bench.score.REFERENCE`) added to every env
    it applies to and where it is not already run: a compiled servo law, a fraction of the cheapest run's cost."""
    out = list(runs)
    for env_id in dict.fromkeys(e for e, _, _ in runs):
        if any(label_of(s, p) == score.REFERENCE for e, s, p in runs if e == env_id):
            continue
        try:
            policy = resolve_policy(score.REFERENCE, envs[env_id])
        except ValueError:  # not a contouring env (the positioning env): no score
            continue
        last = max(i for i, (e, _, _) in enumerate(out) if e == env_id)
        out.insert(last + 1, (env_id, score.REFERENCE, policy))
    return out


def _nominal_floors(args, envs: dict, runs: list) -> dict:
    """The floor's figures on the nominal plant of every env whose runs hold no floor: the oracle's replay of its
    shipped solution (only for the ids' own configuration: default feedrate and plant, no ``--shop-floor``, seed 0;
    elsewhere a solve costs minutes and the score is left out).  ``{env: {"max_um", "rms_um", "label"}}``."""
    out = {}
    if args.feedrate is not None or args.plant is not None or args.shop_floor or args.seed != 0:
        return out
    for env_id in dict.fromkeys(e for e, _, _ in runs):
        if any(label_of(s, p).endswith(NON_CAUSAL) for e, s, p in runs if e == env_id):
            continue
        env = envs[env_id]
        try:
            oracle = resolve_policy("oracle", env)
        except ValueError:
            continue
        u = env.unwrapped
        batch = robust.make_batch(env_id, 1)
        try:
            res = robust.run_plants(
                oracle, batch, u.nominal_parameters[None], decision_period=u.decision_period, seed=args.seed
            )
        finally:
            batch.close()
        out[env_id] = {
            "max_um": float(res.max_um[0]),
            "rms_um": float(res.rms_um[0]),
            "label": label_of("oracle", oracle),
        }
    return out


def _print_scores(records: list[dict]) -> None:
    """The normalised scores of every record (nominal plant; IQM over the plants where the floor ran on them)."""
    rows = [r for r in records if r.get("score")]
    if not rows:
        return
    first = rows[0]["score"]
    print(
        f"\nNormalised contour score (0 = {first['reference']}, the reference PD; 1 = the non-causal floor), "
        "on the nominal plant, max and RMS contour error (vcnc_bench.score)"
    )
    width = max(len(r["env"]) for r in rows)
    pw = max(len(r["policy"]) for r in rows)
    env = None
    for r in rows:
        if r["env"] != env:
            env = r["env"]
            s = r["score"]
            print(
                f"  {env}: pd-ref {s['reference_nominal_um']['max']:.4g} um, floor "
                f"{s['floor_nominal_um']['max']:.4g} um (max)"
            )
        s = r["score"]
        cell = " ".join("      -" if s[k] is None else f"{s[k]:7.3f}" for k in ("max", "rms"))
        iqm = "".join(
            f"  IQM {k} {s[f'iqm_{k}'][0]:.3f} [{s[f'iqm_{k}'][1]:.3f}, {s[f'iqm_{k}'][2]:.3f}]"
            for k in ("max", "rms")
            if s.get(f"iqm_{k}") and None not in s[f"iqm_{k}"]
        )
        print(f"  {r['env']:<{width}} {r['policy']:<{pw}} {cell}{iqm}")


def _training_seed_groups(args) -> dict:
    """{label of a member: label of the spec it came from} for the ``--policy`` specs that stand for several (the
    seeds of one training run, :func:`vcnc_bench.policies.expand_spec`), judged as one controller."""
    groups = {}
    for spec in _unique(args.policy or []):
        members = expand_spec(spec)
        if members != [spec]:
            groups.update({policy_label(m): policy_label(spec) for m in members})
    return groups


def _robust(args, envs: dict, runs: list) -> int:
    """``--plants N``: every run on the nominal plant, N sampled plants and the vertices (vcnc_bench.robust)."""
    from tqdm import tqdm

    trials = args.trials or 1
    kwargs = _env_kwargs(args)
    with tqdm(
        total=len(runs),
        unit="run",
        file=sys.stderr,
        dynamic_ncols=True,
        leave=False,
        disable=True if args.no_progress else None,
    ) as bar:
        records, plant_sets = robust.evaluate(
            [(e, label_of(s, p), p) for e, s, p in runs],
            envs,
            args.plants,
            plant_seed=args.plant_seed,
            seed=args.seed,
            trials=trials,
            env_kwargs=kwargs,
            parallel=args.parallel,
            bar=bar,
            noise_seeds=args.noise_seeds,
        )
    score.add_scores(records, _nominal_floors(args, envs, runs))
    kinds = {(e, label_of(s, p)): split_spec(s)[0] for e, s, p in runs}
    groups = _training_seed_groups(args)
    for r in records:
        r["kind"] = kinds.get((r["env"], r["policy"]))
        if r["policy"] in groups:
            r["group"] = groups[r["policy"]]
    # every policy that is not a classical baseline (an agent, a user's kind) meets the strongest causal baseline
    learned = {label_of(s, p) for _, s, p in runs if split_spec(s)[0] != "baseline"}
    causal = {
        label_of(s, p) for _, s, p in runs if split_spec(s)[0] == "baseline" and getattr(p, "causal", True) is not False
    }
    verdict_rows = verdicts.robust_verdicts(records, learned, causal, seed=args.seed)
    print(
        f"Contour error over the uncertainty box (um): the nominal plant, median and 95th percentile over "
        f"{args.plants} plants drawn uniformly from the box (plant seed {args.plant_seed}), worst over them and "
        f"the box's vertices where it has at most {robust.MAX_VERTICES}; cycle time in s; a diverged plant counts "
        f"as an infinite error, a contour never finished as an infinite cycle time"
    )
    for env_id, plants in plant_sets.items():
        wall = sum(r["wall_s"] for r in records if r["env"] == env_id)
        print(
            f"  {env_id}: {len(plants.samples)} samples + {len(plants.vertices)} vertices"
            + (
                ""
                if len(plants.vertices)
                else f" (the box has 2^{envs[env_id].unwrapped.plant.box()[0].size} > {robust.MAX_VERTICES})"
            )
            + f", every policy in {wall:.0f} s"
        )
    if any(r["trials"] > 1 for r in records):
        print(f"  policies that learn across episodes: {trials} trials per plant, the last scored")
    print(format_table(records, robust.ROBUST_COLUMNS))
    nominal_bad = [f"{r['env']} {r['policy']}" for r in records if not r["nominal_completed"]]
    if nominal_bad:
        print(f"\nNOT COMPLETE on the nominal plant (diverged or cut short): {', '.join(nominal_bad)}")
    noisy = [r for r in records if "noise" in r]
    if noisy:
        print(
            f"\nSensor noise: every plant over {args.noise_seeds} noise seeds (the figures above: seed 0's); "
            "nominal plant min / median / max over the seeds, median spread (max - min) per sampled plant, IQM "
            "over every (sampled plant, seed) run, um"
        )
        for r in noisy:
            n = r["noise"]
            print(
                f"  {r['env']} {r['policy']}: "
                + "; ".join(
                    f"{k} {n[k]['nominal_min_um']:.4g} / {n[k]['nominal_median_um']:.4g} / {n[k]['nominal_max_um']:.4g}"
                    f", spread {n[k]['median_spread_um']:.3g}, IQM {n[k]['iqm_um']:.4g}"
                    for k in ("max", "rms")
                )
            )
    _print_scores(records)
    if verdict_rows:
        print(
            f"\nVerdicts (vcnc_bench.verdicts): the learned controller X against the strongest causal controller Y "
            f"of each figure, IQM over the {args.plants} sampled plants"
            + (f" x {args.noise_seeds} noise seeds on noisy sensors" if args.noise_seeds > 1 else "")
            + f", 95 % stratified-bootstrap intervals ({verdicts.REPS} replicates); X - Y: the paired bootstrap of "
            "the IQMs' difference (the same plants and noise for both); P(X<Y): X's error the lower (lower is "
            "better); 'wins'/'loses' only when the difference's interval excludes zero, else 'ties'"
        )
        print(verdicts.format_verdicts(verdict_rows))
    if args.json is not None or args.leaderboard is not None:
        settings = {
            "command": args.command,
            "plants": args.plants,
            "plant_seed": args.plant_seed,
            "seed": args.seed,
            "trials": trials,
            "max_vertices": robust.MAX_VERTICES,
            "feedrate": args.feedrate,
            "plant": args.plant,
            "shop_floor": args.shop_floor,
            "noise_seeds": args.noise_seeds,
            "bootstrap": {"reps": verdicts.REPS, "seed": args.seed, "confidence": verdicts.CONFIDENCE},
            "provenance": provenance(),
        }
        out = {
            "settings": settings,
            "robust": [_json_safe(r) for r in records],
            "verdicts": [_json_safe(r) for r in verdict_rows],
        }
        if args.json is not None:
            args.json.write_text(json.dumps(out, indent=2) + "\n")
            print(f"\nwrote {len(records)} robust records to {args.json}")
        _add_to_leaderboard(args, out)
    if args.plots is not None:
        for env_id in plant_sets:
            robust.plot_robust([r for r in records if r["env"] == env_id], args.plots / f"{env_id}_robust.png")
        print(f"wrote {len(plant_sets)} plots to {args.plots}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
