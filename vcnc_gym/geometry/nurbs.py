"""Planar NURBS curves, Jahanpour et al. (2014), eqs. (2)-(5).

The evaluator follows Piegl and Tiller, *The NURBS Book* (their ref. [20]):
algorithm A2.1 (knot span), A2.3 (basis functions and their derivatives) and
A4.2 (derivatives of a rational curve from those of its homogeneous form).
The kernels are module-level numba functions on plain arrays, so the
interpolator and the contour-error projector call them from their own
compiled loops; :class:`NurbsCurve` validates a definition once and wraps them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .quadrature import arc_length

__all__ = [
    "NurbsCurve",
    "NurbsArrays",
    "basis_derivatives",
    "SPAN_LENGTH_TOLERANCE",
    "SPEED_TOLERANCE",
    "TURN_BACK_ANGLE",
    "interior_angle",
    "curve_derivatives",
    "curve_derivatives_into",
    "find_span",
    "workspace_size",
]

#: :meth:`NurbsCurve.check_regular`: a knot span (or the whole curve) shorter
#: than this fraction of the curve's size max(length, max ``|P_k|``) is a
#: (near-)zero-length span.  Above it the span's points stand clear of the
#: rounding of the coordinates (~1e-16 max ``|P_k|``) by seven orders.
SPAN_LENGTH_TOLERANCE = 1e-9

#: :meth:`NurbsCurve.check_regular`: ``|C'(u)|`` below this fraction of its knot
#: span's mean parametric speed (span arc length / span width) is a near-zero
#: derivative.  Random curves with weights in [0.1, 10] keep at least 2e-4;
#: a repeated control point gives ~1e-16, a true cusp ~1e-10 or less.
SPEED_TOLERANCE = 1e-6

#: A curve turns back on itself where its tangent reverses: at a corner
#: whose interior angle (between the reversed incoming and the outgoing
#: tangent: pi straight on, 0 a U-turn) is at most this, rad.  The one rule
#: of every contour source: :meth:`NurbsCurve.check_regular` (every curve an
#: env or the interpolator takes), :func:`~vcnc_gym.geometry.corners.polyline`
#: and :func:`~vcnc_gym.geometry.corners.smooth_polyline` refuse such a
#: point; there the reference would reverse at full feed (its acceleration
#: 2 V / dt in one sample).
TURN_BACK_ANGLE = 1e-9

_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))


class NurbsArrays(NamedTuple):
    """A curve as the compiled kernels take it, one argument (numba reads it as a heterogeneous tuple):
    :attr:`NurbsCurve.kernel_args`.  The module's own kernels keep the four as separate leading arguments."""

    control_points: np.ndarray  #: (n+1, 2) float64, mm
    weights: np.ndarray  #: (n+1,) float64
    knots: np.ndarray  #: (n+p+2,) float64
    degree: int  #: p


def interior_angle(d_in, d_out):
    """Interior angle between incoming and outgoing directions ``d_in``, ``d_out`` (..., 2), rad in [0, pi]:
    pi for a straight continuation, 0 for a U-turn (Simba et al.'s Fig. 3 theta).  Turns back where it is at most
    :data:`TURN_BACK_ANGLE`."""
    d_in, d_out = np.asarray(d_in, dtype=np.float64), np.asarray(d_out, dtype=np.float64)
    cross = d_in[..., 0] * d_out[..., 1] - d_in[..., 1] * d_out[..., 0]
    dot = d_in[..., 0] * d_out[..., 0] + d_in[..., 1] * d_out[..., 1]
    return math.pi - np.arctan2(np.abs(cross), dot)


def _real_array(name: str, value, unit: str) -> np.ndarray:
    """``value`` as a float64 array; ValueError naming ``name`` if it holds anything but real numbers."""
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{name} must be an array of real numbers ({unit}), got the string {value!r}")
    try:
        out = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of real numbers ({unit}), got {value!r}: {exc}") from None
    if isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        return out
    raw = np.asarray(value, dtype=object) if out.size else out
    if any(isinstance(v, (bool, np.bool_, str, bytes, complex)) for v in np.ravel(raw)):
        raise ValueError(f"{name} must be an array of real numbers ({unit}), got {value!r}")
    return out


@njit(cache=True)
def find_span(n, degree, u, knots):
    """Index i of the knot span with knots[i] <= u < knots[i+1] (A2.1).

    ``n`` is the index of the last control point; u at the end of the range
    belongs to the last non-empty span so the curve is closed on the right.
    Repeated knots at either end of the range (possible in an unclamped
    vector) are stepped over so the span returned is never empty.
    """
    if u >= knots[n + 1]:
        span = n
        while knots[span] >= knots[n + 1]:
            span -= 1
        return span
    if u <= knots[degree]:
        span = degree
        while knots[span + 1] <= knots[degree]:
            span += 1
        return span
    low = degree
    high = n + 1
    mid = (low + high) // 2
    while u < knots[mid] or u >= knots[mid + 1]:
        if u < knots[mid]:
            high = mid
        else:
            low = mid
        mid = (low + high) // 2
    return mid


@njit(cache=True)
def basis_derivatives(span, u, degree, order, knots, work, out):
    """Basis functions N_{span-p..span, p} and derivatives up to ``order`` (A2.3).

    Writes d^k/du^k N_{span-p+j, p}(u) to work[out + k (p+1) + j] for
    k <= order <= degree.  ``work`` is flat scratch whose first
    (p+1)^2 + 4(p+1) floats this routine uses for ndu, left, right and a
    (flat indexing: no array views on the hot path).
    """
    p = degree
    q = p + 1
    ndu = 0  # ndu[i, j] -> work[ndu + i q + j]
    left = q * q
    right = left + q
    a = right + q  # a[s, j] -> work[a + s q + j]
    work[ndu] = 1.0
    for j in range(1, p + 1):
        work[left + j] = u - knots[span + 1 - j]
        work[right + j] = knots[span + j] - u
        saved = 0.0
        for r in range(j):
            work[ndu + j * q + r] = work[right + r + 1] + work[left + j - r]
            temp = work[ndu + r * q + j - 1] / work[ndu + j * q + r]
            work[ndu + r * q + j] = saved + work[right + r + 1] * temp
            saved = work[left + j - r] * temp
        work[ndu + j * q + j] = saved
    for j in range(q):
        work[out + j] = work[ndu + j * q + p]
    for r in range(q):
        s1 = 0
        s2 = q
        work[a] = 1.0
        for k in range(1, order + 1):
            d = 0.0
            rk = r - k
            pk = p - k
            if r >= k:
                work[a + s2] = work[a + s1] / work[ndu + (pk + 1) * q + rk]
                d = work[a + s2] * work[ndu + rk * q + pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                work[a + s2 + j] = (work[a + s1 + j] - work[a + s1 + j - 1]) / work[ndu + (pk + 1) * q + rk + j]
                d += work[a + s2 + j] * work[ndu + (rk + j) * q + pk]
            if r <= pk:
                work[a + s2 + k] = -work[a + s1 + k - 1] / work[ndu + (pk + 1) * q + r]
                d += work[a + s2 + k] * work[ndu + r * q + pk]
            work[out + k * q + r] = d
            s1, s2 = s2, s1
    factor = p
    for k in range(1, order + 1):
        for j in range(q):
            work[out + k * q + j] *= factor
        factor *= p - k


#: Derivative orders for jitted callers of :func:`curve_derivatives_into` and :func:`workspace_size`: numba
#: compiles a specialisation of its own for an integer literal argument (a 1 or a 2 written in the call), while
#: numpy ints are typed int64, so that one compiled function serves every caller (fewer cold-start compiles).
FIRST = np.int64(1)
SECOND = np.int64(2)


@njit(cache=True)
def workspace_size(degree, order):
    """Length of the scratch array :func:`curve_derivatives_into` needs."""
    q = degree + 1
    du = min(order, degree)
    return q * q + 4 * q + (du + 1) * q + 3 * (order + 1)


@njit(cache=True)
def curve_derivatives_into(control_points, weights, knots, degree, u, order, out, work):
    """:func:`curve_derivatives` with caller-owned scratch: no allocation.

    ``work`` holds at least ``workspace_size(degree, order)`` floats; hot loops
    (the contour-error projector, the env step) keep one and reuse it.
    """
    n = control_points.shape[0] - 1
    p = degree
    q = p + 1
    span = find_span(n, p, u, knots)
    du = min(order, p)
    nders = q * q + 4 * q  # N^(k)_j -> work[nders + k q + j]
    aders = nders + (du + 1) * q  # A^(k) (x, y) -> work[aders + 2 k], work[aders + 2 k + 1]
    wders = aders + 2 * (order + 1)  # w^(k) -> work[wders + k]
    basis_derivatives(span, u, p, du, knots, work, nders)
    # homogeneous derivatives A^(k) = sum N^(k) w P and w^(k) = sum N^(k) w
    for k in range(order + 1):
        ax = 0.0
        ay = 0.0
        wk = 0.0
        if k <= du:
            for j in range(q):
                i = span - p + j
                nw = work[nders + k * q + j] * weights[i]
                ax += nw * control_points[i, 0]
                ay += nw * control_points[i, 1]
                wk += nw
        work[aders + 2 * k] = ax
        work[aders + 2 * k + 1] = ay
        work[wders + k] = wk
    # A4.2: C^(k) = (A^(k) - sum_{i=1..k} binom(k, i) w^(i) C^(k-i)) / w
    inv_w = 1.0 / work[wders]
    for k in range(order + 1):
        vx = work[aders + 2 * k]
        vy = work[aders + 2 * k + 1]
        binom = 1.0
        for i in range(1, k + 1):
            binom = binom * (k - i + 1) / i
            vx -= binom * work[wders + i] * out[k - i, 0]
            vy -= binom * work[wders + i] * out[k - i, 1]
        out[k, 0] = vx * inv_w
        out[k, 1] = vy * inv_w


@njit(cache=True)
def curve_derivatives(control_points, weights, knots, degree, u, order, out):
    """C(u) and its derivatives with respect to u, Jahanpour et al. (2014), eq. (5) (A4.2).

    Parameters
    ----------
    control_points : (n+1, 2) float64 array, mm.
    weights : (n+1,) float64 array, positive.
    knots : (n+p+2,) float64 array, non-decreasing.
    degree : int, p >= 1.
    u : float, inside [knots[p], knots[n+1]].
    order : int, highest derivative wanted.
    out : (order+1, 2) float64 array, written with [C, C', C'', ...]
        in mm, mm/u, mm/u^2, ...
    """
    work = np.empty(workspace_size(degree, order))
    curve_derivatives_into(control_points, weights, knots, degree, u, order, out, work)


@njit(cache=True)
def _curve_derivatives_batch(control_points, weights, knots, degree, us, order, out):
    """Batched :func:`curve_derivatives`: out has shape (len(us), order+1, 2)."""
    work = np.empty(workspace_size(degree, order))
    for k in range(us.shape[0]):
        curve_derivatives_into(control_points, weights, knots, degree, us[k], order, out[k], work)


def _is_integer(x) -> bool:
    """True for an integral number (3, 3.0, np.int64(3)); False for bool, NaN, inf, str, None."""
    if isinstance(x, (bool, np.bool_, str, bytes)):
        return False
    try:
        return int(x) == x
    except (TypeError, ValueError, OverflowError):
        return False


class NurbsCurve:
    """A planar NURBS curve of any degree p >= 1, Jahanpour et al. (2014), eqs. (2)-(5).

    Parameters
    ----------
    control_points : array_like, shape (n+1, 2)
        Control points P_k in mm.
    weights : array_like, shape (n+1,)
        Positive, finite weights w_k.
    knots : array_like, shape (n+p+2,)
        Non-decreasing knot vector, kept in its own units (not renormalised).
        The curve is defined for u in [knots[p], knots[n+1]].
    degree : int
        Degree p >= 1.

    Raises
    ------
    ValueError
        If the definition is malformed; the message names the problem.

    Examples
    --------
    >>> line = NurbsCurve([[0, 0], [10, 0]], [1, 1], [0, 0, 1, 1], 1)
    >>> line.point(0.25)
    array([2.5, 0. ])
    """

    def __init__(self, control_points, weights, knots, degree: int):
        pts = _real_array("control_points", control_points, "mm")
        w = _real_array("weights", weights, "1")
        kv = _real_array("knots", knots, "units of u")
        if not _is_integer(degree):
            raise ValueError(f"degree must be an integer, got {degree!r}")
        p = int(degree)
        if p < 1:
            raise ValueError(f"degree must be >= 1, got {p}")
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"control_points must have shape (n+1, 2), got {pts.shape}")
        n1 = pts.shape[0]
        if n1 < p + 1:
            raise ValueError(f"a degree-{p} curve needs at least {p + 1} control points, got {n1}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("control_points must be finite")
        if w.shape != (n1,):
            raise ValueError(f"weights must have shape ({n1},) to match the control points, got {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w <= 0.0):
            raise ValueError("weights must be finite and positive")
        if kv.ndim != 1 or kv.shape[0] != n1 + p + 1:
            raise ValueError(
                f"knot count must be n + p + 2 = {n1 + p + 1} (m + 1 with m = n + p + 1) "
                f"for {n1} control points and degree {p}, got {kv.size}"
            )
        if not np.all(np.isfinite(kv)):
            raise ValueError("knots must be finite")
        if np.any(np.diff(kv) < 0.0):
            raise ValueError("knots must be non-decreasing")
        if not kv[n1] > kv[p]:
            raise ValueError("the knot vector leaves the curve an empty parameter range")
        if np.any(kv[p + 1 : n1 + p] - kv[1:n1] <= 0.0):
            raise ValueError(f"an interior knot is repeated more than p = {p} times")
        self.control_points = pts
        self.weights = w
        self.knots = kv
        self.degree = p
        for a in (pts, w, kv):
            a.flags.writeable = False

    @property
    def u_range(self) -> tuple[float, float]:
        """The parameter range (u_start, u_end) = (knots[p], knots[n+1])."""
        return float(self.knots[self.degree]), float(self.knots[-self.degree - 1])

    @property
    def kernel_args(self) -> NurbsArrays:
        """The curve's arrays for the numba kernels, a :class:`NurbsArrays` (a tuple: ``*kernel_args``
        gives the kernels of this module their leading four arguments)."""
        return NurbsArrays(self.control_points, self.weights, self.knots, self.degree)

    def _check_u(self, u: np.ndarray) -> None:
        lo, hi = self.u_range
        if not np.all(np.isfinite(u)):
            raise ValueError("u must be finite")
        if np.any(u < lo) or np.any(u > hi):
            raise ValueError(f"u outside the knot range [{lo}, {hi}]")

    def point(self, u: float) -> np.ndarray:
        """C(u) in mm, shape (2,)."""
        return self.derivatives(u, 0)[0]

    def derivatives(self, u: float, order: int = 2) -> np.ndarray:
        """[C(u), C'(u), ..., C^(order)(u)], shape (order+1, 2), with respect to u."""
        if not _is_integer(order) or order < 0:
            raise ValueError(f"order must be a non-negative integer, got {order!r}")
        uu = float(u)
        self._check_u(np.asarray(uu))
        out = np.empty((int(order) + 1, 2))
        curve_derivatives(self.control_points, self.weights, self.knots, self.degree, uu, int(order), out)
        return out

    def points(self, us) -> np.ndarray:
        """C(u) for an array of u, shape (len(us), 2) in mm."""
        return self.derivatives_array(us, 0)[:, 0, :]

    def derivatives_array(self, us, order: int = 2) -> np.ndarray:
        """Derivatives for an array of u, shape (len(us), order+1, 2)."""
        if not _is_integer(order) or order < 0:
            raise ValueError(f"order must be a non-negative integer, got {order!r}")
        uu = np.array(us, dtype=np.float64).reshape(-1)  # a writable copy: one compiled batch for every caller
        self._check_u(uu)
        out = np.empty((uu.size, int(order) + 1, 2))
        _curve_derivatives_batch(self.control_points, self.weights, self.knots, self.degree, uu, int(order), out)
        return out

    def arc_length(self, u_start: float | None = None, u_end: float | None = None) -> float:
        """Arc length in mm between two parameters (adaptive Gauss-Legendre per knot span).

        :func:`vcnc_gym.geometry.quadrature.arc_length` on ``|C'(u)|``, cut at the knots between: every knot
        span starts as 8 pieces of 16 nodes, bisected until a piece and its halves agree to 1e-12 relative (or
        to the resolution of u).  The compiled :func:`vcnc_gym.geometry.arclength.arc_between` computes the
        same integral (they agree to ~1e-15 on the heart, the omega and random curves of degree 1-5) and is the
        home of the kernels' arc lengths; its stopping rule is an absolute tolerance.
        """
        lo, hi = self.u_range
        a = lo if u_start is None else float(u_start)
        b = hi if u_end is None else float(u_end)
        self._check_u(np.array([a, b]))
        if b < a:
            raise ValueError("u_end must not be smaller than u_start")
        breaks = np.unique(np.concatenate([[a, b], self.knots[(self.knots > a) & (self.knots < b)]]))
        return arc_length(lambda us: np.linalg.norm(self.derivatives_array(us, 1)[:, 1, :], axis=1), breaks)

    def knot_turns(self) -> tuple[np.ndarray, np.ndarray]:
        """The distinct knots strictly inside the curve's range, and the angle (rad, in [0, pi]) by which the
        tangent turns across each: 0 where it is smooth, pi where it reverses; from the one-sided derivatives
        (the left one from the span before the knot)."""
        lo, hi = self.u_range
        inner = np.unique(self.knots[(self.knots > lo) & (self.knots < hi)])
        if not inner.size:
            return inner, np.zeros(0)
        before = self.derivatives_array(np.nextafter(inner, lo), 1)[:, 1]
        after = self.derivatives_array(inner, 1)[:, 1]
        return inner, math.pi - interior_angle(before, after)

    def check_regular(self) -> None:
        """Raise ``ValueError`` where the curve's tangent C'(u) / ``|C'(u)|`` is undefined.

        The interpolator divides by ``|C'(u)|`` (Jahanpour et al. (2014), eq. (9): du/dt =
        V / ``|C'|``) and the envs command the unit tangent, so a curve must be
        *regular*: C'(u) != 0 everywhere.  Checked, with relative tolerances
        so that the answer does not depend on the units of u or of the
        coordinates:

        1. the curve's length L is at least ``SPAN_LENGTH_TOLERANCE`` (1e-9)
           x its size max(L, max ``|P_k|``) mm;
        2. so is every non-empty knot span (a shorter span is a (near-)
           zero-length span: the curve stands still over it);
        3. ``|C'(u)|`` >= ``SPEED_TOLERANCE`` (1e-6) x the span's mean speed
           (span length / span width) for every u: ``|C'|`` is sampled at 65
           points per span (the right end from the left: u = nextafter(b,
           a)) and every sampled local minimum is refined by golden-section
           search to the resolution of u.  A point below the tolerance is
           reported as a *cusp* when the tangent turns by more than 90
           degrees across it, else as a *near-zero derivative* (a stalled
           parametrization, e.g. coincident control points).

        4. at every interior knot the one-sided tangents (the left one from
           the span before it) do not reverse: an interior angle at most
           ``TURN_BACK_ANGLE`` is a curve that *turns back on itself* (a
           180-degree corner), the rule :func:`~vcnc_gym.geometry.polyline`
           applies to its vertices.

        Any other corner at a knot of multiplicity p (one-sided tangents both
        non-zero) is regular.  The outcome is cached: the curve's arrays are
        read-only.

        Raises
        ------
        ValueError
            Naming the defect and the parameter u (or knot span) where it is.
        """
        if not hasattr(self, "_regularity"):
            self._regularity = self._find_irregularity()
        if self._regularity is not None:
            raise ValueError(self._regularity)

    def _find_irregularity(self) -> str | None:
        """The message of :meth:`check_regular`, or None for a regular curve."""
        total = self.arc_length()
        size = max(total, float(np.max(np.abs(self.control_points))))
        min_length = SPAN_LENGTH_TOLERANCE * size
        if not total > min_length:
            return (
                f"curve has (near-)zero length {total:.3g} mm, below SPAN_LENGTH_TOLERANCE = "
                f"{SPAN_LENGTH_TOLERANCE:g} x its size {size:.3g} mm: all control points coincide?"
            )
        lo, hi = self.u_range
        knots = np.unique(self.knots[(self.knots >= lo) & (self.knots <= hi)])
        starts, ends = knots[:-1], knots[1:]
        lengths = np.array([self.arc_length(a, b) for a, b in zip(starts, ends)])
        short = np.flatnonzero(~(lengths > min_length))
        if short.size:
            j = int(short[0])
            return (
                f"knot span [{starts[j]:.10g}, {ends[j]:.10g}] is {lengths[j]:.3g} mm long, below "
                f"SPAN_LENGTH_TOLERANCE = {SPAN_LENGTH_TOLERANCE:g} x the curve's size {size:.3g} mm: a "
                "(near-)zero-length span (coincident control points?) over which the curve stands still and "
                "its tangent is undefined"
            )
        inner = knots[1:-1]
        if inner.size:  # one-sided tangents at every breakpoint: the left from its span, the right from its own
            left = self.derivatives_array(np.nextafter(inner, lo), 1)[:, 1, :]
            right = self.derivatives_array(inner, 1)[:, 1, :]
            theta = interior_angle(left, right)
            back = np.flatnonzero(theta <= TURN_BACK_ANGLE)
            if back.size:
                j = int(back[0])
                return (
                    f"curve turns back on itself at the knot u = {inner[j]:.10g} (point "
                    f"{np.round(self.derivatives(float(inner[j]), 0)[0], 9).tolist()} mm): its tangent reverses "
                    f"there, interior angle {theta[j]:.3g} rad <= TURN_BACK_ANGLE = {TURN_BACK_ANGLE:g} rad (a "
                    "180-degree corner); the reference would reverse at full feed"
                )
        u_min, speed, span = self._slowest_points(starts, ends)
        ratio = speed / (lengths[span] / (ends[span] - starts[span]))
        j = int(np.argmin(ratio))
        if ratio[j] >= SPEED_TOLERANCE:
            return None
        u, a, b = float(u_min[j]), float(starts[span[j]]), float(ends[span[j]])
        where = (
            f"|C'(u)| = {speed[j]:.3g} mm per unit of u, {ratio[j]:.2g} of the knot span [{a:.10g}, {b:.10g}]'s "
            f"mean speed (SPEED_TOLERANCE = {SPEED_TOLERANCE:g})"
        )
        consequence = (
            "the feed relation of Jahanpour et al. (2014), eq. (9), du/dt = V / |C'(u)|, and the tangent are "
            "undefined there"
        )
        near = 1e-6 * (b - a)
        if u - lo <= near or hi - u <= near:
            end = "start" if u - lo <= near else "end"
            return (
                f"curve has a near-zero derivative C'(u) at its {end}, u = {u:.10g}: {where} (its first or last "
                f"control points coincide?); {consequence}"
            )
        step = 1e-3 * (b - a)
        before = self.derivatives(max(lo, u - step), 1)[1]
        after = self.derivatives(min(hi, u + step), 1)[1]
        if float(np.dot(before, after)) < 0.0:
            return f"curve has a cusp at u = {u:.10g}: the tangent reverses and {where}; {consequence}"
        return (
            f"curve has a near-zero derivative C'(u) at u = {u:.10g}: {where} (coincident control points?); "
            f"{consequence}"
        )

    def _slowest_points(self, starts: np.ndarray, ends: np.ndarray, n: int = 64):
        """Local minima of the parametric speed ``|C'(u)|`` on the knot spans [starts[i], ends[i]].

        ``|C'|`` on n + 1 points per span (the right end from the left,
        nextafter(b, a)), then golden-section search around every sampled
        local minimum, all spans at once, until the bracket is 1e-12 of its
        span or 4 floating-point steps of u (``|C'|`` then within ~1e-12 ``|C''|``
        (b - a) of the minimum).

        Returns
        -------
        u, speed : ndarray
            Where the minima are and ``|C'|`` there, mm per unit of u.
        span : ndarray of int
            The span (index into ``starts``) of each minimum.
        """
        ends_left = np.nextafter(ends, starts)
        us = starts[:, None] + (ends_left - starts)[:, None] * np.linspace(0.0, 1.0, n + 1)
        us[:, -1] = ends_left
        speed = self._speeds(us.reshape(-1)).reshape(us.shape)
        padded = np.pad(speed, ((0, 0), (1, 1)), constant_values=np.inf)
        span, i = np.nonzero((speed <= padded[:, :-2]) & (speed <= padded[:, 2:]))
        lo = us[span, np.maximum(i - 1, 0)]
        hi = us[span, np.minimum(i + 1, n)]
        best_u, best = us[span, i], speed[span, i]
        stop = np.maximum(1e-12 * (ends[span] - starts[span]), 4.0 * np.spacing(np.maximum(np.abs(lo), np.abs(hi))))
        x1 = lo + _GOLDEN * (hi - lo)
        x2 = hi - _GOLDEN * (hi - lo)
        f1, f2 = self._speeds(x1), self._speeds(x2)
        for _ in range(100):  # the bracket shrinks by 0.618 per pass: ~50 passes to `stop`
            if not np.any(hi - lo > stop):
                break
            left = f1 < f2  # the minimum lies in [lo, x2], else in [x1, hi]
            lo, hi = np.where(left, lo, x1), np.where(left, x2, hi)
            x1, x2 = np.where(left, lo + _GOLDEN * (hi - lo), x2), np.where(left, x1, hi - _GOLDEN * (hi - lo))
            fresh = self._speeds(np.where(left, x1, x2))
            f1, f2 = np.where(left, fresh, f2), np.where(left, f1, fresh)
            for x, f in ((x1, f1), (x2, f2)):
                better = f < best
                best_u, best = np.where(better, x, best_u), np.where(better, f, best)
        return best_u, best, span

    def _speeds(self, us) -> np.ndarray:
        """``|C'(u)|`` for an array of u, mm per unit of u."""
        d1 = self.derivatives_array(us, 1)[:, 1, :]
        return np.hypot(d1[:, 0], d1[:, 1])

    def __repr__(self) -> str:
        lo, hi = self.u_range
        return f"NurbsCurve(degree={self.degree}, n_control_points={len(self.weights)}, u_range=({lo:g}, {hi:g}))"
