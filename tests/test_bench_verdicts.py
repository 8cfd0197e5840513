"""The bench's score, verdicts, noise seeds and provenance (vcnc_bench.score, .verdicts, .robust, .provenance)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from vcnc_bench import cli, robust, score, verdicts
from vcnc_bench.provenance import cpu, provenance

#: The specialists study's stored runs (``experiments/specialists/data/``) and the predictive controllers' runs over
#: the same plants, which the seeds' tables join.
SPECIALIST_DATA = Path(__file__).resolve().parents[1] / "experiments" / "specialists" / "data"
MPC_BOX = Path(__file__).resolve().parents[1] / "experiments" / "classical-opponents" / "data" / "mpc_box"


def _record(env, policy, max_um, rms_um, kinds, diverged=None, per_noise=None):
    n = len(kinds)
    rec = {
        "env": env,
        "policy": policy,
        "per_plant": {
            "kind": list(kinds),
            "max_um": list(map(float, max_um)),
            "rms_um": list(map(float, rms_um)),
            "diverged": list(diverged if diverged is not None else [False] * n),
        },
    }
    if per_noise is not None:
        rec["per_noise"] = per_noise
    return rec


KINDS = ["nominal"] + ["sample"] * 12 + ["vertex"] * 2


def test_normalised_score_by_hand():
    assert score.normalised_score(10.0, 10.0, 2.0) == 0.0
    assert score.normalised_score(2.0, 10.0, 2.0) == 1.0
    assert score.normalised_score(4.0, 10.0, 2.0) == pytest.approx(0.75)
    assert score.normalised_score(14.0, 10.0, 2.0) == pytest.approx(-0.5)
    assert score.normalised_score(math.inf, 10.0, 2.0) == -math.inf
    assert math.isnan(score.normalised_score(4.0, 2.0, 2.0))  # no room between reference and floor: no scale
    np.testing.assert_allclose(score.normalised_score([10.0, 6.0], [10.0, 20.0], [2.0, 4.0]), [0.0, 0.875])


def test_add_scores_nominal_and_per_plant():
    rng = np.random.default_rng(0)
    base = rng.uniform(1.0, 2.0, len(KINDS))
    ref = _record("E", "pd-ref", 10 * base, 5 * base, KINDS)
    floor = _record("E", "oracle (non-causal)", base, 0.5 * base, KINDS)
    mid = _record("E", "ff-pid", 5.5 * base, 2.75 * base, KINDS)  # half way on every plant
    score.add_scores([ref, floor, mid])
    assert mid["score"]["max"] == pytest.approx(0.5) and mid["score"]["rms"] == pytest.approx(0.5)
    assert ref["score"]["max"] == 0.0 and floor["score"]["max"] == 1.0
    assert mid["score"]["iqm_max"] == pytest.approx([0.5, 0.5, 0.5])
    # the floor only on the nominal plant (its shipped solution): the nominal score, no per-plant IQM
    ref2, mid2 = _record("F", "pd-ref", 10 * base, 5 * base, KINDS), _record("F", "x", 4 * base, base, KINDS)
    score.add_scores([ref2, mid2], {"F": {"max_um": base[0], "rms_um": 0.5 * base[0], "label": "oracle"}})
    assert mid2["score"]["max"] == pytest.approx(6 / 9) and "iqm_max" not in mid2["score"]
    lone = _record("G", "x", base, base, KINDS)
    score.add_scores([lone])
    assert lone["score"] is None and "pd-ref" in lone["score_missing"]


def test_robust_verdicts_pick_the_strongest_per_figure_and_pair_the_plants():
    rng = np.random.default_rng(1)
    plants = rng.lognormal(0.0, 0.8, len(KINDS))
    a = _record("E", "a", plants, 2 * plants, KINDS)  # the strongest on max
    b = _record("E", "b", 1.2 * plants, plants, KINDS)  # the strongest on RMS
    agent = _record("E", "ppo", 0.9 * plants, 1.5 * plants, KINDS)
    rows = verdicts.robust_verdicts([a, b, agent], {"ppo"}, {"a", "b"}, reps=500)
    by = {r["figure"]: r for r in rows}
    assert by["max"]["y"] == "a" and by["max"]["outcome"] == "wins"
    assert by["rms"]["y"] == "b" and by["rms"]["outcome"] == "loses"
    assert by["max"]["n"] == 12  # the sampled plants only
    assert agent["verdicts"]["max"]["outcome"] == "wins"
    assert "verdict" in verdicts.format_verdicts(rows)


def test_sampled_figures_with_noise_seeds():
    k, kinds = 3, ["nominal", "sample", "sample"]
    per_noise = {
        "shape": [k, 3],
        "max_um": [float(i) for i in range(9)],
        "rms_um": [1.0] * 9,
        "diverged": [False] * 8 + [True],
        "completed": [True] * 9,
    }
    rec = _record("E", "x", [0, 1, 2], [1, 1, 1], kinds, per_noise=per_noise)
    x = verdicts.sampled_figures(rec, "max")
    assert x.shape == (2, 3)  # (sampled plants, noise seeds)
    np.testing.assert_array_equal(x[0], [1.0, 4.0, 7.0])
    assert x[1, 2] == np.inf  # diverged


def test_the_cycle_time_is_a_figure_and_an_unfinished_run_is_infinite():
    kinds = ["nominal", "sample", "sample", "sample"]
    rec = _record("E", "x", [1, 2, 3, 4], [1, 1, 1, 1], kinds)
    rec["per_plant"]["cycle_time_s"] = [0.7, 0.8, None, 0.9]  # plant 2 did not arrive
    rec["per_plant"]["diverged"] = [False, False, False, True]
    np.testing.assert_array_equal(verdicts.sampled_figures(rec, "cycle"), [0.8, np.inf, np.inf])
    with pytest.raises(ValueError, match="figure: 'time'"):
        verdicts.sampled_figures(rec, "time")


def test_split_noise_and_summary():
    k, m = 2, 3
    runs = robust.PlantRuns(
        max_um=np.arange(6.0),
        rms_um=np.ones(6),
        cycle_time_s=np.ones(6),
        has_cycle_time=True,
        diverged=np.zeros(6, bool),
        completed=np.ones(6, bool),
        steps=np.ones(6, int),
        trials=1,
        wall_s=1.0,
    )
    first, per = robust.split_noise(runs, k)
    np.testing.assert_array_equal(first.max_um, [0.0, 1.0, 2.0])  # copy 0: envs 0..M-1
    assert per["max_um"].shape == (k, m)
    plants = robust.PlantSet(np.zeros((2, 1)), np.zeros((2, 2, 1)), np.zeros((0, 2, 1)), 0)
    s = robust.noise_summary(per, plants)
    assert s["max"]["nominal_min_um"] == 0.0 and s["max"]["nominal_max_um"] == 3.0
    assert s["max"]["median_spread_um"] == 3.0


def test_noise_seeds_options_are_checked():
    with pytest.raises(SystemExit):
        cli.main(["--env", "VCNC-Heart-v1", "--noise-seeds", "2"])  # without --plants
    with pytest.raises(SystemExit):
        cli.main(["--env", "VCNC-Heart-v1", "--plants", "2", "--noise-seeds", "0"])


def test_provenance(tmp_path):
    info = tmp_path / "cpuinfo"
    info.write_text(
        "processor\t: 0\nmodel name\t: Test CPU 9000\nflags\t\t: sse2 fma avx2\n\n"
        "processor\t: 1\nmodel name\t: Test CPU 9000\nflags\t\t: sse2 fma avx2\n"
    )
    c = cpu(info)
    assert c["model"] == "Test CPU 9000" and c["flags"] == ["avx2", "fma", "sse2"]
    p = provenance()
    assert {"numpy", "numba", "torch", "stable-baselines3", "gymnasium"} <= set(p["libraries"])
    assert p["libraries"]["numpy"] == np.__version__
    assert {"threading_layer", "threading_layer_requested", "opt"} <= set(p["numba"])
    assert set(p["code_paths"]) == {
        "NPY_DISABLE_CPU_FEATURES",
        "OPENBLAS_CORETYPE",
        "ATEN_CPU_CAPABILITY",
        "MKL_ENABLE_INSTRUCTIONS",
        "ONEDNN_MAX_CPU_ISA",
    }
    json.dumps(p)


def test_another_cpus_code_paths_come_from_its_recorded_provenance():
    """``code_paths_of``: a run made on a Zen 3 host (no AVX-512) gives numba its CPU name and features, OpenBLAS
    its Zen kernels and torch AVX2; a CPU without a known OpenBLAS core is said, not guessed; a provenance without
    numba's CPU is refused by name."""

    from vcnc_bench.provenance import code_paths_of

    data = json.loads((SPECIALIST_DATA / "shop_seeds_5" / "VCNC-HeartShop-v1.json").read_text())
    recorded = data["settings"]["provenance"]
    env, left = code_paths_of(recorded)
    assert env["NUMBA_CPU_NAME"] == "znver3" and "-avx512f" in env["NUMBA_CPU_FEATURES"]
    assert env["OPENBLAS_CORETYPE"] == "Zen" and env["ATEN_CPU_CAPABILITY"] == "avx2" and not left
    zen5 = dict(
        recorded,
        numba=dict(recorded["numba"], cpu_name="znver5"),
        cpu=dict(recorded["cpu"], flags=recorded["cpu"]["flags"] + ["avx512f"]),
    )
    env, left = code_paths_of(zen5)
    assert "OPENBLAS_CORETYPE" not in env and "znver5" in left[0] and env["ATEN_CPU_CAPABILITY"] == "avx512"
    with pytest.raises(ValueError, match="cpu_name"):
        code_paths_of({"cpu": recorded["cpu"], "numba": {}})


@pytest.mark.slow
def test_plants_json_carries_scores_verdicts_noise_and_provenance(tmp_path, capsys):
    """End to end on a cheap shop-floor id: pd-ref is added, the floor's nominal replay scores every record, the
    agent gets a verdict per figure, every plant runs over 2 noise seeds, and the JSON is strict."""
    out = tmp_path / "robust.json"
    assert (
        cli.main(
            [
                "--env",
                "VCNC-OmegaLookaheadShop-v1",
                "--plants",
                "3",
                "--noise-seeds",
                "2",
                "--policy",
                "ff-pid",
                "--policy",
                "ppo",
                "--no-progress",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    text = out.read_text()
    assert "Infinity" not in text and "NaN" not in text
    data = json.loads(text)
    labels = [r["policy"] for r in data["robust"]]
    assert labels == ["ff-pid", "ppo", "pd-ref"]
    for r in data["robust"]:
        assert r["per_noise"]["shape"] == [2, 4] and r["noise"]["noise_seeds"] == 2
        assert r["score"]["floor"].endswith("(non-causal)")
    pd = data["robust"][2]
    assert pd["score"]["max"] == 0.0
    assert {v["figure"] for v in data["verdicts"]} == {"max", "rms"}
    assert all(v["x"] == "ppo" and v["y"] == "ff-pid" and v["n"] == 6 for v in data["verdicts"])
    assert data["settings"]["noise_seeds"] == 2 and "provenance" in data["settings"]
    printed = capsys.readouterr().out
    assert "Verdicts" in printed and "Normalised contour score" in printed


def _seed_verdicts():
    from benchmark_script import study_script

    return study_script("specialists", "seed_verdicts")


def test_joined_run_judges_the_seeds_against_a_later_controller():
    """``experiments/specialists/seed_verdicts.py --with``: the sharp corners' five seeds, evaluated before ``mpc`` was in the
    house, meet ``mpc`` from its own run on the same 20 plants; its IQM is checked against scipy's trimmed mean,
    and a run on other plants is refused by name."""

    from scipy.stats import trim_mean

    data_dir = SPECIALIST_DATA
    seeds = json.loads((data_dir / "ideal_seeds_before_mpc" / "VCNC-Corners-v1.json").read_text())
    box = json.loads((MPC_BOX / "VCNC-Corners-v1.json").read_text())
    sv = _seed_verdicts()
    joined = sv.join(seeds, box)
    # the classical controller both runs hold is the same on the same plants: the pairing is plant by plant
    fb = [next(r for r in run["robust"] if r["policy"] == "contouring-fb") for run in (seeds, box)]
    np.testing.assert_allclose(fb[0]["per_plant"]["max_um"], fb[1]["per_plant"]["max_um"], rtol=1e-9)
    rows = {(v["x"], v["figure"]): v for v in joined["verdicts"]}
    seeds_max = rows[("ppo:runs/seeds/VCNC-Corners-v1", "max")]
    assert seeds_max["y"] == "mpc" and seeds_max["training_seeds"] == 5
    mpc = next(r for r in joined["robust"] if r["policy"] == "mpc")
    sampled = [m for m, k in zip(mpc["per_plant"]["max_um"], mpc["per_plant"]["kind"]) if k == "sample"]
    assert seeds_max["iqm_y"] == pytest.approx(trim_mean(sampled, 0.25), rel=1e-12)
    assert seeds_max["outcome"] == "loses" and seeds_max["low"] > 0
    before = {(v["x"], v["figure"]): v["outcome"] for v in seeds["verdicts"]}
    assert before[("ppo:runs/seeds/VCNC-Corners-v1", "max")] == "ties"  # against lq-preview, the strongest then
    other = dict(box, settings=dict(box["settings"], plant_seed=1))
    with pytest.raises(ValueError, match="plant_seed"):
        sv.join(seeds, other)


def test_a_join_restricted_to_some_policies_adds_only_their_records():
    """``--only``: the earlier five-seed run of the sharp corners lends its costly controller (``mpc`` here) and not
    its agents; a policy the other run lacks is named."""

    data_dir = SPECIALIST_DATA
    seeds = json.loads((data_dir / "ideal_seeds_before_mpc" / "VCNC-Corners-v1.json").read_text())
    box = json.loads((MPC_BOX / "VCNC-Corners-v1.json").read_text())
    sv = _seed_verdicts()
    lacking = {r["policy"] for r in box["robust"]} - {r["policy"] for r in seeds["robust"]}
    assert lacking == {"mpc"}  # what a plain join adds
    base = dict(seeds, robust=[r for r in seeds["robust"] if r["policy"] != "lq-preview"])
    joined = sv.join(base, box, only=("mpc",))
    added = [r["policy"] for r in joined["robust"][len(base["robust"]) :]]
    assert added == ["mpc"] and "joined with the mpc of" in joined["settings"]["command"]
    with pytest.raises(ValueError, match="no records of 'ilc'"):
        sv.join(base, box, only=("ilc",))


def test_with_is_repeatable_and_joins_every_file_in_order(tmp_path, capsys):
    """``--with A --with B``: the records each lacks join, A's first, then B's (a later --with replaced an earlier
    one before)."""

    data_dir = SPECIALIST_DATA
    seeds = json.loads((data_dir / "ideal_seeds_before_mpc" / "VCNC-Corners-v1.json").read_text())
    box = json.loads((MPC_BOX / "VCNC-Corners-v1.json").read_text())
    paths = {}
    for name, run, keep in (
        ("base", seeds, lambda p: p != "lq-preview"),
        ("a", box, lambda p: p == "mpc"),
        ("b", seeds, lambda p: p == "lq-preview"),
    ):
        paths[name] = tmp_path / f"{name}.json"
        paths[name].write_text(json.dumps(dict(run, robust=[r for r in run["robust"] if keep(r["policy"])])))
    out = tmp_path / "joined.json"
    assert (
        _seed_verdicts().main(
            [str(paths["base"]), "--with", str(paths["a"]), "--with", str(paths["b"]), "--json", str(out)]
        )
        == 0
    )
    capsys.readouterr()
    policies = [r["policy"] for r in json.loads(out.read_text())["robust"]]
    assert policies[-2:] == ["mpc", "lq-preview"] and policies.count("mpc") == 1


def test_the_seeds_spread_is_the_range_of_their_own_interquartile_means():
    """``--summary``'s spread table: the lowest and highest of the seeds' IQMs over the sampled plants, each checked
    here against scipy's 25 %-trimmed mean of that seed's per-plant figures."""

    from scipy.stats import trim_mean

    data = json.loads((SPECIALIST_DATA / "ideal_seeds_5" / "VCNC-Heart-v1.json").read_text())
    row = next(line for line in _seed_verdicts().spread([data]) if "runs/seeds/VCNC-Heart-v1" in line)
    seeds = [r for r in data["robust"] if r.get("group") == "ppo:runs/seeds/VCNC-Heart-v1"]
    iqms = {
        f: [
            trim_mean([m for m, k in zip(r["per_plant"][f"{f}_um"], r["per_plant"]["kind"]) if k == "sample"], 0.25)
            for r in seeds
        ]
        for f in ("max", "rms")
    }
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert cells[2] == "5"
    for cell, f in zip(cells[3:], ("max", "rms")):
        lo, hi = (float(x) for x in cell.split(" - "))
        assert lo == pytest.approx(min(iqms[f]), rel=1e-3) and hi == pytest.approx(max(iqms[f]), rel=1e-3)


def test_the_changes_table_counts_the_verdicts_an_earlier_run_gave_otherwise():
    """``--summary --before``: the sharp corners' five seeds before ``mpc`` joined (a tie on the max against
    ``lq-preview``) and after (a loss against ``mpc``) is one changed verdict, read from the two JSONs."""

    data_dir = SPECIALIST_DATA
    before, now = (
        json.loads((data_dir / d / "VCNC-Corners-v1.json").read_text())
        for d in ("ideal_seeds_before_mpc", "ideal_seeds_5")
    )
    lines = _seed_verdicts().changes([(before, now)])
    row = next(line for line in lines if line.startswith("| VCNC-Corners-v1 | max |"))
    assert "5, ties (`lq-preview`)" in row and "5, loses (`mpc`)" in row and row.endswith("**yes** |")
    rms = [
        next(v["outcome"] for v in d["verdicts"] if v["training_seeds"] > 1 and v["figure"] == "rms")
        for d in (before, now)
    ]
    assert lines[-1] == f"{1 + (rms[0] != rms[1])} of 2 verdicts changed."


def test_within_counts_the_plants_whose_max_is_within_each_tolerance():
    """``--within``: per policy, the nominal plant's verdict and the count of sampled plants whose max is at most T,
    counted here from the JSON's per-plant figures (a diverged plant never within); a run on the shop floor is
    not paired with one off it, and a JSON written before the setting existed counts as off it."""

    data = json.loads((SPECIALIST_DATA / "shop_seeds" / "VCNC-HeartShop-v1.json").read_text())
    sv = _seed_verdicts()
    rows = {
        line.split("|")[1].strip(" `"): line.split("|")[2:5]
        for line in sv.within(data["robust"], [5, 10, 20])
        if line.startswith("| `")
    }
    for r in data["robust"]:
        if r["policy"] == "pd-ref":
            continue
        per = r["per_plant"]
        for t, cell in zip((5, 10, 20), rows[r["policy"]]):
            count = sum(
                1
                for m, k, d in zip(per["max_um"], per["kind"], per["diverged"])
                if k == "sample" and not d and m is not None and m <= t
            )
            nominal = r["nominal_max_um"] is not None and r["nominal_max_um"] <= t
            assert cell.strip() == f"{'yes' if nominal else 'no'}, {count} of {per['kind'].count('sample')}"
    assert "shop_floor" not in data["settings"]
    sv.join(data, dict(data, settings=dict(data["settings"], shop_floor=False)))  # the same: written before it
    with pytest.raises(ValueError, match="shop_floor"):
        sv.join(data, dict(data, settings=dict(data["settings"], shop_floor=True)))


def test_cross_cpu_counts_the_figures_that_moved_and_the_verdicts_that_changed():
    """``experiments/specialists/cross_cpu.py``: one plant's max moved by 1 % and one verdict flipped, counted as such; labels
    matched after the rename; runs of other plants refused."""
    from benchmark_script import study_script

    cc = study_script("specialists", "cross_cpu")
    kinds = ["nominal", "sample", "sample"]

    def run(cpu, max_um, outcome):
        rec = [
            _record("E", "ppo:A/seed0/best", max_um, [1, 1, 1], kinds),
            _record("E", "zpetc", [1, 2, 3], [1, 1, 1], kinds),
        ]
        v = {
            "x": "ppo:A",
            "y": "zpetc",
            "figure": "max",
            "outcome": outcome,
            "difference": 0.1,
            "low": -0.1,
            "high": 0.3,
        }
        return {"settings": {"provenance": {"numba": {"cpu_name": cpu}}}, "robust": rec, "verdicts": [v]}

    old, new = run("znver4", [1.0, 2.0, 3.0], "ties"), run("znver3", [1.0, 2.02, 3.0], "loses")
    for r in new["robust"] + new["verdicts"]:
        for key in ("policy", "x"):
            if key in r:
                r[key] = r[key].replace("ppo:A", "ppo:B")
    lines = cc.compare(old, new, ("ppo:A", "ppo:B"))
    row = next(line for line in lines if line.startswith("| `ppo:B/seed0/best`"))
    assert [c.strip() for c in row.split("|")[2:6]] == ["3", "1", f"{0.02 / 2.0:.2g}", "0"]
    assert next(line for line in lines if line.startswith("| `zpetc`")).split("|")[3].strip() == "0"
    assert (
        "**yes**" in next(line for line in lines if line.startswith("| `ppo:B` | max"))
        and lines[-1] == "1 of 1 verdicts changed."
    )
    assert "`znver4` (old) against `znver3` (new)" in lines[0]
    new["robust"][1]["per_plant"]["max_um"] = [1, 2]
    with pytest.raises(ValueError, match="not the same run"):
        cc.compare(old, new, ("ppo:A", "ppo:B"))


def test_a_joined_floor_scores_every_record_plant_by_plant():
    """``--with`` a floor's own ``--plants`` run (``vcnc-bench --policy oracle``: minutes a plant, run apart from the
    agents): every record's score is then per plant, its IQM scipy's trimmed mean of (ref - e) / (ref - floor) over
    the sampled plants, and the table gets the score column; a join without a floor leaves the scores as they were."""
    from scipy.stats import trim_mean

    rng = np.random.default_rng(3)
    base = rng.uniform(1.0, 2.0, len(KINDS))
    settings = {"command": "vcnc-bench --plants 12", "plants": 12, "plant_seed": 0, "seed": 0}
    agents = [
        _record("E", "pd-ref", 10 * base, 5 * base, KINDS),
        _record("E", "ff-pid", 4 * base, 2 * base, KINDS),
        _record("E", "ppo:run/seed0/best", 3 * base + 0.1 * rng.random(len(KINDS)), base, KINDS),
    ]
    agents[1]["kind"], agents[2]["kind"] = "baseline", "ppo"
    for r in agents:
        r["score"] = {"max": 0.5}  # the bench's nominal score, from the shipped nominal floor
    floor = _record("E", "oracle (non-causal)", base, 0.5 * base, KINDS)
    floor["kind"] = "baseline"
    sv = _seed_verdicts()
    unchanged = sv.join(
        {"settings": settings, "robust": agents[:2], "verdicts": []},
        {"settings": settings, "robust": agents[2:], "verdicts": []},
    )
    assert all(r["score"] == {"max": 0.5} for r in unchanged["robust"])
    joined = sv.join(
        {"settings": settings, "robust": agents, "verdicts": []},
        {"settings": settings, "robust": [floor], "verdicts": []},
        only=("oracle (non-causal)",),
    )
    sampled = np.array(KINDS) == "sample"
    for r in joined["robust"]:
        e = np.array(r["per_plant"]["max_um"])
        expected = trim_mean(((10 * base - e) / (9 * base))[sampled], 0.25)
        assert r["score"]["iqm_max"][0] == pytest.approx(expected, rel=1e-12)
    assert agents[1]["score"] == {"max": 0.5}  # the inputs are not changed
    for r in joined["robust"]:  # the figures a --plants record carries beside its per-plant ones
        x = np.array(r["per_plant"]["max_um"]), np.array(r["per_plant"]["rms_um"])
        for k, v in zip(("max", "rms"), x):
            r[f"nominal_{k}_um"], r[f"median_{k}_um"], r[f"worst_{k}_um"] = v[0], np.median(v[1:]), v.max()
    lines = sv.tables(joined, "ff-pid")
    assert "score of the max" in lines[2] and lines[4].startswith("| `ff-pid`") and lines[4].count("|") == 6


def test_the_tables_name_the_causal_controllers_a_run_did_not_hold():
    """A verdict weighs the strongest causal controller among those that ran: the shop-floor heart's 5-seed run
    holds ``ff-pid@machine`` but not ``zpetc@machine``, which is stronger there on the max (an IQM of 5.96 against
    6.06 um over the same plants, ``experiments/adaptive/README.md``, "Every causal controller and the floor over the box");
    the tables say so.  Neither the reference PD (never a start of the floor) nor ``mpcc`` (it sets a feed
    override) is asked for, and an unregistered id asks for none."""

    data_dir = SPECIALIST_DATA
    run = json.loads((data_dir / "shop_seeds_5" / "VCNC-HeartShop-v1.json").read_text())
    sv = _seed_verdicts()
    present = {r["policy"] for r in run["robust"]}
    absent = sv.not_run("VCNC-HeartShop-v1", present)
    assert "zpetc@machine" in absent and "ff-ccc@machine" in absent
    assert not {"ff-pid@machine", "pd-ref", "mpcc", "oracle"} & set(absent)
    assert sv.not_run("VCNC-HeartShop-v1", present | set(absent)) == []
    assert sv.not_run("E", set()) == []
    assert "ilc" not in sv.not_run("VCNC-CornersSmoothShop-v1", {"ilc (trial 10)"})
    assert any("`zpetc@machine`" in line for line in sv.tables(run, "ff-ccc"))
