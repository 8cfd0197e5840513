"""Step-response metrics: overshoot, settling time, rise time (Yadav et al. (2020), Table 2).

The response ``y(t)`` to a step from ``initial`` to ``target`` applied at
``t[0]`` is normalised, ``z = (y - initial) / (target - initial)``, and

- **overshoot** [%]: ``100 max(0, max z - 1)``;
- **settling time** [s]: the time after which ``|z - 1| <= band`` (2 %) for
  the rest of the record; ``inf`` if the record ends outside the band;
- **rise time** [s]: from the first time ``z`` reaches 10 % to the first time
  it reaches 90 % (the limits of ``rise``); ``nan`` if it never does;
- **rise time 0-100 %** [s]: the first time ``z`` reaches 1 (the textbook
  rise time of an underdamped response); ``nan`` if it never does.

Crossing times are interpolated linearly between samples, so a record
sampled at ``dt`` resolves them far below ``dt`` for a smooth response.
Times are measured from ``t[0]``, the instant of the step.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["StepMetrics", "step_metrics"]


@dataclass(frozen=True)
class StepMetrics:
    """Metrics of one step response (see the module docstring)."""

    overshoot: float
    """Overshoot in % of the step."""
    settling_time: float
    """2 % settling time in s (``inf``: not settled within the record)."""
    rise_time: float
    """10-90 % rise time in s (``nan``: never reached 90 %)."""
    rise_time_100: float
    """0-100 % rise time in s (``nan``: never reached the target)."""

    def as_dict(self) -> dict:
        """The metrics as a plain dict of floats."""
        return asdict(self)


def _first_crossing(t: np.ndarray, z: np.ndarray, level: float) -> float:
    """First time z reaches ``level`` from below, interpolated; nan if never."""
    above = np.nonzero(z >= level)[0]
    if above.size == 0:
        return math.nan
    j = int(above[0])
    if j == 0:
        return float(t[0])
    z0, z1 = z[j - 1], z[j]
    return float(t[j - 1] + (level - z0) / (z1 - z0) * (t[j] - t[j - 1]))


def step_metrics(
    t, y, target: float, initial: float | None = None, band: float = 0.02, rise: tuple[float, float] = (0.1, 0.9)
) -> StepMetrics:
    """Overshoot, settling time and rise times of a step response.

    Parameters
    ----------
    t : array_like, (K,)
        Sample times in s, increasing; ``t[0]`` is the instant of the step.
    y : array_like, (K,)
        The response (any unit; mm in the envs).  Non-finite samples count
        as outside the settling band.
    target : float
        The set-point the step goes to (same unit as ``y``).
    initial : float, optional
        The value before the step; default ``y[0]``.
    band : float
        Settling band as a fraction of the step, in (0, 1); 0.02 for 2 %.
    rise : (float, float)
        Rise-time limits as fractions of the step, 0 <= lo < hi <= 1.

    Returns
    -------
    StepMetrics

    Raises
    ------
    ValueError
        For arrays of different or too short lengths, non-increasing times,
        a step of zero size, or a band or rise limits out of range.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if t.ndim != 1 or t.shape != y.shape or t.size < 2:
        raise ValueError(f"t and y must be 1-D of one length >= 2, got shapes {t.shape} and {y.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0.0)):
        raise ValueError("t must be finite and strictly increasing (s)")
    y0 = float(y[0]) if initial is None else float(initial)
    step = float(target) - y0
    if not math.isfinite(step) or step == 0.0:
        raise ValueError(f"the step from {y0} to {target} has no finite non-zero size")
    if not 0.0 < band < 1.0:
        raise ValueError(f"band must be a fraction in (0, 1), got {band!r}")
    lo, hi = rise
    if not 0.0 <= lo < hi <= 1.0:
        raise ValueError(f"rise limits must satisfy 0 <= lo < hi <= 1, got {rise!r}")

    z = (y - y0) / step
    finite = np.isfinite(z)
    peak = float(np.max(z[finite])) if finite.any() else math.inf
    overshoot = 100.0 * max(0.0, peak - 1.0) if finite.all() else math.inf

    outside = ~finite | (np.abs(z - 1.0) > band)
    if outside[-1]:
        settling = math.inf
    elif not outside.any():
        settling = float(t[0])
    else:
        j = int(np.nonzero(outside)[0][-1])
        if finite[j]:
            boundary = 1.0 + band if z[j] > 1.0 else 1.0 - band
            settling = float(t[j] + (boundary - z[j]) / (z[j + 1] - z[j]) * (t[j + 1] - t[j]))
        else:
            settling = float(t[j + 1])

    z_rise = np.where(finite, z, -np.inf)
    t_lo = _first_crossing(t, z_rise, lo)
    t_hi = _first_crossing(t, z_rise, hi)
    return StepMetrics(
        overshoot=overshoot,
        settling_time=settling - float(t[0]),
        rise_time=t_hi - t_lo,
        rise_time_100=_first_crossing(t, z_rise, 1.0) - float(t[0]),
    )
