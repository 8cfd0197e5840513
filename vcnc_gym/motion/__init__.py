"""How fast along the curve: feedrate profiles and the interpolator.

:class:`SCurveFeedrate` plans the cubic S-curve of seed 000 section 2b over a
path length; :func:`interpolate` turns a curve and a profile into a
:class:`Reference` sampled at the control period, with the second-order
Taylor interpolator of seed 000 eqs. (8)-(10), checked step by step
(``STEP_TOLERANCE``) and bounded in cost (:func:`reference_samples`,
``MAX_REFERENCE_SAMPLES``).
"""

from .feedrate import FeedratePlan, SCurveFeedrate
from .interpolator import MAX_REFERENCE_SAMPLES, STEP_TOLERANCE, Reference, interpolate, reference_samples

__all__ = [
    "FeedratePlan",
    "MAX_REFERENCE_SAMPLES",
    "Reference",
    "SCurveFeedrate",
    "STEP_TOLERANCE",
    "interpolate",
    "reference_samples",
]
