"""vcnc_bench.verdicts against rliable (Agarwal et al., 2021), scipy and computations written here.

rliable 1.2.0's metrics (``rliable.metrics``: the IQM, the probability of improvement) are imported and compared
exactly.  Its bootstrap (``rliable.library``) subclasses ``arch``'s, and no ``arch`` release imports with this
venv's pandas 3 (arch 7.2, the last rliable allows, fails on pandas' ``deprecate_kwarg``; arch 8 drops the
``random_state`` keyword rliable passes): the intervals are checked against ``scipy.stats.bootstrap`` (percentile
method) within bootstrap noise and, draw for draw, against rliable's stratified scheme written out here.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from vcnc_bench import verdicts as v

rliable_metrics = pytest.importorskip("rliable.metrics")


def _data(seed=3, runs=20, tasks=3):
    rng = np.random.default_rng(seed)
    return rng.lognormal(mean=1.0, sigma=0.6, size=(runs, tasks))


@pytest.mark.parametrize("shape", [(20, 3), (7, 1), (5, 4), (101, 2)])
def test_iqm_is_rliables(shape):
    x = _data(runs=shape[0], tasks=shape[1])
    assert v.iqm(x) == pytest.approx(rliable_metrics.aggregate_iqm(x), rel=1e-12, abs=0)
    assert v.iqm(x) == pytest.approx(scipy.stats.trim_mean(x, 0.25, axis=None), rel=1e-12, abs=0)
    np.testing.assert_allclose(v.iqm(x, axis=0), scipy.stats.trim_mean(x, 0.25, axis=0), rtol=1e-12)


def test_iqm_by_hand():
    # 8 values: drop 2 at each end, the mean of the 4 in the middle
    assert v.iqm([9.0, 1.0, 100.0, 3.0, 4.0, 5.0, 6.0, -50.0]) == pytest.approx((3 + 4 + 5 + 6) / 4, rel=1e-15)
    assert v.iqm([1.0, 2.0, 3.0, np.inf]) == pytest.approx(2.5)  # 1 of 4 dropped per end: inf drops out


def test_ci_matches_scipy_bootstrap_within_bootstrap_noise():
    """One task: the stratified bootstrap is the plain one.  scipy's percentile interval of the 25 % trimmed mean
    at the same reps, another generator: the endpoints agree within the replicates' noise (a percentile of 2000
    replicates moves by ~2 % of the interval's width between seeds; 10 % allowed)."""
    x = _data(runs=15, tasks=1)[:, 0]
    reps = 2000
    point, low, high = v.stratified_bootstrap_ci(x, reps=reps, seed=1)
    ref = scipy.stats.bootstrap(
        (x,),
        lambda s, axis: scipy.stats.trim_mean(s, 0.25, axis=axis),
        n_resamples=reps,
        method="percentile",
        random_state=np.random.default_rng(7),
    )
    assert point == pytest.approx(scipy.stats.trim_mean(x, 0.25), rel=1e-12)
    width = high - low
    assert width > 0
    assert low == pytest.approx(ref.confidence_interval.low, abs=0.1 * width)
    assert high == pytest.approx(ref.confidence_interval.high, abs=0.1 * width)


def test_ci_by_hand_is_the_same_draws():
    """rliable's ``StratifiedBootstrap.update_indices`` (a run index drawn for every (run, task) cell, so the runs
    are resampled within each task independently) as a loop, with the same generator's draws: the vectorised
    replicates and the percentile interval are the loop's."""
    x = _data(runs=9, tasks=2)
    reps, seed = 300, 5
    rng = np.random.default_rng(seed)
    rows = rng.integers(0, 9, size=(reps, 9, 2))
    values = np.array(
        [
            scipy.stats.trim_mean(np.stack([x[rows[r, :, j], j] for j in range(2)], 1), 0.25, axis=None)
            for r in range(reps)
        ]
    )
    lo, hi = np.percentile(values, [2.5, 97.5])
    _, low, high = v.stratified_bootstrap_ci(x, reps=reps, seed=seed)
    assert (low, high) == pytest.approx((lo, hi), rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_probability_of_improvement_is_rliables_on_negated_errors(seed):
    x, y = _data(seed, runs=12, tasks=3), _data(seed + 10, runs=9, tasks=3)
    y[:3, 0] = x[:3, 0]  # ties across the two
    assert v.probability_of_improvement(x, y) == rliable_metrics.probability_of_improvement(-x, -y)
    # lower is better: a controller with every error lower improves with probability 1
    assert v.probability_of_improvement(x, x + x.max()) == 1.0
    assert v.probability_of_improvement(x + x.max(), x) == 0.0
    assert v.probability_of_improvement(x, x) == 0.5


def test_paired_difference_ci_by_hand_and_the_rule():
    rng = np.random.default_rng(0)
    plants = rng.lognormal(1.0, 1.0, 30)  # a spread both controllers share
    y = plants
    x = plants * 0.97  # 3 % better on every plant
    d, low, high = v.paired_difference_ci(x, y, reps=1000, seed=2)
    assert d == pytest.approx(v.iqm(x) - v.iqm(y), rel=1e-12)
    assert high < 0 and v.decide(low, high) == "wins"
    # by hand: the same plant indices for both
    idx = np.random.default_rng(2).integers(0, 30, size=(1000, 30))
    diffs = scipy.stats.trim_mean(x[idx], 0.25, axis=1) - scipy.stats.trim_mean(y[idx], 0.25, axis=1)
    assert (low, high) == pytest.approx(tuple(np.percentile(diffs, [2.5, 97.5])), rel=1e-12)
    # unpaired, the shared spread would hide the same 3 %: the two IQM intervals overlap
    _, xl, xh = v.stratified_bootstrap_ci(x, reps=1000, seed=2)
    _, yl, yh = v.stratified_bootstrap_ci(y, reps=1000, seed=3)
    assert xh > yl
    # noise on top of a zero difference: a tie; the reverse: a loss
    noisy = plants * (1.0 + 0.05 * rng.standard_normal(30))
    assert v.verdict(noisy, plants, figure="max", x_label="x", y_label="y").outcome == "ties"
    assert v.verdict(plants * 1.05, plants, figure="max", x_label="x", y_label="y").outcome == "loses"


def test_paired_with_noise_seeds_and_infinite_errors():
    rng = np.random.default_rng(1)
    y = rng.lognormal(1.0, 0.5, (12, 4))
    x = y - 0.1
    out = v.verdict(x, y, figure="rms", x_label="a", y_label="b", reps=500)
    assert out.outcome == "wins" and out.n == 48 and out.paired_fraction == 1.0
    x[0, :] = np.inf  # x diverged on one plant: not a win anymore
    assert v.verdict(x, y, figure="rms", x_label="a", y_label="b", reps=500).outcome != "wins"
    assert out.to_dict()["outcome"] == "wins"


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="x and y must be paired"):
        v.paired_difference_ci(np.ones(3), np.ones(4))
    with pytest.raises(ValueError, match="reps"):
        v.stratified_bootstrap_ci(np.ones(3), reps=0)
    with pytest.raises(ValueError, match="confidence"):
        v.stratified_bootstrap_ci(np.ones(3), confidence=1.5)
    with pytest.raises(ValueError, match="NaN"):
        v.paired_difference_ci(np.array([1.0, np.nan]), np.ones(2))


def test_own_interval_resamples_plants_not_runs():
    """With noise seeds the runs of one plant are not independent: a controller's own interval resamples plants
    (then seeds within them), so copying every run K times does not narrow it (a bootstrap over the K N runs as if
    independent would, by about sqrt(K))."""
    rng = np.random.default_rng(4)
    y = rng.lognormal(1.0, 0.8, 15)
    one = v.verdict(y * 0.9, y, figure="max", x_label="a", y_label="b", reps=2000, seed=1)
    five = v.verdict(
        np.repeat((y * 0.9)[:, None], 5, 1),
        np.repeat(y[:, None], 5, 1),
        figure="max",
        x_label="a",
        y_label="b",
        reps=2000,
        seed=1,
    )
    w1, w5 = one.ci_y[1] - one.ci_y[0], five.ci_y[1] - five.ci_y[0]
    assert w5 == pytest.approx(w1, rel=0.25)


# -- training seeds (issue 33): a learned controller is the draw of its training run as much as of the plant --------
def test_training_seeds_are_resampled_with_the_plants_by_hand():
    """X of 3 training seeds on the same 20 plants: each replicate draws the plants (shared with Y), then the
    seeds (with replacement); the interval is the percentiles of the IQMs' differences, recomputed here from the
    same generator with scipy's trim_mean."""
    rng = np.random.default_rng(5)
    plants = rng.lognormal(1.0, 0.6, 20)
    x = plants[None, :] * np.array([0.9, 1.0, 1.1])[:, None]  # three training runs: one good, one even, one poor
    d, low, high = v.paired_difference_ci(x[:, :, None], plants, reps=800, seed=3)  # (seeds, plants, 1 noise seed)
    gen = np.random.default_rng(3)
    p_idx = gen.integers(0, 20, size=(800, 20))
    s_idx = gen.integers(0, 3, size=(800, 3))
    xa = np.stack([x[s_idx[r]][:, p_idx[r]].reshape(-1) for r in range(800)])
    diffs = scipy.stats.trim_mean(xa, 0.25, axis=1) - scipy.stats.trim_mean(plants[p_idx], 0.25, axis=1)
    assert (low, high) == pytest.approx(tuple(np.percentile(diffs, [2.5, 97.5])), rel=1e-12)
    assert d == pytest.approx(scipy.stats.trim_mean(x.reshape(-1), 0.25) - scipy.stats.trim_mean(plants, 0.25))


def test_one_training_seed_gives_the_interval_it_gave_without_the_axis():
    rng = np.random.default_rng(6)
    y = rng.lognormal(1.0, 0.5, (10, 3))
    x = y * 0.95
    assert v.paired_difference_ci(x[None], y, seed=4) == v.paired_difference_ci(x, y, seed=4)


def test_a_seed_that_failed_its_training_keeps_a_win_from_being_declared():
    """Four seeds 5 % better on every plant win; a fifth that diverged on a third of the plants makes it no win:
    the seeds are resampled, so a poor training run cannot hide behind the good ones."""
    rng = np.random.default_rng(7)
    y = rng.lognormal(1.0, 0.5, 24)
    good = np.repeat((y * 0.95)[None, :, None], 4, axis=0)  # (seeds, plants, 1 noise seed)
    assert v.verdict(good, y, figure="max", x_label="a", y_label="b").outcome == "wins"
    bad = y * 0.95
    bad[::3] = np.inf
    out = v.verdict(np.vstack([good, bad[None, :, None]]), y, figure="max", x_label="a", y_label="b")
    assert out.outcome != "wins" and out.n == 5 * 24


def _record(policy, max_um, group=None):
    rec = {
        "env": "E",
        "policy": policy,
        "per_plant": {
            "kind": ["nominal"] + ["sample"] * len(max_um),
            "max_um": [1.0, *max_um],
            "rms_um": [0.1, *(m / 10 for m in max_um)],
            "diverged": [False] * (len(max_um) + 1),
        },
    }
    if group is not None:
        rec["group"] = group
    return rec


def test_the_bench_judges_the_seeds_of_one_run_as_one_controller():
    rng = np.random.default_rng(8)
    y = rng.lognormal(1.0, 0.5, 16)
    records = [_record("ff-pid", y)] + [
        _record(f"ppo:run/seed{s}/best", y * f, group="ppo:run") for s, f in enumerate((0.9, 0.92, 0.95))
    ]
    rows = v.robust_verdicts(records, {r["policy"] for r in records[1:]}, {"ff-pid"}, reps=500)
    assert [(r["x"], r["figure"], r["training_seeds"], r["outcome"]) for r in rows] == [
        ("ppo:run", "max", 3, "wins"),
        ("ppo:run", "rms", 3, "wins"),
    ]
    assert all(r["verdicts"]["max"]["x"] == "ppo:run" for r in records[1:])
    expected = v.verdict(
        np.stack([y * 0.9, y * 0.92, y * 0.95])[:, :, None],
        y,
        figure="max",
        x_label="ppo:run",
        y_label="ff-pid",
        reps=500,
    )
    assert rows[0]["low"] == expected.low and rows[0]["high"] == expected.high
    assert "ppo:run (3 seeds)" in v.format_verdicts(rows)


def test_a_y_with_training_seeds_is_resampled_after_everything_else():
    """An ablation's variant against its agent: both with seeds.  Y's seeds are drawn after the plants, the noise
    and X's seeds, so a Y of one training seed gives exactly the intervals it gave as a plain (plants, noise)
    array; a Y that is X shifted by 1 um is judged 1 um worse at its point estimate, with X's and Y's seeds
    drawn independently (the interval is wider than the plants' alone); X against itself ties at 0."""
    from vcnc_bench.verdicts import paired_difference_ci, verdict

    rng = np.random.default_rng(5)
    x = rng.lognormal(0.0, 0.3, size=(4, 30, 3))
    y = rng.lognormal(0.1, 0.3, size=(30, 3))
    assert paired_difference_ci(x, y[None], reps=500) == paired_difference_ci(x, y, reps=500)
    assert verdict(x, y[None], figure="max", x_label="x", y_label="y", reps=500) == verdict(
        x, y, figure="max", x_label="x", y_label="y", reps=500
    )
    d, low, high = paired_difference_ci(x, x + 1.0, reps=500)
    assert d == pytest.approx(-1.0) and low < -1.0 < high
    same = verdict(x, x.copy(), figure="max", x_label="x", y_label="x", reps=500)
    assert same.difference == 0.0 and same.outcome == "ties"
    with pytest.raises(ValueError, match="paired"):
        paired_difference_ci(x, np.stack([y[:29]] * 2))
