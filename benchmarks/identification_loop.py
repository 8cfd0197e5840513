"""What the identification experiment's holding loop costs (a commissioning's main part): one kernel call for the
whole run (``Machines.hold``) against the loop that commands the machines one period at a time from Python
(``Machines.step``, the experiment before the kernel), measured in the same run.

    python benchmarks/identification_loop.py [--env VCNC-OmegaLookaheadShop-v1] [--machines 1 8] [--periods 20000]
        [--repeats 3]

Per batch size: the best of ``--repeats`` runs of each loop over the same machines (plants of the id's box) and
the same random loop arrays, its wall time and the ratio.  A per-machine commissioning (``ff-pid@machine`` in a
trainer's envs, which draw a plant at every reset) runs this loop for about 98 000 periods per call; the two loops'
records are equal to the bit (``tests/test_commissioning_kernel.py``).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import vcnc_gym  # noqa: F401
from vcnc_baselines.commissioning.identify import Machines
from vcnc_gym.envs import step_kernel as sk


def random_loop(rng, n: int, periods: int, u_max) -> sk.HoldingLoop:
    """A holding loop of ``periods`` periods with random feedforward, moves and excitation (fresh outputs)."""
    return sk.HoldingLoop(
        feedforward=0.2 * u_max * rng.standard_normal((periods // 2, 2)),
        legs=0.05 * u_max * rng.standard_normal((periods, 2)),
        offset=np.cumsum(1e-4 * rng.standard_normal((periods, 2)), axis=0),
        offset_rate=0.5 * rng.standard_normal((periods, 2)),
        excitation=0.3 * u_max * np.where(rng.random((n, periods, 2)) < 0.5, -1.0, 1.0),
        kp=np.array([40.0, 55.0]),
        kd=np.array([0.3, 0.4]),
        ki=np.array([900.0, 700.0]),
        alpha=np.array([0.6, 0.7]),
        dt=1e-3,
        u_max=np.asarray(u_max, dtype=np.float64),
        u=np.zeros((n, periods, 2)),
        e=np.zeros((n, periods, 2)),
        velocity=np.zeros((n, periods, 2)),
    )


def numpy_loop(machines: Machines, h: sk.HoldingLoop) -> None:
    """The same loop, one period and one ``Machines.step`` at a time, in numpy (the experiment's loop before the
    kernel); fills ``h``'s outputs."""
    lay = machines.layout
    n = machines.n
    obs = machines.observe()
    vf = np.zeros((n, 2))
    integral = np.zeros((n, 2))
    for k in range(h.u.shape[1]):
        E = lay.tracking_error(obs)
        h.velocity[:, k] = lay.velocity(obs)
        vf = h.alpha * vf + (1 - h.alpha) * h.velocity[:, k]
        ek = E + h.offset[k]
        h.e[:, k] = E
        integral += ek * h.dt
        h.u[:, k] = (
            h.feedforward[min(k, h.feedforward.shape[0] - 1)]
            + h.legs[k]
            + h.kp * ek
            + h.kd * (lay.reference_velocity(obs) + h.offset_rate[k] - vf)
            + h.ki * integral
            + h.excitation[:, k]
        )
        h.u[:, k] = np.clip(h.u[:, k], -h.u_max, h.u_max)
        obs = machines.step(h.u[:, k])


def box_plants(env_id: str, n: int) -> np.ndarray:
    """``n`` plants drawn from the id's box (its env's resets with seeds 0 .. n - 1), (n, 2, P)."""
    env = gym.make(env_id, randomize=True).unwrapped
    out = []
    for seed in range(n):
        env.reset(seed=seed)
        out.append(np.array(env.parameters))
    return np.array(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="VCNC-OmegaLookaheadShop-v1")
    p.add_argument("--machines", type=int, nargs="+", default=[1, 8])
    p.add_argument("--periods", type=int, default=20000)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    task = gym.make(args.env).unwrapped.task
    warm = Machines(task, box_plants(args.env, 1))
    warm.hold(random_loop(np.random.default_rng(0), 1, 10, warm.u_max))  # compiled (or loaded) before timing
    print(f"{args.env}: {args.periods} periods of the holding loop, best of {args.repeats}")
    for n in args.machines:
        params = box_plants(args.env, n)
        best = {"kernel": np.inf, "numpy": np.inf}
        for _ in range(args.repeats):
            for name in best:  # alternately, so that a busy moment of a shared host falls on both
                machines = Machines(task, params)
                h = random_loop(np.random.default_rng(1), n, args.periods, machines.u_max)
                t0 = time.perf_counter()
                machines.hold(h) if name == "kernel" else numpy_loop(machines, h)
                best[name] = min(best[name], time.perf_counter() - t0)
        print(
            f"  {n} machine(s): kernel {best['kernel']:.4f} s, numpy loop {best['numpy']:.3f} s: "
            f"{best['numpy'] / best['kernel']:.0f} x"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
