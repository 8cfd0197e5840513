"""Bring the shipped floors up to date with causal controllers registered after they were solved.

The oracle (``baselines/optimal``) treats a stored solution whose starts lack a causal controller that now
applies as stale, and solves again (minutes per id).  This script runs each missing controller closed-loop on the
stored solution's own env (the nominal plant, seed 0: the shipped ones) with the search's own start evaluation
(:func:`vcnc_baselines.optimal.search.warm_starts`), and

- where none beats the stored floor (max contour error, then RMS), records their figures among the solution's
  starts: the floor is at or below them, measured;
- where one does, solves that id again (with every start, the new ones included) and stores the new floor.

Run ``python experiments/classical-opponents/oracle_new_starts.py [--env ID ...]``; it prints one line per id and controller.
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium as gym
import numpy as np

import vcnc_gym  # noqa: F401
from vcnc_baselines.optimal import solutions
from vcnc_baselines.optimal.rollout import Rollouts
from vcnc_baselines.optimal.search import causal_names, solve, warm_starts
from vcnc_gym.envs import CONTOURING_IDS


def update(env_id: str, seed: int = 0) -> str:
    env = gym.make(env_id)
    env.reset(seed=seed)
    u = env.unwrapped
    p = np.asarray(u.parameters, dtype=np.float64)
    arrays = u._batch.plant_arrays
    noise = int(arrays.rng[0]) if hasattr(arrays, "rng") else None
    key = solutions.signature(env, p, noise)
    sol = solutions.load(key)
    if sol is None:
        return f"{env_id}: no stored solution ({key})"
    have = {k.split("#")[0] for k in sol.warm_starts}
    missing = [n for n in causal_names(env) if n not in have]
    if not missing:
        return f"{env_id}: up to date"
    t0 = time.perf_counter()
    rollouts = Rollouts(u.task, p, 1, noise)
    new = warm_starts(env, rollouts, names=missing, log=print)
    figures = {k: (1e3 * v.max, 1e3 * v.rms) for k, v in new.items()}
    beats = [k for k, (mx, rms) in figures.items() if (mx, rms) < (sol.max_um, sol.rms_um)]
    if beats:
        print(f"{env_id}: {', '.join(beats)} below the stored floor {sol.max_um:.4g} um: solving again", flush=True)
        sol = solve(env, p, noise_state=noise, log=print)
        solutions.store(key, sol, solutions.DIRECTORY)
        return (
            f"{env_id}: solved again in {time.perf_counter() - t0:.0f} s, floor {sol.max_um:.4g} um (start {sol.start})"
        )
    sol.warm_starts.update(figures)
    solutions.store(key, sol, solutions.DIRECTORY)
    return (
        f"{env_id}: floor {sol.max_um:.4g} um at or below "
        + ", ".join(f"{k} {mx:.4g}" for k, (mx, _) in figures.items())
        + f" ({time.perf_counter() - t0:.0f} s)"
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", action="append", help="ids (default: every contouring id)")
    args = p.parse_args(argv)
    for env_id in args.env or CONTOURING_IDS:
        print(update(env_id), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
