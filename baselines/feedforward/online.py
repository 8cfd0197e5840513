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

``ff-pid-online@machine`` (``commissioning="machine"``) commissions each machine before its episode, as
``ff-pid@machine`` does (:class:`~vcnc_baselines.commissioning.machines.PerMachine`): ``c_n``, ``F_c``, the gains and
the filters are then those of the env's own machine's record, one row per env.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit
from numba.extending import overload

from vcnc_gym.envs import controller_contract
from vcnc_gym.validation import positive
from ..base import BaselinePolicy
from ..commissioning.machines import PerMachine
from ..commissioning.design import NO_NOTCH, pid_gains
from ..servo import ERROR_LIMIT

__all__ = ["OnlineFeedforwardPIDPolicy", "OnlineArrays"]


class OnlineFeedforwardPIDPolicy(PerMachine, BaselinePolicy):
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
        ``"nominal"`` (the nominal machine's shipped record), ``"model"`` (the rules on the declared model) or
        ``"machine"`` (``ff-pid-online@machine``: from the nominal record, then an identification run on each plant
        before its episode, :meth:`plan`, and the law of each env from its own machine's record, as
        ``ff-pid@machine``); None: the nominal machine's where there is one, else the model's.
    """

    name = "ff-pid-online"
    plants = ("vcnc_feed_drive", "current_feed_drive")
    state_shape = (8,)  # the integrators (mm s), the filtered velocities (mm/s), the notches' states (input unit)

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        *,
        bandwidth=None,
        integral: bool = True,
        commissioning: str | None = None,
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        declared = self.plant.inverse(self.nominal_parameters)
        if np.any(declared.delay > 0) or np.any(declared.coefficients[:, 2:] != 0):
            raise ValueError(
                f"ff-pid-online computes a second-order model's input from the current reference; "
                f"plant {self.plant.name!r} has a dead time or higher-order terms"
            )
        from ..commissioning.record import model_record, nominal_record

        if commissioning not in (None, "nominal", "model", "machine"):
            raise ValueError(
                f"commissioning must be 'nominal', 'model', 'machine' or None for ff-pid-online, got {commissioning!r}"
            )
        self.commissioning = commissioning
        self.dt = self.decision_period  # the records' control period: the law is called every period
        record = None
        if commissioning != "model":
            record = nominal_record(self.plant, self.nominal_parameters, self.decision_period)
            if record is None and commissioning is not None:
                raise ValueError(
                    f"ff-pid-online: commissioning={commissioning!r} starts from the shipped record of "
                    "the nominal machine, and there is none (python -m vcnc_baselines.commissioning.record "
                    "ENV_ID)"
                )
        self.records = [record or model_record(self.plant, self.nominal_parameters, self.decision_period)]
        self.bandwidth = positive(
            "bandwidth", self.records[0].designs[0].bandwidth if bandwidth is None else bandwidth, "rad/s"
        )
        self._bandwidth_override = None if bandwidth is None else self.bandwidth
        self.integral = bool(integral)
        self._build()

    def _law(self, record) -> dict:
        """One design row from ``record``: its inverse's linear coefficients and Coulomb levels, the PID (pole
        placement at :attr:`bandwidth` when given), the integral's bound, the velocity filters and notches."""
        inverse = record.inverse(with_mode=False)
        gains = record.gains()
        kp, kd, ki = gains["kp"], gains["kd"], gains["ki"]
        if self._bandwidth_override is not None:
            kp, kd, ki = pid_gains(inverse.mass, inverse.damping, self._bandwidth_override)
        if not self.integral:
            ki = np.zeros(2)
        notch = np.asarray(gains["notch"], dtype=np.float64)
        return {
            "coefficients": inverse.coefficients[:, :2],
            "coulomb": inverse.coulomb,
            "kp": kp,
            "kd": kd,
            "ki": ki,
            "integral_limit": np.where(ki > 0, self.u_max / np.where(ki > 0, ki, 1.0), 0.0),
            "velocity_filter": gains["velocity_filter"],
            "notch": notch,
            "notched": np.any(notch != np.array(NO_NOTCH), axis=1).astype(np.float64),
        }

    def _build(self) -> None:
        """The law's arrays from :attr:`records`, stacked (G, ...) with G = 1 or one row per env."""
        rows = [self._law(r) for r in self.records]
        for name in _LAW_FIELDS:
            setattr(self, name, np.ascontiguousarray(np.stack([np.asarray(r[name], dtype=np.float64) for r in rows])))
        self.record = self.records[0]
        self.inverse = self.record.inverse(with_mode=False)
        self._compiled = None

    def plan(self, env) -> None:
        """With ``commissioning="machine"``: commission each plant ``env`` holds (an identification run per machine
        never met before, on the env's task or :meth:`identify_on`'s) and rebuild the law, one row per env.  Called
        by the evaluation loops and the residual wrapper after every reset; with the same plants it does nothing."""
        if self._commission_machines(env):
            self._build()

    def _rows(self, n: int) -> np.ndarray:
        """Each env's design row for a batch of ``n``: 0 when the envs share one, else its own."""
        g = self.kp.shape[0]
        if g > 1 and g != n:
            raise ValueError(
                f"ff-pid-online commissioned {g} machines and is given {n} envs: plan(env) on the env it runs first"
            )
        return np.arange(n) if g > 1 else np.zeros(n, dtype=np.int64)

    def _command(self, obs: np.ndarray) -> np.ndarray:
        """The law in NumPy for a batch (the readable statement; the compiled form repeats its operations)."""
        lay = self.layout
        r = self._rows(obs.shape[0])
        v_d = lay.reference_velocity(obs).astype(np.float64)
        a_d = lay.reference_acceleration(obs).astype(np.float64)
        v_h = v_d + 0.5 * self.decision_period * a_d
        c, f = self.coefficients[r], self.coulomb[r]
        kp, kd, ki = self.kp[r], self.kd[r], self.ki[r]
        coulomb = np.where(v_h > 0, f[:, :, 0], np.where(v_h < 0, f[:, :, 1], 0.0))
        u_ff = c[:, :, 0] * v_h + c[:, :, 1] * a_d + coulomb
        limit = ERROR_LIMIT * self.u_max / kp
        e = np.minimum(np.maximum(lay.tracking_error(obs).astype(np.float64), -limit), limit)
        mem = self._state
        a_v = self.velocity_filter[r]
        v = a_v * mem[:, 2:4] + (1.0 - a_v) * lay.velocity(obs)
        mem[:, 2:4] = v
        ed = v_d - v
        integral = mem[:, 0:2].copy()
        u = u_ff + kp * e + kd * ed + ki * integral
        notched = self.notched[r] > 0
        if notched.any():
            x = kp * e + kd * ed + ki * integral
            b0, b1, b2, a1, a2 = (self.notch[r][:, :, c] for c in range(5))
            z1, z2 = mem[:, 4:8:2], mem[:, 5:8:2]
            y = b0 * x + z1
            mem[:, 4:8:2], mem[:, 5:8:2] = (
                np.where(notched, b1 * x - a1 * y + z2, z1),
                np.where(notched, b2 * x - a2 * y, z2),
            )
            u = np.where(notched, u_ff + y, u)
        bound = self.integral_limit[r]
        mem[:, 0:2] = np.minimum(np.maximum(integral + e * self.decision_period, -bound), bound)
        return u

    def _compiled_arrays(self) -> "OnlineArrays":
        self._rows(self._state.shape[0])
        return OnlineArrays(
            self._state,
            *(getattr(self, name) for name in _LAW_FIELDS[:6]),
            self.u_max,
            self.decision_period,
            *(getattr(self, name) for name in _LAW_FIELDS[6:]),
        )


#: The law's per-row arrays, in :class:`OnlineArrays`' order (u_max and the period between the sixth and seventh).
_LAW_FIELDS = ("coefficients", "coulomb", "kp", "kd", "ki", "integral_limit", "velocity_filter", "notch", "notched")


#: The compiled law: memory (N, 8) (the integrators, filtered velocities, notch states); per design row (G = 1, or
#: one per env after a per-machine commissioning) the record's linear coefficients (G, 2, 2) (per axis: of velocity,
#: of acceleration), Coulomb levels (G, 2, 2) (per axis: positive, negative direction), the PID gains (G, 2) each,
#: integral limits (G, 2); u_max (2,), the call period (s); the velocity filters' poles (G, 2), the notches (G, 2, 5)
#: and whether each is one (G, 2).
OnlineArrays = namedtuple(
    "OnlineArrays",
    [
        "memory",
        "coefficients",
        "coulomb",
        "kp",
        "kd",
        "ki",
        "integral_limit",
        "u_max",
        "period",
        "velocity_filter",
        "notch",
        "notched",
    ],
)


@njit(cache=True, _nrt=False)
def _online_command(s, i, obs, o, out):
    """:meth:`OnlineFeedforwardPIDPolicy._command` and ``predict``'s normalisation for env ``i``, the same
    floating-point operations."""
    mem = s.memory[i]
    g = i if s.kp.shape[0] > 1 else 0
    for j in range(2):
        v = np.float64(obs[o.reference_velocity + j])
        a = np.float64(obs[o.reference_acceleration + j])
        vh = v + 0.5 * s.period * a
        coulomb = s.coulomb[g, j, 0] if vh > 0 else (s.coulomb[g, j, 1] if vh < 0 else 0.0)
        u_ff = s.coefficients[g, j, 0] * vh + s.coefficients[g, j, 1] * a + coulomb
        kp, kd, ki = s.kp[g, j], s.kd[g, j], s.ki[g, j]
        limit = ERROR_LIMIT * s.u_max[j] / kp
        e = min(max(np.float64(obs[o.tracking_error + j]), -limit), limit)
        a_v = s.velocity_filter[g, j]
        vf = a_v * mem[2 + j] + (1.0 - a_v) * np.float64(obs[o.velocity + j])
        mem[2 + j] = vf
        ed = v - vf
        integral = mem[j]
        if s.notched[g, j] > 0.0:
            x = kp * e + kd * ed + ki * integral
            c = s.notch[g, j]
            y = c[0] * x + mem[4 + 2 * j]
            mem[4 + 2 * j] = c[1] * x - c[3] * y + mem[5 + 2 * j]
            mem[5 + 2 * j] = c[2] * x - c[4] * y
            u = u_ff + y
        else:
            u = u_ff + kp * e + kd * ed + ki * integral
        mem[j] = min(max(integral + e * s.period, -s.integral_limit[g, j]), s.integral_limit[g, j])
        out[j] = np.float32(min(max(u / s.u_max[j], -1.0), 1.0))


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, OnlineArrays):
        return lambda controller, i, obs, o, out: _online_command(controller, i, obs, o, out)
