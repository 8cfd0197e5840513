"""The ordinary table's runs: every (env, policy) pair for one deterministic episode, on one or more processes.

An env of the table is an :class:`EnvRecipe` (its table name, the id ``gym.make`` builds, the arguments and the
policy specs to run on it), so a worker process can build it again from a few picklable fields.  With
``jobs = 1`` everything runs in this process on the envs and policies the caller already built; with more,
each env is one task of a pool of ``jobs`` worker processes (``spawn``: no state inherited from a parent that
may hold numba's or torch's threads), handed out longest first (episode steps times episodes) so that the
long envs do not end up last.  A policy that learns across episodes (ILC) runs its trials in the worker that
owns its env, in order.  :func:`run_table` calls ``on_env_done`` as each env finishes, for one progress line
per env.

Nothing here prints or reads the command line: :mod:`vcnc_bench.cli` does.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from multiprocessing import get_context
from typing import Callable

__all__ = [
    "EnvRecipe",
    "PolicyRun",
    "EnvRuns",
    "BuildError",
    "idle_cores",
    "label_of",
    "trials_of",
    "run_env",
    "run_table",
]


class BuildError(ValueError):
    """An env that cannot be built from its recipe (a bad ``--plant``, ``--feedrate`` or program), or a policy
    spec that cannot be built for an env (a bad ``ppo:PATH``); the message names the env and the spec."""


@dataclass(frozen=True)
class EnvRecipe:
    """One env of the table, as a worker builds it again.

    Attributes
    ----------
    key : str
        Its name in the table (the id, or ``GCode:<name>`` for a ``--program``).
    env_id : str
        The registered id ``gym.make`` builds.
    kwargs : dict
        The arguments of ``gym.make`` (``feedrate``, ``plant``, a program's ``program`` and ``tolerance``).
    specs : tuple of str
        The policy specs run on it, in table order; empty: every kind's defaults for the env
        (:func:`vcnc_bench.policies.default_specs`).
    everything : bool
        With the defaults, also run the policies that learn across episodes (ILC) and every kind's extras (the
        costly ones, ``mpc``): ``vcnc-bench --all``.  Named specs always run.
    """

    key: str
    env_id: str
    kwargs: dict = field(default_factory=dict)
    specs: tuple = ()
    everything: bool = True

    def make(self):
        """The env (``gym.make(env_id, **kwargs)``)."""
        import gymnasium as gym

        import vcnc_gym  # noqa: F401  (registers the ids)

        return gym.make(self.env_id, **self.kwargs)


@dataclass
class PolicyRun:
    """One policy's episodes on one env: ``trials`` holds every trial's EpisodeResult (one, but for a policy
    that learns across episodes), the last being the scored one; ``build_s`` the time to build the policy, s;
    ``paper`` the source paper that designed it (its ``paper`` attribute; "" for the suite's own designs)."""

    spec: str
    label: str
    trials: list
    build_s: float = 0.0
    paper: str = ""


@dataclass
class EnvRuns:
    """Every policy's runs on one env, in the recipe's order, the env's wall time (build, runs, plots and the
    reports' preparation), s, the plots drawn of it, and what the kinds' ``prepare`` gave ({kind: object})."""

    key: str
    runs: list
    wall_s: float
    plots: list = field(default_factory=list)
    prepared: dict = field(default_factory=dict)


def label_of(spec: str, policy) -> str:
    """A policy's label in the tables and the JSON: a non-causal floor (``causal = False``, the baselines'
    oracle) is marked so wherever it appears, never to be read as a controller."""
    from .headroom import NON_CAUSAL
    from .policies import policy_label

    return policy_label(spec) + (NON_CAUSAL if getattr(policy, "causal", True) is False else "")


def trials_of(policy, trials: int) -> int:
    """Episodes run by ``policy``: ``trials`` for one that learns across episodes (ILC), else one."""
    return trials if getattr(policy, "learns_across_episodes", False) else 1


def _cpu_times() -> tuple[float, float]:
    """(idle, total) jiffies of all cores since boot, from Linux's /proc/stat."""
    with open("/proc/stat") as f:
        fields = [float(x) for x in f.readline().split()[1:]]
    return fields[3] + fields[4], sum(fields[:8])  # idle + iowait; user .. steal


def idle_cores(sample: float = 0.3) -> int:
    """Cores this process may use that other processes are not using now (at least 1): the cores of the
    affinity mask times the idle fraction of the CPU over the next ``sample`` seconds (Linux's /proc/stat), or,
    where that cannot be read, minus the one-minute load average (which lags: right after another job it still
    counts that job)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover  (macOS, Windows)
        cores = os.cpu_count() or 1
    try:
        idle0, total0 = _cpu_times()
        time.sleep(sample)
        idle1, total1 = _cpu_times()
        busy = (1.0 - (idle1 - idle0) / max(total1 - total0, 1e-9)) * (os.cpu_count() or cores)  # busy cores
    except (OSError, ValueError, IndexError):  # pragma: no cover  (no /proc)
        try:
            busy = os.getloadavg()[0]
        except OSError:
            busy = 0.0
    return max(1, min(cores, round(cores - busy)))


def _policy(spec: str, env, key: str, policies: dict | None):
    from .policies import resolve_policy

    if policies is not None and spec in policies:
        return policies[spec]
    try:
        return resolve_policy(spec, env)
    except (ValueError, OSError) as exc:
        raise BuildError(f"cannot build policy {spec!r} for {key}: {exc}") from exc


def run_env(
    recipe: EnvRecipe,
    *,
    seed: int,
    trials: int,
    env=None,
    policies: dict | None = None,
    progress: Callable[[int], object] | None = None,
    plots=None,
    plot_all: bool = False,
    prepare: bool = False,
) -> EnvRuns:
    """Run every spec of ``recipe`` on its env: one deterministic episode each (``trials`` for a policy that
    learns across episodes), with ``env.reset(seed=seed)``; with ``plots`` (a folder), draw the env's plots of the
    runs :func:`vcnc_bench.plots.shown_labels` chooses (every run with ``plot_all``); with ``prepare``, run every
    kind's :attr:`~vcnc_bench.policies.PolicyKind.prepare` on the env.

    ``env`` and ``policies`` (spec -> policy) are used when given (the caller built them), else built here.
    """
    from vcnc_gym.evaluation import run_episode

    from .plots import plot_env, shown_labels
    from .policies import default_specs, policy_kinds

    t0 = time.perf_counter()
    own = env is None
    if own:
        try:
            env = recipe.make()
        except (ValueError, TypeError) as exc:
            raise BuildError(f"{recipe.key}: {exc}") from exc
    runs = []
    for spec in recipe.specs or default_specs(env, extras=recipe.everything):
        b0 = time.perf_counter()
        policy = _policy(spec, env, recipe.key, policies)
        if not recipe.specs and not recipe.everything and getattr(policy, "learns_across_episodes", False):
            continue
        build = time.perf_counter() - b0
        results = [run_episode(policy, env, seed=seed, progress=progress) for _ in range(trials_of(policy, trials))]
        confirm = getattr(policy, "confirm", None)
        while confirm is not None and not confirm(results[-1]):  # a stored floor the episode did not reproduce
            # the next stored solution, else solved again by its plan (a solved one needs no confirmation)
            results = [run_episode(policy, env, seed=seed, progress=progress)]
        runs.append(PolicyRun(spec, label_of(spec, policy), results, build, str(getattr(policy, "paper", "") or "")))
    drawn = []
    if plots is not None:
        shown = set(shown_labels(recipe.key, runs, everything=plot_all))
        drawn = plot_env(env, recipe.key, {r.label: r.trials[-1] for r in runs if r.label in shown}, plots)
    prepared = {}
    if prepare:
        for kind in policy_kinds().values():
            data = kind.prepare(env) if kind.prepare is not None else None
            if data is not None:
                prepared[kind.name] = data
    if own:
        env.close()
    return EnvRuns(recipe.key, runs, time.perf_counter() - t0, drawn, prepared)


def _worker_init() -> None:
    """A worker's settings: torch on one thread (the agents' networks are tiny, and the workers share the
    cores), numba's kernels serial (a single env's kernel is)."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("MKL_NUM_THREADS", "1")
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")


def _run_in_worker(recipe: EnvRecipe, seed: int, trials: int, plots, plot_all: bool, prepare: bool) -> EnvRuns:
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # the agents extra is not installed
        pass
    import matplotlib

    matplotlib.use("Agg")
    return run_env(recipe, seed=seed, trials=trials, plots=plots, plot_all=plot_all, prepare=prepare)


def run_table(
    recipes: list[EnvRecipe],
    *,
    seed: int,
    trials: int,
    jobs: int = 1,
    envs: dict | None = None,
    policies: dict | None = None,
    cost: Callable[[EnvRecipe], float] | None = None,
    on_env_done: Callable[[EnvRuns, int, int], object] | None = None,
    plots=None,
    plot_all: bool = False,
    prepare: bool = False,
) -> dict[str, EnvRuns]:
    """Every recipe's runs, {key: EnvRuns} in the recipes' order.

    Parameters
    ----------
    recipes : list of EnvRecipe
    seed, trials : int
        As :func:`run_env`.
    jobs : int
        Processes; 1 runs here on ``envs`` (key -> env) and ``policies`` (key -> {spec: policy}) when given.
    cost : callable, optional
        An estimate of a recipe's run time (any unit): the pool hands out the costliest first.
    on_env_done : callable (EnvRuns, done, total), optional
        Called in this process as each env finishes.
    plots, plot_all, prepare :
        As :func:`run_env`: each env's plots are drawn, and its reports prepared, where it ran.

    Raises
    ------
    BuildError
        For an env or a spec that cannot be built (the pool's remaining envs are cancelled).
    """
    total = len(recipes)
    done: dict[str, EnvRuns] = {}

    def finished(result: EnvRuns) -> None:
        done[result.key] = result
        if on_env_done is not None:
            on_env_done(result, len(done), total)

    if jobs <= 1 or total <= 1:
        for r in recipes:
            finished(
                run_env(
                    r,
                    seed=seed,
                    trials=trials,
                    env=(envs or {}).get(r.key),
                    policies=(policies or {}).get(r.key),
                    plots=plots,
                    plot_all=plot_all,
                    prepare=prepare,
                )
            )
    else:
        order = sorted(recipes, key=cost, reverse=True) if cost is not None else list(recipes)
        with ProcessPoolExecutor(
            max_workers=min(jobs, total), mp_context=get_context("spawn"), initializer=_worker_init
        ) as pool:
            futures = [pool.submit(_run_in_worker, r, seed, trials, plots, plot_all, prepare) for r in order]
            try:
                for f in as_completed(futures):
                    finished(f.result())
            except BaseException:
                for f in futures:
                    f.cancel()
                raise
    return {r.key: done[r.key] for r in recipes}
