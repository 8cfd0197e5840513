"""``lq-preview`` and ``mpc`` on a shop-floor id with the nominal linear model and with a model that has the shop
floor's structural mode and command delay: how a commissioned model plugs in (``models=``, ``delays=``).

Run: ``python benchmarks/predictive_model.py [--env VCNC-HeartShop-v1] [--policy lq-preview] [--policy mpc]``.

The second model is, per axis, the plant's nominal ``linear_model`` times the mode of
:mod:`vcnc_gym.plants.shop_floor` (drive to table, ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``) at the
shop floor's *nominal* frequency and damping, with its nominal command delay: what commissioning would identify on
the nominal machine, standing in for the commissioned model (the controller still never reads the plant it runs
on).  Its state is not determined by the measured position and velocity, so the controller estimates it with its
steady-state Kalman filter (:func:`vcnc_baselines.predictive.design.estimator_gain`).  One nominal episode each.
"""

from __future__ import annotations

import argparse
import time

import control
import gymnasium as gym
import numpy as np

import vcnc_baselines
import vcnc_gym  # noqa: F401
from vcnc_gym.evaluation import run_episode


def mode_models(env):
    """Per axis the nominal linear model times the shop floor's nominal mode, and the nominal command delay (s)."""
    u = env.unwrapped
    names = list(u.plant.parameter_names)
    p = u.nominal_parameters
    models = []
    for j in range(2):
        w = 2 * np.pi * p[j, names.index("mode_frequency")]
        zeta = p[j, names.index("mode_damping")]
        models.append(u.plant.linear_model(axis=j) * control.tf([2 * zeta * w, w * w], [1.0, 2 * zeta * w, w * w]))
    delay = p[0, names.index("command_delay")] * u.task.dt
    return models, (delay, delay)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="VCNC-HeartShop-v1")
    parser.add_argument("--policy", action="append", choices=["lq-preview", "mpc"])
    args = parser.parse_args(argv)
    env = gym.make(args.env)
    models, delays = mode_models(env)
    for name in args.policy or ["lq-preview"]:
        for label, params in (("nominal linear model", {}), ("with the mode and the delay",
                                                             {"models": models, "delays": delays})):
            policy = vcnc_baselines.make(name, env, **params)
            t0 = time.perf_counter()
            r = run_episode(policy, env)
            print(f"{args.env} {name}, {label}: max {r.max_contour_error_um:.2f} um, RMS {r.rms_contour_error_um:.3f} "
                  f"um ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
