"""Solve time of the MPC's QP (``baselines/predictive/mpc.py``) with DAQP, OSQP, PIQP and scipy's BVLS, in one run.

Run: ``python benchmarks/mpc_solvers.py`` (``--env ID``, ``--steps N``, ``--repeat R``).

``mpc`` runs ``--steps`` control periods of the env (default ``VCNC-Omega-v1``, whose S-curve corners ask more
than the input limit: the bound is active on many steps) and keeps every box-constrained QP it solves (the
unconstrained minimiser outside the bounds).  Each solver then solves each kept QP ``--repeat`` times, through its
Python interface as the policy would call it: DAQP (dense dual active set, the bounds as simple bounds, cold and
warm-started from the previous QP's active set), OSQP (ADMM; set up once per axis with ``A = I``, then ``update``
of ``q``, ``l``, ``u`` per QP, warm-started by default), PIQP (proximal interior point, its dense solver, set up
per QP: its ``update`` of the bounds gave solutions up to 10 V off in 0.7.0) and scipy's ``lsq_linear`` with the bounded-variable least-squares method on the
Cholesky factor (the reference solution).  Printed: microseconds per solve, each solver's time over DAQP's, and
the largest distance of its solution from BVLS's (V); beside them, the unconstrained minimiser (a matrix product)
and a whole ``predict`` call of ``lq-preview`` and of ``mpc`` in the same run.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import vcnc_baselines
import vcnc_gym  # noqa: F401
from vcnc_baselines.predictive import mpc as mpc_module


def collect(env_id: str, steps: int):
    """The QPs ``mpc`` solves in the first ``steps`` control periods of ``env_id``: (axis, H, f, lower, upper)."""
    kept = []
    solve = mpc_module.solve_box_qp

    def keeping(H, f, lower, upper, active=None):
        axis = next(j for j, qp in enumerate(policy.qps) if qp.H is H)
        kept.append((axis, H, f.copy(), lower.copy(), upper.copy()))
        return solve(H, f, lower, upper, active)

    env = gym.make(env_id)
    policy = vcnc_baselines.make("mpc", env)
    mpc_module.solve_box_qp = keeping
    try:
        obs, _ = env.reset(seed=0)
        per_call = []
        for k in range(steps):
            t0 = time.perf_counter()
            action, _ = policy.predict(obs, episode_start=k == 0)
            per_call.append(time.perf_counter() - t0)
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    finally:
        mpc_module.solve_box_qp = solve
    return policy, kept, np.median(per_call), env


def timed(fn, items, repeat):
    out = [fn(*item) for item in items]  # warm-up and the solutions
    t0 = time.perf_counter()
    for _ in range(repeat):
        for item in items:
            fn(*item)
    return (time.perf_counter() - t0) / (repeat * len(items)), out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="VCNC-Omega-v1")
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    import daqp
    import osqp
    import piqp
    from scipy import optimize, sparse

    policy, kept, mpc_call, env = collect(args.env, args.steps)
    if not kept:
        raise SystemExit(f"no QP solved in {args.steps} steps of {args.env}: the bound was never active")
    b = kept[0][1].shape[0]
    print(f"{args.env}: {len(kept)} QPs in {policy.calls} calls of mpc ({b} variables, {b} bounds each)")

    def scaled(H, f):
        s = 1.0 / np.mean(np.diag(H))
        return H * s, f * s

    def bvls(axis, H, f, lo, hi):
        L = np.linalg.cholesky(H)
        return optimize.lsq_linear(L.T, -np.linalg.solve(L, f), bounds=(lo, hi), method="bvls", tol=1e-12).x

    def daqp_cold(axis, H, f, lo, hi):
        Hs, fs = scaled(H, f)
        return daqp.solve(Hs, fs, np.zeros((0, b)), hi, lo, np.zeros(b, dtype=np.int32))[0]

    active = [np.zeros(b, dtype=np.int32), np.zeros(b, dtype=np.int32)]

    def daqp_warm(axis, H, f, lo, hi):
        return mpc_module.solve_box_qp(H, f, lo, hi, active[axis])

    osqp_solvers = []
    for qp in policy.qps:
        s = osqp.OSQP()
        Hs, _ = scaled(qp.H, np.zeros(b))
        s.setup(
            sparse.csc_matrix(np.triu(Hs)),
            np.zeros(b),
            sparse.identity(b, format="csc"),
            -np.ones(b),
            np.ones(b),
            verbose=False,
            eps_abs=1e-9,
            eps_rel=1e-9,
            polishing=True,
        )
        osqp_solvers.append(s)

    def osqp_solve(axis, H, f, lo, hi):
        s = osqp_solvers[axis]
        s.update(q=scaled(H, f)[1], l=lo, u=hi)
        return s.solve().x

    piqp_failures = [0]

    def piqp_solve(axis, H, f, lo, hi):  # set up per QP: its update of the bounds after a solve gave wrong
        s = piqp.DenseSolver()  # solutions (up to 10 V off) with piqp 0.7.0
        s.settings.eps_abs, s.settings.eps_rel = 1e-9, 1e-9
        Hs, fs = scaled(H, f)
        s.setup(np.asfortranarray(Hs), fs, x_l=lo, x_u=hi)
        if s.solve() != piqp.PIQP_SOLVED:
            piqp_failures[0] += 1
        return s.result.x

    qp0 = policy.qps[0]
    X, R = np.zeros(qp0.Gx.shape[1]), np.zeros(qp0.preview)
    t0 = time.perf_counter()
    for _ in range(10000):
        qp0.unconstrained(X, 0.0, R)
    unconstrained = (time.perf_counter() - t0) / 10000
    lq = vcnc_baselines.make("lq-preview", env)
    obs, _ = env.reset(seed=0)
    lq.predict(obs, episode_start=True)
    t0 = time.perf_counter()
    for _ in range(2000):
        lq.predict(obs)
    lq_call = (time.perf_counter() - t0) / 2000

    reference_time, reference = timed(bvls, kept, args.repeat)
    rows = []
    for name, fn in (
        ("daqp (cold)", daqp_cold),
        ("daqp (warm)", daqp_warm),
        ("osqp", osqp_solve),
        ("piqp", piqp_solve),
        ("scipy bvls", bvls),
    ):
        seconds, solutions = timed(fn, kept, args.repeat)
        error = max(float(np.abs(np.asarray(z) - r).max()) for z, r in zip(solutions, reference))
        rows.append((name, seconds, error))
    base = rows[0][1]
    print(f"{'solver':<14}{'us/solve':>10}{'/ daqp':>9}{'max |z - z_bvls| V':>21}")
    for name, seconds, error in rows:
        print(f"{name:<14}{1e6 * seconds:>10.1f}{seconds / base:>9.2f}{error:>21.2e}")
    print(
        f"unconstrained minimiser (one axis, matrix product): {1e6 * unconstrained:.1f} us ({unconstrained / base:.2f}"
        " x daqp)"
    )
    print(
        f"predict per call, one env: mpc {1e6 * mpc_call:.0f} us (median over the run), lq-preview (compiled) "
        f"{1e6 * lq_call:.0f} us"
    )
    if piqp_failures[0]:
        print(f"piqp did not report PIQP_SOLVED on {piqp_failures[0]} of its {(args.repeat + 1) * len(kept)} solves")
    _ = reference_time


if __name__ == "__main__":
    main()
