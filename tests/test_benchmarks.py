"""Every script of ``benchmarks/`` (cost and speed benchmarks) runs: a smoke run of each in its quick or small mode,
in a process of its own, as ``python benchmarks/NAME.py ARGS`` runs it.  The figures of a smoke run mean nothing;
the full runs are the scripts' defaults (each docstring says what it measures and how to run it).

A new benchmark names its smoke run in :data:`SMOKE`.  The runs that build a second process tree of their own (a
git worktree, a training run per candidate, a child per threading layer) or train are marked slow (``make
test-all``).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys

import pytest

from benchmark_script import BENCHMARKS, ROOT

#: Each benchmark's smoke run: its arguments (``{tmp}``: a temporary folder) and whether it is slow (> 10 s).
SMOKE: dict[str, tuple[list[str], bool]] = {
    "baseline_predict": (["--calls", "200"], False),
    "before_after": (["--quick"], True),
    "history_cost": (["--n-envs", "2", "--history", "4", "--decisions", "5", "--blocks", "1"], False),
    "identification_loop": (["--machines", "1", "--periods", "200", "--repeats", "1"], False),
    "learnability": (["--quick"], True),
    "mpc_solvers": (["--steps", "50", "--repeat", "1"], False),
    "mpcc_cost": (["--steps", "20"], False),
    "numba_torch_threads": (["--envs", "4", "--calls", "2"], True),
    "oracle_convergence": (["--plot-stored", "{tmp}/oracle_convergence.png"], False),
    "per_machine_episode": (["--episodes", "1"], False),
    "ppo_trainers": (
        ["--n-envs", "2", "--steps", "256", "--candidates", "sb3:rollout=256,threads=1", "lean:rollout=256,threads=1"],
        True,
    ),
    "projector_cost": (["--repeats", "1"], False),
    "random_contour_reset": (["--episodes", "1"], False),
    "render_timing": (["--frames", "2", "--no-video"], False),
    "shop_floor_cost": (["--steps", "200", "--envs", "2", "--repeats", "1"], False),
    "step_cost": (["--steps", "1000", "--repeats", "1", "--no-start-up"], False),
    "train_throughput": (["--quick"], True),
    "vector_env": (["--seconds", "0.05", "--envs", "4", "--ids", "VCNC-Heart-v1", "--no-load"], False),
}
SCRIPTS = sorted(p.stem for p in BENCHMARKS.glob("*.py"))


def _param(name: str):
    slow = SMOKE.get(name, ([], False))[1]
    return pytest.param(name, marks=[pytest.mark.slow] if slow else [], id=name)


def test_every_benchmark_has_a_smoke_run():
    assert [name for name in SCRIPTS if name not in SMOKE] == [], "name its smoke run in SMOKE"


@pytest.mark.parametrize("name", SCRIPTS)
def test_every_benchmark_says_what_it_measures_and_how_to_run_it(name):
    """A module docstring naming the command that runs it."""
    doc = ast.get_docstring(ast.parse((BENCHMARKS / f"{name}.py").read_text(encoding="utf-8"))) or ""
    assert doc.strip(), f"benchmarks/{name}.py has no module docstring"
    assert f"benchmarks/{name}.py" in doc, f"benchmarks/{name}.py's docstring does not say how to run it"


@pytest.mark.parametrize("name", [_param(n) for n in SCRIPTS])
def test_a_benchmark_s_smoke_run_succeeds(name, tmp_path):
    args = [a.format(tmp=tmp_path) for a in SMOKE[name][0]]
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run(
        [sys.executable, str(BENCHMARKS / f"{name}.py"), *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, f"benchmarks/{name}.py {' '.join(args)}:\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    assert proc.stdout.strip(), f"benchmarks/{name}.py printed nothing"
