"""``vcnc-train --seeds K`` (vcnc_agents.seeds): K runs of the same options, one folder and one seed each."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from vcnc_agents import cli
from vcnc_agents.seeds import seed_argv, seed_folders


def test_each_seed_runs_the_parents_options_with_its_own_seed_and_folder():
    argv = [
        "--env",
        "VCNC-Heart-v1",
        "--seeds",
        "3",
        "--seed=4",
        "--output",
        "runs/x",
        "--jobs",
        "2",
        "--timesteps",
        "4096",
        "--ray-address=auto",
    ]
    assert seed_argv(argv, 5, Path("runs/x/seed5")) == [
        "--env",
        "VCNC-Heart-v1",
        "--timesteps",
        "4096",
        "--seed",
        "5",
        "--output",
        "runs/x/seed5",
        "--no-progress",
    ]
    assert seed_folders("VCNC-Heart-v1", [0, 1], None) == [
        Path("runs/VCNC-Heart-v1_seed0"),
        Path("runs/VCNC-Heart-v1_seed1"),
    ]
    assert seed_folders("E", [7], Path("out")) == [Path("out/seed7")]


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--env", "VCNC-Heart-v1", "--seeds", "0"], "--seeds and --jobs must be positive"),
        (["--resume", "runs/x", "--seeds", "2"], "--seeds starts new runs"),
        (["--env", "VCNC-Heart-v1", "--jobs", "2"], "--jobs applies to --seeds K"),
        (["--sweep", "agents/sweeps/omega.yml", "--seeds", "2"], "drop --seeds"),
        (["--env", "VCNC-Heart-v1", "--seeds", "2", "--seed", "4294967295"], "seed must be an integer"),
    ],
)
def test_bad_seed_options_exit_2_naming_them(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


@pytest.mark.slow
def test_two_seeds_train_into_their_own_folders(tmp_path, capsys):
    code = cli.main(
        [
            "--env",
            "VCNC-Circle-v1",
            "--seeds",
            "2",
            "--seed",
            "3",
            "--timesteps",
            "2048",
            "--n-envs",
            "8",
            "--trainer",
            "lean",
            "--output",
            str(tmp_path / "circle"),
            "--jobs",
            "2",
        ]
    )
    assert code == 0, capsys.readouterr()
    for s in (3, 4):
        config = (tmp_path / "circle" / f"seed{s}" / "config.yml").read_text()
        assert f"seed: {s}" in config
        assert (tmp_path / "circle" / f"seed{s}" / "final").is_dir()
    runs = json.loads((tmp_path / "circle" / "seeds.json").read_text())["runs"]
    assert [r["seed"] for r in runs] == [3, 4] and all(r["code"] == 0 for r in runs)
    assert "seed  exit" in capsys.readouterr().out


def test_the_bench_reads_a_seeds_folder_as_every_seeds_agent(tmp_path):
    """``vcnc-bench --policy ppo:FOLDER`` of a ``vcnc-train --seeds`` folder: one spec per seed's best agent, in
    seed order (judged as one controller: tests/test_verdicts.py); a seed without a best agent is named."""
    from vcnc_bench.policies import expand_spec

    runs = []
    for seed in (3, 4):
        (tmp_path / f"seed{seed}" / "best").mkdir(parents=True)
        runs.append({"seed": seed, "folder": f"somewhere/else/seed{seed}", "code": 0})
    (tmp_path / "seeds.json").write_text(json.dumps({"env": "VCNC-Heart-v1", "argv": [], "runs": runs}))
    assert expand_spec(f"ppo:{tmp_path}") == [
        f"ppo:{tmp_path / 'seed3' / 'best'}",
        f"ppo:{tmp_path / 'seed4' / 'best'}",
    ]
    assert expand_spec("ppo:runs/x/best") == ["ppo:runs/x/best"] and expand_spec("ff-pid") == ["ff-pid"]
    with pytest.raises(ValueError, match="no final agent for seed 3"):  # FOLDER/final: every seed's final agent
        expand_spec(f"ppo:{tmp_path / 'final'}")
    for seed in (3, 4):
        (tmp_path / f"seed{seed}" / "final").mkdir()
    assert expand_spec(f"ppo:{tmp_path / 'final'}") == [f"ppo:{tmp_path / f'seed{s}' / 'final'}" for s in (3, 4)]
    runs[1]["code"] = 1
    (tmp_path / "seeds.json").write_text(json.dumps({"env": "VCNC-Heart-v1", "argv": [], "runs": runs}))
    with pytest.raises(ValueError, match="no best agent for seed 4"):
        expand_spec(f"ppo:{tmp_path}")


def test_a_later_command_adds_its_seeds_to_the_folder_s_summary(tmp_path, monkeypatch):
    """A family trained over several sessions: ``--seed 1 --seeds 2`` with the first command's options and
    ``--output`` adds seeds 1 and 2 to its ``seeds.json`` (in seed order); other options are refused by name before
    anything trains."""
    from vcnc_agents import seeds as seeds_module

    trained = []

    def fake_run(argv, folder):  # no training: the folder appears, as a run's would
        Path(folder).mkdir(parents=True)
        trained.append(folder)
        return 0, 1.0, "done"

    monkeypatch.setattr(seeds_module, "_run_one", fake_run)
    out = tmp_path / "family"
    opts = ["--env", "VCNC-Heart-v1", "--timesteps", "4096"]
    seeds_module.run_seeds(opts + ["--seeds", "1", "--output", str(out)], "VCNC-Heart-v1", 0, 1, out, jobs=1)
    seeds_module.run_seeds(
        opts + ["--seed", "1", "--seeds", "2", "--output", str(out), "--no-progress"],
        "VCNC-Heart-v1",
        1,
        2,
        out,
        jobs=1,
    )
    runs = json.loads((out / "seeds.json").read_text())["runs"]
    assert [r["seed"] for r in runs] == [0, 1, 2] and [r["folder"] for r in runs] == [
        str(out / f"seed{s}") for s in (0, 1, 2)
    ]
    with pytest.raises(ValueError, match="seeds.json holds the seeds of another run"):
        seeds_module.run_seeds(["--env", "VCNC-Heart-v1", "--timesteps", "8192"], "VCNC-Heart-v1", 3, 1, out, jobs=1)
    assert len(trained) == 3
