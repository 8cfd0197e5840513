"""The floor's solve on each contouring id's nominal plant: convergence (max contour error against whole-episode
evaluations), solve time, the replayed figures beside the strongest causal controller, and the headroom
(baselines/optimal/oracle.py; experiments/classical-opponents/README.md, "The floor")::

    python benchmarks/oracle_convergence.py [--env ID ...] [--store | --stored] [--plot PNG]
    python benchmarks/oracle_convergence.py --plot-stored experiments/classical-opponents/figures/oracle_convergence.png

Solves afresh (``VCNC_ORACLE_RECOMPUTE``); ``--store`` writes the solutions into the package
(``baselines/optimal/solutions/``, what the bench replays), else into a temporary directory; ``--stored``
replays the shipped solutions instead (their convergence and solve time are the stored ones).  The shipped
specialist of each id (``agents/trained``, the bench's ``ppo``) is among the starts unless ``--no-agents``.  The floor's
figure printed is :func:`vcnc_gym.evaluation.run_episode` of the oracle through ``gym.make(ID)``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import gymnasium as gym
import numpy as np

import vcnc_baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_baselines.optimal import solutions
from vcnc_gym.envs.registry import CONTOURING_IDS
from vcnc_gym.evaluation import run_episode


#: The smaller search of ``--quick``.
QUICK = {"population": 8, "ilc_iterations": 4, "rounds": 4, "generations": 8, "trials": 3}


def _specialist(env) -> dict:
    """The agent shipped for the env (what ``vcnc-bench --policy ppo`` runs), as a start of the floor: a causal
    controller too."""
    from vcnc_agents import TRAINED, load_agent
    from vcnc_agents.policy import agent_mismatch

    folder = TRAINED.get(env.unwrapped.spec.id)
    if folder is None or not folder.is_dir() or agent_mismatch(folder, env) is not None:
        return {}
    return {"ppo": load_agent(folder, env)}


def _saturated(result, env) -> str:
    """Share of control periods with an axis command at 0.999 u_max or more, over the episode and over the 200
    periods before the largest contour error."""
    u = np.abs(result.command) / env.unwrapped.u_max
    at = np.any(u >= 0.999, axis=1)
    k = int(np.argmax(result.contour_error))
    return f"{at.mean():.3f} overall, {at[max(0, k - 200) : k + 1].mean():.3f} before the max"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", action="append", help=f"ids (default: {', '.join(CONTOURING_IDS)})")
    parser.add_argument("--store", action="store_true", help="write the solutions into the package")
    parser.add_argument("--stored", action="store_true", help="replay the shipped solutions, do not solve")
    parser.add_argument("--plot", help="convergence plot (PNG) of every id solved")
    parser.add_argument("--seed", type=int, default=0, help="env.reset seed (the bench's default: 0)")
    parser.add_argument(
        "--quick", action="store_true", help=f"a smaller search ({QUICK}), a quarter of the default's episodes"
    )
    parser.add_argument(
        "--no-agents",
        dest="agents",
        action="store_false",
        help="leave out the shipped specialist (agents/trained/ID) among the starts",
    )
    parser.add_argument("--plot-stored", metavar="PNG", help="only plot the shipped solutions' convergence")
    args = parser.parse_args()
    if args.plot_stored:
        plot_stored(args.plot_stored)
        return
    os.environ["VCNC_ORACLE_RECOMPUTE"] = "0" if args.stored else "1"
    if args.store or args.stored:  # the package's: what the bench replays
        os.environ["VCNC_ORACLE_SOLUTIONS"] = str(solutions.DIRECTORY)
    elif not args.stored:
        os.environ["VCNC_ORACLE_SOLUTIONS"] = tempfile.mkdtemp(prefix="oracle-")
    curves = {}
    for env_id in args.env or CONTOURING_IDS:
        env = gym.make(env_id)
        extra = _specialist(env) if args.agents else {}
        oracle = vcnc_baselines.make("oracle", env, extra_starts=extra, **(QUICK if args.quick else {}))
        env.reset(seed=args.seed)
        t0 = time.perf_counter()
        oracle.plan(env)
        solve = time.perf_counter() - t0
        result = run_episode(oracle, env, seed=args.seed)  # plan() again: the same plant, nothing solved
        sol = oracle.solutions[0]
        best = min(sol.warm_starts, key=lambda k: tuple(sol.warm_starts[k]))
        b_max, b_rms = sol.warm_starts[best]
        curves[env_id] = sol.history
        print(
            f"{env_id:28s} floor {result.max_contour_error_um:9.4f} um max {result.rms_contour_error_um:9.4f} um rms"
            f" (search {sol.max_um:.4f}) | strongest causal {best} {b_max:9.4f} / {b_rms:9.4f} | headroom "
            f"{b_max / result.max_contour_error_um:6.3f} | solve {sol.solve_time_s:6.1f} s, {sol.evaluations} "
            f"episodes | plan {solve:5.1f} s, episode {result.wall_s:5.1f} s | saturated {_saturated(result, env)}",
            flush=True,
        )
        env.close()
    if args.plot and curves:
        plot(curves, args.plot)


def plot(curves: dict, path: str) -> None:
    """Max contour error over the best start's against whole-episode evaluations, one line per id."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5))
    for env_id, h in curves.items():
        ax.plot(h[:, 0], h[:, 1] / h[0, 1], label=env_id)
    ax.set_xlabel("whole-episode evaluations on the exact plant")
    ax.set_ylabel("max contour error / best causal controller's")
    ax.set_title("The floor's search (benchmarks/oracle_convergence.py)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


def plot_stored(path: str) -> None:
    """:func:`plot` of the convergence stored with every shipped solution (no replay)."""
    from vcnc_baselines.optimal import solutions

    curves = {}
    for f in sorted(solutions.DIRECTORY.glob("*.npz")):
        sol = solutions.load(f.stem)
        curves[f.stem.rsplit("-", 1)[0]] = sol.history
    plot(curves, path)


if __name__ == "__main__":
    main()
