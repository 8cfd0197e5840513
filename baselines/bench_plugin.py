"""The ``baseline`` policy kind of vcnc-bench: every classical controller, on the plants it was designed for.

Found by the bench through the entry point ``baseline`` of the group
``vcnc_bench.policy_kinds`` (``pyproject.toml``).  A bare baseline name
(``qft``) is a spec of this kind; by default the bench runs, on each env,
every baseline whose ``plants`` include the env's plant.
"""

from __future__ import annotations

from vcnc_bench.policies import PolicyKind

from . import qft
from .registry import make, names, policy_class

__all__ = ["KIND", "applies"]


def applies(name: str, env) -> bool:
    """True if baseline ``name`` was designed for the plant of ``env``."""
    plant = getattr(env.unwrapped, "plant", None)
    return plant is not None and plant.name in policy_class(name).plants


def _stability_notes(env_ids, labels, envs) -> list[str]:
    """Seed 000 eq. (11) for the QFT loop, when "qft" ran."""
    if "qft" not in labels:
        return []
    dts = sorted({envs[e].unwrapped.decision_period for e in env_ids if applies("qft", envs[e])})
    head = "QFT robust-stability peak max|T(jw)| over the uncertainty box, seed 000 eq. (11)"
    lines = [f"{head} (bound mu = {qft.MU:g}):"]
    for axis in ("x", "y"):
        parts = [f"{qft.robust_stability_peak(axis=axis):.3f} continuous"]
        parts += [f"{qft.robust_stability_peak(axis=axis, dt=dt):.3f} sampled at dt = {dt:g} s" for dt in dts]
        lines.append(f"  {axis}: " + ", ".join(parts))
    return lines


KIND = PolicyKind(
    name="baseline",
    make=lambda arg, env: make(arg, env),
    names=names,
    defaults=lambda env: [n for n in names() if applies(n, env)],
    notes=_stability_notes,
    description="the papers' classical controllers (baselines.names())",
)
