"""Tests of the warm-started contour error (project_point_warm) and of the projector's tables.

The warm start must change nothing but the cost: on every query its distance
equals the global search's (project_point, itself checked against geomdl in
tests/test_contour.py) to below 1e-9 mm, and its foot lies at that distance.
Checked along the env's reference paths offset by random-walk errors (the
foot carried from step to step as the env does), with jumps, with feet far
from the truth, around centres of curvature, on random curves with C0
corners, from numba ``prange`` threads, and on a subset against the geomdl
oracle of tests/test_contour.py.  The tables the shortcuts rest on (piece
polynomials, convexity bounds, isolation radii) are checked against the
NURBS evaluator and dense sampling.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit, prange

from test_contour import TOL as ORACLE_TOL
from test_contour import Oracle, corner_parameters
from test_geometry import random_curve
from vcnc_gym.contour import NO_FOOT, ContourProjector, project_point, project_point_warm
from vcnc_gym.contour import projector as P
from vcnc_gym.geometry import NurbsCurve, heart, omega
from vcnc_gym.motion import SCurveFeedrate, interpolate

TOL = 1e-9  # mm: warm against global


class Shape:
    """A contour, its projector, its reference path (the env's settings) and oracle, built once."""

    def __init__(self, name):
        self.name = name
        self.curve = {"heart": heart, "omega": omega}[name]()
        self.proj = ContourProjector(self.curve)
        self.path = interpolate(self.curve, SCurveFeedrate(feedrate=100.0, ramp_time=0.12), 1e-4).position
        self._oracle = None
        self._corners = None

    @property
    def oracle(self):
        if self._oracle is None:
            self._oracle = Oracle(self.curve)
        return self._oracle

    @property
    def corners(self):
        if self._corners is None:
            self._corners = corner_parameters(self.oracle, self.curve, 4 if self.name == "omega" else 3)
        return self._corners


@pytest.fixture(scope="module", params=["heart", "omega"])
def shape(request):
    return Shape(request.param)


def walk(rng, k: int, r_min: float, r_max: float, step: float) -> np.ndarray:
    """(k, 2) offsets in mm: radius and angle both random walks, the radius folded into [r_min, r_max]."""
    span = r_max - r_min
    s = np.cumsum(rng.normal(0.0, step, k)) + rng.uniform(0.0, span)
    radius = r_min + np.abs((s + span) % (2.0 * span) - span)  # reflect into [0, span]
    angle = np.cumsum(rng.normal(0.0, step / max(r_max, 1e-3), k)) + rng.uniform(0.0, 2.0 * np.pi)
    return radius[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])


def check_warm(proj, q, d_warm, u_warm, label):
    """Warm distances equal the global ones and the feet lie at them; returns the global distances."""
    d_glob, _u = proj.project(q)
    dev = np.abs(d_warm - d_glob)
    worst = int(np.argmax(dev))
    assert dev[worst] < TOL, f"{label}: warm {d_warm[worst]!r} vs global {d_glob[worst]!r} at q={q[worst].tolist()}"
    lo, hi = proj.curve.u_range
    assert np.all((u_warm >= lo) & (u_warm <= hi))
    foot = np.linalg.norm(proj.curve.points(u_warm) - q, axis=1)
    np.testing.assert_allclose(foot, d_warm, rtol=0, atol=TOL, err_msg=label)
    return d_glob


# --------------------------------------------------------------------------- trajectories


@pytest.mark.parametrize("band", [(0.0, 0.02, 0.001), (1.0, 3.0, 0.01)], ids=["0-20um", "1-3mm"])
def test_reference_path_with_random_walk_error(shape, band):
    """The whole reference path (dt = 0.1 ms) offset by a random-walk error, foot carried."""
    rng = np.random.default_rng(20 + int(band[1] * 10))
    q = shape.path + walk(rng, len(shape.path), *band)
    d, u = shape.proj.track(q)
    d_glob = check_warm(shape.proj, q, d, u, f"{shape.name} walk {band}")
    assert d_glob.max() <= band[1] + 1e-9  # the path lies on the curve


def test_near_the_corners_far_from_the_curve(shape):
    """1-3 mm errors along the stretches around the sharpest corners, inside and past the centres."""
    curve = shape.curve
    rng = np.random.default_rng(31)
    lo, hi = curve.u_range
    for uc in shape.corners:
        us = np.clip(np.linspace(uc - 0.02 * (hi - lo), uc + 0.02 * (hi - lo), 2000), lo, hi)
        q = curve.points(us) + walk(rng, len(us), 1.0, 3.0, 0.01)
        d, u = shape.proj.track(q)
        check_warm(shape.proj, q, d, u, f"{shape.name} corner {uc}")


def test_jumps(shape):
    """The tool teleports every 97 steps: to a random grid point, far outside the grid, onto the
    curve at a random u, or across the contour; the stale foot must not matter."""
    proj = shape.proj
    rng = np.random.default_rng(41)
    q = shape.path[::5] + walk(rng, len(shape.path[::5]), 0.0, 0.02, 0.002)
    g_lo = proj.grid_origin
    g_hi = g_lo + proj.grid_shape * proj.cell_size
    centre = 0.5 * (g_lo + g_hi)
    for k in range(50, len(q), 97):
        kind = (k // 97) % 4
        if kind == 0:
            q[k] = rng.uniform(g_lo, g_hi)
        elif kind == 1:
            q[k] = centre + 300.0 * rng.normal(size=2)
        elif kind == 2:
            q[k] = proj.curve.point(rng.uniform(*proj.curve.u_range)) + rng.normal(0.0, 0.01, 2)
        else:
            q[k] = 2.0 * centre - q[k]
    d, u = proj.track(q)
    check_warm(proj, q, d, u, f"{shape.name} jumps")


def test_bad_previous_foot(shape):
    """Points near the curve (1 nm to 3 mm) with u_prev drawn anywhere: at random, at the range
    ends, at knots and exactly at piece ends."""
    proj = shape.proj
    curve = shape.curve
    rng = np.random.default_rng(51)
    lo, hi = curve.u_range
    k = 3000
    ang = rng.uniform(0.0, 2.0 * np.pi, k)
    dist = 10.0 ** rng.uniform(-6.0, math.log10(3.0), k)
    q = curve.points(rng.uniform(lo, hi, k)) + dist[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    specials = np.concatenate([[lo, hi], np.unique(curve.knots), proj.piece_u])
    u_prev = np.where(rng.random(k) < 0.5, rng.uniform(lo, hi, k), rng.choice(specials, k))
    d, u = proj.project_warm(q, u_prev)
    check_warm(proj, q, d, u, f"{shape.name} bad u_prev")
    # and each point with the foot of the previous point (a trajectory of jumps)
    d, u = proj.track(q, u_start=lo)
    check_warm(proj, q, d, u, f"{shape.name} chained jumps")


def test_heart_closing_point():
    """The heart ends where it starts: past the end, coming from u = 6, the foot is the start."""
    shape = Shape("heart")
    proj = shape.proj
    end = shape.curve.derivatives(6.0, 1)
    tangent = end[1] / np.linalg.norm(end[1])
    for u_prev in (6.0, 5.999, 5.9):
        for s in (1e-6, 1e-3, 0.1):
            d, u = proj.project_warm(end[0] + s * tangent, u_prev)
            assert u < 0.01 and d < 0.1 * s * s + 1e-12  # curvature there is about 0.11 / mm
    q = shape.path[-3000:] + 0.3 * tangent * np.linspace(0.0, 1.0, 3000)[:, None]  # run on past the end
    d, u = proj.track(q, u_start=5.9)
    check_warm(proj, q, d, u, "heart closing point")
    assert u[0] > 5.0 and u[-1] < 0.01


def test_centres_of_curvature(shape):
    """Around the corners' centres of curvature, where g is flat and the foot may sit on either
    side, with u_prev on either side of the corner and at it."""
    proj = shape.proj
    oracle = shape.oracle
    rng = np.random.default_rng(61)
    lo, hi = shape.curve.u_range
    qs, priors = [], []
    for uc in shape.corners:
        p, _t, n, kappa = oracle.frame(uc)
        radius = 1.0 / abs(kappa)
        centre = p + n * np.sign(kappa) * radius
        for s in (0.0, 1e-4, 1e-2, 0.3, 1.5, 5.0):
            pts = centre + rng.normal(0.0, s, (20, 2)) * radius
            for du in (-0.01, -1e-4, 0.0, 1e-4, 0.01):
                qs.append(pts)
                priors.append(np.full(len(pts), min(hi, max(lo, uc + du * (hi - lo)))))
    q = np.vstack(qs)
    d, u = proj.project_warm(q, np.concatenate(priors))
    check_warm(proj, q, d, u, f"{shape.name} centres of curvature")


def test_against_the_geomdl_oracle(shape):
    """A subset of warm queries (trajectory near and far, corner centres) against geomdl."""
    proj = shape.proj
    oracle = shape.oracle
    rng = np.random.default_rng(71)
    idx = rng.choice(len(shape.path), 120, replace=False)
    near = shape.path + walk(rng, len(shape.path), 0.0, 0.02, 0.001)
    far = shape.path + walk(rng, len(shape.path), 1.0, 3.0, 0.01)
    centres = []
    for uc in shape.corners:
        p, _t, n, kappa = oracle.frame(uc)
        centres.append(p + n * np.sign(kappa) / abs(kappa) + rng.normal(0.0, 0.05, (15, 2)) / abs(kappa))
    for label, q_all, sel in (("near", near, idx), ("far", far, idx), ("centres", np.vstack(centres), None)):
        d_all, u_all = proj.track(q_all)
        q, d = (q_all, d_all) if sel is None else (q_all[sel], d_all[sel])
        ref = np.array([oracle.project(x)[0] for x in q])
        dev = np.abs(d - ref)
        assert dev.max() < ORACLE_TOL, f"{shape.name} {label}: {dev.max():.3e} mm from geomdl"


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_random_curves_with_corners(degree):
    """Random rational curves with knots of multiplicity p (C0 corners): trajectories along the
    curve through the corners, random u_prev, and a few points against the oracle."""
    rng = np.random.default_rng(800 + degree)
    curve = NurbsCurve(*random_curve(rng, degree, force_full_multiplicity=True))
    proj = ContourProjector(curve)
    lo, hi = curve.u_range
    us = np.linspace(lo, hi, 4000)
    for band in ((0.0, 0.02, 0.001), (0.5, 3.0, 0.01)):
        q = curve.points(us) + walk(rng, len(us), *band)
        d, u = proj.track(q)
        check_warm(proj, q, d, u, f"random p={degree} walk {band}")
    q = curve.points(rng.uniform(lo, hi, 500)) + rng.normal(0.0, 1.0, (500, 2))
    d, u = proj.project_warm(q, rng.uniform(lo, hi, 500))
    check_warm(proj, q, d, u, f"random p={degree} bad u_prev")
    oracle = Oracle(curve, per_span=200)
    ref = np.array([oracle.project(x)[0] for x in q[:40]])
    assert np.abs(d[:40] - ref).max() < ORACLE_TOL


# --------------------------------------------------------------------------- the kernel's contract


def test_no_previous_foot_is_the_global_search():
    """NaN (NO_FOOT) and any u_prev outside the range give project_point's result, bit for bit."""
    proj = ContourProjector(omega())
    args = (proj.arrays, np.empty((3, 2)))
    rng = np.random.default_rng(81)
    for q in rng.uniform(-5.0, 20.0, (20, 2)):
        ref = project_point(q[0], q[1], *args)
        for u_prev in (NO_FOOT, -1.0, 1.5, -np.inf, np.inf):
            assert project_point_warm(q[0], q[1], u_prev, *args) == ref
    assert math.isnan(NO_FOOT)
    d, u = proj.project_warm(rng.uniform(-5.0, 20.0, (20, 2)), NO_FOOT)
    assert d.shape == u.shape == (20,)


def test_non_finite_points_in_the_kernels():
    """A diverged plant's NaN or inf position gives NaN or inf at once (no crash, no endless walk);
    the NaN foot then means "no previous foot"."""
    proj = ContourProjector(heart())
    args = (proj.arrays, np.empty((3, 2)))
    for qx, qy, want in (
        (np.nan, 1.0, np.nan),
        (1.0, np.nan, np.nan),
        (np.inf, 0.0, np.inf),
        (0.0, -np.inf, np.inf),
        (np.nan, np.inf, np.nan),
    ):
        for d, u in (
            project_point(qx, qy, *args),
            project_point_warm(qx, qy, 1.0, *args),
            project_point_warm(qx, qy, NO_FOOT, *args),
        ):
            assert (math.isnan(d) if math.isnan(want) else d == want) and math.isnan(u)


def test_single_point_and_scalar_u_prev():
    proj = ContourProjector(heart())
    d, u = proj.project_warm([45.0, 1.0], 2.9)
    assert np.ndim(d) == 0 and np.ndim(u) == 0
    assert d == pytest.approx(proj.project([45.0, 1.0])[0], abs=TOL)


@pytest.mark.parametrize("bad", [-0.1, 6.5, np.inf, -np.inf])
def test_u_prev_outside_the_range_raises(bad):
    proj = ContourProjector(heart())
    with pytest.raises(ValueError, match=r"u_prev must be NaN \(no previous foot\) or a curve parameter"):
        proj.project_warm([[1.0, 2.0], [3.0, 4.0]], [0.5, bad])
    with pytest.raises(ValueError, match="u_prev must be NaN"):
        proj.track([[1.0, 2.0]], u_start=bad)


def test_non_finite_points_raise():
    proj = ContourProjector(omega())
    with pytest.raises(ValueError, match="points must be finite"):
        proj.project_warm([[1.0, np.nan]], 0.5)
    with pytest.raises(ValueError, match="points must be finite"):
        proj.track([[1.0, 2.0], [np.inf, 0.0]])


@njit(parallel=True, cache=False)
def _machines_in_parallel(paths, pieces, der, dist, feet):
    """N machines, each following its own path, one prange thread per machine, own scratch."""
    for m in prange(paths.shape[0]):
        u = np.nan
        for k in range(paths.shape[1]):
            dist[m, k], u = project_point_warm(paths[m, k, 0], paths[m, k, 1], u, pieces, der[m])
            feet[m, k] = u


def test_concurrent_calls_from_prange_threads():
    """Machines stepped in a numba prange loop (each with its own der row) get exactly what
    each gets alone."""
    shape = Shape("heart")
    rng = np.random.default_rng(91)
    n_machines, steps = 8, 3000
    paths = np.stack(
        [
            shape.path[rng.integers(0, len(shape.path) - steps) :][:steps]
            + walk(rng, steps, 0.0, 0.02 + 0.5 * (m % 3), 0.002)
            for m in range(n_machines)
        ]
    )
    dist = np.empty((n_machines, steps))
    feet = np.empty((n_machines, steps))
    der = np.zeros((n_machines, 3, 2))
    _machines_in_parallel(paths, shape.proj.arrays, der, dist, feet)
    for m in range(n_machines):
        d, u = shape.proj.track(paths[m])
        np.testing.assert_array_equal(dist[m], d)
        np.testing.assert_array_equal(feet[m], u)


# --------------------------------------------------------------------------- the tables


def _pieces_and_curves():
    out = [ContourProjector(heart()), ContourProjector(omega())]
    for degree in (1, 2, 3, 4, 5):
        rng = np.random.default_rng(900 + degree)
        out.append(ContourProjector(NurbsCurve(*random_curve(rng, degree, force_full_multiplicity=True))))
    return out


@pytest.fixture(scope="module")
def projectors():
    return _pieces_and_curves()


def test_piece_polynomials_match_the_nurbs_evaluator(projectors):
    """C, C', C'' from the pieces' Taylor polynomials against the A2.3/A4.2 evaluator (itself
    checked against geomdl in tests/test_geometry.py), relative to each quantity's size."""
    for proj in projectors:
        rng = np.random.default_rng(3)
        n = len(proj.piece_sag)
        idx = rng.integers(0, n, 3000)
        frac = rng.uniform(1e-6, 1.0 - 1e-6, 3000)
        us = proj.piece_u[idx] + frac * (proj.piece_u[idx + 1] - proj.piece_u[idx])
        ref = proj.curve.derivatives_array(us, 2)
        got = np.empty_like(ref)
        der = np.empty((3, 2))
        for k in range(len(us)):
            t = us[k] - proj.piece_u[idx[k]]
            P._piece_derivatives(proj.piece_table, proj.curve.degree, idx[k], t, der)
            got[k] = der
        scale = np.abs(ref).max(axis=(0, 2))
        err = np.abs(got - ref).max(axis=(0, 2)) / scale
        assert err.max() < 1e-11, (proj.curve.degree, err)


def test_convexity_bounds_hold_on_dense_samples(projectors):
    """Wherever a piece's stored bound says g = |C - q|^2 / 2 is convex for q, g'' > 0 at 65
    samples of the piece (q drawn within 0-5 mm of the piece and around its centre of curvature)."""
    rng = np.random.default_rng(5)
    for proj in projectors:
        n = len(proj.piece_sag)
        t = proj.piece_table
        s = np.linspace(0.0, 1.0, 65)
        us = proj.piece_u[:-1, None] + s[None, :] * np.diff(proj.piece_u)[:, None]
        us[:, -1] = np.nextafter(proj.piece_u[1:], -np.inf)
        der = proj.curve.derivatives_array(us.reshape(-1), 2).reshape(n, len(s), 3, 2)
        c, d1, d2 = der[:, :, 0], der[:, :, 1], der[:, :, 2]
        kappa = (d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]) / np.linalg.norm(d1, axis=-1) ** 3
        normal = np.stack([-d1[..., 1], d1[..., 0]], axis=-1) / np.linalg.norm(d1, axis=-1)[..., None]
        mid = len(s) // 2
        centre = c[:, mid] + normal[:, mid] / np.where(kappa[:, mid] == 0, np.inf, kappa[:, mid])[:, None]
        claimed = 0
        for _ in range(40):
            q = c[:, mid] + rng.normal(0.0, 1.0, (n, 2)) * 10.0 ** rng.uniform(-4, math.log10(5.0), (n, 1))
            q = np.where(rng.random((n, 1)) < 0.3, centre + rng.normal(0.0, 0.2, (n, 2)), q)
            m = t[:-1, P._CONVEX : P._CONVEX + 2] - q
            bound = (
                t[:-1, P._CONVEX + 5]
                + np.sum(m * t[:-1, P._CONVEX + 2 : P._CONVEX + 4], axis=1)
                - np.linalg.norm(m, axis=1) * t[:-1, P._CONVEX + 4]
            )
            g2 = np.sum(d1 * d1, axis=-1) + np.sum((c - q[:, None, :]) * d2, axis=-1)
            convex = bound > 0.0
            claimed += convex.sum()
            bad = convex & (g2.min(axis=1) <= 0.0)
            assert not bad.any(), f"degree {proj.curve.degree}: pieces {np.nonzero(bad)[0][:5]}"
        assert claimed > 0


def test_isolation_radii_hold_on_dense_samples(projectors):
    """No sampled point of a piece other than i-1, i, i+1 lies within piece i's isolation radius
    of a sampled point of piece i (33 samples per piece)."""
    from scipy.spatial import cKDTree

    for proj in projectors:
        n = len(proj.piece_sag)
        s = np.linspace(0.0, 1.0, 33)
        us = proj.piece_u[:-1, None] + s[None, :] * np.diff(proj.piece_u)[:, None]
        pts = proj.curve.points(us.reshape(-1))
        owner = np.repeat(np.arange(n), len(s))
        tree = cKDTree(pts)
        rho = proj.piece_table[:-1, P._ISOLATION]
        assert np.all(rho >= 0.0) and rho.max() > 0.0
        for i in range(n):
            if rho[i] == 0.0:
                continue
            near = tree.query_ball_point(pts[owner == i], rho[i])
            others = {j for hits in near for j in owner[hits] if abs(j - i) > 1}
            assert not others, f"degree {proj.curve.degree}: piece {i} within {rho[i]} mm of {sorted(others)[:5]}"
