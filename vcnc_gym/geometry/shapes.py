"""The named contours of the source papers, in machine coordinates (mm).

Each function returns a fresh curve exactly as the paper defines it: not
rescaled, not shifted, knots in their own units.
"""

from __future__ import annotations

import math

import numpy as np

from ..plants.current_feed_drive import SIMBA_A_MAX, SIMBA_J_MAX
from ..validation import positive
from .corners import polyline, smooth_polyline
from .nurbs import NurbsCurve

__all__ = ["heart", "omega", "corners_vertices", "corners_path", "circle", "SHAPES"]


def heart() -> NurbsCurve:
    """The "heart" of Jahanpour et al. (2014), section 3a: cubic, 9 control points, u in [0, 6].

    It starts and ends at the origin; the paper traces it clockwise.
    """
    x = [0, 0, -20, 40, 90, 40, -20, 0, 0]
    y = [0, 10, 50, 50, 0, -50, -50, -10, 0]
    return NurbsCurve(
        control_points=list(zip(x, y)),
        weights=[1, 1, 1.7, 1, 4, 1, 1.7, 1, 1],
        knots=[0, 0, 0, 0, 1, 2, 3, 4, 5, 6, 6, 6, 6],
        degree=3,
    )


def omega() -> NurbsCurve:
    """The "omega" of Jahanpour et al. (2014), section 3a: quadratic, 12 control points, u in [0, 1].

    Traced from left to right.
    """
    x = [0, 0, 6, 4, 1, 5, 11, 15, 12, 10, 16, 16]
    y = [1, 0, 0, 2, 11, 16, 16, 11, 2, 0, 0, 1]
    return NurbsCurve(
        control_points=list(zip(x, y)),
        weights=[1] * 12,
        knots=[0, 0, 0, 0.025, 0.1, 0.2, 0.4, 0.5, 0.6, 0.8, 0.9, 0.975, 1, 1, 1],
        degree=2,
    )


def corners_vertices() -> np.ndarray:
    """Vertices (mm) of Simba et al.'s test path (Fig. 5): corners of 30, 60 and 90 degrees.

    Simba et al. name the interior angles (section IV-A) but give no lengths.
    Our choice: four 50 mm segments (200 mm, 4 s at the paper's 50 mm/s, so
    the linear path meets its corners at 1, 2 and 3 s and stops at 4 s, where
    the paper's Fig. 11 shows its overshoots), starting at the origin along
    +x, turning left 150 degrees (a 30-degree corner), right 120 degrees (60)
    and left 90 degrees (90).  Every vertex is >= 25 mm from the segments not
    meeting it, so the path never comes near itself.

    Returns
    -------
    (5, 2) float64 array, mm.
    """
    segment = 50.0
    headings = [0.0, 150.0, 30.0, 120.0]  # degrees: turns of +150, -120, +90
    steps = [[segment * math.cos(math.radians(h)), segment * math.sin(math.radians(h))] for h in headings]
    return np.cumsum(np.array([[0.0, 0.0]] + steps), axis=0)


def corners_path(
    smooth: bool = True, epsilon: float = 0.05, a_max: float | None = None, j_max: float | None = None
) -> NurbsCurve:
    """Simba et al.'s test path (Fig. 5, :func:`corners_vertices`), sharp or corner-smoothed.

    Parameters
    ----------
    smooth : bool
        True: corners replaced by quintic Bezier blends (Simba et al., eqs. (12)-(23)),
        a degree-5 NURBS; False: the sharp polyline, a degree-1 NURBS whose
        parameter is the arc length.
    epsilon : float
        Corner tolerance, mm (Simba et al., section IV-A: 50 um).
    a_max, j_max : float or None
        Limits the blends are designed for, mm/s^2 and mm/s^3; None: Simba et al.'s
        drives (:mod:`vcnc_gym.plants.current_feed_drive`).
    """
    if not smooth:
        return polyline(corners_vertices())
    a_max = SIMBA_A_MAX if a_max is None else a_max
    j_max = SIMBA_J_MAX if j_max is None else j_max
    return smooth_polyline(corners_vertices(), epsilon, a_max, j_max).curve


def circle(radius: float = 1.0) -> NurbsCurve:
    """The circle of Purtojo et al., section IV: radius ``radius`` mm (the paper's 1 mm), centred at the origin.

    An exact NURBS: rational quadratic, 9 control points on the corners and
    edge midpoints of the circumscribed square, weights 1 and sqrt(2)/2
    (Piegl and Tiller, The NURBS Book, 2nd ed., section 7.5), u in [0, 1],
    one quarter per knot span.  It starts at (0, R) and runs clockwise, as
    x = R sin(w t), y = R cos(w t) do (Purtojo et al.: a sine on the x axis, a
    cosine on the y axis).
    """
    r = positive("radius", radius, "mm")
    x = [0, r, r, r, 0, -r, -r, -r, 0]
    y = [r, r, 0, -r, -r, -r, 0, r, r]
    w = math.sqrt(0.5)
    return NurbsCurve(
        control_points=list(zip(x, y)),
        weights=[1, w, 1, w, 1, w, 1, w, 1],
        knots=[0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1],
        degree=2,
    )


def corners_smooth(epsilon: float = 0.05):
    """Simba et al.'s test path with its corners smoothed (eqs. (12)-(23), epsilon = 50 um), as the
    :class:`~vcnc_gym.geometry.corners.SmoothedPolyline` (curve and corner zones, which the
    jerk-limited feedrate plans along)."""
    return smooth_polyline(corners_vertices(), epsilon, SIMBA_A_MAX, SIMBA_J_MAX)


SHAPES = {
    "heart": heart,
    "omega": omega,
    "circle": circle,
    "corners": lambda: corners_path(smooth=False),
    "corners-smooth": corners_smooth,
}
"""Named contour constructors, by the name used in env ids: a NurbsCurve, or for
"corners-smooth" a SmoothedPolyline (its ``curve`` is the contour)."""
