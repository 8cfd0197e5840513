"""The LQ preview servo on a machine's commissioned model: the commissioning's margin rule applied to its loop, and
what the rule costs it.

Run: ``python experiments/classical-opponents/lq_commissioning.py [--env ID ...] [--sweep]``.

Per id and axis x, for ``lq-preview`` (the plant's declared nominal model at the commissioned PID's bandwidth) and
``lq-preview@commissioned`` (the nominal machine's identified model: rigid body, the mode and the command delay
where the record has them, at the weight of :func:`vcnc_baselines.predictive.design.margin_weight`), prints the
input weight, the loop's margins on the *identified* model (:func:`vcnc_baselines.predictive.design.loop_response`
with ``plant=``: the controller on the plant the commissioning measured, the rule's phase >= 45 deg, gain >= 6 dB,
sensitivity peak <= 6 dB, crossover at most the PID's and half the mode) and one nominal episode's max and RMS
contour error.  ``--sweep`` adds the commissioned model's loop over a grid of input weights: margins and the
episode's figures, to show where the rule stops and what a faster weight would give.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import vcnc_baselines
import vcnc_gym  # noqa: F401
from vcnc_baselines.commissioning.design import margins
from vcnc_baselines.predictive.design import axis_model, closed_loop_stable, loop_response
from vcnc_baselines.predictive.lq_preview import record_models
from vcnc_gym.evaluation import run_episode

SHOP_IDS = ("VCNC-HeartShop-v1", "VCNC-OmegaLookaheadShop-v1", "VCNC-CornersSmoothShop-v1", "VCNC-CircleShop-v1")


def identified_plant(policy, axis: int = 0):
    """The record's model of ``axis`` as the LQ design discretises it, with the policy's measured outputs."""
    models, delays = record_models(policy.records[0])
    return axis_model(models[axis], policy.dt, delays[axis], policy.velocity)


def report(env, name: str, **params) -> str:
    policy = vcnc_baselines.make(name, env, **params)
    plant = identified_plant(policy)
    omega = np.logspace(-1, np.log10(0.999 * np.pi / policy.dt), 4000)
    model, design, L = policy.axis_models[0], policy.designs[0], policy.estimator_gains[0]
    if model.measurement().shape[0] != plant.measurement().shape[0]:
        loop = "measured outputs differ"
    else:
        m = margins(loop_response(model, design, L, omega, plant=plant), omega)
        loop = (
            f"GM {m.gain_db:5.1f} dB, PM {m.phase_deg:5.1f} deg, Ms {m.sensitivity_db:4.1f} dB, crossover "
            f"{m.crossover:6.0f} rad/s"
        )
    r = run_episode(policy, env)
    return (
        f"{name:24s} rho {design.rho:9.3g}  on the identified model: {loop}  |  max {r.max_contour_error_um:8.4g} um"
        f", RMS {r.rms_contour_error_um:8.4g} um"
    )


def sweep(env, exponents) -> None:
    base = vcnc_baselines.make("lq-preview@commissioned", env)
    model, L = base.axis_models[0], base.estimator_gains[0]
    omega = np.logspace(-1, np.log10(0.999 * np.pi / base.dt), 4000)
    for e in exponents:
        policy = vcnc_baselines.make("lq-preview@commissioned", env, input_weight=10.0**e)
        design = policy.designs[0]
        m = margins(loop_response(model, design, L, omega), omega)
        r = run_episode(policy, env)
        print(
            f"  rho 1e{e:+.1f}: GM {m.gain_db:5.1f} dB, PM {m.phase_deg:5.1f} deg, Ms {m.sensitivity_db:4.1f} dB, "
            f"crossover {m.crossover:6.0f} rad/s, stable {closed_loop_stable(model, design, L)}  |  max "
            f"{r.max_contour_error_um:8.4g} um, RMS {r.rms_contour_error_um:8.4g} um",
            flush=True,
        )


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", action="append", help=f"default: {', '.join(SHOP_IDS)}")
    parser.add_argument("--sweep", action="store_true")
    args = parser.parse_args(argv)
    for env_id in args.env or SHOP_IDS:
        env = gym.make(env_id)
        print(env_id, flush=True)
        for name in ("lq-preview", "lq-preview@commissioned"):
            print("  " + report(env, name), flush=True)
        if args.sweep:
            sweep(env, np.arange(4.0, -6.5, -1.0))


if __name__ == "__main__":
    main()
