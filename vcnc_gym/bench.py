"""``vcnc-bench``: every baseline on every VCNC contour, beside seed 000's Table 4.

Runs each policy for one deterministic episode on the nominal plant of each
registered env and prints max, mean and RMS contour error (um) with the
paper's maximum beside ours::

    vcnc-bench                                  # all baselines x all envs
    vcnc-bench --env VCNC-Omega-v0 --policy qft --policy smc
    vcnc-bench --json bench.json --plots bench-plots

A policy is named by a spec: a bare name is a baseline of the ``baselines``
package (``qft``, ``smc``, ``fuzzy``); ``KIND:ARGUMENT`` picks a policy
factory from :data:`POLICY_KINDS` (``baseline:qft`` is the long form); a
trained agent is ``ppo:PATH`` (its folder) and the bare ``ppo`` is the agent
shipped for the env in ``agents/trained/``.  By default the bench runs every
baseline and the shipped agents.  :func:`resolve_policy` is the one place
that turns a spec into a policy.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any, Callable

import gymnasium as gym

from . import ENV_IDS
from .evaluation import EpisodeResult, plot_contour_errors, plot_contours, run_episode

__all__ = ["PAPER_TABLE_4", "POLICY_KINDS", "resolve_policy", "policy_label", "format_table", "main"]

#: Seed 000 (Jahanpour et al. 2014), Table 4 "Simulation results for the
#: contour following tasks with the designed controllers": maximum contour
#: error in um and the paper's "average contour error (%)", per contour and
#: controller (FC = "fuzzy", SMC = "smc", QFT = "qft").  The only copy of
#: these numbers in the package.
PAPER_TABLE_4: dict[tuple[str, str], dict[str, float]] = {
    ("VCNC-Heart-v0", "fuzzy"): {"max_contour_error_um": 35.5, "average_contour_error_percent": 18.54},
    ("VCNC-Heart-v0", "smc"): {"max_contour_error_um": 13.16, "average_contour_error_percent": 3.25},
    ("VCNC-Heart-v0", "qft"): {"max_contour_error_um": 10.14, "average_contour_error_percent": 3.34},
    ("VCNC-Omega-v0", "fuzzy"): {"max_contour_error_um": 44.19, "average_contour_error_percent": 17.82},
    ("VCNC-Omega-v0", "smc"): {"max_contour_error_um": 28.22, "average_contour_error_percent": 9.46},
    ("VCNC-Omega-v0", "qft"): {"max_contour_error_um": 27.33, "average_contour_error_percent": 6.91},
}


# -- policies ------------------------------------------------------------------------
def _baselines():
    """The ``baselines`` package, or None if it cannot be imported."""
    try:
        import baselines
    except ImportError:
        return None
    return baselines


def _baseline_names() -> list[str]:
    b = _baselines()
    return list(b.names()) if b is not None and hasattr(b, "names") else []


def _make_baseline(name: str, env) -> Any:
    b = _baselines()
    if b is None:
        raise ValueError("the baselines package cannot be imported")
    return b.make(name, env)


def _agents():
    """The ``agents`` package, or None if it (or Stable-Baselines3) cannot be imported."""
    try:
        import agents
    except ImportError:
        return None
    return agents


def _shipped_agent(env_id: str):
    """Folder of the agent shipped for ``env_id``, or None."""
    a = _agents()
    folder = a.TRAINED.get(env_id) if a is not None else None
    return folder if folder is not None and folder.is_dir() else None


def _load_ppo(path: str, env) -> Any:
    """A trained PPO agent: folder with model.zip, vecnormalize.pkl, config.yml; "" = the one shipped for env."""
    a = _agents()
    if a is None:
        raise ValueError("ppo agents need the agents extra: pip install 'vcnc-gym[agents]'")
    if path == "":
        env_id = env.unwrapped.spec.id if env.unwrapped.spec is not None else None
        path = _shipped_agent(env_id)
        if path is None:
            raise ValueError(f"no agent is shipped for {env_id}; give its folder as ppo:PATH")
    return a.load_agent(path, env)


#: Policy kind -> factory(argument, env) returning an object with SB3's predict.
#: A spec "KIND:ARGUMENT" calls ``POLICY_KINDS[KIND](ARGUMENT, env)``; a bare
#: name is ``baseline:NAME``; ``ppo:PATH`` is a trained agent's folder (a
#: run's ``best``) and the bare ``ppo`` the agent shipped for the env
#: (``agents/trained/<env id>``).
POLICY_KINDS: dict[str, Callable[[str, gym.Env], Any]] = {
    "baseline": _make_baseline,
    "ppo": _load_ppo,
}


def _split_spec(spec: str) -> tuple[str, str]:
    kind, sep, arg = spec.partition(":")
    if sep:
        return kind, arg
    # a bare name: a baseline, or a kind with its default argument ("ppo": the shipped agent)
    return (spec, "") if spec in POLICY_KINDS and spec not in _baseline_names() else ("baseline", spec)


def policy_label(spec: str) -> str:
    """Label of a policy spec in the table and the JSON: the baseline name, or the spec itself."""
    kind, arg = _split_spec(spec)
    return arg if kind == "baseline" else spec


def _policy_choices() -> str:
    names = ", ".join(_baseline_names()) or "(none: the baselines package cannot be imported)"
    kinds = ", ".join(sorted(POLICY_KINDS))
    return f"baselines: {names}; or KIND:ARGUMENT with KIND one of: {kinds}"


def check_policy_spec(spec: str) -> None:
    """Raise ValueError, naming the valid choices, if ``spec`` names no known policy."""
    kind, arg = _split_spec(spec)
    if kind not in POLICY_KINDS:
        raise ValueError(f"unknown policy kind {kind!r} in {spec!r}; valid policies are {_policy_choices()}")
    if kind == "baseline" and arg not in _baseline_names():
        raise ValueError(f"unknown policy {spec!r}; valid policies are {_policy_choices()}")


def resolve_policy(spec: str, env) -> Any:
    """Turn a policy spec into a policy for ``env`` (an object with SB3's ``predict``).

    Parameters
    ----------
    spec : str
        ``"qft"`` (a baseline name) or ``"KIND:ARGUMENT"`` with KIND a key
        of :data:`POLICY_KINDS` (``"baseline:qft"``).
    env : gymnasium.Env
        The env the policy will run on.

    Raises
    ------
    ValueError
        For an unknown spec; the message lists the valid ones.
    """
    check_policy_spec(spec)
    kind, arg = _split_spec(spec)
    return POLICY_KINDS[kind](arg, env)


# -- the table -------------------------------------------------------------------------
_COLUMNS = [
    # header, width, record key, format
    ("env", 14, "env", "{}"),
    ("policy", 10, "policy", "{}"),
    ("max_um", 10, "max_contour_error_um", "{:.2f}"),
    ("mean_um", 10, "mean_contour_error_um", "{:.2f}"),
    ("rms_um", 10, "rms_contour_error_um", "{:.2f}"),
    ("paper_max_um", 12, "paper_max_contour_error_um", "{:.2f}"),
    ("ours/paper", 10, "ratio_to_paper", "{:.2f}"),
    ("steps", 7, "episode_steps", "{:d}"),
    ("wall_s", 7, "wall_s", "{:.2f}"),
    ("diverged", 8, "diverged", "{}"),
]


def _cell(value, fmt: str) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    return fmt.format(value)


def format_table(records: list[dict]) -> str:
    """The records as a fixed-width table in the shape of seed 000's Table 4 (errors in um)."""
    columns = [(h, max([w] + [len(str(r.get(key))) for r in records]) if key == "policy" else w, key, fmt)
               for h, w, key, fmt in _COLUMNS]
    lines = [" ".join(f"{h:>{w}}" if i > 1 else f"{h:<{w}}" for i, (h, w, _, _) in enumerate(columns))]
    lines.append("-" * len(lines[0]))
    previous_env = None
    for rec in records:
        if previous_env is not None and rec["env"] != previous_env:
            lines.append("")
        previous_env = rec["env"]
        cells = []
        for i, (_, w, key, fmt) in enumerate(columns):
            c = _cell(rec.get(key), fmt)
            cells.append(f"{c:>{w}}" if i > 1 else f"{c:<{w}}")
        lines.append(" ".join(cells))
    return "\n".join(lines)


def _record(env_id: str, label: str, result: EpisodeResult, compare: bool = True) -> dict:
    paper = PAPER_TABLE_4.get((env_id, label), {}).get("max_contour_error_um") if compare else None
    ratio = result.max_contour_error_um / paper if paper else None
    return {
        "env": env_id,
        "policy": label,
        "max_contour_error_um": result.max_contour_error_um,
        "mean_contour_error_um": result.mean_contour_error_um,
        "rms_contour_error_um": result.rms_contour_error_um,
        "paper_max_contour_error_um": paper,
        "ratio_to_paper": ratio,
        "episode_steps": result.episode_steps,
        "wall_s": result.wall_s,
        "diverged": result.diverged,
        "max_tracking_error_um": result.max_tracking_error_um,
    }


def _json_safe(rec: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in rec.items()}


def _stability_lines(dts: list[float]) -> list[str]:
    """Seed 000 eq. (11) for the QFT loop, if the baselines package offers it."""
    b = _baselines()
    if b is None or not hasattr(b, "robust_stability_peak"):
        return []
    mu = getattr(b, "MU", None)
    head = "QFT robust-stability peak max|T(jw)| over the uncertainty box, seed 000 eq. (11)"
    lines = [head + (f" (bound mu = {mu:g}):" if mu is not None else ":")]
    for axis in ("x", "y"):
        try:
            parts = [f"{b.robust_stability_peak(axis=axis):.3f} continuous"]
            parts += [f"{b.robust_stability_peak(axis=axis, dt=dt):.3f} sampled at dt = {dt:g} s" for dt in dts]
            lines.append(f"  {axis}: " + ", ".join(parts))
        except Exception as exc:  # report, do not lose the table for it
            lines.append(f"  {axis}: not available ({type(exc).__name__}: {exc})")
    return lines


# -- command line -------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vcnc-bench",
        description="Run the contouring baselines on the VCNC envs (nominal plant, one deterministic "
                    "episode each) and compare with seed 000's Table 4.",
    )
    p.add_argument("--env", action="append", metavar="ID",
                   help=f"env id, repeatable (default: all of {', '.join(ENV_IDS)})")
    p.add_argument("--policy", action="append", metavar="SPEC",
                   help="baseline name, 'ppo' (the agent shipped for the env) or KIND:ARGUMENT such as "
                        "ppo:RUN/best, repeatable (default: every baseline and the shipped agent)")
    p.add_argument("--seed", type=int, default=0, help="seed passed to env.reset (default 0)")
    p.add_argument("--feedrate", type=float, metavar="MM_PER_S",
                   help="S-curve feedrate in mm/s (default: the env's, seed 000's 100 mm/s); "
                        "with another value the paper's columns stay empty")
    p.add_argument("--json", metavar="PATH", type=Path, help="write one record per run to this JSON file")
    p.add_argument("--plots", metavar="DIR", type=Path,
                   help="write ENV_contour.png and ENV_error.png per env into this directory")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    return p


#: Seed 000, section 3: the feedrate of every contour following task, mm/s.
PAPER_FEEDRATE = 100.0


def _make_env(env_id: str, feedrate: float | None, parser):
    """The env of ``env_id``; another feedrate also gets a time limit that fits it."""
    if feedrate is None:
        return gym.make(env_id)
    try:
        steps = gym.make(env_id, feedrate=feedrate).unwrapped.episode_steps
    except ValueError as exc:
        parser.error(str(exc))
    return gym.make(env_id, feedrate=feedrate, max_episode_steps=steps)


def _unique(items):
    return list(dict.fromkeys(items))


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vcnc-bench``; returns the exit code (argument errors exit with 2)."""
    wall0 = time.perf_counter()
    parser = _parser()
    args = parser.parse_args(argv)

    env_ids = _unique(args.env or list(ENV_IDS))
    unknown = [e for e in env_ids if e not in ENV_IDS]
    if unknown:
        parser.error(f"unknown env id(s) {', '.join(map(repr, unknown))}; valid ids are {', '.join(ENV_IDS)}")
    specs = _unique(args.policy or _baseline_names())
    if not specs:
        parser.error(f"no policies to run: {_policy_choices()}")
    for spec in specs:
        try:
            check_policy_spec(spec)
        except ValueError as exc:
            parser.error(str(exc))

    # build every env and policy first, so a bad spec fails before any run
    envs = {env_id: _make_env(env_id, args.feedrate, parser) for env_id in env_ids}
    compare = args.feedrate is None or args.feedrate == PAPER_FEEDRATE
    runs = []
    for env_id, env in envs.items():
        # by default every baseline, and the agent shipped for the env if there is one
        shipped = ["ppo"] if args.policy is None and _shipped_agent(env_id) is not None else []
        for spec in specs + shipped:
            try:
                runs.append((env_id, spec, resolve_policy(spec, env)))
            except (ValueError, OSError) as exc:
                parser.error(f"cannot build policy {spec!r} for {env_id}: {exc}")

    from tqdm import tqdm

    total = sum(envs[e].unwrapped.episode_steps for e, _, _ in runs)
    records: list[dict] = []
    results: dict[str, dict[str, EpisodeResult]] = {e: {} for e in env_ids}
    with tqdm(total=total, unit="step", file=sys.stderr, dynamic_ncols=True, leave=False,
              disable=True if args.no_progress else None) as bar:
        for env_id, spec, policy in runs:
            label = policy_label(spec)
            bar.set_postfix_str(f"{env_id} {label}")
            result = run_episode(policy, envs[env_id], seed=args.seed, progress=bar.update)
            results[env_id][label] = result
            records.append(_record(env_id, label, result, compare))

    feed = envs[env_ids[0]].unwrapped.feedrate_profile.feedrate
    print(f"Contour error on the nominal plant at {feed:g} mm/s, one deterministic episode each "
          f"(seed {args.seed}); paper = seed 000 Table 4 (at {PAPER_FEEDRATE:g} mm/s)")
    print(format_table(records))
    if any(policy_label(s) == "qft" for s in specs):
        lines = _stability_lines(_unique(envs[e].unwrapped.decision_period for e in env_ids))
        if lines:
            print()
            print("\n".join(lines))

    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps([_json_safe(r) for r in records], indent=2) + "\n")
        print(f"\nwrote {len(records)} records to {args.json}")
    if args.plots is not None:
        args.plots.mkdir(parents=True, exist_ok=True)
        for env_id, by_policy in results.items():
            plot_contours(by_policy, envs[env_id], args.plots / f"{env_id}_contour.png")
            plot_contour_errors(by_policy, envs[env_id], args.plots / f"{env_id}_error.png")
        print(f"wrote {2 * len(results)} plots to {args.plots}")
    for env in envs.values():
        env.close()
    print(f"total wall time {time.perf_counter() - wall0:.1f} s")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
