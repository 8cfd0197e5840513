"""Gymnasium environments: they wire a reference, a plant and a reward together."""

from .contouring_env import ContouringEnv
from .layout import Field, ObservationLayout

__all__ = ["ContouringEnv", "Field", "ObservationLayout"]
