"""``vcnc-train --sweep``: a tiny Ray Tune sweep runs locally and writes its results table; bad sweep files,
option clashes, a missing Ray and an unreachable cluster are refused before anything is written.

The tiny sweep (agents/sweeps/tiny.yml) runs 2 trials of 256 agent steps on the omega, one direct and one
residual over QFT; its table is checked against the trials' own run folders (evaluations.csv, config.yml)
and its retrain command against what vcnc-train's parser and set-up make of it.
"""

import csv
import math
import shlex
import sys
from pathlib import Path

import pytest
import yaml

import vcnc_gym

pytest.importorskip("ray.tune", reason="the sweep needs Ray Tune: pip install 'vcnc-gym[sweep]'")

from vcnc_agents.arguments import parser as _parser  # noqa: E402
from vcnc_agents.cli import main  # noqa: E402
from vcnc_agents.sweep import RESULT_FIELDS, _train_kwargs, load_sweep  # noqa: E402
from vcnc_agents.training import evaluation_score, prepare_run  # noqa: E402

SWEEPS = Path(__file__).parents[1] / "agents" / "sweeps"
#: The omega's id as registered now (its version follows the env's behaviour).
OMEGA = next(i for i in vcnc_gym.ENV_IDS if i.startswith("VCNC-Omega-"))


def sweep_file(folder: Path, name: str = "tiny", **changes) -> Path:
    """agents/sweeps/tiny.yml on OMEGA, with ``changes`` (None removes a key; search: merged)."""
    data = yaml.safe_load((SWEEPS / "tiny.yml").read_text())
    data["env"] = OMEGA
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        elif key == "search":
            data["search"].update(value)
        else:
            data[key] = value
    path = folder / f"{name}.yml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sweep")
    out = folder / "out"
    assert main(["--sweep", str(sweep_file(folder)), "--output", str(out)]) == 0
    with open(out / "sweep_results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return out, rows


@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
def test_tiny_sweep_writes_one_row_per_trial(tiny):
    out, rows = tiny
    assert len(rows) == 2 and list(rows[0]) == list(RESULT_FIELDS)
    assert all(r["status"] == "finished" for r in rows)
    assert sorted(r["action_mode"] for r in rows) == ["direct", "residual"]
    assert (out / "sweep.yml").is_file() and (out / "sweep_results.md").is_file()
    for r in rows:
        assert 1e-4 <= float(r["learning_rate"]) <= 1e-3 and r["seed"] == "0" and r["timesteps"] == "256"
        run = Path(r["run_dir"])
        assert run == out / "trials" / r["trial"] / "run" and (run / "final" / "model.zip").is_file()
        assert yaml.safe_load((run.parent / "ppo.yml").read_text())[OMEGA]["learning_rate"] == float(r["learning_rate"])
        if r["action_mode"] == "residual":
            assert r["baseline"] == "qft" and 0.3 <= float(r["correction"]) <= 1.0
        else:
            assert r["baseline"] == r["correction"] == ""


@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
def test_tiny_sweep_figures_are_the_runs_best_evaluations(tiny):
    out, rows = tiny
    for r in rows:
        with open(Path(r["run_dir"]) / "evaluations.csv", newline="") as f:
            evaluations = [e for e in csv.DictReader(f) if e["diverged"] == "False"]
        if not evaluations:  # every evaluation diverged: scored inf, noted
            assert float(r["score_um"]) == math.inf and "diverged" in r["note"]
            continue
        best = min(evaluations, key=lambda e: float(e["score_um"]))
        assert float(r["max_um"]) == float(best["max_um"]) and float(r["rms_um"]) == float(best["rms_um"])
        assert float(r["score_um"]) == pytest.approx(evaluation_score(float(best["max_um"]), float(best["rms_um"])))
        assert int(r["best_steps"]) == int(best["steps"]) and float(r["wall_s"]) > float(r["train_wall_s"]) > 0
    scores = [float(r["score_um"]) for r in rows]
    assert scores == sorted(scores)  # best first


@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
def test_tiny_sweep_retrain_command_is_the_trials_run(tiny, tmp_path):
    out, rows = tiny
    text = (out / "sweep_results.md").read_text()
    best = rows[0]
    assert f"## Best trial: {best['trial']}" in text and best["command"] in text
    words = shlex.split(best["command"])
    assert words[0] == "vcnc-train"
    args = _parser().parse_args(words[1:])
    assert (args.env, args.seed, args.timesteps, args.action_mode) == (OMEGA, 0, 256, best["action_mode"])
    # what vcnc-train sets up from the command is the trial's run, but for its folder
    argv = words[1:-1] + [str(tmp_path / "retrain")]
    _, config, _ = prepare_run(**_train_kwargs(argv))
    trial = yaml.safe_load((Path(best["run_dir"]) / "config.yml").read_text())
    for key in (
        "env_id",
        "seed",
        "n_envs",
        "n_timesteps",
        "eval_freq",
        "checkpoint_freq",
        "action_mode",
        "hyperparams",
    ):
        assert getattr(config, key) == trial[key], key


BAD_FILES = [
    ("a misspelt key", dict(serach={}), ["serach", "did you mean 'search'"]),
    ("no env", dict(env=None), ["env", "required"]),
    ("an unknown env", dict(env="VCNC-Nothing-v0"), ["unknown env", "VCNC-Nothing-v0"]),
    ("no search", dict(search=None), ["search must be a mapping"]),
    ("an unknown parameter", dict(search={"learning_rat": 1e-3}), ["learning_rat", "did you mean 'learning_rate'"]),
    ("a range on an integer", dict(search={"seed": {"uniform": [0, 3]}}), ["seed", "uniform applies to"]),
    ("an empty range", dict(search={"learning_rate": {"loguniform": [1e-3, 1e-4]}}), ["low < high"]),
    ("an unknown form", dict(search={"seed": {"gauss": [0, 1]}}), ["seed", "a search form is one of"]),
    ("a negative learning rate", dict(search={"learning_rate": [1e-4, -1e-3]}), ["learning_rate", "> 0.0"]),
    ("too large a correction", dict(search={"correction": {"uniform": [0.3, 3.0]}}), ["correction", "(0, 2]"]),
    ("an unknown baseline", dict(search={"baseline": ["qft", "pid"]}), ["baseline must be one of", "pid"]),
    ("an unknown action mode", dict(search={"action_mode": "fancy"}), ["action_mode must be one of"]),
    ("a fractional seed", dict(search={"seed": [0, 1.5]}), ["seed must be an integer"]),
    ("a repeated grid value", dict(search={"seed": [1, 1]}), ["seed", "each once"]),
    ("zero steps", dict(search={"timesteps": 0}), ["timesteps"]),
    ("a misspelt override", dict(overrides={"n_step": 64}), ["n_step", "did you mean 'n_steps'"]),
    ("a searched override", dict(overrides={"learning_rate": 3e-4}), ["learning_rate", "keep one"]),
    ("zero samples", dict(num_samples=0), ["num_samples"]),
    ("a bad training option", dict(vec_env="threads"), ["vec_env"]),
    ("a missing hyperparameter file", dict(hyperparams="nowhere.yml"), ["nowhere.yml", "does not exist"]),
    (
        "a baseline for another plant",
        dict(search={"baseline": "contouring-fb"}),
        ["cannot run", "contouring-fb", "designed for"],
    ),
]


@pytest.mark.parametrize("what, changes, words", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_sweep_files_are_refused_before_anything_runs(tmp_path, capsys, what, changes, words):
    path = sweep_file(tmp_path, **changes)
    with pytest.raises(ValueError) as info:
        load_sweep(path)
    for word in words:
        assert word in str(info.value), (what, str(info.value))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as code:
        main(["--sweep", str(path), "--output", str(out)])
    assert code.value.code == 2 and str(path) in capsys.readouterr().err and not out.exists()


def test_not_a_sweep_file(tmp_path):
    (tmp_path / "list.yml").write_text("- 1\n- 2\n")
    (tmp_path / "broken.yml").write_text("search: [\n")
    with pytest.raises(ValueError, match="must be a mapping"):
        load_sweep(tmp_path / "list.yml")
    with pytest.raises(ValueError, match="not valid YAML"):
        load_sweep(tmp_path / "broken.yml")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_sweep(tmp_path / "absent.yml")


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--seed", "3"], "drop --seed"),
        (["--env", "VCNC-Heart-v0", "--vec-env", "dummy"], "drop --env, --vec-env"),
    ],
)
def test_sweep_refuses_the_options_its_file_sets(tmp_path, capsys, argv, words):
    with pytest.raises(SystemExit) as code:
        main(["--sweep", str(SWEEPS / "tiny.yml"), *argv])
    assert code.value.code == 2 and words in capsys.readouterr().err


def test_ray_address_needs_a_sweep(capsys):
    with pytest.raises(SystemExit):
        main(["--env", OMEGA, "--ray-address", "auto"])
    assert "--ray-address applies to --sweep" in capsys.readouterr().err


def test_missing_ray_says_how_to_install_it(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as code:
        main(["--sweep", str(sweep_file(tmp_path)), "--output", str(out)])
    err = capsys.readouterr().err
    assert code.value.code == 2 and "pip install 'vcnc-gym[sweep]'" in err and "Ray Tune" in err
    assert not out.exists()


def test_unreachable_cluster_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    import ray

    def refuse(*args, **kwargs):
        raise ConnectionError("could not find any running Ray instance")

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", refuse)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as code:
        main(["--sweep", str(sweep_file(tmp_path)), "--output", str(out), "--ray-address", "127.0.0.1:1"])
    err = capsys.readouterr().err
    assert code.value.code == 2 and "cannot connect to the Ray cluster at '127.0.0.1:1'" in err
    assert not out.exists()


def test_used_output_folder_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "something").write_text("")
    with pytest.raises(SystemExit) as code:
        main(["--sweep", str(sweep_file(tmp_path)), "--output", str(out)])
    assert code.value.code == 2 and "choose another --output" in capsys.readouterr().err


def test_shipped_sweep_files_are_valid():
    """agents/sweeps/*.yml name a registered id with an entry (a new id version must update them)."""
    assert load_sweep(SWEEPS / "tiny.yml").n_trials == 2
    spec = load_sweep(SWEEPS / "omega.yml")
    assert spec.n_trials == 24 and spec.env_id == OMEGA
