"""Is a ``vcnc-bench --json`` file complete?  ``python -m vcnc_bench.check bench-out/bench.json [--default]``.

CI runs the README's main job (``make bench``) and then this check: the JSON must exist, hold the plan the run
printed (every env with the labels of the policies it ran) and, for every env and policy of the plan, a record of
its scored episode with finite max, mean and RMS errors; and every floor must be one: at or below the strongest
causal controller (a headroom row under 1 says the stored floor is stale, solved before a controller changed).
With ``--default`` the plan's envs must also be
:data:`vcnc_bench.recipes.DEFAULT_IDS`, every one with at least one policy.  Exit 1 with one line per problem.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from vcnc_gym.schema import BadFile, read_json

from .files import check_bench

__all__ = ["problems", "main"]

_FIGURES = ("max_contour_error_um", "mean_contour_error_um", "rms_contour_error_um")


def problems(data, default_ids: tuple | None = None) -> list[str]:
    """What is missing or not finite in a bench JSON (its parsed content); empty when complete.  ``default_ids``:
    the envs the plan must hold, in order."""
    if not isinstance(data, dict) or not {"settings", "plan", "records"} <= set(data):
        return ["not a vcnc-bench table JSON: expected the keys settings, plan and records"]
    try:
        check_bench(data)
    except ValueError as exc:
        return [f"not as vcnc-bench writes it: {exc}"]
    plan, records = data["plan"], data["records"]
    out = []
    if default_ids is not None and list(plan) != list(default_ids):
        out.append(f"the plan's envs {list(plan)} are not the default table's {list(default_ids)}")
    scored = {}
    for r in records:
        if r.get("table") == "headroom" and not (r.get("headroom") or 0.0) >= 1.0:
            out.append(
                f"{r.get('env')}: the floor ({r.get('floor_max_um')} um) is above the strongest causal "
                f"controller ({r.get('strongest')}, {r.get('strongest_max_um')} um): a stale floor; solve it "
                f"again (python benchmarks/oracle_convergence.py --env {r.get('env')} --store)"
            )
        if "table" in r:  # a report's rows (ISO 230-4, headroom)
            continue
        key = (r.get("env"), r.get("policy"))
        trial = r.get("trial")
        if trial is not None:  # every trial of a learning policy: the last is scored under its own label
            key = (r.get("env"), r.get("policy", "").rsplit(" (trial ", 1)[0])
        scored[key] = r
    for env, labels in plan.items():
        if not labels:
            out.append(f"{env}: no policy ran")
        for label in labels:
            rec = scored.get((env, label))
            if rec is None:
                out.append(f"{env} {label}: no record")
                continue
            bad = [k for k in _FIGURES if not (isinstance(rec.get(k), (int, float)) and math.isfinite(rec[k]))]
            if bad:
                out.append(f"{env} {label}: no finite {', '.join(bad)} (diverged: {rec.get('diverged')})")
    return out


#: A record's fields that time the run, not the policy: left out of :func:`figure_differences`.
TIMING_FIELDS = ("wall_s",)


def figure_differences(data: dict, other: dict) -> list[str]:
    """The records (by env, policy or table, and trial) that only one of two bench JSONs holds, and every field
    but :data:`TIMING_FIELDS` whose value differs between the two (NaN equal to NaN)."""

    def rows(d):
        return {(r.get("env"), r.get("policy", r.get("table")), r.get("trial")): r for r in d["records"]}

    a, b = rows(data), rows(other)
    out = [f"{k}: in one file only" for k in sorted(set(a) ^ set(b), key=str)]
    for key in sorted(set(a) & set(b), key=str):
        for field in sorted((set(a[key]) | set(b[key])) - set(TIMING_FIELDS)):
            x, y = a[key].get(field), b[key].get(field)
            nan = isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)
            if x != y and not nan:
                out.append(f"{key}: {field} {x!r} against {y!r}")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m vcnc_bench.check", description=(__doc__ or "").partition("\n")[0])
    p.add_argument("json", type=Path, help="the file vcnc-bench --json wrote")
    p.add_argument("--default", action="store_true", help="the plan must be the default table's envs")
    p.add_argument(
        "--same-figures",
        type=Path,
        metavar="OTHER",
        help="another vcnc-bench --json output whose records must hold the same figures, field by field (the run's "
        "wall times aside): a change that should move no figure",
    )
    args = p.parse_args(argv)
    if not args.json.is_file():
        print(f"{args.json}: no such file (did vcnc-bench run to its end?)", file=sys.stderr)
        return 1
    try:
        data = read_json(args.json, "a vcnc-bench --json output")
    except BadFile as exc:
        print(exc, file=sys.stderr)
        return 1
    default_ids = None
    if args.default:
        from .cli import DEFAULT_IDS

        default_ids = DEFAULT_IDS
    found = problems(data, default_ids)
    if args.same_figures is not None and not found:
        try:
            other = read_json(args.same_figures, "a vcnc-bench --json output")
        except (BadFile, OSError) as exc:
            print(f"--same-figures: {exc}", file=sys.stderr)
            return 1
        found = figure_differences(data, other)
        if not found:
            print(f"{args.json}: the same figures as {args.same_figures}, {len(data['records'])} records")
    for line in found:
        print(f"{args.json}: {line}", file=sys.stderr)
    if not found:
        n = sum(len(v) for v in data["plan"].values())
        print(
            f"{args.json}: complete, {len(data['plan'])} envs x their policies = {n} runs, every one with finite "
            f"figures"
        )
    return 1 if found else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
