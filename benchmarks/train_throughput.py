"""vcnc-train throughput before and after the native vector env, same settings, in one run (issue 8).

Run: ``python benchmarks/train_throughput.py`` from the repository root
(``--steps N``, ``--n-envs N [N ...]``, ``--before COMMIT``; ``--help``).  ``--quick`` is a smoke run: the
working tree's trainer alone (no "before", no worktree), 2 envs, one rollout; it checks the script, not a figure.

"Before" is the trainer of commit ``e9abf30`` (the last one before the native
vector env: SB3's ``DummyVecEnv`` over single Gymnasium envs, the residual
wrapper calling the baseline env by env); "after" is the working tree's
trainer with its default VecEnv, the native one (one compiled call steps
every env, the baseline's ``predict`` batched).  The old code is checked
out as a git worktree in a temporary folder, imported by a child process
that puts it first on ``sys.path`` (the child prints the files it imported
from, so the comparison cannot silently run the new code twice), and
removed at the end (``--keep-worktree`` keeps it; its numba cache lands in
it).

Both sides train PPO on ``VCNC-Heart-v0`` (the only heart the "before" code
has) with the same settings: VCNC-Heart-v1's shipped entry of
``agents/hyperparams/ppo.yml`` (residual over Jahanpour et al.'s sliding-mode
controller, correction 0.2 x 5 V = 1 V, a decision every 10 control periods)
given to both as the same file, the same agent steps, n_envs and seed, one
torch thread and one numba thread (``NUMBA_NUM_THREADS=1``: the after side's
kernel would otherwise run a 2-thread ``prange`` whose every call waits for a
core on a shared machine), no TensorBoard, and the cadence both trainers
share: no checkpoint or evaluation during training, one checkpoint and one
deterministic evaluation at the end.  Before the timed run each side
trains one rollout in the same process, so numba compiles (or loads its
cache) outside the timed run.

Printed per side: agent steps/s and control periods/s (agent steps x 10) as
the trainer reports them (``TrainingResult``, the same figures as the run's
``summary.json``: ``model.learn`` wall time, the final evaluation included),
and the same without the final evaluation's wall time (timed around
``vcnc_gym.evaluation.run_episode``, which both trainers' callbacks call),
then the ratio after / before of each.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
#: Trained on both sides: the "before" code knows only the v0 ids, so both train the v0 heart, with the
#: working tree's VCNC-Heart-v1 hyperparameters (ENTRY).
ENV_ID = "VCNC-Heart-v0"
ENTRY = "VCNC-Heart-v1"
BEFORE = "e9abf30"

#: The child: imports agents and vcnc_gym from the code root given first on sys.path, warms up, trains, reports.
_CHILD = r"""
import json, sys, time, warnings
root, config_file, out_dir, env_id, steps, n_envs = sys.argv[1:7]
sys.path.insert(0, root)
import importlib.util
import torch
torch.set_num_threads(1)
spec = importlib.util.find_spec("vcnc_agents")  # found, not imported: an installed one may be another tree's
if spec is not None and spec.origin.startswith(root):
    import vcnc_agents as agents, vcnc_baselines as baselines
else:  # a tree from before the packages' own names (0.2.0): its top-level folders
    import agents, baselines
import vcnc_gym
import vcnc_gym.evaluation as evaluation
warnings.simplefilter("ignore")
for module in (agents, baselines, vcnc_gym):
    if not module.__file__.startswith(root):
        raise SystemExit(f"{module.__name__} imported from {module.__file__}, not from {root}")
eval_wall = []
_run_episode = evaluation.run_episode
def timed_run_episode(*args, **kwargs):
    t0 = time.perf_counter()
    try:
        return _run_episode(*args, **kwargs)
    finally:
        eval_wall.append(time.perf_counter() - t0)
evaluation.run_episode = timed_run_episode
new = hasattr(agents.training, "VEC_ENVS")  # the trainer with the native vector env
# only at the end: the old trainer reads None that way, the new one 0
options = dict(config_file=config_file, seed=0, n_envs=int(n_envs), progress_bar=False, tensorboard=False,
               checkpoint_freq=10**9, eval_freq=0 if new else None)
from stable_baselines3.common.vec_env import VecNormalize  # noqa: F401  (imported before timing, as SB3 is)
h = agents.config.load_hyperparameters(env_id, config_file)
rollout = int(h["n_steps"]) * int(n_envs)
agents.train(env_id, f"{out_dir}/warmup", n_timesteps=rollout, **options)  # numba compiles or loads its cache
eval_wall.clear()
r = agents.train(env_id, f"{out_dir}/run", n_timesteps=int(steps), **options)
summary = json.load(open(f"{out_dir}/run/summary.json"))["sessions"][-1]
print(json.dumps({"agents": agents.__file__, "vcnc_gym": vcnc_gym.__file__, "steps": r.session_timesteps,
                  "wall_s": r.wall_s, "steps_per_s": r.steps_per_s, "control_periods_per_s": r.control_periods_per_s,
                  "eval_s": sum(eval_wall), "summary_steps_per_s": summary["steps_per_s"],
                  "vec_env": summary.get("vec_env")}))
"""


def _heart_entry_file(folder: Path) -> Path:
    """The working tree's ENTRY alone, keyed by ENV_ID, as a hyperparameter file both trainers read."""
    entry = yaml.safe_load((ROOT / "agents" / "hyperparams" / "ppo.yml").read_text())[ENTRY]
    path = folder / "ppo_heart.yml"
    path.write_text(yaml.safe_dump({ENV_ID: entry}, sort_keys=False))
    return path


def _run_side(code_root: Path, config_file: Path, out_dir: Path, steps: int, n_envs: int) -> dict:
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", PYTHONPATH=str(code_root))
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, str(code_root), str(config_file), str(out_dir), ENV_ID, str(steps), str(n_envs)],
        cwd=code_root,
        env=env,
        capture_output=True,
        text=True,
    )
    if proc.returncode != 0:
        raise SystemExit(f"training in {code_root} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _rates(r: dict, repeat: int) -> tuple[float, float, float, float]:
    train_s = r["wall_s"] - r["eval_s"]
    return (r["steps_per_s"], r["control_periods_per_s"], r["steps"] / train_s, r["steps"] * repeat / train_s)


def _print_side(n: int, side: str, r: dict, rates: tuple) -> None:
    vec = r["vec_env"] or "dummy"
    print(
        f"{n:6d} {side:7s} {vec:7s} {r['steps']:7d} {rates[0]:9.0f} {rates[1]:10.0f} {rates[2]:9.0f} "
        f"{rates[3]:11.0f}  {Path(r['agents']).parent}"
    )


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--steps",
        type=int,
        default=40_960,
        help="agent steps of each timed run, rounded up to whole rollouts by both trainers (default 40960)",
    )
    p.add_argument(
        "--n-envs",
        type=int,
        nargs="+",
        default=[2, 16, 64],
        help="training envs, the same on both sides; one comparison each (default: 2, the entry's, 16, 64)",
    )
    p.add_argument("--before", default=BEFORE, help=f"commit of the 'before' trainer (default {BEFORE})")
    p.add_argument(
        "--worktree",
        type=Path,
        default=Path(tempfile.gettempdir()) / "vcnc_before",
        help="where the 'before' commit is checked out (default /tmp/vcnc_before)",
    )
    p.add_argument("--keep-worktree", action="store_true", help="leave the worktree (and its numba cache) in place")
    p.add_argument("--quick", action="store_true", help="a smoke run: the working tree alone, 2 envs, one rollout")
    args = p.parse_args(argv)
    if args.quick:
        args.n_envs, args.steps = [2], 1  # rounded up to one rollout

    entry = yaml.safe_load((ROOT / "agents" / "hyperparams" / "ppo.yml").read_text())[ENTRY]
    repeat = entry["env_wrapper"][0]["vcnc_agents.action_modes.ResidualAction"]["action_repeat"]
    made = not args.quick and not args.worktree.exists()
    if made:
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(args.worktree), args.before],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
    try:
        with tempfile.TemporaryDirectory(prefix="vcnc_train_throughput_") as tmp:
            tmp = Path(tmp)
            config_file = _heart_entry_file(tmp)
            mode = entry["env_wrapper"][0]["vcnc_agents.action_modes.ResidualAction"]
            print(
                f"{ENV_ID} with {ENTRY}'s hyperparameters: {args.steps} agent steps per run (whole rollouts "
                f"of n_steps {entry['n_steps']} x n_envs), residual over {mode['baseline']} (correction {mode['correction']}, action_repeat "
                f"{repeat}), 1 torch + 1 numba thread; before = {'not run (--quick)' if args.quick else args.before}, "
                "after = the working tree"
            )
            header = (
                f"{'n_envs':>6s} {'side':7s} {'VecEnv':7s} {'steps':>7s} {'steps/s':>9s} {'periods/s':>10s} "
                f"{'steps/s*':>9s} {'periods/s*':>11s}  code"
            )
            print(header)
            for n in args.n_envs:
                if args.quick:
                    after = _run_side(ROOT, config_file, tmp / f"after_{n}", args.steps, n)
                    _print_side(n, "after", after, _rates(after, repeat))
                    continue
                before = _run_side(args.worktree, config_file, tmp / f"before_{n}", args.steps, n)
                after = _run_side(ROOT, config_file, tmp / f"after_{n}", args.steps, n)
                rb, ra = _rates(before, repeat), _rates(after, repeat)
                _print_side(n, "before", before, rb)
                _print_side(n, "after", after, ra)
                print(
                    f"{n:6d} {'ratio':7s} {'':7s} {'':7s} {ra[0] / rb[0]:8.2f}x {ra[1] / rb[1]:9.2f}x "
                    f"{ra[2] / rb[2]:8.2f}x {ra[3] / rb[3]:10.2f}x"
                )
            print(
                "steps/s, periods/s: as the trainer reports them (model.learn wall time, final checkpoint and "
                "evaluation included); * without the final evaluation's time"
            )
    finally:
        if made and not args.keep_worktree:
            subprocess.run(
                ["git", "worktree", "remove", "--force", str(args.worktree)], cwd=ROOT, check=True, capture_output=True
            )


if __name__ == "__main__":
    main()
