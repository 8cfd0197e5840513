"""Fuzz of the files a user passes (hypothesis): leaderboard pages' rows, ``vcnc-train --seeds`` folders and
commissioning records, each a valid file mutated (a value replaced by any JSON value, NaN and infinities included,
a field deleted, a value nested deep, the text cut short).

Each case is judged: refused with one line that names the file (a :class:`vcnc_gym.schema.BadFile`), or accepted,
and then what the suite does with it runs and holds the invariants of a file it wrote itself (the figures finite
or null, the gains positive, the agents inside the folder).  Any other exception, a refusal on several lines or an
accepted file that breaks an invariant is a failure; ``test_the_fuzz_fails_on_a_check_that_lets_anything_through``
shows that the judges can fail.  The counts of each outcome are printed (``pytest -s``) and must both be non-zero.
"""

from __future__ import annotations

import copy
import json
import math
import tempfile
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vcnc_gym.schema import BadFile

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_RECORD = ROOT / "baselines" / "commissioning" / "shipped" / "nct_xy_table-shop-3d91b03cb981.json"
#: Examples per surface: a few seconds each (CI runs them; ``--hypothesis-seed`` reproduces one).
EXAMPLES = 120
FUZZ = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None)
COUNTS: dict[str, Counter] = {}

_scalars = (
    st.none()
    | st.booleans()
    | st.integers(-(10**12), 10**12)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.sampled_from([0, -1, 1e-300, 1e300, "", "0", "abc", "nan"])
    | st.text(max_size=6)
)
_json = st.recursive(
    _scalars,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=8,
)


def _places(holder: list) -> list:
    """Every (container, key) under ``holder`` (a list holding the document: its root is ``(holder, 0)``)."""
    out, stack = [], [(holder, 0)]
    while stack:
        container, key = stack.pop()
        out.append((container, key))
        value = container[key]
        if isinstance(value, dict):
            stack.extend((value, k) for k in value)
        elif isinstance(value, list):
            stack.extend((value, i) for i in range(len(value)))
    return out


@st.composite
def _mutated(draw, base) -> str:
    """The text of ``base`` after none to three mutations (a value replaced by any JSON value, an awkward number or
    a value of its own type, a field or item deleted, a value nested 20 to 3000 lists deep), one time in ten cut
    short."""
    holder = [copy.deepcopy(base)]
    for _ in range(draw(st.integers(0, 3))):
        container, key = draw(st.sampled_from(_places(holder)))
        action = draw(st.sampled_from(["replace", "replace", "delete", "nest", "number", "alike"]))
        if action == "alike":  # a value of the same type: a file the suite could have written, or near it
            value = container[key]
            if isinstance(value, bool):
                container[key] = draw(st.booleans())
            elif isinstance(value, (int, float)):
                container[key] = type(value)(draw(st.integers(0, 10**6)) / (1 if isinstance(value, int) else 7))
            elif isinstance(value, str):
                container[key] = draw(st.text(min_size=1, max_size=8))
        elif action == "delete" and container is not holder:
            del container[key]
        elif action == "nest":
            value = container[key]
            for _ in range(draw(st.sampled_from([20, 40, 3000]))):
                value = [value]
            container[key] = value
        elif action == "number":
            container[key] = draw(st.sampled_from([float("nan"), float("inf"), -1.0, 0, 1e308, True, "1"]))
        else:
            container[key] = draw(_json)
    try:
        text = json.dumps(holder[0], allow_nan=True)
    except RecursionError:  # nested beyond the encoder's own stack
        text = "[" * 3000 + json.dumps(base) + "]" * 3000
    if draw(st.integers(0, 9)) == 0:
        text = text[: draw(st.integers(0, max(len(text) - 1, 0)))]
    return text


def _judge(surface: str, path: Path, read, use) -> None:
    """``read(path)`` must refuse with a one-line BadFile naming ``path``, or accept, and then ``use`` the result
    without an exception and its invariants holding; counted per surface."""
    counts = COUNTS.setdefault(surface, Counter())
    try:
        value = read(path)
    except BadFile as exc:
        message = str(exc)
        assert message.startswith(f"{path}: ") and "\n" not in message and len(message) < 600, message
        counts["refused in one line"] += 1
        return
    use(value)
    counts["accepted, used, invariants held"] += 1


def _figure_ok(v) -> bool:
    return v is None or (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0)


# -- leaderboard pages ------------------------------------------------------------------------------------------------
def _board():
    from vcnc_bench import leaderboard

    records = [
        {
            "env": env,
            "policy": p,
            "kind": "ppo" if p == "ppo" else "baseline",
            "max_contour_error_um": m,
            "rms_contour_error_um": m / 2,
            "completed": True,
            "diverged": False,
        }
        for env in ("A", "B", "C")
        for p, m in (("pd-ref", 10.0), ("oracle (non-causal)", 1.0), ("qft", 5.0), ("ppo", 2.0))
    ]
    rows = leaderboard.rows_of(
        {"settings": {"command": "vcnc-bench", "provenance": {"cpu": {"model": "x"}}}, "records": records}
    )
    rows[3].update(
        plants=20,
        iqm_max=[2.0, 1.5, 2.5],
        iqm_rms=[1.0, None, 1.2],
        verdicts={"max": {"outcome": "wins", "opponent": "qft", "difference": [-1.0, -2.0, -0.5], "training_seeds": 1}},
    )
    return {"rows": rows}


def _use_board(rows) -> None:
    from vcnc_bench import leaderboard

    for r in rows:
        assert _figure_ok(r["max_um"]) and _figure_ok(r["rms_um"]), r
        assert isinstance(r["env"], str) and isinstance(r["policy"], str)
    board = leaderboard.ranked(leaderboard.merge(rows, rows[:1]))
    leaderboard.format_page(board, None)
    leaderboard.profile(board)


def _read_board(path):
    from vcnc_bench.files import read_board

    return read_board(path)


@FUZZ
@given(text=_mutated(_board()))
def test_fuzz_leaderboard_pages(text):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "board.json"
        path.write_text(text)
        _judge("leaderboard pages", path, _read_board, _use_board)


# -- seed folders -----------------------------------------------------------------------------------------------------
_SEEDS = {
    "env": "VCNC-Heart-v1",
    "argv": ["--env", "VCNC-Heart-v1", "--seeds", "2", "--output", "family"],
    "runs": [
        {"seed": 0, "folder": "family/seed0", "code": 0, "wall_s": 10.0, "best_max_um": 3.0, "best_rms_um": 1.0},
        {"seed": 1, "folder": "family/seed1", "code": 0, "wall_s": 11.0, "best_max_um": None, "best_rms_um": None},
    ],
}


def _expand(folder: Path):
    from vcnc_bench.kinds import ppo

    try:
        return folder, ppo.KIND.expand(str(folder))
    except BadFile:
        raise
    except ValueError as exc:  # a seed without its agent: named, one line
        assert "\n" not in str(exc) and "no best agent for seed" in str(exc), str(exc)
        return folder, None


def _use_seeds(result) -> None:
    folder, agents = result
    for a in agents or []:
        p = Path(a)
        assert p.parent.parent == folder and p.name == "best" and p.is_dir(), a


@FUZZ
@given(text=_mutated(_SEEDS))
def test_fuzz_seed_folders(text):
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "family"
        for s in ("seed0", "seed1"):
            (folder / s / "best").mkdir(parents=True)
        path = folder / "seeds.json"
        path.write_text(text)
        _judge("seed folders", path, lambda p: _expand(p.parent), _use_seeds)


# -- commissioning records --------------------------------------------------------------------------------------------
def _use_record(r) -> None:
    g = r.gains()
    assert len(r.axes) == len(r.designs) == 2 and r.dt > 0
    assert all(math.isfinite(v) for k in ("kp", "kd", "ki") for v in g[k]) and (g["kp"] > 0).all(), g
    assert all(math.isfinite(a.mass) and a.mass > 0 for a in r.axes)
    str(r)
    from vcnc_baselines.commissioning.record import CommissioningRecord

    assert CommissioningRecord.from_dict(json.loads(r.to_json())) == r


def _load_record(path):
    from vcnc_baselines.commissioning import record

    return record.load(path)


@FUZZ
@given(text=_mutated(json.loads(SHIPPED_RECORD.read_text())))
def test_fuzz_commissioning_records(text):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "record.json"
        path.write_text(text)
        _judge("commissioning records", path, _load_record, _use_record)


def test_zz_the_fuzz_saw_both_outcomes_on_every_surface():
    """Runs after the three fuzz tests (this file's order): each surface had refusals and acceptances."""
    for surface in ("leaderboard pages", "seed folders", "commissioning records"):
        counts = COUNTS.get(surface)
        if counts is None:
            pytest.skip(f"the fuzz of {surface} did not run in this session")
        print(f"{surface}: {dict(counts)}")
        assert counts["refused in one line"] > 0 and counts["accepted, used, invariants held"] > 0, counts


# -- the judges can fail ----------------------------------------------------------------------------------------------
def test_the_fuzz_fails_on_a_check_that_lets_anything_through(tmp_path, monkeypatch):
    """With the checks emptied, a NaN figure is accepted and breaks the board's invariant, a negative gain the
    record's, a folder as a number the expansion: each judge raises."""
    from vcnc_bench import files
    from vcnc_baselines.commissioning import record

    monkeypatch.setattr(files, "check_row", lambda name, r: r)
    board = _board()
    board["rows"][0]["max_um"] = float("nan")
    path = tmp_path / "board.json"
    path.write_text(json.dumps(board, allow_nan=True))
    with pytest.raises(AssertionError):
        _judge("sabotaged", path, _read_board, _use_board)

    monkeypatch.setattr(record, "check_record", lambda d, where="": d)
    d = json.loads(SHIPPED_RECORD.read_text())
    d["designs"][0]["kp"] = -1e9
    path = tmp_path / "record.json"
    path.write_text(json.dumps(d))
    with pytest.raises((AssertionError, TypeError)):
        _judge("sabotaged", path, _load_record, _use_record)

    import vcnc_agents.seeds as seeds

    monkeypatch.setattr(seeds, "_check_run", lambda name, r: r)
    folder = tmp_path / "family"
    (folder / "seed0" / "best").mkdir(parents=True)
    (folder / "seeds.json").write_text(json.dumps({**_SEEDS, "runs": [{**_SEEDS["runs"][0], "folder": 5}]}))
    with pytest.raises(TypeError):
        _judge("sabotaged", folder / "seeds.json", lambda p: _expand(p.parent), _use_seeds)
