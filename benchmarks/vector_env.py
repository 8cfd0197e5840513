"""Throughput of the native vector env against Gymnasium's SyncVectorEnv, in one run.

Run: ``python benchmarks/vector_env.py`` (``--seconds S`` per measurement,
``--envs N`` for the native env's size, ``--ids`` for the envs, ``--no-load``
to skip the loaded half).

For each env id (heart, omega) it times, with a PD tracking controller
driving every env (so the tables follow the contour for real: friction,
backlash, exact contour error), only the ``step`` calls of

1. ``gym.make_vec(id, num_envs=8, vectorization_mode="sync")`` (SyncVectorEnv);
2. ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
   (the native vector env) with 1 numba thread, with 2 (its default
   ``parallel=None``: the serial or the parallel kernel, whichever is faster,
   :class:`~vcnc_gym.envs.contouring_vector_env.KernelPath`), and with 2
   forced onto the parallel kernel (``parallel=True``, the behaviour before
   issue 21),

first on the machine as it is ("idle"), then again while a busy loop this
script starts (``--load-nice``, default 0: a normal-priority process such as
another engineer's test run) holds a core ("loaded").  It prints env-steps/s,
the ratio of each native figure to SyncVectorEnv at N = 8 (same load) and to
the native env at 1 thread (same load), and the share of the default's
calls that ran the parallel kernel.  The rows of one load take turns in
slices of 0.2 s (``--seconds`` each in all), so other processes' load falls
on all of them alike.  Episodes end and reset inside the timed loop.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from contextlib import contextmanager

import gymnasium as gym
import numba
import numpy as np

import vcnc_gym  # noqa: F401


def _pd(layout, obs):
    u = 300.0 * layout.tracking_error(obs) + 1.0 * (layout.reference_velocity(obs) - layout.velocity(obs))
    return np.clip(u / 5.0, -1.0, 1.0).astype(np.float32)


def env_steps_per_second(envs, seconds: float) -> float:
    """Env-steps per second of ``envs.step`` alone, under a PD controller, over ``seconds`` of stepping."""
    return Stepper(envs).run(seconds).rate


class Stepper:
    """Steps ``envs`` under the PD controller in slices, accumulating the time of the ``step`` calls alone."""

    def __init__(self, envs):
        self.envs = envs
        u = envs.unwrapped
        self.layout = u.layout if hasattr(u, "layout") else u.envs[0].unwrapped.layout
        self.obs, _ = envs.reset(seed=0)
        for _ in range(20):  # compile and warm up
            self.obs, *_ = envs.step(_pd(self.layout, self.obs))
        self.stepping = 0.0
        self.steps = 0

    def run(self, seconds: float) -> "Stepper":
        until = self.stepping + seconds
        while self.stepping < until:
            action = _pd(self.layout, self.obs)
            t0 = time.perf_counter()
            self.obs, *_ = self.envs.step(action)
            self.stepping += time.perf_counter() - t0
            self.steps += 1
        return self

    @property
    def rate(self) -> float:
        return self.steps * self.envs.num_envs / self.stepping


@contextmanager
def busy_core(nice: int | None):
    """A busy loop in a child process at priority ``nice`` while the block runs (nothing for None)."""
    if nice is None:
        yield
        return
    proc = subprocess.Popen(["nice", "-n", str(nice), sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.3)
        yield
    finally:
        proc.kill()
        proc.wait()


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=3.0, help="stepping time per measurement, s")
    p.add_argument("--envs", type=int, default=1024, help="envs in the native vector env")
    p.add_argument("--ids", nargs="+", default=["VCNC-Heart-v1", "VCNC-Omega-v1"], help="env ids")
    p.add_argument("--load-nice", type=int, default=0, help="nice level of the busy loop of the loaded half")
    p.add_argument("--no-load", action="store_true", help="measure only the machine as it is")
    args = p.parse_args(argv)
    cores = numba.config.NUMBA_NUM_THREADS
    threads = min(2, cores)
    print(f"numba threads available: {cores}; PD controller on every env; env-steps/s of step() alone")
    loads = [("idle", None)] + (
        [] if args.no_load else [(f"loaded (busy loop, nice {args.load_nice})", args.load_nice)]
    )
    print(f"{'env':15s} {'load':28s} {'vector env':40s} {'env-steps/s':>12s} {'x Sync(8)':>10s} {'x 1 thread':>10s}")
    for env_id in args.ids:
        sync = gym.make_vec(env_id, num_envs=8, vectorization_mode="sync")
        auto = gym.make_vec(env_id, num_envs=args.envs, vectorization_mode="vector_entry_point")
        forced = gym.make_vec(env_id, num_envs=args.envs, vectorization_mode="vector_entry_point", parallel=True)
        for load, nice in loads:
            with busy_core(nice):
                # the rows take turns in slices of 0.2 s, so a change of the host's load falls on all of them
                rows = [
                    ("SyncVectorEnv, N = 8", Stepper(sync), None),
                    (f"native, N = {args.envs}, 1 thread", Stepper(auto), 1),
                    (f"native, N = {args.envs}, {threads} threads (default)", Stepper(auto), threads),
                    (f"native, N = {args.envs}, {threads} threads, parallel=True", Stepper(forced), threads),
                ]
                path = auto.unwrapped._path
                calls0 = list(path.calls) if path is not None else None
                for _ in range(max(1, round(args.seconds / 0.2))):
                    for _, stepper, t in rows:
                        numba.set_num_threads(t or cores)
                        stepper.run(0.2)
                numba.set_num_threads(cores)
                base, one = rows[0][1].rate, rows[1][1].rate
                for label, stepper, t in rows:
                    rate = stepper.rate
                    note = ""
                    if t == threads and stepper.envs is auto and path is not None:
                        serial, parallel = (c - c0 for c, c0 in zip(path.calls, calls0))
                        note = f"  parallel kernel on {parallel / max(1, serial + parallel):.0%} of calls"
                    print(
                        f"{env_id:15s} {load:28s} {label:40s} {rate:12,.0f} {rate / base:10.2f} "
                        f"{'' if t is None else f'{rate / one:10.2f}'}{note}",
                        flush=True,
                    )
        for envs in (sync, auto, forced):
            envs.close()
    print(f"numba threading layer: {numba.threading_layer()}")


if __name__ == "__main__":
    main()
