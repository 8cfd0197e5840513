"""What a control period of the contouring MPC (``mpcc``) costs, against the MPC's (``mpc``).

Each policy's ``predict`` is timed alone (the env's step is not) over the first ``--steps`` control periods of the
omega from rest: ``mpcc`` on ``VCNC-OmegaOverride-v1`` (its 30-block QP, 90 variables, 60 general rows, per period),
``mpc`` on ``VCNC-Omega-v1`` (its two 10-variable box QPs per period, only where the unconstrained minimiser
leaves the bounds).  The host is shared: run it twice and give both.

    python benchmarks/mpcc_cost.py --steps 2000
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import vcnc_gym  # noqa: F401  (registers the ids)
import vcnc_baselines


def timed(name: str, env_id: str, steps: int, **params) -> tuple[float, int]:
    """Mean wall time of ``predict`` per control period (s) over ``steps`` periods, and the QPs it solved."""
    env = gym.make(env_id)
    policy = vcnc_baselines.make(name, env, **params)
    obs, _ = env.reset(seed=0)
    spent = 0.0
    for k in range(steps):
        t0 = time.perf_counter()
        action, _ = policy.predict(obs, episode_start=k == 0)
        spent += time.perf_counter() - t0
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    env.close()
    return spent / (k + 1), int(getattr(policy, "solves", 0))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=2000, help="control periods timed per policy (default 2000)")
    args = parser.parse_args(argv)
    mpcc, mpcc_solves = timed("mpcc", "VCNC-OmegaOverride-v1", args.steps)
    mpc, mpc_solves = timed("mpc", "VCNC-Omega-v1", args.steps)
    print(f"mpcc: {1e3 * mpcc:.2f} ms per control period ({mpcc_solves} QPs in {args.steps} periods)")
    print(f"mpc:  {1e3 * mpc:.2f} ms per control period ({mpc_solves} QPs in {args.steps} periods)")
    print(f"ratio mpcc / mpc: {mpcc / mpc:.1f}")
    print(f"an omega episode (~{7000} periods) of mpcc: ~{7000 * mpcc:.0f} s of predict")
    return 0 if np.isfinite(mpcc) else 1


if __name__ == "__main__":
    raise SystemExit(main())
