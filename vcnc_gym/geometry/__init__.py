"""What the tool must trace: curves that know points and derivatives, not time."""

from .nurbs import NurbsCurve
from .shapes import SHAPES, heart, omega

__all__ = ["NurbsCurve", "SHAPES", "heart", "omega"]
