"""``vcnc-bench --plants N``: every policy on the nominal plant, N plants drawn from the uncertainty set and its vertices.

:func:`robust_main` builds every env and policy here (the runs go through :func:`vcnc_bench.robust.evaluate`,
one batch of plants per env), adds the normalised score's reference PD where it applies, and prints the robust
table, the sensor noise's spread, the normalised scores and the verdicts of the learned controllers against the
strongest causal one (:mod:`vcnc_bench.verdicts`); ``--json`` and ``--plots`` write them.
"""

from __future__ import annotations

import json
import sys
import time

from . import robust, score, verdicts
from .arguments import check_sizes
from .headroom import NON_CAUSAL
from .output import add_to_leaderboard, format_table, json_safe
from .policies import default_specs, expand_spec, policy_choices, policy_label, resolve_policy, split_spec
from .provenance import provenance
from .recipes import build_envs, env_kwargs, unique
from .runner import EnvRecipe, label_of

__all__ = ["nominal_floors", "robust_main"]


def robust_main(args, recipes: list[EnvRecipe], parser, wall0: float) -> int:
    """``--plants N``: every policy of every env built here, then :func:`_robust`."""
    envs = build_envs(recipes, parser)
    check_sizes(args, envs, parser)
    runs = []
    for r in recipes:
        specs = r.specs or tuple(s for s in default_specs(envs[r.key]))
        for spec in specs:
            try:
                runs.append((r.key, spec, resolve_policy(spec, envs[r.key])))
            except (ValueError, OSError) as exc:
                parser.error(f"cannot build policy {spec!r} for {r.key}: {exc}")
    if not runs:
        parser.error(f"no policies to run: {policy_choices()}")
    runs = _with_reference(runs, envs)
    code = _robust(args, envs, runs)
    for env in envs.values():
        env.close()
    print(f"total wall time {time.perf_counter() - wall0:.1f} s")
    return code


def _with_reference(runs: list, envs: dict) -> list:
    """``runs`` with the normalised score's reference PD (:data:`vcnc_bench.score.REFERENCE`) added to every env
    it applies to and where it is not already run: a compiled servo law, a fraction of the cheapest run's cost."""
    out = list(runs)
    for env_id in dict.fromkeys(e for e, _, _ in runs):
        if any(label_of(s, p) == score.REFERENCE for e, s, p in runs if e == env_id):
            continue
        try:
            policy = resolve_policy(score.REFERENCE, envs[env_id])
        except ValueError:  # not a contouring env (the positioning env): no score
            continue
        last = max(i for i, (e, _, _) in enumerate(out) if e == env_id)
        out.insert(last + 1, (env_id, score.REFERENCE, policy))
    return out


def nominal_floors(args, envs: dict, runs: list) -> dict:
    """The floor's figures on the nominal plant of every env whose runs hold no floor: the oracle's replay of its
    shipped solution (only for the ids' own configuration: default feedrate and plant, no ``--shop-floor``, seed 0;
    elsewhere a solve costs minutes and the score is left out).  ``{env: {"max_um", "rms_um", "label"}}``."""
    out = {}
    if args.feedrate is not None or args.plant is not None or args.shop_floor or args.seed != 0:
        return out
    for env_id in dict.fromkeys(e for e, _, _ in runs):
        if any(label_of(s, p).endswith(NON_CAUSAL) for e, s, p in runs if e == env_id):
            continue
        env = envs[env_id]
        try:
            oracle = resolve_policy("oracle", env)
        except ValueError:
            continue
        u = env.unwrapped
        batch = robust.make_batch(env_id, 1)
        try:
            res = robust.run_plants(
                oracle, batch, u.nominal_parameters[None], decision_period=u.decision_period, seed=args.seed
            )
        finally:
            batch.close()
        out[env_id] = {
            "max_um": float(res.max_um[0]),
            "rms_um": float(res.rms_um[0]),
            "label": label_of("oracle", oracle),
        }
    return out


def _print_scores(records: list[dict]) -> None:
    """The normalised scores of every record (nominal plant; IQM over the plants where the floor ran on them)."""
    rows = [r for r in records if r.get("score")]
    if not rows:
        return
    first = rows[0]["score"]
    print(
        f"\nNormalised contour score (0 = {first['reference']}, the reference PD; 1 = the non-causal floor), "
        "on the nominal plant, max and RMS contour error (vcnc_bench.score)"
    )
    width = max(len(r["env"]) for r in rows)
    pw = max(len(r["policy"]) for r in rows)
    env = None
    for r in rows:
        if r["env"] != env:
            env = r["env"]
            s = r["score"]
            print(
                f"  {env}: pd-ref {s['reference_nominal_um']['max']:.4g} um, floor "
                f"{s['floor_nominal_um']['max']:.4g} um (max)"
            )
        s = r["score"]
        cell = " ".join("      -" if s[k] is None else f"{s[k]:7.3f}" for k in ("max", "rms"))
        iqm = "".join(
            f"  IQM {k} {s[f'iqm_{k}'][0]:.3f} [{s[f'iqm_{k}'][1]:.3f}, {s[f'iqm_{k}'][2]:.3f}]"
            for k in ("max", "rms")
            if s.get(f"iqm_{k}") and None not in s[f"iqm_{k}"]
        )
        print(f"  {r['env']:<{width}} {r['policy']:<{pw}} {cell}{iqm}")


def _training_seed_groups(args) -> dict:
    """{label of a member: label of the spec it came from} for the ``--policy`` specs that stand for several (the
    seeds of one training run, :func:`vcnc_bench.policies.expand_spec`), judged as one controller."""
    groups = {}
    for spec in unique(args.policy or []):
        members = expand_spec(spec)
        if members != [spec]:
            groups.update({policy_label(m): policy_label(spec) for m in members})
    return groups


def _robust(args, envs: dict, runs: list) -> int:
    """``--plants N``: every run on the nominal plant, N sampled plants and the vertices (vcnc_bench.robust)."""
    from tqdm import tqdm

    code = 0
    trials = args.trials or 1
    kwargs = env_kwargs(args)
    with tqdm(
        total=len(runs),
        unit="run",
        file=sys.stderr,
        dynamic_ncols=True,
        leave=False,
        disable=True if args.no_progress else None,
    ) as bar:
        records, plant_sets = robust.evaluate(
            [(e, label_of(s, p), p) for e, s, p in runs],
            envs,
            args.plants,
            plant_seed=args.plant_seed,
            seed=args.seed,
            trials=trials,
            env_kwargs=kwargs,
            parallel=args.parallel,
            bar=bar,
            noise_seeds=args.noise_seeds,
        )
    score.add_scores(records, nominal_floors(args, envs, runs))
    kinds = {(e, label_of(s, p)): split_spec(s)[0] for e, s, p in runs}
    groups = _training_seed_groups(args)
    for r in records:
        r["kind"] = kinds.get((r["env"], r["policy"]))
        if r["policy"] in groups:
            r["group"] = groups[r["policy"]]
    # every policy that is not a classical baseline (an agent, a user's kind) meets the strongest causal baseline
    learned = {label_of(s, p) for _, s, p in runs if split_spec(s)[0] != "baseline"}
    causal = {
        label_of(s, p) for _, s, p in runs if split_spec(s)[0] == "baseline" and getattr(p, "causal", True) is not False
    }
    verdict_rows = verdicts.robust_verdicts(records, learned, causal, seed=args.seed)
    print(
        f"Contour error over the uncertainty box (um): the nominal plant, median and 95th percentile over "
        f"{args.plants} plants drawn uniformly from the box (plant seed {args.plant_seed}), worst over them and "
        f"the box's vertices where it has at most {robust.MAX_VERTICES}; cycle time in s; a diverged plant counts "
        f"as an infinite error, a contour never finished as an infinite cycle time"
    )
    for env_id, plants in plant_sets.items():
        wall = sum(r["wall_s"] for r in records if r["env"] == env_id)
        print(
            f"  {env_id}: {len(plants.samples)} samples + {len(plants.vertices)} vertices"
            + (
                ""
                if len(plants.vertices)
                else f" (the box has 2^{envs[env_id].unwrapped.plant.box()[0].size} > {robust.MAX_VERTICES})"
            )
            + f", every policy in {wall:.0f} s"
        )
    if any(r["trials"] > 1 for r in records):
        print(f"  policies that learn across episodes: {trials} trials per plant, the last scored")
    print(format_table(records, robust.ROBUST_COLUMNS))
    nominal_bad = [f"{r['env']} {r['policy']}" for r in records if not r["nominal_completed"]]
    if nominal_bad:
        print(f"\nNOT COMPLETE on the nominal plant (diverged or cut short): {', '.join(nominal_bad)}")
    noisy = [r for r in records if "noise" in r]
    if noisy:
        print(
            f"\nSensor noise: every plant over {args.noise_seeds} noise seeds (the figures above: seed 0's); "
            "nominal plant min / median / max over the seeds, median spread (max - min) per sampled plant, IQM "
            "over every (sampled plant, seed) run, um"
        )
        for r in noisy:
            n = r["noise"]
            print(
                f"  {r['env']} {r['policy']}: "
                + "; ".join(
                    f"{k} {n[k]['nominal_min_um']:.4g} / {n[k]['nominal_median_um']:.4g} / {n[k]['nominal_max_um']:.4g}"
                    f", spread {n[k]['median_spread_um']:.3g}, IQM {n[k]['iqm_um']:.4g}"
                    for k in ("max", "rms")
                )
            )
    _print_scores(records)
    if verdict_rows:
        print(
            f"\nVerdicts (vcnc_bench.verdicts): the learned controller X against the strongest causal controller Y "
            f"of each figure, IQM over the {args.plants} sampled plants"
            + (f" x {args.noise_seeds} noise seeds on noisy sensors" if args.noise_seeds > 1 else "")
            + f", 95 % stratified-bootstrap intervals ({verdicts.REPS} replicates); X - Y: the paired bootstrap of "
            "the IQMs' difference (the same plants and noise for both); P(X<Y): X's error the lower (lower is "
            "better); 'wins'/'loses' only when the difference's interval excludes zero, else 'ties'"
        )
        print(verdicts.format_verdicts(verdict_rows))
    if args.json is not None or args.leaderboard is not None:
        settings = {
            "command": args.command,
            "plants": args.plants,
            "plant_seed": args.plant_seed,
            "seed": args.seed,
            "trials": trials,
            "max_vertices": robust.MAX_VERTICES,
            "feedrate": args.feedrate,
            "plant": args.plant,
            "shop_floor": args.shop_floor,
            "noise_seeds": args.noise_seeds,
            "bootstrap": {"reps": verdicts.REPS, "seed": args.seed, "confidence": verdicts.CONFIDENCE},
            "provenance": provenance(),
        }
        out = {
            "settings": settings,
            "robust": [json_safe(r) for r in records],
            "verdicts": [json_safe(r) for r in verdict_rows],
        }
        if args.json is not None:
            args.json.write_text(json.dumps(out, indent=2) + "\n")
            print(f"\nwrote {len(records)} robust records to {args.json}")
        code = add_to_leaderboard(args, out)
    if args.plots is not None:
        for env_id in plant_sets:
            robust.plot_robust([r for r in records if r["env"] == env_id], args.plots / f"{env_id}_robust.png")
        print(f"wrote {len(plant_sets)} plots to {args.plots}")
    return code
