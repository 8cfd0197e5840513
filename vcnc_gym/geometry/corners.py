"""Polyline tool paths with quintic Bezier corner blends, Simba et al.'s eqs. (12)-(23).

Simba et al. (section III, after their ref. [16], Sencer et al.)
replace every corner of a piecewise-linear tool path by a fifth-order Bezier
curve, eq. (12),

    p(h) = sum_{i=0..5} binom(5, i) h^i (1-h)^(5-i) p_{i+1},    h in [0, 1].

Placement (Simba et al., Fig. 3)
--------------------------------
At a corner G with interior angle theta between the legs, p_1, p_2, p_3
lie on the incoming leg and p_4, p_5, p_6 on the outgoing one, symmetric
about the bisector::

    |p_1 p_2| = |p_2 p_3| = l_1,   |p_3 G| = l_2   (and mirrored on the way out),
    l_t = |p_1 G| = 2 l_1 + l_2,   n = l_1 / l_2.

Three collinear, equally spaced points at each end make the blend's first
derivative tangent to the line and its second derivative zero there, so the
curvature is continuous (zero) where blend and line meet.  At h = 1/2 the
blend passes the bisector at the distance of eq. (13) from G,

    eps = (7 n + 16) sqrt(2 + 2 cos theta) / (64 n + 32) * l_t,

which is also its closest approach to G: the largest distance from the sharp
path to the smoothed one is eps (tests/test_corners.py measures it).

Length ratio (Simba et al., eqs. (14)-(20))
-------------------------------------------
With eq. (13) solved for l_t, the blend of a given (theta, eps) depends on n
only.  Travelled at a constant speed v, its acceleration is v^2 kappa
(eq. (14)) and its jerk v^3 varkappa (eq. (17)), with kappa the curvature and
varkappa = ``|d^3 p / ds^3|`` = sqrt(kappa_s^2 + kappa^4).  So

    v_max,a(n) = sqrt(a_max / max_h kappa)           (eq. (15)),
    v_max,j(n) = cbrt(j_max / max_h varkappa)       (eq. (18)),

n_opt,a = argmin_n max_h kappa (eq. (16), eps held fixed as Simba et al. do),
n_opt,j = argmin_n max_h varkappa (eq. (19)) and
n_opt = argmax_n min(v_max,a, v_max,j) (eq. (20)).  Eq. (17) as printed has
``|p''|^7`` in its denominator and "+" before the p''' p' term of H_1 and before
H_2; differentiating p_ss = (p'' ``|p'|^2`` - (p'.p'') p') / ``|p'|^4`` once more gives
``|p'|^7`` and minus signs, which is what :func:`blend_curvature` uses (the test
checks it against a finite-difference kappa_s).

Maxima over h are found on a 513-point grid of h in [0, 1/2] (the blend is
symmetric about h = 1/2) refined by golden-section search around the best
sample; the optimisations over n by a 61-point grid of log n in [0.01, 100]
refined by golden-section search (the objectives are unimodal in n: Simba et al.'s
Fig. 4, and the brute-force test).

Corner segment (Simba et al., eqs. (21)-(23))
---------------------------------------------
The feedrate planner holds the corner speed over a corner segment that starts
l_s before G on the incoming leg and ends l_s after it (the "unilateral
triangle" of side l_s), eq. (22): l_s = l_t(n_opt,j).  When n_opt,a > n_opt,j
(not met in Simba et al.'s settings) we take l_s = l_t(max(n_opt,a, n_opt,j)),
which keeps l_s >= l_t(n_opt) since l_t grows with n.  The segment's length is
eq. (23), Delta s = 2 (l_s - l_t(n_opt)) + s_arc, with the blend's arc length
s_arc of eq. (21) computed by the adaptive Gauss-Legendre quadrature of every
arc length here (:mod:`vcnc_gym.geometry.quadrature`), to 1e-12 relative
(Simba et al. use a sixth-order point-based method, their ref. [20]; any
converged quadrature gives the same number).

The whole path as one NURBS
---------------------------
:func:`smooth_polyline` returns the lines and blends as one exact
:class:`~vcnc_gym.geometry.nurbs.NurbsCurve` of degree 5: each line is
degree-elevated to 5 (six equally spaced control points), every piece is a
Bezier segment and interior knots have multiplicity 5.  A line's knot span is
its length and a blend's is 5 l_1, so the parameter u runs at unit speed
(mm per unit u) on every line and at both ends of every blend: the curve is
C^2 in u at every joint, not only geometrically.  :func:`polyline` returns
the sharp path as a degree-1 NURBS whose parameter is the arc length.

Examples
--------
>>> import numpy as np
>>> path = smooth_polyline([[0, 0], [50, 0], [50, 50]], epsilon=0.05, a_max=4000.0, j_max=1.6e5)
>>> corner = path.corners[0]
>>> round(float(np.degrees(corner.theta)), 6)
90.0
>>> bool(abs(np.min(np.linalg.norm(path.curve.points(np.linspace(*path.blend_u[0], 20001))
...     - [50, 0], axis=1)) - 0.05) < 1e-9)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..validation import positive as _positive

from .nurbs import TURN_BACK_ANGLE, NurbsCurve, interior_angle
from .quadrature import arc_length

__all__ = [
    "CornerDesign",
    "SmoothedPolyline",
    "bezier_arc_length",
    "bezier_derivatives",
    "blend_control_points",
    "blend_curvature",
    "corner_error",
    "corner_length",
    "design_corner",
    "interior_angles",
    "peak_curvature",
    "polyline",
    "smooth_polyline",
]

BEZIER_DEGREE = 5

#: Interior angles closer than this to 0 (a U-turn) or pi (straight on), rad,
#: are rejected: no corner to blend, or a blend that folds on itself.  The
#: U-turn side is the rule every contour source shares,
#: :data:`~vcnc_gym.geometry.nurbs.TURN_BACK_ANGLE`.
ANGLE_TOLERANCE = TURN_BACK_ANGLE

#: The sharpest corner :func:`design_corner` blends, rad (1.2767 deg, found by
#: bisection to 1e-8 deg; tests/test_sizes_and_physical_ranges.py checks either side):
#: below it the optimal length ratio n = l_1 / l_2 of eqs. (16), (19), (20)
#: (about 0.0085 per degree of interior angle) falls below the search range's
#: lower end _N_RANGE[0] = 0.01.
MIN_BLEND_ANGLE = math.radians(1.2766656)

#: Search range of the length ratio n = l_1 / l_2 and the grid sizes.
_N_RANGE = (1e-2, 1e2)
_N_GRID = 61
_H_GRID = 513
_GOLDEN = 0.5 * (math.sqrt(5.0) - 1.0)


# --------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------


def _angle(name: str, value) -> float:
    """An interior angle strictly inside (0, pi), rad, else a ValueError."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an angle in rad inside (0, pi), got {value!r}") from None
    if not (ANGLE_TOLERANCE < x < math.pi - ANGLE_TOLERANCE):
        raise ValueError(f"{name} must be an angle in rad inside (0, pi), got {value!r}")
    return x


def _check_vertices(vertices) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated vertices (K, 2) mm, segment lengths (K-1,) mm and unit directions (K-1, 2).

    Raises a ValueError naming the vertices if two consecutive ones coincide
    or three consecutive ones are collinear (straight on or a U-turn).
    """
    if isinstance(vertices, (str, bytes, dict)):
        raise ValueError(f"vertices must be K >= 2 points (x, y) in mm, got {type(vertices).__name__} {vertices!r:.40}")
    try:
        pts = np.array(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"vertices must be K >= 2 points (x, y) of real numbers in mm: {exc}") from None
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2:
        raise ValueError(f"vertices must have shape (K, 2) with K >= 2, in mm; got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("vertices must be finite (mm)")
    steps = np.diff(pts, axis=0)
    lengths = np.hypot(steps[:, 0], steps[:, 1])
    scale = max(1.0, float(np.max(np.abs(pts))))
    for k, length in enumerate(lengths):
        if length <= 1e-12 * scale:
            raise ValueError(f"vertices {k} and {k + 1} are repeated ({pts[k].tolist()} mm): segment {k} has no length")
    dirs = steps / lengths[:, None]
    angles = _interior_angles(dirs)
    for k, theta in enumerate(angles):
        if theta >= math.pi - ANGLE_TOLERANCE:
            raise ValueError(
                f"vertices {k}, {k + 1}, {k + 2} are collinear (straight on at vertex {k + 1}): remove vertex {k + 1}"
            )
        if theta <= TURN_BACK_ANGLE:
            raise ValueError(
                f"vertices {k}, {k + 1}, {k + 2} are collinear (the path turns back on itself at vertex {k + 1}: "
                f"interior angle {theta:.3g} rad <= TURN_BACK_ANGLE = {TURN_BACK_ANGLE:g} rad)"
            )
    return pts, lengths, dirs


def _interior_angles(dirs: np.ndarray) -> np.ndarray:
    """Interior angle (rad) at each inner vertex from the unit directions of its legs."""
    return interior_angle(dirs[:-1], dirs[1:])


def interior_angles(vertices) -> np.ndarray:
    """Interior angle theta at each inner vertex of a polyline, rad, shape (K-2,).

    theta is the angle between the two legs at the vertex (Simba et al., Fig. 3):
    pi for a straight continuation, small for a sharp corner.

    Raises
    ------
    ValueError
        For malformed, repeated or collinear vertices (message names them).
    """
    return _interior_angles(_check_vertices(vertices)[2])


# --------------------------------------------------------------------------
# the sharp path
# --------------------------------------------------------------------------


def polyline(vertices) -> NurbsCurve:
    """The sharp polyline through ``vertices`` (mm) as a degree-1 NURBS.

    The knots are the cumulative segment lengths, so u is the arc length in mm.

    Raises
    ------
    ValueError
        For malformed, repeated or collinear vertices (message names them).
    """
    pts, lengths, _ = _check_vertices(vertices)
    s = np.concatenate([[0.0], np.cumsum(lengths)])
    knots = np.concatenate([[0.0], s, [s[-1]]])
    return NurbsCurve(pts, np.ones(len(pts)), knots, 1)


# --------------------------------------------------------------------------
# one blend: eqs. (12), (13), (14), (17)
# --------------------------------------------------------------------------


def _ratio_factor(n: float) -> float:
    """(7 n + 16) / (64 n + 32), the n-dependence of eq. (13)."""
    return (7.0 * n + 16.0) / (64.0 * n + 32.0)


def corner_error(theta: float, l_t: float, n: float) -> float:
    """Simba et al.'s eq. (13): eps = (7n+16) sqrt(2+2cos theta) / (64n+32) l_t, mm.

    Parameters
    ----------
    theta : float
        Interior angle of the corner, rad, in (0, pi).
    l_t : float
        Distance ``|p_1 G|`` from the blend's first control point to the corner, mm.
    n : float
        Length ratio l_1 / l_2, > 0.
    """
    theta = _angle("theta", theta)
    l_t = _positive("l_t", l_t, "mm")
    n = _positive("n", n, "(dimensionless)")
    return _ratio_factor(n) * math.sqrt(2.0 + 2.0 * math.cos(theta)) * l_t


def corner_length(theta: float, epsilon: float, n: float) -> float:
    """Simba et al.'s eq. (13) solved for l_t: the blend length along each leg, mm.

    Parameters
    ----------
    theta : float
        Interior angle of the corner, rad, in (0, pi).
    epsilon : float
        Corner tolerance eps, mm: distance from G to the blend.
    n : float
        Length ratio l_1 / l_2, > 0.
    """
    theta = _angle("theta", theta)
    epsilon = _positive("epsilon", epsilon, "mm")
    n = _positive("n", n, "(dimensionless)")
    return _l_t(theta, epsilon, n)


def _l_t(theta: float, epsilon: float, n: float) -> float:
    return epsilon / (_ratio_factor(n) * math.sqrt(2.0 + 2.0 * math.cos(theta)))


def blend_control_points(corner, d_in, d_out, l_t: float, n: float) -> np.ndarray:
    """The six control points p_1..p_6 of a corner blend (Simba et al., Fig. 3), mm.

    Parameters
    ----------
    corner : array_like (2,)
        The sharp corner G, mm.
    d_in, d_out : array_like (2,)
        Unit directions of travel on the incoming and outgoing legs.
    l_t : float
        ``|p_1 G|`` = ``|G p_6|`` = 2 l_1 + l_2, mm.
    n : float
        Length ratio l_1 / l_2.

    Returns
    -------
    (6, 2) float64 array: p_1, p_2, p_3 at l_t, l_1 + l_2, l_2 before G on
    the incoming leg, p_4, p_5, p_6 at l_2, l_1 + l_2, l_t after G.
    """
    g = np.asarray(corner, dtype=np.float64)
    a = np.asarray(d_in, dtype=np.float64)
    b = np.asarray(d_out, dtype=np.float64)
    l_2 = l_t / (2.0 * n + 1.0)
    l_1 = n * l_2
    return np.array([g - l_t * a, g - (l_1 + l_2) * a, g - l_2 * a, g + l_2 * b, g + (l_1 + l_2) * b, g + l_t * b])


def _unit_blend(theta: float, epsilon: float, n: float) -> np.ndarray:
    """Control points of the blend of (theta, eps, n) at G = 0, incoming along +x."""
    l_t = _l_t(theta, epsilon, n)
    d_out = np.array([-math.cos(theta), math.sin(theta)])
    return blend_control_points([0.0, 0.0], [1.0, 0.0], d_out, l_t, n)


@njit(cache=True)
def _bezier_derivatives_into(control_points, h, order, out):
    """out[k] = d^k p / dh^k at h for k <= order (de Casteljau on the hodographs)."""
    deg = control_points.shape[0] - 1
    diffs = control_points.copy()
    tmp = np.empty_like(diffs)
    factor = 1.0
    for k in range(order + 1):
        m = deg - k
        if m < 0:
            out[k, 0] = 0.0
            out[k, 1] = 0.0
            continue
        for i in range(m + 1):
            tmp[i, 0] = diffs[i, 0]
            tmp[i, 1] = diffs[i, 1]
        for r in range(1, m + 1):
            for i in range(m + 1 - r):
                tmp[i, 0] = (1.0 - h) * tmp[i, 0] + h * tmp[i + 1, 0]
                tmp[i, 1] = (1.0 - h) * tmp[i, 1] + h * tmp[i + 1, 1]
        out[k, 0] = factor * tmp[0, 0]
        out[k, 1] = factor * tmp[0, 1]
        factor *= m
        for i in range(m):
            diffs[i, 0] = diffs[i + 1, 0] - diffs[i, 0]
            diffs[i, 1] = diffs[i + 1, 1] - diffs[i, 1]


@njit(cache=True)
def _bezier_derivatives_batch(control_points, hs, order, out):
    for i in range(hs.shape[0]):
        _bezier_derivatives_into(control_points, hs[i], order, out[i])


@njit(cache=True)
def _curvatures(control_points, h, ders):
    """(kappa, varkappa) of a Bezier curve at h; ``ders`` is (4, 2) scratch."""
    _bezier_derivatives_into(control_points, h, 3, ders)
    p1x, p1y = ders[1, 0], ders[1, 1]
    p2x, p2y = ders[2, 0], ders[2, 1]
    p3x, p3y = ders[3, 0], ders[3, 1]
    g = p1x * p1x + p1y * p1y
    d = p1x * p2x + p1y * p2y
    kappa = abs(p1x * p2y - p1y * p2x) / g**1.5
    coef = 4.0 * d * d - (p2x * p2x + p2y * p2y) * g - (p1x * p3x + p1y * p3y) * g
    sx = p3x * g * g - 3.0 * d * g * p2x + coef * p1x
    sy = p3y * g * g - 3.0 * d * g * p2y + coef * p1y
    return kappa, math.sqrt(sx * sx + sy * sy) / g**3.5


@njit(cache=True)
def _curvature_batch(control_points, hs, kappa, varkappa):
    ders = np.empty((4, 2))
    for i in range(hs.shape[0]):
        kappa[i], varkappa[i] = _curvatures(control_points, hs[i], ders)


@njit(cache=True)
def _peak(control_points, which, n_grid, tol):
    """max over h in [0, 1/2] of kappa (which = 0) or varkappa (which = 1):
    the best of n_grid samples refined by golden section between its neighbours."""
    ders = np.empty((4, 2))
    best = -1.0
    i_best = 0
    step = 0.5 / (n_grid - 1)
    for i in range(n_grid):
        v = _curvatures(control_points, i * step, ders)[which]
        if v > best:
            best = v
            i_best = i
    a = max(i_best - 1, 0) * step
    b = min(i_best + 1, n_grid - 1) * step
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    x1 = b - g * (b - a)
    x2 = a + g * (b - a)
    f1 = _curvatures(control_points, x1, ders)[which]
    f2 = _curvatures(control_points, x2, ders)[which]
    while b - a > tol:
        if f1 >= f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - g * (b - a)
            f1 = _curvatures(control_points, x1, ders)[which]
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + g * (b - a)
            f2 = _curvatures(control_points, x2, ders)[which]
    return max(best, f1, f2)


def bezier_derivatives(control_points, h, order: int = 3) -> np.ndarray:
    """A Bezier curve (eq. (12) for six control points) and its derivatives in h.

    Parameters
    ----------
    control_points : array_like (d+1, 2)
        Control points, mm.
    h : float or array_like
        Parameters in [0, 1].
    order : int
        Highest derivative wanted.

    Returns
    -------
    (len(h), order+1, 2) array: p, dp/dh, d2p/dh2, ... in mm.
    """
    c = np.ascontiguousarray(control_points, dtype=np.float64)
    hh = np.ascontiguousarray(np.atleast_1d(np.asarray(h, dtype=np.float64)).reshape(-1))
    out = np.empty((hh.size, int(order) + 1, 2))
    _bezier_derivatives_batch(c, hh, int(order), out)
    return out


def blend_curvature(control_points, h) -> tuple[np.ndarray, np.ndarray]:
    """Curvature kappa (eq. (14)) and the jerk factor varkappa (eq. (17)) along a blend.

    Parameters
    ----------
    control_points : array_like (6, 2)
        The blend, mm.
    h : float or array_like
        Parameters in [0, 1].

    Returns
    -------
    kappa : array, 1/mm
        ``|p' x p''|`` / ``|p'|^3``: at constant speed v the acceleration is v^2 kappa.
    varkappa : array, 1/mm^2
        ``|d^3 p / ds^3| = |p''' g^2 - 3 d g p'' + (4 d^2 - |p''|^2 g - (p'.p''') g) p'| / |p'|^7``
        with g = ``|p'|^2`` and d = p'.p'': at constant speed the jerk is v^3 varkappa.
    """
    c = np.ascontiguousarray(control_points, dtype=np.float64)
    hh = np.ascontiguousarray(np.atleast_1d(np.asarray(h, dtype=np.float64)).reshape(-1))
    kappa = np.empty(hh.size)
    varkappa = np.empty(hh.size)
    _curvature_batch(c, hh, kappa, varkappa)
    return kappa, varkappa


def _peaks(control_points) -> tuple[float, float]:
    """(max_h kappa, max_h varkappa) of a symmetric blend, searched on h in [0, 1/2]."""
    c = np.ascontiguousarray(control_points, dtype=np.float64)
    return _peak(c, 0, _H_GRID, 1e-10), _peak(c, 1, _H_GRID, 1e-10)


def peak_curvature(theta: float, epsilon: float, n: float) -> tuple[float, float]:
    """Largest kappa (1/mm) and varkappa (1/mm^2) on the blend of (theta, eps, n).

    The blend is symmetric about h = 1/2; the maxima are searched on a
    513-point grid of h in [0, 1/2] refined by golden section (module docstring).

    Parameters
    ----------
    theta : float
        Interior angle, rad.
    epsilon : float
        Corner tolerance, mm.
    n : float
        Length ratio l_1 / l_2.
    """
    theta = _angle("theta", theta)
    epsilon = _positive("epsilon", epsilon, "mm")
    n = _positive("n", n, "(dimensionless)")
    return _peaks(_unit_blend(theta, epsilon, n))


def bezier_arc_length(control_points) -> float:
    """Arc length of a Bezier curve, Simba et al.'s eq. (21), mm.

    :func:`vcnc_gym.geometry.quadrature.arc_length` of ``|dp/dh|`` on [0, 1]: 8 pieces of 16 Gauss-Legendre
    nodes, bisected until a piece and its halves agree to 1e-12 relative.  Where the speed touches zero (a cusp)
    the integral still converges, the bisection gathering at the cusp.
    """
    c = np.asarray(control_points, dtype=np.float64)
    return arc_length(lambda h: np.linalg.norm(bezier_derivatives(c, h, 1)[:, 1, :], axis=1), _UNIT_INTERVAL)


_UNIT_INTERVAL = np.array([0.0, 1.0])


# --------------------------------------------------------------------------
# the optimal length ratio: eqs. (15), (16), (18)-(20), (22), (23)
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class CornerDesign:
    """One corner blend designed by Simba et al.'s eqs. (13)-(23).

    Attributes
    ----------
    theta : float
        Interior angle, rad.
    epsilon : float
        Corner tolerance eps of eq. (13), mm.
    a_max, j_max : float
        Path acceleration (mm/s^2) and jerk (mm/s^3) limits the blend is designed for.
    n : float
        n_opt of eq. (20), the ratio used.
    n_a, n_j : float
        n_opt,a of eq. (16) (eps fixed) and n_opt,j of eq. (19).
    l_t : float
        l_t(n_opt), eq. (13), mm.
    l_s : float
        Side of the corner segment, eq. (22), mm (>= l_t).
    s_arc : float
        Arc length of the blend, eq. (21), mm.
    delta_s : float
        Length of the corner segment, eq. (23), mm.
    kappa_max : float
        max_h kappa at n_opt, 1/mm.
    varkappa_max : float
        max_h varkappa at n_opt, 1/mm^2.
    v_max_a, v_max_j : float
        Eqs. (15) and (18) at n_opt, mm/s.
    """

    theta: float
    epsilon: float
    a_max: float
    j_max: float
    n: float
    n_a: float
    n_j: float
    l_t: float
    l_s: float
    s_arc: float
    delta_s: float
    kappa_max: float
    varkappa_max: float
    v_max_a: float
    v_max_j: float

    @property
    def v_max(self) -> float:
        """Admissible corner speed min(v_max,a, v_max,j), mm/s (eq. (20))."""
        return min(self.v_max_a, self.v_max_j)


def _log_n_search(objective) -> float:
    """argmax over n in _N_RANGE of objective(log n): the best of _N_GRID log-spaced
    samples, refined by golden section between its neighbours to 1e-10 in log n."""
    lo, hi = math.log(_N_RANGE[0]), math.log(_N_RANGE[1])
    xs = np.linspace(lo, hi, _N_GRID)
    values = [objective(x) for x in xs]
    i = int(np.argmax(values))
    if i == 0 or i == _N_GRID - 1:
        raise RuntimeError(
            f"the optimal length ratio left the search range {_N_RANGE} (a corner sharper than "
            f"MIN_BLEND_ANGLE = {math.degrees(MIN_BLEND_ANGLE):.4g} deg?)"
        )
    a, b = xs[i - 1], xs[i + 1]
    x1, x2 = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
    f1, f2 = objective(x1), objective(x2)
    while b - a > 1e-10:
        if f1 >= f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - _GOLDEN * (b - a)
            f1 = objective(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + _GOLDEN * (b - a)
            f2 = objective(x2)
    return math.exp(0.5 * (a + b))


def design_corner(theta: float, epsilon: float, a_max: float, j_max: float) -> CornerDesign:
    """Optimal blend of one corner, Simba et al.'s eqs. (13)-(23).

    Parameters
    ----------
    theta : float
        Interior angle, rad, in (0, pi).
    epsilon : float
        Corner tolerance, mm.
    a_max : float
        Path acceleration limit, mm/s^2.
    j_max : float
        Path jerk limit, mm/s^3.

    Returns
    -------
    CornerDesign
        n_opt,a, n_opt,j, n_opt, the corner speeds and lengths.

    Raises
    ------
    ValueError
        If an argument is out of range (message names it and its unit).
    """
    theta = _angle("theta", theta)
    if theta < MIN_BLEND_ANGLE:
        raise ValueError(
            f"theta = {math.degrees(theta):.4g} deg is sharper than MIN_BLEND_ANGLE = "
            f"{math.degrees(MIN_BLEND_ANGLE):.4g} deg, the sharpest corner the blend design reaches"
        )
    epsilon = _positive("epsilon", epsilon, "mm")
    a_max = _positive("a_max", a_max, "mm/s^2")
    j_max = _positive("j_max", j_max, "mm/s^3")

    cache: dict[float, tuple[float, float]] = {}

    def peaks(log_n: float) -> tuple[float, float]:
        if log_n not in cache:
            cache[log_n] = _peaks(_unit_blend(theta, epsilon, math.exp(log_n)))
        return cache[log_n]

    def v_a(log_n):
        return math.sqrt(a_max / peaks(log_n)[0])

    def v_j(log_n):
        return (j_max / peaks(log_n)[1]) ** (1.0 / 3.0)

    n_a = _log_n_search(v_a)  # eq. (16): argmin_n max_h kappa = argmax_n v_max,a
    n_j = _log_n_search(v_j)  # eq. (19)
    n_opt = _log_n_search(lambda x: min(v_a(x), v_j(x)))  # eq. (20)
    kappa_max, varkappa_max = _peaks(_unit_blend(theta, epsilon, n_opt))
    l_t = _l_t(theta, epsilon, n_opt)
    l_s = max(l_t, _l_t(theta, epsilon, max(n_a, n_j)))  # eq. (22), conservative (module docstring)
    s_arc = bezier_arc_length(_unit_blend(theta, epsilon, n_opt))  # eq. (21)
    return CornerDesign(
        theta=theta,
        epsilon=epsilon,
        a_max=a_max,
        j_max=j_max,
        n=n_opt,
        n_a=n_a,
        n_j=n_j,
        l_t=l_t,
        l_s=l_s,
        s_arc=s_arc,
        delta_s=2.0 * (l_s - l_t) + s_arc,  # eq. (23)
        kappa_max=kappa_max,
        varkappa_max=varkappa_max,
        v_max_a=math.sqrt(a_max / kappa_max),
        v_max_j=(j_max / varkappa_max) ** (1.0 / 3.0),
    )


# --------------------------------------------------------------------------
# the whole path
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class SmoothedPolyline:
    """A polyline whose corners are quintic Bezier blends (Simba et al., section III).

    Made by :func:`smooth_polyline`.

    Attributes
    ----------
    vertices : (K, 2) array
        The sharp polyline, mm.
    epsilon, a_max, j_max : float
        Corner tolerance (mm) and the limits (mm/s^2, mm/s^3) the blends are designed for.
    curve : NurbsCurve
        Lines and blends as one degree-5 NURBS (module docstring).
    corners : tuple of CornerDesign
        One per inner vertex, in path order.
    blends : (K-2, 6, 2) array
        Control points of each blend, mm.
    blend_u : (K-2, 2) array
        Parameter range of each blend on ``curve``.
    blend_s : (K-2, 2) array
        Arc-length range of each blend along the smoothed path, mm.
    zones : (K-2, 2) array
        Arc-length range of each corner segment of eq. (23) (l_s - l_t of
        line either side of the blend), mm: where the feedrate planner holds
        the corner speed.
    length : float
        Arc length of the smoothed path, mm.
    """

    vertices: np.ndarray
    epsilon: float
    a_max: float
    j_max: float
    curve: NurbsCurve
    corners: tuple
    blends: np.ndarray
    blend_u: np.ndarray
    blend_s: np.ndarray
    zones: np.ndarray
    length: float

    @property
    def corner_speeds(self) -> np.ndarray:
        """min(v_max,a, v_max,j) of each corner, mm/s (eq. (20))."""
        return np.array([c.v_max for c in self.corners])


def smooth_polyline(vertices, epsilon: float, a_max: float, j_max: float) -> SmoothedPolyline:
    """Replace every corner of a polyline by its optimal quintic Bezier blend.

    Parameters
    ----------
    vertices : array_like (K, 2)
        The polyline, mm, K >= 2; no repeated consecutive vertices, no three
        consecutive collinear ones.
    epsilon : float
        Corner tolerance eps of Simba et al.'s eq. (13), mm.
    a_max : float
        Path acceleration limit for the corner speed, mm/s^2 (eq. (15)).
    j_max : float
        Path jerk limit for the corner speed, mm/s^3 (eq. (18)).

    Returns
    -------
    SmoothedPolyline
        With ``curve``, the exact degree-5 NURBS of the smoothed path.

    Raises
    ------
    ValueError
        For malformed, repeated or collinear vertices, non-positive
        ``epsilon``, ``a_max`` or ``j_max``, or an ``epsilon`` so large that
        the corner segments (side l_s of eq. (22)) of a segment's two ends do
        not fit in it; the message names the segment.
    """
    pts, lengths, dirs = _check_vertices(vertices)
    epsilon = _positive("epsilon", epsilon, "mm")
    a_max = _positive("a_max", a_max, "mm/s^2")
    j_max = _positive("j_max", j_max, "mm/s^3")
    thetas = _interior_angles(dirs)
    for k, theta in enumerate(thetas):
        if theta < MIN_BLEND_ANGLE:
            raise ValueError(
                f"the corner at vertex {k + 1} ({pts[k + 1].tolist()} mm) is too sharp to blend: interior angle "
                f"{math.degrees(theta):.4g} deg, below MIN_BLEND_ANGLE = {math.degrees(MIN_BLEND_ANGLE):.4g} deg, "
                "where Simba et al.'s optimal length ratio n (eqs. (16)-(20)) leaves the design's search range; the "
                "path nearly turns back on itself there: open the corner or split the path at it"
            )
    designs = tuple(design_corner(t, epsilon, a_max, j_max) for t in thetas)

    side = np.zeros(len(pts))  # l_s at each vertex (0 at both ends)
    side[1:-1] = [d.l_s for d in designs]
    for k, length in enumerate(lengths):
        need = side[k] + side[k + 1]
        if need >= length:
            raise ValueError(
                f"epsilon = {epsilon:g} mm is too large for segment {k} (vertices {k} to {k + 1}, "
                f"{length:.6g} mm long): its corner segments take {need:.6g} mm (side l_s of Simba et al.'s eq. (22))"
            )

    pieces: list[tuple[np.ndarray, float, float]] = []  # (control points, knot span, arc length)
    blends = []
    start = pts[0]
    for k, d in enumerate(designs):
        ctrl = blend_control_points(pts[k + 1], dirs[k], dirs[k + 1], d.l_t, d.n)
        l_1 = d.n * d.l_t / (2.0 * d.n + 1.0)
        line = float(np.hypot(*(ctrl[0] - start)))
        pieces.append((np.linspace(start, ctrl[0], BEZIER_DEGREE + 1), line, line))
        pieces.append((ctrl, BEZIER_DEGREE * l_1, d.s_arc))
        blends.append(ctrl)
        start = ctrl[-1]
    line = float(np.hypot(*(pts[-1] - start)))
    pieces.append((np.linspace(start, pts[-1], BEZIER_DEGREE + 1), line, line))

    control = np.concatenate([pieces[0][0]] + [p[0][1:] for p in pieces[1:]])
    u_edges = np.concatenate([[0.0], np.cumsum([p[1] for p in pieces])])
    s_edges = np.concatenate([[0.0], np.cumsum([p[2] for p in pieces])])
    knots = np.concatenate(
        [np.full(BEZIER_DEGREE + 1, u_edges[0])]
        + [np.full(BEZIER_DEGREE, u) for u in u_edges[1:-1]]
        + [np.full(BEZIER_DEGREE + 1, u_edges[-1])]
    )
    curve = NurbsCurve(control, np.ones(len(control)), knots, BEZIER_DEGREE)

    idx = np.arange(1, 2 * len(designs), 2)  # blend pieces sit at odd positions
    blend_u = np.stack([u_edges[idx], u_edges[idx + 1]], axis=1).reshape(-1, 2)
    blend_s = np.stack([s_edges[idx], s_edges[idx + 1]], axis=1).reshape(-1, 2)
    margin = np.array([d.l_s - d.l_t for d in designs])
    zones = np.stack([blend_s[:, 0] - margin, blend_s[:, 1] + margin], axis=1).reshape(-1, 2)
    blend_arr = np.array(blends).reshape(-1, BEZIER_DEGREE + 1, 2)
    for a in (pts, blend_arr, blend_u, blend_s, zones):
        a.flags.writeable = False
    return SmoothedPolyline(
        vertices=pts,
        epsilon=epsilon,
        a_max=a_max,
        j_max=j_max,
        curve=curve,
        corners=designs,
        blends=blend_arr,
        blend_u=blend_u,
        blend_s=blend_s,
        zones=zones,
        length=float(s_edges[-1]),
    )
