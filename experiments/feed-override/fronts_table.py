"""The table of every contouring id's front (experiments/feed-override/README.md), from a
``python experiments/feed-override/feed_override.py --id ... --json`` file.

    python experiments/feed-override/fronts_table.py experiments/feed-override/data/fronts.json

Per id: the planned runs' Pareto front at its fastest and at its most accurate point, the operator's most accurate
fixed override, the contouring MPC at its caps ("unfinished": it did not finish within the time limit), and
whether some planned run is both at least as fast and at least as accurate as each MPCC point ("-": unfinished).
Markdown, every figure from the JSON.
"""

from __future__ import annotations

import argparse
import math

from feed_override import pareto, read_fronts


def _run(p) -> str:
    return f"{p.cycle_time_s:.4g} / {p.max_um:.4g}"


def row(env_id: str, points) -> str:
    front = pareto([p for p in points if p.kind == "planned"])
    planned = (
        (
            f"`{front[0].policy}` {front[0].setting}: {_run(front[0])} ; `{front[-1].policy}` {front[-1].setting}: "
            f"{_run(front[-1])}"
        )
        if front
        else "-"
    )
    operator = [p for p in points if p.kind == "operator"]
    best = min(operator, key=lambda p: p.max_um) if operator else None
    op = f"{best.setting}: {_run(best)}" if best else "(not designed for the plant)"
    mpcc = [p for p in points if p.kind == "mpcc"]
    runs, beaten = [], []
    for p in mpcc:
        speed = p.setting.replace("v_max ", "")
        done = math.isfinite(p.cycle_time_s)
        runs.append(
            f"{speed}: {p.cycle_time_s:.4g} / {p.max_um:.4g}" if done else f"{speed}: unfinished / {p.max_um:.4g}"
        )
        if not done:
            beaten.append("-")
        else:
            hit = any(c.cycle_time_s <= p.cycle_time_s and c.max_um <= p.max_um for c in front)
            beaten.append("yes" if hit else "**no**")
    return f"| {env_id} | {planned} | {op} | {'; '.join(runs)} | {', '.join(beaten)} |"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("json", nargs="+")
    args = parser.parse_args(argv)
    print(
        "| id | classical front (planned): fastest ; most accurate, s / um | operator's override, best max, s / um "
        "| `mpcc` at its caps, s / um | `mpcc` beaten by a planned run? |"
    )
    print("|---|---|---|---|---|")
    for env_id, points in read_fronts(args.json).items():
        print(row(env_id, points))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
