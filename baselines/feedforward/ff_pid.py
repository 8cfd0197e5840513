"""Inverse-model feedforward plus PID: what every CNC feed drive runs (``ff-pid``).

The command of each axis is the plant's nominal inverse dynamics along the reference, read ahead by half a
control period and the plant's dead time, with the Coulomb friction of the direction of motion and the
backlash crossing pre-compensated (:func:`baselines.feedforward.tables.inverse_feedforward`), plus a PID on
the measured tracking error (derivative on ``v_d - v``), its gains by pole placement on the nominal axis
(:func:`baselines.servo.pid_gains`: a triple closed-loop pole at ``-bandwidth``).  The law is
:mod:`baselines.servo`'s with ``delta = delta' = 0`` and no coupling.
"""

from __future__ import annotations

from vcnc_gym.validation import non_negative, positive
from ..servo import ServoGains, ServoPolicy, commissioning, U_FF, pid_gains, reference_table
from .tables import inverse_feedforward

__all__ = ["FeedforwardPIDPolicy"]


class FeedforwardPIDPolicy(ServoPolicy):
    """Inverse-model feedforward with friction and backlash pre-compensation, plus PID.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt
        As :class:`~baselines.servo.ServoPolicy` (:meth:`from_env` fills them).
    bandwidth : float, optional
        Closed-loop pole of the PID design, rad/s; default the machine's :func:`~baselines.servo.commissioning`.
    integral : bool
        PID (True, default) or PD.
    feedforward : bool
        Add the inverse-model input (True, default); False leaves the PID alone (the coupling controller
        ``ccc`` builds on that).
    friction_time : float, optional
        s, the Coulomb level's change at a reversal; default the machine's :func:`~baselines.servo.commissioning`.
    backlash_time : float
        s; both as :func:`~baselines.feedforward.tables.inverse_feedforward`.
    """

    name = "ff-pid"

    def __init__(self, layout, decision_period, nominal_parameters, plant=None, *, reference, dt, bandwidth=None,
                 integral: bool = True, feedforward: bool = True, friction_time: float | None = None,
                 backlash_time: float = 16e-3):
        super().__init__(layout, decision_period, nominal_parameters, plant, reference=reference, dt=dt)
        design = commissioning(self.plant)
        self.bandwidth = positive(
            "bandwidth", design.bandwidth if bandwidth is None else bandwidth, "rad/s")
        self.feedforward = bool(feedforward)
        self.integral = bool(integral)
        self.friction_time = non_negative(
            "friction_time", design.friction_time if friction_time is None else friction_time, "s")
        self.backlash_time = non_negative("backlash_time", backlash_time, "s")
        self._build()

    def _build(self) -> None:
        table = reference_table(self.reference)
        if self.feedforward:
            table[:, U_FF:U_FF + 2] = inverse_feedforward(self.inverse, self.reference, self.dt,
                                                          friction_time=self.friction_time,
                                                          backlash_time=self.backlash_time)
        kp, kd, ki = pid_gains(self.inverse.mass, self.inverse.damping, self.bandwidth, integral=self.integral)
        self._set_law(table, self._gains(kp, kd, ki))

    def _gains(self, kp, kd, ki) -> ServoGains:
        """The law's gains from the axis PID's (a coupling controller adds its own)."""
        return ServoGains(kp, kd, ki)
