"""The tolerance task's front: cycle time against the contour tolerance T, every opponent and the agents (issue 37).

Issue 37 asks for "the front: cycle time against T for every opponent and the agent", per id, nominal and median
over the plants, with the runs that exceed T.  This module draws and tabulates it from the JSON files the searches
and the bench wrote; it runs nothing:

- **every classical controller** the searches ran (:mod:`tolerance`'s look-ahead search: the
  nominal and per-machine commissionings, the contouring MPC; :mod:`override_schedule`'s
  look-ahead through the dial, on either commissioning): on the nominal plant its fastest run within T (the
  builder's setting of that controller); over the sampled plants the median of each plant's fastest run within T
  (the machine commissioned with that controller), and the plants where it has none;
- **the searches together** (:func:`tolerance.merge_searches`): the builder's setting (the
  fastest of any on the nominal plant) run on every plant, with the plants it takes over T, and the per-plant
  search (the fastest of any per plant), the strongest classical opponent;
- **each group of agents** (a ``vcnc-bench --plants`` JSON of a ``vcnc-train --seeds`` folder): each seed's
  nominal cycle, the median over the seeds' runs on the sampled plants, and the runs over T.

A run over T, or one whose tool did not arrive, is scrap: its cycle time counts as infinite, so a median over a
set that is half scrap or more is infinite (drawn at the panel's top edge as an open marker).  The verdicts by the
rule are :mod:`tolerance`'s ``--agents`` tables; this is the picture and the summary beside
them.

The fronts are listed in a JSON file (``--spec``): a list of ``{"id": ..., "title": ..., "search": [FILE[:ID],
...], "agents": {NAME: BENCH_JSON, ...}}``, the search files relative to the current folder::

    python experiments/tolerance/tolerance_front.py --spec experiments/tolerance/data/searches/fronts.json \\
        --plot experiments/tolerance/figures/tolerance_front.png
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vcnc_gym.envs.feed_override_env import TOLERANCES

from tolerance import Setting, agent_cycles, merge_searches, read_search_entry, scrapped, search_cycles

__all__ = [
    "FrontPoint",
    "Front",
    "read_search",
    "read_agents",
    "agent_records",
    "front",
    "format_front",
    "plot_fronts",
    "main",
]


@dataclass(frozen=True)
class FrontPoint:
    """One opponent or agent group at one tolerance: cycle times (s; inf where scrap) on the nominal plant (one per
    seed for agents) and the median over the sampled plants (and seeds), and the runs over T (or, for a
    controller's per-plant choice, the plants with no run within T) of ``runs`` on the plants of the box."""

    name: str
    kind: str  # "controller", "builder", "per-plant" or "agents"
    tolerance_um: float
    nominal_s: tuple[float, ...]
    median_s: float
    over: int
    runs: int
    choice: str = ""  # the builder's: its controller and setting


@dataclass(frozen=True)
class Front:
    """An id's front: its title and every point, per tolerance."""

    env_id: str
    title: str
    points: tuple[FrontPoint, ...]


def read_search(items: list[str]) -> dict:
    """The searches ``items`` (``FILE`` or ``FILE:ID``, over the same plants) as one
    (:func:`tolerance.merge_searches`)."""
    found = [read_search_entry(item)[1] for item in items]
    return found[0] if len(found) == 1 else merge_searches(found)


def read_agents(path: str, kinds: list[str]) -> list[dict]:
    """The training seeds' records of the ``vcnc-bench --plants`` JSON ``path`` (:func:`agent_records`)."""
    with open(path) as f:
        data = json.load(f)
    return agent_records(data.get("robust", []), kinds, path)


def agent_records(records: list[dict], kinds: list[str], source: str = "the agents") -> list[dict]:
    """The training seeds' records among a bench JSON's ``records``, checked to have run the search's plants
    (``kinds``: the search's plant kinds, the nominal plant first; the bench's first plants are the same draws)."""
    seeds = [r for r in records if r.get("group") and "per_plant" in r]
    if not seeds:
        raise ValueError(f"{source}: no training seeds' records (a vcnc-bench --plants JSON of vcnc-train --seeds)")
    n = len(kinds)
    if any(list(r["per_plant"]["kind"][:n]) != list(kinds) for r in seeds):
        raise ValueError(f"{source}: the agents ran other plants than the search")
    return seeds


def _controller_points(search: dict, t_um: float) -> list[FrontPoint]:
    kinds = np.asarray(search["kinds"])
    sampled, boxed = kinds == "sample", kinds != "nominal"
    points = []
    for name in dict.fromkeys(r["controller"] for r in search["runs"]):
        cycles = np.stack(
            [scrapped(r["cycle_time_s"], r["max_um"], t_um) for r in search["runs"] if r["controller"] == name]
        )
        best = cycles.min(axis=0)  # per plant, the fastest of this controller's settings within T
        points.append(
            FrontPoint(
                name,
                "controller",
                t_um,
                (float(best[0]),),
                float(np.median(best[sampled])),
                int(np.isinf(best[boxed]).sum()),
                int(boxed.sum()),
            )
        )
    return points


def _search_points(search: dict, t_um: float) -> list[FrontPoint]:
    kinds = np.asarray(search["kinds"])
    sampled, boxed = kinds == "sample", kinds != "nominal"
    c = search_cycles(search, 1e-3 * t_um)
    points = [
        FrontPoint(
            "per-plant search",
            "per-plant",
            t_um,
            (float(c.per_plant[0]),),
            float(np.median(c.per_plant[sampled])),
            int(np.isinf(c.per_plant[boxed]).sum()),
            int(boxed.sum()),
        )
    ]
    if c.builder is not None:
        b = c.builder_choice
        points.append(
            FrontPoint(
                "builder's setting",
                "builder",
                t_um,
                (float(c.builder[0]),),
                float(np.median(c.builder[sampled])),
                int(np.isinf(c.builder[boxed]).sum()),
                int(boxed.sum()),
                f"{b['controller']}, {Setting(**b['setting']).label}",
            )
        )
    return points


def _agent_point(name: str, records: list[dict], kinds: list[str], t_um: float) -> FrontPoint:
    kinds = np.asarray(kinds)
    x = agent_cycles(records, kinds.size, t_um)
    boxed = kinds != "nominal"
    return FrontPoint(
        name,
        "agents",
        t_um,
        tuple(float(c) for c in x[:, 0]),
        float(np.median(x[:, kinds == "sample"])),
        int(np.isinf(x[:, boxed]).sum()),
        int(x[:, boxed].size),
    )


def front(env_id: str, title: str, search: dict, agents: dict[str, list[dict]], tolerances=TOLERANCES) -> Front:
    """``env_id``'s front (``title``): ``search``'s controllers, builder's setting and per-plant search, and each
    agent group of ``agents`` ({name: seeds' bench records}), at each tolerance (mm)."""
    points = []
    for tol in tolerances:
        t_um = 1e3 * tol
        points += _controller_points(search, t_um) + _search_points(search, t_um)
        points += [_agent_point(name, records, search["kinds"], t_um) for name, records in agents.items()]
    return Front(env_id, title, tuple(points))


def _s(v: float) -> str:
    return "scrap" if not math.isfinite(v) else f"{v:.4g}"


def format_front(fr: Front) -> str:
    """The Markdown table of a front: per tolerance and point, nominal and median cycle (s) and the runs over T."""
    out = [
        f"{fr.env_id} ({fr.title}):",
        "",
        "| T, um | opponent or agents | nominal cycle, s | median cycle, s | over T or none within T |",
        "|---|---|---|---|---|",
    ]
    for p in fr.points:
        what = "runs over T" if p.kind in ("agents", "builder") else "plants with none within T"
        name = f"{p.name} ({p.choice})" if p.choice else p.name
        out.append(
            f"| {p.tolerance_um:g} | {name} | {', '.join(_s(c) for c in p.nominal_s)} | {_s(p.median_s)} | "
            f"{p.over} of {p.runs} ({what}) |"
        )
    return "\n".join(out)


_AGENT_COLOURS = ("crimson", "darkorange", "darkviolet", "teal")


def _style(kind: str, k_agent: int, k_controller: int) -> dict:
    if kind == "per-plant":
        return dict(color="k", marker="s", lw=2.4, ls="-", alpha=1.0)
    if kind == "builder":
        return dict(color="0.4", marker="D", lw=1.6, ls="--", alpha=1.0)
    if kind == "agents":
        return dict(color=_AGENT_COLOURS[k_agent % len(_AGENT_COLOURS)], marker="o", lw=2.0, ls="-", alpha=1.0)
    return dict(color=f"C{k_controller % 10}", marker=".", lw=0.9, ls=":", alpha=0.7)


def _panel(ax, fr: Front, which: str) -> None:
    """One panel: cycle time against T, ``which`` = "nominal" (the nominal plant; agents: the line through the
    slowest seed, a dot per seed) or "median" (the sampled plants)."""
    names = list(dict.fromkeys(p.name for p in fr.points))
    value = (lambda p: max(p.nominal_s)) if which == "nominal" else (lambda p: p.median_s)  # noqa: E731
    best = [value(p) for p in fr.points if p.kind == "per-plant" and math.isfinite(value(p))]
    finite = [c for p in fr.points for c in (p.nominal_s if which == "nominal" else (p.median_s,)) if math.isfinite(c)]
    low = 0.99 * min(finite) if finite else 0.0
    top = min(max(finite), 1.25 * max(best)) * 1.01 if best else (max(finite) * 1.01 if finite else 1.0)
    k_agent = k_controller = 0
    for name in names:
        pts = [p for p in fr.points if p.name == name]
        style = _style(pts[0].kind, k_agent, k_controller)
        k_agent += pts[0].kind == "agents"
        k_controller += pts[0].kind == "controller"
        t = np.array([p.tolerance_um for p in pts])
        y = np.array([value(p) for p in pts])
        ax.plot(t, np.where(np.isfinite(y), y, np.nan), label=name, ms=5, **style)
        if which == "nominal" and pts[0].kind == "agents":
            seeds = [(p.tolerance_um, c) for p in pts for c in p.nominal_s if math.isfinite(c)]
            ax.plot([a for a, _ in seeds], [c for _, c in seeds], ls="none", marker=".", color=style["color"], ms=4)
        off = ~np.isfinite(y)
        if off.any():  # scrap: at the top edge, open
            ax.plot(
                t[off],
                np.full(off.sum(), top),
                ls="none",
                marker=style["marker"],
                mfc="none",
                color=style["color"],
                ms=8,
                clip_on=False,
            )
    ax.set_xscale("log")
    ax.minorticks_off()
    ax.set_xticks([5, 10, 20], ["5", "10", "20"])
    ax.set_ylim(low, top)
    ax.set_xlabel("contour tolerance T, um")
    ax.set_ylabel("cycle time, s")
    label = "nominal plant (agents: slowest seed)" if which == "nominal" else "median plant"
    ax.set_title(f"{fr.title}: {label}", fontsize=9)
    ax.grid(alpha=0.3)


def plot_fronts(fronts: list[Front], path) -> Path:
    """Draw each front as a row of two panels (the nominal plant, the median plant) into ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(fronts), 2, figsize=(12.5, 3.6 * len(fronts)), squeeze=False)
    for row, fr in zip(axes, fronts):
        _panel(row[0], fr, "nominal")
        _panel(row[1], fr, "median")
        row[1].legend(fontsize=6.5, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.suptitle(
        "The tolerance task's front: the fastest cycle within T (open markers on the top edge: scrap, over T "
        "or unfinished; lines above the top run off the panel)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.45 / fig.get_figheight()))  # room for the title
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _read_spec(path: str) -> list[dict]:
    with open(path) as f:
        spec = json.load(f)
    if not isinstance(spec, list) or not all(isinstance(e, dict) for e in spec):
        raise ValueError(f"{path}: a list of fronts, each {{'id', 'title', 'search': [...], 'agents': {{...}}}}")
    for k, e in enumerate(spec):
        missing = {"id", "title", "search"} - set(e)
        if missing:
            raise ValueError(f"{path}: front {k} lacks {sorted(missing)}")
        if not isinstance(e["search"], list) or not e["search"]:
            raise ValueError(f"{path}: front {k} ({e['id']}): 'search' is a non-empty list of FILE[:ID]")
    return spec


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python experiments/tolerance/tolerance_front.py", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--spec", required=True, help="the fronts, a JSON list (this module's docstring)")
    parser.add_argument("--plot", help="draw the fronts into this PNG")
    args = parser.parse_args(argv)
    try:
        spec = _read_spec(args.spec)
        fronts = []
        for e in spec:
            search = read_search(e["search"])
            agents = {name: read_agents(p, search["kinds"]) for name, p in e.get("agents", {}).items()}
            fronts.append(front(e["id"], e["title"], search, agents))
    except (OSError, ValueError, KeyError) as err:
        parser.error(f"--spec {args.spec}: {err}")
    for fr in fronts:
        print(format_front(fr) + "\n")
    if args.plot:
        print(f"wrote {plot_fronts(fronts, args.plot)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
