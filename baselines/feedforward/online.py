"""Inverse-model feedforward computed from the reference as it arrives, plus PID (``ff-pid-online``).

``ff-pid`` reads its feedforward from a table computed ahead from the whole reference (the interpolator's
output, which a CNC computes before its servo loop runs).  Under a feed override the reference is re-timed
while the part runs (:class:`~vcnc_gym.envs.feed_override_env.FeedOverrideEnv`), and no table exists ahead:
this controller computes the same nominal inverse dynamics from the reference velocity and acceleration of
the current observation, per axis ``j``::

    v_h = v_d + a_d T / 2                      (half a control period ahead, as ff-pid reads its table)
    u_ff = c_1 v_h + c_2 a_d + F_c(sgn v_h)    (the nominal linear part and Coulomb level of the direction)
    u = u_ff + K_p e + K_d (v_d - v) + K_i I,  e = clip(x_d - x, +-50 u_max / K_p),  I <- clip(I + e T)

with ``c_n``, ``F_c`` of the nominal machine's commissioning record (:mod:`vcnc_baselines.commissioning`: the
identified rigid body and Coulomb levels) and its gains and filters: the derivative acts on the measured
velocity through the record's low-pass, the feedback part passes its notch (as :mod:`vcnc_baselines.servo`'s law).  What it gives up against
``ff-pid``: the friction switch's zero-phase spread before a reversal, the backlash crossing's lead and the
jerk and snap terms (zero for the two drives it serves: their models are second order), and any dead time
(so it serves the plants without one).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit
from numba.extending import overload

from vcnc_gym.envs import controller_contract
from vcnc_gym.validation import positive
from ..base import BaselinePolicy
from ..commissioning.design import NO_NOTCH, pid_gains
from ..servo import ERROR_LIMIT

__all__ = ["OnlineFeedforwardPIDPolicy", "OnlineArrays"]


class OnlineFeedforwardPIDPolicy(BaselinePolicy):
    """Inverse-model feedforward from the observed reference, plus PID: ``ff-pid`` without a table.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant
        As :class:`~vcnc_baselines.base.BaselinePolicy`.
    bandwidth : float, optional
        Closed-loop pole of the PID design, rad/s; default the commissioning record's.
    integral : bool
        PID (True, default) or PD.
    commissioning : str, optional
        ``"nominal"`` (the nominal machine's shipped record) or ``"model"`` (the rules on the declared model);
        None: the nominal machine's where there is one, else the model's.  (No ``"machine"``: the controller
        has no table to rebuild before an episode.)
    """

    name = "ff-pid-online"
    plants = ("vcnc_feed_drive", "current_feed_drive")
    state_shape = (8,)  # the integrators (mm s), the filtered velocities (mm/s), the notches' states (input unit)

    def __init__(self, layout, decision_period, nominal_parameters, plant=None, *, bandwidth=None,
                 integral: bool = True, commissioning: str | None = None):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        declared = self.plant.inverse(self.nominal_parameters)
        if np.any(declared.delay > 0) or np.any(declared.coefficients[:, 2:] != 0):
            raise ValueError(f"ff-pid-online computes a second-order model's input from the current reference; "
                             f"plant {self.plant.name!r} has a dead time or higher-order terms")
        from ..commissioning.record import model_record, nominal_record

        if commissioning not in (None, "nominal", "model"):
            raise ValueError(f"commissioning must be 'nominal', 'model' or None for ff-pid-online, got "
                             f"{commissioning!r}")
        record = None
        if commissioning != "model":
            record = nominal_record(self.plant, self.nominal_parameters, self.decision_period)
            if record is None and commissioning == "nominal":
                raise ValueError("ff-pid-online: no shipped record of this nominal machine "
                                 "(python -m vcnc_baselines.commissioning.record ENV_ID)")
        self.record = record or model_record(self.plant, self.nominal_parameters, self.decision_period)
        self.inverse = self.record.inverse(with_mode=False)
        gains = self.record.gains()
        self.bandwidth = positive("bandwidth", self.record.designs[0].bandwidth if bandwidth is None
                                  else bandwidth, "rad/s")
        if bandwidth is None:
            self.kp, self.kd, self.ki = gains["kp"], gains["kd"], gains["ki"]
        else:
            self.kp, self.kd, self.ki = pid_gains(self.inverse.mass, self.inverse.damping, self.bandwidth)
        if not integral:
            self.ki = np.zeros(2)
        self.velocity_filter = np.ascontiguousarray(gains["velocity_filter"])
        self.notch = np.ascontiguousarray(gains["notch"])
        self.notched = np.any(self.notch != np.array(NO_NOTCH), axis=1).astype(np.float64)
        ki = self.ki
        self.integral_limit = np.where(ki > 0, self.u_max / np.where(ki > 0, ki, 1.0), 0.0)

    def _command(self, obs: np.ndarray) -> np.ndarray:
        """The law in NumPy for a batch (the readable statement; the compiled form repeats its operations)."""
        lay = self.layout
        v_d = lay.reference_velocity(obs).astype(np.float64)
        a_d = lay.reference_acceleration(obs).astype(np.float64)
        v_h = v_d + 0.5 * self.decision_period * a_d
        c = self.inverse.coefficients
        coulomb = np.where(v_h > 0, self.inverse.coulomb[:, 0], np.where(v_h < 0, self.inverse.coulomb[:, 1], 0.0))
        u_ff = c[:, 0] * v_h + c[:, 1] * a_d + coulomb
        limit = ERROR_LIMIT * self.u_max / self.kp
        e = np.minimum(np.maximum(lay.tracking_error(obs).astype(np.float64), -limit), limit)
        mem = self._state
        v = self.velocity_filter * mem[:, 2:4] + (1.0 - self.velocity_filter) * lay.velocity(obs)
        mem[:, 2:4] = v
        ed = v_d - v
        integral = mem[:, 0:2].copy()
        u = u_ff + self.kp * e + self.kd * ed + self.ki * integral
        if self.notched.any():
            x = self.kp * e + self.kd * ed + self.ki * integral
            b0, b1, b2, a1, a2 = (self.notch[:, c] for c in range(5))
            z1, z2 = mem[:, 4:8:2], mem[:, 5:8:2]
            y = b0 * x + z1
            mem[:, 4:8:2], mem[:, 5:8:2] = (np.where(self.notched > 0, b1 * x - a1 * y + z2, z1),
                                            np.where(self.notched > 0, b2 * x - a2 * y, z2))
            u = np.where(self.notched > 0, u_ff + y, u)
        mem[:, 0:2] = np.minimum(np.maximum(integral + e * self.decision_period, -self.integral_limit),
                                 self.integral_limit)
        return u

    def _compiled_arrays(self) -> "OnlineArrays":
        inv = self.inverse
        return OnlineArrays(self._state, np.ascontiguousarray(inv.coefficients[:, :2]),
                            np.ascontiguousarray(inv.coulomb), self.kp, self.kd, self.ki, self.integral_limit,
                            self.u_max, self.decision_period, self.velocity_filter, self.notch, self.notched)


#: The compiled law: memory (N, 8) (the integrators, filtered velocities, notch states), the record's linear
#: coefficients (2, 2) (per axis: of velocity, of acceleration), Coulomb levels (2, 2) (per axis: positive, negative
#: direction), the PID gains (2,) each, integral limits (2,), u_max (2,), the call period (s), the velocity filters'
#: poles (2,), the notches (2, 5) and whether each is one (2,).
OnlineArrays = namedtuple("OnlineArrays", ["memory", "coefficients", "coulomb", "kp", "kd", "ki", "integral_limit",
                                           "u_max", "period", "velocity_filter", "notch", "notched"])


@njit(cache=True, _nrt=False)
def _online_command(s, i, obs, o, out):
    """:meth:`OnlineFeedforwardPIDPolicy._command` and ``predict``'s normalisation for env ``i``, the same
    floating-point operations."""
    mem = s.memory[i]
    for j in range(2):
        v = np.float64(obs[o.reference_velocity + j])
        a = np.float64(obs[o.reference_acceleration + j])
        vh = v + 0.5 * s.period * a
        coulomb = s.coulomb[j, 0] if vh > 0 else (s.coulomb[j, 1] if vh < 0 else 0.0)
        u_ff = s.coefficients[j, 0] * vh + s.coefficients[j, 1] * a + coulomb
        limit = ERROR_LIMIT * s.u_max[j] / s.kp[j]
        e = min(max(np.float64(obs[o.tracking_error + j]), -limit), limit)
        a_v = s.velocity_filter[j]
        vf = a_v * mem[2 + j] + (1.0 - a_v) * np.float64(obs[o.velocity + j])
        mem[2 + j] = vf
        ed = v - vf
        integral = mem[j]
        if s.notched[j] > 0.0:
            x = s.kp[j] * e + s.kd[j] * ed + s.ki[j] * integral
            c = s.notch[j]
            y = c[0] * x + mem[4 + 2 * j]
            mem[4 + 2 * j] = c[1] * x - c[3] * y + mem[5 + 2 * j]
            mem[5 + 2 * j] = c[2] * x - c[4] * y
            u = u_ff + y
        else:
            u = u_ff + s.kp[j] * e + s.kd[j] * ed + s.ki[j] * integral
        mem[j] = min(max(integral + e * s.period, -s.integral_limit[j]), s.integral_limit[j])
        out[j] = np.float32(min(max(u / s.u_max[j], -1.0), 1.0))


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, OnlineArrays):
        return lambda controller, i, obs, o, out: _online_command(controller, i, obs, o, out)
