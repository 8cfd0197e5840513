"""Simba et al.'s cycle-time figure: their test path sharp at a constant feed against corner-smoothed with JLAPs.

``python -c "from vcnc_bench.reports.simba import corners_cycle_times as c; print(c())"``
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.geometry.corners import smooth_polyline
from vcnc_gym.geometry.shapes import corners_vertices
from vcnc_gym.motion.jlap import SIMBA_A_MAX, SIMBA_FEEDRATE, SIMBA_J_MAX, JlapFeedrate, constant_feedrate

__all__ = ["corners_cycle_times"]


def corners_cycle_times(epsilon: float = 0.05) -> dict:
    """Cycle times of Simba et al.'s test path: sharp at constant feed, smoothed with JLAPs.

    Simba et al., section IV-C, report +1.36 % for the smoothed path (experiment).

    Parameters
    ----------
    epsilon : float
        Corner tolerance, mm (Simba et al.: 0.05).

    Returns
    -------
    dict with ``linear_length`` (mm), ``linear_time`` (s, length / 50 mm/s),
    ``smooth_length`` (mm), ``smooth_time`` (s, the JLAP plan's duration),
    ``increase`` (relative, smooth / linear - 1) and ``corner_speeds`` (mm/s).
    """
    vertices = corners_vertices()
    path = smooth_polyline(vertices, epsilon, SIMBA_A_MAX, SIMBA_J_MAX)
    linear_length = float(np.sum(np.hypot(*np.diff(vertices, axis=0).T)))
    linear = constant_feedrate(linear_length, SIMBA_FEEDRATE)
    smooth = JlapFeedrate().plan_path(path)
    return {
        "linear_length": linear_length,
        "linear_time": linear.duration,
        "smooth_length": path.length,
        "smooth_time": smooth.duration,
        "increase": smooth.duration / linear.duration - 1.0,
        "corner_speeds": path.corner_speeds.tolist(),
    }
