"""Cost of a baseline's ``predict``: its compiled law against its NumPy statement, in one run.

Run: ``python benchmarks/baseline_predict.py`` (``--calls N``).

A baseline with a compiled form (``BaselinePolicy.compiled``: SMC, QFT) runs
it in ``predict`` on float32 observations, the env's dtype, and its NumPy
``_command`` on float64 ones; both give the same commands to the bit
(``tests/test_vec_env.py``).  This times one-env ``predict`` calls, as
``vcnc_gym.evaluation.run_episode`` makes them every control period, on
``VCNC-Heart-v1``'s first observation, both ways.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import vcnc_baselines
import vcnc_gym  # noqa: F401


def seconds_per_call(policy, obs, calls: int) -> float:
    policy.predict(obs)  # compile or load, allocate the memory
    t0 = time.perf_counter()
    for _ in range(calls):
        policy.predict(obs)
    return (time.perf_counter() - t0) / calls


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--calls", type=int, default=20_000, help="predict calls per measurement (default 20000)")
    args = p.parse_args(argv)
    env = gym.make("VCNC-Heart-v1")
    obs, _ = env.reset(seed=0)
    print(f"{'baseline':9s} {'compiled us':>12s} {'NumPy us':>9s} {'ratio':>6s}")
    for name in ("smc", "qft"):
        policy = vcnc_baselines.make(name, env)
        compiled = seconds_per_call(policy, obs, args.calls)
        plain = seconds_per_call(policy, obs.astype(np.float64), args.calls)
        print(f"{name:9s} {compiled * 1e6:12.1f} {plain * 1e6:9.1f} {plain / compiled:6.2f}")


if __name__ == "__main__":
    main()
