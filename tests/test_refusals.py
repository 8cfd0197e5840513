"""Bad input to the newer surfaces answered in one line, before any long work, naming the argument, the file or the
field; nothing written where the user did not say.

Every file a user passes is checked on load as the suite writes it (:mod:`vcnc_gym.schema`): a leaderboard's rows
and a bench JSON (:mod:`vcnc_bench.files`), a ``vcnc-train --seeds`` folder's ``seeds.json``
(:func:`vcnc_agents.seeds.read_summary`), a commissioning record (:func:`vcnc_baselines.commissioning.record.load`),
a stored floor (:mod:`vcnc_baselines.optimal.solutions`).  Each case has a variant; the fuzz of these files is in
``tests/test_file_fuzz.py``.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from vcnc_gym.schema import MAX_DEPTH, BadFile

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_RECORD = ROOT / "baselines" / "commissioning" / "shipped" / "vcnc_feed_drive-ideal-33572f1e47df.json"


def _one_line(text: str) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip()]
    assert "Traceback" not in text, text
    return lines[-1]


def _exits_2(main, argv, capsys) -> str:
    """Run a command's ``main``; it must exit 2 with one line of error (argparse's usage above it), which is
    returned."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    return _one_line(capsys.readouterr().err)


# -- commissioning records ---------------------------------------------------------------------------------------------
def _record(**changes):
    d = json.loads(SHIPPED_RECORD.read_text())
    for path, value in changes.items():
        target, *keys = path.split("__")
        node = d
        for k in [target, *keys][:-1]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        last = [target, *keys][-1]
        if value is _DELETE:
            del node[last]
        else:
            node[int(last) if isinstance(node, list) else last] = value
    return d


_DELETE = object()


@pytest.mark.parametrize(
    "content, field",
    [
        ('{"plant": ', "is not JSON"),
        ('{"plant": "vcnc_feed_drive", "axes": [}', "line 1"),
        (_record(axes=_DELETE), "no field 'axes'"),
        (_record(designs=_DELETE), "no field 'designs'"),
        (_record(designs__0__kp="abc"), "designs[0].kp must be a real number"),
        (_record(designs__1__kd=[1]), "designs[1].kd must be a real number"),
        (_record(designs__0__kp=-1e9), "designs[0].kp must be > 0"),
        (_record(designs__1__ki=-1.0), "designs[1].ki must be >= 0"),
        (_record(dt=0), "dt must be > 0"),
        (_record(dt=-1e-4), "dt must be > 0"),
        (_record(axes__0__mass=float("nan")), "axes[0].mass must be finite"),
        (_record(axes__1__damping=float("inf")), "axes[1].damping must be finite"),
        (_record(axes=[_record()["axes"][0]]), "axes must hold 2 items, got 1"),
        (_record(axes=_record()["axes"] * 2), "axes must hold 2 items, got 4"),
        (_record(plant={"name": "vcnc_feed_drive"}), "plant must be a string, got an object"),
        (_record(plant=["vcnc_feed_drive"]), "plant must be a string, got a list"),
        (_record(source="bought"), "source must be one of"),
        (_record(designs__0__velocity_pole=1.5), "velocity_pole must be < 1"),
        ([1, 2], "the record must be an object"),
        ("[" * 5000 + "]" * 5000, f"deeper than {MAX_DEPTH} levels"),
    ],
)
def test_a_malformed_commissioning_record_is_refused_naming_the_file_and_the_field(tmp_path, content, field):
    from vcnc_baselines.commissioning import record

    path = tmp_path / "record.json"
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    with pytest.raises(BadFile) as exc:
        record.load(path)
    message = str(exc.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and field in message, message


def test_a_shipped_record_loads_and_round_trips_with_its_gains_positive(tmp_path):
    from vcnc_baselines.commissioning import record

    r = record.load(SHIPPED_RECORD)
    assert np.all(r.gains()["kp"] > 0) and len(r.axes) == 2
    path = tmp_path / "again.json"
    r.save(path)
    assert record.load(path) == r
    for machines in (ROOT / "baselines" / "commissioning" / "shipped" / "machines").glob("*.json"):
        assert [record.CommissioningRecord.from_dict(d) for d in json.loads(machines.read_text())]


def test_a_stored_list_of_machine_records_names_the_record_at_fault(tmp_path, monkeypatch):
    from vcnc_baselines.commissioning import record

    monkeypatch.setattr(record, "MACHINES_SHIPPED", tmp_path)
    (tmp_path / "k.json").write_text(json.dumps([_record(), _record(ceiling=0)]))
    with pytest.raises(BadFile, match=r"k\.json: ceiling must be > 0"):
        record._load_machines("k")
    (tmp_path / "k.json").write_text("{}")
    with pytest.raises(BadFile, match=r"k\.json: the file must be a list"):
        record._load_machines("k")


# -- stored floors -----------------------------------------------------------------------------------------------------
def _floor(tmp_path, name="K", **changes):
    from vcnc_baselines.optimal import solutions

    source = sorted(solutions.DIRECTORY.glob("*.npz"))[0]
    z = dict(np.load(source, allow_pickle=False))
    for k, v in changes.items():
        if v is _DELETE:
            del z[k]
        else:
            z[k] = v
    path = tmp_path / f"{name}.npz"
    np.savez(path, **z)
    return path, source


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p, b: p.write_bytes(b[: len(b) // 2]), "BadZipFile"),
        (lambda p, b: p.write_bytes(b[:100]), "BadZipFile"),
        (lambda p, b: p.write_bytes(b""), "EOFError"),
        (lambda p, b: p.write_bytes(b"\n"), "is not a stored floor's .npz"),
        (lambda p, b: np.save(p.with_suffix(".npy"), np.zeros(3)) or p.with_suffix(".npy").rename(p), "single .npy"),
    ],
)
def test_a_truncated_or_empty_stored_floor_is_named_and_passed_over(tmp_path, monkeypatch, damage, message):
    from vcnc_baselines.optimal import solutions

    path, source = _floor(tmp_path)
    damage(path, source.read_bytes())
    with pytest.raises(BadFile) as exc:
        solutions._read(path)
    assert str(exc.value).startswith(f"{path}: ") and message in str(exc.value) and "\n" not in str(exc.value)
    monkeypatch.setenv("VCNC_ORACLE_SOLUTIONS", str(tmp_path))
    with pytest.raises(BadFile):
        solutions.load("K")
    good, _ = _floor(tmp_path, "K~othercpu")
    with pytest.warns(UserWarning, match=rf"the stored floor {path}: .*: the next stored solution, else solving again"):
        found = solutions.load_all("K")
    assert len(found) == 1 and found[0].max_um == float(np.load(good)["max_um"])


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"correction": _DELETE}, "has no array 'correction'"),
        ({"evaluations": _DELETE}, "has no array 'evaluations'"),
        ({"max_um": np.float64("nan")}, "max_um must be finite"),
        ({"rms_um": np.float64(-1.0)}, "rms_um must be >= 0"),
        ({"correction": np.zeros((5, 1), np.float32)}, "correction must be (L, 2)"),
        ({"table": np.full((3, 2), np.inf, np.float32)}, "table holds a value that is not finite"),
        ({"warm_starts": np.array("{")}, "warm_starts is not the JSON"),
        ({"warm_starts": np.array('{"qft": 1}')}, "warm_starts['qft'] must be a list"),
    ],
)
def test_a_stored_floor_is_checked_as_store_writes_it(tmp_path, changes, message):
    from vcnc_baselines.optimal import solutions

    path, _ = _floor(tmp_path, **changes)
    with pytest.raises(BadFile) as exc:
        solutions._read(path)
    assert str(exc.value).startswith(f"{path}: ") and message in str(exc.value), str(exc.value)


def test_every_shipped_floor_passes_the_check():
    from vcnc_baselines.optimal import solutions

    for path in sorted(solutions.DIRECTORY.glob("*.npz")):
        assert solutions._read(path).correction.shape[1] == 2


# -- the leaderboard ---------------------------------------------------------------------------------------------------
_BENCH = ["--env", "VCNC-Circle-v1", "--policy", "pd-ref", "--no-progress"]


def _bench_main(argv):
    from vcnc_bench import cli

    return cli.main(argv)


def _board_rows():
    from vcnc_bench import leaderboard

    bench = {
        "settings": {"command": "vcnc-bench", "provenance": {"cpu": {"model": "test"}}},
        "records": [
            {
                "env": "A",
                "policy": p,
                "kind": "baseline",
                "max_contour_error_um": m,
                "rms_contour_error_um": m / 2,
                "completed": True,
                "diverged": False,
            }
            for p, m in (("pd-ref", 10.0), ("oracle (non-causal)", 1.0), ("qft", 5.0))
        ],
    }
    return leaderboard.rows_of(bench)


@pytest.mark.parametrize(
    "page, message",
    [
        ("board.json", "would be both the page and its rows"),
        ("sub/board.json", "would be both the page and its rows"),
        ("/dev/null", "/dev/null is not a regular file"),
        ("/dev/zero", "/dev/zero is not a regular file"),
        (".", "is a folder; give the page's file name"),
        ("", "is a folder; give the page's file name"),
    ],
)
def test_a_leaderboard_page_that_cannot_be_one_is_refused_before_the_run(tmp_path, monkeypatch, capsys, page, message):
    monkeypatch.chdir(tmp_path)
    line = _exits_2(_bench_main, [*_BENCH, "--leaderboard", page], capsys)
    assert line.startswith("vcnc-bench: error: --leaderboard ") and message in line, line
    assert not Path("/dev/null.json").exists() and not Path("/dev/zero.json").exists()
    assert sorted(p.name for p in tmp_path.rglob("*")) == []


def test_a_folder_as_the_leaderboard_names_the_leaderboard_not_the_json(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("d").mkdir()
    for argv in (["--leaderboard", "d"], ["--leaderboard", "d", "--json", "out.json"]):
        line = _exits_2(_bench_main, [*_BENCH, *argv], capsys)
        assert "--leaderboard d is a folder" in line and "--json" not in line, line
    line = _exits_2(_bench_main, [*_BENCH, "--json", "d"], capsys)
    assert "--json d is a directory" in line


@pytest.mark.parametrize("json_name", ["board.json", "board.md", "board_profile.png"])
def test_the_json_of_the_run_may_not_be_a_file_of_the_leaderboard(tmp_path, monkeypatch, capsys, json_name):
    monkeypatch.chdir(tmp_path)
    line = _exits_2(_bench_main, [*_BENCH, "--leaderboard", "board.md", "--json", json_name], capsys)
    assert f"--json {json_name} is one of the leaderboard's files" in line


def _rows_file(rows):
    return json.dumps({"rows": rows}, allow_nan=True)


@pytest.mark.parametrize(
    "content, message",
    [
        ('{"rows": [', "is not JSON (a leaderboard's rows): Expecting value at line 1"),
        ("", "is not JSON (a leaderboard's rows): empty"),
        ("[1, 2]", "the file must be an object {...}, got a list"),
        ("null", "the file must be an object {...}, got null"),
        ("{}", "the file has no field 'rows'"),
        ('{"rows": {}}', "rows must be a list [...], got an object"),
        (
            lambda rows: _rows_file([{k: v for k, v in r.items() if k != "policy"} for r in rows]),
            "has no field 'policy'",
        ),
        (lambda rows: _rows_file([{**rows[0], "policy": 3}]), "rows[0].policy must be a string"),
        (lambda rows: _rows_file([rows[0], {**rows[1], "max_um": float("nan")}]), "rows[1].max_um must be finite"),
        (lambda rows: _rows_file([{**rows[0], "rms_um": float("inf")}]), "rows[0].rms_um must be finite"),
        (lambda rows: _rows_file([{**rows[0], "max_um": -1.0}]), "rows[0].max_um must be >= 0"),
        (lambda rows: _rows_file([{**rows[0], "role": "king"}]), "rows[0].role must be one of"),
        (lambda rows: '{"rows": ' + "[" * 100 + "]" * 100 + "}", f"deeper than {MAX_DEPTH} levels"),
    ],
)
def test_a_malformed_leaderboard_is_refused_before_the_run(tmp_path, monkeypatch, capsys, content, message):
    """Refused by the first checks, naming the page's rows file and the field: no env is built, no episode runs
    (the run's rows would otherwise be lost at its end), the files are left as they were."""
    monkeypatch.chdir(tmp_path)
    text = content(_board_rows()) if callable(content) else content
    Path("board.json").write_text(text)
    line = _exits_2(_bench_main, [*_BENCH, "--leaderboard", "board.md"], capsys)
    assert line.startswith("vcnc-bench: error: --leaderboard board.json: ") and message in line, line
    assert Path("board.json").read_text() == text and not Path("board.md").exists()


def test_the_runs_rows_are_kept_when_the_board_cannot_be_written_after_the_run(tmp_path, monkeypatch, capsys):
    """The board checked before the run, then damaged while it ran: one line, exit 1, the run's records kept
    beside the page (or in --json) with the command that adds them; the damaged board is left as it is."""
    from types import SimpleNamespace

    from vcnc_bench import leaderboard, output

    monkeypatch.chdir(tmp_path)
    out = {"settings": {"command": "vcnc-bench"}, "records": _board_records()}
    Path("board.json").write_text("{")
    args = SimpleNamespace(leaderboard=Path("board.md"), json=None)
    assert output.add_to_leaderboard(args, out) == 1
    line = _one_line(capsys.readouterr().err)
    kept = sorted(tmp_path.glob("board-run-*.json"))
    assert len(kept) == 1 and json.loads(kept[0].read_text()) == out
    assert (
        "--leaderboard board.json: is not JSON" in line and f"python -m vcnc_bench.leaderboard {kept[0].name}" in line
    )
    assert Path("board.json").read_text() == "{"
    Path("mine.json").write_text(json.dumps(out))
    args = SimpleNamespace(leaderboard=Path("board.md"), json=Path("mine.json"))
    assert output.add_to_leaderboard(args, out) == 1
    assert "records are in mine.json" in capsys.readouterr().err
    assert len(list(tmp_path.glob("board-run-*.json"))) == 1
    Path("board.json").unlink()
    assert output.add_to_leaderboard(args, out) == 0  # and once the board is whole, they are added
    assert {r["policy"] for r in leaderboard.board_rows("board.md")} == {"pd-ref", "oracle (non-causal)", "qft"}


def _board_records():
    return [
        {
            "env": "A",
            "policy": p,
            "kind": "baseline",
            "max_contour_error_um": m,
            "rms_contour_error_um": m / 2,
            "completed": True,
            "diverged": False,
        }
        for p, m in (("pd-ref", 10.0), ("oracle (non-causal)", 1.0), ("qft", 5.0))
    ]


def test_the_leaderboard_command_refuses_a_bench_json_of_the_wrong_shape(tmp_path, capsys):
    from vcnc_bench import leaderboard

    bad = tmp_path / "bench.json"
    for content, message in (
        ({"settings": {}, "records": [{"env": "A", "policy": 5, "completed": True, "diverged": False}]}, "policy"),
        ({"settings": [], "records": []}, "settings must be an object"),
        ({"settings": {}, "robust": [{"env": "A"}]}, "robust[0] has no field 'policy'"),
    ):
        bad.write_text(json.dumps(content))
        line = _exits_2(leaderboard.main, [str(bad), "--out", str(tmp_path / "lb.md")], capsys)
        assert f"{bad}: not a vcnc-bench JSON: " in line and message in line, line
    (tmp_path / "lb.json").write_text('{"rows": [{"env": "A"}]}')
    bad.write_text(json.dumps({"settings": {}, "records": _board_records()}))
    line = _exits_2(leaderboard.main, [str(bad), "--out", str(tmp_path / "lb.md")], capsys)
    assert "--out" in line and "lb.json: rows[0] has no field 'policy'" in line


# -- python -m vcnc_bench.check ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "content, message",
    [
        ({"settings": {}, "plan": [1], "records": []}, "plan must be an object {...}, got a list"),
        ({"settings": {}, "plan": {"A": "pd-ref"}, "records": []}, "plan['A'] must be a list"),
        ({"settings": {}, "plan": {"A": ["p"]}, "records": {}}, "records must be a list"),
        ({"settings": {}, "plan": {"A": ["p"]}, "records": [5]}, "records[0] must be an object"),
        (
            {"settings": {}, "plan": {}, "records": [{"env": "A", "policy": 7, "completed": True, "diverged": False}]},
            "records[0].policy must be a string",
        ),
        (
            {"settings": {}, "plan": {}, "records": [{"env": "A", "policy": "p", "completed": "yes", "diverged": 0}]},
            "records[0].completed must be True or False",
        ),
        ({"settings": {"provenance": []}, "plan": {}, "records": []}, "settings.provenance must be an object"),
        ("[" * 100_000 + "]" * 100_000, f"deeper than {MAX_DEPTH} levels"),
        ('{"settings": {}, "plan": {"A": ' + "[" * 40 + "]" * 40 + '}, "records": []}', f"deeper than {MAX_DEPTH}"),
        ('{"settings": {}, "plan": {}, "records": [}', "is not JSON"),
    ],
)
def test_the_check_answers_wrong_types_and_deep_nesting_in_one_line(tmp_path, capsys, content, message):
    from vcnc_bench import check

    path = tmp_path / "bench.json"
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    assert check.main([str(path)]) == 1
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"{path}: ") and message in line, line


# -- seeds.json of --policy ppo:FOLDER ---------------------------------------------------------------------------------
_GOOD_SEEDS = {
    "env": "VCNC-Heart-v1",
    "argv": ["--env", "VCNC-Heart-v1", "--seeds", "1"],
    "runs": [{"seed": 0, "folder": "x/seed0", "code": 0, "wall_s": 1.0, "best_max_um": 1.0, "best_rms_um": 0.5}],
}


def _seeds(**run):
    return {**_GOOD_SEEDS, "runs": [{**_GOOD_SEEDS["runs"][0], **run}]}


@pytest.mark.parametrize(
    "content, message",
    [
        ([_GOOD_SEEDS], "the file must be an object {...}, got a list"),
        (None, "the file must be an object {...}, got null"),
        (_seeds(folder=5), "runs[0].folder must be a string, got the number 5"),
        (_seeds(folder=None), "runs[0].folder must be a string, got null"),
        ('{"runs": ' + "[" * 5000 + "]" * 5000 + "}", f"deeper than {MAX_DEPTH} levels"),
        ('{"runs": [[[[' + "[" * 30 + "]" * 34 + "}", f"deeper than {MAX_DEPTH} levels"),
        ({**_GOOD_SEEDS, "runs": [{"seed": 0, "folder": "seed0"}]}, "runs[0] has no field 'code'"),
        ({"env": "VCNC-Heart-v1"}, "the file has no field 'runs'"),
        ({**_GOOD_SEEDS, "runs": {"0": 1}}, "runs must be a list"),
        ({**_GOOD_SEEDS, "runs": []}, "runs must hold at least 1 item"),
        ("{runs: 1", "is not JSON (a vcnc-train --seeds summary): Expecting property name"),
        ("", "is not JSON (a vcnc-train --seeds summary): empty"),
        (_seeds(seed=-1), "runs[0].seed must be an integer in [0, 4294967295]"),
        (_seeds(seed="0"), "runs[0].seed must be an integer"),
        (_seeds(folder=".."), "runs[0].folder must name a run folder"),
        (_seeds(code=True), "runs[0].code must be an integer"),
        (_seeds(best_max_um=float("nan")), "runs[0].best_max_um must be finite"),
        ({**_GOOD_SEEDS, "runs": _GOOD_SEEDS["runs"] * 2}, "runs holds seed 0 twice"),
    ],
)
def test_a_malformed_seeds_json_is_refused_naming_the_file_and_the_field(tmp_path, capsys, content, message):
    folder = tmp_path / "family"
    folder.mkdir()
    path = folder / "seeds.json"
    path.write_text(content if isinstance(content, str) else json.dumps(content, allow_nan=True))
    line = _exits_2(_bench_main, ["--env", "VCNC-Heart-v1", "--policy", f"ppo:{folder}", "--no-progress"], capsys)
    assert line.startswith(f"vcnc-bench: error: --policy: {path}: ") and message in line, line


def test_a_good_seeds_json_names_each_seeds_agent(tmp_path):
    from vcnc_bench.policies import expand_spec

    folder = tmp_path / "family"
    (folder / "seed0" / "best").mkdir(parents=True)
    (folder / "seeds.json").write_text(json.dumps(_GOOD_SEEDS))
    assert expand_spec(f"ppo:{folder}") == [f"ppo:{folder / 'seed0' / 'best'}"]


# -- the positioning env ---------------------------------------------------------------------------------------------
def test_the_floor_is_refused_on_the_positioning_env_as_the_predictive_controllers_are(capsys):
    import gymnasium as gym

    from vcnc_bench.policies import resolve_policy

    env = gym.make("VCNC-Step-v0")
    for spec in ("oracle", "mpc"):
        with pytest.raises(ValueError, match="needs a contouring env"):
            resolve_policy(spec, env)
    for argv in (["--policy", "oracle", "--jobs", "1"], ["--policy", "oracle", "--plants", "2"]):
        line = _exits_2(_bench_main, ["--env", "VCNC-Step-v0", "--no-progress", *argv], capsys)
        assert "cannot build policy 'oracle' for VCNC-Step-v0" in line and "needs a contouring env" in line, line


def test_the_positioning_env_under_plants_has_no_floor_to_score_against():
    """``--plants N`` on VCNC-Step-v0 adds the floor's replay where it applies: not there (was: a traceback)."""
    from types import SimpleNamespace

    import gymnasium as gym

    from vcnc_bench.robust_run import nominal_floors

    args = SimpleNamespace(feedrate=None, plant=None, shop_floor=False, seed=0)
    env = gym.make("VCNC-Step-v0")
    assert nominal_floors(args, {"VCNC-Step-v0": env}, [("VCNC-Step-v0", "imc", None)]) == {}


# -- sizes ------------------------------------------------------------------------------------------------------------
def _check_sizes(env_id, capsys, **options):
    import argparse
    from types import SimpleNamespace

    import gymnasium as gym

    from vcnc_bench.arguments import check_sizes

    args = SimpleNamespace(trials=None, **options)
    parser = argparse.ArgumentParser(prog="vcnc-bench")
    return _exits_2(lambda _: check_sizes(args, {env_id: gym.make(env_id)}, parser), [], capsys)


def test_the_noise_seeds_limit_counts_the_runs_it_refuses(capsys):
    line = _check_sizes("VCNC-HeartShop-v1", capsys, plants=1, noise_seeds=10**10)
    assert "--plants 1 x --noise-seeds 10000000000" in line and "the nominal one, 1 sampled and 0 vertices" in line
    assert line.endswith("got 20,000,000,000"), line
    line = _check_sizes("VCNC-Heart-v1", capsys, plants=10**8, noise_seeds=1)
    assert "--plants 100000000 (the nominal one, 100,000,000 sampled and 64 vertices)" in line
    assert line.endswith("got 100,000,065"), line


def test_a_million_seeds_are_refused_before_anything_is_allocated(tmp_path, capsys):
    from vcnc_agents import cli
    from vcnc_agents.seeds import MAX_SEEDS, run_seeds

    out = tmp_path / "family"
    line = _exits_2(
        cli.main, ["--env", "VCNC-Heart-v1", "--seeds", "1000000", "--jobs", "2", "--output", str(out)], capsys
    )
    assert "--seeds must be at most 1,000" in line and "a whole training run" in line and line.endswith("1,000,000")
    assert not out.exists()
    with pytest.raises(ValueError, match="--seeds must be at most 1,000"):
        run_seeds([], "VCNC-Heart-v1", 0, MAX_SEEDS + 1, out)


def test_a_history_longer_than_any_episode_is_refused_in_one_line(tmp_path, capsys):
    from vcnc_agents import cli
    from vcnc_agents.action_modes import MAX_HISTORY, ActionMode

    out = tmp_path / "run"
    argv = ["--env", "VCNC-Heart-v1", "--action-mode", "residual", "--output", str(out)]
    line = _exits_2(cli.main, [*argv, "--history", "1000000000"], capsys)
    assert "history must be at most 1,000 past decisions" in line and line.endswith("got 1,000,000,000")
    assert "invalid int value: '1e9'" in _exits_2(cli.main, [*argv, "--history", "1e9"], capsys)
    assert not out.exists()
    with pytest.raises(ValueError, match="history must be at most"):
        ActionMode(mode="residual", baseline="smc", history=MAX_HISTORY + 1)


# -- two trainers on one folder ----------------------------------------------------------------------------------------
def test_a_second_trainer_on_a_folder_another_trains_is_refused_in_one_line(tmp_path, capsys):
    """The first holds the folder's lock.  The second, started before the first wrote anything but its lock (its
    checks pass) or after (its checks see the lock), says so in one line, exit 2, and claims nothing was cleared;
    the folder is as the first left it."""
    from vcnc_agents import cli
    from vcnc_agents.run_folder import run_lock

    run = tmp_path / "run"
    run.mkdir()
    argv = ["--env", "VCNC-Step-v0", "--output", str(run), "--timesteps", "64", "--no-progress"]
    with run_lock(run):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert "is being trained by another process" in _one_line(err) and "cleared" not in err, err
        assert sorted(p.name for p in run.iterdir()) == [".lock"]
        (run / "config.yml").write_text("env_id: VCNC-Step-v0\n")
        line = _exits_2(cli.main, argv, capsys)
        assert "is being trained by another process" in line and "cleared" not in line, line
        assert sorted(p.name for p in run.iterdir()) == [".lock", "config.yml"]


# -- G-code and random contours ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("circle", [(1e-9, 3000.0), (50.0, 1e-6), (1e-4, 3000.0), (50.0, 1e-4)])
def test_a_circle_the_program_cannot_write_is_refused_naming_circle(capsys, circle):
    line = _exits_2(
        _bench_main,
        ["--program", "iso230-4", "--circle", *map(str, circle), "--policy", "pd-ref", "--no-progress"],
        capsys,
    )
    assert "--circle D F must be at least 0.002 mm and 0.001 mm/min" in line, line


def test_the_smallest_circle_allowed_is_written_as_the_reader_reads_it():
    from vcnc_gym.gcode.interpreter import read_program_text
    from vcnc_gym.gcode.pieces import CIRCLE_MIN_DIAMETER, CIRCLE_MIN_FEED, circle_program

    for d, f in ((CIRCLE_MIN_DIAMETER, 3000.0), (50.0, CIRCLE_MIN_FEED), (50.0, 0.0123456)):
        text = circle_program(d, f)
        assert "e-" not in text.split("\n", 3)[3]  # no exponent in the program's words
        read_program_text(text)
    with pytest.raises(ValueError, match="the circle's diameter must be in"):
        circle_program(1e-9, 3000.0)
    with pytest.raises(ValueError, match="the circle's feed must be in"):
        circle_program(50.0, 1e-6)


@pytest.mark.parametrize("feeds", [(1e-9, 1e-9), (5.0, 5.0), (0.01, 100.0)])
def test_a_random_contours_feed_too_slow_to_write_is_refused(feeds):
    from vcnc_gym.gcode.random_contour import RandomContourSpec

    with pytest.raises(ValueError, match="spec feed_min must be at least 10 mm/min"):
        RandomContourSpec(feed_min=feeds[0], feed_max=feeds[1])


def test_the_slowest_random_feed_allowed_is_read_back():
    from vcnc_gym.gcode.interpreter import read_program_text
    from vcnc_gym.gcode.random_contour import MIN_FEED, RandomContourSpec, random_program

    spec = RandomContourSpec(feed_min=MIN_FEED, feed_max=MIN_FEED)
    read_program_text(random_program(np.random.default_rng(0), spec))


# -- a damaged checkpoint ----------------------------------------------------------------------------------------------
def test_a_resume_refused_for_damaged_checkpoints_sets_them_aside_as_promised(tmp_path):
    from vcnc_agents.run_folder import write_config
    from vcnc_agents.run_session import prepare_run

    run = tmp_path / "run"
    _, config, _ = prepare_run("VCNC-Step-v0", run, n_timesteps=64)
    run.mkdir()
    write_config(run, config)
    checkpoints = run / "checkpoints"
    checkpoints.mkdir()
    (checkpoints / "rl_model_64_steps.zip").write_bytes(b"PK\x03\x04 truncated")
    (checkpoints / "rl_model_vecnormalize_64_steps.npz").write_bytes(b"")
    (checkpoints / "rl_model_128_steps.zip").write_bytes(b"")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(FileNotFoundError, match=r"the damaged ones are set aside as \*\.damaged \(3 files\)"):
            prepare_run(None, run, resume=True)
    assert sorted(p.name for p in checkpoints.iterdir()) == [
        "rl_model_128_steps.zip.damaged",
        "rl_model_64_steps.zip.damaged",
        "rl_model_vecnormalize_64_steps.npz.damaged",
    ]


@pytest.mark.parametrize(
    "vertices, message",
    [
        ("abc", "vertices must be K >= 2 points (x, y) in mm, got str 'abc'"),
        ({"x": 1}, "got dict"),
        ([[0, 0], ["a", 1]], "of real numbers in mm: could not convert string to float"),
        ([[0, 0], [1, {}]], "of real numbers in mm"),
    ],
)
def test_a_polyline_of_no_numbers_is_refused_naming_the_vertices(vertices, message):
    from vcnc_gym.geometry import smooth_polyline

    with pytest.raises(ValueError, match="^vertices must be") as exc:
        smooth_polyline(vertices, 0.1, 1000.0, 1e5)
    assert message in str(exc.value)
