"""Contour error: the shortest distance from a point to a whole curve.

The contour error is the distance from the actual tool position to the
closest point of the reference contour, not to the current reference point
(that is the tracking error, seed 002 eq. (2) and Fig. 1).

How it is found exactly and fast enough for every control period:

1. At construction the curve is cut into short pieces [u_i, u_i+1]; each
   piece's chord and a bound h_i on how far the curve strays from that chord
   are stored, and a uniform grid of square cells lists the pieces whose
   chord, widened by h_i, touches each cell.
2. A query visits grid cells in rings around the point until no unvisited
   piece can be closer than the best upper bound found (chord distance + h_i).
3. Every piece whose lower bound (chord distance - h_i) is below that upper
   bound is refined on the true curve: f(u) = (C(u) - q) . C'(u) = 0 is
   solved by Newton's method safeguarded by bisection, on a bracket
   f(lo) < 0 < f(hi) (C' is stored at the piece ends).  When
   g(u) = |C(u) - q|^2 / 2 is provably convex on the piece (q well inside
   the radius of curvature: |C - q| |C''| < |C'|^2 from stored per-piece
   bounds) there is one minimum; otherwise (q near or beyond the centre of
   curvature, where g is flat and may have several minima) the piece is
   cut in 16 and every sign change of f is bracketed and solved.

A point outside the grid starts from the nearest cell (valid, only slower).

Its own numerical error is far below a nanometre (see tests/test_contour.py,
which checks it against dense sampling plus an independent Newton solver).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..geometry.nurbs import curve_derivatives_into, workspace_size

__all__ = ["ContourProjector", "project_point"]

_MAX_ITERATIONS = 60  # Newton steps, each falling back on bisection of the bracket
_SUBDIVISIONS = 16  # sub-intervals of a piece on which g is not provably convex
_FINAL_STEP = 1e-5  # mm along the curve: below it the last Newton step is taken on a Taylor expansion


@njit(cache=True)
def _chord_distance(qx, qy, ax, ay, bx, by):
    """Distance from (qx, qy) to the segment a-b and the fraction t of its foot."""
    dx = bx - ax
    dy = by - ay
    ll = dx * dx + dy * dy
    t = 0.0
    if ll > 0.0:
        t = ((qx - ax) * dx + (qy - ay) * dy) / ll
        t = min(1.0, max(0.0, t))
    ex = qx - ax - t * dx
    ey = qy - ay - t * dy
    return np.sqrt(ex * ex + ey * ey), t


@njit(cache=True)
def _bracketed_newton(control_points, weights, knots, degree, qx, qy, lo, hi, u0, der, work):
    """Local minimum of |C(u) - q| in [lo, hi] given f(lo) < 0 < f(hi): (dist mm, u).

    Newton's method on f(u) = (C(u) - q) . C'(u), each step kept inside the
    bracket (else a bisection step), the bracket shrunk by the sign of f.  It
    cannot stall where f' = |C'|^2 + (C - q) . C'' is small or negative.
    """
    u = u0
    if not (lo < u < hi):
        u = 0.5 * (lo + hi)
    best_d = np.inf
    best_u = u
    for _ in range(_MAX_ITERATIONS):
        curve_derivatives_into(control_points, weights, knots, degree, u, 2, der, work)
        rx = der[0, 0] - qx
        ry = der[0, 1] - qy
        speed2 = der[1, 0] * der[1, 0] + der[1, 1] * der[1, 1]
        f = rx * der[1, 0] + ry * der[1, 1]
        fp = speed2 + rx * der[2, 0] + ry * der[2, 1]
        d = np.sqrt(rx * rx + ry * ry)
        if d < best_d:
            best_d = d
            best_u = u
        if f < 0.0:
            lo = u
        elif f > 0.0:
            hi = u
        else:
            break
        speed = np.sqrt(speed2)
        newton = False
        u_new = 0.5 * (lo + hi)
        if fp > 0.0:
            u_try = u - f / fp
            # strictly inside: C is never evaluated at the bracket's ends (a piece end
            # may be a knot where C' jumps); a converged last step is not evaluated at all
            if lo < u_try < hi or (lo <= u_try <= hi and abs(u_try - u) * speed < _FINAL_STEP):
                u_new = u_try
                newton = True
        du = u_new - u
        if newton and abs(du) * speed < _FINAL_STEP:
            # last step taken on the second-order Taylor expansion of C:
            # its error is O(du^3), far below a picometre
            rx += der[1, 0] * du + 0.5 * der[2, 0] * du * du
            ry += der[1, 1] * du + 0.5 * der[2, 1] * du * du
            d = np.sqrt(rx * rx + ry * ry)
            if d < best_d:
                best_d = d
                best_u = u_new
            break
        if (hi - lo) * speed < 1e-13:
            break
        u = u_new
    return best_d, best_u


@njit(cache=True)
def _refine_on_piece(control_points, weights, knots, degree, qx, qy, u0, i, piece_u, piece_table,
                     reach, der, work):
    """Closest point of the curve piece i to q: (dist mm, u).

    ``piece_table`` rows hold C(u_i), C'(u_i) from the right and from the left
    (they differ at a knot of multiplicity p) and, for piece i, a radius below
    which g = |C - q|^2 / 2 is convex on the piece; ``reach`` bounds |C(u) - q|
    on the piece.  C is evaluated only strictly inside the piece; its end
    points (stored exactly) cover a minimum on its boundary.
    """
    ua = piece_u[i]
    ub = piece_u[i + 1]
    ax = piece_table[i, 0] - qx
    ay = piece_table[i, 1] - qy
    bx = piece_table[i + 1, 0] - qx
    by = piece_table[i + 1, 1] - qy
    fa = ax * piece_table[i, 2] + ay * piece_table[i, 3]
    fb = bx * piece_table[i + 1, 4] + by * piece_table[i + 1, 5]
    best_d = np.sqrt(ax * ax + ay * ay)
    best_u = ua
    d = np.sqrt(bx * bx + by * by)
    if d < best_d:
        best_d = d
        best_u = ub
    if reach < piece_table[i, 6]:
        # g'' = |C'|^2 + (C - q) . C'' > 0 on the whole piece: f increases, one minimum
        if fa < 0.0 < fb:
            d, u = _bracketed_newton(control_points, weights, knots, degree, qx, qy, ua, ub, u0, der, work)
            if d < best_d:
                best_d = d
                best_u = u
        return best_d, best_u
    # g may have several minima here: bracket every sign change of f on sub-intervals
    ul = ua
    fl = fa
    for j in range(1, _SUBDIVISIONS + 1):
        if j == _SUBDIVISIONS:
            ur = ub
            fr = fb
        else:
            ur = ua + (ub - ua) * j / _SUBDIVISIONS
            curve_derivatives_into(control_points, weights, knots, degree, ur, 1, der, work)
            rx = der[0, 0] - qx
            ry = der[0, 1] - qy
            fr = rx * der[1, 0] + ry * der[1, 1]
            d = np.sqrt(rx * rx + ry * ry)
            if d < best_d:
                best_d = d
                best_u = ur
        if fl < 0.0 < fr:
            d, u = _bracketed_newton(control_points, weights, knots, degree, qx, qy, ul, ur, u0, der, work)
            if d < best_d:
                best_d = d
                best_u = u
        ul = ur
        fl = fr
    return best_d, best_u


@njit(cache=True)
def project_point(
    qx, qy,
    control_points, weights, knots, degree,
    piece_u, piece_table, piece_sag,
    grid_origin, cell_size, grid_shape, cell_start, cell_pieces,
    der, work,
):
    """Closest point of the curve to (qx, qy): returns (distance mm, u).

    ``piece_table`` is ``ContourProjector.piece_table``: per piece end, the
    point, the tangent C' from the right and from the left, and (for the
    piece starting there) its convexity radius.

    ``der`` is a (3, 2) scratch array and ``work`` holds
    ``workspace_size(degree, 2)`` floats.  A point outside the grid starts
    from the nearest cell: the clamped point is no farther from any cell than
    the point itself, so the ring bound stays valid (only slower).
    """
    nx = grid_shape[0]
    ny = grid_shape[1]
    cx = min(max(int(np.floor((qx - grid_origin[0]) / cell_size)), 0), nx - 1)
    cy = min(max(int(np.floor((qy - grid_origin[1]) / cell_size)), 0), ny - 1)
    # pass 1: rings of cells until no unvisited piece can beat the best upper bound
    best_upper = np.inf
    r = 0
    while True:
        for ix in range(max(cx - r, 0), min(cx + r + 1, nx)):
            on_edge_x = ix == cx - r or ix == cx + r
            for iy in range(max(cy - r, 0), min(cy + r + 1, ny)):
                if not on_edge_x and iy != cy - r and iy != cy + r:
                    continue  # inside the ring: visited already
                cell = ix * ny + iy
                for k in range(cell_start[cell], cell_start[cell + 1]):
                    i = cell_pieces[k]
                    d, _t = _chord_distance(qx, qy, piece_table[i, 0], piece_table[i, 1],
                                            piece_table[i + 1, 0], piece_table[i + 1, 1])
                    best_upper = min(best_upper, d + piece_sag[i])
        if r * cell_size >= best_upper or r > max(nx, ny):
            break
        r += 1
    # pass 2: Newton on every visited piece whose lower bound can beat it
    best_d = np.inf
    best_u = piece_u[0]
    for ix in range(max(cx - r, 0), min(cx + r + 1, nx)):
        for iy in range(max(cy - r, 0), min(cy + r + 1, ny)):
            cell = ix * ny + iy
            for k in range(cell_start[cell], cell_start[cell + 1]):
                i = cell_pieces[k]
                ax = piece_table[i, 0]
                ay = piece_table[i, 1]
                bx = piece_table[i + 1, 0]
                by = piece_table[i + 1, 1]
                d, t = _chord_distance(qx, qy, ax, ay, bx, by)
                if d - piece_sag[i] > min(best_upper, best_d):
                    continue
                u0 = piece_u[i] + t * (piece_u[i + 1] - piece_u[i])
                # |C(u) - q| on the piece is at most: to the chord, along it, off it
                reach = d + np.hypot(bx - ax, by - ay) + piece_sag[i]
                dd, uu = _refine_on_piece(control_points, weights, knots, degree, qx, qy,
                                          u0, i, piece_u, piece_table, reach, der, work)
                if dd < best_d:
                    best_d = dd
                    best_u = uu
    return best_d, best_u


@njit(cache=True)
def _project_points(qs, control_points, weights, knots, degree, piece_u, piece_table, piece_sag,
                    grid_origin, cell_size, grid_shape, cell_start, cell_pieces, dist, us):
    der = np.empty((3, 2))
    work = np.empty(workspace_size(degree, 2))
    for k in range(qs.shape[0]):
        dist[k], us[k] = project_point(qs[k, 0], qs[k, 1], control_points, weights, knots, degree,
                                       piece_u, piece_table, piece_sag, grid_origin, cell_size,
                                       grid_shape, cell_start, cell_pieces, der, work)


class ContourProjector:
    """Closest points and contour errors for one curve.

    Parameters
    ----------
    curve : NurbsCurve
        The reference contour (any object with ``kernel_args`` and ``u_range``
        and ``derivatives_array``).
    piece_length : float
        Target arc length of the chord pieces in mm (default 0.5).
    cell_size : float
        Edge of the square grid cells in mm (default 1.0).
    margin : float
        How far around the curve's bounding box the grid reaches, in mm;
        points farther out are still answered exactly, only more slowly.

    Examples
    --------
    >>> from vcnc_gym.geometry import heart
    >>> proj = ContourProjector(heart())
    >>> d, u = proj.project([45.0, 0.0])
    """

    def __init__(self, curve, piece_length: float = 0.5, cell_size: float = 1.0, margin: float = 10.0):
        for name, v in (("piece_length", piece_length), ("cell_size", cell_size), ("margin", margin)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        self.curve = curve
        self.kernel_args = curve.kernel_args
        self.piece_u, self.piece_points, self.piece_sag = self._cut(curve, piece_length)
        self.piece_table = self._table(curve, self.piece_u, self.piece_points)
        self.cell_size = float(cell_size)
        self._build_grid(margin)

    @staticmethod
    def _cut(curve, piece_length):
        """Pieces: per knot span, equal parameter steps, ~piece_length of arc each."""
        knots = np.unique(curve.knots)
        lo, hi = curve.u_range
        spans = [(a, b) for a, b in zip(knots[:-1], knots[1:]) if a >= lo and b <= hi and b > a]
        us = []
        for a, b in spans:
            n = max(2, int(np.ceil(curve.arc_length(a, b) / piece_length)))
            us.append(np.linspace(a, b, n + 1)[:-1])
        us.append([hi])
        piece_u = np.concatenate(us)
        # refine where a piece turns too much: its deviation above 5 % of its chord
        for _ in range(8):
            dev, chord = ContourProjector._chord_deviation(curve, piece_u)
            bad = dev > 0.05 * np.maximum(chord, 1e-9)
            if not bad.any():
                break
            mids = 0.5 * (piece_u[:-1][bad] + piece_u[1:][bad])
            piece_u = np.sort(np.concatenate([piece_u, mids]))
        dev, _ = ContourProjector._chord_deviation(curve, piece_u)
        # the sampled deviation, doubled, bounds the curve's distance from its chord
        sag = 2.0 * dev + 1e-9
        return piece_u, curve.points(piece_u), sag

    @staticmethod
    def _table(curve, piece_u, piece_points, sub: int = 16):
        """Per piece end: C, C' from the right, C' from the left and (piece i) the
        convexity radius, shape (n+1, 7).

        On piece i, g(u) = |C(u) - q|^2 / 2 has g'' = |C'|^2 + (C - q) . C''
        >= min|C'|^2 - |C - q| max|C''| > 0 when |C - q| < min|C'|^2 / max|C''|.
        The sampled minimum speed is halved and the sampled maximum of |C''|
        doubled, as the sampled deviation is doubled for the sag.  C' and C''
        of piece i are sampled on [u_i, u_i+1) and at u_i+1 from the left.
        """
        lo, hi = curve.u_range
        left_u = np.maximum(np.nextafter(piece_u, -np.inf), lo)  # u_i from the left (in span i-1)
        fine = piece_u[:-1, None] + np.linspace(0.0, 1.0, sub + 1)[None, :] * np.diff(piece_u)[:, None]
        fine[:, -1] = left_u[1:]
        der = curve.derivatives_array(fine.reshape(-1), 2).reshape(fine.shape + (3, 2))
        speed2 = np.sum(der[..., 1, :] ** 2, axis=-1).min(axis=1)
        acc = np.linalg.norm(der[..., 2, :], axis=-1).max(axis=1)
        with np.errstate(divide="ignore"):
            radius = np.where(acc > 0.0, 0.5 * speed2 / (2.0 * acc), np.inf)
        right = curve.derivatives_array(piece_u, 1)[:, 1, :]
        left = curve.derivatives_array(left_u, 1)[:, 1, :]
        # at a knot of multiplicity p, C' jumps: the sides differ; elsewhere keep the exact value
        at_knot = np.isin(piece_u, curve.knots)
        table = np.zeros((len(piece_u), 7))
        table[:, :2] = piece_points
        table[:, 2:4] = right
        table[:, 4:6] = np.where(at_knot[:, None], left, right)
        table[0, 4:6] = right[0]
        table[-1, 2:6] = np.concatenate([right[-1], right[-1]])  # C'(u_end) is taken from the left
        table[:-1, 6] = radius
        return table

    @staticmethod
    def _chord_deviation(curve, piece_u, sub: int = 16):
        """Largest sampled distance of each piece from its chord, and the chord length (mm)."""
        fine = piece_u[:-1, None] + np.linspace(0.0, 1.0, sub + 1)[None, :] * np.diff(piece_u)[:, None]
        pts = curve.points(fine.reshape(-1)).reshape(fine.shape + (2,))
        a, ab = pts[:, :1, :], pts[:, -1:, :] - pts[:, :1, :]
        ll = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)
        t = np.clip(np.sum((pts - a) * ab, axis=-1) / ll, 0.0, 1.0)
        dev = np.linalg.norm(pts - a - t[..., None] * ab, axis=-1).max(axis=1)
        return dev, np.sqrt(ll[:, 0])

    def _build_grid(self, margin):
        p = self.piece_points
        lo = p.min(axis=0) - margin
        hi = p.max(axis=0) + margin
        shape = np.maximum(np.ceil((hi - lo) / self.cell_size).astype(np.int64), 1)
        buckets = [[] for _ in range(int(shape[0] * shape[1]))]
        for i in range(len(self.piece_sag)):
            a, b, h = p[i], p[i + 1], self.piece_sag[i]
            c0 = np.floor((np.minimum(a, b) - h - lo) / self.cell_size).astype(int)
            c1 = np.floor((np.maximum(a, b) + h - lo) / self.cell_size).astype(int)
            c0 = np.clip(c0, 0, shape - 1)
            c1 = np.clip(c1, 0, shape - 1)
            for ix in range(c0[0], c1[0] + 1):
                for iy in range(c0[1], c1[1] + 1):
                    buckets[ix * shape[1] + iy].append(i)
        self.grid_origin = lo.astype(np.float64)
        self.grid_shape = shape
        self.cell_start = np.concatenate([[0], np.cumsum([len(b) for b in buckets])]).astype(np.int64)
        self.cell_pieces = np.array([i for b in buckets for i in b], dtype=np.int64)

    @property
    def arrays(self) -> tuple:
        """The arrays :func:`project_point` takes after the curve's kernel args.

        The second is :attr:`piece_table` (points, one-sided tangents and
        convexity radii), not :attr:`piece_points`.
        """
        return (self.piece_u, self.piece_table, self.piece_sag, self.grid_origin, self.cell_size,
                self.grid_shape, self.cell_start, self.cell_pieces)

    def project(self, points):
        """Closest curve points to ``points`` (mm, (2,) or (k, 2)): (distance mm, u)."""
        q = np.ascontiguousarray(points, dtype=np.float64)
        single = q.ndim == 1
        q = q.reshape(-1, 2)
        if not np.all(np.isfinite(q)):
            raise ValueError("points must be finite")
        dist = np.empty(len(q))
        us = np.empty(len(q))
        _project_points(q, *self.kernel_args, *self.arrays, dist, us)
        return (dist[0], us[0]) if single else (dist, us)

    def contour_error(self, points):
        """Shortest distance from ``points`` to the whole curve, in mm."""
        return self.project(points)[0]
