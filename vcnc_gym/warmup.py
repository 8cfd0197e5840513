"""Compile the suite's numba kernels once, ahead of use: ``python -m vcnc_gym.warmup``.

numba compiles a kernel the first time it runs and keeps the machine code in
its cache (``cache=True``, ``__pycache__`` beside the sources).  A fresh
install has no cache, so the first ``gym.make`` + ``reset`` + ``step`` of an
env compiles the reference builder, the contour projector and the step
kernel for its plant: 20-30 s on this project's 2-core machines, against
about 2 s once cached (``benchmarks/step_cost.py`` prints both).  ``make
install`` runs this module once, the way an extension module is compiled at
install time, so that a new user's first env starts warm.

For every current id (and one learnable id per machine, :data:`LEARNABLE_MACHINES`) it makes the env, resets it
and steps it once, and
does the same with the native vector env at 16 envs (its parallel kernel),
one fresh process per id, ``--jobs`` at a time (``--ids ID ...``: only those).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

from .envs.registry import LEARNABLE, SUITE

#: The learnable ids whose kernels are warmed too: one per machine (a plant, ideal or on the shop floor), whose
#: compiled servo loop every learnable id of that machine shares (numba caches a kernel per argument types).
LEARNABLE_MACHINES = tuple(
    {(e.kwargs.get("plant"), bool(e.kwargs.get("shop_floor"))): e.id for e in reversed(LEARNABLE)}.values()
)

_ONE = """
import gymnasium as gym, numpy as np, vcnc_gym
from vcnc_gym.envs.registry import suite_env
e = suite_env({id!r})
env = gym.make(e.id)
env.reset(seed=0)
env.step(np.zeros(env.action_space.shape, dtype=np.float32))
if e.vector_entry_point is not None:
    envs = gym.make_vec(e.id, num_envs=16, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    envs.step(np.zeros(envs.action_space.shape, dtype=np.float32))
"""


def _warm(script: str, env_id: str) -> tuple[str, float, str]:
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", script.format(id=env_id)], capture_output=True, text=True)
    return env_id, time.perf_counter() - t0, "" if proc.returncode == 0 else proc.stderr[-2000:]


def warm_in_processes(name: str, ids: list[str], script: str, jobs: int) -> int:
    """Run ``script`` (Python, ``{id}`` the env id) in one fresh process per id of ``ids``, ``jobs`` at a time,
    printing each one's time under ``name``; 1 (and each failure's stderr) if any failed, else 0.  The suite's
    other warm-ups (:mod:`vcnc_bench.warmup`, the controllers' laws) run through it too."""
    t0 = time.perf_counter()
    failed = []
    with ThreadPoolExecutor(jobs) as pool:
        for env_id, seconds, error in pool.map(lambda i: _warm(script, i), ids):
            print(f"  {env_id:26s} {seconds:6.1f} s{'  FAILED' if error else ''}", flush=True)
            if error:
                failed.append((env_id, error))
    print(f"{name}: done in {time.perf_counter() - t0:.0f} s", flush=True)
    for env_id, error in failed:
        print(f"\n{env_id} failed:\n{error}", file=sys.stderr)
    return 1 if failed else 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes at a time (default: the cores)")
    p.add_argument("--ids", nargs="+", metavar="ID", help="only these ids (default: every current id)")
    args = p.parse_args(argv)
    if args.jobs < 1:
        p.error(f"--jobs must be >= 1, got {args.jobs}")
    ids = [e.id for e in SUITE] + list(LEARNABLE_MACHINES)
    unknown = sorted(set(args.ids or ()) - set(ids))
    if unknown:
        p.error(f"--ids: {', '.join(unknown)} not among the current ids ({', '.join(ids)})")
    ids = [i for i in ids if args.ids is None or i in args.ids]
    print(f"vcnc_gym.warmup: compiling the kernels of {len(ids)} envs, {args.jobs} at a time", flush=True)
    return warm_in_processes("vcnc_gym.warmup", ids, _ONE, args.jobs)


if __name__ == "__main__":
    sys.exit(main())
