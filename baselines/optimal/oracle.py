"""The optimal-control floor (``oracle``): the best input found offline with the exact plant and the whole reference.

For each env and each plant instance, the oracle runs model-inversion iterative learning control to
convergence on that exact plant (its true, possibly randomised, parameters: what no causal controller may
read) over the whole reference, within the input limits:

- trial 0 is ``ff-ccc`` (feedforward, PID and Koren and Lo's coupling) built from the *exact* inverse
  dynamics;
- after trial ``j`` (true tracking error ``e_j``, which the oracle reads from the simulation, not through the
  sensor; applied input ``u_j``; both per control period),
  ``U_{j+1} = U_j + gain * Q(u_j - U_j + P^{-1} e_j)``, with ``P^{-1}`` the exact plant's linear inverse read ahead as
  the feedforward reads the reference (:func:`baselines.feedforward.tables.linear_inverse`) and ``Q`` a
  zero-phase low-pass (Butterworth, ``filtfilt``) at ``q_cutoff``.  For a linear plant ``P``, folding the
  trial's whole input (feedforward and feedback) in makes ``gain = 1`` the exact inverse in one step; the
  friction, backlash and saturation are what the further trials learn;
- the table of the trial with the smallest maximum contour error (then mean) is kept, and runs with the same loop
  (the feedback only corrects what the deterministic replay does not reproduce).

What the learning reaches (``python benchmarks/oracle_convergence.py``, docs/reproduction.md): on Simba et
al.'s current-driven drive it converges (VCNC-CornersSmooth-v1: 0.015 -> 0.003 um); on Jahanpour et al.'s
drive the largest errors sit at the axis reversals, where the drive must cross its 3 um backlash gap while
saturated at 5 V, and the linear inverse cannot learn through the gap or through stick-slip from low speeds
(those stretches are left out of the learning: ``backlash_window``, :data:`SLOW_SPEED`), so the floor there is
ff-ccc with the exact plant; on Purtojo et al.'s table the loop's velocity, a 1 um encoder's count
difference, keeps its noise in every trial, and the floor improves little.  A loose floor where it does not
converge, said so.

It is **non-causal** (:attr:`OraclePolicy.causal` is False): it reads the plant it runs on through
:meth:`OraclePolicy.plan`, which the evaluation loops (:func:`vcnc_gym.evaluation.run_episode`,
:func:`vcnc_bench.robust.run_plants`) call after every reset.  It is never counted as a controller: the
bench marks it in every table; it shows how much headroom every controller leaves.
"""

from __future__ import annotations

import time

import numpy as np
from scipy import signal

from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.envs.task import ContouringBatch
from vcnc_gym.validation import positive, non_negative
from ..servo import BANDWIDTH, U_FF, ServoGains, ServoPolicy, pid_gains, reference_table
from ..feedforward.tables import inverse_feedforward, linear_inverse

#: mm/s: on a drive with backlash, an axis slower than this is left out of the learning (stick-slip from rest,
#: the gap's crossing), as is the backlash window around each of its reversals.
SLOW_SPEED = 2.0

#: The coupling of ff-ccc's loop, which the oracle's trials run in (baselines.coupling.ccc's default).
COUPLING = 0.1

__all__ = ["OraclePolicy"]


class OraclePolicy(ServoPolicy):
    """Model-inversion ILC on the exact plant, to convergence: a non-causal floor, not a controller.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt
        As :class:`~baselines.servo.ServoPolicy` (:meth:`from_env` fills them).
    iterations : int
        Learning trials after the first, >= 0.  Default 10.
    gain : float
        Learning gain in (0, 1].  Default 0.5.
    q_cutoff : float, optional
        Cut-off of the zero-phase Q filter, Hz; default ``0.05 / dt`` (500 Hz at 0.1 ms, 50 Hz at 1 ms).
    bandwidth : float, optional
        The PID's pole, rad/s; default the plant's :data:`~baselines.servo.BANDWIDTH`.
    normal_only : bool
        Learn from the error's component along the contour normal only (default): the contour error, not
        the lag along the path, which costs input the saturated reversals do not have.
    backlash_window : float
        s; on a plant with backlash, no learning within half of it on either side of an axis reversal.

    Attributes
    ----------
    solve_time_s : float
        Wall time of the last :meth:`plan`, s.
    history_um : ndarray, (iterations + 1, N)
        Max contour error of every trial and env of the last :meth:`plan`, um.
    """

    name = "oracle"
    #: Not a controller: it reads the exact plant (:meth:`plan`).
    causal = False

    def __init__(self, layout, decision_period, nominal_parameters, plant=None, *, reference, dt, iterations=10,
                 gain=0.5, q_cutoff=None, bandwidth=None, normal_only: bool = True, backlash_window: float = 0.02):
        super().__init__(layout, decision_period, nominal_parameters, plant, reference=reference, dt=dt)
        if self.stride != 1:
            raise ValueError(f"the oracle plans at the control period: it needs decision_period = dt ({self.dt} s)")
        if isinstance(iterations, bool) or int(iterations) != iterations or iterations < 0:
            raise ValueError(f"iterations must be an integer >= 0, got {iterations!r}")
        self.iterations = int(iterations)
        self.gain = positive("gain", gain)
        if self.gain > 1.0:
            raise ValueError(f"gain must be in (0, 1], got {self.gain}")
        nyquist = 0.5 / self.dt
        self.q_cutoff = positive("q_cutoff", 0.05 / self.dt if q_cutoff is None else q_cutoff)
        if self.q_cutoff >= nyquist:
            raise ValueError(f"q_cutoff must be below the Nyquist frequency {nyquist:g} Hz, got {self.q_cutoff:g}")
        self.bandwidth = positive("bandwidth", BANDWIDTH[self.plant.name] if bandwidth is None else bandwidth, "rad/s")
        self.normal_only = bool(normal_only)
        self.backlash_window = non_negative("backlash_window", backlash_window)
        self.slow_speed = SLOW_SPEED
        kp, kd, ki = pid_gains(self.inverse.mass, self.inverse.damping, self.bandwidth)
        self._gains = ServoGains(kp, kd, ki, kc=COUPLING * float(np.mean(kp)), kci=COUPLING * float(np.mean(ki)),
                                 variable=1.0)  # ff-ccc's loop
        self.solve_time_s = float("nan")
        self.history_um = np.zeros((0, 0))
        self._planned_for = None

    def plan(self, env) -> None:
        """Learn the input for the plants ``env`` holds now (after its reset): ``env.unwrapped.parameters``,
        (2, P) for a single env or (N, 2, P) for a vector env, on ``env.unwrapped.task``."""
        u = getattr(env, "unwrapped", env)
        task = getattr(u, "task", None)
        if task is None or not hasattr(u, "parameters"):
            raise ValueError(f"the oracle plans on a vcnc_gym contouring env, got {type(env).__name__}")
        params = np.asarray(u.parameters, dtype=np.float64)
        params = params[None] if params.ndim == 2 else params
        key = (id(task), params.tobytes())
        if self._planned_for == key:
            return
        t0 = time.perf_counter()
        n = params.shape[0]
        steps = task.end_index + 2
        batch = ContouringBatch(task, n)
        b, a = signal.butter(2, self.q_cutoff, fs=1.0 / self.dt)
        inverses = [task.plant.inverse(p) for p in params]
        u_max = task.plant.input_limits(params)  # (N, 2): a table beyond the limit learns nothing
        K = self.reference.shape[0]
        table = np.repeat(reference_table(self.reference)[None], n, axis=0)
        for i, inv in enumerate(inverses):  # trial 0: ff-pid from the exact plant
            table[i, :, U_FF:U_FF + 2] = inverse_feedforward(inv, self.reference, self.dt)
        v = self.reference[:, sk.REF_VELOCITY:sk.REF_VELOCITY + 2]
        self._coupled = np.ones_like(v)
        half = int(round(0.5 * self.backlash_window / self.dt))
        for j in range(2):
            for r in np.flatnonzero(np.diff(np.sign(v[:, j])) != 0):
                self._coupled[max(0, r - half):r + half + 1, j] = 0.0
        self._coupled[np.abs(v) < self.slow_speed] = 0.0
        best = table.copy()
        errors = np.zeros((n, max(steps, K), 2))
        best_peak = np.full(n, np.inf)
        best_mean = np.full(n, np.inf)
        history = []
        record = None
        for trial in range(self.iterations + 1):
            self._set_law(table, self._gains)
            record = self.record(n, steps)
            peak, mean = self._trial(batch, params, errors)
            history.append(peak * 1e3)
            better = (peak < best_peak * (1.0 - 1e-3)) | ((peak <= best_peak * (1.0 + 1e-3)) & (mean < best_mean))
            best[better] = table[better]
            best_peak[better] = peak[better]
            best_mean[better] = mean[better]
            if trial == self.iterations:
                break
            tangent = self.reference[:, sk.REF_TANGENT:sk.REF_TANGENT + 2]
            normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
            for i, inv in enumerate(inverses):
                e, applied = errors[i, :K], record[i, :K]
                if self.normal_only:
                    e = normal * np.sum(e * normal, axis=1, keepdims=True)
                current = table[i, :, U_FF:U_FF + 2]
                update = self.gain * signal.filtfilt(b, a, applied - current + linear_inverse(inv, e, self.dt), axis=0)
                if np.any(inv.backlash > 0):  # no learning through the gap, nor through stick-slip from low speeds
                    update *= self._coupled
                table[i, :, U_FF:U_FF + 2] = np.clip(current + update, -u_max[i], u_max[i])
        self._set_law(best, self._gains)
        self._record = np.zeros((0, 0, 2))
        self._compiled = None
        self.history_um = np.array(history)
        self.solve_time_s = time.perf_counter() - t0
        self._planned_for = key

    def _trial(self, batch, params, errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One whole episode of every env of ``batch`` with the current table, a kernel call per control period:
        the true tracking error (mm, x_d - x, not the sensor's) after period k goes into ``errors[:, k + 1]``
        (N, K, 2).  Returns the max and the mean contour error per env, mm (inf where it diverged)."""
        n = batch.n_envs
        for i in range(n):
            batch.reset_env(i, params[i])
        batch.run()
        controller = self.compiled(n)
        loop = sk.ControlLoop(np.zeros((n, 2), dtype=np.float32), np.float32(0.0), np.int64(1), np.zeros((n, 2)),
                              np.zeros(n), np.zeros(n))
        b = batch.buffers
        b.mode[:] = sk.MODE_STEP
        errors[:] = 0.0
        peak, total, steps = np.zeros(n), np.zeros(n), np.zeros(n)
        parallel = n > 1
        for k in range(errors.shape[1] - 1):
            active = b.mode == sk.MODE_STEP
            if not active.any():
                break
            batch.run_controlled(controller, loop, parallel)
            errors[active, k + 1] = b.info[active, sk.INFO_TRACKING_ERROR:sk.INFO_TRACKING_ERROR + 2]
            e = b.info[active, sk.INFO_CONTOUR_ERROR]
            peak[active] = np.maximum(peak[active], e)
            total[active] += e
            steps[active] += 1
            ended = active & (b.flags[:, sk.FLAG_TERMINATED] | b.flags[:, sk.FLAG_TRUNCATED])
            b.mode[ended] = sk.MODE_IDLE
        diverged = b.flags[:, sk.FLAG_DIVERGED]
        return np.where(diverged, np.inf, peak), np.where(diverged, np.inf, total / np.maximum(steps, 1))

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self._planned_for is None:
            raise RuntimeError("the oracle has no plan: call plan(env) after the env's reset (the evaluation loops "
                               "of vcnc_gym and vcnc_bench do)")
        return super().predict(observation, state, episode_start, deterministic)
