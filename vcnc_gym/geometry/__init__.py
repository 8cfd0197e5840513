"""What the tool must trace: curves that know points and derivatives, not time."""

from .corners import CornerDesign, SmoothedPolyline, polyline, smooth_polyline
from .nurbs import NurbsCurve
from .shapes import SHAPES, corners_path, corners_vertices, heart, omega

__all__ = [
    "CornerDesign",
    "NurbsCurve",
    "SHAPES",
    "SmoothedPolyline",
    "corners_path",
    "corners_vertices",
    "heart",
    "omega",
    "polyline",
    "smooth_polyline",
]
