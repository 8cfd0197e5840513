"""Analysis tools shared by the papers: interval polynomials (Kharitonov) and step-response metrics.

- :mod:`~vcnc_gym.analysis.kharitonov`: the four Kharitonov polynomials of an
  interval polynomial (Yadav et al. (2020), eq. (4)), a Routh-Hurwitz test and the
  stability margin of a third-order interval polynomial (Yadav et al. (2020), eq. (5));
- :mod:`~vcnc_gym.analysis.step_metrics`: overshoot, settling time and rise
  time of a step response (Yadav et al. (2020), Table 2).
"""

from .kharitonov import (
    hurwitz,
    interval_polynomial,
    kharitonov_polynomials,
    robustly_stable,
    routh_first_column,
    stability_margin,
)
from .step_metrics import StepMetrics, step_metrics

__all__ = [
    "hurwitz",
    "interval_polynomial",
    "kharitonov_polynomials",
    "robustly_stable",
    "routh_first_column",
    "stability_margin",
    "StepMetrics",
    "step_metrics",
]
