"""The one free number of the model-based controllers' design rule: the PID's closed-loop pole, per plant.

``baselines.servo.pid_gains`` places a triple pole at ``-bandwidth`` on the nominal axis; this script runs
``ff-pid`` and ``ff-ccc`` on the nominal plant of each plant's contouring ids over a grid of bandwidths (and of
coupling gains for ``ff-ccc``) and prints max / RMS contour error, the figures behind
``baselines.servo.BANDWIDTH`` and ``baselines.coupling.ccc``'s default coupling (docs/reproduction.md)::

    python benchmarks/tune_servo.py            # every plant's grid, a few minutes on 2 cores
    python benchmarks/tune_servo.py --env VCNC-Heart-v1
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.evaluation import run_episode

#: Bandwidths tried per plant (rad/s) and the ids they are tried on.
GRID = {
    "vcnc_feed_drive": ((300.0, 1000.0, 2000.0), ("VCNC-Heart-v1", "VCNC-OmegaLookahead-v1")),
    "current_feed_drive": ((300.0, 1000.0, 2000.0), ("VCNC-CornersSmooth-v1",)),
    "nct_xy_table": ((10.0, 30.0, 100.0), ("VCNC-Circle-v1",)),
}
COUPLINGS = (0.1, 0.3, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", action="append", help="only these ids")
    args = parser.parse_args()
    print(f"{'env':26s} {'controller':8s} {'bandwidth':>9s} {'coupling':>8s} {'max um':>8s} {'rms um':>8s}")
    for plant, (bandwidths, env_ids) in GRID.items():
        for env_id in env_ids:
            if args.env and env_id not in args.env:
                continue
            env = gym.make(env_id)
            for w in bandwidths:
                runs = [("ff-pid", None)] + [("ff-ccc", c) for c in COUPLINGS]
                for name, coupling in runs:
                    params = {"bandwidth": w} | ({"coupling": coupling} if coupling is not None else {})
                    r = run_episode(baselines.make(name, env, **params), env)
                    flag = " diverged" if r.diverged else ""
                    print(f"{env_id:26s} {name:8s} {w:9g} {coupling if coupling is not None else '':>8} "
                          f"{r.max_contour_error_um:8.3f} {r.rms_contour_error_um:8.4f}{flag}", flush=True)


if __name__ == "__main__":
    main()
