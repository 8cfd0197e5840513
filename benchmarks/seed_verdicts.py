"""An agent's training seeds on the box, from a ``vcnc-bench --plants N --policy ppo:FOLDER --json`` file.

    python benchmarks/seed_verdicts.py docs/data/shop_seeds/VCNC-HeartShop-v1.json [--base ff-ccc]

``ppo:FOLDER`` of a ``vcnc-train --seeds K`` folder stands for the K seeds' agents, judged as one controller
(``vcnc_bench.verdicts``).  Prints Markdown: every record's nominal / median / worst max and RMS contour error and
its own IQM of the max with its interval (a seed's row is that seed's spread), then the verdict rows the bench
wrote, then the seeds against their own base (the classical controller their residual corrects) by the same rule.
Every figure comes from the JSON; nothing is typed.
"""

from __future__ import annotations

import argparse
import json

from vcnc_bench.verdicts import sampled_figures, seed_figures, stratified_bootstrap_ci, verdict


def _f(v) -> str:
    return "inf" if v is None else f"{v:.4g}"


def tables(data: dict, base: str) -> list[str]:
    """The Markdown lines of one JSON (one env)."""
    records = data["robust"]
    env = records[0]["env"]
    out = [f"**{env}** (`{data['settings']['command']}`)", "",
           "| policy | max nominal / median / worst, um | RMS nominal / median / worst, um | IQM max [95 % CI], um |",
           "|---|---|---|---|"]
    for r in records:
        if r["policy"] == "pd-ref":
            continue
        iqm = stratified_bootstrap_ci(sampled_figures(r, "max"), seed=0)
        out.append(f"| `{r['policy']}` | {_f(r['nominal_max_um'])} / {_f(r['median_max_um'])} / "
                   f"{_f(r['worst_max_um'])} | {_f(r['nominal_rms_um'])} / {_f(r['median_rms_um'])} / "
                   f"{_f(r['worst_rms_um'])} | {_f(iqm[0])} [{_f(iqm[1])}, {_f(iqm[2])}] |")
    out += ["", "| learned X | fig | X IQM [95 % CI] | strongest causal Y | Y IQM [95 % CI] | X - Y [95 % CI] | "
                "P(X<Y) | verdict |", "|---|---|---|---|---|---|---|---|"]
    for v in data["verdicts"]:
        seeds = v.get("training_seeds", 1)
        out.append(f"| `{v['x']}`{f' ({seeds} seeds)' if seeds > 1 else ''} | {v['figure']} | {_f(v['iqm_x'])} "
                   f"[{_f(v['ci_x'][0])}, {_f(v['ci_x'][1])}] | `{v['y']}` | {_f(v['iqm_y'])} [{_f(v['ci_y'][0])}, "
                   f"{_f(v['ci_y'][1])}] | {_f(v['difference'])} [{_f(v['low'])}, {_f(v['high'])}] | "
                   f"{v['p_improvement']:.2f} | {v['outcome']} |")
    against = next((r for r in records if r["policy"] == base), None)
    runs = dict.fromkeys(r["group"] for r in records if r.get("group"))  # each training run's seeds, in order
    for run in runs if against is not None else ():
        members = [r for r in records if r.get("group") == run]
        cells = []
        for figure in ("max", "rms"):
            v = verdict(seed_figures(members, figure), sampled_figures(against, figure), figure=figure,
                        x_label=run, y_label=base)
            cells.append(f"{figure} {v.outcome}, X - Y {_f(v.difference)} [{_f(v.low)}, {_f(v.high)}] um")
        out += ["", f"Against their base `{base}`, the {len(members)} seeds of `{run}` as one: "
                + "; ".join(cells) + "."]
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("json", nargs="+", help="vcnc-bench --plants N --json files")
    p.add_argument("--base", default="ff-ccc", help="the controller the agents' residual corrects (default ff-ccc)")
    args = p.parse_args(argv)
    for path in args.json:
        with open(path) as f:
            print("\n".join(tables(json.load(f), args.base)) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
