"""Throughput of the native vector env against Gymnasium's SyncVectorEnv, in one run.

Run: ``python benchmarks/vector_env.py`` (``--seconds S`` per measurement,
``--envs N`` for the native env's size).

For each env id (heart, omega) it times, with a PD tracking controller
driving every env (so the tables follow the contour for real: friction,
backlash, exact contour error), only the ``step`` calls of

1. ``gym.make_vec(id, num_envs=8, vectorization_mode="sync")`` (SyncVectorEnv);
2. ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
   (the native vector env) with 1 and with 2 numba threads,

and prints env-steps/s and the ratio of each native figure to SyncVectorEnv
at N = 8.  Episodes end and reset inside the timed loop.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numba
import numpy as np

import vcnc_gym  # noqa: F401


def _pd(layout, obs):
    u = 300.0 * layout.tracking_error(obs) + 1.0 * (layout.reference_velocity(obs) - layout.velocity(obs))
    return np.clip(u / 5.0, -1.0, 1.0).astype(np.float32)


def env_steps_per_second(envs, seconds: float) -> float:
    """Env-steps per second of ``envs.step`` alone, under a PD controller, over ``seconds`` of stepping."""
    layout = envs.unwrapped.layout if hasattr(envs.unwrapped, "layout") else envs.unwrapped.envs[0].unwrapped.layout
    obs, _ = envs.reset(seed=0)
    for _ in range(20):  # compile and warm up
        obs, *_ = envs.step(_pd(layout, obs))
    stepping = 0.0
    steps = 0
    while stepping < seconds:
        action = _pd(layout, obs)
        t0 = time.perf_counter()
        obs, *_ = envs.step(action)
        stepping += time.perf_counter() - t0
        steps += 1
    return steps * envs.num_envs / stepping


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=3.0, help="stepping time per measurement, s")
    p.add_argument("--envs", type=int, default=1024, help="envs in the native vector env")
    args = p.parse_args(argv)
    cores = numba.config.NUMBA_NUM_THREADS
    print(f"numba threads available: {cores}; PD controller on every env; env-steps/s of step() alone")
    print(f"{'env':15s} {'vector env':32s} {'env-steps/s':>12s} {'x Sync(8)':>10s}")
    for env_id in ("VCNC-Heart-v1", "VCNC-Omega-v1"):
        sync = gym.make_vec(env_id, num_envs=8, vectorization_mode="sync")
        base = env_steps_per_second(sync, args.seconds)
        sync.close()
        print(f"{env_id:15s} {'SyncVectorEnv, N = 8':32s} {base:12,.0f} {1.0:10.2f}")
        native = gym.make_vec(env_id, num_envs=args.envs, vectorization_mode="vector_entry_point")
        for threads in sorted({1, min(2, cores)}):
            numba.set_num_threads(threads)
            rate = env_steps_per_second(native, args.seconds)
            label = f"native, N = {args.envs}, {threads} thread{'s' if threads > 1 else ''}"
            print(f"{env_id:15s} {label:32s} {rate:12,.0f} {rate / base:10.2f}")
        numba.set_num_threads(cores)
        native.close()


if __name__ == "__main__":
    main()
