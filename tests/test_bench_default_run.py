"""vcnc-bench's default run: every env kind it contains through the runner, the reports, the JSON and the plots.

The full default table (``vcnc-bench`` with no option, what ``make bench`` and CI run, checked by
``python -m vcnc_bench.check --default``) is the slow test at the end; the fast ones run the same path on the
kinds beside the contouring envs: the positioning env (Yadav et al. (2020)'s step response, whose env has no
contour: the reports that look for one must meet it) and the feed override (the shipped agent), and a G-code
program outside the table (a contouring env with its ISO 230-4 report).
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym  # noqa: F401
from vcnc_bench import check, cli, programs
from vcnc_bench.runner import EnvRecipe, idle_cores, run_table
from vcnc_gym.evaluation import run_episode

#: A short part program: a 2 mm line, a full counter-clockwise circle of 1 mm radius and a 2 mm line on, at 1200 mm/min.
SHORT_PROGRAM = "G21 G90 G17\nG00 X0 Y0\nG01 X2 Y0 F1200\nG03 X2 Y0 I0 J1\nG01 X4 Y0\n"


def test_default_ids_are_the_ids_that_carry_a_verdict():
    """The default table: every id with a shipped agent, and Yadav et al. (2020)'s step response; current ids of the
    contouring, positioning and feed-override kinds."""
    import vcnc_agents
    from vcnc_gym.envs.registry import SUITE

    by_id = {e.id: e for e in SUITE}
    assert set(cli.DEFAULT_IDS) == set(vcnc_agents.TRAINED) | {"VCNC-Step-v0"}
    assert set(cli.DEFAULT_IDS) <= set(by_id)
    entry_points = {by_id[e].entry_point.rsplit(":", 1)[1] for e in cli.DEFAULT_IDS}
    assert entry_points == {"ContouringEnv", "FeedOverrideEnv", "PositioningEnv"}
    assert sorted(cli.LONGEST_FIRST) == sorted(cli.DEFAULT_IDS)  # the pool's order: every default id, once


def test_circular_report_meets_a_positioning_env():
    """The crash of the first `make bench`: the ISO 230-4 report looked for a contour on the positioning env."""
    env = gym.make("VCNC-Step-v0")
    from vcnc_baselines import make

    result = run_episode(make("pi", env), env, seed=0)
    assert programs.circular_report({"VCNC-Step-v0": {"pi": result}}, {"VCNC-Step-v0": env}) == ([], [])


@pytest.mark.slow  # a worker pool: make bench runs this path in CI (.ci/run)
def test_the_default_path_on_the_positioning_env_and_the_override(tmp_path, capsys):
    """The default table's kinds beyond the contouring envs (which `make bench` runs in CI, and the slow test at the
    end): every default policy of the positioning env and of the feed override through the pool, the reports, the
    JSON and the plots."""
    out_json, plots = tmp_path / "bench.json", tmp_path / "plots"
    code = cli.main(
        [
            "--env",
            "VCNC-Step-v0",
            "--env",
            "VCNC-OmegaOverride-v1",
            "--jobs",
            "2",
            "--json",
            str(out_json),
            "--plots",
            str(plots),
        ]
    )
    assert code == 0
    captured = capsys.readouterr()
    data = json.loads(out_json.read_text())
    assert check.problems(data) == []
    assert list(data["plan"]) == ["VCNC-Step-v0", "VCNC-OmegaOverride-v1"]
    assert data["plan"]["VCNC-Step-v0"] == ["hinf", "hinf-reduced", "imc", "pi"]
    assert data["plan"]["VCNC-OmegaOverride-v1"] == ["ppo"]
    # one progress line per env, the reports of every kind (Table 2 prepared in the worker), where the outputs went
    assert captured.err.count("policies in") == 2
    assert "Table 2 on VCNC-Step-v0" in captured.out and "Table 2, continuous loop" in captured.out
    assert f"to {out_json}" in captured.out and f"to {plots}" in captured.out
    assert (plots / "VCNC-Step-v0_step_responses.png").stat().st_size > 1000


def test_a_program_through_the_bench_gets_its_iso230_report(tmp_path, capsys):
    """A G-code program (not in the default table: --program PART) through the same path, with its ISO 230-4
    circular-test report and plots."""
    part = tmp_path / "part.nc"
    part.write_text(SHORT_PROGRAM)
    out_json, plots = tmp_path / "bench.json", tmp_path / "plots"
    code = cli.main(
        [
            "--program",
            str(part),
            "--policy",
            "ff-pid",
            "--policy",
            "zpetc@machine",
            "--jobs",
            "1",
            "--json",
            str(out_json),
            "--plots",
            str(plots),
        ]
    )
    assert code == 0
    captured = capsys.readouterr()
    data = json.loads(out_json.read_text())
    assert check.problems(data) == []
    assert data["plan"] == {"GCode:part": ["ff-pid", "zpetc@machine"]}
    assert "ISO 230-4 circular test" in captured.out
    assert {r["env"] for r in data["records"] if r.get("table") == "iso230-4"} == {"GCode:part"}
    for name in ("GCode:part_contour.png", "GCode:part_error.png"):
        assert (plots / name).stat().st_size > 1000


@pytest.mark.slow  # a worker pool: make bench runs this path in CI (.ci/run)
def test_two_processes_give_the_figures_of_one(tmp_path):
    """The pool's workers build their envs and policies again: the same figures, to the bit, as this process."""
    recipes = [
        EnvRecipe("VCNC-Step-v0", "VCNC-Step-v0", {}, ("pi", "imc")),
        EnvRecipe("GCode:part", "VCNC-GCode-v1", {"program": SHORT_PROGRAM, "tolerance": 0.01}, ("ff-pid",)),
    ]
    one = run_table(recipes, seed=0, trials=1, jobs=1)
    two = run_table(recipes, seed=0, trials=1, jobs=2)
    for key in one:
        for a, b in zip(one[key].runs, two[key].runs, strict=True):
            assert a.label == b.label
            np.testing.assert_array_equal(a.trials[-1].contour_error, b.trials[-1].contour_error)


@pytest.mark.slow  # a worker pool: make bench runs this path in CI (.ci/run)
def test_a_policy_that_cannot_be_built_exits_2_naming_it(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(
            [
                "--env",
                "VCNC-Step-v0",
                "--env",
                "VCNC-Circle-v1",
                "--policy",
                f"ppo:{tmp_path / 'nope'}",
                "--jobs",
                "2",
                "--no-progress",
            ]
        )
    assert exc.value.code == 2
    assert "cannot build policy" in capsys.readouterr().err


def test_check_names_what_is_missing():
    data = {
        "settings": {},
        "plan": {"A": ["p", "q"], "B": []},
        "records": [
            {
                "env": "A",
                "policy": "p",
                "max_contour_error_um": 1.0,
                "mean_contour_error_um": 0.5,
                "rms_contour_error_um": None,
                "completed": True,
                "diverged": False,
            }
        ],
    }
    found = check.problems(data, default_ids=("A", "C"))
    assert any("not the default table" in f for f in found)
    assert "A p: no finite rms_contour_error_um (diverged: False)" in found
    assert "A q: no record" in found and "B: no policy ran" in found
    stale = {
        **data,
        "records": data["records"]
        + [
            {
                "table": "headroom",
                "env": "A",
                "strongest": "p",
                "strongest_max_um": 1.0,
                "floor_max_um": 1.1,
                "headroom": 1 / 1.1,
            }
        ],
    }
    assert any("A: the floor (1.1 um) is above the strongest causal" in f for f in check.problems(stale))
    assert check.problems([]) != []


def test_idle_cores_is_within_the_machine():
    import os

    assert 1 <= idle_cores() <= len(os.sched_getaffinity(0))


@pytest.mark.slow
def test_the_default_table_runs_to_its_end(tmp_path):
    """`vcnc-bench` with no option (what `make bench` runs): every env of DEFAULT_IDS, every policy of its plan, finite
    figures in the JSON."""
    out_json = tmp_path / "bench.json"
    assert cli.main(["--json", str(out_json), "--no-progress"]) == 0
    assert check.problems(json.loads(out_json.read_text()), default_ids=cli.DEFAULT_IDS) == []


def test_the_bench_warm_up_compiles_every_machine_of_the_default_table_once():
    """``python -m vcnc_bench.warmup`` (the install's second warm-up): one env per machine of the default table
    (plant, ideal or shop floor), the ideal heart first beside the step response; on the step response it steps
    each of the four classical policies the bench runs there."""
    from vcnc_bench.cli import DEFAULT_IDS
    from vcnc_bench.warmup import _one_per_machine, warm_env
    from vcnc_gym.envs.registry import suite_env

    ids = _one_per_machine(list(DEFAULT_IDS))
    machines = {(suite_env(i).kwargs.get("plant"), bool(suite_env(i).kwargs.get("shop_floor"))) for i in DEFAULT_IDS}
    assert len(ids) == len(machines) and set(ids) <= set(DEFAULT_IDS)
    assert warm_env("VCNC-Step-v0") == 4


def test_same_figures_names_every_field_that_moved(tmp_path):
    record = {
        "env": "A",
        "policy": "p",
        "trial": None,
        "max_contour_error_um": 1.0,
        "mean_contour_error_um": 0.5,
        "rms_contour_error_um": 0.6,
        "completed": True,
        "diverged": False,
        "wall_s": 1.0,
    }
    data = {"settings": {}, "plan": {"A": ["p"]}, "records": [record]}
    moved = {**record, "rms_contour_error_um": 0.7, "wall_s": 9.0}
    assert check.figure_differences(data, {**data, "records": [dict(record, wall_s=3.0)]}) == []
    assert check.figure_differences(data, {**data, "records": [moved]}) == [
        "('A', 'p', None): rms_contour_error_um 0.6 against 0.7"
    ]
    assert check.figure_differences(data, {**data, "records": []}) == ["('A', 'p', None): in one file only"]
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps(data))
    b.write_text(json.dumps({**data, "records": [moved]}))
    assert check.main([str(a), "--same-figures", str(b)]) == 1
    assert check.main([str(a), "--same-figures", str(a)]) == 0
