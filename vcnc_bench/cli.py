"""``vcnc-bench``: every policy on every env of the suite, in one table, JSON and plots.

Runs each policy for one deterministic episode on the nominal plant of each
env and prints max, mean and RMS contour error (um) with the paper's
figures beside ours (:mod:`vcnc_bench.papers`)::

    vcnc-bench                                  # every policy that applies, on every env
    vcnc-bench --env VCNC-Omega-v0 --policy qft --policy smc
    vcnc-bench --json bench.json --plots bench-plots

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

    vcnc-bench --plants 100                     # every policy, every env: 100 plants (+ vertices) each
    vcnc-bench --env VCNC-Omega-v1 --plants 100 --plant-seed 1 --json robust.json --plots robust-plots

There ``--json`` writes ``{"settings": {...}, "robust": [one record per env
and policy, with every plant's figures]}`` and ``--plots`` one
``ENV_robust.png`` per env (box plots of max and RMS over the samples, the
vertices and the nominal plant marked, log scale).  A policy that learns
across episodes (ILC) runs its first trial unless ``--trials K`` is given
(then K trials per plant, the last scored).  The kernel runs on one thread
unless ``--parallel`` (on cores other processes share, a parallel step
waits for both threads and is many times slower).  The papers' reports,
which need the single episodes, are not printed.

A policy is named by a spec (:mod:`vcnc_bench.policies`): a bare name such
as ``qft``, or ``KIND:ARGUMENT`` such as ``ppo:runs/x/best``.  The kinds
come from the packages that provide them (``baselines``, ``agents``); the
bench names none.  By default each env runs the policies that apply to its
plant (every kind's ``defaults``).

This package is the top layer: it imports ``vcnc_gym`` and, through the
policy kinds, ``baselines`` and ``agents``; nothing imports it.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import gymnasium as gym

import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs import ENV_IDS, ContouringEnv
from vcnc_gym.envs.registry import LEGACY
from vcnc_gym.evaluation import EpisodeResult, plot_contour_errors, plot_contours, plot_trials, run_episode

from vcnc_gym.deviation_plot import plot_deviation
from vcnc_gym.validation import size

from .papers import paper_figures
from . import programs, robust
from .policies import (BenchContext, check_policy_spec, default_specs, policy_choices, policy_kinds, policy_label,
                       resolve_policy)

#: The v0 ids, kept for agents trained on them: benchmarked when named.
LEGACY_IDS = tuple(e.id for e in LEGACY)

__all__ = ["format_table", "main"]


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
    columns = [(h, max([w] + [len(str(r.get(key))) for r in records]) if key in ("env", "policy") else w, key, fmt)
               for h, w, key, fmt in (columns or _COLUMNS)]
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


def _label(spec: str, policy) -> str:
    """A policy's label in the tables and the JSON: a non-causal floor (``causal = False``, the baselines'
    oracle) is marked so wherever it appears, never to be read as a controller."""
    return policy_label(spec) + (" (non-causal)" if getattr(policy, "causal", True) is False else "")


def _record(env_id: str, label: str, result: EpisodeResult, compare: bool = True, trial: int | None = None) -> dict:
    paper = paper_figures(env_id, label).get("max_contour_error_um") if compare else None
    ratio = result.max_contour_error_um / paper if paper else None
    return {
        "env": env_id,
        "policy": label if trial is None else f"{label} (trial {trial})",
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


def _json_safe(rec: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in rec.items()}


# -- command line -------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vcnc-bench",
        description="Run every policy on the vcnc-gym envs (nominal plant, one deterministic episode each) "
                    "and compare with the source papers' figures.",
    )
    p.add_argument("--env", action="append", metavar="ID",
                   help=f"env id, repeatable (default: all of {', '.join(ENV_IDS)}; the v0 ids when named)")
    p.add_argument("--policy", action="append", metavar="SPEC",
                   help="a baseline name, 'ppo' (the agent shipped for the env) or KIND:ARGUMENT such as "
                        "ppo:RUN/best, repeatable (default: every policy that applies to each env's plant)")
    p.add_argument("--seed", type=int, default=0, help="seed passed to env.reset, >= 0 (default 0)")
    p.add_argument("--feedrate", type=float, metavar="MM_PER_S",
                   help="feedrate in mm/s (default: each env's own); with another value the paper's "
                        "columns stay empty")
    p.add_argument("--plant", metavar="NAME",
                   help="run every env on this plant instead of its own (a name of vcnc_gym.plants.plant_names(), such as "
                        "current_feed_drive: a generalist's machine on the test pieces); the papers' columns stay "
                        "empty")
    p.add_argument("--trials", type=int, metavar="K",
                   help="episodes run by a policy that learns across episodes (ILC); the table shows the first "
                        "and the last, the JSON every one (default 10; with --plants 1, the last scored)")
    p.add_argument("--plants", type=int, metavar="N",
                   help="robust evaluation instead: every policy on the nominal plant, N plants drawn uniformly "
                        "from the env's uncertainty box and the box's vertices when it has at most "
                        f"{robust.MAX_VERTICES}; median, p95 and worst of max and RMS contour error, cycle time, "
                        "divergences")
    p.add_argument("--plant-seed", type=int, default=0, metavar="S",
                   help="seed of the plants drawn by --plants, >= 0 (default 0)")
    p.add_argument("--parallel", action="store_true",
                   help="with --plants: spread each batch of plants over numba's threads (faster on idle cores, "
                        "far slower on cores other processes use; default one thread)")
    p.add_argument("--program", action="append", metavar="PART",
                   help="a G-code part program (a file, a test piece of vcnc_gym.gcode.pieces.PIECES, or "
                        "'iso230-4': the circular test both ways) run as VCNC-GCode-v1, repeatable; with no --env "
                        "only the programs run (vcnc_bench.programs)")
    p.add_argument("--tolerance", metavar="MM", default="0.01",
                   help="with --program: corner blending tolerance in mm, or 'sharp' (exact stops; default 0.01)")
    p.add_argument("--circle", nargs=2, type=float, metavar=("D_MM", "F_MM_PER_MIN"),
                   help="with --program iso230-4: the circle's diameter (mm) and feed (mm/min)")
    p.add_argument("--json", metavar="PATH", type=Path, help="write one record per run to this JSON file")
    p.add_argument("--plots", metavar="DIR", type=Path,
                   help="write ENV_contour.png, ENV_error.png and ENV_deviation.png (the deviation magnified along "
                        "the contour's normal, an inset at every corner) per env into this directory")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    return p


def _env_kwargs(args) -> dict:
    """The arguments every env is made with: ``feedrate`` and ``plant`` when given."""
    kwargs = {} if args.feedrate is None else {"feedrate": args.feedrate}
    if args.plant is not None:
        kwargs["plant"] = args.plant
    return kwargs


def _make_env(env_id: str, kwargs: dict, parser):
    """The env of ``env_id`` with ``kwargs`` (another feedrate, another plant)."""
    try:
        return gym.make(env_id, **kwargs)
    except (ValueError, TypeError) as exc:
        parser.error(f"{env_id}: {exc}")


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
                robust.check_plants(args.plants, env)
        if args.trials is not None:
            steps = max(int(env.unwrapped.episode_steps) for env in envs.values())
            size("--trials", args.trials, ceiling=MAX_TRIALS,
                 why="a learning controller converges within tens of trials; 10 000 episodes are hours")
            if args.plants is None:
                size("--trials", args.trials, bytes_each=2 * steps * TRACE_BYTES_PER_STEP,
                     why=f"every trial's traces are kept, {steps} steps of the longest env's episode (twice, "
                         "for one that runs to its time limit)")
    except ValueError as exc:
        parser.error(str(exc))


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vcnc-bench``; returns the exit code (argument errors exit with 2)."""
    wall0 = time.perf_counter()
    parser = _parser()
    args = parser.parse_args(argv)
    if args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    if args.trials is not None and args.trials < 1:
        parser.error(f"--trials must be >= 1, got {args.trials}")
    if args.plants is not None and args.plants < 1:
        parser.error(f"--plants must be >= 1, got {args.plants}")
    if args.plant_seed < 0:
        parser.error(f"--plant-seed must be >= 0, got {args.plant_seed}")
    if args.parallel and args.plants is None:
        parser.error("--parallel spreads the batch of --plants N over threads; without --plants each episode "
                     "runs on one env and there is nothing to spread: add --plants N or drop --parallel")

    env_ids = _unique(args.env or ([] if args.program else list(ENV_IDS)))
    unknown = [e for e in env_ids if e not in ENV_IDS + LEGACY_IDS]
    if unknown:
        parser.error(f"unknown env id(s) {', '.join(map(repr, unknown))}; valid ids are {', '.join(ENV_IDS)}")
    specs = _unique(args.policy or [])
    for spec in specs:
        try:
            check_policy_spec(spec)
        except ValueError as exc:
            parser.error(str(exc))
    if args.json is not None:
        _check_writable(args.json, parser, "file")
    if args.plots is not None:
        _check_writable(args.plots, parser, "directory")

    # build every env and policy first, so a bad spec fails before any run
    envs = {env_id: _make_env(env_id, _env_kwargs(args), parser) for env_id in env_ids}
    if args.program:
        if args.feedrate is not None:
            parser.error("--feedrate does not apply to --program: a program's F words set its feeds")
        try:
            tolerance = None if args.tolerance == "sharp" else float(args.tolerance)
            envs.update(programs.make_program_envs(programs.expand_programs(args.program, args.circle), tolerance,
                                                   plant=args.plant))
        except ValueError as exc:
            parser.error(str(exc))
        env_ids = list(envs)
    _check_sizes(args, envs, parser)
    compare = args.feedrate is None and args.plant is None
    runs = []
    for env_id, env in envs.items():
        for spec in specs or default_specs(env):
            try:
                runs.append((env_id, spec, resolve_policy(spec, env)))
            except (ValueError, OSError) as exc:
                parser.error(f"cannot build policy {spec!r} for {env_id}: {exc}")
    if not runs:
        parser.error(f"no policies to run: {policy_choices()}")

    if args.plants is not None:
        code = _robust(args, envs, runs)
        for env in envs.values():
            env.close()
        print(f"total wall time {time.perf_counter() - wall0:.1f} s")
        return code
    if args.trials is None:
        args.trials = 10

    from tqdm import tqdm

    def trials_of(policy) -> int:
        return args.trials if getattr(policy, "learns_across_episodes", False) else 1

    total = sum(envs[e].unwrapped.episode_steps * trials_of(p) for e, _, p in runs)
    records: list[dict] = []
    ctx = BenchContext(env_ids=env_ids, envs=envs, plots=args.plots, trials=args.trials)
    with tqdm(total=total, unit="step", file=sys.stderr, dynamic_ncols=True, leave=False,
              disable=True if args.no_progress else None) as bar:
        for env_id, spec, policy in runs:
            label = _label(spec, policy)
            k = trials_of(policy)
            trials = []
            for trial in range(1, k + 1):
                bar.set_postfix_str(f"{env_id} {label}" + (f" trial {trial}/{k}" if k > 1 else ""))
                result = run_episode(policy, envs[env_id], seed=args.seed, progress=bar.update)
                trials.append(result)
                records.append(_record(env_id, label, result, compare and trial == k, trial if k > 1 else None))
            ctx.results.setdefault(env_id, {})[label] = trials[-1]
            if k > 1:
                ctx.trials_of[(env_id, label)] = trials
    ctx.records = records

    feeds = sorted({envs[e].unwrapped.feedrate_profile.feedrate for e in env_ids
                    if hasattr(envs[e].unwrapped, "feedrate_profile")})
    print(f"Error of every policy on the nominal plant, one deterministic episode each (seed {args.seed}"
          + (f"; policies that learn across episodes: {args.trials} trials, first and last shown" if ctx.trials_of
             else "") + ")" + (f"; contours at {', '.join(f'{f:g}' for f in feeds)} mm/s" if feeds else ""))
    print("error: the contour error on contouring envs, the distance to the set-point on positioning envs; "
          "paper = the source paper's figure")
    shown = [r for r in records if r.get("trial") in (None, 1, args.trials)]
    print(format_table(shown))
    incomplete = [f"{r['env']} {r['policy']}" for r in shown if not r["completed"]]
    if incomplete:
        print(f"\nNOT COMPLETE (diverged, or cut short before the end of its contour or step-response window; "
              f"its errors cover only the part it ran): {', '.join(incomplete)}")
    for kind in policy_kinds().values():
        if kind.report is not None:
            lines = kind.report(ctx)
            if lines:
                print()
                print("\n".join(lines))

    circular_lines, circular_rows = programs.circular_report(ctx.results, envs)
    if circular_lines:
        print()
        print("\n".join(circular_lines))
        records += [{"table": "iso230-4", **r} for r in circular_rows]
    if args.json is not None:
        args.json.write_text(json.dumps([_json_safe(r) for r in records], indent=2) + "\n")
        print(f"\nwrote {len(records)} records to {args.json}")
    if args.plots is not None:
        written = 0
        for env_id, by_policy in ctx.results.items():
            if not isinstance(envs[env_id].unwrapped, ContouringEnv):  # a G-code program's, a random contour's too
                continue
            plot_contours(by_policy, envs[env_id], args.plots / f"{env_id}_contour.png")
            plot_contour_errors(by_policy, envs[env_id], args.plots / f"{env_id}_error.png")
            plot_deviation(by_policy, envs[env_id], args.plots / f"{env_id}_deviation.png")
            written += 3
        for (env_id, label), trials in ctx.trials_of.items():
            plot_trials(trials, args.plots / f"{env_id}_{label}_trials.png",
                        title=f"{env_id}: {label}, max contour error per trial")
            written += 1
        written += len(ctx.plots_written)
        print(f"wrote {written} plots to {args.plots}")
    for env in envs.values():
        env.close()
    print(f"total wall time {time.perf_counter() - wall0:.1f} s")
    return 0


def _robust(args, envs: dict, runs: list) -> int:
    """``--plants N``: every run on the nominal plant, N sampled plants and the vertices (vcnc_bench.robust)."""
    from tqdm import tqdm

    trials = args.trials or 1
    kwargs = _env_kwargs(args)
    with tqdm(total=len(runs), unit="run", file=sys.stderr, dynamic_ncols=True, leave=False,
              disable=True if args.no_progress else None) as bar:
        records, plant_sets = robust.evaluate([(e, _label(s, p), p) for e, s, p in runs], envs, args.plants,
                                              plant_seed=args.plant_seed, seed=args.seed, trials=trials,
                                              env_kwargs=kwargs, parallel=args.parallel, bar=bar)
    print(f"Contour error over the uncertainty box (um): the nominal plant, median and 95th percentile over "
          f"{args.plants} plants drawn uniformly from the box (plant seed {args.plant_seed}), worst over them and "
          f"the box's vertices where it has at most {robust.MAX_VERTICES}; cycle time in s; a diverged plant counts "
          f"as an infinite error, a contour never finished as an infinite cycle time")
    for env_id, plants in plant_sets.items():
        wall = sum(r["wall_s"] for r in records if r["env"] == env_id)
        print(f"  {env_id}: {len(plants.samples)} samples + {len(plants.vertices)} vertices"
              + ("" if len(plants.vertices) else
                 f" (the box has 2^{envs[env_id].unwrapped.plant.box()[0].size} > {robust.MAX_VERTICES})")
              + f", every policy in {wall:.0f} s")
    if any(r["trials"] > 1 for r in records):
        print(f"  policies that learn across episodes: {trials} trials per plant, the last scored")
    print(format_table(records, robust.ROBUST_COLUMNS))
    nominal_bad = [f"{r['env']} {r['policy']}" for r in records if not r["nominal_completed"]]
    if nominal_bad:
        print(f"\nNOT COMPLETE on the nominal plant (diverged or cut short): {', '.join(nominal_bad)}")
    if args.json is not None:
        settings = {"plants": args.plants, "plant_seed": args.plant_seed, "seed": args.seed, "trials": trials,
                    "max_vertices": robust.MAX_VERTICES, "feedrate": args.feedrate, "plant": args.plant}
        out = {"settings": settings, "robust": [_json_safe(r) for r in records]}
        args.json.write_text(json.dumps(out, indent=2) + "\n")
        print(f"\nwrote {len(records)} robust records to {args.json}")
    if args.plots is not None:
        for env_id in plant_sets:
            robust.plot_robust([r for r in records if r["env"] == env_id], args.plots / f"{env_id}_robust.png")
        print(f"wrote {len(plant_sets)} plots to {args.plots}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
