"""What a per-machine commissioning adds to a training episode under the feed override: ``ff-pid-online@machine``
against ``ff-pid-online`` in the residual wrapper a tolerance agent trains in (``ResidualAction``, the env drawing a
plant of the box at every reset), measured in the same run.

    python benchmarks/per_machine_episode.py [--env VCNC-OmegaToleranceShop-v2] [--episodes 4]

Per baseline: the mean wall time of a reset (the new plant's identification run, with ``@machine``) and of the
episode that follows (the dial at 100 % of the id's look-ahead, a zero residual), and their ratio to the nominal
design's episode.  Each episode's plant is new (``randomize=True``), as a training env's are.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import vcnc_gym  # noqa: F401
from vcnc_agents.action_modes import ResidualAction


def episodes(env_id: str, baseline: str, n: int) -> tuple[float, float]:
    """Mean wall time (s) of a reset and of the episode after it, over ``n`` episodes of new plants."""
    env = ResidualAction(
        gym.make(env_id, action_repeat=1, randomize=True), baseline=baseline, correction=0.1, action_repeat=20
    )
    resets, runs = [], []
    for k in range(n + 1):  # the first episode compiles: left out
        t0 = time.perf_counter()
        env.reset(seed=100 + k)
        t1 = time.perf_counter()
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(np.zeros(3))
            done = terminated or truncated
        if k:
            resets.append(t1 - t0)
            runs.append(time.perf_counter() - t1)
    env.close()
    return float(np.mean(resets)), float(np.mean(runs))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="VCNC-OmegaToleranceShop-v2")
    parser.add_argument("--episodes", type=int, default=4)
    args = parser.parse_args(argv)
    rows = {name: episodes(args.env, name, args.episodes) for name in ("ff-pid-online", "ff-pid-online@machine")}
    base = rows["ff-pid-online"][1]
    print(f"{args.env}, {args.episodes} episodes of new plants each (the residual wrapper, decisions of 2 ms):")
    for name, (reset, run) in rows.items():
        print(
            f"  {name:<22} reset {reset:7.3f} s, episode {run:6.3f} s; reset + episode = "
            f"{(reset + run) / base:5.2f} x the nominal design's episode"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
