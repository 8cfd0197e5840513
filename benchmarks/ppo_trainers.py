"""PPO trainers side by side on the heart's residual task: same task, same budget, one run (issue 21).

Run: ``python benchmarks/ppo_trainers.py --n-envs 64 --steps 131072`` (``--candidates``, ``--help``).

The task: ``VCNC-Heart-v1``, residual over Jahanpour et al.'s sliding-mode controller
(correction 0.2 x 5 V, a decision every 10 control periods), the shipped
entry of ``agents/hyperparams/ppo.yml`` for everything a candidate does not
change; seed 0; no checkpoint or evaluation during training, one
deterministic evaluation on the nominal plant at the end (the same
``vcnc_gym.evaluation.run_episode`` as ``vcnc-bench``).  Every candidate
trains the same number of agent steps (``--steps``, rounded up to a whole
number of every candidate's rollouts) with the same ``--n-envs``, each in a
fresh process that first trains one rollout untimed (numba and JAX compile
or load their caches).

Candidates (``--candidates``), ``TRAINER[:key=value,...]``:

- ``sb3``: ``vcnc-train`` as configured today (SB3's PPO, native vector
  env, torch's own thread count; ``sb3:threads=1``, the first default, with
  one torch thread as ``benchmarks/train_throughput.py`` runs it: on a shared
  2-core machine torch's second thread mostly waits);
- ``sb3:...``, ``lean:...``, ``sbx:...``: SB3's PPO, the lean trainer
  (``vcnc-train --trainer lean``, ``agents/lean_ppo.py``) or SBX's PPO (SB3's
  JAX port, ``pip install sbx-rl jax``, over the same ``VcncVecEnv`` and
  ``VecNormalize``) with entry keys changed: ``n_steps``, ``batch_size``,
  ``n_epochs``, ``learning_rate``, ``rollout=R`` (n_steps = R / n_envs) and
  ``threads=T`` (torch threads; JAX: XLA's own).

Printed per candidate: agent steps/s and env steps/s (agent steps x 10 control
periods, the plant's steps) of training (the final evaluation's time and the
lean trainer's staggered start left out: the start is printed apart, a
one-off cost of about N x L / 2 decisions of the baseline, L = 3 221
decisions per episode), the share of that time in the env (the vector env's
calls), the policy's forward pass during the rollout, the PPO update and the
rest, the process's CPU time per agent step (every thread; the staggered
start included, the final evaluation not: 1e6 / it is what one core given
to the run alone would reach at most, whatever the host's load), and
the final evaluation's max and RMS contour error (um).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
ENV_ID = "VCNC-Heart-v1"
REPEAT = 10
#: Rollouts of 16 384 agent steps, minibatches of 4 096, 3 epochs, learning rate 1e-3: the lean entry
#: (agents/hyperparams/ppo_lean.yml), chosen with this script (a lower error than 2 048 x 5 epochs at 3e-4, faster).
BIG = "rollout=16384,batch_size=4096,n_epochs=3,learning_rate=0.001"
DEFAULT_CANDIDATES = ["sb3:threads=1", f"sb3:{BIG},threads=1", f"sbx:{BIG}", f"lean:{BIG},threads=1"]

#: The child: trains one candidate, prints one JSON line.
_CHILD = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
trainer, config_file, out_dir, env_id, steps, n_envs, threads = sys.argv[1:8]
steps, n_envs = int(steps), int(n_envs)
import torch
if threads != "default":
    torch.set_num_threads(int(threads))
import numpy as np
import vcnc_agents, vcnc_gym
import vcnc_gym.evaluation as evaluation
from vcnc_agents.config import load_hyperparameters, ppo_arguments, normalize_kwargs, action_mode_of
from vcnc_agents.vec_env import VcncVecEnv

clock = {"env": 0.0, "forward": 0.0, "update": 0.0, "eval": 0.0, "eval_cpu": 0.0}
def cpu():  # CPU seconds of this process, every thread
    import resource
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime
def timed(owner, name, phase):
    original = getattr(owner, name)
    def wrapper(*args, **kwargs):
        t0, c0 = time.perf_counter(), cpu() if phase == "eval" else 0.0
        try:
            return original(*args, **kwargs)
        finally:
            clock[phase] += time.perf_counter() - t0
            if phase == "eval":
                clock["eval_cpu"] += cpu() - c0
    setattr(owner, name, wrapper)
timed(evaluation, "run_episode", "eval")
h = load_hyperparameters(env_id, config_file)
rollout = int(h["n_steps"]) * n_envs
options = dict(config_file=config_file, seed=0, n_envs=n_envs, eval_freq=0, checkpoint_freq=10**9)

if trainer in ("sb3", "lean"):
    if trainer == "sb3":
        from stable_baselines3 import PPO
        from stable_baselines3.common.policies import ActorCriticPolicy
        timed(VcncVecEnv, "step_wait", "env")
        timed(ActorCriticPolicy, "forward", "forward")
        timed(PPO, "train", "update")
        run = lambda d, n: vcnc_agents.train(env_id, d, n_timesteps=n, progress_bar=False, tensorboard=False, **options)
    else:
        from vcnc_agents.lean_ppo import train_lean
        run = lambda d, n: train_lean(env_id, d, n_timesteps=n, progress_bar=False, **options)
    run(f"{out_dir}/warmup", rollout)  # compiles or loads the caches
    for k in clock:
        clock[k] = 0.0
    cpu0 = cpu()
    r = run(f"{out_dir}/run", steps)
    cpu_s = cpu() - cpu0
    session = json.load(open(f"{out_dir}/run/summary.json"))["sessions"][-1]
    if trainer == "lean":
        clock.update({k: session["phase_s"][k] for k in ("env", "forward", "update")})
        stagger = session["stagger_s"]
    else:
        stagger = 0.0
    result = {"wall_s": r.wall_s, "steps": r.session_timesteps, "max_um": r.best["max_um"], "rms_um": r.best["rms_um"]}
else:  # SBX over the same VecEnv and VecNormalize as vcnc-train
    import sbx
    from stable_baselines3.common.vec_env import VecNormalize
    from vcnc_agents.normalization import NormalizationStats
    from vcnc_agents.policy import AgentPolicy
    import gymnasium as gym
    _, kwargs = ppo_arguments(h)
    policy_kwargs = kwargs.pop("policy_kwargs", {})
    mode = action_mode_of(h)
    timed(VcncVecEnv, "step_wait", "env")
    timed(sbx.PPO, "train", "update")
    def run(n):
        venv = VecNormalize(VcncVecEnv(env_id, n_envs, mode, {}, seed=0), **normalize_kwargs(h))
        model = sbx.PPO("MlpPolicy", venv, seed=0, policy_kwargs=policy_kwargs, **kwargs)
        timed(model.policy, "predict_all", "forward")
        t0 = time.perf_counter()
        model.learn(total_timesteps=n)
        env = gym.make(env_id)
        res = evaluation.run_episode(AgentPolicy(model, NormalizationStats.from_vecnormalize(venv), mode, env),
                                     env, seed=0)
        return time.perf_counter() - t0, model.num_timesteps, res
    run(rollout)
    for k in clock:
        clock[k] = 0.0
    cpu0 = cpu()
    wall, done, res = run(steps)
    cpu_s = cpu() - cpu0
    stagger = 0.0
    result = {"wall_s": wall, "steps": done, "max_um": res.max_contour_error_um, "rms_um": res.rms_contour_error_um}
result.update(clock, stagger_s=stagger, threads=torch.get_num_threads(), cpu_s=cpu_s)
print(json.dumps(result))
"""


def parse_candidate(spec: str) -> tuple[str, dict, str]:
    """(trainer, entry changes, torch threads) of ``TRAINER[:key=value,...]``."""
    trainer, _, rest = spec.partition(":")
    if trainer not in ("sb3", "lean", "sbx"):
        raise SystemExit(f"candidate {spec!r}: the trainer must be sb3, lean or sbx")
    changes, threads = {}, "default"
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        if key == "threads":
            threads = value
        elif key in ("rollout", "n_steps", "batch_size", "n_epochs"):
            changes[key] = int(value)
        elif key == "learning_rate":
            changes[key] = float(value)
        else:
            raise SystemExit(f"candidate {spec!r}: unknown key {key!r}")
    return trainer, changes, threads


def entry_for(changes: dict, n_envs: int) -> dict:
    entry = yaml.safe_load((ROOT / "agents" / "hyperparams" / "ppo.yml").read_text())[ENV_ID]
    changes = dict(changes)
    if "rollout" in changes:
        changes["n_steps"] = max(1, changes.pop("rollout") // n_envs)
    entry.update(changes)
    return entry


def run_candidate(spec: str, n_envs: int, steps: int, folder: Path) -> dict:
    trainer, changes, threads = parse_candidate(spec)
    entry = entry_for(changes, n_envs)
    config = folder / "ppo.yml"
    folder.mkdir(parents=True)
    config.write_text(yaml.safe_dump({ENV_ID: entry}, sort_keys=False))
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, trainer, str(config), str(folder), ENV_ID, str(steps), str(n_envs), threads],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
    )
    if proc.returncode != 0:
        raise SystemExit(f"candidate {spec} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    r["entry"] = {k: entry[k] for k in ("n_steps", "batch_size", "n_epochs", "learning_rate")}
    return r


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n-envs", type=int, default=64, help="training envs of every candidate (default 64)")
    p.add_argument(
        "--steps",
        type=int,
        default=131072,
        help="agent steps of every candidate, rounded up to whole rollouts of all (default 131072)",
    )
    p.add_argument(
        "--candidates",
        nargs="+",
        default=DEFAULT_CANDIDATES,
        metavar="SPEC",
        help="TRAINER[:key=value,...] (see the module docstring); default: " + " ".join(DEFAULT_CANDIDATES),
    )
    p.add_argument("--json", type=Path, help="also write the records to this file")
    args = p.parse_args(argv)
    rollouts = [entry_for(parse_candidate(c)[1], args.n_envs)["n_steps"] * args.n_envs for c in args.candidates]
    lcm = math.lcm(*rollouts)
    steps = -(-args.steps // lcm) * lcm
    print(
        f"{ENV_ID}, residual over SMC (correction 0.2, action repeat {REPEAT}), n_envs {args.n_envs}, "
        f"{steps} agent steps per candidate, seed 0; rates of training without the final evaluation"
    )
    print(
        f"{'candidate':58s} {'agent st/s':>10s} {'env st/s':>10s} {'env':>5s} {'fwd':>5s} {'upd':>5s} "
        f"{'other':>5s} {'stagger':>7s} {'CPU us/st':>9s} {'max um':>7s} {'RMS um':>7s}"
    )
    records = []
    with tempfile.TemporaryDirectory(prefix="vcnc_ppo_trainers_") as tmp:
        for k, spec in enumerate(args.candidates):
            r = run_candidate(spec, args.n_envs, steps, Path(tmp) / f"c{k}")
            train_s = r["wall_s"] - r["eval"] - r["stagger_s"]
            rate = r["steps"] / train_s
            r["env"] -= r["stagger_s"]
            shares = {ph: r[ph] / train_s for ph in ("env", "forward", "update")}
            shares["other"] = 1.0 - sum(shares.values())
            cpu_us = 1e6 * (r["cpu_s"] - r["eval_cpu"]) / r["steps"]  # the staggered start included
            records.append(
                {
                    "candidate": spec,
                    "n_envs": args.n_envs,
                    "steps": r["steps"],
                    "agent_steps_per_s": rate,
                    "cpu_us_per_agent_step": cpu_us,
                    "env_steps_per_s": rate * REPEAT,
                    "train_s": train_s,
                    "stagger_s": r["stagger_s"],
                    "shares": shares,
                    "max_um": r["max_um"],
                    "rms_um": r["rms_um"],
                    "entry": r["entry"],
                    "torch_threads": r["threads"],
                }
            )
            print(
                f"{spec:58s} {rate:10,.0f} {rate * REPEAT:10,.0f} "
                + " ".join(f"{shares[ph]:5.2f}" for ph in ("env", "forward", "update", "other"))
                + f" {r['stagger_s']:6.1f}s {cpu_us:9.1f} {r['max_um']:7.2f} {r['rms_um']:7.2f}",
                flush=True,
            )
    base = records[0]
    for rec in records[1:]:
        print(
            f"{rec['candidate']:58s} {rec['agent_steps_per_s'] / base['agent_steps_per_s']:9.2f}x of "
            f"{base['candidate']}"
        )
    if args.json:
        args.json.write_text(json.dumps(records, indent=1))


if __name__ == "__main__":
    main()
