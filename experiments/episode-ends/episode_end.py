"""How each baseline arrives at the end of its contour: what the v1 episode end's defaults rest on.

For every contouring id and its baselines, one episode with a 0.01 um band
and a long wait (0.5 s; 3 s on the circle), printing the contour left ahead
of the tool's closest point at the reference's end and at the end of the
wait (um), and how long after the reference's end the tool came within 20,
5, 2 and 1 um of the end (s; "-": never)::

    python experiments/episode-ends/episode_end.py
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import vcnc_baselines
import vcnc_gym  # noqa: F401

CASES = [
    ("VCNC-Heart-v1", ["qft", "smc", "fuzzy"]),
    ("VCNC-Omega-v1", ["qft", "smc", "fuzzy"]),
    ("VCNC-Corners-v1", ["contouring-fb", "ilc-q"]),
    ("VCNC-CornersSmooth-v1", ["contouring-fb"]),
    ("VCNC-Circle-v1", ["nctf"]),
]
BANDS_UM = (20, 5, 2, 1)


def arrival(env_id: str, name: str):
    env = gym.make(env_id, completion_tolerance=1e-5, completion_timeout=3.0 if "Circle" in env_id else 0.5)
    u = env.unwrapped
    policy = vcnc_baselines.make(name, env)
    obs, _ = env.reset(seed=0)
    left, times = [], []
    done = False
    while not done:
        action, _ = policy.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        if info["time"] >= u.reference.duration:
            left.append(1e3 * (u.task.contour_length - info["progress"]))
            times.append(info["time"] - u.reference.duration)
    left, times = np.array(left), np.array(times)
    after = [times[np.flatnonzero(left <= b)[0]] if np.any(left <= b) else None for b in BANDS_UM]
    return left[0], left[-1], after


def main():
    print(
        f"{'env':<22} {'policy':<14} {'left at ref end um':>18} {'at rest um':>10} "
        + " ".join(f"{f'to {b} um s':>10}" for b in BANDS_UM)
    )
    for env_id, names in CASES:
        for name in names:
            first, final, after = arrival(env_id, name)
            print(
                f"{env_id:<22} {name:<14} {first:18.2f} {final:10.2f} "
                + " ".join(f"{'-' if a is None else f'{a:.4f}':>10}" for a in after)
            )


if __name__ == "__main__":
    main()
