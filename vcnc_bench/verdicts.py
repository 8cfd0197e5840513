"""Interval estimates and the one rule for a verdict: the IQM, stratified-bootstrap intervals, P(X < Y).

The estimators are Agarwal et al. (NeurIPS 2021)'s ("Deep reinforcement learning at the edge of the statistical
precipice", the ``rliable`` library), written here in vectorised numpy and checked against ``rliable``'s on the
same data (``tests/test_verdicts.py``):

- :func:`iqm`, the interquartile mean: the mean of the middle half of the scores, ``scipy.stats.trim_mean(x,
  0.25)`` over every score (``int(0.25 n)`` dropped at each end);
- :func:`stratified_bootstrap_ci`, the percentile stratified-bootstrap interval of a statistic of a score matrix
  (runs x tasks): every replicate resamples the runs *within each task* independently, with replacement;
  the interval is the (2.5 %, 97.5 %) percentiles (numpy's linear interpolation) of the replicates;
- :func:`probability_of_improvement`, ``P(X < Y)``: the Mann-Whitney U statistic over all pairs of runs of a task
  (ties count one half), averaged over tasks.  **Lower is better** here (the figures are errors), so it is
  rliable's ``probability_of_improvement(-X, -Y)``: the chance that X's error on a random run is *below* Y's
  on another.

The verdict (:func:`verdict`)
-----------------------------
A learned controller X is set against the strongest causal controller Y of the same id on the **same plants**
(and, on a noisy sensor, the same sensor-noise seeds: the envs' noise generators are seeded from the reset seed,
so both meet the same noise).  The data are paired, so the interval is a **paired bootstrap of the difference**
``IQM(X) - IQM(Y)`` (um): each replicate draws one set of plant indices (with replacement) and, within each drawn
plant, one set of noise-seed indices, and applies the *same* indices to X and to Y
(:func:`paired_difference_ci`).  Pairing removes the plant-to-plant spread both controllers share (a stiff plant
is easy for both) from the difference's interval: an unpaired bootstrap of two IQMs on the same 20 plants would
count that spread twice and call most real differences ties.  The point estimate is the difference of the IQMs
on the data as measured.  Then

- X **wins** the figure when the 95 % interval lies below zero (X's error is lower),
- X **loses** it when the interval lies above zero,
- else it **ties**.

A plant on which a controller diverged counts as an infinite error (:mod:`vcnc_bench.robust`); the interval's
endpoints may then be infinite, and the rule reads them as such (an infinite upper bound never wins).

Every function is seeded (``seed``: numpy's ``default_rng``), vectorised over the replicates and validated by
:mod:`vcnc_gym.validation`'s checks.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from vcnc_gym.validation import integer

__all__ = [
    "REPS",
    "CONFIDENCE",
    "iqm",
    "stratified_bootstrap_ci",
    "probability_of_improvement",
    "paired_difference_ci",
    "Verdict",
    "verdict",
    "decide",
    "FIGURE_KEYS",
    "sampled_figures",
    "seed_figures",
    "strongest",
    "robust_verdicts",
    "format_verdicts",
]

#: Bootstrap replicates by default: Agarwal et al.'s figures use 2 000 for the intervals of their tables (50 000 in
#: rliable's default); at 2 000 the endpoints of a 95 % percentile interval move by about 1 % of its width from
#: seed to seed, and a bench verdict costs milliseconds.
REPS = 2000

#: The intervals' coverage.
CONFIDENCE = 0.95


def _scores(name: str, x, ndim: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim not in ndim or a.size == 0:
        raise ValueError(
            f"{name} must be a non-empty array with {' or '.join(map(str, ndim))} dimensions, got shape {a.shape}"
        )
    if np.isnan(a).any():
        raise ValueError(f"{name} holds NaN (a diverged plant is +inf, never NaN)")
    return a


def iqm(x, axis=None) -> np.ndarray | float:
    """The interquartile mean of ``x`` (any units; um here): the mean after dropping ``int(0.25 n)`` of the
    lowest and of the highest values, over every value (``axis=None``, as rliable's ``aggregate_iqm``) or along
    ``axis``.  An infinite value inside the middle half makes it infinite."""
    a = np.asarray(x, dtype=np.float64)
    if axis is None:
        a, axis = a.reshape(-1), 0
    a = np.sort(a, axis=axis)
    n = a.shape[axis]
    if n == 0:
        raise ValueError("x must hold at least one value")
    cut = int(0.25 * n)
    middle = np.take(a, np.arange(cut, n - cut), axis=axis)
    with np.errstate(invalid="ignore"):
        out = middle.mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def _percentiles(replicates: np.ndarray, confidence: float) -> tuple[float, float]:
    """The (1 - c)/2 and (1 + c)/2 percentiles of ``replicates`` (1-D), numpy's linear interpolation, with an
    infinite neighbour the outer of the two (numpy's interpolation gives NaN there); a wider interval, never a
    narrower one."""
    s = np.sort(replicates)
    out = []
    for q, outer in (((1.0 - confidence) / 2.0, 0), ((1.0 + confidence) / 2.0, 1)):
        h = (s.size - 1) * q
        lo, hi = math.floor(h), math.ceil(h)
        a, b, t = float(s[lo]), float(s[hi]), h - lo
        if a == b or t == 0.0:
            out.append(a)
        elif math.isfinite(a) and math.isfinite(b):
            out.append(a + t * (b - a))
        else:  # an infinite neighbour: the outer one (the wider interval)
            out.append((a, b)[outer])
    return out[0], out[1]


def _confidence(confidence: float) -> float:
    c = float(confidence)
    if not 0.0 < c < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    return c


def stratified_bootstrap_ci(
    scores, statistic=iqm, *, reps: int = REPS, seed: int = 0, confidence: float = CONFIDENCE
) -> tuple[float, float, float]:
    """Point estimate and percentile stratified-bootstrap interval of ``statistic`` on a score matrix.

    Parameters
    ----------
    scores : array_like, (runs,) or (runs, tasks)
        One column per task (an id), one row per run (a plant, a training seed); a 1-D array is one task.
    statistic : callable
        Of a (reps, runs, tasks) array along axes (1, 2) when it accepts ``axis`` (as :func:`iqm`), else called
        on each replicate's (runs, tasks) matrix.
    reps : int
        Replicates, >= 1.
    seed : int
        Of ``numpy.random.default_rng``: the same seed, the same interval.
    confidence : float
        Coverage, in (0, 1).

    Returns
    -------
    (point, low, high) : floats, in the scores' unit
    """
    a = _scores("scores", scores, (1, 2))
    a = a[:, None] if a.ndim == 1 else a
    reps = integer("reps", reps, 1)
    confidence = _confidence(confidence)
    runs, tasks = a.shape
    rng = np.random.default_rng(integer("seed", seed, 0))
    rows = rng.integers(0, runs, size=(reps, runs, tasks))  # within each task (column), independently
    resampled = a[rows, np.arange(tasks)[None, None, :]]
    if statistic is iqm:
        values = iqm(resampled.reshape(reps, -1), axis=1)
    else:
        values = np.array([statistic(r) for r in resampled], dtype=np.float64)
    low, high = _percentiles(np.asarray(values, dtype=np.float64), confidence)
    return float(statistic(a)), low, high


def probability_of_improvement(x, y) -> float:
    """``P(X < Y)`` for errors (lower is better): per task (column), the fraction of the pairs (a run of X, a run
    of Y) in which X's error is the lower, ties counted one half (the Mann-Whitney U statistic over
    ``runs_x * runs_y``); averaged over tasks.  ``x`` (runs_x,) or (runs_x, tasks), ``y`` likewise with the same
    tasks.  Equal to rliable's ``probability_of_improvement(-x, -y)``, to the last bit for finite data."""
    a, b = _scores("x", x, (1, 2)), _scores("y", y, (1, 2))
    a, b = (a[:, None] if a.ndim == 1 else a), (b[:, None] if b.ndim == 1 else b)
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"x and y must have the same tasks (columns), got {a.shape[1]} and {b.shape[1]}")
    out = []
    for j in range(a.shape[1]):
        xa, yb = a[:, j], b[:, j]
        if xa.shape == yb.shape and np.array_equal(xa, yb):
            out.append(0.5)  # rliable's convention for identical columns
            continue
        less = (xa[:, None] < yb[None, :]).sum() + 0.5 * (xa[:, None] == yb[None, :]).sum()
        out.append(float(less) / (xa.size * yb.size))
    return float(np.mean(out))


def _runs(name: str, x) -> np.ndarray:
    """``x`` as (training seeds, plants, noise seeds): (plants,) and (plants, noise) are one training seed; a 3-D
    array is several, each on the same plants and noise seeds."""
    a = _scores(name, x, (1, 2, 3))
    a = a[:, None] if a.ndim == 1 else a
    return a[None] if a.ndim == 2 else a


def paired_difference_ci(
    x, y, statistic=iqm, *, reps: int = REPS, seed: int = 0, confidence: float = CONFIDENCE
) -> tuple[float, float, float]:
    """The paired bootstrap of ``statistic(X) - statistic(Y)`` (see the module docstring).

    Parameters
    ----------
    x : array_like, (plants,), (plants, noise_seeds) or (training_seeds, plants, noise_seeds)
        The learned controller's figures; with a leading axis, one row per training seed, each on the same
        plants and noise seeds.  Each replicate resamples the training seeds too (with replacement, independently
        of the plants): a learned controller is its training run's draw as much as the plant is the box's.
    y : array_like, (plants,), (plants, noise_seeds) or (training_seeds, plants, noise_seeds)
        The classical controller's figures on the same plants (rows) and sensor-noise seeds (columns); with a
        leading axis, another learned controller's seeds (an ablation against its agent), resampled as ``x``'s and
        independently of them.
    statistic : callable
        :func:`iqm` (vectorised over the replicates) or any function of an array (called per replicate).

    Returns
    -------
    (difference, low, high) : floats
        ``statistic(x) - statistic(y)`` and its interval; negative: X is the lower.
    """
    a, b = _runs("x", x), _runs("y", y)
    if a.shape[1:] != b.shape[1:]:
        raise ValueError(
            f"x and y must be paired: the same plants and noise seeds, got shapes {np.shape(x)} and {np.shape(y)}"
        )
    reps = integer("reps", reps, 1)
    confidence = _confidence(confidence)
    _, n, k = a.shape
    rng = np.random.default_rng(integer("seed", seed, 0))
    plants = rng.integers(0, n, size=(reps, n))[:, :, None]
    noise = rng.integers(0, k, size=(reps, n, k)) if k > 1 else np.zeros((reps, n, 1), dtype=np.int64)
    # drawn after the plants and noise, so that one training seed gives the intervals it gave before the axis existed
    ra = a[_seed_draws(rng, a, reps)[:, :, None, None], plants[:, None], noise[:, None]].reshape(reps, -1)
    rb = b[_seed_draws(rng, b, reps)[:, :, None, None], plants[:, None], noise[:, None]].reshape(reps, -1)
    if statistic is iqm:
        sa, sb = iqm(ra, axis=1), iqm(rb, axis=1)
    else:
        sa = np.array([statistic(r) for r in ra], dtype=np.float64)
        sb = np.array([statistic(r) for r in rb], dtype=np.float64)
    diff = _difference(np.asarray(sa), np.asarray(sb))
    low, high = _percentiles(diff, confidence)
    return float(_difference(np.float64(statistic(a)), np.float64(statistic(b)))), low, high


def _seed_draws(rng, runs: np.ndarray, reps: int) -> np.ndarray:
    """(reps, S) training seeds drawn with replacement for each replicate of ``runs`` (S, plants, noise); no draw
    (zeros) for one seed."""
    trained = runs.shape[0]
    return rng.integers(0, trained, size=(reps, trained)) if trained > 1 else np.zeros((reps, 1), dtype=np.int64)


def _difference(a, b):
    """``a - b`` with equal values (two infinities included) giving 0."""
    with np.errstate(invalid="ignore"):
        return np.where(a == b, 0.0, a - b)


def decide(low: float, high: float) -> str:
    """The rule: ``"wins"`` when the interval of X - Y (errors) lies below zero, ``"loses"`` above, else
    ``"ties"``."""
    if high < 0.0:
        return "wins"
    if low > 0.0:
        return "loses"
    return "ties"


@dataclass(frozen=True)
class Verdict:
    """X against Y on one figure (max or RMS contour error, um), by :func:`verdict`.

    Attributes
    ----------
    figure : str
        ``"max"`` or ``"rms"``.
    x, y : str
        Labels: the learned controller, the strongest causal one.
    iqm_x, iqm_y : float
        um.
    ci_x, ci_y : (float, float)
        Each one's own bootstrap interval of the IQM, um, resampling plants and, within each, noise seeds (for
        the table; the verdict reads the paired interval of the difference).
    difference, low, high : float
        ``IQM(X) - IQM(Y)`` and its paired-bootstrap 95 % interval, um.
    p_improvement : float
        ``P(X < Y)`` over all pairs of (plant, noise seed) runs (:func:`probability_of_improvement`).
    paired_fraction : float
        The fraction of the (plant, noise seed) pairs on which X's error is the lower (ties one half).
    n : int
        Paired runs.
    reps, seed : int
        Of the bootstrap.
    outcome : str
        ``"wins"``, ``"ties"`` or ``"loses"`` (:func:`decide`).
    """

    figure: str
    x: str
    y: str
    iqm_x: float
    iqm_y: float
    ci_x: tuple
    ci_y: tuple
    difference: float
    low: float
    high: float
    p_improvement: float
    paired_fraction: float
    n: int
    reps: int
    seed: int
    outcome: str

    def to_dict(self) -> dict:
        """JSON-ready (an infinite endpoint as None)."""

        def safe(v):
            if isinstance(v, float):
                return v if math.isfinite(v) else None
            if isinstance(v, tuple):
                return [safe(e) for e in v]
            return v

        return {k: safe(v) for k, v in asdict(self).items()}


def verdict(
    x, y, *, figure: str, x_label: str, y_label: str, reps: int = REPS, seed: int = 0, confidence: float = CONFIDENCE
) -> Verdict:
    """The verdict of X (a learned controller) against Y (the strongest causal controller) on one figure.

    ``x``: (plants,) or (plants, noise_seeds) errors (um), or (training_seeds, plants, noise_seeds) for an agent
    trained from several seeds; ``y``: the same shapes, on the same plants and noise seeds (with seeds: another
    agent, e.g. an ablation's variant against the agent it varies).
    """
    a, b = _runs("x", x), _runs("y", y)
    d, low, high = paired_difference_ci(a, b, reps=reps, seed=seed, confidence=confidence)
    # each one's own interval by the same resampling (training seeds, plants, then noise seeds within a plant): the
    # runs of one plant are not independent draws
    zero = np.zeros_like(b[0])
    _, xl, xh = paired_difference_ci(a, zero, reps=reps, seed=seed, confidence=confidence)
    _, yl, yh = paired_difference_ci(b, zero, reps=reps, seed=seed, confidence=confidence)
    fa, fb = a.reshape(-1), b.reshape(-1)
    # every training seed of X against every one of Y, on the same plant and noise
    paired = float(np.mean((a[:, None] < b[None]) + 0.5 * (a[:, None] == b[None])))
    return Verdict(
        figure,
        x_label,
        y_label,
        iqm(a),
        iqm(b),
        (xl, xh),
        (yl, yh),
        d,
        low,
        high,
        probability_of_improvement(fa, fb),
        paired,
        int(fa.size),
        int(reps),
        int(seed),
        decide(low, high),
    )


# -- the bench's verdicts (vcnc-bench --plants N) ---------------------------------------------------------------
#: A robust record's figures by name, and their keys in its ``per_plant``: max and RMS contour error (um), and the
#: cycle time (s; an unfinished run's is None, counted as infinite like a diverged run's).
FIGURE_KEYS = {"max": "max_um", "rms": "rms_um", "cycle": "cycle_time_s"}


def sampled_figures(rec: dict, figure: str) -> np.ndarray:
    """A robust record's figure (``"max"``, ``"rms"``: um; ``"cycle"``: s) on its sampled plants, (N,) or, with
    sensor-noise seeds, (N, K): a diverged run infinite, and an unfinished run's cycle time too.  The nominal plant
    and the box's vertices are left out: the bootstrap resamples random draws, and the vertices are not."""
    if figure not in FIGURE_KEYS:
        raise ValueError(f"figure: {figure!r} is none of {', '.join(FIGURE_KEYS)}")
    sampled = np.array(rec["per_plant"]["kind"]) == "sample"
    if "per_noise" in rec:
        if figure == "cycle":
            raise ValueError(
                f"figure: the record of {rec['policy']!r} has sensor-noise seeds, whose cycle times "
                "are not kept; judge its max or rms"
            )
        shape = tuple(rec["per_noise"]["shape"])
        x = np.array([np.inf if v is None else v for v in rec["per_noise"][f"{figure}_um"]]).reshape(shape)
        x = np.where(np.array(rec["per_noise"]["diverged"], dtype=bool).reshape(shape), np.inf, x)
        return x[:, sampled].T
    per = rec["per_plant"]
    x = np.array([np.inf if v is None else v for v in per[FIGURE_KEYS[figure]]], dtype=np.float64)
    return np.where(np.array(per["diverged"], dtype=bool), np.inf, x)[sampled]


def seed_figures(records: list[dict], figure: str) -> np.ndarray:
    """The figure of the records of one controller's training seeds (each on the same plants and noise seeds),
    (seeds, plants, noise seeds): the ``x`` of :func:`verdict` for a controller trained from several seeds."""
    return np.stack([_runs("x", sampled_figures(r, figure))[0] for r in records])


def strongest(records: list[dict], figure: str, candidates) -> dict | None:
    """The record among ``candidates`` (labels) with the least IQM of ``figure`` over the sampled plants (ties:
    the least IQM of the other figure); None if there is none."""
    other = "rms" if figure == "max" else "max"
    pool = [r for r in records if r["policy"] in candidates]
    if not pool:
        return None
    return min(pool, key=lambda r: (iqm(sampled_figures(r, figure)), iqm(sampled_figures(r, other))))


def robust_verdicts(records: list[dict], learned, causal, *, reps: int = REPS, seed: int = 0) -> list[dict]:
    """Per env, every learned controller (records with a label in ``learned``) against the strongest causal
    controller (the best IQM among the labels in ``causal``, chosen per figure, so each figure meets its own
    strongest opponent), by :func:`verdict` on the sampled plants (and noise seeds).  Records that share a
    ``"group"`` (the agents of one training run's seeds: ``vcnc-bench --policy ppo:FOLDER`` of a
    ``vcnc-train --seeds`` folder) are one controller, its training seeds resampled with the plants.  Each learned
    record gets ``verdicts`` = ``{"max": ..., "rms": ...}`` (:meth:`Verdict.to_dict`, its group's); returns the rows
    (``env`` added), one per learned controller and figure.

    Choosing the opponent after seeing its figures on the same plants favours the opponent a little (the
    least of several IQMs is biased low): the rule errs toward "ties" and "loses", never toward "wins"."""
    rows = []
    for env_id in dict.fromkeys(r["env"] for r in records):
        group = [r for r in records if r["env"] == env_id]
        controllers: dict[str, list[dict]] = {}
        for rec in (r for r in group if r["policy"] in learned):
            controllers.setdefault(rec.get("group") or rec["policy"], []).append(rec)
        for label, members in controllers.items():
            for rec in members:
                rec["verdicts"] = {}
            for figure in ("max", "rms"):
                opponent = strongest(group, figure, causal)
                if opponent is None:
                    continue
                x = seed_figures(members, figure)
                v = verdict(
                    x,
                    sampled_figures(opponent, figure),
                    figure=figure,
                    x_label=label,
                    y_label=opponent["policy"],
                    reps=reps,
                    seed=seed,
                ).to_dict()
                v["training_seeds"] = len(members)
                for rec in members:
                    rec["verdicts"][figure] = v
                rows.append({"env": env_id, **v})
    return rows


def format_verdicts(rows: list[dict]) -> str:
    """The verdict rows as a table: env, figure, the learned controller and the strongest causal one with their
    IQMs and intervals (um), the difference's paired interval, P(X < Y) and the outcome."""

    def f(v):
        return "inf" if v is None else f"{v:.4g}"

    w = max(
        [8]
        + [
            len(r["x"]) + (len(f" ({r['training_seeds']} seeds)") if r.get("training_seeds", 1) > 1 else 0)
            for r in rows
        ]
    )
    head = (
        f"{'env':<28} {'fig':<3} {'learned':<{w}} {'IQM [95% CI] um':<28} {'strongest causal':<16} "
        f"{'IQM [95% CI] um':<28} {'X - Y [95% CI] um':<32} {'P(X<Y)':>6} verdict"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        x = r["x"] + (f" ({r['training_seeds']} seeds)" if r.get("training_seeds", 1) > 1 else "")
        lines.append(
            f"{r['env']:<28} {r['figure']:<3} {x:<{w}} "
            f"{f(r['iqm_x']) + ' [' + f(r['ci_x'][0]) + ', ' + f(r['ci_x'][1]) + ']':<28} {r['y']:<16} "
            f"{f(r['iqm_y']) + ' [' + f(r['ci_y'][0]) + ', ' + f(r['ci_y'][1]) + ']':<28} "
            f"{f(r['difference']) + ' [' + f(r['low']) + ', ' + f(r['high']) + ']':<32} "
            f"{r['p_improvement']:>6.2f} {r['outcome']}"
        )
    return "\n".join(lines)
