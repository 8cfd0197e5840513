"""How far the oracle's learning gets: max contour error per trial and solve time, on each contouring id's
nominal plant (baselines/optimal/oracle.py; docs/reproduction.md)::

    python benchmarks/oracle_convergence.py [--env ID ...] [--iterations 10]
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs.registry import CONTOURING_IDS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", action="append", help=f"ids (default: {', '.join(CONTOURING_IDS)})")
    parser.add_argument("--iterations", type=int, default=10)
    args = parser.parse_args()
    for env_id in args.env or CONTOURING_IDS:
        env = gym.make(env_id)
        oracle = baselines.make("oracle", env, iterations=args.iterations)
        env.reset(seed=0)
        oracle.plan(env)
        trials = " ".join(f"{v:.3f}" for v in oracle.history_um[:, 0])
        print(f"{env_id:24s} solve {oracle.solve_time_s:6.1f} s   max um per trial: {trials}", flush=True)


if __name__ == "__main__":
    main()
