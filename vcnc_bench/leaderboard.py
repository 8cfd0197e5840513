"""The leaderboard: per id, every controller and agent ranked by the normalised contour score, with its interval
and its verdict, as a page of the docs site generated from bench JSONs.

::

    python -m vcnc_bench.leaderboard bench-out/bench.json [more.json ...] --out docs/leaderboard.md
    vcnc-bench --env VCNC-Heart-v1 --policy ppo:runs/mine/best --leaderboard docs/leaderboard.md   # add yours

**Rows.**  One per id and policy, from the records of ``vcnc-bench --json`` (the default table: the nominal plant)
or of ``vcnc-bench --plants N --json`` (the uncertainty box); an id run on another plant (``--plant NAME``) or on
the shop floor (``--shop-floor``) is a
section of its own, "ID on NAME".  The page's rows are kept beside it
(``leaderboard.json``); the rows of a new JSON replace those of the same id and policy, so a user's policy joins
the board with one command (the bench's ``--leaderboard``).  Each row keeps the command line and the host that
produced it (:mod:`vcnc_bench.provenance`).

**Rank.**  By the normalised score of the max contour error on the nominal plant (:mod:`vcnc_bench.score`:
0 = ``pd-ref``, the reference PD; 1 = the non-causal floor; the figure of merit is the max), the RMS's score
breaking ties.  A row whose id has no ``pd-ref`` or no floor on the board has no score and ranks last.

**Training seeds.**  The records of one training run's seeds (``vcnc-bench --policy ppo:FOLDER`` of a
``vcnc-train --seeds`` folder: one ``"group"``) are one row, ``FOLDER (K seeds)``, as they are one controller in
the verdict: its nominal figures are the seeds' medians, its IQM over every seed's plants.

**Intervals and verdicts.**  Where a row came from a ``--plants`` run: the IQM of the max and RMS contour error
over the sampled plants (and sensor-noise seeds) with its 95 % stratified-bootstrap interval
(:func:`vcnc_bench.verdicts.stratified_bootstrap_ci`), and, for a policy that is not a classical baseline (an
agent, yours), the verdict of :func:`vcnc_bench.verdicts.robust_verdicts` against the strongest causal
controller of the same run: wins or loses only where the paired interval of the difference excludes zero.  A
row from the nominal plant alone carries no verdict ("nominal only"): one plant is no evidence.

**Performance profile** (Agarwal et al. (2021)): for each policy that ran on at least three ids, the fraction of
those ids on which its nominal score of the max is at least tau, tau from 0 to 1, drawn beside the page
(``leaderboard_profile.png``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from pathlib import Path

import numpy as np

from vcnc_gym.schema import BadFile

from .files import read_bench, read_board
from .headroom import NON_CAUSAL
from .score import REFERENCE, normalised_score
from .verdicts import sampled_figures, seed_figures, stratified_bootstrap_ci

__all__ = ["rows_of", "merge", "ranked", "profile", "format_page", "page_files", "board_rows", "write", "main"]

_TRIAL = re.compile(r" \(trial (\d+)\)$")


def _role(policy: str, kind: str | None) -> str:
    if policy.endswith(NON_CAUSAL):
        return "floor"
    if policy == REFERENCE:
        return "reference"
    return "classical" if kind in (None, "baseline") else "learned or yours"


def _finite(v):
    return v if isinstance(v, (int, float)) and math.isfinite(v) else None


def _interval(rec: dict, figure: str):
    x = sampled_figures(rec, figure)
    if x.size == 0:
        return None
    return [_finite(v) for v in stratified_bootstrap_ci(x)]


def _seeds_row(members: list[dict]) -> dict:
    """One row for the records of one training run's seeds (their ``"group"``): judged as one controller, so ranked
    as one.  Its nominal figures are the seeds' medians; its IQM and interval are its verdict's (the bootstrap over
    seeds, plants and noise seeds), or without one over every seed's plants; its verdict is the group's (every
    member carries it)."""
    first = _robust_row(members[0])
    ok = [r for r in members if r["nominal_completed"] and not r["nominal_diverged"]]
    nominal = {
        k: float(np.median([r[f"nominal_{k}"] for r in ok])) if len(ok) == len(members) else None
        for k in ("max_um", "rms_um")
    }
    intervals = {}
    for figure in ("max", "rms"):
        v = (members[0].get("verdicts") or {}).get(figure)
        if v is not None:  # the verdict's own: its bootstrap resamples the seeds with the plants
            intervals[f"iqm_{figure}"] = [_finite(v["iqm_x"]), _finite(v["ci_x"][0]), _finite(v["ci_x"][1])]
            continue
        x = seed_figures(members, figure)  # (seeds, plants, noise): every seed's runs of a plant as its stratum
        x = x.transpose(1, 0, 2).reshape(x.shape[1], -1)
        intervals[f"iqm_{figure}"] = [_finite(v) for v in stratified_bootstrap_ci(x)] if x.size else None
    return {
        **first,
        "policy": f"{members[0]['group']} ({len(members)} seeds)",
        **nominal,
        **intervals,
        "seeds": len(members),
    }


def _robust_row(r: dict) -> dict:
    verdicts = {
        k: {
            "outcome": v["outcome"],
            "opponent": v["y"],
            "difference": [v["difference"], v["low"], v["high"]],
            "controller": v.get("x"),
            "training_seeds": v.get("training_seeds", 1),
        }
        for k, v in (r.get("verdicts") or {}).items()
    }
    ok = r["nominal_completed"] and not r["nominal_diverged"]
    return {
        "env": r["env"],
        "policy": r["policy"],
        "kind": r.get("kind"),
        "max_um": r["nominal_max_um"] if ok else None,
        "rms_um": r["nominal_rms_um"] if ok else None,
        "plants": r["n_samples"],
        "iqm_max": _interval(r, "max"),
        "iqm_rms": _interval(r, "rms"),
        "verdicts": verdicts,
    }


def _nominal_rows(records: list[dict]) -> list[dict]:
    last: dict = {}
    for r in records:
        label = _TRIAL.sub("", r["policy"])
        trial = int(r["trial"]) if r.get("trial") else 0
        if (r["env"], label) not in last or trial >= last[(r["env"], label)][0]:
            last[(r["env"], label)] = (trial, r)
    rows = []
    for (env, label), (_, r) in last.items():
        ok = r["completed"] and not r["diverged"]
        rows.append(
            {
                "env": env,
                "policy": label,
                "kind": r.get("kind"),
                "max_um": r["max_contour_error_um"] if ok else None,
                "rms_um": r["rms_contour_error_um"] if ok else None,
                "plants": 0,
                "iqm_max": None,
                "iqm_rms": None,
                "verdicts": {},
            }
        )
    return rows


def rows_of(bench: dict) -> list[dict]:
    """The board's rows of one ``vcnc-bench --json`` output (default or ``--plants``): one per id and policy (a
    policy that learns across episodes: its last trial), each with the command and host that produced it."""
    if not isinstance(bench, dict) or not isinstance(bench.get("records") or bench.get("robust"), list):
        raise ValueError("expected the object vcnc-bench --json writes, with its 'records' or 'robust' list")
    records = [r for r in bench.get("records") or bench.get("robust") if "table" not in r and "policy" in r]
    robust = [r for r in records if "per_plant" in r]
    groups: dict[str, list[dict]] = {}
    for r in robust:
        if r.get("group"):
            groups.setdefault(r["group"], []).append(r)
    rows = (
        [_robust_row(r) for r in robust if not r.get("group")]
        + [_seeds_row(m) for m in groups.values()]
        + _nominal_rows([r for r in records if "per_plant" not in r])
    )
    settings = bench.get("settings", {})
    # the id run on another plant (--plant) or on the shop floor (--shop-floor) is another section, not the id's rows
    where = [settings["plant"]] if settings.get("plant") else []
    where += ["the shop floor"] if settings.get("shop_floor") else []
    if where:
        for row in rows:
            row["env"] = f"{row['env']} on {' and '.join(where)}"
    prov = settings.get("provenance") or {}
    source = {
        "command": settings.get("command"),
        "cpu": (prov.get("cpu") or {}).get("model"),
        "version": (prov.get("libraries") or {}).get("vcnc-gym"),
    }
    for row in rows:
        row["role"] = _role(row["policy"], row["kind"])
        row["source"] = source
    return rows


def merge(old: list[dict], new: list[dict]) -> list[dict]:
    """``old`` with each row of ``new`` replacing the row of the same id and policy (or added)."""
    keyed = {(r["env"], r["policy"]): r for r in old}
    keyed.update({(r["env"], r["policy"]): r for r in new})
    return list(keyed.values())


def _scores(rows: list[dict]) -> None:
    """Each row's nominal ``score_max`` and ``score_rms`` from its id's ``pd-ref`` and floor rows (None without)."""
    for env in dict.fromkeys(r["env"] for r in rows):
        group = [r for r in rows if r["env"] == env]
        ref = next((r for r in group if r["role"] == "reference"), None)
        floor = next((r for r in group if r["role"] == "floor"), None)
        for r in group:
            for k in ("max", "rms"):
                s = None
                if ref is not None and floor is not None and None not in (ref[f"{k}_um"], floor[f"{k}_um"]):
                    e = r[f"{k}_um"] if r[f"{k}_um"] is not None else math.inf
                    s = _finite(float(normalised_score(e, ref[f"{k}_um"], floor[f"{k}_um"])))
                r[f"score_{k}"] = s


def ranked(rows: list[dict]) -> dict[str, list[dict]]:
    """Per id (in first-seen order), its rows by descending score of the max, then of the RMS (no score last)."""
    _scores(rows)
    out = {}
    for env in dict.fromkeys(r["env"] for r in rows):
        group = [r for r in rows if r["env"] == env]
        out[env] = sorted(
            group, key=lambda r: (r["score_max"] is None, -(r["score_max"] or 0.0), -(r["score_rms"] or 0.0))
        )
    return out


def profile(board: dict[str, list[dict]], taus=None, min_ids: int = 3) -> dict[str, np.ndarray]:
    """Agarwal et al. (2021)'s performance profile over ids: per policy that has a score on at least ``min_ids``
    ids, the fraction of those ids with a nominal max score >= tau, for each tau of ``taus`` (default 0 to 1)."""
    taus = np.linspace(0.0, 1.0, 1001) if taus is None else np.asarray(taus, dtype=np.float64)
    scores: dict[str, list[float]] = {}
    for rows in board.values():
        for r in rows:
            if r["score_max"] is not None:
                scores.setdefault(r["policy"], []).append(r["score_max"])
    return {p: np.mean(np.asarray(s)[:, None] >= taus[None, :], axis=0) for p, s in scores.items() if len(s) >= min_ids}


def _cell(v, fmt="{:.4f}") -> str:
    return "-" if v is None else fmt.format(v)


def _ci(v) -> str:
    if not v or v[0] is None:
        return "-"
    return f"{v[0]:.4g} [{_cell(v[1], '{:.4g}')}, {_cell(v[2], '{:.4g}')}]"


def _verdict(r: dict) -> str:
    if r["role"] != "learned or yours":
        return ""
    if not r["verdicts"]:
        return "nominal only"
    seeds = max(v.get("training_seeds", 1) for v in r["verdicts"].values())
    judged = f" ({seeds} seeds judged as one)" if seeds > 1 else ""
    return "; ".join(f"{k}: {v['outcome']} ({v['opponent']})" for k, v in r["verdicts"].items()) + judged


def format_page(board: dict[str, list[dict]], figure: str | None) -> str:
    """The leaderboard page (MyST Markdown)."""
    lines = [
        "# Leaderboard",
        "",
        "Generated by `python -m vcnc_bench.leaderboard` (module `vcnc_bench.leaderboard`) from bench JSONs; "
        "do not edit by hand.  Per id, every policy ranked by its **normalised contour score** on the nominal "
        f"plant (0 = `{REFERENCE}`, the reference PD loop; 1 = the non-causal floor, never a controller; "
        "`vcnc_bench.score`), of the max contour error, the RMS's breaking ties.  IQM columns: over the "
        "sampled plants of a `--plants` run, with the 95 % stratified-bootstrap interval.  Verdict: a policy "
        "that is not a classical baseline against the strongest causal controller of its run; wins or loses "
        "only where the paired interval of the difference excludes zero.  A run's training seeds are one "
        "row, `FOLDER (K seeds)`: the seeds' median on the nominal plant, the IQM over every seed's plants.",
        "",
        "Add your policy: `vcnc-bench --env ID --policy KIND:ARG [--plants 20] --leaderboard docs/leaderboard.md`.",
        "",
    ]
    if figure:
        lines += [
            f"![performance profile]({figure})",
            "",
            "Performance profile (Agarwal et al. (2021)): the fraction of ids on which a policy's nominal "
            "score of the max is at least tau.",
            "",
        ]
    for env, rows in board.items():
        lines += [
            f"## {env}",
            "",
            "| rank | policy | role | score max | score RMS | max, um | RMS, um | plants | IQM max, um | "
            "IQM RMS, um | verdict |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for i, r in enumerate(rows, start=1):
            lines.append(
                f"| {i} | `{r['policy']}` | {r['role']} | {_cell(r['score_max'])} | "
                f"{_cell(r['score_rms'])} | {_cell(r['max_um'], '{:.4g}')} | {_cell(r['rms_um'], '{:.4g}')} | "
                f"{r['plants'] or '-'} | {_ci(r['iqm_max'])} | {_ci(r['iqm_rms'])} | {_verdict(r)} |"
            )
        commands = sorted({r["source"]["command"] for r in rows if r["source"].get("command")})
        if commands:
            lines += ["", "From: " + "; ".join(f"`{c}`" for c in commands)]
        lines.append("")
    return "\n".join(lines)


def _shown(curves: dict[str, np.ndarray], board: dict[str, list[dict]], most: int = 8) -> list[str]:
    """The curves worth a reader's look, at most ``most``: the floor, the reference, every policy that is not a
    classical baseline, then the classical ones by their mean over tau (the area under the profile)."""
    roles = {r["policy"]: r["role"] for rows in board.values() for r in rows}
    first = [p for p in curves if roles.get(p) in ("floor", "reference", "learned or yours")]
    rest = sorted((p for p in curves if p not in first), key=lambda p: -float(np.mean(curves[p])))
    return (first + rest)[: max(most, len(first))]


def _plot(curves: dict[str, np.ndarray], board: dict[str, list[dict]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    taus = np.linspace(0.0, 1.0, 1001)
    shown = _shown(curves, board)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), gridspec_kw={"width_ratios": [1, 1]})
    cmap = plt.get_cmap("tab10")
    for ax, (lo, title) in zip(axes, ((0.0, "the whole scale"), (0.9, "the last tenth (the strong controllers)"))):
        for i, p in enumerate(shown):
            ax.step(
                taus,
                curves[p],
                where="post",
                label=p,
                color=cmap(i % 10),
                lw=2.0 if i < 3 else 1.4,
                ls="-" if i < 10 else "--",
            )
        ax.set_xlim(lo, 1.0)
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("normalised contour score of the max, tau")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("fraction of ids with score >= tau")
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(
        f"Performance profile over ids (0 = {REFERENCE}, 1 = the floor); {len(curves) - len(shown)} more "
        "policies in the tables",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def page_files(page) -> tuple[Path, Path, Path]:
    """The files of the leaderboard page ``page``: the page (Markdown), its rows (the page's ``.json``) and its
    profile figure (``_profile.png``), all beside it.  ValueError naming ``page`` where they cannot be: a page that
    is its own rows file (``board.json``), a folder, or something other than a regular file (``/dev/null``: the
    rows and the figure would be new files in ``/dev``)."""
    page = Path(page)
    if page.is_dir() or not page.name:
        raise ValueError(f"{page} is a folder; give the page's file name, such as {page / 'leaderboard.md'}")
    data = page.with_name(page.stem + ".json")
    figure = page.with_name(page.stem + "_profile.png")
    if page.suffix == ".json" or data == page:
        raise ValueError(
            f"{page} would be both the page and its rows (PAGE.json beside it); give the Markdown page, "
            f"{page.with_suffix('.md')}, whose rows are kept in {data}"
        )
    for path in (page, data, figure):
        if path.exists() and not path.is_file():
            raise ValueError(
                f"{path} is not a regular file: the page, its rows ({data.name}) and its profile ({figure.name}) "
                "are written side by side; name a page in a folder of yours, such as docs/leaderboard.md"
            )
    return page, data, figure


def board_rows(page) -> list[dict]:
    """The rows kept beside ``page`` (none if it has no ``.json`` yet), checked as :func:`rows_of` builds them
    (:func:`vcnc_bench.files.read_board`); ValueError naming the file and the field."""
    _, data, _ = page_files(page)
    return read_board(data) if data.exists() else []


def _replace(path: Path, content: str) -> None:
    """Write ``content`` to ``path`` through a temporary file beside it, renamed over it: a reader never sees half
    a file, and a failure leaves the old one."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(content)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write(page: Path, new_rows: list[dict], add: bool = True, drop: tuple[str, ...] = ()) -> Path:
    """Merge ``new_rows`` into the board beside ``page`` (its ``leaderboard.json``; replaced unless ``add``), less
    the board's rows of the policies in ``drop`` (a row's policy as the page names it, such as
    ``"ppo:runs/seeds/VCNC-Heart-v1 (5 seeds)"``: a run retired by a newer one), and write the page and its profile
    figure; returns the page.  ValueError naming the page's files where they cannot be (:func:`page_files`), the
    board's rows file where it is not one (:func:`board_rows`), or a policy of ``drop`` that no row of the board
    has."""
    page, data, figure = page_files(page)
    old = board_rows(page) if add else []
    missing = [p for p in drop if not any(r["policy"] == p for r in old)]
    if missing:
        raise ValueError(f"--drop: no row of {data} has the policy {missing[0]!r}")
    rows = merge([r for r in old if r["policy"] not in drop], new_rows)
    board = ranked(rows)
    curves = profile(board)
    if curves:
        _plot(curves, board, figure)
    _replace(data, json.dumps({"rows": rows}, indent=1) + "\n")
    _replace(page, format_page(board, figure.name if curves else None) + "\n")
    return page


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("json", nargs="+", type=Path, help="vcnc-bench --json outputs (default or --plants)")
    p.add_argument("--out", type=Path, default=Path("docs/leaderboard.md"), help="the page (default %(default)s)")
    p.add_argument("--replace", action="store_true", help="start the board afresh instead of adding to it")
    p.add_argument(
        "--drop",
        action="append",
        default=[],
        metavar="POLICY",
        help="remove the board's rows of this policy, as the page names it (e.g. 'ppo:runs/seeds/ID "
        "(5 seeds)', a run a newer one retires); repeatable",
    )
    args = p.parse_args(argv)
    try:  # every file checked before anything is written
        page_files(args.out)
        if not args.replace:
            board_rows(args.out)
    except ValueError as exc:
        p.error(f"--out {exc}")
    rows: list[dict] = []
    for path in args.json:
        try:
            rows = merge(rows, rows_of(read_bench(path)))
        except ValueError as exc:
            p.error(f"{path}: not a vcnc-bench JSON: {exc.problem if isinstance(exc, BadFile) else exc}")
    try:
        page = write(args.out, rows, add=not args.replace, drop=tuple(args.drop))
    except (ValueError, OSError) as exc:
        p.error(str(exc))
    print(f"wrote {page} ({len(rows)} rows from {len(args.json)} JSON file(s))")
    return 0


if __name__ == "__main__":
    sys.exit(main())
