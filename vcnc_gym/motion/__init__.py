"""How fast along the curve: feedrate profiles and the interpolator.

Profiles (anything with ``plan(length)``): :class:`SCurveFeedrate`, the cubic
S-curve of Jahanpour et al.'s section 2b; :class:`ConstantFeedrate`, a constant feed
from the start (Simba et al.'s linear case, Purtojo et al.'s circle);
:class:`JlapPathFeedrate`, Simba et al.'s jerk-limited profile along a
corner-smoothed path (:mod:`vcnc_gym.motion.jlap`);
:class:`LookaheadFeedrate`, the feed scheduled ahead by the curvature (normal
acceleration and jerk limits) with jerk-limited changes, bidirectional scans
(:mod:`vcnc_gym.motion.lookahead`).  Every plan is a
piecewise quartic S(t) (:mod:`vcnc_gym.motion.profile`), so
:func:`interpolate` turns any curve and profile into a :class:`Reference`
sampled at the control period, with the second-order Taylor interpolator of
Jahanpour et al.'s eqs. (8)-(10), checked step by step (``STEP_TOLERANCE``) and bounded
in cost (:func:`reference_samples`, ``MAX_REFERENCE_SAMPLES``).
"""

from .feedrate import FeedratePlan, SCurveFeedrate
from .interpolator import MAX_REFERENCE_SAMPLES, STEP_TOLERANCE, Reference, interpolate, reference_samples
from .jlap import ConstantFeedrate, JlapFeedrate, JlapPathFeedrate, JlapPlan, constant_feedrate
from .lookahead import LookaheadFeedrate, LookaheadPlan

__all__ = [
    "ConstantFeedrate",
    "FeedratePlan",
    "JlapFeedrate",
    "JlapPathFeedrate",
    "JlapPlan",
    "LookaheadFeedrate",
    "LookaheadPlan",
    "MAX_REFERENCE_SAMPLES",
    "Reference",
    "SCurveFeedrate",
    "STEP_TOLERANCE",
    "constant_feedrate",
    "interpolate",
    "reference_samples",
]
