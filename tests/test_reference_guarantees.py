"""References that are what they claim (issue 9): fuzz, regressions and cost bounds.

:func:`vcnc_gym.motion.interpolate` promises, for every reference it returns,
that every step moves along the curve within ``step_tolerance`` x V_peak x dt
of the distance the profile commands (the last step onto u_end included),
that u runs from u_start to exactly u_end without going back, and that every
array (the unit tangent included) is finite; otherwise it raises a
``ValueError`` that names the curve's defect or the cost.  These tests hold
it to that with an oracle of their own: the arc length of every step by
adaptive Gauss-Legendre quadrature of |C'(u)| cut at the knots (not the
kernel's code), and, on the regression curves, scipy.integrate.quad of |C'|
from geomdl's derivatives.

Run the fuzz at a larger size, with its tally of outcomes, by

    VCNC_FUZZ_EXAMPLES=1000 python -m pytest -q -s tests/test_reference_guarantees.py -k fuzz
"""

from __future__ import annotations

import collections
import math
import os
import re
import time

import numpy as np
import pytest
from geomdl import NURBS
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from vcnc_gym.geometry import NurbsCurve, heart, omega
from vcnc_gym.motion import (
    MAX_REFERENCE_SAMPLES,
    STEP_TOLERANCE,
    SCurveFeedrate,
    interpolate,
    reference_samples,
)

FUZZ_EXAMPLES = int(os.environ.get("VCNC_FUZZ_EXAMPLES", "120"))
FUZZ_MAX_SAMPLES = 20_000  # keeps the oracle fast; a longer reference is refused (an outcome of its own)

# the defects interpolate names, and how a message says so
MESSAGE_KINDS = {
    "cusp": re.compile(r"curve has a cusp at u = "),
    "turns back": re.compile(r"curve turns back on itself at the knot u = .*TURN_BACK_ANGLE"),
    "near-zero derivative": re.compile(r"near-zero derivative C'\(u\) at (its (start|end), )?u = "),
    "zero-length span": re.compile(r"knot span \[.*\] is .* mm long, below SPAN_LENGTH_TOLERANCE"),
    "zero-length curve": re.compile(r"curve has \(near-\)zero length"),
    "knot span too short in u (u cannot resolve the step)": re.compile(
        r"the reference cannot follow the curve (near|at) u = .* one floating-point step of u moves .* mm; the knot "
        r"span \[.*\] is too short in u"
    ),
    "cannot follow": re.compile(r"the reference cannot follow the curve near u = "),
    "too many samples": re.compile(r"would make .* reference samples \(.* GiB\); the limit is max_samples="),
}


def message_kind(message: str) -> str | None:
    for kind, pattern in MESSAGE_KINDS.items():
        if pattern.search(message):
            return kind
    return None


# --------------------------------------------------------------------------
# oracle: the arc length of every step, and the list of broken promises
# --------------------------------------------------------------------------

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


def _gauss(curve: NurbsCurve, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    half, mid = 0.5 * (hi - lo), 0.5 * (hi + lo)
    us = mid[:, None] + half[:, None] * _GL_X
    us = np.minimum(us, np.nextafter(hi, lo)[:, None])  # a knot evaluates on its right span
    d1 = curve.derivatives_array(us.reshape(-1), 1)[:, 1, :]
    return half * (np.hypot(d1[:, 0], d1[:, 1]).reshape(us.shape) @ _GL_W)


def step_arc_lengths(curve: NurbsCurve, u: np.ndarray, abs_tol: float) -> np.ndarray:
    """Arc length of every step [u_k, u_{k+1}], mm: 8-point Gauss-Legendre on pieces
    cut at the knots, bisected until a piece and its halves agree to ``abs_tol`` mm."""
    lo_r, hi_r = curve.u_range
    knots = curve.knots[(curve.knots > lo_r) & (curve.knots < hi_r)]
    cuts = np.unique(np.concatenate([u, knots]))
    lo, hi = cuts[:-1], cuts[1:]
    owner = np.searchsorted(u, lo, side="right") - 1
    whole = _gauss(curve, lo, hi)
    arcs = np.zeros(len(u) - 1)
    for _ in range(60):
        if lo.size == 0:
            break
        mid = 0.5 * (lo + hi)
        left, right = _gauss(curve, lo, mid), _gauss(curve, mid, hi)
        halves = left + right
        done = (np.abs(halves - whole) <= abs_tol + 1e-13 * halves) | ~((lo < mid) & (mid < hi))
        np.add.at(arcs, owner[done], halves[done])
        keep = ~done
        lo, hi, owner = np.r_[lo[keep], mid[keep]], np.r_[mid[keep], hi[keep]], np.r_[owner[keep], owner[keep]]
        whole = np.r_[left[keep], right[keep]]
    assert lo.size == 0, "oracle quadrature did not converge"
    return arcs


def broken_promises(curve: NurbsCurve, ref) -> list[str]:
    """What the reference states and does not hold, checked without the kernel's code."""
    problems = []
    for name in ("t", "u", "position", "velocity", "acceleration", "tangent", "feedrate"):
        if not np.all(np.isfinite(getattr(ref, name))):
            problems.append(f"{name} not finite")
    if problems:
        return problems
    u_start, u_end = curve.u_range
    if ref.u[0] != u_start or ref.u[-1] != u_end:
        problems.append(f"u runs from {ref.u[0]} to {ref.u[-1]}, not {u_start} to {u_end}")
    if np.any(np.diff(ref.u) < 0.0):
        problems.append("u goes back")
    vdt = ref.plan.v_peak * ref.dt
    tol = ref.step_tolerance * vdt
    arcs = step_arc_lengths(curve, ref.u, 1e-7 * tol)
    error = np.abs(arcs - np.diff(ref.plan.distance(ref.t)))
    k = int(np.argmax(error))
    if error[k] > tol * (1.0 + 1e-6):
        problems.append(f"step {k} (u = {ref.u[k]!r}) is off by {error[k] / vdt:.3g} V_peak dt > {ref.step_tolerance}")
    # the kernel's arcs are accurate to ~1e-6 tol, to ~1e-3 tol in knot spans narrow for their |u| (both
    # quadratures place their nodes on floats)
    if not abs(error[k] / vdt - ref.step_error) <= 2e-3 * ref.step_tolerance:
        problems.append(f"step_error {ref.step_error:.6g} but the largest error is {error[k] / vdt:.6g}")
    if not np.allclose(np.linalg.norm(ref.tangent, axis=1), 1.0, rtol=0, atol=1e-12):
        problems.append("tangent is not a unit vector")
    d1 = curve.derivatives_array(ref.u, 1)[:, 1, :]
    cross = ref.tangent[:, 0] * d1[:, 1] - ref.tangent[:, 1] * d1[:, 0]
    if not np.all(np.abs(cross) <= 1e-9 * np.linalg.norm(d1, axis=1)) or np.any(np.sum(ref.tangent * d1, axis=1) <= 0):
        problems.append("tangent is not along C'(u)")
    if not np.allclose(np.linalg.norm(ref.velocity[:-1], axis=1), ref.feedrate[:-1], rtol=1e-9, atol=1e-9):
        problems.append("|velocity| is not the commanded feed")
    return problems


# --------------------------------------------------------------------------
# fuzz
# --------------------------------------------------------------------------


@st.composite
def nurbs_cases(draw):
    """A valid NURBS definition and a setting.

    Hypothesis chooses the structure: degree 1-5, number and kind of interior
    knots (uniform, on a grid with multiplicities up to p, or clustered in
    pairs 1e-12 to 1e-3 of the range apart), the size of the curve and of its
    parameter range, which control points nearly coincide (0 to 1e-4 of the
    size apart), dt, feedrate and ramp time; a seeded generator draws the
    numbers (control points in a box, weights log-uniform in [0.1, 10]).
    """
    p = draw(st.integers(1, 5), label="degree")
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1), label="seed"))
    n_distinct = draw(st.integers(0, 6), label="distinct interior knots")
    kind = draw(st.sampled_from(["uniform", "grid", "clustered"]), label="knots")
    if kind == "grid":
        fractions = np.sort(rng.choice(np.arange(1, 24), size=n_distinct, replace=False)) / 24
    else:
        fractions = np.sort(rng.uniform(0.01, 0.99, n_distinct))
    if kind == "clustered":
        gap = draw(st.sampled_from([1e-12, 1e-9, 1e-6, 1e-3]), label="cluster gap")
        fractions = np.sort(np.r_[fractions, fractions + gap])
    a = draw(st.floats(-50.0, 50.0), label="u_start")
    width = 10.0 ** draw(st.floats(-3.0, 2.0), label="log10 u range")
    values, counts = np.unique(a + width * fractions, return_counts=True)
    values, counts = values[(values > a) & (values < a + width)], counts[(values > a) & (values < a + width)]
    top = draw(st.integers(1, p), label="largest multiplicity")
    mult = np.minimum(rng.integers(1, top + 1, size=values.size) * counts, p)
    knots = np.r_[[a] * (p + 1), np.repeat(values, mult), [a + width] * (p + 1)]
    n1 = len(knots) - p - 1
    scale = draw(st.sampled_from([1.0, 10.0, 50.0]), label="size mm")
    cps = rng.uniform(-scale, scale, size=(n1, 2)) + rng.uniform(-200.0, 200.0, size=2)
    for i, gap in draw(
        st.lists(st.tuples(st.integers(0, n1 - 2), st.sampled_from([0.0, 1e-16, 1e-12, 1e-8, 1e-4])), max_size=2),
        label="near-coincident control points (index, gap / size)",
    ):
        cps[i + 1] = cps[i] + gap * scale * rng.normal(size=2)
    weights = 10.0 ** rng.uniform(-1.0, 1.0, size=n1) if draw(st.booleans(), label="rational") else np.ones(n1)
    dt = draw(st.sampled_from([1e-3, 1e-4]), label="dt s")
    feedrate = draw(st.floats(20.0, 300.0), label="feedrate mm/s")
    ramp_time = draw(st.floats(0.02, 0.2), label="ramp_time s")
    return cps, weights, knots, p, dt, feedrate, ramp_time


FUZZ_OUTCOMES: collections.Counter = collections.Counter()


@pytest.fixture(scope="module")
def fuzz_tally():
    start = time.perf_counter()
    yield FUZZ_OUTCOMES
    if FUZZ_OUTCOMES:
        total = sum(FUZZ_OUTCOMES.values())
        lines = "\n".join(f"  {n:5d}  {k}" for k, n in FUZZ_OUTCOMES.most_common())
        print(f"\nfuzz of interpolate: {total} cases in {time.perf_counter() - start:.1f} s\n{lines}")


@settings(
    max_examples=FUZZ_EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(case=nurbs_cases())
def test_fuzz_reference_is_clean_or_refused_with_a_reason(case, fuzz_tally):
    cps, weights, knots, p, dt, feedrate, ramp_time = case
    curve = NurbsCurve(cps, weights, knots, p)  # a valid definition
    try:
        ref = interpolate(curve, SCurveFeedrate(feedrate, ramp_time), dt, max_samples=FUZZ_MAX_SAMPLES)
    except ValueError as err:
        kind = message_kind(str(err))
        assert kind is not None, f"ValueError without a named defect: {err}"
        fuzz_tally[f"ValueError: {kind}"] += 1
        return
    problems = broken_promises(curve, ref)
    assert not problems, problems
    fuzz_tally[
        "clean reference, eq. (8) only" if ref.corrected_steps == 0 else "clean reference, some steps corrected"
    ] += 1


def test_the_oracle_can_fail():
    """A reference with one step moved, or one NaN, is caught."""
    curve = omega()
    ref = interpolate(curve, SCurveFeedrate(), 1e-3)
    assert broken_promises(curve, ref) == []

    class Doctored:
        def __init__(self, **changes):
            self.__dict__.update(
                {
                    k: getattr(ref, k)
                    for k in (
                        "t",
                        "u",
                        "position",
                        "velocity",
                        "acceleration",
                        "tangent",
                        "feedrate",
                        "plan",
                        "dt",
                        "step_tolerance",
                        "step_error",
                    )
                }
            )
            self.__dict__.update(changes)

    u = ref.u.copy()
    u[300] = 0.5 * (u[300] + u[301])  # one step half as long, the next one and a half
    assert any("off by" in p for p in broken_promises(curve, Doctored(u=u)))
    tangent = ref.tangent.copy()
    tangent[10] = np.nan
    assert broken_promises(curve, Doctored(tangent=tangent)) == ["tangent not finite"]
    assert any("step_error" in p for p in broken_promises(curve, Doctored(step_error=0.0)))


# --------------------------------------------------------------------------
# regressions: the cases of issue 9
# --------------------------------------------------------------------------


def scipy_step_arc(curve: NurbsCurve, a: float, b: float) -> float:
    """Arc length from a to b by scipy.integrate.quad of |C'| from geomdl, cut at the knots."""
    g = NURBS.Curve(normalize_kv=False)
    g.degree = curve.degree
    lo, hi = float(curve.knots[0]), float(curve.knots[-1])
    g.ctrlptsw = [[x * w, y * w, w] for (x, y), w in zip(curve.control_points.tolist(), curve.weights.tolist())]
    g.knotvector = [(k - lo) / (hi - lo) for k in curve.knots.tolist()]
    cuts = np.unique(np.r_[a, b, curve.knots[(curve.knots > a) & (curve.knots < b)]])

    def speed(u):
        return math.hypot(*g.derivatives((u - lo) / (hi - lo), order=1)[1]) / (hi - lo)

    return sum(quad(speed, s, e, epsabs=1e-14, epsrel=1e-12, limit=200)[0] for s, e in zip(cuts[:-1], cuts[1:]))


def test_issue_first_two_control_points_equal_to_1e16():
    """Issue 9: 3 samples, 28.9 mm in one 0.1 ms step, and a fluctuation of 6.9e-7.

    C'(0) is rounding noise (3.7e-16 mm per unit of u against 58 mean): eq. (9)
    divided by it and the first moving step jumped to the end of the curve.
    """
    curve = NurbsCurve([[0.0, 0.0], [1e-16, 0.0], [0.0, -28.9]], [0.7, 1.3, 1.0], [0, 0, 0, 1, 1, 1], 2)
    with pytest.raises(ValueError, match=r"near-zero derivative C'\(u\) at its start, u = 0: \|C'\(u\)\| = 3.71e-16"):
        interpolate(curve, SCurveFeedrate(100.0, 0.12), 1e-4)


CUSPS = {
    # C'(1) = 0 at a knot and the curve turns back: the old reference jumped 20.4 mm in one 0.1 ms step
    "at a knot": (
        NurbsCurve([[0, 0], [15, 15], [15, 15], [0, 1]], [1, 2, 0.5, 1], [0, 0, 0, 0.3, 1, 1, 1], 2),
        r"curve has a cusp at u = 0.3: the tangent reverses",
    ),
    # crossed Bezier control points: C'(1/2) = 0 inside the span (old: feedrate_fluctuation 0.77)
    "inside a span": (
        NurbsCurve([[0, 0], [10, 10], [0, 10], [10, 0]], [1, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1], 3),
        r"curve has a cusp at u = 0.5: the tangent reverses",
    ),
}


@pytest.mark.parametrize("name", CUSPS)
def test_issue_cusp(name):
    """Issue 9: a cusp jumped 17.8 mm in one step."""
    curve, pattern = CUSPS[name]
    with pytest.raises(ValueError, match=pattern):
        interpolate(curve, SCurveFeedrate(), 1e-4)


def test_issue_segment_8e_105_mm_long():
    """Issue 9: a segment 8e-105 mm long raised ZeroDivisionError inside the jitted interpolator."""
    curve = NurbsCurve([[0, 0], [8e-105, 0], [10, 0]], [1, 1, 1], [0, 0, 0.5, 1, 1], 1)
    with pytest.raises(ValueError, match=r"knot span \[0, 0.5\] is 8e-105 mm long, below SPAN_LENGTH_TOLERANCE"):
        interpolate(curve, SCurveFeedrate(), 1e-4)


def test_issue_nan_tangent_at_a_repeated_end_point():
    """Issue 9: NaN tangents where C'(u) = 0 (a repeated last control point)."""
    curve = NurbsCurve([[0, 0], [5, 5], [10, 0], [10, 0]], [1, 1, 1, 1], [0, 0, 0, 0.5, 1, 1, 1], 2)
    with pytest.raises(ValueError, match=r"near-zero derivative C'\(u\) at its end, u = 1: \|C'\(u\)\| = 7.44e-15 mm"):
        interpolate(curve, SCurveFeedrate(), 1e-4)


# Valid curves on which eq. (8) alone went wrong: the old interpolator's largest
# chord over V_peak dt and end gap (mm), measured before the fix.
STEP_CASES = {
    # a polyline whose second segment is 9 times faster in u: eq. (8) crossed the knot at
    # the first segment's speed and made a step 9.0 x V_peak dt (end gap -0.08 mm)
    "polyline speed jump": (NurbsCurve([[0, 0], [10, 0], [10, 10]], [1, 1, 1], [0, 0, 0.9, 1, 1], 1), 1e-4),
    # weights 50 and 0.02: steps 9.3 x V_peak dt
    "weight ratio 2500": (
        NurbsCurve([[0, 0], [10, 0], [10, 10], [0, 10]], [1, 50, 0.02, 1], [0, 0, 0, 0.5, 1, 1, 1], 2),
        1e-4,
    ),
    # the crossed Bezier with weights 2, 1, 1, 0.5: no cusp but a turn of radius 0.7 um (|C'| down to
    # 0.012 of its mean), where eq. (8) jumped 5.2 mm (523 x V_peak dt) in one step
    "near-cusp": (NurbsCurve([[0, 0], [10, 10], [0, 10], [10, 0]], [2, 1, 1, 0.5], [0, 0, 0, 0, 1, 1, 1, 1], 3), 1e-4),
}


@pytest.mark.parametrize("name", STEP_CASES)
def test_issue_steps_over_five_times_nominal_are_corrected(name):
    curve, dt = STEP_CASES[name]
    ref = interpolate(curve, SCurveFeedrate(), dt)
    assert ref.corrected_steps > 0
    assert broken_promises(curve, ref) == []
    vdt = ref.plan.v_peak * dt
    assert np.max(ref.chord_lengths) <= 1.1 * vdt
    assert abs(ref.end_gap) <= 0.1 * vdt
    # the steps around every corrected one, against scipy quad of geomdl's |C'|
    ds = np.diff(ref.plan.distance(ref.t))
    arcs = step_arc_lengths(curve, ref.u, 1e-12)
    worst = np.argsort(np.abs(arcs - ds))[-3:]
    for k in worst:
        arc = scipy_step_arc(curve, float(ref.u[k]), float(ref.u[k + 1]))
        assert arc == pytest.approx(arcs[k], rel=1e-9, abs=1e-12)
        assert abs(arc - ds[k]) <= 0.1 * vdt


def test_issue_stalled_reference_is_corrected():
    """Eq. (10)'s second term made u_{k+1} < u_k, clamped to u_k forever: the old
    reference stood still and closed 28 mm in its last step (end gap 28.3 mm)."""
    curve = NurbsCurve([[0.0, 0.0], [1e-4, 0.0], [20.0, 20.0]], [0.7, 1.3, 1.0], [0, 0, 0, 1, 1, 1], 2)
    ref = interpolate(curve, SCurveFeedrate(), 1e-4)
    assert broken_promises(curve, ref) == []
    assert abs(ref.end_gap) <= 0.1 * ref.plan.v_peak * ref.dt


def test_paper_contours_are_not_corrected():
    """Eq. (8) alone meets the tolerance on the paper's contours (largest step error
    0.06 V_peak dt, the omega's last step at 1 ms): their figures are those of the paper's method."""
    for make, dt, expected in (
        (heart, 1e-3, 6.1e-3),
        (heart, 1e-4, 6.1e-4),
        (omega, 1e-3, 5.95e-2),
        (omega, 1e-4, 1.42e-2),
    ):
        ref = interpolate(make(), SCurveFeedrate(), dt)
        assert ref.corrected_steps == 0
        assert ref.step_error == pytest.approx(expected, rel=0.01)
        assert ref.step_error < STEP_TOLERANCE


def test_a_tighter_tolerance_corrects_the_omega():
    """At 0.01 V_peak dt the omega at 1 ms needs corrections (the steps across its knots
    and the end) and still holds the promise."""
    curve = omega()
    ref = interpolate(curve, SCurveFeedrate(), 1e-3, step_tolerance=0.01)
    assert ref.corrected_steps > 0
    assert ref.step_error <= 0.01
    assert broken_promises(curve, ref) == []
    loose = interpolate(curve, SCurveFeedrate(), 1e-3)
    assert abs(ref.end_gap) < abs(loose.end_gap) / 5


def test_knot_span_too_short_in_u_for_its_length():
    """A 10 mm segment squeezed into 1e-13 of u: one floating-point step of u moves
    6 um, more than the reference may be off by; refused, naming the span."""
    curve = NurbsCurve([[0, 0], [10, 0], [10, 10], [0, 10]], [1, 1, 1, 1], [0, 0, 0.3, 0.3 + 1e-13, 1, 1], 1)
    with pytest.raises(
        ValueError,
        match=r"cannot follow the curve near u = .* one floating-point step of u moves "
        r".* mm; the knot span \[0.3, 0.3000000000000\d*\] is too short in u for "
        r"its 10 mm",
    ):
        interpolate(curve, SCurveFeedrate(), 1e-4)


# --------------------------------------------------------------------------
# what a reference costs
# --------------------------------------------------------------------------


@pytest.mark.parametrize("make", [heart, omega])
@pytest.mark.parametrize("dt", [1e-3, 1e-4, 3.3e-4])
def test_sample_count_is_predicted(make, dt):
    curve, profile = make(), SCurveFeedrate()
    ref = interpolate(curve, profile, dt)
    assert len(ref) == reference_samples(curve.arc_length(), profile, dt)


@pytest.mark.parametrize(
    "feedrate, ramp_time, dt, samples",
    [
        (0.1, 0.12, 1e-4, "3.1e+07"),  # issue 9: 28 s and 5.3 GB before
        (1e-3, 0.12, 1e-4, "3.1e+09"),  # issue 9: MemoryError 23.1 GiB before
        (100.0, 100.0, 1e-4, "2e+06"),  # issue 9: 2 000 100 steps before
    ],
)
def test_references_beyond_the_limit_are_refused_before_they_are_built(feedrate, ramp_time, dt, samples):
    profile = SCurveFeedrate(feedrate, ramp_time)
    start = time.perf_counter()
    with pytest.raises(ValueError) as err:
        interpolate(heart(), profile, dt)
    assert time.perf_counter() - start < 2.0
    message = str(err.value)
    assert f"feedrate={feedrate!r} mm/s, ramp_time={ramp_time!r} s" in message
    assert f"dt={dt!r} s" in message and " mm contour" in message
    assert f"would make {samples} reference samples" in message
    assert re.search(r"\(\d.* GiB\); the limit is max_samples=2000000", message)
    assert reference_samples(heart().arc_length(), profile, dt) > MAX_REFERENCE_SAMPLES


def test_the_limit_is_an_argument():
    curve, profile = omega(), SCurveFeedrate()
    n = reference_samples(curve.arc_length(), profile, 1e-4)
    assert len(interpolate(curve, profile, 1e-4, max_samples=n)) == n
    with pytest.raises(
        ValueError, match=rf"would make {re.escape(f'{n:.3g}')} reference samples .* max_samples={n - 1} \("
    ):
        interpolate(curve, profile, 1e-4, max_samples=n - 1)


@pytest.mark.parametrize(
    "bad", [True, np.True_, "1e-4", 1e-4 + 0j, None, [1e-4], 0.0, -1e-4, float("nan"), float("inf")]
)
def test_dt_must_be_a_positive_real_number(bad):
    with pytest.raises(ValueError, match=r"dt must be .*\(s\)"):
        interpolate(omega(), SCurveFeedrate(), bad)
    with pytest.raises(ValueError, match=r"dt must be .*\(s\)"):
        reference_samples(51.0, SCurveFeedrate(), bad)


@pytest.mark.parametrize("bad", [True, False, "100", 100 + 0j, None, 0, -5.0, float("nan"), float("inf")])
@pytest.mark.parametrize("argument, unit", [("feedrate", "mm/s"), ("ramp_time", "s")])
def test_profile_arguments_must_be_positive_real_numbers(argument, unit, bad):
    with pytest.raises(ValueError, match=rf"{argument} must be .*\({re.escape(unit)}\)"):
        SCurveFeedrate(**{argument: bad})


def test_numpy_and_integer_arguments_are_accepted():
    ref = interpolate(heart(), SCurveFeedrate(np.float32(100), np.int64(1)), np.float64(1e-3))
    assert ref.plan.v_peak == 100.0 and ref.plan.ramp_time == 1.0 and ref.dt == 1e-3


@pytest.mark.parametrize("bad", [0.0, 2.0, 1e-7, "0.1", True, float("nan")])
def test_step_tolerance_range(bad):
    with pytest.raises(ValueError, match="step_tolerance"):
        interpolate(omega(), SCurveFeedrate(), 1e-3, step_tolerance=bad)


@pytest.mark.parametrize("bad", [1, 1.5, "100", True, None])
def test_max_samples_must_be_an_integer_of_at_least_two(bad):
    with pytest.raises(ValueError, match="max_samples"):
        interpolate(omega(), SCurveFeedrate(), 1e-3, max_samples=bad)


def test_a_plan_over_another_length_is_refused():
    class LongerPlan:
        def plan(self, length):
            return SCurveFeedrate().plan(1.01 * length)

    with pytest.raises(ValueError, match=r"profile.plan\(51.14.*\) returned a plan covering 51.6.* mm, not"):
        interpolate(omega(), LongerPlan(), 1e-3)
