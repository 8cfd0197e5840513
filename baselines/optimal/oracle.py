"""The optimal-control floor (``oracle``): the best input found offline with the exact plant and the whole reference.

For each env and each plant instance, the oracle runs model-inversion iterative learning control to
convergence on that exact plant (its true, possibly randomised, parameters: what no causal controller may
read) over the whole reference, within the input limits:

- trial 0 is ``ff-ccc`` (feedforward, PID and Koren and Lo's coupling) built from the *exact* inverse
  dynamics;
- after trial ``j`` (measured tracking error ``e_j``, applied input ``u_j``, both per control period),
  ``U_{j+1} = u_j + Q(gain * P^{-1} e_j)``, with ``P^{-1}`` the exact plant's linear inverse read ahead as
  the feedforward reads the reference (:func:`baselines.feedforward.tables.linear_inverse`) and ``Q`` a
  zero-phase low-pass (Butterworth, ``filtfilt``) at ``q_cutoff``.  For a linear plant ``P``, folding the
  trial's whole input (feedforward and feedback) in makes ``gain = 1`` the exact inverse in one step; the
  friction, backlash and saturation are what the further trials learn;
- the table of the trial with the smallest maximum contour error is kept, and runs with the same loop
  (the feedback only corrects what the deterministic replay does not reproduce).

Where the learning converges (Simba et al.'s current-driven drive: 0.015 -> 0.007 um on VCNC-CornersSmooth-v1)
the floor is far below every controller.  Where it does not (Jahanpour et al.'s drive, whose backlash and
stick-slip the linear inverse cannot learn through; Purtojo et al.'s table, whose 1 um encoder quantises the
error it learns from), the floor is the best trial, at worst ``ff-ccc`` designed with the exact plant: a loose
floor, said so in docs/reproduction.md.

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
from ..base import check_scalar
from ..servo import BANDWIDTH, U_FF, ServoGains, ServoPolicy, pid_gains, reference_table
from ..feedforward.tables import inverse_feedforward, linear_inverse

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
                 gain=0.5, q_cutoff=None, bandwidth=None, normal_only: bool = True):
        super().__init__(layout, decision_period, nominal_parameters, plant, reference=reference, dt=dt)
        if self.stride != 1:
            raise ValueError(f"the oracle plans at the control period: it needs decision_period = dt ({self.dt} s)")
        if isinstance(iterations, bool) or int(iterations) != iterations or iterations < 0:
            raise ValueError(f"iterations must be an integer >= 0, got {iterations!r}")
        self.iterations = int(iterations)
        self.gain = check_scalar("gain", gain, positive=True)
        if self.gain > 1.0:
            raise ValueError(f"gain must be in (0, 1], got {self.gain}")
        nyquist = 0.5 / self.dt
        self.q_cutoff = check_scalar("q_cutoff", 0.05 / self.dt if q_cutoff is None else q_cutoff, positive=True)
        if self.q_cutoff >= nyquist:
            raise ValueError(f"q_cutoff must be below the Nyquist frequency {nyquist:g} Hz, got {self.q_cutoff:g}")
        self.bandwidth = check_scalar("bandwidth", BANDWIDTH[self.plant.name] if bandwidth is None else bandwidth,
                                      positive=True)
        self.normal_only = bool(normal_only)
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
        best = table.copy()
        best_peak = np.full(n, np.inf)
        history = []
        record = None
        for trial in range(self.iterations + 1):
            self._set_law(table, self._gains)
            record = self.record(n, steps)
            peak = self._trial(batch, params)
            history.append(peak * 1e3)
            better = peak < best_peak
            best[better] = table[better]
            best_peak[better] = peak[better]
            if trial == self.iterations:
                break
            tangent = self.reference[:, sk.REF_TANGENT:sk.REF_TANGENT + 2]
            normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
            for i, inv in enumerate(inverses):
                e, applied = record[i, :K, :2], record[i, :K, 2:]
                if self.normal_only:
                    e = normal * np.sum(e * normal, axis=1, keepdims=True)
                correction = signal.filtfilt(b, a, self.gain * linear_inverse(inv, e, self.dt), axis=0)
                table[i, :, U_FF:U_FF + 2] = np.clip(applied + correction, -u_max[i], u_max[i])
        self._set_law(best, self._gains)
        self._record = np.zeros((0, 0, 4))
        self._compiled = None
        self.history_um = np.array(history)
        self.solve_time_s = time.perf_counter() - t0
        self._planned_for = key

    def _trial(self, batch, params) -> np.ndarray:
        """One whole episode of every env of ``batch`` with the current table; its max contour error, mm (inf
        where it diverged)."""
        n = batch.n_envs
        for i in range(n):
            batch.reset_env(i, params[i])
        batch.run()
        controller = self.compiled(n)
        loop = sk.ControlLoop(np.zeros((n, 2), dtype=np.float32), np.float32(0.0),
                              np.int64(batch.task.end_index + 1), np.zeros((n, 2)), np.zeros(n), np.zeros(n))
        batch.buffers.mode[:] = sk.MODE_STEP
        batch.run_controlled(controller, loop, parallel=n > 1)
        diverged = batch.buffers.flags[:, sk.FLAG_DIVERGED]
        return np.where(diverged, np.inf, loop.peak)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self._planned_for is None:
            raise RuntimeError("the oracle has no plan: call plan(env) after the env's reset (the evaluation loops "
                               "of vcnc_gym and vcnc_bench do)")
        return super().predict(observation, state, episode_start, deterministic)
