"""How fast along the curve: feedrate profiles and the interpolator.

Profiles (anything with ``plan(length)``): :class:`SCurveFeedrate`, the cubic
S-curve of seed 000 section 2b; :class:`ConstantFeedrate`, a constant feed
from the start (seed 002's linear case, seed 003's circle);
:class:`JlapPathFeedrate`, seed 002's jerk-limited profile along a
corner-smoothed path (:mod:`vcnc_gym.motion.jlap`);
:class:`LookaheadFeedrate`, the feed scheduled ahead by the curvature (normal
acceleration and jerk limits) with jerk-limited changes, bidirectional scans
(:mod:`vcnc_gym.motion.lookahead`).  Every plan is a
piecewise quartic S(t) (:mod:`vcnc_gym.motion.profile`), so
:func:`interpolate` turns any curve and profile into a :class:`Reference`
sampled at the control period, with the second-order Taylor interpolator of
seed 000 eqs. (8)-(10), checked step by step (``STEP_TOLERANCE``) and bounded
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
