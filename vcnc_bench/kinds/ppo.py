"""The ``ppo`` policy kind of vcnc-bench: trained agents, and by default the one shipped for each env.

Found by the bench through the entry point ``ppo`` of the group
``vcnc_bench.policy_kinds`` (``pyproject.toml``), like any other package's kind; it lives with the bench, above
the agents it runs.  ``ppo:PATH`` is an agent
folder (a run's ``best``) or its ``model.zip``; the bare ``ppo`` is the
agent shipped for the env in ``agents/trained/``.  ``ppo:FOLDER`` of a
``vcnc-train --seeds K`` run (its ``seeds.json``) stands for the K seeds'
agents (each run's ``best``), run one by one and judged as one controller
(:func:`vcnc_bench.verdicts.robust_verdicts`).
"""

from __future__ import annotations

from pathlib import Path

import vcnc_agents  # an install without the agents extra (torch, SB3) skips this kind
from vcnc_agents.seeds import read_summary

from ..policies import PolicyKind

__all__ = ["KIND"]


def _env_id(env) -> str | None:
    spec = env.unwrapped.spec
    return spec.id if spec is not None else None


def _shipped(env):
    folder = vcnc_agents.TRAINED.get(_env_id(env))
    return folder if folder is not None and folder.is_dir() else None


def _make(path: str, env):
    if path == "":
        path = _shipped(env)
        if path is None:
            raise ValueError(f"no agent is shipped for {_env_id(env)}; give its folder as ppo:PATH")
    return vcnc_agents.load_agent(path, env)


def _expand(path: str) -> list[str]:
    """The ``best`` agent of every seed of a ``vcnc-train --seeds`` folder (``seeds.json``), in seed order, or with
    ``FOLDER/final`` (``FOLDER/best``) every seed's ``final`` (``best``) agent; a seed whose run failed or kept no
    such agent is named in the ValueError; any other path: itself."""
    folder, which = Path(path), "best"
    if not (folder / "seeds.json").is_file() and folder.name in ("best", "final"):
        folder, which = folder.parent, folder.name
    summary = folder / "seeds.json"
    if not summary.is_file():
        return [path]
    runs = read_summary(summary)["runs"]  # checked: a BadFile naming the file and the field
    folders = [folder / Path(r["folder"]).name for r in runs]
    missing = [f"seed {r['seed']} ({f})" for r, f in zip(runs, folders) if r["code"] != 0 or not (f / which).is_dir()]
    if missing:
        raise ValueError(
            f"{summary}: no {which} agent for {', '.join(missing)}; train it again or name the other "
            "seeds' folders one by one"
        )
    return [str(f / which) for f in folders]


def _defaults(env) -> list[str]:
    """The shipped agent, when there is one and it was trained on this env configuration (not, e.g., at
    another ``--feedrate``: ``ppo`` named explicitly then says why it does not fit)."""
    from vcnc_agents.policy import agent_mismatch

    folder = _shipped(env)
    return ["ppo"] if folder is not None and agent_mismatch(folder, env) is None else []


KIND = PolicyKind(
    name="ppo",
    make=_make,
    defaults=_defaults,
    description="a trained PPO agent: ppo:FOLDER, or ppo for the agent shipped for the env; ppo:FOLDER of a "
    "vcnc-train --seeds run: every seed's agent, judged as one",
    expand=_expand,
)
