"""Ablations of an agent family (issue 33, item 5): the agent against itself with one thing changed, by the verdict
rule.

    python experiments/ablations/ablations.py --env VCNC-OmegaLookahead-v1 [--config YAML] [--on ID ...] [--seeds 5] [--jobs 2]
        [--plants 20] [--timesteps N] [--eval-freq N] [--variants NAME ...] [--output runs/ablations]
        [--agent runs/seeds/ID] [--which best|final] [--table JSON]

The agent is the id's entry of ``--config`` (default ``agents/hyperparams/specialists.yml``, the recipe of the shipped
specialists; ``agents/hyperparams/generalists.yml`` with ``--env VCNC-RandomContour-v1`` is the generalists' family,
evaluated ``--on`` the named contours it never saw).  Each variant changes one thing of that entry:

- ``direct``: no residual; the agent's action is the normalised amplifier command itself, at the same decision
  period;
- ``no-preview``: the observation without the reference preview and the contour preview (the env's
  ``preview_steps=()`` and ``contour_ahead=()``: 15 numbers instead of 36);
- ``repeat-R``: a decision every R control periods, half and twice the agent's;
- ``correction-C``: the correction bound (a fraction of the input limit), a quarter and five times the agent's
  (at most 1).

Every variant trains ``--seeds`` seeds with the agent's budget of agent steps (``--timesteps`` sets another for
all of them, the agent's too; ``vcnc-train --trainer lean --seeds K``, one folder per variant under ``OUTPUT/ID``; a
variant whose ``seeds.json`` exists is not trained again); ``--agent`` names the agent's own seeds folder if it was
trained already with the same budget (``vcnc-train --config YAML --seeds K``), else it is trained as a variant.  Then
one ``vcnc-bench --plants N`` run per evaluation id (``--on``, default the id itself) evaluates every seed of every
variant, with that id's default causal controllers, into ``OUTPUT/ID.json`` (``OUTPUT/ID-on-EVAL.json`` for another
id), and the table is printed as Markdown: per variant the IQM of max and RMS contour error over plants and seeds with its 95 %
interval, the verdict against the agent (``X`` = the variant; "wins": the variant is better, the change helps), and
against the strongest causal controller.  A variant with a seed that kept no agent (every evaluation in its training
diverged) is not evaluated; its row says how many and counts as a loss.  ``--table JSON`` prints the table of an
earlier run's JSON and trains nothing.

``--which`` names the agent of each seed that is judged: ``best`` (default; the training evaluation with the least
contour error) or ``final`` (the last), the feed-override family's (``agents/hyperparams/override.yml``), whose
reward also pays for cycle time, so that its least contour error is its slowest checkpoint.  Where the records
have cycle times (the override ids) the table has a third figure, the cycle time (s; an unfinished run's is
infinite), judged by the same rule.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import yaml

from vcnc_agents.action_modes import ActionMode
from vcnc_agents.config import action_mode_of, load_hyperparameters, with_action_mode
from vcnc_bench.verdicts import seed_figures, verdict

SPECIALISTS = Path(__file__).resolve().parents[2] / "agents" / "hyperparams" / "specialists.yml"
AGENT = "agent"


def variants(entry: dict) -> dict[str, dict]:
    """The agent's entry and its ablations, by name (see the module docstring)."""
    mode = action_mode_of(entry)
    if mode.mode != "residual":
        raise ValueError("the ablations vary a residual specialist; this entry is direct")
    out = {AGENT: entry, "direct": with_action_mode(entry, ActionMode("direct", action_repeat=mode.action_repeat))}
    bare = dict(entry)
    bare["env_kwargs"] = {**(entry.get("env_kwargs") or {}), "preview_steps": [], "contour_ahead": []}
    out["no-preview"] = bare
    for r in (max(1, mode.action_repeat // 2), 2 * mode.action_repeat):
        out[f"repeat-{r}"] = with_action_mode(
            entry, ActionMode("residual", r, mode.baseline, mode.correction, mode.baseline_params)
        )
    for c in (mode.correction / 4, min(1.0, 5 * mode.correction)):
        out[f"correction-{c:g}"] = with_action_mode(
            entry, ActionMode("residual", mode.action_repeat, mode.baseline, c, mode.baseline_params)
        )
    return out


def train(
    env_id: str,
    configs: dict[str, dict],
    folder: Path,
    seeds: int,
    jobs: int,
    agent: Path | None,
    timesteps: int | None = None,
    eval_freq: int = 262144,
) -> dict:
    """Train every variant's seeds (skipping finished ones); their seeds folders by name."""
    folders = {}
    for name, entry in configs.items():
        if name == AGENT and agent is not None:
            folders[name] = agent
            continue
        out = folder / name
        folders[name] = out
        if (out / "seeds.json").is_file():
            print(f"{name}: trained already ({out / 'seeds.json'})", flush=True)
            continue
        out.mkdir(parents=True, exist_ok=True)
        config = folder / f"{name}.yml"
        config.write_text(yaml.safe_dump({env_id: entry}, sort_keys=False))
        print(f"{name}: training {seeds} seeds into {out}", flush=True)
        subprocess.run(
            [
                sys.executable,
                "-m",
                "vcnc_agents.cli",
                "--trainer",
                "lean",
                "--config",
                str(config),
                "--env",
                env_id,
                "--seeds",
                str(seeds),
                "--jobs",
                str(jobs),
                "--eval-freq",
                str(eval_freq),
                "--output",
                str(out),
                "--no-progress",
                "--no-tensorboard",
            ]
            + ([] if timesteps is None else ["--timesteps", str(timesteps)]),
            check=True,
        )
    return folders


def without_agent(folder: Path, which: str = "best") -> str | None:
    """Why a variant's seeds folder is not evaluated as one controller (a seed kept no ``which`` agent: for
    ``best``, every evaluation in its training diverged), or None."""
    runs = json.loads((Path(folder) / "seeds.json").read_text())["runs"]
    lost = [r for r in runs if r["code"] != 0 or not (Path(folder) / Path(r["folder"]).name / which).is_dir()]
    if not lost:
        return None
    return f"no agent: every evaluation in training diverged for {len(lost)} of {len(runs)} seeds"


def agents_spec(folder: Path, which: str = "best") -> str:
    """The bench's policy of a variant's seeds folder: every seed's ``best`` (``ppo:FOLDER``) or ``final`` agent
    (``ppo:FOLDER/final``), judged as one controller."""
    return f"ppo:{folder}" if which == "best" else f"ppo:{folder}/{which}"


def evaluate(env_id: str, folders: dict, plants: int, out: Path, which: str = "best") -> None:
    """One vcnc-bench --plants run of every variant's seeds (their ``which`` agents) and the id's default causal
    controllers."""
    import gymnasium as gym

    from vcnc_bench.policies import default_specs

    env = gym.make(env_id)
    # not the floor: the oracle solves every sampled plant afresh (minutes each); its nominal figure is in the README
    specs = [s for s in default_specs(env) if s not in ("ppo", "oracle")] + [
        agents_spec(f, which) for f in folders.values()
    ]
    command = [sys.executable, "-m", "vcnc_bench.cli", "--env", env_id, "--plants", str(plants), "--json", str(out)]
    for s in specs:
        command += ["--policy", s]
    subprocess.run(command, check=True)


#: The units of the table's figures.
UNITS = {"max": "um", "rms": "um", "cycle": "s"}


def figures_of(env_id: str) -> list[str]:
    """The figures an ablation of ``env_id`` is judged on: max and RMS contour error, and the cycle time where the
    agent sets the feed override (a :class:`~vcnc_gym.envs.feed_override_env.FeedOverrideEnv`), which its reward pays for."""
    import gymnasium as gym

    from vcnc_gym.envs.feed_override_env import FeedOverrideEnv

    env = gym.make(env_id)
    try:
        return ["max", "rms"] + (["cycle"] if isinstance(env.unwrapped, FeedOverrideEnv) else [])
    finally:
        env.close()


def _f(v) -> str:
    return "inf" if v is None else f"{v:.4g}"


def table(data: dict) -> list[str]:
    """The Markdown lines: every variant against the agent and against the strongest causal controller (the
    variants' groups are ``data["ablations"]``, written by :func:`main`)."""
    records = data["robust"]
    by_name = {
        name: [r for r in records if r.get("group") == group]
        for name, group in data["ablations"].items()
        if group is not None
    }
    agent_name = AGENT
    agent = by_name[AGENT]
    verdicts = {(v["x"], v["figure"]): v for v in data["verdicts"]}
    env = records[0]["env"]
    figures = data.get("figures", ["max", "rms"])
    out = [
        f"**{env}** (`{data['settings']['command']}`)",
        "",
        "| variant | seeds | fig | IQM [95 % CI] | variant - agent [95 % CI] | against the agent | "
        "strongest causal: IQM | against it |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, members in by_name.items():
        for figure in figures:
            x = seed_figures(members, figure)
            own = verdict(x, x, figure=figure, x_label=name, y_label=name)
            if name == agent_name:
                cells = "—", "—"
            else:
                v = verdict(x, seed_figures(agent, figure), figure=figure, x_label=name, y_label=agent_name)
                cells = f"{_f(v.difference)} [{_f(v.low)}, {_f(v.high)}]", v.outcome
            row = verdicts.get((members[0]["group"], figure))
            causal = (f"`{row['y']}` {_f(row['iqm_y'])}", row["outcome"]) if row else ("—", "—")
            out.append(
                f"| {name} | {len(members)} | {figure}, {UNITS[figure]} | {_f(own.iqm_x)} [{_f(own.ci_x[0])}, "
                f"{_f(own.ci_x[1])}] | {cells[0]} | {cells[1]} | {causal[0]} | {causal[1]} |"
            )
    for name, why in data.get("without_agent", {}).items():
        out.append(f"| {name} | - | all | {why} | - | loses | - | loses |")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--env",
        default="VCNC-OmegaLookahead-v1",
        help="the id of the agent's entry, the one it trains on (default %(default)s)",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=SPECIALISTS,
        help="the family's recipe (default agents/hyperparams/specialists.yml)",
    )
    p.add_argument(
        "--on",
        action="append",
        metavar="ID",
        help="an id to evaluate on (repeatable; default --env); the agents must run there",
    )
    p.add_argument("--timesteps", type=int, metavar="N", help="agent steps of every variant (default the entry's)")
    p.add_argument(
        "--variants",
        nargs="+",
        metavar="NAME",
        help="only these variants (and the agent), e.g. the ones trained so far (default all)",
    )
    p.add_argument(
        "--eval-freq",
        type=int,
        default=262144,
        metavar="N",
        help="agent steps between training evaluations, as the agent's own run (default %(default)s)",
    )
    p.add_argument("--seeds", type=int, default=5, help="training seeds per variant (default 5)")
    p.add_argument("--jobs", type=int, default=2, help="seeds trained at a time (default 2)")
    p.add_argument("--plants", type=int, default=20, help="plants drawn from the box (default 20)")
    p.add_argument("--output", type=Path, default=Path("runs/ablations"), help="folder (default runs/ablations)")
    p.add_argument("--agent", type=Path, help="the agent's own seeds folder, trained already")
    p.add_argument(
        "--which",
        choices=("best", "final"),
        default="best",
        help="each seed's agent judged: best (least contour error in training; default) or final",
    )
    p.add_argument("--table", type=Path, help="print the table of this JSON and stop")
    args = p.parse_args(argv)
    if args.table is not None:
        print("\n".join(table(json.loads(args.table.read_text()))))
        return 0
    configs = variants(load_hyperparameters(args.env, args.config))
    unknown = sorted(set(args.variants or ()) - set(configs))
    if unknown:
        p.error(f"--variants: no variant {unknown[0]!r} (the variants: {', '.join(n for n in configs if n != AGENT)})")
    if args.variants:
        configs = {n: c for n, c in configs.items() if n == AGENT or n in args.variants}
    folder = args.output / args.env
    folders = train(args.env, configs, folder, args.seeds, args.jobs, args.agent, args.timesteps, args.eval_freq)
    missing = {name: why for name, folder in folders.items() if (why := without_agent(folder, args.which)) is not None}
    for on in args.on or [args.env]:
        out = args.output / (f"{args.env}.json" if on == args.env else f"{args.env}-on-{on}.json")
        evaluate(on, {n: f for n, f in folders.items() if n not in missing}, args.plants, out, args.which)
        data = json.loads(out.read_text())
        data["ablations"] = {
            name: agents_spec(folder, args.which) for name, folder in folders.items() if name not in missing
        }
        data["without_agent"] = missing
        data["figures"] = figures_of(on)
        out.write_text(json.dumps(data, indent=1))
        print("\n".join(table(data)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
