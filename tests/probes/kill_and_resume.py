"""Kill a vcnc-train run with SIGKILL mid-run, resume it, and account for every logged row.

Run: ``python tests/probes/kill_and_resume.py`` (``--workdir DIR`` to keep the
run folder, ``--mode residual`` for evaluations with finite scores and a best/).

1. ``vcnc-train`` starts a small run on VCNC-Omega-v1 in a subprocess (a tiny
   network, ``n_steps`` 128 x 2 envs = 256 agent steps per rollout,
   a checkpoint every 512 steps, an evaluation every 768);
2. once a checkpoint at 1024 steps or more exists and an episode has been
   logged after the newest checkpoint, it is killed with SIGKILL (so the logs
   have rows past the newest checkpoint, the training they describe being lost);
3. ``vcnc-train --resume`` finishes it;
4. :func:`audit_run` checks the logs:

   - evaluations.csv: steps unique and increasing, the expected grid;
   - every Monitor file: each episode row is accounted for by the steps
     between it and the previous row, ``steps_k - steps_{k-1} = n_envs * l_k``
     (the envs step in lock-step), except right after a session start S,
     where the envs were reset: ``steps_k - S = n_envs * l_k``.  A lost row
     breaks the chain; a duplicated one repeats a step count.
   - the rows written before the kill up to the checkpoint resumed from are
     still there, unchanged;
   - the rows reach the run's end (at most one episode missing): a resumed
     session whose rows all went to a deleted file (the lean trainer before
     issue 35) fails here.

The same audit of a naive merge (the killed session's rows kept and the
resumed session's appended: what "append without roll-back" would give)
shows the check can fail.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_CONFIG = """\
VCNC-Omega-v1:
  n_envs: 2
  n_timesteps: 4096
  policy: MlpPolicy
  normalize: "{{'norm_obs': True, 'norm_reward': True}}"
{mode}
  n_steps: 128
  batch_size: 128
  n_epochs: 1
  gamma: 0.99
  policy_kwargs: "dict(log_std_init=-1.0, net_arch=dict(pi=[16], vf=[16]))"
"""
_MODES = {
    "direct": "  env_kwargs:\n    action_repeat: 10",
    "residual": "  env_wrapper:\n    - vcnc_agents.action_modes.ResidualAction:\n        baseline: qft\n"
    "        correction: 0.3\n        action_repeat: 10",
}


def write_config(folder: Path, mode: str = "direct") -> Path:
    """A tiny hyperparameter file for VCNC-Omega-v1 in ``folder``."""
    path = folder / "tiny.yml"
    path.write_text(_CONFIG.format(mode=_MODES[mode]))
    return path


def _command(*args) -> list[str]:
    return [sys.executable, "-m", "vcnc_agents.cli", "--no-progress", "--no-tensorboard", "--threads", "1", *args]


def monitor_rows(path: Path) -> list[dict]:
    """The episode rows of a Monitor file (r, l, t, steps), as written."""
    lines = path.read_text().splitlines()
    return list(csv.DictReader(lines[1:]))


def evaluation_steps(run_dir: Path) -> list[int]:
    path = run_dir / "evaluations.csv"
    return [int(r["steps"]) for r in csv.DictReader(path.open())] if path.exists() else []


def audit_monitor(rows: list[dict], n_envs: int, session_starts: list[int], end: int | None = None) -> dict:
    """Chain check of one Monitor file's rows (see the module docstring); with ``end`` (the run's last step),
    also that the rows reach it: no more than one episode (the longest logged) is missing at the end, so a
    session whose rows were all lost (written to a file that no longer exists) is caught."""
    broken = duplicates = 0
    seen = set()
    prev = 0
    for r in rows:
        steps, length = int(r["steps"]), int(r["l"])
        duplicates += steps in seen
        seen.add(steps)
        anchor = max([prev] + [s for s in session_starts if prev <= s < steps])
        broken += steps - anchor != n_envs * length
        prev = steps
    longest = max((int(r["l"]) for r in rows), default=0)
    tail_lost = end is not None and (not rows or end - prev > n_envs * longest)
    return {"rows": len(rows), "chain_breaks": broken, "duplicates": duplicates, "tail_lost": bool(tail_lost)}


def audit_run(
    run_dir: Path, monitors: dict[str, list[dict]] | None = None, evaluations: list[int] | None = None
) -> dict:
    """Audit a run folder's logs (or the given rows instead of its files)."""
    summary = json.loads((run_dir / "summary.json").read_text())
    starts = [s["start_timesteps"] for s in summary["sessions"]]
    config_n_envs = summary["sessions"][0]["n_envs"]
    if monitors is None:
        monitors = {p.name: monitor_rows(p) for p in sorted((run_dir / "monitor").glob("*.monitor.csv"))}
    steps = evaluation_steps(run_dir) if evaluations is None else evaluations
    return {
        "monitor": {
            name: audit_monitor(rows, config_n_envs, starts, summary["sessions"][-1]["end_timesteps"])
            for name, rows in monitors.items()
        },
        "evaluations": {
            "rows": len(steps),
            "duplicates": len(steps) - len(set(steps)),
            "increasing": all(a < b for a, b in zip(steps, steps[1:])),
            "steps": steps,
        },
        "sessions": [(s["start_timesteps"], s["end_timesteps"], s["status"]) for s in summary["sessions"]],
    }


def kill_and_resume(
    workdir: Path,
    *,
    mode: str = "direct",
    timesteps: int = 8192,
    kill_after: int = 1024,
    max_wait: float = 3.0,
    timeout: float = 600.0,
    trainer: str = "sb3",
) -> dict:
    """Run, SIGKILL, resume and audit; returns the figures (see :func:`main` for their print-out)."""
    workdir.mkdir(parents=True, exist_ok=True)
    run_dir = workdir / "run"
    config = write_config(workdir, mode)
    common = ["--checkpoint-freq", "512", "--eval-freq", "768"]
    first = subprocess.Popen(
        _command(
            "--env",
            "VCNC-Omega-v1",
            "--config",
            str(config),
            "--output",
            str(run_dir),
            "--timesteps",
            str(timesteps),
            "--trainer",
            trainer,
            *common,
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + timeout

    def newest_checkpoint() -> int:
        folder = run_dir / "checkpoints"
        steps = (
            [int(p.name.split("_")[2]) for p in folder.glob("rl_model_*_steps.zip") if "vecnormalize" not in p.name]
            if folder.is_dir()
            else []
        )
        return max(steps, default=-1)

    def rows_past(steps: int) -> int:
        rows = [r for p in (run_dir / "monitor").glob("*.monitor.csv") for r in monitor_rows(p)]
        return sum(int(r["steps"]) > steps for r in rows if r.get("steps"))

    # kill once the checkpoint at kill_after exists and an episode has been logged after the newest checkpoint
    # (the case a resume must roll back), or after max_wait seconds past that checkpoint
    reached_at = None
    while True:
        newest = newest_checkpoint()
        if newest >= kill_after:
            reached_at = reached_at or time.monotonic()
            if rows_past(newest) > 0 or time.monotonic() - reached_at > max_wait:
                break
        if first.poll() is not None:
            raise RuntimeError(f"the run ended before it could be killed:\n{first.stderr.read()}")
        if time.monotonic() > deadline:
            first.kill()
            raise RuntimeError("timed out waiting for the checkpoint")
        time.sleep(0.02)
    os.kill(first.pid, signal.SIGKILL)
    first.wait()
    before = {p.name: monitor_rows(p) for p in sorted((run_dir / "monitor").glob("*.monitor.csv"))}
    evals_before = evaluation_steps(run_dir)
    checkpoints = sorted(
        int(p.name.split("_")[2])
        for p in (run_dir / "checkpoints").glob("rl_model_*_steps.zip")
        if not p.name.startswith("rl_model_vecnormalize")
    )
    resumed = subprocess.run(_command("--resume", str(run_dir)), capture_output=True, text=True, timeout=timeout)
    if resumed.returncode != 0:
        raise RuntimeError(f"resume failed ({resumed.returncode}):\n{resumed.stderr}")
    summary = json.loads((run_dir / "summary.json").read_text())
    resumed_from = summary["sessions"][-1]["start_timesteps"]
    after = {p.name: monitor_rows(p) for p in sorted((run_dir / "monitor").glob("*.monitor.csv"))}
    kept_intact = all(
        after[name][: len([r for r in rows if int(r["steps"]) <= resumed_from])]
        == [r for r in rows if int(r["steps"]) <= resumed_from]
        for name, rows in before.items()
    )
    naive_monitors = {name: before[name] + [r for r in after[name] if int(r["steps"]) > resumed_from] for name in after}
    naive_evals = evals_before + [s for s in evaluation_steps(run_dir) if s > resumed_from]
    return {
        "killed_at_checkpoints": checkpoints,
        "resumed_from": resumed_from,
        "rows_before_kill": {name: len(rows) for name, rows in before.items()},
        "rows_past_checkpoint": {
            name: sum(int(r["steps"]) > resumed_from for r in rows) for name, rows in before.items()
        },
        "evaluations_before_kill": evals_before,
        "pre_checkpoint_rows_unchanged": kept_intact,
        "audit": audit_run(run_dir),
        "naive_merge_audit": audit_run(run_dir, naive_monitors, naive_evals),
        "resume_stderr": resumed.stderr.strip().splitlines(),
        "total_timesteps": summary["timesteps"],
    }


def _print(report: dict) -> None:
    a, n = report["audit"], report["naive_merge_audit"]
    print(
        f"killed (SIGKILL) with checkpoints at {report['killed_at_checkpoints']}; resumed from "
        f"{report['resumed_from']} steps; finished at {report['total_timesteps']}"
    )
    print(f"sessions: {a['sessions']}")
    print(
        f"{'file':<18}{'rows@kill':>10}{'past ckpt':>10}{'rows now':>10}{'breaks':>8}{'dups':>6}"
        f"{'naive breaks':>14}{'naive dups':>12}"
    )
    for name, m in a["monitor"].items():
        nm = n["monitor"][name]
        print(
            f"{name:<18}{report['rows_before_kill'][name]:>10}{report['rows_past_checkpoint'][name]:>10}"
            f"{m['rows']:>10}{m['chain_breaks']:>8}{m['duplicates']:>6}{nm['chain_breaks']:>14}{nm['duplicates']:>12}"
        )
    e, ne = a["evaluations"], n["evaluations"]
    print(
        f"{'evaluations.csv':<18}{len(report['evaluations_before_kill']):>10}"
        f"{sum(s > report['resumed_from'] for s in report['evaluations_before_kill']):>10}{e['rows']:>10}"
        f"{'-' if e['increasing'] else 'NO':>8}{e['duplicates']:>6}{'-':>14}{ne['duplicates']:>12}"
    )
    print(f"evaluation steps: {e['steps']}")
    print(f"rows up to the checkpoint unchanged: {report['pre_checkpoint_rows_unchanged']}")
    for line in report["resume_stderr"]:
        print(f"  resume says: {line}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workdir", type=Path, help="where to put the run (default: a temporary folder)")
    p.add_argument("--mode", choices=sorted(_MODES), default="direct")
    p.add_argument("--trainer", choices=("sb3", "lean"), default="sb3", help="vcnc-train --trainer (default sb3)")
    args = p.parse_args(argv)
    if args.workdir is not None:
        report = kill_and_resume(args.workdir, mode=args.mode, trainer=args.trainer)
        _print(report)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            report = kill_and_resume(Path(tmp), mode=args.mode, trainer=args.trainer)
            _print(report)
    a = report["audit"]
    ok = (
        report["pre_checkpoint_rows_unchanged"]
        and a["evaluations"]["increasing"]
        and not a["evaluations"]["duplicates"]
        and all(m["chain_breaks"] == 0 and m["duplicates"] == 0 and not m["tail_lost"] for m in a["monitor"].values())
    )
    print("OK: no lost or duplicated rows" if ok else "FAILED: lost or duplicated rows")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
