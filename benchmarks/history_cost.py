"""What a residual's memory costs the lean trainer's envs (issue 37): agent steps/s with ``history`` K against none.

    python benchmarks/history_cost.py [--env VCNC-HeartShop-v1] [--n-envs 64] [--history 16 64] [--decisions 200]
        [--blocks 5]

The envs are what ``vcnc-train`` steps (:class:`vcnc_agents.lean_ppo.DecisionEnv`: the native vector env, the
id's shop-floor specialist's action mode from ``experiments/adaptive/recipes/adaptive.yml``, its compiled baseline), one per
memory length, built and warmed up first.  Each is stepped with the same random actions for ``--decisions``
decisions in turn, block after block (so a busy moment of a shared host falls on every side alike), and the best
block of each is kept.  Printed: agent steps/s per memory length and its ratio to the envs without memory, measured in
this run.  The policy network's cost (the longer input) is not in it: the envs' share of a lean run is about three
quarters (``summary.json``'s ``time_shares``).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from vcnc_agents.config import action_mode_of, load_hyperparameters
from vcnc_agents.lean_ppo import DecisionEnv

ADAPTIVE = Path(__file__).resolve().parents[1] / "experiments" / "adaptive" / "recipes" / "adaptive.yml"


def _block(env: DecisionEnv, actions: np.ndarray) -> float:
    """Agent steps/s of one block of decisions."""
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    return actions.shape[0] * env.n / (time.perf_counter() - t0)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="VCNC-HeartShop-v1")
    p.add_argument("--n-envs", type=int, default=64)
    p.add_argument("--history", type=int, nargs="+", default=[16, 64])
    p.add_argument("--decisions", type=int, default=200)
    p.add_argument("--blocks", type=int, default=5)
    args = p.parse_args(argv)
    entry = load_hyperparameters(args.env, ADAPTIVE)
    mode = action_mode_of(entry)
    kwargs = dict(entry.get("env_kwargs") or {})
    lengths = [0] + [k for k in args.history if k > 0]
    envs = {k: DecisionEnv(args.env, args.n_envs, replace(mode, history=k), kwargs, seed=0) for k in lengths}
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (args.decisions, args.n_envs, 2)).astype(np.float32)
    for env in envs.values():
        env.stagger(env.reset())
        _block(env, actions[:10])  # compiled kernels loaded, buffers touched
    best = dict.fromkeys(lengths, 0.0)
    for _ in range(args.blocks):
        for k, env in envs.items():
            best[k] = max(best[k], _block(env, actions))
    print(
        f"{args.env}, {args.n_envs} envs, {mode.baseline} residual, a decision every {mode.action_repeat} control "
        f"periods; best of {args.blocks} blocks of {args.decisions} decisions"
    )
    for k in lengths:
        size = envs[k].observation_space.shape[0]
        print(
            f"  history {k:3d} ({size:4d} observed numbers): {best[k]:9.0f} agent steps/s, "
            f"{best[k] / best[0]:.3f} x none"
        )
    for env in envs.values():
        env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
