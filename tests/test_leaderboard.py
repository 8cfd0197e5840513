"""The leaderboard (vcnc_bench.leaderboard): rows from bench JSONs, the normalised score, the ranking, the merge
that adds a user's policy, the performance profile and the page."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from vcnc_bench import leaderboard


def _nominal(env, policy, mx, rms, kind="baseline", completed=True):
    return {
        "env": env,
        "policy": policy,
        "kind": kind,
        "trial": None,
        "max_contour_error_um": mx,
        "rms_contour_error_um": rms,
        "completed": completed,
        "diverged": False,
    }


def _bench(records, command="vcnc-bench --json x.json"):
    return {
        "settings": {
            "command": command,
            "provenance": {"cpu": {"model": "test CPU"}, "libraries": {"vcnc-gym": "0.0"}},
        },
        "records": records,
    }


def _default_json():
    recs = []
    for env, scale in (("A", 1.0), ("B", 10.0), ("C", 100.0)):
        recs += [
            _nominal(env, "pd-ref", 10 * scale, 5 * scale),
            _nominal(env, "oracle (non-causal)", 1 * scale, 0.5 * scale),
            _nominal(env, "ff-pid", 2 * scale, 1 * scale),
            _nominal(env, "qft", 8 * scale, 4 * scale),
            _nominal(env, "ppo", 1.5 * scale, 1.2 * scale, kind="ppo"),
        ]
    recs.append({"table": "headroom", "env": "A"})
    return _bench(recs)


def test_scores_and_ranks_are_the_normalised_score_of_the_max():
    board = leaderboard.ranked(leaderboard.rows_of(_default_json()))
    a = board["A"]
    assert [r["policy"] for r in a] == ["oracle (non-causal)", "ppo", "ff-pid", "qft", "pd-ref"]
    by = {r["policy"]: r for r in a}
    assert by["ff-pid"]["score_max"] == pytest.approx((10 - 2) / (10 - 1))
    assert by["ppo"]["score_rms"] == pytest.approx((5 - 1.2) / (5 - 0.5))
    assert by["pd-ref"]["score_max"] == 0.0 and by["oracle (non-causal)"]["score_max"] == 1.0
    assert {r["role"] for r in a} == {"floor", "reference", "classical", "learned or yours"}
    assert by["ppo"]["source"] == {"command": "vcnc-bench --json x.json", "cpu": "test CPU", "version": "0.0"}


def test_an_unfinished_run_scores_minus_infinity_as_none_and_ranks_last():
    data = _default_json()
    data["records"].append(_nominal("A", "smc", 3.0, 1.0, completed=False))
    board = leaderboard.ranked(leaderboard.rows_of(data))
    assert board["A"][-1]["policy"] == "smc" and board["A"][-1]["score_max"] is None


def test_a_users_policy_joins_the_board_and_replaces_its_own_row(tmp_path):
    page = tmp_path / "leaderboard.md"
    leaderboard.write(page, leaderboard.rows_of(_default_json()))
    mine = _bench([_nominal("A", "mine:v1", 1.2, 0.6, kind="mine")], command="vcnc-bench --policy mine:v1")
    leaderboard.write(page, leaderboard.rows_of(mine))
    leaderboard.write(page, leaderboard.rows_of(mine))  # again: replaced, not doubled
    rows = json.loads(page.with_suffix(".json").read_text())["rows"]
    assert sum(r["policy"] == "mine:v1" for r in rows) == 1 and len(rows) == 16
    text = page.read_text()
    assert (
        "`mine:v1`" in text and "| 2 | `mine:v1` |" in text and "| 0.9778 |" in text
    )  # second to the floor: (10-1.2)/9 > ppo's
    assert "nominal only" in text and "vcnc-bench --policy mine:v1" in text
    assert (tmp_path / "leaderboard_profile.png").stat().st_size > 1000


def test_a_retired_policy_is_dropped_from_the_board_on_every_id_and_an_unknown_one_named(tmp_path, capsys):
    page = tmp_path / "leaderboard.md"
    leaderboard.write(page, leaderboard.rows_of(_default_json()))
    mine = _bench([_nominal("A", "mine:v2", 1.2, 0.6, kind="mine")], command="vcnc-bench --policy mine:v2")
    leaderboard.main([str(_write(tmp_path / "v2.json", mine)), "--out", str(page), "--drop", "ppo"])
    rows = json.loads(page.with_suffix(".json").read_text())["rows"]
    assert not any(r["policy"] == "ppo" for r in rows) and len(rows) == 15 - 3 + 1
    assert "`ppo`" not in page.read_text() and "`mine:v2`" in page.read_text()
    with pytest.raises(SystemExit):
        leaderboard.main([str(tmp_path / "v2.json"), "--out", str(page), "--drop", "ppo"])
    err = capsys.readouterr().err
    assert "no row of" in err and "the policy 'ppo'" in err


def _write(path, data):
    path.write_text(json.dumps(data))
    return path


def test_profile_is_the_fraction_of_ids_at_or_above_tau():
    board = leaderboard.ranked(leaderboard.rows_of(_default_json()))
    curves = leaderboard.profile(board, taus=[0.0, 0.5, 0.9, 1.0])
    assert set(curves) == {"pd-ref", "oracle (non-causal)", "ff-pid", "qft", "ppo"}
    np.testing.assert_array_equal(curves["ff-pid"], [1.0, 1.0, 0.0, 0.0])  # 8/9 on every id
    np.testing.assert_array_equal(curves["oracle (non-causal)"], [1.0, 1.0, 1.0, 1.0])


def test_a_plants_record_gives_its_iqm_interval_and_verdict():
    rng = np.random.default_rng(0)
    x = rng.uniform(1.0, 2.0, 20)
    per = {
        "kind": ["nominal"] + ["sample"] * 20,
        "max_um": [1.5] + list(x),
        "rms_um": [0.5] + list(x / 3),
        "diverged": [False] * 21,
        "completed": [True] * 21,
    }
    rec = {
        "env": "A",
        "policy": "ppo",
        "kind": "ppo",
        "nominal_max_um": 1.5,
        "nominal_rms_um": 0.5,
        "nominal_completed": True,
        "nominal_diverged": False,
        "n_samples": 20,
        "per_plant": per,
        "verdicts": {"max": {"outcome": "ties", "y": "ff-pid", "difference": 0.1, "low": -0.1, "high": 0.2}},
    }
    (row,) = leaderboard.rows_of({"settings": {}, "robust": [rec]})
    assert row["plants"] == 20
    assert row["iqm_max"][0] == pytest.approx(stats.trim_mean(x, 0.25))
    assert row["iqm_max"][1] < row["iqm_max"][0] < row["iqm_max"][2]
    assert row["verdicts"]["max"] == {
        "outcome": "ties",
        "opponent": "ff-pid",
        "difference": [0.1, -0.1, 0.2],
        "controller": None,
        "training_seeds": 1,
    }


def test_the_command_line_refuses_what_is_not_a_bench_json(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("[1, 2]")
    with pytest.raises(SystemExit):
        leaderboard.main([str(bad), "--out", str(tmp_path / "lb.md")])
    assert "not a vcnc-bench JSON" in capsys.readouterr().err


def test_a_runs_seeds_are_one_row_with_their_median_and_their_verdicts_interval():
    """The agents of one vcnc-train --seeds run are judged as one controller (tests/test_verdicts.py) and ranked as
    one: a single row ``GROUP (K seeds)`` whose nominal figures are the seeds' medians (numpy's, here) and whose IQM
    and interval are the verdict's (which resampled the seeds with the plants)."""
    rng = np.random.default_rng(1)
    verdict = {
        "outcome": "loses",
        "y": "ff-pid@machine",
        "x": "ppo:run",
        "difference": 1.0,
        "low": 0.5,
        "high": 2.0,
        "iqm_x": 1.7,
        "ci_x": [1.5, 1.9],
        "training_seeds": 3,
    }
    records = []
    for seed, nominal in enumerate((1.0, 3.0, 2.0)):
        x = rng.uniform(1.0, 2.0, 20)
        per = {
            "kind": ["nominal"] + ["sample"] * 20,
            "max_um": [nominal] + list(x),
            "rms_um": [nominal / 2] + list(x / 3),
            "diverged": [False] * 21,
            "completed": [True] * 21,
        }
        records.append(
            {
                "env": "A",
                "policy": f"ppo:run/seed{seed}/best",
                "kind": "ppo",
                "group": "ppo:run",
                "nominal_max_um": nominal,
                "nominal_rms_um": nominal / 2,
                "nominal_completed": True,
                "nominal_diverged": False,
                "n_samples": 20,
                "per_plant": per,
                "verdicts": {"max": verdict},
            }
        )
    (row,) = leaderboard.rows_of({"settings": {}, "robust": records})
    assert row["policy"] == "ppo:run (3 seeds)" and row["seeds"] == 3
    assert row["max_um"] == np.median([1.0, 3.0, 2.0]) and row["rms_um"] == np.median([0.5, 1.5, 1.0])
    assert row["iqm_max"] == [1.7, 1.5, 1.9]
    lo, hi = row["iqm_rms"][1], row["iqm_rms"][2]  # no rms verdict here: the bootstrap over every seed's plants
    assert lo < row["iqm_rms"][0] < hi
    from vcnc_bench.leaderboard import _verdict

    assert _verdict(row) == "max: loses (ff-pid@machine) (3 seeds judged as one)"


def test_an_id_run_on_another_plant_is_a_section_of_its_own():
    """``vcnc-bench --plant NAME``'s rows do not replace the id's own (same id, same policy, another machine)."""
    own = leaderboard.rows_of(_bench([_nominal("A", "ff-ccc", 2.0, 1.0)]))
    other = _bench([_nominal("A", "ff-ccc", 0.02, 0.001)])
    other["settings"]["plant"] = "current_feed_drive"
    rows = leaderboard.merge(own, leaderboard.rows_of(other))
    assert sorted(r["env"] for r in rows) == ["A", "A on current_feed_drive"]
    shop = _bench([_nominal("A", "ff-ccc", 5.0, 1.0)])
    shop["settings"]["shop_floor"] = True  # vcnc-bench --shop-floor: the same machine on its shop floor
    rows = leaderboard.merge(rows, leaderboard.rows_of(shop))
    assert sorted(r["env"] for r in rows) == ["A", "A on current_feed_drive", "A on the shop floor"]
