"""Does a standard algorithm learn on the learnable ids?  SB3's PPO or SAC with their default hyperparameters.

Trains Stable-Baselines3's ``PPO("MlpPolicy")`` (or ``SAC("MlpPolicy")``) with SB3's default hyperparameters on a
learnable id (``VCNC-...-v2``), ``make_vec_env`` with 4 envs (SAC: 1) and ``VecNormalize`` (observation and reward,
SB3's defaults), for each seed, then runs the deterministic policy for one episode on the nominal plant and prints
its contour error beside the references measured in the same run:

- the drive's servo alone (the v2 env with a zero action: the set-point is the reference);
- with ``--base NAME``, the classical controller alone inside the step (a zero correction), the agent's base;
- ``--opponent NAME``, a classical controller on the id's v1 interface (the amplifier command every control period),
  e.g. the id's strongest causal controller; ``pd-ref`` is always run too.

Nothing here is tuned: the hyperparameters are SB3's, and the env is the registered id with its defaults.

    python benchmarks/learnability.py --env VCNC-HeartShop-v2 --seeds 0 1 2 --steps 1000000 --opponent zpetc
    python benchmarks/learnability.py --env VCNC-HeartShop-v2 --base zpetc --seeds 0 1 2 --steps 300000
    python benchmarks/learnability.py --env VCNC-HeartShop-v2 --algo sac --seeds 0 --steps 200000
    python benchmarks/learnability.py --quick          # a smoke run: 2 048 steps of PPO on the circle

``--json FILE`` writes the rows.  Wall times are of this host (``os.cpu_count()`` is printed with them).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

import vcnc_gym  # noqa: F401  (registers the ids)


def _episode(model, env) -> dict:
    """One deterministic episode of ``model`` (or of a zero action with ``model=None``) on ``env``, a VecEnv of one
    env (VecNormalize'd for a model): the env's episode summary, in um."""
    obs = env.reset()
    while True:
        action = np.zeros((1, 2), dtype=np.float32) if model is None else model.predict(obs, deterministic=True)[0]
        obs, _, done, infos = env.step(action)
        if done[0]:
            s = infos[0]["episode_summary"]
            return {
                "max_um": 1e3 * s["contour_error_max"],
                "rms_um": 1e3 * s["contour_error_rms"],
                "completed": s["completed"],
                "diverged": s["diverged"],
            }


def _classical(env_id: str, name: str) -> dict:
    """Classical controller ``name`` on the v1 interface of ``env_id``'s task (nominal plant)."""
    import gymnasium as gym
    import vcnc_baselines
    from vcnc_gym.evaluation import run_episode

    env = gym.make(env_id.replace("-v2", "-v1"))
    r = run_episode(vcnc_baselines.make(name, env), env)
    return {
        "max_um": r.max_contour_error_um,
        "rms_um": r.rms_contour_error_um,
        "completed": r.completed,
        "diverged": r.diverged,
    }


def _eval_env(env_id: str, env_kwargs: dict, stats=None):
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    env = make_vec_env(env_id, n_envs=1, seed=0, env_kwargs=env_kwargs)
    if stats is None:
        return env
    env = VecNormalize(env, training=False, norm_reward=False)
    env.obs_rms = stats.obs_rms
    return env


def train(env_id: str, algo: str, seed: int, steps: int, env_kwargs: dict) -> dict:
    """Train one seed with SB3's defaults and evaluate its deterministic episode on the nominal plant."""
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    env = VecNormalize(make_vec_env(env_id, n_envs=4 if algo == "ppo" else 1, seed=seed, env_kwargs=env_kwargs))
    model = (PPO if algo == "ppo" else SAC)("MlpPolicy", env, seed=seed, verbose=0)
    t0 = time.perf_counter()
    model.learn(steps)
    wall = time.perf_counter() - t0
    row = _episode(model, _eval_env(env_id, env_kwargs, env))
    return {"algo": algo, "env": env_id, **env_kwargs, "seed": seed, "steps": steps, "wall_s": wall, **row}


def main(argv=None) -> list[dict]:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="VCNC-HeartShop-v2", help="a learnable id (-v2)")
    p.add_argument("--algo", choices=("ppo", "sac"), default="ppo")
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--steps", type=int, default=1_000_000, help="agent steps (decisions) per seed")
    p.add_argument("--base", default=None, help="a classical controller the agent corrects (base=)")
    p.add_argument("--opponent", action="append", default=[], help="a classical controller to run on v1 too")
    p.add_argument("--env-kwargs", type=json.loads, default={}, help="the env's arguments, JSON (default: the id's)")
    p.add_argument("--json", default=None, help="write the rows to this file")
    p.add_argument("--quick", action="store_true", help="a smoke run: 2 048 PPO steps on VCNC-Circle-v2")
    a = p.parse_args(argv)
    if a.quick:
        a.env, a.steps, a.seeds, a.opponent = "VCNC-Circle-v2", 2048, [0], []
    if not a.env.endswith("-v2"):
        p.error(f"--env must be a learnable id (-v2), got {a.env!r}")
    if a.steps < 1:
        p.error(f"--steps must be >= 1, got {a.steps}")
    if not isinstance(a.env_kwargs, dict):
        p.error(f"--env-kwargs must be a JSON object, got {a.env_kwargs!r}")
    kwargs = {**a.env_kwargs, **({} if a.base is None else {"base": a.base})}
    servo = {k: v for k, v in a.env_kwargs.items() if k != "setpoint_range"}
    rows = [{"policy": "servo alone", "env": a.env, **_episode(None, _eval_env(a.env, servo))}]
    if a.base is not None:
        rows.append({"policy": f"{a.base} inside the step", "env": a.env, **_episode(None, _eval_env(a.env, kwargs))})
    for name in ["pd-ref", *a.opponent]:
        rows.append({"policy": f"{name} (v1)", "env": a.env, **_classical(a.env, name)})
    for row in rows:
        print(
            f"{row['policy']:<28} max {row['max_um']:8.3f} um  RMS {row['rms_um']:7.3f} um  "
            f"completed {row['completed']}  diverged {row['diverged']}",
            flush=True,
        )
    for seed in a.seeds:
        row = train(a.env, a.algo, seed, a.steps, kwargs)
        rows.append(row)
        print(
            f"{a.algo} seed {seed} ({a.steps} steps, {row['wall_s']:.0f} s on {os.cpu_count()} cores)"
            f"{' base ' + a.base if a.base else ''}: max {row['max_um']:.3f} um  RMS {row['rms_um']:.3f} um  "
            f"completed {row['completed']}  diverged {row['diverged']}",
            flush=True,
        )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
