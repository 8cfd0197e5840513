"""Circular arcs as exact rational quadratic Bezier segments, and Bezier degree elevation.

An arc of sweep phi <= 90 degrees is one rational quadratic Bezier segment
(Piegl and Tiller, *The NURBS Book*, 2nd ed., section 7.3, eqs. (7.7)-(7.8);
Jahanpour et al.'s curve type): end points P0, P2 on the circle, the middle point P1
where the end tangents meet, at distance r / cos(phi / 2) from the centre on
the bisector, weights (1, cos(phi / 2), 1).  A longer arc is cut into
ceil(``|sweep|`` / 90 deg) equal segments (section 7.5, algorithm A7.1), a full
circle into four.  Every point of such a segment lies on the circle exactly
(up to rounding), which tests/test_gcode.py checks to 1e-9 mm.

Degree elevation (section 5.5, eq. (5.36)) raises a Bezier segment from
degree p to p + t without changing the curve:

    Q_i = sum_{j = max(0, i - t)}^{min(p, i)} C(p, j) C(t, i - j) / C(p + t, i) P_j,

applied to the homogeneous control points (w x, w y, w), so a rational arc
stays the same exact arc at degree 5, the degree of Simba et al.'s corner blends.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["arc_segments", "elevate", "homogeneous", "line_segment"]

#: Largest sweep of one rational quadratic segment, rad (Piegl and Tiller, A7.1).
MAX_SEGMENT_SWEEP = 0.5 * math.pi


def homogeneous(points, weights) -> np.ndarray:
    """(k, 3) homogeneous control points (w x, w y, w)."""
    p = np.asarray(points, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    return np.column_stack([p * w[:, None], w])


def arc_segments(centre, radius: float, start_angle: float, sweep: float) -> list[np.ndarray]:
    """The arc as rational quadratic Bezier segments, each (3, 3) homogeneous, in the order travelled.

    Parameters
    ----------
    centre : (2,) mm
    radius : float, mm, > 0
    start_angle : float
        Angle of the start point seen from the centre, rad.
    sweep : float
        Signed sweep, rad (counter-clockwise positive), ``|sweep|`` <= 2 pi.
    """
    c = np.asarray(centre, dtype=np.float64)
    n = max(1, math.ceil(abs(sweep) / MAX_SEGMENT_SWEEP - 1e-12))
    step = sweep / n
    w1 = math.cos(0.5 * step)
    segments = []
    for k in range(n):
        a0 = start_angle + k * step
        a1 = a0 + step
        am = a0 + 0.5 * step
        p0 = c + radius * np.array([math.cos(a0), math.sin(a0)])
        p2 = c + radius * np.array([math.cos(a1), math.sin(a1)])
        p1 = c + radius / w1 * np.array([math.cos(am), math.sin(am)])
        segments.append(homogeneous([p0, p1, p2], [1.0, w1, 1.0]))
    return segments


def line_segment(a, b) -> np.ndarray:
    """A straight segment as a degree-1 Bezier, (2, 3) homogeneous."""
    return homogeneous([a, b], [1.0, 1.0])


def elevate(segment: np.ndarray, degree: int) -> np.ndarray:
    """A Bezier segment (homogeneous, (p + 1, 3)) raised to ``degree`` >= p (eq. (5.36)): the same curve."""
    p = segment.shape[0] - 1
    t = degree - p
    if t < 0:
        raise ValueError(f"cannot lower a degree-{p} segment to degree {degree}")
    if t == 0:
        return segment.copy()
    out = np.zeros((degree + 1, segment.shape[1]))
    for i in range(degree + 1):
        for j in range(max(0, i - t), min(p, i) + 1):
            out[i] += math.comb(p, j) * math.comb(t, i - j) / math.comb(degree, i) * segment[j]
    return out
