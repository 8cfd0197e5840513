"""The shipped agents against the strongest causal controller and the floor, from a ``vcnc-bench --json`` file.

    python experiments/specialists/agents_vs_strongest.py bench-out/bench.json

Prints a Markdown table, one row per env where ``ppo`` ran: the strongest causal classical controller (agents
aside) and its max ; RMS contour error, the agent's, the floor's (non-causal), and where the agent stands on the
nominal plant.  One episode on one plant and one training seed is no verdict (issue 33: several seeds, plants from
the box and an interval); this says only which side of the strongest controller the shipped agent lands on.
"""

from __future__ import annotations

import argparse
import json

NON_CAUSAL = "(non-causal)"


def rows(data: dict) -> list[str]:
    by_env: dict[str, dict[str, dict]] = {}
    for r in data["records"]:
        if "table" in r or r.get("trial") not in (None,):
            continue
        by_env.setdefault(r["env"], {})[r["policy"]] = r
    out = [
        "| env | strongest causal | its max ; RMS, um | `ppo` max ; RMS, um | floor max ; RMS, um | `ppo` on the "
        "nominal plant |",
        "|---|---|---|---|---|---|",
    ]
    for env, runs in by_env.items():
        if "ppo" not in runs:
            continue
        causal = {k: v for k, v in runs.items() if k != "ppo" and NON_CAUSAL not in k}
        if not causal:
            continue
        name, best = min(causal.items(), key=lambda kv: (kv[1]["max_contour_error_um"], kv[1]["rms_contour_error_um"]))
        agent = runs["ppo"]
        floor = next((v for k, v in runs.items() if NON_CAUSAL in k), None)
        fmt = lambda r: f"{r['max_contour_error_um']:.4g} ; {r['rms_contour_error_um']:.4g}"  # noqa: E731
        wins = [agent[k] < best[k] for k in ("max_contour_error_um", "rms_contour_error_um")]
        stand = {(True, True): "below in both", (False, False): "above in both"}.get(
            tuple(wins), ("below in max, above in RMS" if wins[0] else "above in max, below in RMS")
        )
        out.append(f"| {env} | `{name}` | {fmt(best)} | {fmt(agent)} | {fmt(floor) if floor else '-'} | {stand} |")
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("json", help="a vcnc-bench --json file (the default table: bench-out/bench.json)")
    args = p.parse_args(argv)
    with open(args.json) as f:
        print("\n".join(rows(json.load(f))))


if __name__ == "__main__":
    main()
