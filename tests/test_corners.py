"""Corner-smoothed polylines, Simba et al.'s eqs. (12)-(23) (vcnc_gym.geometry.corners).

Oracles that are not the code under test: eq. (12) written out as a direct
Bernstein sum, geomdl (points and derivatives of the blends and of the whole
degree-5 NURBS), scipy (quad for the arc length, minimize_scalar for the
closest point to the corner), finite differences for the jerk factor of
eq. (17), brute-force grids for n_opt, and the statements of Simba et al.'s
section III about Fig. 4.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from geomdl import BSpline
from scipy.integrate import quad
from scipy.optimize import minimize_scalar

from vcnc_gym.geometry import NurbsCurve
from vcnc_gym.geometry.corners import (
    bezier_arc_length,
    bezier_derivatives,
    blend_control_points,
    blend_curvature,
    corner_error,
    corner_length,
    design_corner,
    interior_angles,
    peak_curvature,
    polyline,
    smooth_polyline,
)
from vcnc_gym.geometry.shapes import corners_path, corners_vertices

A_MAX = 4000.0  # mm/s^2 (vcnc_gym.motion.jlap.SIMBA_A_MAX)
J_MAX = 1.6e5  # mm/s^3
EPS = 0.05  # mm, Simba et al.'s section IV-A


@pytest.fixture(scope="module")
def path():
    return smooth_polyline(corners_vertices(), EPS, A_MAX, J_MAX)


# --------------------------------------------------------------------------
# independent evaluations
# --------------------------------------------------------------------------


def eq12(p, h):
    """Simba et al.'s eq. (12) exactly as printed."""
    h = np.asarray(h, dtype=float)[:, None]
    return (
        (1 - h) ** 5 * p[0]
        + 5 * h * (1 - h) ** 4 * p[1]
        + 10 * h**2 * (1 - h) ** 3 * p[2]
        + 10 * h**3 * (1 - h) ** 2 * p[3]
        + 5 * h**4 * (1 - h) * p[4]
        + h**5 * p[5]
    )


def geomdl_bezier(p):
    c = BSpline.Curve()
    c.degree = 5
    c.ctrlpts = np.asarray(p, dtype=float).tolist()
    c.knotvector = [0.0] * 6 + [1.0] * 6
    return c


def geomdl_derivatives(c, h, order):
    return np.array([c.derivatives(float(x), order) for x in np.atleast_1d(h)])


def kappa_geomdl(p, h):
    """Curvature |p' x p''| / |p'|^3 from geomdl's derivatives."""
    d = geomdl_derivatives(geomdl_bezier(p), h, 2)
    p1, p2 = d[:, 1], d[:, 2]
    return np.abs(p1[:, 0] * p2[:, 1] - p1[:, 1] * p2[:, 0]) / np.linalg.norm(p1, axis=1) ** 3


def unit_blend(theta, eps, n):
    l_t = corner_length(theta, eps, n)
    return blend_control_points([0.0, 0.0], [1.0, 0.0], [-math.cos(theta), math.sin(theta)], l_t, n)


def numpy_peaks(theta, eps, ns, h):
    """max_h kappa and max_h varkappa for each n, by brute force on the grid h (numpy Bernstein sums)."""
    return numpy_peaks_of(np.array([unit_blend(theta, eps, n) for n in ns]), h)


def numpy_peaks_of(p, h):
    """max_h kappa and max_h varkappa of each blend p (N, 6, 2) on the grid h."""
    d1 = 5 * eq_deg(np.diff(p, axis=1), h)  # (N, H, 2)
    d2 = 20 * eq_deg(np.diff(p, 2, axis=1), h)
    d3 = 60 * eq_deg(np.diff(p, 3, axis=1), h)
    g = np.sum(d1 * d1, -1)
    d = np.sum(d1 * d2, -1)
    kappa = np.abs(cross2(d1, d2)) / g**1.5
    c = 4 * d * d - np.sum(d2 * d2, -1) * g - np.sum(d1 * d3, -1) * g
    sss = d3 * (g * g)[..., None] - 3 * (d * g)[..., None] * d2 + c[..., None] * d1
    return kappa.max(axis=1), (np.linalg.norm(sss, axis=-1) / g**3.5).max(axis=1)


def cross2(a, b):
    """z-component of the cross product of 2-vectors (arrays of them along the first axes)."""
    a, b = np.asarray(a), np.asarray(b)
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def eq_deg(q, h):
    """Bernstein sums of any degree, numpy: control points q (N, m+1, 2) at h (H,) -> (N, H, 2)."""
    m = q.shape[1] - 1
    basis = np.array([math.comb(m, i) * h**i * (1 - h) ** (m - i) for i in range(m + 1)])  # (m+1, H)
    return np.einsum("ih,nic->nhc", basis, q)


# --------------------------------------------------------------------------
# the blend, eqs. (12) and (13), Fig. 3
# --------------------------------------------------------------------------


@pytest.mark.parametrize("theta_deg, n", [(30, 0.3), (60, 0.73), (90, 1.32), (135, 2.5), (10, 0.1)])
def test_blend_matches_bernstein_sum_and_geomdl(theta_deg, n):
    p = unit_blend(math.radians(theta_deg), EPS, n) + [12.0, -3.0]
    h = np.linspace(0, 1, 101)
    ours = bezier_derivatives(p, h, 3)
    np.testing.assert_allclose(ours[:, 0], eq12(p, h), atol=1e-13, rtol=0)
    ref = geomdl_derivatives(geomdl_bezier(p), h, 3)
    scale = np.abs(ref).max(axis=(0, 2))
    for k in range(4):
        assert np.abs(ours[:, k] - ref[:, k]).max() <= 1e-11 * scale[k], k


def test_control_points_are_placed_as_in_fig3():
    theta, n, l_t = math.radians(60), 0.8, 0.3
    g = np.array([5.0, 7.0])
    d_in = np.array([math.cos(0.4), math.sin(0.4)])
    turn = math.pi - theta  # a left turn of pi - theta
    d_out = np.array([math.cos(0.4 + turn), math.sin(0.4 + turn)])
    p = blend_control_points(g, d_in, d_out, l_t, n)
    l_2 = l_t / (2 * n + 1)
    l_1 = n * l_2
    dist = np.linalg.norm(np.diff(np.vstack([p[:3], g, p[3:]]), axis=0), axis=1)
    np.testing.assert_allclose(dist, [l_1, l_1, l_2, l_2, l_1, l_1], rtol=1e-13)
    # p1..p3 on the incoming leg behind G, p4..p6 on the outgoing leg
    for q in p[:3]:
        assert abs(cross2(g - q, d_in)) < 1e-14 and np.dot(g - q, d_in) > 0
    for q in p[3:]:
        assert abs(cross2(q - g, d_out)) < 1e-14 and np.dot(q - g, d_out) > 0
    legs = np.array([p[0] - g, p[5] - g])
    cos = np.dot(legs[0], legs[1]) / np.prod(np.linalg.norm(legs, axis=1))
    assert math.isclose(math.acos(cos), theta, rel_tol=1e-12)


@pytest.mark.parametrize("theta_deg", [5, 30, 60, 90, 120, 170])
@pytest.mark.parametrize("n", [0.2, 1.0, 4.0])
def test_eq13_is_the_distance_from_the_corner_to_the_blend(theta_deg, n):
    """eps of eq. (13), measured on the curve: the closest point of the blend to G, found by scipy."""
    theta = math.radians(theta_deg)
    p = unit_blend(theta, EPS, n)
    l_t = corner_length(theta, EPS, n)
    assert math.isclose(corner_error(theta, l_t, n), EPS, rel_tol=1e-14)
    h = np.linspace(0, 1, 2001)
    dist = np.linalg.norm(eq12(p, h), axis=1)
    i = int(np.argmin(dist))
    res = minimize_scalar(
        lambda x: float(np.linalg.norm(eq12(p, [x])[0])),
        bounds=(h[max(i - 1, 0)], h[min(i + 1, 2000)]),
        method="bounded",
        options={"xatol": 1e-12},
    )
    assert abs(res.fun - EPS) < 1e-12
    assert abs(res.x - 0.5) < 1e-5  # on the bisector


def test_epsilon_on_simba_path(path):
    """The smoothed NURBS passes eps from every sharp corner, and no point of the sharp path is further."""
    curve = path.curve
    for k, g in enumerate(path.vertices[1:-1]):
        u0, u1 = path.blend_u[k]
        res = minimize_scalar(
            lambda u: float(np.linalg.norm(curve.point(u) - g)),
            bounds=(u0, u1),
            method="bounded",
            options={"xatol": 1e-12},
        )
        assert abs(res.fun - EPS) < 1e-12
        # directed Hausdorff distance from the sharp legs near G to the blend: attained at G
        l_t = path.corners[k].l_t
        dense = curve.points(np.linspace(u0, u1, 4001))
        back = (path.vertices[k] - g) / np.linalg.norm(path.vertices[k] - g)
        ahead = (path.vertices[k + 2] - g) / np.linalg.norm(path.vertices[k + 2] - g)
        r = np.linspace(0, l_t, 200)[:, None]
        legs = np.concatenate([g + r * back, g + r * ahead])
        far = np.min(np.linalg.norm(legs[:, None, :] - dense[None], axis=2), axis=1).max()
        assert EPS - 1e-6 < far < EPS + 1e-6


# --------------------------------------------------------------------------
# curvature, eqs. (14) and (17)
# --------------------------------------------------------------------------


def test_curvature_against_geomdl_and_jerk_factor_against_finite_differences():
    p = unit_blend(math.radians(60), EPS, 0.73)
    h = np.linspace(0.02, 0.98, 49)
    kappa, varkappa = blend_curvature(p, h)
    np.testing.assert_allclose(kappa, kappa_geomdl(p, h), rtol=1e-10)
    # varkappa = |d^3p/ds^3| = sqrt(kappa_s^2 + kappa^4), kappa_s by central differences in h
    dh = 1e-5
    dk = (kappa_geomdl(p, h + dh) - kappa_geomdl(p, h - dh)) / (2 * dh)
    speed = np.linalg.norm(geomdl_derivatives(geomdl_bezier(p), h, 1)[:, 1], axis=1)
    ref = np.sqrt((dk / speed) ** 2 + kappa**4)
    np.testing.assert_allclose(varkappa, ref, rtol=1e-6)


def test_peak_curvature_scales_with_epsilon():
    """kappa ~ 1/eps and varkappa ~ 1/eps^2 (Simba et al., section III)."""
    k1, j1 = peak_curvature(math.radians(45), 0.05, 0.9)
    k2, j2 = peak_curvature(math.radians(45), 0.2, 0.9)
    assert math.isclose(k1 / k2, 4.0, rel_tol=1e-9)
    assert math.isclose(j1 / j2, 16.0, rel_tol=1e-9)


def test_curvature_is_continuous_where_blends_meet_lines(path):
    """Zero curvature on both sides of every joint; C, C', C'' continuous in u (unit speed)."""
    curve = path.curve
    for u in np.unique(path.blend_u):
        left = curve.derivatives(u - 1e-11, 3)
        right = curve.derivatives(u, 3)
        for side in (left, right):
            assert abs(cross2(side[1], side[2])) / np.linalg.norm(side[1]) ** 3 < 1e-6  # 1/mm
            assert math.isclose(np.linalg.norm(side[1]), 1.0, rel_tol=1e-7)
        np.testing.assert_allclose(left[:3], right[:3], atol=1e-6)
        # curvature grows linearly into the blend: kappa(u + d) / d is finite and non-zero
        ks = []
        for d in (1e-4, 2e-4):
            c = curve.derivatives(u + d if u in path.blend_u[:, 0] else u - d, 2)
            ks.append(abs(cross2(c[1], c[2])) / np.linalg.norm(c[1]) ** 3)
        assert 0 < ks[0] and math.isclose(ks[1] / ks[0], 2.0, rel_tol=1e-2)
    # the blend on its own: curvature exactly zero at h = 0 and 1
    for p in path.blends:
        k, _ = blend_curvature(p, [0.0, 1.0])
        assert np.all(k < 1e-9)


# --------------------------------------------------------------------------
# n_opt, eqs. (15)-(20), and the corner segment, eqs. (21)-(23)
# --------------------------------------------------------------------------


@pytest.mark.parametrize("theta_deg", [30, 60, 90])
@pytest.mark.parametrize("a_max, j_max", [(A_MAX, J_MAX), (A_MAX, 1e7), (100.0, 1e5)])
def test_n_opt_against_brute_force(theta_deg, a_max, j_max):
    theta = math.radians(theta_deg)
    d = design_corner(theta, EPS, a_max, j_max)
    ns = np.exp(np.linspace(np.log(0.05), np.log(20), 800))
    step = np.log(ns[1] / ns[0])
    h = np.linspace(0, 1, 2001)
    k_max, j_peak = numpy_peaks(theta, EPS, ns, h)
    v_a = np.sqrt(a_max / k_max)
    v_j = np.cbrt(j_max / j_peak)
    v = np.minimum(v_a, v_j)
    for ours, brute in ((d.n_a, ns[np.argmax(v_a)]), (d.n_j, ns[np.argmax(v_j)]), (d.n, ns[np.argmax(v)])):
        assert abs(math.log(ours / brute)) <= 1.5 * step
    # our optimum is at least as fast as every grid point (up to the grid in h underestimating a peak
    # between its samples), and the brute-force evaluation agrees at our n
    assert d.v_max >= v.max() * (1 - 1e-7)
    k_ours, j_ours = numpy_peaks(theta, EPS, [d.n], np.linspace(0, 1, 200001))
    assert math.isclose(d.v_max, min(math.sqrt(a_max / k_ours[0]), math.cbrt(j_max / j_ours[0])), rel_tol=1e-7)
    assert math.isclose(d.v_max_a, math.sqrt(a_max / d.kappa_max), rel_tol=1e-14)
    # Simba et al., Fig. 4: n_opt lies between n_opt,a and n_opt,j
    assert min(d.n_a, d.n_j) * (1 - 1e-6) <= d.n <= max(d.n_a, d.n_j) * (1 + 1e-6)


@pytest.mark.parametrize("theta_deg", [30, 60, 90, 120])
def test_n_opt_lt_of_ref16_is_slightly_smaller_than_n_opt_a(theta_deg):
    """Simba et al.'s section III: n_opt,lt (ref. [16], l_t = 1 fixed) is always slightly smaller than n_opt,a."""
    theta = math.radians(theta_deg)
    ns = np.exp(np.linspace(np.log(0.05), np.log(20), 1000))
    p = np.array([blend_control_points([0, 0], [1, 0], [-math.cos(theta), math.sin(theta)], 1.0, n) for n in ns])
    n_lt = ns[np.argmin(numpy_peaks_of(p, np.linspace(0, 1, 2001))[0])]
    n_a = design_corner(theta, EPS, A_MAX, J_MAX).n_a
    assert 0.7 * n_a < n_lt < n_a


def test_corner_segment_and_arc_length(path):
    curve = path.curve
    for k, d in enumerate(path.corners):
        assert d.l_s >= d.l_t
        assert math.isclose(d.l_s, corner_length(d.theta, EPS, max(d.n_j, d.n_a)), rel_tol=1e-14)  # eq. (22)
        assert math.isclose(d.delta_s, 2 * (d.l_s - d.l_t) + d.s_arc, rel_tol=1e-14)  # eq. (23)
        assert math.isclose(path.zones[k, 1] - path.zones[k, 0], d.delta_s, rel_tol=1e-9)
        p = path.blends[k]
        c = geomdl_bezier(p)
        speed = lambda x: float(np.linalg.norm(c.derivatives(x, 1)[1]))  # noqa: E731
        ref, _ = quad(speed, 0, 1, epsabs=0, epsrel=1e-13, limit=200)
        assert math.isclose(d.s_arc, ref, rel_tol=1e-11)  # eq. (21)
        assert math.isclose(bezier_arc_length(p), ref, rel_tol=1e-11)
        assert math.isclose(curve.arc_length(*path.blend_u[k]), ref, rel_tol=1e-10)
        assert math.isclose(path.blend_s[k, 1] - path.blend_s[k, 0], ref, rel_tol=1e-11)
    assert math.isclose(curve.arc_length(), path.length, rel_tol=1e-12)


# --------------------------------------------------------------------------
# the whole path as a NURBS
# --------------------------------------------------------------------------


def test_smoothed_path_is_an_exact_degree5_nurbs(path):
    curve = path.curve
    assert curve.degree == 5 and np.all(curve.weights == 1.0)
    knots, counts = np.unique(curve.knots, return_counts=True)
    assert counts[0] == counts[-1] == 6 and np.all(counts[1:-1] == 5)
    assert len(knots) == 2 * len(path.corners) + 2  # lines and blends alternate
    # geomdl on the same definition (knots normalised to [0, 1])
    lo, hi = curve.u_range
    g = BSpline.Curve(normalize_kv=False)
    g.degree = 5
    g.ctrlpts = curve.control_points.tolist()
    g.knotvector = ((curve.knots - lo) / (hi - lo)).tolist()
    us = np.random.default_rng(1).uniform(lo, hi, 300)
    ours = curve.derivatives_array(us, 2)
    ref = np.array([g.derivatives((u - lo) / (hi - lo), 2) for u in us])
    for k in range(3):
        scale = max(1.0, np.abs(ours[:, k]).max())
        np.testing.assert_allclose(ours[:, k], ref[:, k] / (hi - lo) ** k, atol=1e-9 * scale)
    # each blend span of the NURBS is eq. (12) on that blend's control points
    for k, p in enumerate(path.blends):
        h = np.linspace(0, 1, 51)
        u = path.blend_u[k, 0] + h * (path.blend_u[k, 1] - path.blend_u[k, 0])
        np.testing.assert_allclose(curve.points(u), eq12(p, h), atol=1e-12)
    # the lines lie on the sharp polyline, at unit parametric speed
    v = path.vertices
    line_u = np.concatenate([[lo], path.blend_u.reshape(-1), [hi]]).reshape(-1, 2)
    for k, (a, b) in enumerate(line_u):
        u = np.linspace(a, b, 21)
        d = curve.derivatives_array(u, 1)
        seg = (v[k + 1] - v[k]) / np.linalg.norm(v[k + 1] - v[k])
        assert np.abs(cross2(d[:, 0] - v[k], seg)).max() < 1e-12
        np.testing.assert_allclose(d[:, 1], np.tile(seg, (21, 1)), atol=1e-12)


def test_sharp_polyline_is_degree1_in_arc_length():
    curve = corners_path(smooth=False)
    v = corners_vertices()
    assert curve.degree == 1
    np.testing.assert_allclose(curve.u_range, (0.0, 200.0), atol=1e-12)
    np.testing.assert_allclose(curve.points(np.arange(5) * 50.0), v, atol=1e-12)
    assert math.isclose(curve.arc_length(), 200.0, rel_tol=1e-13)


def test_simba_test_path():
    v = corners_vertices()
    np.testing.assert_allclose(np.degrees(interior_angles(v)), [30, 60, 90], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(np.diff(v, axis=0), axis=1), 50.0, rtol=1e-14)
    c = corners_path(smooth=True, epsilon=EPS)
    assert c.degree == 5
    smooth = smooth_polyline(v, EPS, A_MAX, J_MAX)
    np.testing.assert_array_equal(c.control_points, smooth.curve.control_points)


# --------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "vertices, match",
    [
        ([[0, 0], [10, 0], [10, 0], [10, 10]], "vertices 1 and 2 are repeated"),
        ([[0, 0], [10, 0], [20, 0], [20, 10]], "vertices 0, 1, 2 are collinear"),
        ([[0, 0], [10, 0], [10, 10], [10, 5]], r"vertices 1, 2, 3 are collinear \(the path turns back"),
        ([[0, 0]], r"shape \(K, 2\)"),
        ([[0, 0, 0], [1, 1, 1]], r"shape \(K, 2\)"),
        ([[0, 0], [np.nan, 1]], "finite"),
    ],
)
def test_bad_vertices(vertices, match):
    with pytest.raises(ValueError, match=match):
        smooth_polyline(vertices, EPS, A_MAX, J_MAX)
    with pytest.raises(ValueError, match=match):
        polyline(vertices)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(epsilon=0.0), "epsilon must be"),
        (dict(epsilon=-1.0), "epsilon"),
        (dict(epsilon=float("nan")), "epsilon"),
        (dict(epsilon=True), "epsilon"),
        (dict(a_max=0.0), r"a_max must be"),
        (dict(j_max=-5.0), r"j_max must be"),
        (dict(j_max=float("inf")), "j_max"),
        (dict(epsilon=30.0), r"epsilon = 30 mm is too large for segment 1 \(vertices 1 to 2"),
    ],
)
def test_bad_limits(kwargs, match):
    args = dict(epsilon=EPS, a_max=A_MAX, j_max=J_MAX) | kwargs
    with pytest.raises(ValueError, match=match):
        smooth_polyline(corners_vertices(), **args)


def test_epsilon_too_large_for_a_short_end_segment():
    with pytest.raises(ValueError, match="segment 0"):
        smooth_polyline([[0, 0], [0.1, 0], [0.1, 50]], EPS, A_MAX, J_MAX)


def test_bad_angles_and_ratios():
    with pytest.raises(ValueError, match="theta"):
        design_corner(math.pi, EPS, A_MAX, J_MAX)
    with pytest.raises(ValueError, match="theta"):
        corner_length(0.0, EPS, 1.0)
    with pytest.raises(ValueError, match="n must be"):
        corner_length(1.0, EPS, 0.0)
    with pytest.raises(ValueError, match="l_t"):
        corner_error(1.0, -1.0, 1.0)
    assert isinstance(polyline([[0, 0], [1, 1]]), NurbsCurve)
