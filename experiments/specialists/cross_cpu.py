"""The same ``vcnc-bench --plants N`` run on two CPUs' code paths, compared figure by figure and verdict by verdict
(issue 33: "no verdict that flips with the CPU").

    python -m vcnc_bench.provenance --like OLD.json -- vcnc-bench ... --json NEW.json     # OLD's CPU, this host
    python experiments/specialists/cross_cpu.py OLD.json NEW.json [--rename runs/seeds10=agents/trained/seeds/specialists]

Per policy both runs hold (labels matched after ``--rename OLD_PREFIX=NEW_PREFIX``, for agents moved since), on
every plant of the run: how many max and RMS figures differ at all, and the largest relative difference; then per
learned controller and figure the verdict of each run (against the strongest causal controller of its own run) and
whether it changed.  The CPUs are the two JSONs' ``settings.provenance`` (numba's target CPU).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def _cpu(data: dict) -> str:
    numba = (data["settings"].get("provenance") or {}).get("numba") or {}
    return str(numba.get("cpu_name"))


def _figures(rec: dict, figure: str) -> np.ndarray:
    return np.array([np.inf if v is None else v for v in rec["per_plant"][f"{figure}_um"]], dtype=np.float64)


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    both = np.isfinite(a) & np.isfinite(b)
    if not both.any():
        return 0.0
    return float(np.max(np.abs(a[both] - b[both]) / np.maximum(np.abs(a[both]), 1e-300)))


def compare(old: dict, new: dict, rename: tuple[str, str] | None = None) -> list[str]:
    """The Markdown lines of both tables (see the module docstring)."""

    def label(s: str) -> str:
        return s.replace(rename[0], rename[1]) if rename else s

    mine = {r["policy"]: r for r in new["robust"]}
    out = [
        f"{old['robust'][0]['env']}: numba target `{_cpu(old)}` (old) against `{_cpu(new)}` (new)",
        "",
        "| policy | plants | max differs on | largest relative difference of the max | RMS differs on | "
        "largest of the RMS |",
        "|---|---|---|---|---|---|",
    ]
    for r in old["robust"]:
        other = mine.get(label(r["policy"]))
        if other is None:
            continue
        cells = []
        for figure in ("max", "rms"):
            a, b = _figures(r, figure), _figures(other, figure)
            if a.shape != b.shape:
                raise ValueError(f"{r['policy']}: {a.size} plants against {b.size}: not the same run")
            cells += [f"{int(np.sum(a != b))}", f"{_relative(a, b):.2g}"]
        out.append(f"| `{label(r['policy'])}` | {len(r['per_plant']['kind'])} | " + " | ".join(cells) + " |")
    out += [
        "",
        "| learned X | fig | old: verdict (against), X - Y [95 % CI] | new: verdict (against), X - Y [95 % CI] | "
        "changed |",
        "|---|---|---|---|---|",
    ]
    verdicts = {(label(v["x"]), v["figure"]): v for v in new["verdicts"]}
    changed = total = 0
    for v in old["verdicts"]:
        w = verdicts.get((label(v["x"]), v["figure"]))
        if w is None:
            continue
        total += 1
        changed += v["outcome"] != w["outcome"]
        cell = [f"{u['outcome']} (`{u['y']}`), {u['difference']:.4g} [{u['low']:.4g}, {u['high']:.4g}]" for u in (v, w)]
        out.append(
            f"| `{label(v['x'])}` | {v['figure']} | {cell[0]} | {cell[1]} | "
            f"{'**yes**' if v['outcome'] != w['outcome'] else 'no'} |"
        )
    return out + ["", f"{changed} of {total} verdicts changed."]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("old", type=Path, help="the stored run (vcnc-bench --plants N --json)")
    p.add_argument("new", type=Path, help="the same command's run on another CPU's code paths")
    p.add_argument("--rename", metavar="OLD=NEW", help="a prefix of the old run's policy labels and the new run's")
    args = p.parse_args(argv)
    rename = None
    if args.rename is not None:
        if "=" not in args.rename:
            p.error(f"--rename: OLD=NEW, got {args.rename!r}")
        rename = tuple(args.rename.split("=", 1))
    print("\n".join(compare(json.loads(args.old.read_text()), json.loads(args.new.read_text()), rename)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
