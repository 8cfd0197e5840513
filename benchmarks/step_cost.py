"""Per-step cost of the VCNC envs against CartPole, and numba start-up time.

Run: ``python benchmarks/step_cost.py`` (``--steps N`` to change the count, ``--ids`` the envs: Jahanpour et
al.'s drive, e.g. ``VCNC-HeartShop-v1``, for the PD gains below).

1. Steps ``gym.make("CartPole-v1")`` and ``gym.make("VCNC-Heart-v1")`` (both
   with the wrappers gym.make adds) in the same process and prints the cost
   per step and the ratio.  The VCNC env replays the commands of a PD
   controller recorded beforehand, so it follows the contour for real (plant
   substeps with friction and backlash, exact contour error) and the
   controller's own cost is not counted.
2. Times ``import vcnc_gym; gym.make; reset; step`` in a fresh interpreter,
   first with an empty numba cache (every kernel compiles) and then again with
   the cache that run left behind (warm start).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

#: The envs timed: Jahanpour et al.'s, whose PD gains (V/mm) below fit their plant.
ENV_IDS = ("VCNC-Heart-v1", "VCNC-Omega-v1")

START_UP = """
import time
t0 = time.perf_counter()
import gymnasium as gym
import vcnc_gym
env = gym.make("VCNC-Heart-v1")
env.reset(seed=0)
env.step(env.action_space.sample())
print(time.perf_counter() - t0)
"""


def pd_actions(env_id: str, n: int) -> np.ndarray:
    """Actions of a PD tracking controller (x 300 V/mm, 1 V s/mm) over n steps."""
    import gymnasium as gym

    env = gym.make(env_id)
    layout = env.unwrapped.layout
    obs, _ = env.reset(seed=0)
    actions = np.empty((n, 2), dtype=np.float32)
    for i in range(n):
        u = 300.0 * layout.tracking_error(obs) + 1.0 * (layout.reference_velocity(obs) - layout.velocity(obs))
        actions[i] = np.clip(u / 5.0, -1.0, 1.0)
        obs, _, term, trunc, _ = env.step(actions[i])
        if term or trunc:
            obs, _ = env.reset()
    return actions


def time_steps(env, actions) -> float:
    """Seconds per step over the action sequence, resetting at episode ends."""
    env.reset(seed=0)
    t0 = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return (time.perf_counter() - t0) / len(actions)


def start_up_times() -> tuple[float, float]:
    """(cold, warm) seconds for import + make + reset + first step."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        runs = [
            float(
                subprocess.run([sys.executable, "-c", START_UP], env=env, check=True, capture_output=True, text=True)
                .stdout.strip()
                .splitlines()[-1]
            )
            for _ in range(2)
        ]
    return runs[0], runs[1]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="steps timed per env (default 100000)")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats, best kept (default 3)")
    parser.add_argument("--no-start-up", action="store_true", help="skip the cold/warm start-up timing")
    parser.add_argument(
        "--ids",
        nargs="+",
        default=list(ENV_IDS),
        help=f"env ids on Jahanpour et al.'s drive (default {' '.join(ENV_IDS)})",
    )
    args = parser.parse_args(argv)

    import gymnasium as gym

    import vcnc_gym  # noqa: F401

    cart = gym.make("CartPole-v1")
    cart_actions = np.random.default_rng(0).integers(0, 2, args.steps)
    rows = []
    cart_cost = min(time_steps(cart, cart_actions) for _ in range(args.repeats))
    for env_id in args.ids:
        env = gym.make(env_id)
        actions = pd_actions(env_id, args.steps)
        cost = min(time_steps(env, actions) for _ in range(args.repeats))
        rows.append((env_id, cost))

    width = max(16, *(len(env_id) for env_id in args.ids))
    print(f"{'env':<{width}} {'us/step':>9} {'x CartPole':>11}")
    print(f"{'CartPole-v1':<{width}} {cart_cost * 1e6:9.2f} {1.0:11.2f}")
    for env_id, cost in rows:
        print(f"{env_id:<{width}} {cost * 1e6:9.2f} {cost / cart_cost:11.2f}")
    print(
        f"(best of {args.repeats} x {args.steps} steps, gym.make wrappers included; "
        f"plant substeps per step: {gym.make('VCNC-Heart-v1').unwrapped._batch.plant_arrays.n_substeps})"
    )
    if not args.no_start_up:
        cold, warm = start_up_times()
        print(f"import + make + reset + first step: cold numba cache {cold:.2f} s, warm cache {warm:.2f} s")


if __name__ == "__main__":
    main()
