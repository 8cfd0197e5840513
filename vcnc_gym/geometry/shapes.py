"""The named contours of the seeds, in machine coordinates (mm).

Each function returns a fresh curve exactly as the paper defines it: not
rescaled, not shifted, knots in their own units.
"""

from __future__ import annotations

from .nurbs import NurbsCurve

__all__ = ["heart", "omega", "SHAPES"]


def heart() -> NurbsCurve:
    """The "heart" of seed 000, section 3a: cubic, 9 control points, u in [0, 6].

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
    """The "omega" of seed 000, section 3a: quadratic, 12 control points, u in [0, 1].

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


SHAPES = {"heart": heart, "omega": omega}
"""Named contour constructors, by the name used in env ids."""
