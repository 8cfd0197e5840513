"""Zero-phase-error tracking control (Tomizuka 1987) of the discretised closed loop (``zpetc``).

Each axis runs the PID loop ``u_k = K_p (r_k - x_k) + K_d (\\Delta r_k / T - v_k) + K_i I_k`` (gains by the same pole
placement as ``ff-pid``) plus the nominal Coulomb-friction and backlash pre-compensation, and its loop reference ``r``
is ZPETC's: the discretised closed loop ``G_c(z^-1) = z^-d B_a B_u / A`` (the nominal axis under
zero-order hold, its dead time a whole number of samples) inverted except for its unacceptable zeros,
whose phase is cancelled by their mirror image (:func:`vcnc_baselines.feedforward.tables.zpetc_filter`).  The
inverse of the loop is not causal (the delay ``d`` and the preview ``s`` of the mirrored zeros) and not
stable (the zero-order hold's sampling zero near -1): ZPETC reads the reference ``d + s`` samples ahead,
from the table computed when the controller is built.
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.validation import non_negative, positive
from ..servo import OFFSET, U_FF, VELOCITY_OFFSET, ServoGains, ServoPolicy, reference_table
from vcnc_gym.envs import step_kernel as sk
from ..inverse_model import inverse_feedforward, path_force_feedforward
from .tables import closed_loop, zpetc_filter, zpetc_reference

__all__ = ["ZPETCPolicy"]


class ZPETCPolicy(ServoPolicy):
    """ZPETC on the PID loop of each axis, with friction and backlash pre-compensation.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt
        As :class:`~vcnc_baselines.servo.ServoPolicy` (:meth:`from_env` fills them).
    bandwidth : float, optional
        Closed-loop pole of the PID design, rad/s; default the commissioning record's.
    friction_time : float, optional
        s, the Coulomb level's change at a reversal; default the plant's declaration.
    commissioning : str, optional
        As :class:`~vcnc_baselines.feedforward.ff_pid.FeedforwardPIDPolicy`'s.
    backlash_time : float
        s; both as :func:`~vcnc_baselines.inverse_model.inverse_feedforward`.

    Attributes
    ----------
    filters : list of (b, a, preview)
        Per axis, ZPETC's filter in powers of z^-1 and its preview in control periods.
    loops : list of control.TransferFunction
        Per axis, the discretised closed loop it inverts.
    """

    name = "zpetc"

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
        )
        if self.stride != 1:
            raise ValueError(
                f"zpetc is designed at the control period: it needs decision_period = dt "
                f"({self.dt} s), got {self.decision_period} s"
            )
        self._bandwidth_override = None if bandwidth is None else positive("bandwidth", bandwidth, "rad/s")
        self.friction_time = non_negative(
            "friction_time", self.plant.friction_time if friction_time is None else friction_time, "s"
        )
        self.backlash_time = non_negative("backlash_time", backlash_time, "s")
        self._build()

    @property
    def bandwidth(self) -> float:
        """The PID's closed-loop pole, rad/s (the first design row's, x axis)."""
        return self._bandwidth_override or self.records[0].designs[0].bandwidth

    def _build(self) -> None:
        x_d = self.reference[:, sk.REF_POSITION : sk.REF_POSITION + 2]
        tables, gains = [], []
        for record, inverse, g in self.commissioned():
            rigid = record.inverse(with_mode=False)
            self.loops = [closed_loop(rigid, j, self.dt, g["kp"][j], g["kd"][j], g["ki"][j]) for j in range(2)]
            self.filters = [zpetc_filter(loop) for loop in self.loops]
            table = reference_table(self.reference)
            r = zpetc_reference(self.filters, x_d)
            r_rate = np.diff(r, axis=0, prepend=r[:1]) / self.dt  # (r_k - r_{k-1}) / T, as the closed loop models it
            table[:, OFFSET : OFFSET + 2] = r - x_d
            table[:, VELOCITY_OFFSET : VELOCITY_OFFSET + 2] = (
                r_rate - self.reference[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
            )
            table[:, U_FF : U_FF + 2] = inverse_feedforward(  # the loop's reference carries the motion
                rigid,
                self.reference,
                self.dt,
                motion=False,
                friction_time=self.friction_time,
                backlash_time=self.backlash_time,
            )
            table[:, U_FF : U_FF + 2] += path_force_feedforward(
                record.process_force, self.reference, self.dt, rigid.delay
            )
            tables.append(table)
            gains.append(ServoGains(g["kp"], g["kd"], g["ki"], velocity_filter=g["velocity_filter"], notch=g["notch"]))
        self._set_law(tables[0] if len(tables) == 1 else np.stack(tables), gains[0] if len(gains) == 1 else gains)
