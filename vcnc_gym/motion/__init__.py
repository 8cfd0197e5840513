"""How fast along the curve: feedrate profiles and the interpolator.

:class:`SCurveFeedrate` plans the cubic S-curve of seed 000 section 2b over a
path length; :func:`interpolate` turns a curve and a profile into a
:class:`Reference` sampled at the control period, with the second-order
Taylor interpolator of seed 000 eqs. (8)-(10).
"""

from .feedrate import FeedratePlan, SCurveFeedrate
from .interpolator import Reference, interpolate

__all__ = ["FeedratePlan", "Reference", "SCurveFeedrate", "interpolate"]
