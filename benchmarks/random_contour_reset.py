"""Cost of a reset of VCNC-RandomContour-v1 (a new contour) against one episode's steps.

Run: ``python benchmarks/random_contour_reset.py`` (``--episodes N``, default 10).

For N seeds, in one process: times ``env.reset(seed=s)`` (drawing the program,
reading it, Simba et al.'s corner designs, the look-ahead plan, the reference,
the projector's grid, the batch; Simba et al.'s corner design of every turn angle
made beforehand, as after the first resets of a run, unless ``--cold``) and then the episode's ``env.step`` calls
under a PD loop (300 V/mm, 1 V s/mm, the tests' controller, computed outside
the timed steps), and prints per seed and in total the reset time, the
episode's step time and their ratio, and the reset's parts (reading the
program with its blends, the rest: building the task).
"""

from __future__ import annotations

import argparse
import math
import time

import gymnasium as gym
import numpy as np

import vcnc_gym  # noqa: F401
from vcnc_gym.gcode import read_program, toolpath


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument(
        "--cold",
        action="store_true",
        help="leave the corner-design cache empty (each new angle designed inside the reset)",
    )
    args = parser.parse_args()
    env = gym.make("VCNC-RandomContour-v1")
    u = env.unwrapped
    env.reset(seed=10_000)  # compile once
    if not args.cold:  # Simba et al.'s corner design of every angle the spec draws, made once per process
        spec, (a, j) = u._spec, u._limits
        t0 = time.perf_counter()
        for turn in range(math.ceil(spec.turn_min), math.floor(spec.turn_max) + 1):
            toolpath._design(math.pi - math.radians(turn), u._tolerance, a, j)
        print(
            f"corner designs of the {math.floor(spec.turn_max) - math.ceil(spec.turn_min) + 1} turn angles: "
            f"{time.perf_counter() - t0:.1f} s once per process"
        )
    resets, steps, reads, counts = [], [], [], []
    print(
        f"{'seed':>4} {'moves':>5} {'length_mm':>9} {'steps':>6} {'reset_s':>8} {'read_s':>7} {'episode_s':>9} "
        f"{'reset/episode':>13}"
    )
    for seed in range(args.episodes):
        t0 = time.perf_counter()
        obs, info = env.reset(seed=seed)
        reset = time.perf_counter() - t0
        t0 = time.perf_counter()
        read_program(info["program"], 0.01)
        read = time.perf_counter() - t0
        layout = u.layout
        stepping = 0.0
        n = 0
        while True:
            a = np.clip(
                (300.0 * layout.tracking_error(obs) + 1.0 * (layout.reference_velocity(obs) - layout.velocity(obs)))
                / 5.0,
                -1,
                1,
            ).astype(np.float32)
            t0 = time.perf_counter()
            obs, _, term, trunc, _ = env.step(a)
            stepping += time.perf_counter() - t0
            n += 1
            if term or trunc:
                break
        resets.append(reset)
        steps.append(stepping)
        reads.append(read)
        counts.append(n)
        print(
            f"{seed:>4} {len(u.toolpath.program.moves) if hasattr(u, 'toolpath') else len(u.task.path.program.moves):>5} "
            f"{u.task.contour_length:9.1f} {n:>6} {reset:8.3f} {read:7.3f} {stepping:9.3f} {reset / stepping:13.2f}"
        )
    r, s = float(np.sum(resets)), float(np.sum(steps))
    print(
        f"total: {args.episodes} resets {r:.2f} s (reading the programs with their blends {np.sum(reads):.2f} s), "
        f"{int(np.sum(counts))} steps {s:.2f} s ({1e6 * s / np.sum(counts):.1f} us per step); reset / episode = "
        f"{r / s:.2f}"
    )


if __name__ == "__main__":
    main()
