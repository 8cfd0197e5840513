"""The optimal LQ preview servo (``lq-preview``): Tomizuka and Whitney (1975)'s discrete finite preview control with
Katayama et al. (1985)'s integral action, per axis, on the plant's nominal linear model.

Each axis runs the law of :mod:`~vcnc_baselines.predictive.design` at the control period ``T``: per call ``k``,

.. math::

    \\hat x(k) &= \\bar x + L (y_m(k) - C_m \\bar x), \\quad \\bar x = A \\hat x(k-1) + B u_{lin}(k-1)\\\\
    \\Delta u(k) &= -K_e e(k) - K_x (\\hat x(k) - \\hat x(k-1)) - \\sum_{j=1}^{M} K_r(j) (r(k+j) - r(k+j-1))\\\\
    u(k) &= u_{lin}(k-1) + \\Delta u(k) + u_c(k)

with ``e = x_d - x`` the observation's tracking error (mm), ``y_m`` the measured position ``x_d - e`` (mm) and
velocity (mm/s), ``r`` the reference positions of the table ahead (the CNC interpolator's output, as
:mod:`vcnc_baselines.servo` reads it: "Where the reference comes from"), and ``u_c`` the Coulomb-friction and backlash
pre-compensation of ``ff-pid`` (:func:`vcnc_baselines.inverse_model.inverse_feedforward` without the motion
term: the preview gains carry the motion).  ``u_lin(k)`` is the linear part of the command the plant received
(after the clip to the input limit): the velocity form's anti-windup.

The weights: ``q = 1`` per mm^2 of tracking error and the input-increment weight ``rho`` for which the LQ loop's
poles have the machine's commissioned bandwidth (:func:`~vcnc_baselines.commissioning.record.nominal_record`, the same number ``ff-pid``'s
PID is placed at; :func:`.design.input_weight_for_bandwidth`), unless ``input_weight`` is given.

The model
---------
Per axis a transfer function in mm per input unit and a dead time.  By default (``model="declared"``) the plant's
declared nominal :meth:`~vcnc_gym.plants.PlantModel.linear_model` and :meth:`~vcnc_gym.plants.PlantModel.dead_time`,
and ``u_c`` from its declared inverse dynamics, with the loop's poles at the commissioned PID's bandwidth.

``model="commissioned"`` (the registry's ``lq-preview@commissioned``, ``mpc@commissioned``) takes the nominal
machine's commissioning record instead, the one ``ff-pid`` is designed on
(:func:`~vcnc_baselines.commissioning.record.nominal_record`, identified by the shipped run on the nominal machine):
``1 / (m s^2 + c s)``, times the identified first mode ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)`` where one
was found (the shop floor's drive-to-table mode), with the identified command delay's whole periods
(:func:`record_models`); ``u_c`` takes the record's Coulomb levels, Stribeck curve and process force, as
``ff-pid``'s feedforward does; and the input weight is the commissioning's margin rule applied to the LQ loop with
its estimator (:func:`.design.margin_weight`: phase >= 45 deg, gain >= 6 dB, sensitivity peak <= 6 dB, crossover
at most the commissioned PID's and half the mode).  A machine without a shipped record falls back to the declared
model.  It is not the default because it is weaker where it was measured: an LQ regulator with a Kalman filter
has no guaranteed margins (Doyle 1978), and on the shop floor's drives the rule stops its loop at a crossover of
about 90 rad/s (``python experiments/classical-opponents/lq_commissioning.py``; that folder's README.md, "Predictive
control on the commissioned model").

Any other model goes in through ``models=`` and ``delays=``.  A model whose state the measured position and velocity
do not determine (a mode, a delay, a position-only sensor) is estimated by a steady-state Kalman filter
(:func:`.design.estimator_gain`).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit
from numba.extending import overload

from vcnc_gym.envs import controller_contract
from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.validation import non_negative, positive
from ..inverse_model import inverse_feedforward, path_force_feedforward
from ..commissioning.record import nominal_record
from ..servo import ServoPolicy
from .design import (
    axis_model,
    closed_loop_bandwidth,
    estimator_gain,
    input_weight_for_bandwidth,
    margin_weight,
    preview_design,
    sensor_noise,
)

__all__ = ["LQPreviewPolicy", "LQPreviewArrays", "MODEL_SOURCES", "record_models"]

#: Where the predictive controllers' model comes from (module docstring, "The model").
MODEL_SOURCES = ("commissioned", "declared")

#: Columns of the controller's table: the friction and backlash pre-compensation (2, input unit), the reference
#: positions (2, mm).
_COMP, _REF = 0, 2


class LQPreviewPolicy(ServoPolicy):
    """Discrete LQ preview control per axis with friction and backlash pre-compensation (module docstring).

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt
        As :class:`~vcnc_baselines.servo.ServoPolicy` (:meth:`from_env` fills them); the decision period must be the
        control period.
    bandwidth : float, optional
        rad/s, the LQ loop's (:func:`.design.closed_loop_bandwidth`); default: with the commissioned model, the
        input weight of the commissioning's margin rule on the LQ loop (:meth:`_margin_weights`), else the
        machine's commissioned PID bandwidth.
    input_weight : float or (2,), optional
        ``rho`` per axis (per input unit^2, against 1 per mm^2); overrides ``bandwidth``.
    preview : int, optional
        Control periods of reference preview; default where the gains fall below 1e-6 of the largest.
    model : str
        One of :data:`MODEL_SOURCES`: the plant's declared nominal model (default) or the nominal machine's
        commissioning record (where one is shipped; module docstring, "The model"); ignored with ``models``.
    models : sequence of 2 control.TransferFunction, optional
        Per axis, mm per input unit; default the ``model``'s.
    delays : (2,) float, optional
        Per axis input dead time, s; default the ``model``'s (with ``models``: 0).
    friction_time, backlash_time : float
        s, as ``ff-pid`` (:func:`~vcnc_baselines.inverse_model.inverse_feedforward`); ``friction_time`` defaults to
        the machine's commissioning.
    velocity : bool, optional
        Whether the estimator reads the measured velocity; default: unless the plant declares a position sensor
        with a resolution or noise (a ``resolution``, ``encoder_resolution`` or ``noise_std`` parameter above 0 at
        the nominal plant: Purtojo et al.'s 1 um encoder, the shop floor), whose velocity reading is a backward
        difference of its counts (1 mm/s steps at 1 um and 1 ms), which the increments ``Dx`` would take for
        accelerations.
    input_noise, position_noise, velocity_noise : float, optional
        The Kalman filter's noise levels (input unit, mm, mm/s), used only for a model whose state the measured
        position (and velocity) do not determine; defaults 1 % of the input limit, the sensor's
        ``sqrt(resolution^2 / 12 + noise_std^2)`` (1e-5 mm without one) and 1 mm/s.

    Attributes
    ----------
    axis_models : list of :class:`.design.AxisModel`
    designs : list of :class:`.design.Preview`
    """

    name = "lq-preview"

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        *,
        reference,
        dt,
        bandwidth=None,
        input_weight=None,
        preview=None,
        model: str = "declared",
        models=None,
        delays=None,
        friction_time: float | None = None,
        backlash_time: float = 16e-3,
        velocity: bool | None = None,
        input_noise: float | None = None,
        position_noise: float | None = None,
        velocity_noise: float = 1.0,
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant, reference=reference, dt=dt)
        if self.stride != 1:
            raise ValueError(
                f"{self.name} is designed at the control period: it needs decision_period = dt "
                f"({self.dt} s), got {self.decision_period} s"
            )
        if bandwidth is None:  # the nominal machine's commissioning (its slower axis), else the plant's ceiling
            record = nominal_record(self.plant, self.nominal_parameters, self.dt)
            pid_bandwidth = (
                min(d.bandwidth for d in record.designs) if record is not None else self.plant.servo_bandwidth
            )
        else:
            pid_bandwidth = positive("bandwidth", bandwidth, "rad/s")
        self.friction_time = non_negative(
            "friction_time", self.plant.friction_time if friction_time is None else friction_time, "s"
        )
        self.backlash_time = non_negative("backlash_time", backlash_time, "s")
        if model not in MODEL_SOURCES:
            raise ValueError(f"model must be one of {list(MODEL_SOURCES)}, got {model!r}")
        record = self.records[0]
        self.model = "commissioned" if model == "commissioned" and record.source != "model" else "declared"
        self.process_force = np.zeros(2)
        from_record = models is None and self.model == "commissioned"
        if from_record:
            models, identified = record_models(record)
            delays = identified if delays is None else delays
            self.inverse = record.inverse()
            self.process_force = record.process_force
        elif models is None:
            models = [self.plant.linear_model(self.nominal_parameters, axis=j) for j in range(2)]
            delays = (
                [self.plant.dead_time(self.nominal_parameters, axis=j) for j in range(2)] if delays is None else delays
            )
        elif len(models) != 2:
            raise ValueError(f"models must be one transfer function per axis (2), got {len(models)}")
        delays = np.zeros(2) if delays is None else np.asarray(delays, dtype=np.float64)
        if delays.shape != (2,) or not np.all(np.isfinite(delays)) or np.any(delays < 0):
            raise ValueError(f"delays must be two finite dead times >= 0 s, got {delays!r}")
        sensor = sensor_noise(self.plant, self.nominal_parameters)
        self.velocity = bool(np.all(sensor == 0.0)) if velocity is None else bool(velocity)
        position_noise = (
            np.where(sensor > 0, sensor, 1e-5)
            if position_noise is None
            else np.broadcast_to(np.asarray(position_noise, dtype=np.float64), (2,))
        )
        input_noise = (
            0.01 * self.u_max
            if input_noise is None
            else np.broadcast_to(np.asarray(input_noise, dtype=np.float64), (2,))
        )
        modes = [2 if from_record and a.mode_frequency > 0.0 else 0 for a in record.axes]
        self.axis_models = [axis_model(models[j], self.dt, delays[j], self.velocity, modes[j]) for j in range(2)]
        self.estimator_gains = [
            estimator_gain(m, input_noise[j], position_noise[j], velocity_noise) for j, m in enumerate(self.axis_models)
        ]
        self.bandwidth = pid_bandwidth
        if input_weight is None and bandwidth is None and from_record:
            rho = [
                w if w is not None else input_weight_for_bandwidth(m, pid_bandwidth)
                for m, w in zip(self.axis_models, self._margin_weights(record))
            ]
            self.bandwidth = min(closed_loop_bandwidth(m, r) for m, r in zip(self.axis_models, rho))
        elif input_weight is None:
            rho = [input_weight_for_bandwidth(m, pid_bandwidth) for m in self.axis_models]
        else:
            rho = np.broadcast_to(np.asarray(input_weight, dtype=np.float64), (2,))
            for r in rho:
                positive("input_weight", r)
        self.designs = [preview_design(m, r, preview) for m, r in zip(self.axis_models, rho)]
        n = max(m.n for m in self.axis_models)
        self.n_states = n
        self.state_shape = (1 + 2 * (1 + 2 * n),)
        M = max(d.preview for d in self.designs)
        self.gains = _pack(self.axis_models, self.designs, self.estimator_gains, n, M)
        self._build()

    def _margin_weights(self, record):
        """With the commissioned model, per axis the input weight of the commissioning's rule applied to the LQ
        loop itself and its estimator (:func:`.design.margin_weight`: the fastest with the margins and the
        sensitivity peak, crossing over no higher than the commissioned PID and, on a machine with a mode, below
        half of it); None where no weight meets it (then the PID's bandwidth places the poles)."""
        return [
            margin_weight(m, L, d.margins.crossover, a.mode_frequency)
            for m, L, d, a in zip(self.axis_models, self.estimator_gains, record.designs, record.axes)
        ]

    def _build(self) -> None:
        table = np.zeros((self.reference.shape[0], 4))
        table[:, _COMP : _COMP + 2] = inverse_feedforward(
            self.inverse,
            self.reference,
            self.dt,
            motion=False,
            friction_time=self.friction_time,
            backlash_time=self.backlash_time,
        )
        if np.any(self.process_force != 0.0):
            table[:, _COMP : _COMP + 2] += path_force_feedforward(
                self.process_force, self.reference, self.dt, self.inverse.delay
            )
        table[:, _REF : _REF + 2] = self.reference[:, sk.REF_POSITION : sk.REF_POSITION + 2]
        self.table = np.ascontiguousarray(table)
        self._compiled = None

    def _initial_state(self) -> np.ndarray:
        return np.zeros(self.state_shape)

    # -- the law in NumPy (the readable statement; the compiled form repeats its operations) -----------------
    def _estimate(self, obs):
        """The state estimates: ``(k, e (N, 2), dx (N, 2, n), u_prev (N, 2), comp (N, 2))``; the memory's estimate
        moves to ``x(k|k)``."""
        g, mem, n = self.gains, self._state, self.n_states
        N = obs.shape[0]
        K = self.table.shape[0]
        k = mem[:, 0].astype(np.int64)
        rows = self.table[np.minimum(k, K - 1)]
        e = self.layout.tracking_error(obs).astype(np.float64)
        v = self.layout.velocity(obs).astype(np.float64)
        y = rows[:, _REF : _REF + 2] - e
        ym = np.stack([y, v], axis=2)  # (N, 2, 2): position, velocity per axis
        dx = np.empty((N, 2, n))
        up = np.empty((N, 2))
        for j in range(2):
            base = 1 + j * (1 + 2 * n)
            up[:, j] = mem[:, base]
            xh = mem[:, base + 1 : base + 1 + n]
            xm = xh @ g.A[j].T + np.outer(up[:, j], g.B[j])
            first = k == 0
            xm[first] = ym[first, j] @ g.C_pinv[j].T
            x_new = xm + (ym[:, j] - xm @ g.Cm[j].T) @ g.L[j].T
            dx[:, j] = np.where(first[:, None], 0.0, x_new - xh)
            mem[:, base + 1 : base + 1 + n] = x_new
        return k, e, dx, up, rows[:, _COMP : _COMP + 2]

    def _preview_increments(self, k, length):
        """``r(k+j) - r(k+j-1)``, j = 1 .. length, per env and axis: (N, 2, length), mm (the table's last row held)."""
        K = self.table.shape[0]
        idx = np.minimum(k[:, None] + np.arange(length + 1)[None, :], K - 1)
        r = self.table[idx][:, :, _REF : _REF + 2]  # (N, length + 1, 2)
        return np.transpose(np.diff(r, axis=1), (0, 2, 1))

    def _finish(self, k, u_lin, comp):
        """The command (N, 2) from the linear part; stores the linear part the plant receives after the clip."""
        mem, n = self._state, self.n_states
        u = u_lin + comp
        applied = np.clip(u / self.u_max, -1.0, 1.0).astype(np.float32).astype(np.float64) * self.u_max
        for j in range(2):
            mem[:, 1 + j * (1 + 2 * n)] = applied[:, j] - comp[:, j]
        mem[:, 0] = k + 1
        return u

    def _command(self, obs):
        g = self.gains
        k, e, dx, up, comp = self._estimate(obs)
        dr = self._preview_increments(k, g.Kr.shape[1])
        du = -(g.Ke * e + np.einsum("jn,ijn->ij", g.Kx, dx) + np.einsum("jm,ijm->ij", g.Kr, dr))
        return self._finish(k, up + du, comp)

    def _compiled_arrays(self):
        g = self.gains
        return LQPreviewArrays(self._state, self.table, g.Ke, g.Kx, g.Kr, g.A, g.B, g.Cm, g.L, g.C_pinv, self.u_max)


def record_models(record):
    """Per axis the commissioning record's model as a continuous ``control.TransferFunction`` (mm per input unit):
    ``1 / (m s^2 + c s)``, times ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)`` where a mode was identified;
    and its command delay, s (the identified dead time's whole periods beyond the hold's half period).  Returns
    ``(models, delays)``."""
    import control

    models = []
    for a in record.axes:
        tf = control.tf([1.0], [a.mass, a.damping, 0.0])
        if a.mode_frequency > 0.0:
            w = 2.0 * np.pi * a.mode_frequency
            tf = tf * control.tf([2.0 * a.mode_damping * w, w * w], [1.0, 2.0 * a.mode_damping * w, w * w])
        models.append(tf)
    return models, np.array([a.command_delay for a in record.axes])


#: The gains of both axes, padded to ``n`` states and ``M`` preview steps: ``Ke`` (2,), ``Kx`` (2, n), ``Kr``
#: (2, M), ``A`` (2, n, n), ``B`` (2, n), ``Cm`` (2, 2, n) (position and velocity rows; a zero row for a model
#: without the velocity output), ``L`` (2, n, 2), ``C_pinv`` (2, n, 2) (the first call's estimate).
_Gains = namedtuple("_Gains", ["Ke", "Kx", "Kr", "A", "B", "Cm", "L", "C_pinv"])


def _pack(models, designs, gains, n, M) -> _Gains:
    out = _Gains(
        np.zeros(2),
        np.zeros((2, n)),
        np.zeros((2, M)),
        np.zeros((2, n, n)),
        np.zeros((2, n)),
        np.zeros((2, 2, n)),
        np.zeros((2, n, 2)),
        np.zeros((2, n, 2)),
    )
    for j, (m, d, L) in enumerate(zip(models, designs, gains)):
        a = m.n
        out.Ke[j] = d.K[0]
        out.Kx[j, :a] = d.K[1:]
        out.Kr[j, : d.preview] = d.Kr
        out.A[j, :a, :a] = m.A
        out.B[j, :a] = m.B
        Cm = m.measurement()
        out.Cm[j, : Cm.shape[0], :a] = Cm
        out.L[j, :a, : Cm.shape[0]] = L
        out.C_pinv[j, :a, : Cm.shape[0]] = np.linalg.pinv(Cm)
    return out


#: The compiled law: memory (N, 1 + 2 (1 + 2 n)) (k; per axis the linear input u_lin(k-1), the estimate
#: x(k-1|k-1) and a scratch row for x(k|k-1)), the table (K, 4) (pre-compensation, reference positions), the gains of ``_Gains`` and u_max (2,).
LQPreviewArrays = namedtuple(
    "LQPreviewArrays", ["memory", "table", "Ke", "Kx", "Kr", "A", "B", "Cm", "L", "C_pinv", "u_max"]
)


@njit(cache=True, _nrt=False)
def _lq_command(s, i, obs, o, out):
    """:meth:`LQPreviewPolicy._command` for env ``i``, its operations in the same order up to the sums' rounding."""
    mem = s.memory[i]
    n = s.A.shape[1]
    K = s.table.shape[0]
    k = np.int64(mem[0])
    kk = min(k, K - 1)
    for j in range(2):
        base = 1 + j * (1 + 2 * n)
        xh = base + 1  # x(k-1|k-1), then x(k|k)
        xm = base + 1 + n  # scratch: x(k|k-1)
        e = np.float64(obs[o.tracking_error + j])
        v = np.float64(obs[o.velocity + j])
        y = s.table[kk, _REF + j] - e
        up = mem[base]
        for a in range(n):
            if k == 0:
                mem[xm + a] = s.C_pinv[j, a, 0] * y + s.C_pinv[j, a, 1] * v
            else:
                acc = s.B[j, a] * up
                for b in range(n):
                    acc += s.A[j, a, b] * mem[xh + b]
                mem[xm + a] = acc
        iy = y
        iv = v
        for a in range(n):
            iy -= s.Cm[j, 0, a] * mem[xm + a]
            iv -= s.Cm[j, 1, a] * mem[xm + a]
        du = -s.Ke[j] * e
        for a in range(n):
            x_new = mem[xm + a] + s.L[j, a, 0] * iy + s.L[j, a, 1] * iv
            if k > 0:
                du -= s.Kx[j, a] * (x_new - mem[xh + a])
            mem[xh + a] = x_new
        for m in range(1, s.Kr.shape[1] + 1):
            du -= s.Kr[j, m - 1] * (s.table[min(k + m, K - 1), _REF + j] - s.table[min(k + m - 1, K - 1), _REF + j])
        comp = s.table[kk, _COMP + j]
        u = up + du + comp
        out[j] = np.float32(min(max(u / s.u_max[j], -1.0), 1.0))
        mem[base] = np.float64(out[j]) * s.u_max[j] - comp
    mem[0] = k + 1


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, LQPreviewArrays):
        return lambda controller, i, obs, o, out: _lq_command(controller, i, obs, o, out)
