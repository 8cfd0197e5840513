"""Fuzz the contouring env: random valid curves, random settings, random and PD policies.

Run: ``python benchmarks/fuzz_envs.py --episodes 1000`` (``--seed S``).

Each episode draws a random NURBS (degree 1-5, 4-12 control points within
+-60 mm, weights in [0.3, 3], random clamped knots), random settings
(plant, profile, feedrate, ramp time, dt, action repeat, preview steps,
randomised plant, reward scale, effort weight) and a policy (uniform random
actions, full saturation, or a PD loop), builds the env and runs up to
``--steps`` decisions.  It counts, for every step:

- NaN or infinite values in the observation or the reward;
- observations outside the observation space, *and* observation entries the
  env had to clip (``info["observation_clipped"]``): a clipped value is not a
  clean one;
- rewards above 0 (the reward is minus an error);

and, per episode, exceptions other than a ``ValueError`` at construction
(which is the env refusing a curve or a setting with a message: counted and
listed by kind, not a failure).  It exits 1 if any failure was seen.
"""

from __future__ import annotations

import argparse
import collections
import re
import sys
import time
import traceback

import numpy as np

import vcnc_gym
from vcnc_gym.geometry import NurbsCurve

#: Plants with a contouring configuration here: name -> (feedrate range mm/s, dt range s).
PLANTS = {
    "vcnc_feed_drive": ((5.0, 200.0), (5e-5, 5e-4)),
    "current_feed_drive": ((5.0, 100.0), (5e-5, 5e-4)),
    "nct_xy_table": ((0.5, 20.0), (1e-4, 2e-3)),
}


def random_curve(rng: np.random.Generator) -> NurbsCurve:
    """A random NURBS: degree 1-5, 4-12 control points in +-60 mm, weights in [0.3, 3], clamped knots."""
    degree = int(rng.integers(1, 6))
    n = int(rng.integers(degree + 1, max(degree + 2, 13)))
    points = rng.uniform(-60.0, 60.0, (n, 2))
    if rng.random() < 0.2:  # near-degenerate: two control points almost equal
        i = int(rng.integers(0, n - 1))
        points[i + 1] = points[i] + rng.normal(0.0, 1e-9, 2)
    weights = rng.uniform(0.3, 3.0, n)
    inner = np.sort(rng.random(n - degree - 1))
    knots = np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])
    return NurbsCurve(points, weights, knots, degree)


def random_settings(rng: np.random.Generator) -> dict:
    plant = list(PLANTS)[int(rng.integers(0, len(PLANTS)))]
    (f_lo, f_hi), (dt_lo, dt_hi) = PLANTS[plant]
    profile = "scurve" if rng.random() < 0.7 else "constant"
    settings = dict(
        plant=plant,
        profile=profile,
        feedrate=float(np.exp(rng.uniform(np.log(f_lo), np.log(f_hi)))),
        dt=float(np.exp(rng.uniform(np.log(dt_lo), np.log(dt_hi)))),
        action_repeat=int(rng.integers(1, 21)),
        randomize=bool(rng.random() < 0.5),
        preview_steps=tuple(sorted(int(s) for s in rng.integers(1, 200, int(rng.integers(1, 5))))),
        reward_scale=float(10 ** rng.uniform(-3, -1)),
        effort_weight=float(rng.choice([0.0, 0.1])),
    )
    if profile == "scurve":
        settings["ramp_time"] = float(rng.uniform(0.005, 0.3))
    return settings


def _kind(message: str) -> str:
    """A refusal's message with its numbers blanked: its kind."""
    return re.sub(r"[-+]?\d[\d.]*(e[-+]?\d+)?", "#", message.split(";")[0])[:90]


def policy_for(kind: str, env, rng):
    lay = env.layout

    def act(obs):
        if kind == "random":
            return rng.uniform(-1.5, 1.5, 2)
        if kind == "saturate":
            return np.array([1.0, -1.0]) * (1 if rng.random() < 0.99 else -1)
        e = lay.tracking_error(obs)
        return np.clip(300.0 * e + (lay.reference_velocity(obs) - lay.velocity(obs)), -1.0, 1.0)

    return act


def fuzz(episodes: int, steps: int, seed: int, progress: bool = True) -> dict:
    """Run the fuzz; returns the counts (see the module docstring)."""
    rng = np.random.default_rng(seed)
    counts = collections.Counter()
    refused = collections.Counter()
    failures = []
    t0 = time.perf_counter()
    for ep in range(episodes):
        try:
            curve = random_curve(rng)
        except ValueError as exc:
            refused["curve: " + _kind(str(exc))] += 1
            continue
        settings = random_settings(rng)
        try:
            env = vcnc_gym.ContouringEnv(contour=curve, **settings)
        except ValueError as exc:
            refused[_kind(str(exc))] += 1
            continue
        except Exception:  # noqa: BLE001 - a crash is what the fuzz looks for
            failures.append(("construction", settings, traceback.format_exc(limit=3)))
            continue
        counts["episodes"] += 1
        kind = ["random", "saturate", "pd"][ep % 3]
        act = policy_for(kind, env, rng)
        space = env.observation_space
        try:
            obs, _ = env.reset(seed=int(rng.integers(0, 2**31)))
            for _ in range(steps):
                obs, reward, terminated, truncated, info = env.step(act(obs))
                counts["steps"] += 1
                if not np.all(np.isfinite(obs)):
                    counts["non-finite observation"] += 1
                if not np.isfinite(reward):
                    counts["non-finite reward"] += 1
                if reward > 0.0:
                    counts["positive reward"] += 1
                if not space.contains(obs):
                    counts["observation outside the space"] += 1
                if info["observation_clipped"]:
                    # on the step that diverges the tracking error may pass its bound: said apart
                    counts["observation clipped at a divergence" if info["diverged"] else "observation clipped"] += 1
                if info["diverged"]:
                    counts["diverged episodes"] += 1
                if terminated or truncated:
                    counts["ended episodes"] += 1
                    break
        except Exception:  # noqa: BLE001
            failures.append(("episode", settings, traceback.format_exc(limit=3)))
        if progress and (ep + 1) % 100 == 0:
            print(f"  {ep + 1} episodes, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    counts["exceptions"] = len(failures)
    return {"counts": counts, "refused": refused, "failures": failures, "wall_s": time.perf_counter() - t0}


FAILURE_KEYS = ("non-finite observation", "non-finite reward", "positive reward", "observation outside the space",
                "observation clipped", "exceptions")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=1000)
    p.add_argument("--steps", type=int, default=300, help="decisions per episode at most")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    out = fuzz(args.episodes, args.steps, args.seed)
    c = out["counts"]
    print(f"{args.episodes} drawn; {c['episodes']} episodes ran ({c['steps']} steps, {c['ended episodes']} ended, "
          f"{c['diverged episodes']} diverged) in {out['wall_s']:.0f} s; "
          f"{args.episodes - c['episodes']} refused at construction with a ValueError:")
    for reason, n in out["refused"].most_common():
        print(f"  {n:5d}  {reason}")
    print("failures:")
    for key in FAILURE_KEYS:
        print(f"  {key:32s} {c[key]}")
    print(f"(not failures: observation clipped on the diverging step itself: {c['observation clipped at a divergence']})")
    for where, settings, tb in out["failures"][:5]:
        print(f"--- {where} with {settings}\n{tb}")
    return 1 if any(c[k] for k in FAILURE_KEYS) else 0


if __name__ == "__main__":
    sys.exit(main())
