"""The free numbers of the model-based controllers' design rule, per plant: the PID's closed-loop pole and the
feedforward's friction transition.

``vcnc_baselines.commissioning.design.pid_gains`` places a triple pole at ``-bandwidth`` on the nominal axis; this script runs
``ff-pid`` and ``ff-ccc`` on the nominal plant of each plant's contouring ids over a grid of bandwidths (and of
coupling gains for ``ff-ccc``) and prints max / RMS contour error, the figures behind
the bandwidths (now each plant's ``servo_bandwidth`` ceiling, below which ``vcnc_baselines.commissioning`` designs) and ``vcnc_baselines.coupling.ccc``'s default coupling (experiments/classical-opponents/README.md).
``--transitions`` runs ``zpetc``, ``ff-pid`` and ``ff-ccc`` over a grid of the durations over which the
feedforward's Coulomb level (``friction_time``) and the backlash crossing (``backlash_time``) change at a
reversal, and ``--shop-floor`` the bandwidth grid on the shop-floor ids, the rest of the former hand table (now ``PlantModel.friction_time``)::

    python experiments/classical-opponents/tune_servo.py            # every plant's grid, a few minutes on 2 cores
    python experiments/classical-opponents/tune_servo.py --env VCNC-Heart-v1
    python experiments/classical-opponents/tune_servo.py --transitions
    python experiments/classical-opponents/tune_servo.py --shop-floor
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import vcnc_baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.evaluation import run_episode

#: Bandwidths tried per plant (rad/s) and the ids they are tried on.
GRID = {
    "vcnc_feed_drive": ((300.0, 1000.0, 2000.0), ("VCNC-Heart-v1", "VCNC-OmegaLookahead-v1")),
    "current_feed_drive": ((300.0, 1000.0, 2000.0), ("VCNC-CornersSmooth-v1",)),
    "nct_xy_table": ((10.0, 30.0, 100.0), ("VCNC-Circle-v1",)),
}
COUPLINGS = (0.1, 0.3, 1.0)

#: The shop-floor ids per plant and the bandwidths (rad/s) tried there, each with friction transitions 0 and 1 ms.
SHOP_GRID = {
    "vcnc_feed_drive": ((700.0, 1000.0, 1500.0, 2000.0, 3000.0), ("VCNC-HeartShop-v1", "VCNC-OmegaLookaheadShop-v1")),
    "current_feed_drive": ((1500.0, 2000.0, 3000.0), ("VCNC-CornersSmoothShop-v1",)),
    "nct_xy_table": ((10.0, 30.0, 60.0, 100.0), ("VCNC-CircleShop-v1",)),
}

#: Friction transitions tried (s; 0 switches at the reversal) and backlash transitions (s, on plants with backlash).
FRICTION_TIMES = (0.0, 0.2e-3, 0.3e-3, 0.5e-3, 0.7e-3, 1e-3, 1.5e-3, 2e-3, 3e-3, 4e-3)
BACKLASH_TIMES = (8e-3, 16e-3, 32e-3)


def shop_floor(env_ids) -> None:
    """Print the shop-floor grid (max / RMS contour error, um, nominal plant): bandwidth x friction transition."""
    print(f"{'env':26s} {'controller':8s} {'bandwidth':>9s} {'friction ms':>11s} {'max um':>8s} {'rms um':>8s}")
    for plant, (bandwidths, ids) in SHOP_GRID.items():
        for env_id in ids:
            if env_ids and env_id not in env_ids:
                continue
            env = gym.make(env_id)
            frictions = (0.0, 1e-3) if plant != "nct_xy_table" else (1e-3,)
            for name in ("ff-pid", "zpetc", "ff-ccc"):
                for w in bandwidths:
                    for ft in frictions:
                        r = run_episode(vcnc_baselines.make(name, env, bandwidth=w, friction_time=ft), env)
                        print(
                            f"{env_id:26s} {name:8s} {w:9g} {ft * 1e3:11g} "
                            f"{r.max_contour_error_um:8.3f} {r.rms_contour_error_um:8.4f}",
                            flush=True,
                        )


def transitions(env_ids) -> None:
    """Print the transition grid (max / RMS contour error, um, nominal plant) of the model-based controllers."""
    print(f"{'env':26s} {'controller':8s} {'friction ms':>11s} {'backlash ms':>11s} {'max um':>8s} {'rms um':>8s}")
    for plant, (_, ids) in GRID.items():
        for env_id in ids:
            if env_ids and env_id not in env_ids:
                continue
            env = gym.make(env_id)
            backlash = BACKLASH_TIMES if plant == "vcnc_feed_drive" else (16e-3,)
            for name in ("zpetc", "ff-pid", "ff-ccc"):
                for ft in FRICTION_TIMES:
                    for bt in backlash:
                        r = run_episode(vcnc_baselines.make(name, env, friction_time=ft, backlash_time=bt), env)
                        print(
                            f"{env_id:26s} {name:8s} {ft * 1e3:11g} {bt * 1e3:11g} "
                            f"{r.max_contour_error_um:8.4f} {r.rms_contour_error_um:8.5f}",
                            flush=True,
                        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", action="append", help="only these ids")
    parser.add_argument("--transitions", action="store_true", help="the friction and backlash transition grid")
    parser.add_argument("--shop-floor", action="store_true", help="the bandwidth x friction grid on the shop-floor ids")
    args = parser.parse_args()
    if args.transitions:
        transitions(args.env)
        return
    if args.shop_floor:
        shop_floor(args.env)
        return
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
                    r = run_episode(vcnc_baselines.make(name, env, **params), env)
                    flag = " diverged" if r.diverged else ""
                    print(
                        f"{env_id:26s} {name:8s} {w:9g} {coupling if coupling is not None else '':>8} "
                        f"{r.max_contour_error_um:8.3f} {r.rms_contour_error_um:8.4f}{flag}",
                        flush=True,
                    )


if __name__ == "__main__":
    main()
