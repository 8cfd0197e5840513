"""An agent's training seeds on the box, from a ``vcnc-bench --plants N --policy ppo:FOLDER --json`` file.

    python experiments/specialists/seed_verdicts.py experiments/specialists/data/shop_seeds/VCNC-HeartShop-v1.json \
        [--base ff-ccc] [--within 5 10 20]
    python experiments/specialists/seed_verdicts.py experiments/specialists/data/ideal_seeds/VCNC-Corners-v1.json \
        --with experiments/classical-opponents/data/mpc_box/VCNC-Corners-v1.json
    python experiments/specialists/seed_verdicts.py --summary \
        experiments/generalists/data/generalist_seeds/current_feed_drive/*.json
    python experiments/specialists/seed_verdicts.py --summary experiments/specialists/data/*_seeds/VCNC-*.json \
        --before experiments/specialists/data/ideal_seeds_5 --before experiments/specialists/data/shop_seeds_5

``ppo:FOLDER`` of a ``vcnc-train --seeds K`` folder stands for the K seeds' agents, judged as one controller
(``vcnc_bench.verdicts``).  Prints Markdown: every record's nominal / median / worst max and RMS contour error and
its own IQM of the max with its interval (a seed's row is that seed's spread), then the verdict rows the bench
wrote, then the seeds against their own base (the classical controller their residual corrects) by the same rule.
Every figure comes from the JSON; nothing is typed.

``--with OTHER.json`` (repeatable) joins the records of another ``--plants`` run of the same id, plants and settings (a
controller added to the house after the seeds were evaluated, such as ``mpc``, whose run is costly; or another
training run's seeds) and judges the agents again, by the bench's own rule
(:func:`vcnc_bench.verdicts.robust_verdicts`), against the strongest causal controller of the two runs together;
``--only POLICY`` joins that policy's records only (an old run's costly controllers, not its agents).  Where the floor
joins (``vcnc-bench --plants N --policy oracle``, run apart: a search per plant), every record's normalised score is
computed again plant by plant (:func:`vcnc_bench.score.add_scores`) and the table gets its IQM.  ``--json
OUT`` writes the joined run.  ``--against GROUP`` judges every training run against the seeds of
``GROUP`` (an ablation: the same recipe with one thing changed, "wins" where the run is better).  Runs whose settings
differ (plants, plant seed, reset seed, trials, vertices, feed, plant, noise seeds, shop floor) are refused, since their
plants cannot be paired.  ``--within T ...`` (um) adds a table: per policy, whether its max contour error on the
nominal plant is within each contour tolerance T, and on how many sampled plants.
"""

from __future__ import annotations

import argparse
import json

from vcnc_bench.headroom import NON_CAUSAL
from vcnc_bench.score import add_scores
from vcnc_bench.verdicts import iqm, robust_verdicts, sampled_figures, seed_figures, stratified_bootstrap_ci, verdict

#: The settings two ``--plants`` runs must share for their records to be paired plant by plant.
PAIRED_SETTINGS = (
    "plants",
    "plant_seed",
    "seed",
    "trials",
    "max_vertices",
    "feedrate",
    "plant",
    "noise_seeds",
    "shop_floor",
)

#: The value of a setting a run's JSON does not hold: written before the setting existed, it ran without it.
SETTING_DEFAULTS = {"shop_floor": False}


def _f(v) -> str:
    return "inf" if v is None else f"{v:.4g}"


def _score(v) -> str:
    """A normalised score (None: -inf, a diverged plant, or no score)."""
    return "-" if v is None else f"{v:.3f}"


def tables(data: dict, base: str) -> list[str]:
    """The Markdown lines of one JSON (one env)."""
    records = data["robust"]
    env = records[0]["env"]
    scored = any((r.get("score") or {}).get("iqm_max") for r in records)  # the floor ran on the plants
    out = [
        f"**{env}** (`{data['settings']['command']}`)",
        "",
        "| policy | max nominal / median / worst, um | RMS nominal / median / worst, um | IQM max [95 % CI], um |"
        + (" score of the max, IQM [95 % CI] |" if scored else ""),
        "|---|---|---|---|" + ("---|" if scored else ""),
    ]
    for r in records:
        if r["policy"] == "pd-ref":
            continue
        iqm = stratified_bootstrap_ci(sampled_figures(r, "max"), seed=0)
        s = (r.get("score") or {}).get("iqm_max") or [None] * 3
        out.append(
            f"| `{r['policy']}` | {_f(r['nominal_max_um'])} / {_f(r['median_max_um'])} / "
            f"{_f(r['worst_max_um'])} | {_f(r['nominal_rms_um'])} / {_f(r['median_rms_um'])} / "
            f"{_f(r['worst_rms_um'])} | {_f(iqm[0])} [{_f(iqm[1])}, {_f(iqm[2])}] |"
            + (f" {_score(s[0])} [{_score(s[1])}, {_score(s[2])}] |" if scored else "")
        )
    out += [
        "",
        "| learned X | fig | X IQM [95 % CI] | strongest causal Y | Y IQM [95 % CI] | X - Y [95 % CI] | "
        "P(X<Y) | verdict |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for v in data["verdicts"]:
        seeds = v.get("training_seeds", 1)
        out.append(
            f"| `{v['x']}`{f' ({seeds} seeds)' if seeds > 1 else ''} | {v['figure']} | {_f(v['iqm_x'])} "
            f"[{_f(v['ci_x'][0])}, {_f(v['ci_x'][1])}] | `{v['y']}` | {_f(v['iqm_y'])} [{_f(v['ci_y'][0])}, "
            f"{_f(v['ci_y'][1])}] | {_f(v['difference'])} [{_f(v['low'])}, {_f(v['high'])}] | "
            f"{v['p_improvement']:.2f} | {v['outcome']} |"
        )
    out += [""] + [line[0].upper() + line[1:] for line in _against_base(records, base)]
    absent = _not_run_names(records)
    if absent:
        out += ["", f"Not in this run, so not weighed by its verdicts: the causal controllers of {env} {absent}."]
    return out


def _not_run_names(records: list[dict]) -> str:
    """:func:`not_run` of a run's records, as Markdown names ('' when none)."""
    return ", ".join(f"`{n}`" for n in not_run(records[0]["env"], {r["policy"] for r in records}))


def not_run(env_id: str, policies: set[str]) -> list[str]:
    """The causal controllers of :mod:`vcnc_baselines` that apply to ``env_id`` (the floor's starts,
    :func:`vcnc_baselines.optimal.search.causal_names`) and have no record among ``policies``: a verdict names the
    strongest of those that ran (a learning controller's ``NAME (trial K)`` counts as ``NAME``).  Empty for an id that
    is not registered."""
    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)
    from vcnc_baselines.optimal.search import causal_names

    if env_id not in gym.registry:
        return []
    env = gym.make(env_id)
    try:
        ran = {p.split(" (trial ")[0] for p in policies}  # a learning controller's label names its trial
        return [n for n in causal_names(env) if n not in ran]
    finally:
        env.close()


def within(records: list[dict], tolerances: list[float]) -> list[str]:
    """The Markdown lines of a table: per record, whether its max contour error on the nominal plant is within each
    tolerance T (um), and on how many of the sampled plants it is (a diverged run is not; a part over T is
    scrapped, issue 37)."""
    head = " | ".join(f"within {t:g} um: nominal, sampled plants" for t in tolerances)
    out = [f"| policy | {head} |", "|---|" + "---|" * len(tolerances)]
    for r in records:
        if r["policy"] == "pd-ref":
            continue
        x = sampled_figures(r, "max")
        x = x.reshape(x.shape[0], -1).max(axis=1)  # with noise seeds: a plant is within T if every seed is
        nominal = r["nominal_max_um"]
        cells = [
            f"{'yes' if nominal is not None and nominal <= t else 'no'}, {int((x <= t).sum())} of {x.size}"
            for t in tolerances
        ]
        out.append(f"| `{r['policy']}` | " + " | ".join(cells) + " |")
    return out


def run_name(data: dict) -> str:
    """The id of a run's JSON, with the plant it ran on (``--plant``) and ``shop floor`` (``--shop-floor``)."""
    settings = data["settings"]
    extra = [f"`{settings['plant']}`"] if settings.get("plant") else []
    extra += ["shop floor"] if settings.get("shop_floor") else []
    return data["robust"][0]["env"] + (f" ({', '.join(extra)})" if extra else "")


def base_of(bases: list[str], env: str) -> str:
    """The base of ``env`` among ``--base`` entries: ``ID=NAME`` for that id, else a plain ``NAME``, else
    ``ff-ccc``."""
    own = [b.split("=", 1)[1] for b in bases if b.startswith(f"{env}=")]
    plain = [b for b in bases if "=" not in b]
    return (own or plain or ["ff-ccc"])[-1]


def summary(runs: list[dict], base: str | list[str]) -> list[str]:
    """One Markdown table over several runs (one id each): every training run's seeds against the strongest causal
    controller, figure by figure, then a line per id against their ``base``; what the studies' seed tables
    hold (``experiments/specialists/README.md``)."""
    rows = [
        "| id | fig | seeds' IQM [95 % CI] | strongest causal Y | Y IQM [95 % CI] | X - Y [95 % CI] | P(X<Y) | "
        "verdict |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines = []
    for data in runs:
        records = data["robust"]
        name = run_name(data)
        for v in (v for v in data["verdicts"] if v.get("training_seeds", 1) > 1):
            rows.append(
                f"| {name} | {v['figure']} | {_f(v['iqm_x'])} [{_f(v['ci_x'][0])}, {_f(v['ci_x'][1])}] | "
                f"`{v['y']}` | {_f(v['iqm_y'])} [{_f(v['ci_y'][0])}, {_f(v['ci_y'][1])}] | "
                f"{_f(v['difference'])} [{_f(v['low'])}, {_f(v['high'])}] | {v['p_improvement']:.2f} | "
                f"{v['outcome']} |"
            )
        own = base_of([base] if isinstance(base, str) else base, records[0]["env"])
        lines += [f"- {name}: {line}" for line in _against_base(records, own)]
        absent = _not_run_names(records)
        if absent:
            lines.append(f"- {name}: not in the run, so not weighed by its verdicts: {absent}.")
    return rows + [""] + spread(runs) + [""] + lines


def changes(pairs: list[tuple[dict, dict]]) -> list[str]:
    """Per id and figure, the verdict of an earlier run's training seeds (``before``) beside this run's (``now``),
    each against the strongest causal controller of its own run; pairs of (before, now) runs of one id each."""
    out = [
        "| id | fig | before: seeds, verdict (against) | now: seeds, verdict (against) | changed |",
        "|---|---|---|---|---|",
    ]
    n = 0
    for before, now in pairs:
        name = now["robust"][0]["env"]
        for figure in ("max", "rms"):
            cells = []
            for data in (before, now):
                v = next(
                    (v for v in data["verdicts"] if v.get("training_seeds", 1) > 1 and v["figure"] == figure), None
                )
                cells.append(None if v is None else (v["training_seeds"], v["outcome"], v["y"]))
            moved = None not in cells and cells[0][1] != cells[1][1]
            n += moved
            text = ["-" if c is None else f"{c[0]}, {c[1]} (`{c[2]}`)" for c in cells]
            out.append(f"| {name} | {figure} | {text[0]} | {text[1]} | {'**yes**' if moved else 'no'} |")
    return out + ["", f"{n} of {2 * len(pairs)} verdicts changed."]


def spread(runs: list[dict]) -> list[str]:
    """The training seeds' spread: per id and training run, the lowest and highest of the seeds' own IQMs (over
    the run's plants) of the max and of the RMS contour error."""
    out = [
        "| id | training run | seeds | seeds' IQM of the max, lowest - highest, um | of the RMS, um |",
        "|---|---|---|---|---|",
    ]
    for data in runs:
        records = data["robust"]
        name = run_name(data)
        for run in dict.fromkeys(r["group"] for r in records if r.get("group")):
            members = [r for r in records if r.get("group") == run]
            cells = []
            for figure in ("max", "rms"):
                iqms = [iqm(sampled_figures(r, figure)) for r in members]
                cells.append(f"{_f(min(iqms))} - {_f(max(iqms))}")
            out.append(f"| {name} | `{run}` | {len(members)} | {cells[0]} | {cells[1]} |")
    return out


def _against_base(records: list[dict], base: str) -> list[str]:
    """Per training run of ``records``: its seeds as one against ``base`` (the controller the residual corrects)."""
    against = next((r for r in records if r["policy"] == base), None)
    out = []
    for run in dict.fromkeys(r["group"] for r in records if r.get("group")) if against is not None else ():
        members = [r for r in records if r.get("group") == run]
        cells = []
        for figure in ("max", "rms"):
            v = verdict(
                seed_figures(members, figure),
                sampled_figures(against, figure),
                figure=figure,
                x_label=run,
                y_label=base,
            )
            cells.append(f"{figure} {v.outcome}, X - Y {_f(v.difference)} [{_f(v.low)}, {_f(v.high)}] um")
        out.append(f"the {len(members)} seeds of `{run}` against `{base}`: " + "; ".join(cells) + ".")
    return out


def ablation(records: list[dict], against: str) -> list[str]:
    """Every training run of ``records`` against the seeds of the run ``against`` (both resampled with the plants:
    :func:`vcnc_bench.verdicts.verdict` with seeds on both sides), by figure."""
    groups = {}
    for r in records:
        if r.get("group"):
            groups.setdefault(r["group"], []).append(r)
    if against not in groups:
        raise ValueError(f"no training run {against!r} among {sorted(groups)}")
    out = [
        f"| run X | seeds | fig | X IQM [95 % CI] | `{against}` IQM [95 % CI] | X - Y [95 % CI] | P(X<Y) | verdict |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for run, members in groups.items():
        if run == against:
            continue
        for figure in ("max", "rms"):
            v = verdict(
                seed_figures(members, figure),
                seed_figures(groups[against], figure),
                figure=figure,
                x_label=run,
                y_label=against,
            )
            out.append(
                f"| `{run}` | {len(members)} | {figure} | {_f(v.iqm_x)} [{_f(v.ci_x[0])}, {_f(v.ci_x[1])}] | "
                f"{_f(v.iqm_y)} [{_f(v.ci_y[0])}, {_f(v.ci_y[1])}] | {_f(v.difference)} [{_f(v.low)}, "
                f"{_f(v.high)}] | {v.p_improvement:.2f} | {v.outcome} |"
            )
    return out


def _causal(rec: dict) -> bool:
    return rec.get("kind") == "baseline" and not rec["policy"].endswith(NON_CAUSAL)


def join(data: dict, other: dict, other_name: str = "the other run", only: tuple[str, ...] = ()) -> dict:
    """``data`` with the records of ``other`` it lacks (controllers and agents; with ``only``, those policies'
    only), and its verdicts judged again by :func:`vcnc_bench.verdicts.robust_verdicts` (the reset seed of
    ``data``'s settings); ValueError where the two runs' settings or plants differ, or a policy of ``only`` is not
    in ``other``."""
    a, b = data["settings"], other["settings"]

    def get(settings, k):
        return settings.get(k, SETTING_DEFAULTS.get(k))

    differ = [k for k in PAIRED_SETTINGS if get(a, k) != get(b, k)]
    if differ:
        raise ValueError(
            f"{other_name} was not run on the same plants: its settings differ in "
            + ", ".join(f"{k} ({get(a, k)!r} against {get(b, k)!r})" for k in differ)
        )
    envs = {r["env"] for r in data["robust"]}
    have = {(r["env"], r["policy"]) for r in data["robust"]}
    absent = [p for p in only if not any(r["policy"] == p for r in other["robust"])]
    if absent:
        raise ValueError(f"{other_name} has no records of {absent[0]!r}")
    added = [
        r
        for r in other["robust"]
        if r["env"] in envs and (r["env"], r["policy"]) not in have and (not only or r["policy"] in only)
    ]
    for r in added:
        mine = next(m for m in data["robust"] if m["env"] == r["env"])
        if r["per_plant"]["kind"] != mine["per_plant"]["kind"]:
            raise ValueError(
                f"{other_name}'s {r['policy']} on {r['env']} ran other plants "
                f"({len(r['per_plant']['kind'])} against {len(mine['per_plant']['kind'])})"
            )
    records = [dict(r) for r in data["robust"]] + [dict(r) for r in added]
    learned = {r["policy"] for r in records if r.get("kind") not in (None, "baseline")}
    causal = {r["policy"] for r in records if _causal(r)}
    rows = robust_verdicts(records, learned, causal, seed=a.get("seed", 0))
    if any(r["policy"].endswith(NON_CAUSAL) for r in added):  # the floor ran on these plants: scores per plant
        add_scores(records, seed=a.get("seed", 0))
    command = a["command"] + f"  # joined with{' the ' + ', '.join(only) + ' of' if only else ''}: {b['command']}"
    return {"settings": dict(a, command=command), "robust": records, "verdicts": rows}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("json_files", nargs="+", metavar="JSON", help="vcnc-bench --plants N --json files")
    p.add_argument(
        "--base",
        action="append",
        default=[],
        metavar="[ID=]NAME",
        help="the controller the agents' residual corrects (default ff-ccc); ID=NAME for one id's run "
        "(repeatable: with --summary, one per id)",
    )
    p.add_argument(
        "--with",
        dest="other",
        metavar="OTHER",
        action="append",
        default=[],
        help="another --plants run of the same id and plants: the records this one lacks (controllers and "
        "agents) join it, and the verdicts are judged again (repeatable: joined in the order given)",
    )
    p.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="POLICY",
        help="with --with: join this policy's records only (repeatable; default every one this run lacks)",
    )
    p.add_argument("--json", metavar="OUT", help="with --with and one JSON: write the joined run here")
    p.add_argument("--summary", action="store_true", help="one table of every JSON's seeds' verdicts")
    p.add_argument(
        "--before",
        metavar="DIR",
        action="append",
        default=[],
        help="with --summary: the verdicts of the JSON of the same name in DIR (an earlier run's seeds; "
        "repeatable, the first DIR that has it) beside this run's, and how many changed",
    )
    p.add_argument("--against", metavar="GROUP", help="judge every training run against the seeds of GROUP")
    p.add_argument(
        "--within",
        nargs="+",
        type=float,
        metavar="T",
        help="contour tolerances, um: per policy, whether the nominal plant's max is within each, and on "
        "how many sampled plants",
    )
    args = p.parse_args(argv)
    if args.within and any(not t > 0 for t in args.within):
        p.error(f"--within: a tolerance is a positive number of um, got {min(args.within)!r}")
    if args.summary:
        runs = [json.loads(open(path).read()) for path in args.json_files]
        print("\n".join(summary(runs, args.base)))
        if args.before:
            from pathlib import Path

            old = []
            for path in args.json_files:
                found = [Path(d) / Path(path).name for d in args.before if (Path(d) / Path(path).name).is_file()]
                if not found:
                    p.error(f"--before: no {Path(path).name} in {', '.join(args.before)}")
                old.append(json.loads(found[0].read_text()))
            print("\n" + "\n".join(changes(list(zip(old, runs)))))
        return 0
    if args.json and not (args.other and len(args.json_files) == 1):
        p.error("--json needs --with and one JSON")
    if args.only and not args.other:
        p.error("--only needs --with")
    for path in args.json_files:
        with open(path) as f:
            data = json.load(f)
        for other in args.other:
            with open(other) as f:
                data = join(data, json.load(f), other, tuple(args.only))
        if args.json:
            with open(args.json, "w") as f:
                json.dump(data, f, indent=1)
        print("\n".join(tables(data, base_of(args.base, data["robust"][0]["env"]))) + "\n")
        if args.against:
            print("\n".join(ablation(data["robust"], args.against)) + "\n")
        if args.within:
            print("\n".join(within(data["robust"], args.within)) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
