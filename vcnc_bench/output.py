"""What ``vcnc-bench`` prints and writes: the table, the headroom, the reports, the JSON and the trials' plots.

:func:`format_table` lays out the records (one per episode, :func:`table_records`) as a fixed-width table, the
robust evaluation's too (:data:`vcnc_bench.robust.ROBUST_COLUMNS`); :func:`bench_json` is what ``--json`` writes.
"""

from __future__ import annotations

import math
import sys
import time

from vcnc_gym.envs import ENV_IDS
from vcnc_gym.evaluation import EpisodeResult, plot_trials

from . import programs
from .arguments import DEFAULT_TRIALS
from .headroom import headroom
from .papers import paper_figures
from .plots import shown_labels
from .policies import BenchContext, policy_kinds, split_spec
from .provenance import provenance
from .recipes import DEFAULT_IDS
from .runner import EnvRecipe, EnvRuns

__all__ = ["bench_json", "format_table", "json_safe", "table_records"]


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


def json_safe(rec):
    """``rec`` with every non-finite float (at any depth) as None: strict JSON."""
    if isinstance(rec, dict):
        return {k: json_safe(v) for k, v in rec.items()}
    if isinstance(rec, (list, tuple)):
        return [json_safe(v) for v in rec]
    return None if isinstance(rec, float) and not math.isfinite(rec) else rec


def print_plan(args, recipes: list[EnvRecipe], jobs: int) -> None:
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


def progress(wall0: float):
    """One line per finished env on stderr: its policies, its own wall time and the run's so far."""

    def line(result: EnvRuns, done: int, total: int) -> None:
        print(
            f"  [{done:>{len(str(total))}}/{total}] {result.key}: {len(result.runs)} policies in "
            f"{result.wall_s:.1f} s (run so far {time.perf_counter() - wall0:.0f} s)",
            file=sys.stderr,
            flush=True,
        )

    return line


def bench_context(args, envs: dict, results: dict) -> BenchContext:
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


def table_records(args, ctx: BenchContext, results: dict) -> list[dict]:
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


def print_table(args, ctx: BenchContext, records: list[dict]) -> None:
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


def print_headroom(results: dict, records: list[dict]) -> None:
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


def print_reports(ctx: BenchContext, records: list[dict]) -> None:
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


def bench_json(args, results: dict, records: list[dict], jobs: int) -> dict:
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
    return {"settings": settings, "plan": plan, "records": [json_safe(r) for r in records]}


def write_trial_plots(ctx: BenchContext) -> None:
    assert ctx.plots is not None  # --plots
    for (env_id, label), trials in ctx.trials_of.items():
        path = ctx.plots / f"{env_id}_{label}_trials.png"
        plot_trials(trials, path, title=f"{env_id}: {label}, max contour error per trial")
        ctx.plots_written.append(path)


def add_to_leaderboard(args, out: dict) -> int:
    """``--leaderboard PAGE``: this run's rows added to the board (:mod:`vcnc_bench.leaderboard`); 0, or 1 where the
    board cannot be written now (changed since the run began, a full disk): one line says so and where the run's
    records are kept (``--json``, else a file beside the page), so that no run is lost."""
    if args.leaderboard is None:
        return 0
    from . import leaderboard

    rows = leaderboard.rows_of(out)
    try:
        page = leaderboard.write(args.leaderboard, rows)
    except (ValueError, OSError) as exc:
        kept = args.json if args.json is not None else _keep(args.leaderboard, out)
        where = (
            f"this run's records are in {kept}: add them with python -m vcnc_bench.leaderboard {kept} --out "
            f"{args.leaderboard}"
            if kept is not None
            else "this run's records could not be kept (no folder was writable)"
        )
        print(f"vcnc-bench: error: --leaderboard {exc}; {where}", file=sys.stderr)
        return 1
    print(f"added {len(rows)} rows to the leaderboard {page}")
    return 0


def _keep(page, out: dict):
    """Write the run's JSON beside ``page`` (else in the current folder); its path, or None."""
    import json
    from pathlib import Path

    name = f"{Path(page).stem}-run-{time.strftime('%Y%m%d-%H%M%S')}.json"
    for folder in (Path(page).parent, Path.cwd()):
        try:
            path = folder / name
            path.write_text(json.dumps(out, indent=2) + "\n")
            return path
        except OSError:
            continue
    return None
