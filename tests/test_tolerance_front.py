"""The tolerance task's front (issue 37: cycle time against T, every opponent and the agents;
``experiments/tolerance/tolerance_front.py``), checked against figures worked out by hand in the test."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from benchmark_script import study_module

tl = study_module("tolerance", "tolerance")
tf = study_module("tolerance", "tolerance_front")

INF = math.inf
KINDS = ["nominal", "sample", "sample", "sample", "vertex"]


def _run(controller, feed, max_um, cycle):
    return {
        "controller": controller,
        "setting": {"feed": feed, "acceleration": 1000.0},
        "max_um": max_um,
        "cycle_time_s": cycle,
    }


def _search():
    """Two controllers over the nominal plant, three sampled plants and a vertex of the box."""
    runs = [
        _run("a", 100.0, [4.0, 4.0, 12.0, 4.0, 30.0], [1.0, 1.0, 1.0, 1.0, 1.0]),
        _run("a", 80.0, [3.0, 3.0, 8.0, 3.0, 25.0], [1.2, 1.2, 1.2, 1.2, 1.2]),
        _run("b", 120.0, [9.0, 6.0, 6.0, None, 6.0], [0.9, 0.9, 0.9, None, 0.9]),
    ]
    grid = [
        tl.GridRun(
            r["controller"],
            tl.Setting(**r["setting"]),
            np.array([INF if v is None else v for v in r["max_um"]]),
            np.array([INF if v is None else v for v in r["cycle_time_s"]]),
        )
        for r in runs
    ]
    return {
        "plants": 3,
        "plant_seed": 0,
        "kinds": KINDS,
        "rows": tl.tolerance_table(grid, KINDS, (0.005, 0.01)),
        "runs": runs,
    }


def _agents():
    per_plant = lambda cycles, errs: {  # noqa: E731
        "kind": KINDS + ["vertex"],
        "cycle_time_s": cycles,
        "max_um": errs,
    }
    return [
        {
            "group": "g",
            "policy": "ppo:x/seed0",
            "per_plant": per_plant([0.95, 0.95, 0.96, 0.97, 0.9, 0.9], [4.0, 4.0, 6.0, 4.0, 11.0, 1.0]),
        },
        {
            "group": "g",
            "policy": "ppo:x/seed1",
            "per_plant": per_plant([0.8, 0.85, None, 0.85, 0.9, 0.9], [9.0, 9.0, 2.0, 9.0, 9.0, 1.0]),
        },
    ]


def _point(fr, name, t_um):
    return next(p for p in fr.points if p.name == name and p.tolerance_um == t_um)


def test_each_point_is_the_fastest_within_t_worked_out_by_hand():
    """Per controller, the fastest run within T per plant; the per-plant search over both; the builder's setting
    (the nominal plant's fastest) on every plant; the agents' seeds, a run over T or unfinished counted as scrap."""
    fr = tf.front("X", "x", _search(), {"agents": _agents()}, tolerances=(0.005, 0.01))
    # T = 5 um.  a: plant 2 has no run within 5 um (12, 8); b: only plant 1, 2 and the vertex (6 um > 5: none).
    a5 = _point(fr, "a", 5.0)
    assert a5.nominal_s == (1.0,) and a5.median_s == 1.0 and (a5.over, a5.runs) == (2, 4)  # samples 1.0, inf, 1.0
    b5 = _point(fr, "b", 5.0)
    assert b5.nominal_s == (INF,) and b5.median_s == INF and b5.over == 4
    s5 = _point(fr, "per-plant search", 5.0)
    assert s5.nominal_s == (1.0,) and s5.median_s == 1.0 and s5.over == 2
    builder5 = _point(fr, "builder's setting", 5.0)
    assert builder5.choice.startswith("a, 100 mm/s") and builder5.median_s == 1.0 and builder5.over == 2
    g5 = _point(fr, "agents", 5.0)
    # seed 0: 0.95, inf (6 um), 0.97 over the samples; seed 1: all over 5 um, and plant 2 unfinished
    assert g5.nominal_s == (0.95, INF) and g5.median_s == INF and (g5.over, g5.runs) == (2 + 4, 8)
    # T = 10 um.  b: 0.9 on plants 1, 2 and the vertex, nominal 0.9 (9 um); a: plant 2 at 1.2 (8 um)
    s10 = _point(fr, "per-plant search", 10.0)
    assert s10.nominal_s == (0.9,) and s10.median_s == 0.9 and s10.over == 0  # samples 0.9, 0.9, 1.0
    g10 = _point(fr, "agents", 10.0)
    # samples: 0.95, 0.96, 0.97 and 0.85, inf, 0.85: median of six, (0.95 + 0.96) / 2
    assert g10.nominal_s == (0.95, 0.8) and g10.median_s == pytest.approx(0.955) and g10.over == 2


def test_the_table_names_the_builder_s_choice_and_scrap():
    text = tf.format_front(tf.front("X", "x", _search(), {"agents": _agents()}, tolerances=(0.005,)))
    assert "| 5 | builder's setting (a, 100 mm/s, 1000 mm/s^2) | 1 | 1 | 2 of 4 (runs over T) |" in text
    assert "| 5 | agents | 0.95, scrap | scrap | 6 of 8 (runs over T) |" in text


def test_agents_of_other_plants_are_refused():
    agents = _agents()
    agents[0]["per_plant"]["kind"] = ["nominal", "vertex", "sample", "sample", "sample", "vertex"]
    with pytest.raises(ValueError, match="other plants"):
        tf.agent_records(agents, KINDS, "x.json")


def test_the_shipped_fronts_draw_and_a_bad_spec_is_refused_by_name(tmp_path, capsys):
    """The shipped spec's files exist and give a table and a figure; a spec without a search is named."""
    out = tmp_path / "front.png"
    assert tf.main(["--spec", "experiments/tolerance/data/searches/fronts.json", "--plot", str(out)]) == 0
    assert out.stat().st_size > 10_000
    assert "VCNC-OmegaTolerance-v2 (the omega, ideal drives):" in capsys.readouterr().out
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps([{"id": "X", "title": "x"}]))
    with pytest.raises(SystemExit):
        tf.main(["--spec", str(bad)])
    assert "front 0 lacks ['search']" in capsys.readouterr().err
