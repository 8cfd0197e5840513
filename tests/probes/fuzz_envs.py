"""Fuzz the contouring env: random valid curves, random settings, random and PD policies; then every id.

Run: ``python tests/probes/fuzz_envs.py --episodes 1000`` (``--seed S``; ``--id-episodes K`` per id).

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
listed by kind, not a failure).

Then every current id (``vcnc_gym.envs.ENV_IDS``), as registered, single and
(where it has one) as a native vector env of 3, plants drawn from the box,
under random and saturating actions, with the same counts; and in every
other episode the **NaN check**: at a random step the plant's state is
overwritten with NaN (the way a plant that blew up would leave it) and that
step must end the episode flagged ``diverged`` with a finite observation
inside the space and a finite reward at most the divergence penalty
(-divergence_bound / reward_scale); anything else is counted under "NaN
state not ended as a divergence".  It exits 1 if any failure was seen.
"""

from __future__ import annotations

import argparse
import collections
import re
import sys
import time
import traceback

import numpy as np

import gymnasium as gym

import vcnc_gym
from vcnc_gym.envs import ENV_IDS, VECTOR_IDS
from vcnc_gym.geometry import NurbsCurve

#: Plants with a contouring configuration here: name -> (feedrate range mm/s, dt range s).
PLANTS = {
    "vcnc_feed_drive": ((5.0, 200.0), (5e-5, 5e-4)),
    "current_feed_drive": ((5.0, 100.0), (5e-5, 5e-4)),
    "nct_xy_table": ((0.5, 20.0), (1e-4, 2e-3)),
    "cncmt_axis": ((5.0, 100.0), (1e-4, 2e-3)),
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
        dt=float(np.exp(rng.uniform(np.log(dt_lo), np.log(dt_hi))))
        if plant != "cncmt_axis"
        else 0.1 / int(rng.integers(50, 1000)),  # Yadav et al.'s 0.1 s dead time is a whole number of periods
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


FAILURE_KEYS = (
    "non-finite observation",
    "non-finite reward",
    "positive reward",
    "observation outside the space",
    "observation clipped",
    "exceptions",
)

#: What the per-id fuzz counts as a failure besides :data:`FAILURE_KEYS`.
ID_FAILURE_KEYS = FAILURE_KEYS + ("NaN state not ended as a divergence",)


def _plant_state(env):
    """The plant's state array (N, 2, S) of a single or vector env (where the NaN check writes)."""
    u = env.unwrapped if hasattr(env, "unwrapped") else env
    batch = getattr(u, "_batch", None)
    return batch.plant_arrays.state if batch is not None else u._plant.state


def _penalty(env) -> float:
    u = env.unwrapped if hasattr(env, "unwrapped") else env
    task = getattr(u, "task", u)
    return -task.divergence_bound / task.reward_scale


def fuzz_ids(episodes: int, steps: int, seed: int, ids=ENV_IDS, progress: bool = True) -> dict:
    """``episodes`` episodes per id of ``ids`` (half as native vector envs of 3 where the id has one), every
    other one with the NaN check; returns the counts per id and in all (module docstring)."""
    rng = np.random.default_rng(seed)
    counts, per_id, failures = collections.Counter(), {}, []
    t0 = time.perf_counter()
    for env_id in ids:
        c = per_id[env_id] = collections.Counter()
        for ep in range(episodes):
            vector = env_id in VECTOR_IDS and ep % 4 >= 2
            poison = ep % 2 == 1
            kwargs = {"randomize": True} if env_id in VECTOR_IDS else {}
            try:
                env = (
                    gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
                    if vector
                    else gym.make(env_id, **kwargs)
                )
                space = env.single_observation_space if vector else env.observation_space
                obs, _ = env.reset(seed=int(rng.integers(0, 2**31)))
                at = int(rng.integers(0, steps)) if poison else -1
                c["episodes"] += 1
                for k in range(steps):
                    if k == at:
                        _plant_state(env)[0] = np.nan
                    shape = (3, 2) if vector else (2,)
                    action = rng.uniform(-1.0, 1.0, shape) if ep % 3 else np.sign(rng.normal(size=shape))
                    obs, reward, terminated, truncated, info = env.step(action.astype(np.float32))
                    c["steps"] += 1
                    rows = obs if vector else obs[None]
                    rewards = np.atleast_1d(reward)
                    c["non-finite observation"] += int(not np.all(np.isfinite(rows)))
                    c["non-finite reward"] += int(not np.all(np.isfinite(rewards)))
                    c["positive reward"] += int(np.any(rewards > 0.0))
                    c["observation outside the space"] += int(not all(space.contains(o) for o in rows))
                    diverged = np.atleast_1d(info["diverged"])
                    c["diverged steps"] += int(diverged.any())
                    clipped = np.atleast_1d(info.get("observation_clipped", 0))
                    c["observation clipped"] += int(np.any((clipped > 0) & ~diverged))
                    if k == at:
                        ok = (
                            bool(np.atleast_1d(terminated)[0])
                            and bool(diverged[0])
                            and np.isfinite(rewards[0])
                            and rewards[0] <= _penalty(env)
                            and np.all(np.isfinite(rows[0]))
                            and space.contains(rows[0])
                        )
                        c["NaN checks"] += 1
                        c["NaN state not ended as a divergence"] += int(not ok)
                    if not vector and (terminated or truncated):
                        break
                    if vector and k > at and np.all(np.atleast_1d(terminated) | np.atleast_1d(truncated)):
                        break
                env.close()
            except Exception:  # noqa: BLE001 - a crash is what the fuzz looks for
                c["exceptions"] += 1
                failures.append((env_id, traceback.format_exc(limit=3)))
        counts.update(c)
        if progress:
            print(f"  {env_id}: {c['episodes']} episodes, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return {"counts": counts, "per_id": per_id, "failures": failures, "wall_s": time.perf_counter() - t0}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=1000)
    p.add_argument("--steps", type=int, default=300, help="decisions per episode at most")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--id-episodes", type=int, default=20, help="episodes per registered id (0: none)")
    args = p.parse_args(argv)
    out = fuzz(args.episodes, args.steps, args.seed)
    c = out["counts"]
    print(
        f"{args.episodes} drawn; {c['episodes']} episodes ran ({c['steps']} steps, {c['ended episodes']} ended, "
        f"{c['diverged episodes']} diverged) in {out['wall_s']:.0f} s; "
        f"{args.episodes - c['episodes']} refused at construction with a ValueError:"
    )
    for reason, n in out["refused"].most_common():
        print(f"  {n:5d}  {reason}")
    print("failures:")
    for key in FAILURE_KEYS:
        print(f"  {key:32s} {c[key]}")
    print(
        f"(not failures: observation clipped on the diverging step itself: {c['observation clipped at a divergence']})"
    )
    for where, settings, tb in out["failures"][:5]:
        print(f"--- {where} with {settings}\n{tb}")
    failed = any(c[k] for k in FAILURE_KEYS)
    if args.id_episodes > 0:
        ids = fuzz_ids(args.id_episodes, args.steps, args.seed)
        ci = ids["counts"]
        print(
            f"\nevery id ({len(ids['per_id'])}), {args.id_episodes} episodes each (half of the vector ids' as "
            f"vector envs of 3): {ci['episodes']} episodes, {ci['steps']} steps, {ci['NaN checks']} NaN checks, "
            f"in {ids['wall_s']:.0f} s"
        )
        print(f"  {'id':<26}{'episodes':>9}{'steps':>8}" + "".join(f"{k[:14]:>16}" for k in ID_FAILURE_KEYS))
        for env_id, c in ids["per_id"].items():
            print(f"  {env_id:<26}{c['episodes']:>9}{c['steps']:>8}" + "".join(f"{c[k]:>16}" for k in ID_FAILURE_KEYS))
        for env_id, tb in ids["failures"][:5]:
            print(f"--- {env_id}\n{tb}")
        failed = failed or any(ci[k] for k in ID_FAILURE_KEYS)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
