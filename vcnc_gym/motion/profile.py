"""Every feedrate plan in one form: the distance along the path S(t) as a piecewise quartic.

The interpolator (:func:`vcnc_gym.motion.interpolate`) reads a plan only
through its ``kernel_args``, ``(breaks, coeffs)``:

- ``breaks`` (K+1,), s: piece boundaries, ``breaks[0] = 0`` and
  ``breaks[K]`` the duration;
- ``coeffs`` (K+1, 5): row k < K holds the Taylor coefficients of S at
  ``breaks[k]``, ``[S, V, A/2, J/6, Sn/24]`` (mm, mm/s, mm/s^2, mm/s^3,
  mm/s^4), so that ``S(t) = sum_j coeffs[k, j] tau^j`` with
  ``tau = t - breaks[k]``; row K is the rest after the motion,
  ``[length, 0, 0, 0, 0]``.

Jahanpour et al.'s (2014) cubic S-curve (quartic S on its ramps), Simba et
al.'s jerk-limited profiles (cubic S, constant jerk per piece) and a constant feedrate (linear
S) are all exactly of this form, so one compiled evaluator,
:func:`plan_state`, serves them all.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["PLAN_COLUMNS", "PlanArrays", "plan_state", "plan_arrays"]

#: Columns of ``coeffs``: S, V, A/2, J/6, snap/24.
PLAN_COLUMNS = 5


class PlanArrays(NamedTuple):
    """A plan as the compiled kernels take it, one argument: :func:`plan_arrays`."""

    breaks: np.ndarray  #: (K+1,) float64, s
    coeffs: np.ndarray  #: (K+1, PLAN_COLUMNS) float64, the Taylor coefficients of S per piece


@njit(cache=True)
def plan_piece(t, breaks):
    """Index k of the piece holding time ``t`` s (K, the rest row, at and after the end)."""
    k_end = breaks.shape[0] - 1
    if t >= breaks[k_end]:
        return k_end
    lo = 0
    hi = k_end
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if breaks[mid] <= t:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True)
def plan_state(t, breaks, coeffs):
    """Planned (S mm, V mm/s, A mm/s^2) at time ``t`` s; (0, 0, 0) before the start."""
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    k = plan_piece(t, breaks)
    c = coeffs[k]
    tau = t - breaks[k] if k < breaks.shape[0] - 1 else 0.0
    s = c[0] + tau * (c[1] + tau * (c[2] + tau * (c[3] + tau * c[4])))
    v = c[1] + tau * (2.0 * c[2] + tau * (3.0 * c[3] + tau * 4.0 * c[4]))
    a = 2.0 * c[2] + tau * (6.0 * c[3] + tau * 12.0 * c[4])
    return s, v, a


def plan_arrays(plan) -> PlanArrays:
    """``(breaks, coeffs)`` of any plan in this module's form, a :class:`PlanArrays`: ``plan.kernel_args``, a
    cubic (4-column, Simba et al.'s jerk-limited plans) widened with a zero quartic column.

    Raises
    ------
    ValueError
        If the arrays are not of the form (breaks increasing from 0, one row more than pieces).
    """
    breaks, coeffs = (np.ascontiguousarray(a, dtype=np.float64) for a in plan.kernel_args)
    if coeffs.ndim != 2 or coeffs.shape[1] > PLAN_COLUMNS or coeffs.shape[0] != breaks.shape[0]:
        raise ValueError(
            f"a plan's kernel_args must be breaks (K+1,) and coeffs (K+1, <= {PLAN_COLUMNS}), "
            f"got {breaks.shape} and {coeffs.shape}"
        )
    if breaks[0] != 0.0 or np.any(np.diff(breaks) <= 0.0):
        raise ValueError("a plan's breaks must start at 0 s and increase")
    if coeffs.shape[1] < PLAN_COLUMNS:
        coeffs = np.hstack([coeffs, np.zeros((coeffs.shape[0], PLAN_COLUMNS - coeffs.shape[1]))])
    return PlanArrays(breaks, coeffs)
