"""Each env's plots of the ordinary table, and which policies they show.

A plot with a dozen traces in one panel says nothing; by default an env's plots show the few runs a reader
compares (:func:`shown_labels`): the source papers' controllers (a policy's ``paper`` attribute, or a figure in
:mod:`vcnc_bench.papers`), the strongest causal controller (the lowest max contour error among the classical
controllers that read only what a CNC's servo reads), the learned agents (``ppo`` specs) and the non-causal floor.
``vcnc-bench --plot-all`` shows every run.
"""

from __future__ import annotations

import math
from pathlib import Path

from .headroom import NON_CAUSAL
from .papers import paper_figures
from .policies import split_spec

__all__ = ["shown_labels", "plot_env"]


def _is_agent(spec: str) -> bool:
    return split_spec(spec)[0] == "ppo"


def shown_labels(key: str, runs, everything: bool = False) -> list[str]:
    """The labels of ``runs`` (:class:`~vcnc_bench.runner.PolicyRun`, on env ``key``) an env's plots show, in run
    order: every one with ``everything``; else the paper's controllers, the strongest causal one, the agents and
    the floor."""
    if everything:
        return [r.label for r in runs]
    causal = [r for r in runs if not r.label.endswith(NON_CAUSAL) and not _is_agent(r.spec)]
    finite = [r for r in causal if math.isfinite(r.trials[-1].max_contour_error_um)]
    strongest = min(finite, key=lambda r: r.trials[-1].max_contour_error_um).label if finite else None
    keep = {
        r.label
        for r in runs
        if r.paper
        or paper_figures(key, r.label)
        or r.label == strongest
        or _is_agent(r.spec)
        or r.label.endswith(NON_CAUSAL)
    }
    return [r.label for r in runs if r.label in keep]


def plot_env(env, key: str, by_policy: dict, folder: Path) -> list[Path]:
    """The contour, the contour error and the magnified deviation of ``by_policy`` ({label: EpisodeResult}) on
    ``env`` (a contouring env), as ``KEY_contour.png``, ``KEY_error.png`` and ``KEY_deviation.png`` in ``folder``;
    none for another env (the positioning env has its own report)."""
    from vcnc_gym.deviation_plot import plot_deviation
    from vcnc_gym.envs import ContouringEnv
    from vcnc_gym.evaluation import plot_contour_errors, plot_contours

    if not isinstance(env.unwrapped, ContouringEnv) or not by_policy:  # a G-code program's, a random contour's too
        return []
    paths = [folder / f"{key}_contour.png", folder / f"{key}_error.png", folder / f"{key}_deviation.png"]
    plot_contours(by_policy, env, paths[0])
    plot_contour_errors(by_policy, env, paths[1])
    plot_deviation(by_policy, env, paths[2])
    return paths
