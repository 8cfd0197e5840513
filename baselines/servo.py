"""The servo law of the model-based controllers: a table read from the reference ahead, PID, cross-coupling.

Every controller of the feedforward, coupling and optimal families (``ff-pid``, ``zpetc``, ``ccc``, ``ff-ccc``,
``oracle``) is this one law with its own table and gains, so one compiled form serves them all.  Per control
period ``k`` (the controller's own count of its calls since the episode's start, times the control periods of
a call) and axis ``j``:

.. math::

    e_j &= \\mathrm{clip}((x_{d,j}[k] - x_j) + \\delta_j[k], \\pm 50 u_{max,j} / K_{p,j})  && \\text{mm}\\\\
    \\dot e_j &= (v_{d,j}[k] - v_j) + \\delta'_j[k]                  && \\text{mm/s}\\\\
    u_j &= u_{ff,j}[k] + K_{p,j} e_j + K_{d,j} \\dot e_j + K_{i,j} I_j + c_j  && \\text{input unit}\\\\
    I_j &\\leftarrow \\mathrm{clip}(I_j + e_j T, \\pm I_{lim,j})

with ``x``, ``v`` the measured position and table velocity of the observation, ``T`` the call period, and the
table row ``k`` holding the feedforward input ``u_ff``, the loop's reference offsets ``delta`` (mm) and
``delta'`` (mm/s) (zero for plain feedforward; ZPETC's modified reference minus ``x_d``), and the reference's
unit tangent and signed curvature.

The cross-coupled correction ``c`` (Koren 1980; the variable gains of Koren and Lo 1991, ``variable = 1``)
acts on the contour error estimated from the measured tracking error ``E = x_d - x``:

.. math::

    \\varepsilon &= -E_x C_x + E_y C_y, \\quad
    C_x = \\sin\\theta - g \\kappa E_x / 2, \\quad C_y = \\cos\\theta + g \\kappa E_y / 2\\\\
    w &= K_c \\varepsilon + K_{ci} J, \\qquad J \\leftarrow J + \\varepsilon T\\\\
    c &= (-C_x w, \\; C_y w)

with ``theta`` the reference tangent's angle, ``kappa`` its signed curvature (1/mm, positive turning left),
``g`` 0 (Koren's fixed gains, ``epsilon`` the normal error) or 1 (Koren and Lo's: the second-order term of a
circle of radius ``1/kappa``).

Where the reference comes from
------------------------------
The table is computed once, when the controller is built, from the env's reference
(``env.unwrapped.task.reference_arrays.samples``: the interpolator's output, which a CNC computes ahead of
its servo loop) and the plant's *nominal* inverse dynamics (:meth:`vcnc_gym.plants.PlantModel.inverse`).
No causal controller here reads the plant's true (randomised) parameters; only the non-causal ``oracle``
does, and it is marked so in every table.
"""

from __future__ import annotations

import inspect
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit
from numba.extending import overload

from vcnc_gym.envs import controller_contract
from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.validation import positive, non_negative, per_axis
from .base import BaselinePolicy
from .commissioning.design import NO_NOTCH, pid_gains
from .commissioning.machines import PerMachine

__all__ = [
    "COMMISSIONING_SOURCES",
    "ServoGains",
    "ServoPolicy",
    "ServoArrays",
    "pid_gains",
    "TABLE_COLUMNS",
    "U_FF",
    "OFFSET",
    "VELOCITY_OFFSET",
    "TANGENT",
    "CURVATURE",
    "reference_table",
    "coupling_estimate",
    "NO_NOTCH",
]

#: Columns of a servo table row: feedforward input (2, input unit), position offset of the loop's reference
#: (2, mm), its velocity offset (2, mm/s), the reference's unit tangent (2) and signed curvature (1/mm).
U_FF, OFFSET, VELOCITY_OFFSET, TANGENT, CURVATURE = 0, 2, 4, 6, 8
TABLE_COLUMNS = 9

#: How a model-based controller is commissioned (:mod:`vcnc_baselines.commissioning.record`): ``"nominal"`` (the
#: identification run on the env's nominal machine, shipped with the project), ``"machine"`` (an identification run
#: on each plant instance in :meth:`ServoPolicy.plan`, before its episode), ``"model"`` (the design rules on the model
#: the parameters declare, no experiment: non-causal when they are a plant's true ones).
COMMISSIONING_SOURCES = ("nominal", "machine", "model")

#: Memory columns per env: the control period k of the next call, the axes' integrals (mm s), the coupling's (mm s),
#: the axes' filtered velocities (mm/s) and the notch filters' two states per axis (input unit).
_M_K, _M_I, _M_J, _M_V, _M_N = 0, 1, 3, 4, 6
_MEMORY = 10

#: The position error the PID acts on is bounded at ``ERROR_LIMIT u_max / K_p`` per axis (a saturated-error PD): an
#: error that alone asks fifty times the input limit asks no more, so the derivative term keeps some authority to
#: brake.  It acts only on references the drives cannot follow: on the S-curve omega (0.19 mm corners at 100 mm/s) it
#: keeps ff-pid and zpetc within the divergence bound on every vertex of the box (ff-pid 3.1 -> 2.1 mm nominal); the
#: heart's figures and the shop-floor ids' are unchanged (a bound of 2 made the shop ids' structural mode ring into a
#: limit cycle: ff-pid 63 um -> 1.75 mm on VCNC-OmegaLookaheadShop-v1).
ERROR_LIMIT = 50.0


@dataclass(frozen=True)
class ServoGains:
    """The feedback gains of the servo law.

    A policy holds them stacked, (G, 2) and (G,), G = 1 or one row per env (:meth:`ServoPolicy._set_law`).

    Attributes
    ----------
    kp, kd, ki : ndarray, (2,)
        Per axis, input unit per mm, per mm/s and per mm s.
    kc, kci : float
        Cross-coupling gains, input unit per mm and per mm s (0: no coupling).
    variable : float
        0: Koren's fixed coupling gains; 1: Koren and Lo's variable gains.
    integral_limit : ndarray, (2,)
        Bound of each axis integral, mm s (anti-windup: ``K_i I_lim = u_max``).
    coupling_limit : float
        Bound of the coupling's integral, mm s (anti-windup: ``K_ci J_lim = min(u_max)``).
    velocity_filter : ndarray, (2,)
        Per axis the pole ``a`` in [0, 1) of the first-order low-pass the measured velocity passes before the
        derivative term, ``v_f <- a v_f + (1 - a) v`` (``a = exp(-w_v T)`` for a cutoff ``w_v``); 0 (default): the
        measured velocity itself.
    notch : ndarray, (2, 5)
        Per axis a biquad ``(b0, b1, b2, a1, a2)`` the feedback part of the command passes (the PID's and the
        coupling's output, not the feedforward): a notch at a structural mode; default :data:`NO_NOTCH`.
    """

    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray
    kc: float = 0.0
    kci: float = 0.0
    variable: float = 0.0
    integral_limit: np.ndarray = None
    coupling_limit: float = None
    velocity_filter: np.ndarray = None
    notch: np.ndarray = None


_GAIN_FIELDS = (
    "kp",
    "kd",
    "ki",
    "kc",
    "kci",
    "variable",
    "integral_limit",
    "coupling_limit",
    "velocity_filter",
    "notch",
)


def reference_table(samples: np.ndarray) -> np.ndarray:
    """A servo table (K, TABLE_COLUMNS) with the reference's tangent and curvature and no feedforward."""
    table = np.zeros((samples.shape[0], TABLE_COLUMNS))
    table[:, TANGENT : TANGENT + 2] = samples[:, sk.REF_TANGENT : sk.REF_TANGENT + 2]
    table[:, CURVATURE] = samples[:, sk.REF_CURVATURE]
    return table


def coupling_estimate(E, tangent, curvature, variable):
    """The cross-coupled contour-error estimate and gains, Koren (1980) (``variable = 0``) and Koren and Lo
    (1991) (``variable = 1``), for tracking errors ``E`` (..., 2) mm at reference points with unit
    ``tangent`` (..., 2) = (cos theta, sin theta) and signed ``curvature`` (...) 1/mm.

    Returns ``(epsilon, C_x, C_y)``: ``C_x = sin(theta) - g kappa E_x / 2``, ``C_y = cos(theta) + g kappa E_y / 2``,
    ``epsilon = -E_x C_x + E_y C_y`` (mm; positive when the tool lies right of the path)."""
    half = variable * curvature * 0.5
    cx = tangent[..., 1] - half * E[..., 0]
    cy = tangent[..., 0] + half * E[..., 1]
    return -E[..., 0] * cx + E[..., 1] * cy, cx, cy


class ServoPolicy(PerMachine, BaselinePolicy):
    """The servo law as a policy (see the module docstring); subclasses build the table and the gains.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant
        As :class:`~vcnc_baselines.base.BaselinePolicy`.
    reference : ndarray, (K, REF_COLUMNS)
        The env's packed reference samples (:data:`vcnc_gym.envs.step_kernel.REF_POSITION` ...), one per
        control period; :meth:`from_env` reads ``env.unwrapped.task.reference_arrays.samples``.
    dt : float
        The env's control period, s.

    Notes
    -----
    Subclasses implement :meth:`_build`, which calls :meth:`_set_law` with the table ((K, TABLE_COLUMNS), or
    (N, K, TABLE_COLUMNS): one per env of a batch) and the gains (a :class:`ServoGains`, or one per env), from
    :attr:`reference` and :attr:`inverse`.  Calls after the reference's last sample read its last row.  An env
    whose contour changes at reset (``VCNC-RandomContour-v1``) is followed through :meth:`plan`, which the
    evaluation loops call after every reset.
    """

    state_shape = (_MEMORY,)
    #: It follows a contour's reference: only contouring envs (vcnc_bench's ``applies``).
    needs_reference = True

    @classmethod
    def designed_for(cls, plant) -> bool:
        """Any plant that declares its inverse dynamics (the model the design inverts and the commissioning fits)
        and its ``servo_bandwidth`` (the ceiling of the commissioning's design rule): a plant is one module."""
        return plant.inverse_dynamics is not None and plant.servo_bandwidth is not None

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
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        if commissioning is not None and commissioning not in COMMISSIONING_SOURCES:
            raise ValueError(
                f"commissioning must be one of {list(COMMISSIONING_SOURCES)} (or None: the nominal "
                f"machine's record where there is one, else the model's), got {commissioning!r}"
            )
        samples = np.asarray(reference, dtype=np.float64)
        if samples.ndim != 2 or samples.shape[1] != sk.REF_COLUMNS or samples.shape[0] < 2:
            raise ValueError(
                f"reference must be the env's packed reference samples, (K >= 2, {sk.REF_COLUMNS}), "
                f"got shape {samples.shape}"
            )
        self.reference = samples
        self.dt = positive("dt", dt)
        stride = self.decision_period / self.dt
        if abs(stride - round(stride)) > 1e-9 * stride:
            raise ValueError(
                f"decision_period {self.decision_period} s is not a whole number of control periods dt = {self.dt} s"
            )
        self.stride = int(round(stride))
        self.inverse = self.plant.inverse(self.nominal_parameters)
        self.task = task
        self.commissioning = commissioning
        self.records = [self._nominal_record()]
        self.table = None
        self.gains = None
        self._record = np.zeros((0, 0, 2))

    def _nominal_record(self):
        """The record the controller starts from: the nominal machine's (shipped, or identified on ``task``'s
        nominal machine), or with ``commissioning="model"`` (or None and neither) the declared model's."""
        from .commissioning.record import model_record, nominal_record

        if self.commissioning != "model":
            same = self.task is not None and np.array_equal(self.task.nominal_parameters, self.nominal_parameters)
            record = nominal_record(self.plant, self.nominal_parameters, self.dt, self.task if same else None)
            if record is not None:
                return record
            if self.commissioning is not None:
                raise ValueError(
                    f"baseline {self.name!r}: commissioning={self.commissioning!r} needs the env's task "
                    "(build it with from_env) or a shipped record of its nominal machine "
                    "(python -m vcnc_baselines.commissioning.record ENV_ID)"
                )
        return model_record(self.plant, self.nominal_parameters, self.dt)

    def commissioned(self):
        """Per design row (1, or one per env after a per-machine commissioning): ``(record, inverse, gains)``,
        the record's inverse dynamics (with its mode; the nominal backlash) and its
        :class:`ServoGains` arrays (``kp``, ``kd``, ``ki``, ``velocity_filter``, ``notch``), with
        :attr:`bandwidth` (when a subclass sets one explicitly) overriding the record's PID by pole placement on
        the record's axes."""
        rows = []
        for r in self.records:
            g = r.gains()
            inv = r.inverse()
            override = getattr(self, "_bandwidth_override", None)
            if override is not None:
                g["kp"], g["kd"], g["ki"] = pid_gains(inv.mass, inv.damping, override)
            rows.append((r, inv, g))
        return rows

    @classmethod
    def from_env(cls, env, **params):
        """As :meth:`BaselinePolicy.from_env`, plus the env's reference samples and control period."""
        if hasattr(env, "get_attr") and hasattr(env, "env_method"):  # an SB3 VecEnv
            task = env.get_attr("task")[0]
        else:
            task = getattr(getattr(env, "unwrapped", env), "task", None)
        if task is None or not hasattr(task, "reference_arrays"):
            raise ValueError(
                f"baseline {cls.name!r} follows a contour's reference: it needs a contouring env "
                f"(env.unwrapped.task.reference_arrays), got {type(env).__name__}"
            )
        if getattr(getattr(env, "unwrapped", env), "retimes_reference", False):
            raise ValueError(
                f"baseline {cls.name!r} reads the reference ahead from a table computed once; "
                f"{type(env.unwrapped).__name__} re-times its reference while it runs (a feed "
                "override): use 'ff-pid-online'"
            )
        if "task" in inspect.signature(cls.__init__).parameters:  # the task commissions the nominal machine
            params = {"task": task, **params}
        return super().from_env(env, reference=task.reference_arrays.samples, dt=task.dt, **params)

    def plan(self, env) -> None:
        """Rebuild the table if ``env``'s reference is not the one it was built from (a contour drawn at reset):
        what a CNC's interpolator does when a new part program is loaded; with ``commissioning="machine"``,
        first commission each plant ``env`` holds (once per set of plants).  Called by the evaluation loops after
        every reset; with the same reference and plants it does nothing."""
        task = getattr(getattr(env, "unwrapped", env), "task", None)
        samples = getattr(getattr(task, "reference_arrays", None), "samples", None)
        if self._commission_machines(env) and (samples is None or samples is self.reference):
            self._build()
            return
        if samples is None or samples is self.reference:
            return
        if task.dt != self.dt:
            raise ValueError(f"baseline {self.name!r} was built for dt = {self.dt} s, the env has {task.dt} s")
        self.reference = np.asarray(samples, dtype=np.float64)
        self._build()

    def _build(self) -> None:
        """Compute the table and the gains from :attr:`reference` and :attr:`inverse` (:meth:`_set_law`)."""
        raise NotImplementedError

    # -- the law -------------------------------------------------------------
    def _set_law(self, table: np.ndarray, gains) -> None:
        """Set the table ((K, C), or (N, K, C): one per env) and the gains (a :class:`ServoGains`, or a sequence
        of N: one per env)."""
        table = np.ascontiguousarray(table, dtype=np.float64)
        if table.ndim == 2:
            table = table[None]
        if table.ndim != 3 or table.shape[2] != TABLE_COLUMNS or not np.all(np.isfinite(table)):
            raise ValueError(
                f"servo table must be finite, (K, {TABLE_COLUMNS}) or (N, K, {TABLE_COLUMNS}), got shape {table.shape}"
            )
        rows = [self._checked(g) for g in ([gains] if isinstance(gains, ServoGains) else gains)]
        self.gains = ServoGains(*(np.ascontiguousarray(np.stack([getattr(r, f) for r in rows])) for f in _GAIN_FIELDS))
        self.table = table
        self._compiled = None

    def _gains_row(self, i: int) -> ServoGains:
        """The gains of env ``i`` (row 0 when all envs share them)."""
        g = self.gains
        r = i if g.kp.shape[0] > 1 else 0
        return ServoGains(*(getattr(g, f)[r] for f in _GAIN_FIELDS))

    def _checked(self, gains: ServoGains) -> ServoGains:
        limit = gains.integral_limit
        if limit is None:  # anti-windup: the integral alone never asks more than the input limit
            ki = np.asarray(gains.ki, dtype=np.float64)
            limit = np.where(ki > 0, self.u_max / np.where(ki > 0, ki, 1.0), 0.0)
        kci = non_negative("kci", gains.kci)
        coupling_limit = gains.coupling_limit
        if coupling_limit is None:
            coupling_limit = float(np.min(self.u_max)) / kci if kci > 0 else 0.0
        alpha = (
            np.zeros(2)
            if gains.velocity_filter is None
            else per_axis("velocity_filter", gains.velocity_filter, rule=non_negative)
        )
        if np.any(alpha >= 1.0):
            raise ValueError(f"velocity_filter must be a low-pass pole in [0, 1) per axis, got {alpha}")
        notch = np.array([NO_NOTCH, NO_NOTCH]) if gains.notch is None else np.array(gains.notch, dtype=np.float64)
        if notch.shape != (2, 5) or not np.all(np.isfinite(notch)):
            raise ValueError(f"notch must be finite (b0, b1, b2, a1, a2) per axis, shape (2, 5), got {gains.notch!r}")
        return ServoGains(
            per_axis("kp", gains.kp, rule=positive),
            per_axis("kd", gains.kd, rule=non_negative),
            per_axis("ki", gains.ki, rule=non_negative),
            non_negative("kc", gains.kc),
            kci,
            non_negative("variable", gains.variable),
            per_axis("integral_limit", limit, rule=non_negative),
            non_negative("coupling_limit", coupling_limit),
            alpha,
            notch,
        )

    def record(self, n_envs: int, steps: int) -> np.ndarray:
        """Record the next episodes' commands: returns the (n_envs, steps, 2) array the law writes into, row k
        the command of control period k in the input unit, clipped to the limit (what the plant received: the
        oracle's learning reads it)."""
        self._record = np.zeros((n_envs, steps, 2))
        self._compiled = None
        return self._record

    def _initial_state(self) -> np.ndarray:
        return np.zeros(_MEMORY)

    def _command(self, obs):
        """The servo law in NumPy for a batch (the readable statement; the compiled form repeats its operations)."""
        table, mem = self.table, self._state
        n = obs.shape[0]
        own, first = np.arange(n), np.zeros(n, dtype=np.int64)
        g = ServoGains(*(a[own if a.shape[0] > 1 else first] for a in (getattr(self.gains, f) for f in _GAIN_FIELDS)))
        k = mem[:, _M_K].astype(np.int64)
        rows = table[own if table.shape[0] > 1 else first, np.minimum(k, table.shape[1] - 1)]
        E = self.layout.tracking_error(obs)
        v = g.velocity_filter * mem[:, _M_V : _M_V + 2] + (1.0 - g.velocity_filter) * self.layout.velocity(obs)
        mem[:, _M_V : _M_V + 2] = v
        Ed = self.layout.reference_velocity(obs) - v
        limit = ERROR_LIMIT * self.u_max / g.kp
        e = np.minimum(np.maximum(E + rows[:, OFFSET : OFFSET + 2], -limit), limit)
        ed = Ed + rows[:, VELOCITY_OFFSET : VELOCITY_OFFSET + 2]
        eps, cx, cy = coupling_estimate(E, rows[:, TANGENT : TANGENT + 2], rows[:, CURVATURE], g.variable)
        w = g.kc * eps + g.kci * mem[:, _M_J]
        coupling = np.column_stack([-cx * w, cy * w])
        integral = mem[:, _M_I : _M_I + 2]
        notched = np.any(g.notch != np.array(NO_NOTCH), axis=2)  # (n, 2)
        if notched.any():
            x = g.kp * e + g.kd * ed + g.ki * integral + coupling
            b0, b1, b2, a1, a2 = (g.notch[:, :, c] for c in range(5))
            z1, z2 = mem[:, _M_N : _M_N + 4 : 2], mem[:, _M_N + 1 : _M_N + 4 : 2]
            y = b0 * x + z1
            z1_new, z2_new = b1 * x - a1 * y + z2, b2 * x - a2 * y
            mem[:, _M_N : _M_N + 4 : 2] = np.where(notched, z1_new, z1)
            mem[:, _M_N + 1 : _M_N + 4 : 2] = np.where(notched, z2_new, z2)
            u_notched = rows[:, U_FF : U_FF + 2] + y
        u = rows[:, U_FF : U_FF + 2] + g.kp * e + g.kd * ed + g.ki * integral + coupling
        if notched.any():
            u = np.where(notched, u_notched, u)
        mem[:, _M_I : _M_I + 2] = np.minimum(
            np.maximum(integral + e * self.decision_period, -g.integral_limit), g.integral_limit
        )
        mem[:, _M_J] = np.minimum(
            np.maximum(mem[:, _M_J] + eps * self.decision_period, -g.coupling_limit), g.coupling_limit
        )
        if self._record.shape[0]:
            rows = np.flatnonzero((k < self._record.shape[1]) & (np.arange(n) < self._record.shape[0]))
            self._record[rows, k[rows]] = np.clip(u[rows] / self.u_max, -1.0, 1.0).astype(np.float32) * self.u_max
        mem[:, _M_K] = mem[:, _M_K] + self.stride
        return u

    def _compiled_arrays(self) -> ServoArrays:
        g = self.gains
        notched = np.ascontiguousarray(np.any(g.notch != np.array(NO_NOTCH), axis=2).astype(np.float64))
        return ServoArrays(
            self._state,
            self.table,
            g.kp,
            g.kd,
            g.ki,
            g.integral_limit,
            g.kc,
            g.kci,
            g.variable,
            g.coupling_limit,
            self.decision_period,
            float(self.stride),
            self.u_max,
            self._record,
            g.velocity_filter,
            g.notch,
            notched,
        )


#: The compiled servo law: memory (N, 4) (k, I_x, I_y, J), table (1 or N, K, TABLE_COLUMNS), gains ((1 or N, 2)
#: or (1 or N,)), the call period (s), control periods per call, u_max (2,), the command record (N_r, K_r, 2)
#: (ServoPolicy.record), the velocity filters' poles (1 or N, 2), the notches (1 or N, 2, 5) and whether each is one
#: (1 or N, 2; 0: the command skips it, the same operations as without the field).
ServoArrays = namedtuple(
    "ServoArrays",
    [
        "memory",
        "table",
        "kp",
        "kd",
        "ki",
        "integral_limit",
        "kc",
        "kci",
        "variable",
        "coupling_limit",
        "period",
        "stride",
        "u_max",
        "record",
        "velocity_filter",
        "notch",
        "notched",
    ],
)


@njit(cache=True, _nrt=False)
def _servo_command(s, i, obs, o, out):
    """:meth:`ServoPolicy._command` and ``predict``'s normalisation for env ``i``, the same floating-point
    operations."""
    mem = s.memory[i]
    k = np.int64(mem[_M_K])
    t = s.table[i if s.table.shape[0] > 1 else 0, min(k, s.table.shape[1] - 1)]
    g = i if s.kp.shape[0] > 1 else 0
    Ex = np.float64(obs[o.tracking_error])
    Ey = np.float64(obs[o.tracking_error + 1])
    a0 = s.velocity_filter[g, 0]
    a1 = s.velocity_filter[g, 1]
    vx = a0 * mem[_M_V] + (1.0 - a0) * np.float64(obs[o.velocity])
    vy = a1 * mem[_M_V + 1] + (1.0 - a1) * np.float64(obs[o.velocity + 1])
    mem[_M_V] = vx
    mem[_M_V + 1] = vy
    Edx = np.float64(obs[o.reference_velocity]) - vx
    Edy = np.float64(obs[o.reference_velocity + 1]) - vy
    recording = i < s.record.shape[0] and k < s.record.shape[1]
    half = s.variable[g] * t[CURVATURE] * 0.5
    cx = t[TANGENT + 1] - half * Ex
    cy = t[TANGENT] + half * Ey
    eps = -Ex * cx + Ey * cy
    w = s.kc[g] * eps + s.kci[g] * mem[_M_J]
    for j in range(2):
        E = Ex if j == 0 else Ey
        Ed = Edx if j == 0 else Edy
        coupling = -cx * w if j == 0 else cy * w
        limit = ERROR_LIMIT * s.u_max[j] / s.kp[g, j]
        e = min(max(E + t[OFFSET + j], -limit), limit)
        ed = Ed + t[VELOCITY_OFFSET + j]
        integral = mem[_M_I + j]
        if s.notched[g, j] > 0.0:
            x = s.kp[g, j] * e + s.kd[g, j] * ed + s.ki[g, j] * integral + coupling
            c = s.notch[g, j]
            z1 = mem[_M_N + 2 * j]
            z2 = mem[_M_N + 2 * j + 1]
            y = c[0] * x + z1
            mem[_M_N + 2 * j] = c[1] * x - c[3] * y + z2
            mem[_M_N + 2 * j + 1] = c[2] * x - c[4] * y
            u = t[U_FF + j] + y
        else:
            u = t[U_FF + j] + s.kp[g, j] * e + s.kd[g, j] * ed + s.ki[g, j] * integral + coupling
        mem[_M_I + j] = min(max(integral + e * s.period, -s.integral_limit[g, j]), s.integral_limit[g, j])
        out[j] = np.float32(min(max(u / s.u_max[j], -1.0), 1.0))
        if recording:
            s.record[i, k, j] = out[j] * s.u_max[j]
    mem[_M_J] = min(max(mem[_M_J] + eps * s.period, -s.coupling_limit[g]), s.coupling_limit[g])
    mem[_M_K] = mem[_M_K] + s.stride


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, ServoArrays):
        return lambda controller, i, obs, o, out: _servo_command(controller, i, obs, o, out)
