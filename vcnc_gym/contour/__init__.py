"""Contour error: shortest distance from the tool to the whole reference contour."""

from .projector import ContourProjector, project_point

__all__ = ["ContourProjector", "project_point"]
