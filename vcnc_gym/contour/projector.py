"""Contour error: the shortest distance from a point to a whole curve.

The contour error is the distance from the actual tool position to the
closest point of the reference contour, not to the current reference point
(that is the tracking error, Simba et al., eq. (2) and Fig. 1).

How it is found exactly and fast enough for every control period:

1. At construction the curve is cut into short pieces [u_i, u_i+1], each
   inside one knot span.  Per piece the table stores its chord, a bound h_i
   on how far the curve strays from that chord (the sag), the Taylor
   coefficients of its homogeneous polynomials (the curve on a span is a
   rational polynomial: evaluating it costs a few Horner steps instead of
   The NURBS Book's A2.3 + A4.2), bounds that prove g(u) = ``|C(u) - q|^2`` / 2
   convex on the piece for a given q, and an isolation radius (how far the
   piece is from every piece but its two neighbours).  A uniform grid of
   square cells lists the pieces whose chord, widened by h_i, touches each
   cell.
2. Global search (:func:`project_point`): grid cells are visited in rings
   around the point until no unvisited piece can be closer than the best
   upper bound found (chord distance + h_i); then every piece in the disk of
   that radius whose lower bound (chord distance - h_i) can beat the best
   point so far is refined on the true curve.
3. Refining a piece solves f(u) = (C(u) - q) . C'(u) = 0 by Newton's method
   safeguarded by bisection, on a bracket f(lo) < 0 < f(hi) (C' is stored
   at the piece ends).  When g is provably convex on the piece (q on the
   outer side of the bend, or inside it well within the radius of
   curvature) there is one minimum; otherwise (q near or beyond the centre
   of curvature, where g is flat and may have several minima) the piece is
   cut in 16 and every sign change of f is bracketed and solved.
4. Warm start (:func:`project_point_warm`, one call per control period
   carrying the foot parameter): the previous foot's piece (and, if the
   foot runs off it, the next ones) is refined from the previous foot, then
   the two pieces beside the foot's.  If twice the distance found is within
   the foot piece's isolation radius no other piece can come closer and the
   point is final; otherwise the search of 2. certifies it, starting from
   that bound (a bad previous foot makes it the global search).

A point outside the grid starts from the nearest cell (valid, only slower).

Its own numerical error is far below a nanometre (see tests/test_contour.py,
which checks it against dense sampling plus an independent Newton solver,
and tests/test_contour_warm.py for the warm start).

The query kernels allocate nothing and are compiled without numba's
reference counting (``_nrt=False``): with it every array argument of every
inner call costs an atomic increment and decrement, which measured 2.5x the
work of a whole query (and would contend between ``prange`` threads sharing
the tables).  They read the tables and write only the caller's scratch, so
threads may share one projector.  They take the tables as one record,
:class:`ProjectorArrays` (``ContourProjector.arrays``), and the scratch
``der`` (3, 2): ``project_point_warm(qx, qy, u_prev, arrays, der)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..geometry.nurbs import basis_derivatives, find_span

__all__ = ["ContourProjector", "NO_FOOT", "ProjectorArrays", "project_point", "project_point_warm"]

#: ``u_prev`` meaning "no previous foot" for :func:`project_point_warm`.
NO_FOOT = np.nan

_MAX_ITERATIONS = 60  # Newton steps, each falling back on bisection of the bracket
_SUBDIVISIONS = 16  # sub-intervals of a piece on which g is not provably convex
_FINAL_STEP = 1e-5  # mm along the curve: below it the last Newton step is taken on a Taylor expansion
_WALK = 8  # pieces project_point_warm walks along the curve from the previous foot's piece
# columns of the piece table (row i: piece end u_i and, where it applies, piece i = [u_i, u_i+1])
_CONVEX = 6  # 6 numbers (M, A, rho, k) bounding g'' = |C'|^2 + (C - q) . C'' on piece i, see _table
_ISOLATION = 12  # lower bound (mm) on the distance from piece i to every piece but i-1, i, i+1
_POLY = 13  # first of the 3 (p + 1) coefficients of piece i's homogeneous polynomials
_ISOLATION_CELLS = 1.0  # isolation radii are computed out to this many grid cells
_NEAR_CELLS = 4.0  # a best distance within this many grid cells is certified without the chord rings first
# the empty range of pieces already refined, for _search (numpy ints: numba compiles a function once per integer
# literal argument, so literals 0 and -1 would compile a second _search and _certify)
_NONE_LO = np.int64(0)
_NONE_HI = np.int64(-1)


class ProjectorArrays(NamedTuple):
    """Everything the query kernels read, one argument (a heterogeneous tuple to numba):
    :attr:`ContourProjector.arrays`.  Built by :class:`ContourProjector`; the kernels do not check it."""

    degree: int  #: p of the curve (its pieces' polynomials have p + 1 coefficients)
    piece_u: np.ndarray  #: (n+1,) float64, the piece ends u_i
    piece_table: np.ndarray  #: (n+1, _POLY + 3 (p+1)) float64, see ContourProjector._table
    piece_sag: np.ndarray  #: (n,) float64, mm: how far piece i strays from its chord
    grid_origin: np.ndarray  #: (2,) float64, mm: the lower left corner of the grid
    cell_size: float  #: mm, the edge of a square cell
    grid_shape: np.ndarray  #: (2,) int64, cells along x and y
    cell_start: np.ndarray  #: (cells+1,) int64: cell c lists cell_pieces[cell_start[c]:cell_start[c+1]]
    cell_pieces: np.ndarray  #: int64, the pieces of every cell, cell by cell


@njit(cache=True)
def _piece_polynomials(control_points, weights, knots, degree, piece_u, table):
    """Write each piece's homogeneous polynomials into ``table[i, _POLY:]``.

    On a knot span the homogeneous curve (w C, w) = sum N_j (w_j P_j, w_j) is
    a polynomial of degree p (Jahanpour et al. (2014), eq. (2)); on piece i it is stored as
    its Taylor expansion at u_i, coefficient k = (d^k/du^k (w C, w))(u_i) / k!
    as (x, y, w) in columns _POLY + 3k .. _POLY + 3k + 2, from the basis
    derivatives of The NURBS Book A2.3 on the span holding [u_i, u_i+1].
    """
    n = control_points.shape[0] - 1
    p = degree
    q = p + 1
    out = q * q + 4 * q
    work = np.empty(out + q * q)
    for i in range(piece_u.shape[0] - 1):
        span = find_span(n, p, piece_u[i], knots)
        basis_derivatives(span, piece_u[i], p, p, knots, work, out)
        factorial = 1.0
        for k in range(q):
            if k > 0:
                factorial *= k
            ax = 0.0
            ay = 0.0
            aw = 0.0
            for j in range(q):
                c = span - p + j
                nw = work[out + k * q + j] * weights[c]
                ax += nw * control_points[c, 0]
                ay += nw * control_points[c, 1]
                aw += nw
            table[i, _POLY + 3 * k] = ax / factorial
            table[i, _POLY + 3 * k + 1] = ay / factorial
            table[i, _POLY + 3 * k + 2] = aw / factorial


@njit(cache=True, _nrt=False)
def _piece_derivatives(piece_table, degree, i, t, der):
    """C, C', C'' at u = u_i + t on piece i, into der (3, 2), from its polynomials.

    Horner's scheme for the homogeneous coordinates (A, w) and their first
    two derivatives, then the quotient rule (The NURBS Book eq. (4.8), as
    its A4.2): C = A / w, C' = (A' - w' C) / w, C'' = (A'' - 2 w' C' - w'' C) / w.
    """
    c = _POLY + 3 * degree
    x0 = piece_table[i, c]
    y0 = piece_table[i, c + 1]
    w0 = piece_table[i, c + 2]
    x1 = 0.0
    y1 = 0.0
    w1 = 0.0
    x2 = 0.0
    y2 = 0.0
    w2 = 0.0
    for k in range(degree - 1, -1, -1):
        c = _POLY + 3 * k
        x2 = x2 * t + x1
        y2 = y2 * t + y1
        w2 = w2 * t + w1
        x1 = x1 * t + x0
        y1 = y1 * t + y0
        w1 = w1 * t + w0
        x0 = x0 * t + piece_table[i, c]
        y0 = y0 * t + piece_table[i, c + 1]
        w0 = w0 * t + piece_table[i, c + 2]
    inv_w = 1.0 / w0
    cx = x0 * inv_w
    cy = y0 * inv_w
    dx = (x1 - w1 * cx) * inv_w
    dy = (y1 - w1 * cy) * inv_w
    der[0, 0] = cx
    der[0, 1] = cy
    der[1, 0] = dx
    der[1, 1] = dy
    der[2, 0] = (2.0 * (x2 - w1 * dx - w2 * cx)) * inv_w
    der[2, 1] = (2.0 * (y2 - w1 * dy - w2 * cy)) * inv_w


@njit(cache=True, _nrt=False)
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


@njit(cache=True, _nrt=False)
def _bracketed_newton(piece_table, degree, i, ui, qx, qy, lo, hi, u0, der):
    """Local minimum of ``|C(u) - q|`` in [lo, hi] given f(lo) < 0 < f(hi): (dist mm, u).

    [lo, hi] lies on piece i, which starts at ``ui``.

    Newton's method on f(u) = (C(u) - q) . C'(u), each step kept inside the
    bracket (else a bisection step), the bracket shrunk by the sign of f.  It
    cannot stall where f' = ``|C'|^2`` + (C - q) . C'' is small or negative.
    """
    u = u0
    if not (lo < u < hi):
        u = 0.5 * (lo + hi)
    best_d = np.inf
    best_u = u
    for _ in range(_MAX_ITERATIONS):
        _piece_derivatives(piece_table, degree, i, u - ui, der)
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


@njit(cache=True, _nrt=False)
def _refine_on_piece(degree, qx, qy, u0, i, piece_u, piece_table, der):
    """Closest point of the curve piece i to q: (dist mm, u).

    ``piece_table`` rows hold C(u_i), C'(u_i) from the right and from the left
    (they differ at a knot of multiplicity p) and, for piece i, the bounds of
    :meth:`ContourProjector._table` that prove g = ``|C - q|^2`` / 2 convex on
    the piece for this q, or not.  C is evaluated only strictly inside the
    piece; its end points (stored exactly) cover a minimum on its boundary.
    ``u0`` is the first Newton iterate (the bracket's middle if it lies
    outside it).
    """
    ua = piece_u[i]
    ub = piece_u[i + 1]
    ax = piece_table[i, 0] - qx
    ay = piece_table[i, 1] - qy
    bx = piece_table[i + 1, 0] - qx
    by = piece_table[i + 1, 1] - qy
    fa = ax * piece_table[i, 2] + ay * piece_table[i, 3]
    fb = bx * piece_table[i + 1, 4] + by * piece_table[i + 1, 5]
    da = np.sqrt(ax * ax + ay * ay)
    db = np.sqrt(bx * bx + by * by)
    best_d = da
    best_u = ua
    if db < best_d:
        best_d = db
        best_u = ub
    mx = piece_table[i, _CONVEX] - qx
    my = piece_table[i, _CONVEX + 1] - qy
    convexity = (
        piece_table[i, _CONVEX + 5]
        + mx * piece_table[i, _CONVEX + 2]
        + my * piece_table[i, _CONVEX + 3]
        - np.sqrt(mx * mx + my * my) * piece_table[i, _CONVEX + 4]
    )
    if convexity > 0.0:
        # g'' = |C'|^2 + (C - q) . C'' > 0 on the whole piece: f increases, one minimum
        if fa < 0.0 < fb:
            d, u = _bracketed_newton(piece_table, degree, i, ua, qx, qy, ua, ub, u0, der)
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
            _piece_derivatives(piece_table, degree, i, ur - ua, der)
            rx = der[0, 0] - qx
            ry = der[0, 1] - qy
            fr = rx * der[1, 0] + ry * der[1, 1]
            d = np.sqrt(rx * rx + ry * ry)
            if d < best_d:
                best_d = d
                best_u = ur
        if fl < 0.0 < fr:
            d, u = _bracketed_newton(piece_table, degree, i, ua, qx, qy, ul, ur, u0, der)
            if d < best_d:
                best_d = d
                best_u = u
        ul = ur
        fl = fr
    return best_d, best_u


@njit(cache=True, _nrt=False)
def _refine_from_chord(degree, qx, qy, i, limit, piece_u, piece_table, piece_sag, der):
    """:func:`_refine_on_piece` started from the foot of q on piece i's chord, or
    (inf, u_i) at once if no point of the piece can be closer than ``limit`` (mm)."""
    d, t = _chord_distance(qx, qy, piece_table[i, 0], piece_table[i, 1], piece_table[i + 1, 0], piece_table[i + 1, 1])
    if d - piece_sag[i] > limit:
        return np.inf, piece_u[i]
    return _refine_on_piece(
        degree, qx, qy, piece_u[i] + t * (piece_u[i + 1] - piece_u[i]), i, piece_u, piece_table, der
    )


@njit(cache=True, _nrt=False)
def _cell_index(x, origin, cell_size, n):
    """Grid index of coordinate x (mm), clamped to [0, n - 1] (also for x = +-inf; 0 for NaN)."""
    v = (x - origin) / cell_size
    if not v >= 1.0:
        return 0
    if v >= n - 1:
        return n - 1
    return int(v)


@njit(cache=True, _nrt=False)
def _clearance(qx, qy, ix0, ix1, iy0, iy1, grid_origin, cell_size, grid_shape):
    """Distance (mm) from q, inside the cell block [ix0, ix1] x [iy0, iy1], to any
    point of a piece listed in no cell of the block.

    Every piece is listed in the cells its chord box widened by its sag
    touches, and the border cells of the grid reach out to infinity (a box
    beyond the grid is clamped onto them), so such a piece lies wholly
    outside the block: beyond one of its sides that is not the grid's border.
    ``inf`` when the block is the whole grid.
    """
    c = np.inf
    if ix0 > 0:
        c = min(c, qx - (grid_origin[0] + ix0 * cell_size))
    if ix1 < grid_shape[0] - 1:
        c = min(c, grid_origin[0] + (ix1 + 1) * cell_size - qx)
    if iy0 > 0:
        c = min(c, qy - (grid_origin[1] + iy0 * cell_size))
    if iy1 < grid_shape[1] - 1:
        c = min(c, grid_origin[1] + (iy1 + 1) * cell_size - qy)
    return c


@njit(cache=True, _nrt=False)
def _ring_bound(qx, qy, bound, pieces):
    """Tighten an upper bound (mm) on the distance from q to the curve from chords alone.

    Visits rings of cells around q's cell (the nearest cell if q is outside
    the grid), taking chord distance + sag of every piece met, while the disk
    of radius ``bound`` around q reaches beyond the block visited so far
    (pieces beyond it are at least :func:`_clearance` away, so they cannot
    lower the bound once the disk fits).  No curve evaluation.
    """
    _degree, piece_u, piece_table, piece_sag, grid_origin, cell_size, grid_shape, cell_start, cell_pieces = pieces
    nx = grid_shape[0]
    ny = grid_shape[1]
    cx = _cell_index(qx, grid_origin[0], cell_size, nx)
    cy = _cell_index(qy, grid_origin[1], cell_size, ny)
    if _clearance(qx, qy, cx, cx, cy, cy, grid_origin, cell_size, grid_shape) >= bound:
        return bound  # the disk fits in q's own cell: nothing to gain here
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
                    d, _t = _chord_distance(
                        qx, qy, piece_table[i, 0], piece_table[i, 1], piece_table[i + 1, 0], piece_table[i + 1, 1]
                    )
                    bound = min(bound, d + piece_sag[i])
        if _clearance(qx, qy, cx - r, cx + r, cy - r, cy + r, grid_origin, cell_size, grid_shape) >= bound:
            break
        r += 1
    return bound


@njit(cache=True, _nrt=False)
def _segment_gap(ax, ay, bx, by, cx, cy, dx, dy):
    """Distance (mm) between the segments a-b and c-d (0 if they cross or touch)."""
    o1 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    o2 = (bx - ax) * (dy - ay) - (by - ay) * (dx - ax)
    o3 = (dx - cx) * (ay - cy) - (dy - cy) * (ax - cx)
    o4 = (dx - cx) * (by - cy) - (dy - cy) * (bx - cx)
    if o1 * o2 <= 0.0 and o3 * o4 <= 0.0:
        return 0.0
    return min(
        _chord_distance(ax, ay, cx, cy, dx, dy)[0],
        _chord_distance(bx, by, cx, cy, dx, dy)[0],
        _chord_distance(cx, cy, ax, ay, bx, by)[0],
        _chord_distance(dx, dy, ax, ay, bx, by)[0],
    )


@njit(cache=True)
def _isolation_radii(pieces, reach):
    """Write into ``piece_table[i, _ISOLATION]`` a lower bound (mm, at most ``reach``) on the
    distance from any point of piece i to any point of a piece other than i-1, i, i+1.

    From the chords: their distance less both sags.  The pieces listed in
    the cells around piece i's chord box widened by its sag + ``reach`` are
    checked; any other lies wholly outside those cells (see
    :func:`_clearance`), at least ``reach`` away.
    """
    _degree, piece_u, piece_table, piece_sag, grid_origin, cell_size, grid_shape, cell_start, cell_pieces = pieces
    nx = grid_shape[0]
    ny = grid_shape[1]
    for i in range(piece_sag.shape[0]):
        ax = piece_table[i, 0]
        ay = piece_table[i, 1]
        bx = piece_table[i + 1, 0]
        by = piece_table[i + 1, 1]
        w = piece_sag[i] + reach
        best = reach
        for ix in range(
            _cell_index(min(ax, bx) - w, grid_origin[0], cell_size, nx),
            _cell_index(max(ax, bx) + w, grid_origin[0], cell_size, nx) + 1,
        ):
            for iy in range(
                _cell_index(min(ay, by) - w, grid_origin[1], cell_size, ny),
                _cell_index(max(ay, by) + w, grid_origin[1], cell_size, ny) + 1,
            ):
                cell = ix * ny + iy
                for k in range(cell_start[cell], cell_start[cell + 1]):
                    j = cell_pieces[k]
                    if i - 1 <= j <= i + 1:
                        continue
                    gap = _segment_gap(
                        ax,
                        ay,
                        bx,
                        by,
                        piece_table[j, 0],
                        piece_table[j, 1],
                        piece_table[j + 1, 0],
                        piece_table[j + 1, 1],
                    )
                    best = min(best, gap - piece_sag[i] - piece_sag[j])
        piece_table[i, _ISOLATION] = max(best, 0.0)


@njit(cache=True, _nrt=False)
def _certify(qx, qy, bound, best_d, best_u, skip_lo, skip_hi, pieces, der):
    """The closest point, given an upper bound (mm) on its distance: (dist mm, u).

    Visits the cells the disk of radius min(bound, best_d) around q touches
    (border cells reaching out to infinity), skipping cells wholly outside
    it, and refines on the curve every piece whose lower bound (chord
    distance - sag) is below that radius, which shrinks as better points are
    found.  Pieces skip_lo..skip_hi were refined by the caller already and
    are left out; (best_d, best_u) is the best point found so far (inf if
    none).
    """
    _degree, piece_u, piece_table, piece_sag, grid_origin, cell_size, grid_shape, cell_start, cell_pieces = pieces
    nx = grid_shape[0]
    ny = grid_shape[1]
    ox = grid_origin[0]
    oy = grid_origin[1]
    lim = min(bound, best_d)
    ix0 = _cell_index(qx - lim, ox, cell_size, nx)
    ix1 = _cell_index(qx + lim, ox, cell_size, nx)
    iy0 = _cell_index(qy - lim, oy, cell_size, ny)
    iy1 = _cell_index(qy + lim, oy, cell_size, ny)
    for ix in range(ix0, ix1 + 1):
        # distance from q to the column of cells ix along x (0 if inside it)
        dx = 0.0
        if ix > 0:
            dx = max(dx, ox + ix * cell_size - qx)
        if ix < nx - 1:
            dx = max(dx, qx - (ox + (ix + 1) * cell_size))
        for iy in range(iy0, iy1 + 1):
            dy = 0.0
            if iy > 0:
                dy = max(dy, oy + iy * cell_size - qy)
            if iy < ny - 1:
                dy = max(dy, qy - (oy + (iy + 1) * cell_size))
            if dx * dx + dy * dy > lim * lim:
                continue  # the cell lies outside the disk
            cell = ix * ny + iy
            for k in range(cell_start[cell], cell_start[cell + 1]):
                i = cell_pieces[k]
                if skip_lo <= i <= skip_hi:
                    continue
                d, t = _chord_distance(
                    qx, qy, piece_table[i, 0], piece_table[i, 1], piece_table[i + 1, 0], piece_table[i + 1, 1]
                )
                if d - piece_sag[i] > lim:
                    continue
                u0 = piece_u[i] + t * (piece_u[i + 1] - piece_u[i])
                dd, uu = _refine_on_piece(pieces.degree, qx, qy, u0, i, piece_u, piece_table, der)
                if dd < best_d:
                    best_d = dd
                    best_u = uu
                    lim = min(lim, best_d)
    return best_d, best_u


@njit(cache=True, _nrt=False)
def _search(qx, qy, best_d, best_u, skip_lo, skip_hi, pieces, der):
    """The global closest point, given the best point found so far (best_d may be inf):
    :func:`_certify`, after a cheap chord bound from the rings around q
    (:func:`_ring_bound`) unless best_d is already within ``_NEAR_CELLS``
    cells (then the rings would cost as much as the certification)."""
    bound = best_d
    if not best_d <= _NEAR_CELLS * pieces.cell_size:
        bound = _ring_bound(qx, qy, best_d, pieces)
    return _certify(qx, qy, bound, best_d, best_u, skip_lo, skip_hi, pieces, der)


@njit(cache=True, _nrt=False)
def _not_finite(qx, qy):
    """The answer for a non-finite point: (NaN if a coordinate is NaN else inf, NaN)."""
    if qx != qx or qy != qy:
        return np.nan, np.nan
    return np.inf, np.nan


@njit(cache=True, _nrt=False)
def project_point(qx, qy, pieces, der):
    """Closest point of the curve to (qx, qy): returns (distance mm, u).

    The global search, with no prior (module docstring, steps 2-3).

    Parameters
    ----------
    qx, qy : float
        The point, mm.
    pieces : ProjectorArrays
        ``ContourProjector.arrays``: the curve is evaluated from its piece
        polynomials, not from the NURBS arrays.
    der : (3, 2) float64 array
        Scratch (C, C', C'' of the last evaluation): one per thread when
        called from parallel loops; nothing else is written.

    Returns
    -------
    distance : float
        Shortest distance from the point to the whole curve, mm.
    u : float
        Parameter of a closest point.

    A point outside the grid starts from the nearest cell (exact, only slower).
    A non-finite point (a diverged plant) returns (inf, NaN), or (NaN, NaN)
    if a coordinate is NaN, at once.
    """
    if not (abs(qx) < np.inf and abs(qy) < np.inf):
        return _not_finite(qx, qy)
    return _search(qx, qy, np.inf, pieces.piece_u[0], _NONE_LO, _NONE_HI, pieces, der)


@njit(cache=True, _nrt=False)
def project_point_warm(qx, qy, u_prev, pieces, der):
    """Closest point of the curve to (qx, qy) starting from a previous foot: (distance mm, u).

    The same global, exact answer as :func:`project_point` (the same distance
    to rounding), found faster when the closest point is near ``u_prev``
    (module docstring, step 4):

    1. the piece holding ``u_prev`` is refined with Newton's method started
       at ``u_prev``; while the foot lands on an end of the pieces refined so
       far, the piece beyond that end is refined too (at most ``_WALK``);
    2. the pieces on both sides of the foot's are refined (at once dismissed
       if their chord is too far);
    3. if twice the distance found is within the foot piece's isolation
       radius, no point of another piece can be closer: done (the common
       case, no grid access).  Otherwise the distance found bounds the
       global search, which skips the pieces refined already; a bad
       ``u_prev`` costs one piece refinement more than :func:`project_point`.

    Parameters
    ----------
    qx, qy : float
        The point, mm.
    u_prev : float
        The previous foot parameter.  NaN (or any value outside the curve's
        parameter range ``[piece_u[0], piece_u[-1]]``) means no previous foot:
        the call is then :func:`project_point`.
    pieces : ProjectorArrays
        ``ContourProjector.arrays``, as for :func:`project_point`.
    der : (3, 2) float64 array
        Scratch, as for :func:`project_point`: each thread of a parallel loop
        passes its own; the call keeps no other state.

    Returns
    -------
    distance : float
        Shortest distance from the point to the whole curve, mm.
    u : float
        Parameter of a closest point (the next call's ``u_prev``).
    """
    piece_u = pieces.piece_u
    n = pieces.piece_sag.shape[0]
    if not (abs(qx) < np.inf and abs(qy) < np.inf):
        return _not_finite(qx, qy)
    if not (piece_u[0] <= u_prev <= piece_u[n]):  # also false for NaN
        return project_point(qx, qy, pieces, der)
    i = min(np.searchsorted(piece_u, u_prev, side="right") - 1, n - 1)
    degree = pieces.degree
    piece_table = pieces.piece_table
    piece_sag = pieces.piece_sag
    best_d, best_u = _refine_on_piece(degree, qx, qy, u_prev, i, piece_u, piece_table, der)
    f = i  # the piece holding the best point
    lo = i  # pieces lo..hi are refined
    hi = i
    for _ in range(_WALK):
        if best_u == piece_u[lo] and lo > 0:
            lo -= 1
            j = lo
        elif best_u == piece_u[hi + 1] and hi < n - 1:
            hi += 1
            j = hi
        else:
            break
        d, u = _refine_from_chord(degree, qx, qy, j, best_d, piece_u, piece_table, piece_sag, der)
        if not d < best_d:
            break
        best_d = d
        best_u = u
        f = j
    # the pieces on both sides of the foot's, then the isolation of the foot's piece
    moved = False
    if 0 < f < lo + 1:
        lo = f - 1
        d, u = _refine_from_chord(degree, qx, qy, lo, best_d, piece_u, piece_table, piece_sag, der)
        if d < best_d:
            best_d = d
            best_u = u
            moved = True
    if hi - 1 < f < n - 1:
        hi = f + 1
        d, u = _refine_from_chord(degree, qx, qy, hi, best_d, piece_u, piece_table, piece_sag, der)
        if d < best_d:
            best_d = d
            best_u = u
            moved = True
    if not moved and 2.0 * best_d <= piece_table[f, _ISOLATION]:
        # a point of any other piece closer than best_d to q would lie within
        # 2 best_d of the foot: the isolation radius says there is none
        return best_d, best_u
    return _search(qx, qy, best_d, best_u, lo, hi, pieces, der)


@njit(cache=True)
def _project_points(qs, u_prev, carry, pieces, dist, us):
    """Batch of :func:`project_point_warm` (NaN u_prev: :func:`project_point`).

    ``carry``: the foot of point k is the ``u_prev`` of point k + 1 (a
    trajectory; only ``u_prev[0]`` is read), else ``u_prev[k]`` per point.
    """
    der = np.empty((3, 2))
    u = u_prev[0]
    for k in range(qs.shape[0]):
        if not carry:
            u = u_prev[k]
        dist[k], u = project_point_warm(qs[k, 0], qs[k, 1], u, pieces, der)
        us[k] = u


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

    Attributes
    ----------
    arrays : ProjectorArrays
        The piece table and the grid, what :func:`project_point` and
        :func:`project_point_warm` read (one argument).
    """

    def __init__(self, curve, piece_length: float = 0.5, cell_size: float = 1.0, margin: float = 10.0):
        for name, v in (("piece_length", piece_length), ("cell_size", cell_size), ("margin", margin)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        self.curve = curve
        self.piece_u, self.piece_points, self.piece_sag = self._cut(curve, piece_length)
        self.piece_table = self._table(curve, self.piece_u, self.piece_points)
        self.cell_size = float(cell_size)
        self._build_grid(margin)
        self.arrays = ProjectorArrays(
            curve.degree,
            self.piece_u,
            self.piece_table,
            self.piece_sag,
            self.grid_origin,
            self.cell_size,
            self.grid_shape,
            self.cell_start,
            self.cell_pieces,
        )
        _isolation_radii(self.arrays, _ISOLATION_CELLS * self.cell_size)

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
        """Per piece end: C, C' from the right, C' from the left; per piece the
        convexity bounds, the isolation radius (left 0 here: it needs the
        grid) and the polynomials of :func:`_piece_polynomials`; shape
        (n+1, 13 + 3 (p+1)).

        Convexity: on piece i, g(u) = ``|C(u) - q|^2`` / 2 has g'' = ``|C'|^2`` +
        (C - q) . C''.  With C = M + c, ``|c|`` <= r, and C'' = A + a, ``|a|`` <= rho::

            g'' >= min|C'|^2 - r (|A| + rho) + (M - q) . A - |M - q| rho,

        stored as (M, A, rho, k = min|C'|^2 - r (``|A|`` + rho)).  When it is
        positive g is convex on the whole piece (one minimum): q on the outer
        side of a bend at any distance, or inside it closer than about the
        radius of curvature.  M is the middle of the box of the sampled
        points and A of the sampled second derivatives; the sampled bounds
        get margins, as the sag does: the least ``|C'|^2`` is halved, rho doubled
        and r widened by the longest step between samples.  C' and C'' of
        piece i are sampled on [u_i, u_i+1) and at u_i+1 from the left.
        """
        lo, hi = curve.u_range
        left_u = np.maximum(np.nextafter(piece_u, -np.inf), lo)  # u_i from the left (in span i-1)
        fine = piece_u[:-1, None] + np.linspace(0.0, 1.0, sub + 1)[None, :] * np.diff(piece_u)[:, None]
        fine[:, -1] = left_u[1:]
        der = curve.derivatives_array(fine.reshape(-1), 2).reshape(fine.shape + (3, 2))
        speed2 = 0.5 * np.sum(der[..., 1, :] ** 2, axis=-1).min(axis=1)
        pts, acc = der[..., 0, :], der[..., 2, :]
        centre = 0.5 * (pts.min(axis=1) + pts.max(axis=1))
        step = np.linalg.norm(np.diff(pts, axis=1), axis=-1).max(axis=1)
        r = np.linalg.norm(pts - centre[:, None, :], axis=-1).max(axis=1) + step
        acc_centre = 0.5 * (acc.min(axis=1) + acc.max(axis=1))
        rho = 2.0 * np.linalg.norm(acc - acc_centre[:, None, :], axis=-1).max(axis=1)
        k = speed2 - r * (np.linalg.norm(acc_centre, axis=-1) + rho)
        right = curve.derivatives_array(piece_u, 1)[:, 1, :]
        left = curve.derivatives_array(left_u, 1)[:, 1, :]
        # at a knot of multiplicity p, C' jumps: the sides differ; elsewhere keep the exact value
        at_knot = np.isin(piece_u, curve.knots)
        table = np.zeros((len(piece_u), _POLY + 3 * (curve.degree + 1)))  # _ISOLATION: set with the grid
        table[:, :2] = piece_points
        table[:, 2:4] = right
        table[:, 4:6] = np.where(at_knot[:, None], left, right)
        table[0, 4:6] = right[0]
        table[-1, 2:6] = np.concatenate([right[-1], right[-1]])  # C'(u_end) is taken from the left
        table[:-1, _CONVEX : _CONVEX + 6] = np.column_stack([centre, acc_centre, rho, k])
        _piece_polynomials(*curve.kernel_args, piece_u, table)
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

    def project(self, points):
        """Closest curve points to ``points`` (mm, (2,) or (k, 2)): (distance mm, u).

        The global search, :func:`project_point`, for every point.
        """
        q, single = self._points(points)
        return self._run(q, np.full(len(q), NO_FOOT), False, single)

    def project_warm(self, points, u_prev):
        """:func:`project_point_warm` for every point, each with its own previous foot.

        Parameters
        ----------
        points : array_like, (2,) or (k, 2)
            Points, mm.
        u_prev : float or array_like, (k,)
            Previous foot parameter of each point, in the curve's parameter
            range, or NaN (:data:`NO_FOOT`) for none.

        Returns
        -------
        distance, u
            As :meth:`project` (the same distances, to rounding).
        """
        q, single = self._points(points)
        return self._run(q, self._feet(u_prev, len(q)), False, single)

    def track(self, points, u_start=NO_FOOT):
        """:func:`project_point_warm` along a trajectory, each point's foot the next one's ``u_prev``.

        Parameters
        ----------
        points : array_like, (k, 2)
            The tool positions in time order, mm.
        u_start : float
            ``u_prev`` of the first point (NaN, the default: none).

        Returns
        -------
        distance, u : ndarray, (k,)
            As :meth:`project`.
        """
        q, _single = self._points(points)
        return self._run(q, self._feet(u_start, 1), True, False)

    def _points(self, points):
        q = np.ascontiguousarray(points, dtype=np.float64)
        single = q.ndim == 1
        q = q.reshape(-1, 2)
        if not np.all(np.isfinite(q)):
            raise ValueError("points must be finite")
        return q, single

    def _feet(self, u_prev, k):
        u = np.ascontiguousarray(np.broadcast_to(np.asarray(u_prev, dtype=np.float64), (k,)))
        lo, hi = self.curve.u_range
        bad = ~np.isnan(u) & ~((u >= lo) & (u <= hi))
        if bad.any():
            raise ValueError(
                f"u_prev must be NaN (no previous foot) or a curve parameter in [{lo}, {hi}], got {u[bad][0]!r}"
            )
        return u

    def _run(self, q, u_prev, carry, single):
        dist = np.empty(len(q))
        us = np.empty(len(q))
        _project_points(q, u_prev, carry, self.arrays, dist, us)
        return (dist[0], us[0]) if single else (dist, us)

    def contour_error(self, points):
        """Shortest distance from ``points`` to the whole curve, in mm."""
        return self.project(points)[0]
