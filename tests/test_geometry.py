"""Tests of vcnc_gym.geometry: the NURBS evaluator and the paper's named shapes.

Oracles that are not the code under test: geomdl (points, first and second
derivatives; its knots normalised to [0, 1] and its derivatives rescaled by
the chain rule d/du = d/dv / (b - a)), scipy.integrate.quad (arc length, span
by span), and the numbers printed in Jahanpour et al.'s section 3a.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from geomdl import NURBS
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from vcnc_gym.geometry import SHAPES, NurbsCurve, heart, omega

# Jahanpour et al. (2014), section 3a, exactly as printed
HEART_X = [0, 0, -20, 40, 90, 40, -20, 0, 0]
HEART_Y = [0, 10, 50, 50, 0, -50, -50, -10, 0]
HEART_W = [1, 1, 1.7, 1, 4, 1, 1.7, 1, 1]
HEART_U = [0, 0, 0, 0, 1, 2, 3, 4, 5, 6, 6, 6, 6]
OMEGA_X = [0, 0, 6, 4, 1, 5, 11, 15, 12, 10, 16, 16]
OMEGA_Y = [1, 0, 0, 2, 11, 16, 16, 11, 2, 0, 0, 1]
OMEGA_W = [1] * 12
OMEGA_U = [0, 0, 0, 0.025, 0.1, 0.2, 0.4, 0.5, 0.6, 0.8, 0.9, 0.975, 1, 1, 1]

REL_TOL = 1e-9  # relative to the curve's size (and its derivatives' size)


# --------------------------------------------------------------------------- oracle


class GeomdlCurve:
    """geomdl's NURBS curve on the same definition, in the curve's own u.

    geomdl is fed the knot vector normalised to [0, 1] (v = (u - a) / (b - a));
    its k-th derivative with respect to v is divided by (b - a)^k.
    """

    def __init__(self, control_points, weights, knots, degree):
        kv = np.asarray(knots, dtype=float)
        self.a, self.b = float(kv[0]), float(kv[-1])
        self.g = NURBS.Curve(normalize_kv=False)
        self.g.degree = int(degree)
        self.g.ctrlptsw = [
            [x * w, y * w, w] for (x, y), w in zip(np.asarray(control_points, float).tolist(), list(weights))
        ]
        self.g.knotvector = [(k - self.a) / (self.b - self.a) for k in kv.tolist()]

    @classmethod
    def of(cls, curve: NurbsCurve) -> "GeomdlCurve":
        return cls(curve.control_points, curve.weights.tolist(), curve.knots, curve.degree)

    def v(self, u: float) -> float:
        return min(1.0, max(0.0, (float(u) - self.a) / (self.b - self.a)))

    def derivatives(self, u: float, order: int = 2) -> np.ndarray:
        d = np.array(self.g.derivatives(self.v(u), order=order), dtype=float)
        return d / ((self.b - self.a) ** np.arange(order + 1))[:, None]


def random_curve(rng: np.random.Generator, degree: int, force_full_multiplicity: bool = False):
    """A random clamped NURBS definition in a non-unit knot range.

    Interior knots sit on a grid of the range (so spans are either empty or not
    tiny) with multiplicities 1..p; weights in [0.25, 4]; control points in a
    box of a few tens of mm.
    """
    p = degree
    a = float(rng.uniform(-20.0, 20.0))
    b = a + float(rng.uniform(0.5, 30.0))
    grid = 24
    n_distinct = int(rng.integers(0, 7))
    values = np.sort(rng.choice(np.arange(1, grid), size=n_distinct, replace=False))
    mult = rng.integers(1, p + 1, size=n_distinct)
    if force_full_multiplicity and n_distinct == 0:
        values, mult = np.array([int(rng.integers(1, grid))]), np.array([p])
    if force_full_multiplicity:
        mult[int(rng.integers(0, len(mult)))] = p
    interior = [a + (b - a) * j / grid for j, m in zip(values, mult) for _ in range(int(m))]
    knots = [a] * (p + 1) + interior + [b] * (p + 1)
    n1 = len(knots) - p - 1
    cps = rng.uniform(-40.0, 40.0, size=(n1, 2)) + rng.uniform(-100.0, 100.0, size=2)
    weights = rng.uniform(0.25, 4.0, size=n1)
    return cps, weights, knots, p


def sample_us(rng: np.random.Generator, knots, degree, n_random: int = 40) -> np.ndarray:
    """Random u in the range, every distinct knot (ends included), and u just beside each knot."""
    kv = np.asarray(knots, float)
    lo, hi = kv[degree], kv[-degree - 1]
    distinct = np.unique(kv[(kv >= lo) & (kv <= hi)])
    eps = 1e-7 * (hi - lo)
    beside = np.concatenate([distinct - eps, distinct + eps])
    beside = beside[(beside >= lo) & (beside <= hi)]
    return np.concatenate([rng.uniform(lo, hi, n_random), distinct, beside, [lo, hi]])


def compare_with_geomdl(curve: NurbsCurve, us: np.ndarray) -> np.ndarray:
    """Assert derivatives (0..2) match geomdl; return the worst deviation per order, relative."""
    g = GeomdlCurve.of(curve)
    ours = curve.derivatives_array(us, 2)
    ref = np.array([g.derivatives(u, 2) for u in us])
    lo, hi = curve.u_range
    size = np.ptp(curve.control_points, axis=0).max() + np.abs(curve.control_points).max()
    worst = np.empty(3)
    for k in range(3):
        # the scale of the k-th derivative: the curve's size per (u range)^k, or what it actually reaches
        scale = max(size / (hi - lo) ** k, np.abs(ref[:, k, :]).max())
        dev = np.abs(ours[:, k, :] - ref[:, k, :]).max() / scale
        worst[k] = dev
        assert dev < REL_TOL, f"order {k}: deviation {dev:.3e} of scale {scale:.3e}"
    # the scalar entry points agree with the batched one
    for j, u in enumerate(us):
        np.testing.assert_array_equal(curve.derivatives(float(u), 2), ours[j])
        np.testing.assert_array_equal(curve.point(float(u)), ours[j, 0])
    np.testing.assert_array_equal(curve.points(us), ours[:, 0])
    return worst


# --------------------------------------------------------------------------- named shapes


def test_heart_is_the_seed_definition():
    c = heart()
    np.testing.assert_array_equal(c.control_points, np.column_stack([HEART_X, HEART_Y]).astype(float))
    np.testing.assert_array_equal(c.weights, HEART_W)
    np.testing.assert_array_equal(c.knots, HEART_U)
    assert c.degree == 3
    assert c.u_range == (0.0, 6.0)
    np.testing.assert_allclose(c.point(0.0), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(c.point(6.0), [0.0, 0.0], atol=1e-12)


def test_omega_is_the_seed_definition():
    c = omega()
    np.testing.assert_array_equal(c.control_points, np.column_stack([OMEGA_X, OMEGA_Y]).astype(float))
    np.testing.assert_array_equal(c.weights, OMEGA_W)
    np.testing.assert_array_equal(c.knots, OMEGA_U)
    assert c.degree == 2
    assert c.u_range == (0.0, 1.0)
    np.testing.assert_allclose(c.point(0.0), [0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(c.point(1.0), [16.0, 1.0], atol=1e-12)


def test_shapes_registry_and_fresh_read_only_curves():
    assert {"heart", "omega"} <= set(SHAPES)
    assert SHAPES["heart"] is heart and SHAPES["omega"] is omega
    a, b = heart(), heart()
    assert a is not b
    with pytest.raises(ValueError):
        a.control_points[0, 0] = 1.0  # read-only: a shared curve cannot be bent by accident
    with pytest.raises(ValueError):
        a.knots[0] = 1.0


def test_heart_traced_clockwise_from_origin():
    """Jahanpour et al.'s section 3b: the heart starts at the origin and runs clockwise (negative area)."""
    c = heart()
    pts = c.points(np.linspace(0.0, 6.0, 4001))
    area = 0.5 * np.sum(pts[:-1, 0] * pts[1:, 1] - pts[1:, 0] * pts[:-1, 1])
    assert area < 0.0


@pytest.mark.parametrize("make", [heart, omega], ids=["heart", "omega"])
def test_named_shapes_match_geomdl(make):
    c = make()
    rng = np.random.default_rng(0)
    us = sample_us(rng, c.knots, c.degree, n_random=300)
    compare_with_geomdl(c, us)


# --------------------------------------------------------------------------- random curves


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("seed", range(6))
def test_random_curves_match_geomdl(degree, seed):
    rng = np.random.default_rng(1000 * degree + seed)
    cps, w, kv, p = random_curve(rng, degree, force_full_multiplicity=seed % 2 == 0)
    c = NurbsCurve(cps, w, kv, p)
    assert c.u_range == (kv[0], kv[-1])
    np.testing.assert_array_equal(c.knots, kv)  # kept in its own units
    compare_with_geomdl(c, sample_us(rng, kv, p))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), degree=st.integers(1, 5))
def test_random_curves_match_geomdl_hypothesis(seed, degree):
    rng = np.random.default_rng(seed)
    cps, w, kv, p = random_curve(rng, degree)
    compare_with_geomdl(NurbsCurve(cps, w, kv, p), sample_us(rng, kv, p, n_random=15))


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_clamped_ends_are_the_end_control_points(degree):
    rng = np.random.default_rng(degree)
    cps, w, kv, p = random_curve(rng, degree)
    c = NurbsCurve(cps, w, kv, p)
    lo, hi = c.u_range
    scale = np.abs(cps).max()
    np.testing.assert_allclose(c.point(lo), cps[0], rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(c.point(hi), cps[-1], rtol=0, atol=1e-13 * scale)
    # u_end is evaluated on the last span, from the left: continuous with u just below it
    d_end = c.derivatives(hi, 2)
    d_near = c.derivatives(np.nextafter(hi, -np.inf), 2)
    np.testing.assert_allclose(d_end, d_near, rtol=1e-9, atol=1e-9 * scale)


@pytest.mark.parametrize("degree", [2, 3, 4])
def test_interior_knot_of_full_multiplicity_is_a_corner(degree):
    """A knot repeated p times: C0 there, the curve passes through a control point, right derivative."""
    p = degree
    a, b, k = 2.5, 17.0, 9.25
    kv = [a] * (p + 1) + [k] * p + [b] * (p + 1)
    rng = np.random.default_rng(p)
    n1 = len(kv) - p - 1
    cps = rng.uniform(-30, 30, size=(n1, 2))
    w = rng.uniform(0.5, 2.0, size=n1)
    c = NurbsCurve(cps, w, kv, p)
    np.testing.assert_allclose(c.point(k), cps[p], atol=1e-12 * np.abs(cps).max())
    g = GeomdlCurve(cps, w.tolist(), kv, p)
    np.testing.assert_allclose(c.derivatives(k, 2), g.derivatives(k, 2), rtol=1e-10, atol=1e-10)
    # from the right: the first derivative at the knot points along P_p -> P_p+1
    d1 = c.derivatives(k, 1)[1]
    cross = d1[0] * (cps[p + 1, 1] - cps[p, 1]) - d1[1] * (cps[p + 1, 0] - cps[p, 0])
    assert abs(cross) < 1e-9 * np.linalg.norm(d1) * np.linalg.norm(cps[p + 1] - cps[p])
    assert np.dot(d1, cps[p + 1] - cps[p]) > 0


def test_unclamped_knot_vector_with_repeated_end_knots():
    """Repeated knots at the ends of the range of an unclamped vector (empty end spans).

    Regression: find_span returned the empty span there and the evaluator
    divided by zero at u_start / u_end.
    """
    cps = [[0, 0], [1, 1], [2, 0], [3, 1]]
    for kv in ([0, 0, 1, 1, 2, 3, 4], [0, 0, 1, 2, 2, 3, 4]):
        c = NurbsCurve(cps, [1, 1.5, 0.7, 1], kv, 2)
        lo, hi = c.u_range
        for u, inward in ((lo, np.nextafter(lo, np.inf)), (hi, np.nextafter(hi, -np.inf))):
            d = c.derivatives(u, 2)
            assert np.all(np.isfinite(d))
            np.testing.assert_allclose(d[0], c.point(inward), atol=1e-12)


def test_degree_one_is_the_polyline():
    cps = np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 10.0], [-5.0, 10.0]])
    c = NurbsCurve(cps, [1, 1, 1, 1], [2.5, 2.5, 7.0, 11.0, 17.0, 17.0], 1)
    np.testing.assert_allclose(c.points([2.5, 7.0, 11.0, 17.0]), cps, atol=1e-14)
    np.testing.assert_allclose(c.point(4.75), [1.5, 2.0], atol=1e-14)
    assert c.arc_length() == pytest.approx(5.0 + 6.0 + 8.0, rel=1e-13)
    np.testing.assert_allclose(c.derivatives(5.0, 2)[1:], [[3 / 4.5, 4 / 4.5], [0.0, 0.0]], atol=1e-14)


def test_rational_quadratic_is_a_circle():
    """The standard 90-degree arc: w = 1, sqrt(2)/2, 1 traces a unit circle exactly."""
    s = math.sqrt(0.5)
    c = NurbsCurve([[1, 0], [1, 1], [0, 1]], [1, s, 1], [3, 3, 3, 8, 8, 8], 2)
    us = np.linspace(3, 8, 101)
    np.testing.assert_allclose(np.linalg.norm(c.points(us), axis=1), 1.0, atol=1e-14)
    assert c.arc_length() == pytest.approx(math.pi / 2, rel=1e-13)


# --------------------------------------------------------------------------- arc length


def quad_arc_length(g: GeomdlCurve, knots, lo: float, hi: float) -> float:
    """Arc length by adaptive quadrature of |C'(u)| (C' from geomdl), one knot span at a time."""
    breaks = np.unique(np.concatenate([[lo, hi], [k for k in knots if lo < k < hi]]))
    total = 0.0
    for s, e in zip(breaks[:-1], breaks[1:]):
        val, _err = quad(lambda u: math.hypot(*g.derivatives(u, 1)[1]), s, e, epsabs=1e-13, epsrel=1e-13, limit=200)
        total += val
    return total


@pytest.mark.parametrize("make", [heart, omega], ids=["heart", "omega"])
def test_arc_length_named_shapes(make):
    c = make()
    g = GeomdlCurve.of(c)
    lo, hi = c.u_range
    ref = quad_arc_length(g, c.knots, lo, hi)
    assert c.arc_length() == pytest.approx(ref, rel=1e-11, abs=0)
    # partial lengths, not starting or ending on knots
    for a, b in ((lo + 0.13 * (hi - lo), lo + 0.71 * (hi - lo)), (lo + 0.42 * (hi - lo), hi), (lo, lo)):
        assert c.arc_length(a, b) == pytest.approx(quad_arc_length(g, c.knots, a, b), rel=1e-11, abs=1e-12)
    # additive over a split point
    m = lo + 0.377 * (hi - lo)
    assert c.arc_length(lo, m) + c.arc_length(m, hi) == pytest.approx(c.arc_length(), rel=1e-13)


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_arc_length_random_curves(degree):
    rng = np.random.default_rng(77 + degree)
    cps, w, kv, p = random_curve(rng, degree, force_full_multiplicity=True)
    c = NurbsCurve(cps, w, kv, p)
    g = GeomdlCurve(cps, w.tolist(), kv, p)
    lo, hi = c.u_range
    assert c.arc_length() == pytest.approx(quad_arc_length(g, kv, lo, hi), rel=1e-10)
    a, b = np.sort(rng.uniform(lo, hi, 2))
    assert c.arc_length(a, b) == pytest.approx(quad_arc_length(g, kv, a, b), rel=1e-10)


def test_arc_length_rejects_bad_ranges():
    c = heart()
    with pytest.raises(ValueError, match="u_end must not be smaller"):
        c.arc_length(3.0, 2.0)
    with pytest.raises(ValueError, match="outside the knot range"):
        c.arc_length(-0.1, 2.0)
    with pytest.raises(ValueError, match="outside the knot range"):
        c.arc_length(1.0, 6.5)
    with pytest.raises(ValueError, match="u must be finite"):
        c.arc_length(float("nan"), 2.0)


# --------------------------------------------------------------------------- bad definitions

CP4 = [[0, 0], [1, 2], [3, 2], [4, 0]]
W4 = [1, 1, 1, 1]
KV4 = [0, 0, 0, 0.5, 1, 1, 1]  # degree 2, 4 control points: 4 + 2 + 1 = 7 knots

BAD_DEFINITIONS = [
    # knot count != n + p + 2
    (CP4, W4, [0, 0, 0, 1, 1, 1], 2, r"knot count must be n \+ p \+ 2 = 7"),
    (CP4, W4, [0, 0, 0, 0.3, 0.6, 1, 1, 1], 2, r"knot count must be n \+ p \+ 2 = 7"),
    (CP4, W4, [[0, 0, 0, 0.5, 1, 1, 1]], 2, "knot count"),
    # decreasing knots
    (CP4, W4, [0, 0, 0, 0.5, 0.4, 1, 1], 2, "non-decreasing"),
    (CP4, W4, [1, 1, 1, 0.5, 0, 0, 0], 2, "non-decreasing"),
    (CP4, W4, [0, 0, 0, np.nan, 1, 1, 1], 2, "knots must be finite"),
    (CP4, W4, [0, 0, 0, 0.5, np.inf, np.inf, np.inf], 2, "knots must be finite"),
    (CP4, W4, [1, 1, 1, 1, 1, 1, 1], 2, "empty parameter range"),
    # interior multiplicity > p
    (CP4 + [[5, 1]], W4 + [1], [0, 0, 0, 0.5, 0.5, 0.5, 1, 1], 2, "repeated more than p = 2 times"),
    ([[0, 0], [1, 1], [2, 0]], [1, 1, 1], [0, 0, 0.5, 0.5, 1], 1, "repeated more than p = 1 times"),
    # weights
    (CP4, [1, 0, 1, 1], KV4, 2, "weights must be finite and positive"),
    (CP4, [1, -0.5, 1, 1], KV4, 2, "weights must be finite and positive"),
    (CP4, [1, np.nan, 1, 1], KV4, 2, "weights must be finite and positive"),
    (CP4, [1, np.inf, 1, 1], KV4, 2, "weights must be finite and positive"),
    (CP4, [1, 1, 1], KV4, 2, r"weights must have shape \(4,\)"),
    (CP4, [[1, 1, 1, 1]], KV4, 2, "weights must have shape"),
    # control points
    ([[0, 0], [1, np.nan], [3, 2], [4, 0]], W4, KV4, 2, "control_points must be finite"),
    ([[0, 0], [1, 2], [np.inf, 2], [4, 0]], W4, KV4, 2, "control_points must be finite"),
    ([[0, 0, 0], [1, 2, 0], [3, 2, 0], [4, 0, 0]], W4, KV4, 2, "control_points must have shape"),
    ([0, 1, 3, 4], W4, KV4, 2, "control_points must have shape"),
    ([[[0, 0], [1, 2]], [[3, 2], [4, 0]]], W4, KV4, 2, "control_points must have shape"),
    ([[0, 0], [1, 2]], [1, 1], [0, 0, 0, 1, 1], 2, "needs at least 3 control points"),
    # degree
    (CP4, W4, KV4, 0, "degree must be >= 1"),
    (CP4, W4, [0, 0, 1, 1], -1, "degree must be >= 1"),
    (CP4, W4, KV4, 2.5, "degree must be an integer"),
    (CP4, W4, KV4, float("nan"), "degree must be an integer"),
    (CP4, W4, KV4, float("inf"), "degree must be an integer"),
    (CP4, W4, KV4, None, "degree must be an integer"),
    (CP4, W4, KV4, "2", "degree must be an integer"),
    (CP4, W4, KV4, True, "degree must be an integer"),
]


@pytest.mark.parametrize("cps, w, kv, p, msg", BAD_DEFINITIONS)
def test_bad_definitions_raise(cps, w, kv, p, msg):
    with pytest.raises(ValueError, match=msg):
        NurbsCurve(cps, w, kv, p)


def test_integral_degree_types_are_accepted():
    for p in (2, 2.0, np.int64(2), np.float64(2.0)):
        c = NurbsCurve(CP4, W4, KV4, p)
        assert c.degree == 2 and type(c.degree) is int


def test_multiplicity_p_interior_and_p_plus_one_ends_are_accepted():
    NurbsCurve(CP4 + [[5, 1]], W4 + [1], [0, 0, 0, 0.5, 0.5, 1, 1, 1], 2)


@pytest.mark.parametrize(
    "bad_u, msg",
    [
        (-1e-9, "outside the knot range"),
        (6.0 + 1e-9, "outside the knot range"),
        (-100.0, "outside the knot range"),
        (float("nan"), "u must be finite"),
        (float("inf"), "u must be finite"),
        (float("-inf"), "u must be finite"),
    ],
)
def test_u_outside_the_range_raises(bad_u, msg):
    c = heart()
    with pytest.raises(ValueError, match=msg):
        c.point(bad_u)
    with pytest.raises(ValueError, match=msg):
        c.derivatives(bad_u, 2)
    with pytest.raises(ValueError, match=msg):
        c.points([0.0, 3.0, bad_u])
    with pytest.raises(ValueError, match=msg):
        c.derivatives_array(np.array([bad_u, 1.0]), 1)


def test_u_range_of_non_unit_knots_is_checked_in_their_own_units():
    rng = np.random.default_rng(5)
    cps, w, kv, p = random_curve(rng, 3)
    c = NurbsCurve(cps, w, kv, p)
    lo, hi = c.u_range
    c.point(lo)
    c.point(hi)
    with pytest.raises(ValueError, match="outside the knot range"):
        c.point(np.nextafter(hi, np.inf))
    with pytest.raises(ValueError, match="outside the knot range"):
        c.point(np.nextafter(lo, -np.inf))


@pytest.mark.parametrize("order", [-1, 1.5, float("nan"), float("inf")])
def test_bad_derivative_order_raises(order):
    c = heart()
    with pytest.raises(ValueError, match="order must be a non-negative integer"):
        c.derivatives(1.0, order)
    with pytest.raises(ValueError, match="order must be a non-negative integer"):
        c.derivatives_array([1.0], order)


def test_higher_orders_than_degree_are_zero_for_polynomial_pieces():
    c = NurbsCurve(CP4, W4, KV4, 2)
    d = c.derivatives(0.3, 4)
    np.testing.assert_allclose(d[3:], 0.0, atol=1e-12)
    g = GeomdlCurve(CP4, W4, KV4, 2)
    np.testing.assert_allclose(d[:3], g.derivatives(0.3, 2), atol=1e-12)


# --------------------------------------------------------------------------- regularity (check_regular)


def _message(curve: NurbsCurve) -> str | None:
    try:
        curve.check_regular()
    except ValueError as err:
        return str(err)
    return None


@pytest.mark.parametrize("make", [heart, omega], ids=["heart", "omega"])
def test_named_shapes_are_regular(make):
    make().check_regular()


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_random_curves_are_regular(degree):
    """The random definitions used above (weights 0.25-4, corners of full multiplicity) are all regular."""
    for seed in range(8):
        rng = np.random.default_rng(1000 * degree + seed)
        NurbsCurve(*random_curve(rng, degree, force_full_multiplicity=seed % 2 == 0)).check_regular()


def test_corner_of_full_multiplicity_is_regular():
    """A C0 corner has non-zero one-sided tangents: regular."""
    kv = [2.5] * 3 + [9.25] * 2 + [17.0] * 3
    NurbsCurve([[0, 0], [5, 8], [10, 0], [20, 5], [25, -3]], [1, 2, 1, 0.5, 1], kv, 2).check_regular()


IRREGULAR = {
    # first two control points coincide: C'(u_start) = 0
    "repeated first point": (
        NurbsCurve([[0.0, 0.0], [0.0, 0.0], [10.0, 0.0]], [1, 1, 1], [0, 0, 0, 1, 1, 1], 2),
        r"near-zero derivative C'\(u\) at its start, u = 0: \|C'\(u\)\| = 0 mm per unit of u",
        0.0,
    ),
    # two interior control points coincide on a straight line: the curve stalls at the knot u = 1
    "stall": (
        NurbsCurve([[0, 0], [5, 5], [5, 5], [10, 10]], [1, 1, 1, 1], [0, 0, 0, 1, 2, 2, 2], 2),
        r"near-zero derivative C'\(u\) at u = 1: \|C'\(u\)\| = 0 mm .* knot span \[1, 2\]",
        1.0,
    ),
    # ... and on a turn back: a cusp
    "cusp at a knot": (
        NurbsCurve([[0, 0], [5, 5], [5, 5], [0, 1]], [1, 1, 1, 1], [0, 0, 0, 1, 2, 2, 2], 2),
        r"curve has a cusp at u = 1: the tangent reverses",
        1.0,
    ),
    # crossed Bezier control points: C'(1/2) = 0 inside the span, found between the samples
    "cusp inside a span": (
        NurbsCurve([[0, 0], [10, 10], [0, 10], [10, 0]], [1, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1], 3),
        r"curve has a cusp at u = 0.5: the tangent reverses",
        0.5,
    ),
    "zero-length span": (
        NurbsCurve([[0, 0], [1, 0], [1, 0], [1, 0], [2, 0]], [1] * 5, [0, 0, 1, 2, 3, 4, 4], 1),
        r"knot span \[1, 2\] is 0 mm long, below SPAN_LENGTH_TOLERANCE = 1e-09 x the curve's size 2 mm",
        None,
    ),
    "a point": (
        NurbsCurve([[1, 1], [1, 1], [1, 1]], [1, 2, 1], [0, 0, 0, 1, 1, 1], 2),
        r"curve has \(near-\)zero length .* mm, below SPAN_LENGTH_TOLERANCE = 1e-09 x its size 1 mm",
        None,
    ),
}


@pytest.mark.parametrize("name", IRREGULAR)
def test_irregular_curves_are_named(name):
    curve, pattern, u = IRREGULAR[name]
    message = _message(curve)
    assert message is not None and re.search(pattern, message), message
    if u is not None:
        # where C' vanishes by geomdl too
        assert np.linalg.norm(GeomdlCurve.of(curve).derivatives(u, 1)[1]) < 1e-9


@pytest.mark.parametrize("gap, regular", [(1e-7, False), (4e-7, False), (1e-6, True), (1e-5, True)])
def test_speed_tolerance_boundary(gap, regular):
    """P1 = P0 + gap (10, 0) on a nearly straight quadratic of length ~10: |C'(0)| / mean speed = 2 gap."""
    curve = NurbsCurve([[0, 0], [10 * gap, 0], [10, 1]], [1, 1, 1], [0, 0, 0, 1, 1, 1], 2)
    mean_speed = curve.arc_length()
    assert np.linalg.norm(GeomdlCurve.of(curve).derivatives(0.0, 1)[1]) / mean_speed == pytest.approx(2 * gap, rel=0.01)
    assert (_message(curve) is None) == regular


@pytest.mark.parametrize("name", ["stall", "cusp inside a span", "zero-length span"])
def test_regularity_does_not_depend_on_units(name):
    """Coordinates x 1000 (m -> mm) and knots x 1e3 + 7: the same defect, at the mapped u."""
    curve, _, u = IRREGULAR[name]
    scaled = NurbsCurve(curve.control_points * 1000.0, curve.weights, curve.knots * 1e3 + 7.0, curve.degree)
    a, b = _message(curve), _message(scaled)
    assert a is not None and b is not None
    kind = re.compile(r"^(curve has a \S+|knot span)")
    assert kind.match(a).group(0) == kind.match(b).group(0)
    if u is None:
        assert "knot span [1007, 2007]" in b
    else:
        assert f"u = {u * 1e3 + 7:.10g}" in b


def test_check_regular_is_cached():
    curve, _, _ = IRREGULAR["cusp inside a span"]
    first = _message(curve)
    assert curve._regularity == first
    assert _message(curve) == first


def test_the_python_arc_length_is_written_once():
    """One Gauss-Legendre arc length on the Python side (vcnc_gym.geometry.quadrature) and its compiled twin
    (vcnc_gym.geometry.arclength): no other module builds a Gauss-Legendre rule (issue 34)."""
    from pathlib import Path

    import vcnc_gym

    root = Path(vcnc_gym.__file__).parent
    builders = sorted(str(p.relative_to(root)) for p in root.rglob("*.py") if "leggauss(" in p.read_text())
    assert builders == ["geometry/arclength.py", "geometry/quadrature.py"]


def test_bezier_arc_length_through_a_cusp():
    """A cubic Bezier whose speed is zero at h = 1/2 (control points (0,0), (1,1), (0,1), (1,0): a cusp); the
    shared quadrature against scipy's QUADPACK on the same |dp/dh|, written here from Bernstein's formula."""
    from vcnc_gym.geometry.corners import bezier_arc_length
    from vcnc_gym.geometry.quadrature import arc_length

    p = np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [1.0, 0.0]])

    def speed(h):
        d = 3 * ((1 - h) ** 2 * (p[1] - p[0]) + 2 * h * (1 - h) * (p[2] - p[1]) + h**2 * (p[3] - p[2]))
        return float(np.hypot(*d))

    ref = quad(speed, 0, 0.5, epsabs=0, epsrel=1e-13)[0] + quad(speed, 0.5, 1, epsabs=0, epsrel=1e-13)[0]
    assert speed(0.5) == 0.0
    assert bezier_arc_length(p) == pytest.approx(ref, rel=1e-11)
    assert arc_length(np.vectorize(speed, otypes=[float]), np.array([0.0, 0.5, 1.0]), nodes=7) == pytest.approx(
        ref, rel=1e-11
    )
