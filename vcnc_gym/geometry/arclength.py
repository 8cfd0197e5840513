"""Arc length and curvature of a NURBS curve, as numba kernels: the interpolator's and the look-ahead feed's.

:func:`arc_between` integrates ``|C'(u)|`` by adaptive 5-point Gauss-Legendre per knot span, cut at the knots
(where ``C'`` may jump), accurate to a given tolerance in mm; :func:`curve_speed` and :func:`curve_curvature` read
``|C'|`` and ``|C' x C''| / |C'|^3`` from a derivatives array (:func:`~vcnc_gym.geometry.nurbs.curve_derivatives_into`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .nurbs import FIRST, curve_derivatives_into, find_span

__all__ = ["ARC_STACK", "gauss_arc", "arc_between", "curve_speed", "curve_curvature"]

# 5-point Gauss-Legendre rule on [-1, 1], for arc lengths of single steps
_GL_X, _GL_W = np.polynomial.legendre.leggauss(5)
ARC_STACK = 64  # depth of the adaptive quadrature's stack (bisections of one step)


@njit(cache=True)
def gauss_arc(control_points, weights, knots, degree, a, b, ders, work):
    """Arc length from a to b (one knot span) by 5-point Gauss-Legendre on ``|C'(u)|``, mm.

    A node that rounds onto b (a piece a few ulps wide) is moved just below
    it: at a knot the evaluator takes the span on the right.
    """
    half = 0.5 * (b - a)
    mid = 0.5 * (a + b)
    below_b = np.nextafter(b, a)
    total = 0.0
    for i in range(_GL_X.shape[0]):
        x = min(max(mid + half * _GL_X[i], a), below_b)
        curve_derivatives_into(control_points, weights, knots, degree, x, FIRST, ders, work)
        total += _GL_W[i] * math.sqrt(ders[1, 0] * ders[1, 0] + ders[1, 1] * ders[1, 1])
    return half * total


@njit(cache=True)
def _arc_within_span(control_points, weights, knots, degree, a, b, tol, ders, work, stack):
    """Arc length from a to b inside one knot span (``|C'|`` smooth), adaptive Gauss-Legendre, mm.

    A piece is accepted when its 5-point value and the sum over its two
    halves agree to ``tol`` mm (or to 1e-13 relative); otherwise its halves
    are pushed on ``stack`` (shape (3, ARC_STACK)): at most ~60 bisections
    deep, far below the resolution of u.
    """
    total = 0.0
    top = 0
    stack[0, 0] = a
    stack[1, 0] = b
    stack[2, 0] = gauss_arc(control_points, weights, knots, degree, a, b, ders, work)
    top = 1
    while top > 0:
        top -= 1
        lo = stack[0, top]
        hi = stack[1, top]
        whole = stack[2, top]
        mid = 0.5 * (lo + hi)
        left = gauss_arc(control_points, weights, knots, degree, lo, mid, ders, work)
        right = gauss_arc(control_points, weights, knots, degree, mid, hi, ders, work)
        halves = left + right
        if abs(halves - whole) <= max(tol, 1e-13 * halves) or top >= ARC_STACK - 2 or not (lo < mid < hi):
            total += halves
        else:
            stack[0, top] = lo
            stack[1, top] = mid
            stack[2, top] = left
            stack[0, top + 1] = mid
            stack[1, top + 1] = hi
            stack[2, top + 1] = right
            top += 2
    return total


@njit(cache=True)
def arc_between(control_points, weights, knots, degree, a, b, tol, ders, work, stack):
    """Arc length of the curve from u = a to u = b >= a in mm, cut at the knots between.

    Adaptive Gauss-Legendre per knot span (see :func:`_arc_within_span`),
    accurate to about ``tol`` mm per span.  ``ders`` (>= (2, 2)), ``work``
    (``workspace_size(degree, 1)``) and ``stack`` ((3, 64)) are scratch.
    """
    n = control_points.shape[0] - 1
    j = find_span(n, degree, a, knots) + 1
    lo = a
    total = 0.0
    while j <= n and knots[j] < b:
        if knots[j] > lo:
            total += _arc_within_span(control_points, weights, knots, degree, lo, knots[j], tol, ders, work, stack)
            lo = knots[j]
        j += 1
    if b > lo:
        total += _arc_within_span(control_points, weights, knots, degree, lo, b, tol, ders, work, stack)
    return total


@njit(cache=True)
def curve_speed(ders):
    """``|C'(u)|`` from ``ders`` ((>= 2, 2): C, C', ...), mm per unit of u."""
    return math.sqrt(ders[1, 0] * ders[1, 0] + ders[1, 1] * ders[1, 1])


@njit(cache=True)
def curve_curvature(ders, speed):
    """``|C' x C''|`` / ``|C'|^3``, 1/mm, in an order that neither overflows nor underflows early."""
    cross = abs(ders[1, 0] * ders[2, 1] - ders[1, 1] * ders[2, 0])
    return cross / speed / speed / speed
