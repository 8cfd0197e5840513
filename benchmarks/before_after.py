"""Step cost and vector-env throughput of this tree against an earlier commit, in one run.

Run: ``python benchmarks/before_after.py --before REF`` (``--pairs P``, ``--ids`` the envs).  ``--quick`` is a smoke
run of a few seconds: both workers run this tree (no worktree, this tree's numba cache), two block pairs of a few
steps on the heart; it checks the script, its figures mean nothing.

A git worktree of ``REF`` is made in a temporary folder and put first on ``PYTHONPATH`` for the "before"
worker process; the "after" worker imports this tree.  Each side has its own numba cache.  Each worker builds
its envs once and warms them (compilation is not timed), then times blocks of steps on request, with the same
code on both sides:

1. ``env.step`` of ``gym.make(id)`` replaying a PD tracking controller's actions recorded beforehand in the
   worker (as ``benchmarks/step_cost.py`` does): us per step over a block of ``--block`` steps;
2. ``step`` of the native vector env (``gym.make_vec(id, num_envs=N, vectorization_mode=
   "vector_entry_point")``) under the PD controller, default numba threads: env-steps/s over ``--vector-block``
   steps.

The two workers time blocks in turns (before, after; then after, before; ...), ``P`` pairs per figure, each
block tens of milliseconds.  On this shared 2-core host the speed of a whole process swings by up to 2x for
seconds at a time (a pure-Python loop in fresh processes: 0.17 to 0.27 s), so processes timed one after the
other cannot show 5 %; adjacent blocks see the same host.  It prints each side's median block, the median of
the pairs' ratios after / before and its 95 % bootstrap interval.  A ratio of 1.05 is 5 % slower after (for
the step cost; for env-steps/s, 5 % faster).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: The worker each side runs: it builds every env once, then times blocks of steps on request (a line on stdin:
#: ``single ID`` or ``vector ID``), answering with the block's us per step or env-steps/s.  It uses only what both
#: sides have (gym.make, make_vec, the layout's fields).
WORKER = r"""
import json, sys, time
import numpy as np
import gymnasium as gym
import vcnc_gym

ids, steps, block, vector_block, n_envs = json.loads(sys.argv[1])

def pd(layout, obs):
    u = 300.0 * layout.tracking_error(obs) + 1.0 * (layout.reference_velocity(obs) - layout.velocity(obs))
    return np.clip(u / 5.0, -1.0, 1.0).astype(np.float32)

class Single:
    def __init__(self, env_id):
        self.env = env = gym.make(env_id)
        layout = env.unwrapped.layout
        obs, _ = env.reset(seed=0)
        self.actions = []
        for _ in range(steps):
            a = pd(layout, obs)
            self.actions.append(a)
            obs, _, term, trunc, _ = env.step(a)
            if term or trunc:
                obs, _ = env.reset()
        env.reset(seed=0)
        self.i = 0

    def time(self):
        env, actions, i = self.env, self.actions, self.i
        t0 = time.perf_counter()
        for _ in range(block):
            _, _, term, trunc, _ = env.step(actions[i])
            i += 1
            if term or trunc or i == len(actions):
                env.reset(seed=0)
                i = 0
        self.i = i
        return (time.perf_counter() - t0) / block * 1e6

class Vector:
    def __init__(self, env_id):
        self.envs = envs = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point")
        self.layout = envs.unwrapped.layout
        self.obs, _ = envs.reset(seed=0)
        for _ in range(20):
            self.obs, *_ = envs.step(pd(self.layout, self.obs))

    def time(self):
        stepping = 0.0
        for _ in range(vector_block):
            a = pd(self.layout, self.obs)
            t0 = time.perf_counter()
            self.obs, *_ = self.envs.step(a)
            stepping += time.perf_counter() - t0
        return vector_block * n_envs / stepping

runs = {("single", i): Single(i) for i in ids}
runs.update({("vector", i): Vector(i) for i in ids})
print(json.dumps({"file": vcnc_gym.__file__}), flush=True)
for line in sys.stdin:
    kind, env_id = line.split()
    print(runs[kind, env_id].time(), flush=True)
"""


class Worker:
    """One side's worker process (:data:`WORKER`)."""

    def __init__(self, side_env: dict, settings: list):
        self.proc = subprocess.Popen(
            [sys.executable, "-c", WORKER, json.dumps(settings)],
            env=side_env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=tempfile.gettempdir(),
        )
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the worker failed to start (PYTHONPATH={side_env.get('PYTHONPATH')})")
        self.file = json.loads(line)["file"]

    def time(self, kind: str, env_id: str) -> float:
        self.proc.stdin.write(f"{kind} {env_id}\n")
        self.proc.stdin.flush()
        return float(self.proc.stdout.readline())

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def ratio_interval(ratios: np.ndarray, rng, n_boot: int = 10_000) -> tuple[float, float]:
    """95 % bootstrap interval of the median of the paired ratios."""
    boot = np.median(rng.choice(ratios, (n_boot, ratios.size)), axis=1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return float(lo), float(hi)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", help="the earlier commit (any git ref); required but with --quick")
    p.add_argument("--pairs", type=int, default=300, help="timed block pairs per figure (default 300)")
    p.add_argument("--ids", nargs="+", default=["VCNC-Heart-v1", "VCNC-HeartShop-v1"], help="env ids")
    p.add_argument("--block", type=int, default=2000, help="single-env steps per timed block (default 2000)")
    p.add_argument("--vector-block", type=int, default=10, help="vector-env steps per timed block (default 10)")
    p.add_argument("--envs", type=int, default=1024, help="envs in the native vector env (default 1024)")
    p.add_argument("--json", help="write every block's figures here")
    p.add_argument("--quick", action="store_true", help="a smoke run: this tree on both sides, a few tiny blocks")
    args = p.parse_args(argv)
    if args.quick:
        args.before, args.pairs, args.ids = "this tree (--quick)", 2, args.ids[:1]
        args.block, args.vector_block, args.envs = 20, 1, 4
    elif args.before is None:
        p.error("--before REF is required (or --quick)")
    settings = [args.ids, 200 if args.quick else 20_000, args.block, args.vector_block, args.envs]
    figures = [(kind, env_id) for kind in ("single", "vector") for env_id in args.ids]
    blocks = {f"{k} {i}": {"before": [], "after": []} for k, i in figures}

    with tempfile.TemporaryDirectory() as tmp:
        tree = ROOT if args.quick else Path(tmp) / "before"
        if not args.quick:
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(tree), args.before], check=True
            )
        workers = {}
        try:
            for name, path in (("before", tree), ("after", ROOT)):
                cache = {} if args.quick else {"NUMBA_CACHE_DIR": str(Path(tmp) / f"numba-{name}")}
                side = dict(os.environ, PYTHONPATH=str(path), **cache)
                workers[name] = Worker(side, settings)
                print(f"{name}: {workers[name].file} (built and warmed)", flush=True)
            for kind, env_id in figures:
                for t in range(args.pairs):
                    order = ("before", "after") if t % 2 == 0 else ("after", "before")
                    for name in order:
                        blocks[f"{kind} {env_id}"][name].append(workers[name].time(kind, env_id))
                print(f"{kind} {env_id}: {args.pairs} pairs done", flush=True)
        finally:
            for w in workers.values():
                w.close()
            if not args.quick:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False)

    rng = np.random.default_rng(0)
    rev = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    print(
        f"\nbefore {args.before}, after {rev} (this tree): median over {args.pairs} adjacent block pairs "
        f"({args.block} single-env steps, {args.vector_block} vector steps of {args.envs} envs a block)"
    )
    print(f"{'figure':44s} {'before':>10s} {'after':>10s} {'after/before':>13s} {'95 % interval':>17s}")
    for kind, env_id in figures:
        b, a = (np.array(blocks[f"{kind} {env_id}"][n]) for n in ("before", "after"))
        ratios = a / b
        lo, hi = ratio_interval(ratios, rng)
        label = "us per env.step" if kind == "single" else f"native N={args.envs}, env-steps/s"
        print(
            f"{env_id + ', ' + label:44s} {np.median(b):10.4g} {np.median(a):10.4g} "
            f"{np.median(ratios):13.3f} {f'[{lo:.3f}, {hi:.3f}]':>17s}"
        )
    if args.json:
        Path(args.json).write_text(json.dumps({"before": args.before, "after": rev, "blocks": blocks}, indent=1))


if __name__ == "__main__":
    main()
