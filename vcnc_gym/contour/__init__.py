"""Contour error: shortest distance from the tool to the whole reference contour."""

from .projector import NO_FOOT, ContourProjector, project_point, project_point_warm

__all__ = ["ContourProjector", "NO_FOOT", "project_point", "project_point_warm"]
