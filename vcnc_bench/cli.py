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
import shlex
import sys
import threading
import time

import vcnc_gym  # noqa: F401  (registers the ids)

from .arguments import DEFAULT_TRIALS, bench_parser, check_arguments, check_outputs, check_sizes
from .output import (
    add_to_leaderboard,
    bench_context,
    bench_json,
    format_table,
    print_headroom,
    print_plan,
    print_reports,
    print_table,
    progress,
    table_records,
    write_trial_plots,
)
from .policies import policy_choices
from .recipes import DEFAULT_IDS, LEGACY_IDS, LONGEST_FIRST, build_envs, build_quietly, env_recipes, run_cost
from .robust_run import robust_main
from .runner import BuildError, EnvRecipe, idle_cores, run_table

__all__ = ["DEFAULT_IDS", "LEGACY_IDS", "LONGEST_FIRST", "format_table", "main"]


def _run(
    args, recipes: list[EnvRecipe], envs: dict | None, parser: argparse.ArgumentParser, jobs: int, wall0: float
) -> dict:
    """{key: EnvRuns} of every recipe; an env or a policy that cannot be built exits 2 naming it."""
    try:
        return run_table(
            recipes,
            seed=args.seed,
            trials=args.trials or DEFAULT_TRIALS,
            jobs=jobs,
            envs=envs,
            cost=run_cost(envs),
            on_env_done=None if args.no_progress else progress(wall0),
            plots=args.plots,
            plot_all=args.plot_all,
            prepare=True,
        )
    except BuildError as exc:
        parser.error(str(exc))


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vcnc-bench``; returns the exit code (argument errors exit with 2)."""
    wall0 = time.perf_counter()
    parser = bench_parser()
    args = parser.parse_args(argv)
    args.command = "vcnc-bench " + shlex.join(sys.argv[1:] if argv is None else argv)
    check_arguments(args, parser)
    recipes = env_recipes(args, parser)
    check_outputs(args, parser)
    if args.plants is not None:
        return robust_main(args, recipes, parser, wall0)

    jobs = min(args.jobs or idle_cores(), len(recipes))
    print_plan(args, recipes, jobs)
    if jobs == 1 or args.trials is not None:  # the runs use these envs, or --trials is checked against them
        envs = build_envs(recipes, parser)
        check_sizes(args, envs, parser)
        results = _run(args, recipes, envs, parser, jobs, wall0)
    else:  # the workers build their own: this process builds the reports' envs while they run
        built: dict = {}
        builder = threading.Thread(target=build_quietly, args=(recipes, built), daemon=True)
        builder.start()
        results = _run(args, recipes, None, parser, jobs, wall0)
        builder.join()
        envs = build_envs(recipes, parser, built)
    if not any(env_runs.runs for env_runs in results.values()):
        parser.error(f"no policies to run: {policy_choices()}")
    ctx = bench_context(args, envs, results)
    records = table_records(args, ctx, results)
    print_table(args, ctx, records)
    print_headroom(results, records)
    print_reports(ctx, records)
    if args.plots is not None:
        write_trial_plots(ctx)
    out = bench_json(args, results, records, jobs)
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
    code = add_to_leaderboard(args, out)
    for env in envs.values():
        env.close()
    print(f"total wall time {time.perf_counter() - wall0:.1f} s")
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
