"""Cross-coupled control: Koren (1980), and the variable gains of Koren and Lo (1991) (``ccc``, ``vgccc``, ``ff-ccc``).

Each axis keeps its PID loop (:mod:`vcnc_baselines.feedforward.ff_pid`'s, with or without the inverse-model
feedforward); a coupling controller acts on the contour error estimated from both axes' tracking errors
``E = x_d - x`` and the reference's tangent angle ``theta`` and curvature ``kappa``, and returns its output
to the axes along the contour normal (:mod:`vcnc_baselines.servo`):

- Koren (1980): ``epsilon = -E_x sin(theta) + E_y cos(theta)`` (the normal error), corrections
  ``(-C_x w, C_y w)`` with ``C_x = sin(theta)``, ``C_y = cos(theta)``;
- Koren and Lo (1991): ``C_x = sin(theta) - kappa E_x / 2``, ``C_y = cos(theta) + kappa E_y / 2``, which
  adds the second-order term of the distance to a circle of radius ``1 / kappa``.

The coupling controller ``w = K_c epsilon + K_ci integral(epsilon)`` is a PI whose gains follow the axes'
(``K_c = coupling * mean(K_p)``, ``K_ci = coupling * mean(K_i)``).
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.validation import non_negative
from ..feedforward.ff_pid import FeedforwardPIDPolicy
from ..servo import ServoGains

__all__ = ["CrossCoupledPolicy", "FeedforwardCrossCoupledPolicy"]


class CrossCoupledPolicy(FeedforwardPIDPolicy):
    """Axis PID loops plus a cross-coupled PI on the estimated contour error (Koren 1980; Koren and Lo 1991).

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt, bandwidth, integral, friction_time, backlash_time
        As :class:`~vcnc_baselines.feedforward.ff_pid.FeedforwardPIDPolicy`.
    feedforward : bool
        Default False: Koren's CCC runs the axis loops without feedforward (``ff-ccc`` adds it).
    coupling : float
        Coupling gains relative to the axis gains, >= 0.  Default 0.1: the best max contour error of 0.1, 0.3
        and 1 on the heart, the look-ahead omega and the circle
        (``python experiments/classical-opponents/tune_servo.py``; 1 is 3-4 times worse on Jahanpour et al.'s drive).
    variable : bool
        Koren and Lo's variable gains (True) or Koren's fixed ones (False, default).
    """

    name = "ccc"

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        *,
        reference,
        dt,
        task=None,
        commissioning: str | None = None,
        bandwidth=None,
        integral: bool = True,
        feedforward=False,
        coupling: float = 0.1,
        variable: bool = False,
        friction_time: float | None = None,
        backlash_time: float = 16e-3,
    ):
        self.coupling = non_negative("coupling", coupling)
        self.variable = bool(variable)
        super().__init__(
            layout,
            decision_period,
            nominal_parameters,
            plant,
            reference=reference,
            dt=dt,
            task=task,
            commissioning=commissioning,
            bandwidth=bandwidth,
            integral=integral,
            feedforward=feedforward,
            friction_time=friction_time,
            backlash_time=backlash_time,
        )

    def _gains(self, g: dict) -> ServoGains:
        kp, ki = g["kp"], g["ki"]
        return ServoGains(
            kp,
            g["kd"],
            ki,
            kc=self.coupling * float(np.mean(kp)),
            kci=self.coupling * float(np.mean(ki)),
            variable=1.0 if self.variable else 0.0,
            velocity_filter=g["velocity_filter"],
            notch=g["notch"],
        )


class FeedforwardCrossCoupledPolicy(CrossCoupledPolicy):
    """``ff-ccc``: inverse-model feedforward, axis PID loops and Koren and Lo's variable-gain CCC."""

    name = "ff-ccc"

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        *,
        reference,
        dt,
        task=None,
        commissioning: str | None = None,
        bandwidth=None,
        integral: bool = True,
        coupling: float = 0.1,
        variable: bool = True,
        friction_time: float | None = None,
        backlash_time: float = 16e-3,
    ):
        super().__init__(
            layout,
            decision_period,
            nominal_parameters,
            plant,
            reference=reference,
            dt=dt,
            task=task,
            commissioning=commissioning,
            bandwidth=bandwidth,
            integral=integral,
            feedforward=True,
            coupling=coupling,
            variable=variable,
            friction_time=friction_time,
            backlash_time=backlash_time,
        )
