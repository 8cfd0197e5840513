"""The optimal-control floor (``oracle``): the best input found offline with the exact plant and the whole reference.

For each env and each plant instance, the oracle runs model-inversion iterative learning control to
convergence on that exact plant (its true, possibly randomised, parameters: what no causal controller may
read) over the whole reference, within the input limits:

- it scores the causal model-based designs (:data:`CANDIDATES`: ``ff-pid``, ``zpetc``, ``ff-ccc``) built
  with the nominal plant (as they run) and with the *exact* plant, and keeps the best per env (max contour
  error, then mean); the learning starts from ``ff-pid`` with the exact plant, whose table is the whole
  feedforward input the update writes;
- after trial ``j`` (true tracking error ``e_j``, which the oracle reads from the simulation, not through the
  sensor; applied input ``u_j``; both per control period),
  ``U_{j+1} = U_j + gain * Q(u_j - U_j + P^{-1} e_j)``, with ``P^{-1}`` the exact plant's linear inverse read ahead as
  the feedforward reads the reference (:func:`baselines.feedforward.tables.linear_inverse`) and ``Q`` a
  zero-phase low-pass (Butterworth, ``filtfilt``) at ``q_cutoff``.  For a linear plant ``P``, folding the
  trial's whole input (feedforward and feedback) in makes ``gain = 1`` the exact inverse in one step; the
  friction, backlash and saturation are what the further trials learn;
- a trial's table replaces the best one where it is no worse in max and in mean contour error, and
  everything runs with its design's loop (the feedback only corrects what the deterministic replay does not reproduce).
  So on every plant the oracle is at or below ``ff-pid``, ``zpetc`` and ``ff-ccc`` by construction.

What the learning reaches (``python benchmarks/oracle_convergence.py``, docs/reproduction.md): on Simba et
al.'s current-driven drive it converges (VCNC-CornersSmooth-v1: 0.005 -> 0.002 um); on Jahanpour et al.'s
drive the largest errors sit at the axis reversals, where the drive must cross its 3 um backlash gap while
saturated at 5 V, and the linear inverse cannot learn through the gap or through stick-slip from low speeds
(those stretches are left out of the learning: ``backlash_window``, :data:`SLOW_SPEED`), so the floor there is
the best causal design with the exact plant; on Purtojo et al.'s table the loop's velocity, a 1 um encoder's count
difference, keeps its noise in every trial, and the floor improves little.  A loose floor where it does not
converge, said so.  It is no floor against the papers' feedback controllers where they lead, on references the
drives cannot follow (the S-curve omega: QFT; the sharp corners: Simba et al.'s contouring FB): those are not
among its starting designs.

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
from ..coupling.ccc import FeedforwardCrossCoupledPolicy
from ..feedforward.ff_pid import FeedforwardPIDPolicy
from ..feedforward.tables import linear_inverse
from ..feedforward.zpetc import ZPETCPolicy
from ..servo import TABLE_COLUMNS, U_FF, ServoPolicy

#: mm/s: on a drive with backlash, an axis slower than this is left out of the learning (stick-slip from rest,
#: the gap's crossing), as is the backlash window around each of its reversals.
SLOW_SPEED = 2.0

#: The causal model-based designs the learning starts from, each built with the nominal plant (as the causal
#: controllers run) and with the exact plant: per env, the best of the six.
CANDIDATES = (FeedforwardPIDPolicy, ZPETCPolicy, FeedforwardCrossCoupledPolicy)

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
                 gain=0.5, q_cutoff=None, normal_only: bool = True, backlash_window: float = 0.02):
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
        self.normal_only = bool(normal_only)
        self.backlash_window = non_negative("backlash_window", backlash_window)
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
        samples = task.reference_arrays.samples
        if self._planned_for is not None and samples is self.reference and self._planned_for == params.tobytes():
            return
        if task.dt != self.dt:
            raise ValueError(f"the oracle was built for dt = {self.dt} s, the env has {task.dt} s")
        self.reference = samples
        t0 = time.perf_counter()
        n = params.shape[0]
        steps = task.end_index + 2
        batch = ContouringBatch(task, n)
        K = self.reference.shape[0]
        # the causal model-based designs, with the nominal and with the exact plant: the best per env is the floor
        # to beat; the learning starts from ff-pid with the exact plant (its table is the whole feedforward input,
        # what the learning update writes)
        best_peak, best_mean = np.full(n, np.inf), np.full(n, np.inf)
        best = np.zeros((n, K, TABLE_COLUMNS))
        best_gains = [None] * n
        for design, exact in [(d, e) for d in CANDIDATES for e in (False, True)]:
            built = [design(self.layout, self.decision_period, p if exact else self.nominal_parameters, self.plant,
                            reference=self.reference, dt=self.dt) for p in (params if exact else params[:1])]
            built = built if exact else built * n
            self._set_law(np.stack([c.table[0] for c in built]), [c._gains_row(0) for c in built])
            if design is FeedforwardPIDPolicy and exact:
                table, gains = self.table.copy(), [c._gains_row(0) for c in built]
            peak, mean = self._score(batch, params)
            better = (peak < best_peak) | ((peak == best_peak) & (mean < best_mean)) | np.array(
                [g is None for g in best_gains])
            for i in np.flatnonzero(better):
                best[i], best_gains[i] = built[i].table[0], built[i]._gains_row(0)
            best_peak[better], best_mean[better] = peak[better], mean[better]
        b, a = signal.butter(2, self.q_cutoff, fs=1.0 / self.dt)
        inverses = [task.plant.inverse(p) for p in params]
        u_max = task.plant.input_limits(params)  # (N, 2): a table beyond the limit learns nothing
        v = self.reference[:, sk.REF_VELOCITY:sk.REF_VELOCITY + 2]
        coupled = np.ones_like(v)  # where the learning acts, per axis, on a plant with backlash
        half = int(round(0.5 * self.backlash_window / self.dt))
        for j in range(2):
            for r in np.flatnonzero(np.diff(np.sign(v[:, j])) != 0):
                coupled[max(0, r - half):r + half + 1, j] = 0.0
        coupled[np.abs(v) < SLOW_SPEED] = 0.0
        tangent = self.reference[:, sk.REF_TANGENT:sk.REF_TANGENT + 2]
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
        errors = np.zeros((n, max(steps, K), 2))
        history = []
        for trial in range(self.iterations + 1):
            self._set_law(table, gains)
            record = self.record(n, steps)
            peak, mean = self._trial(batch, params, errors)
            history.append(peak * 1e3)
            better = (peak <= best_peak) & (mean <= best_mean)  # no worse in either figure
            for i in np.flatnonzero(better):
                best[i], best_gains[i] = table[i], gains[i]
            best_peak[better], best_mean[better] = peak[better], mean[better]
            if trial == self.iterations:
                break
            for i, inv in enumerate(inverses):
                e, applied = errors[i, :K], record[i, :K]
                if self.normal_only:
                    e = normal * np.sum(e * normal, axis=1, keepdims=True)
                current = table[i, :, U_FF:U_FF + 2]
                update = self.gain * signal.filtfilt(b, a, applied - current + linear_inverse(inv, e, self.dt), axis=0)
                if np.any(inv.backlash > 0):  # no learning through the gap, nor through stick-slip from low speeds
                    update *= coupled
                table[i, :, U_FF:U_FF + 2] = np.clip(current + update, -u_max[i], u_max[i])
        self._set_law(best, best_gains)
        self._record = np.zeros((0, 0, 2))
        self._compiled = None
        self.history_um = np.array(history)
        self.solve_time_s = time.perf_counter() - t0
        self._planned_for = params.tobytes()

    def _score(self, batch, params) -> tuple[np.ndarray, np.ndarray]:
        """One whole episode of every env of ``batch`` with the current law in one kernel call: max and mean
        contour error per env, mm (inf where it diverged)."""
        n = batch.n_envs
        for i in range(n):
            batch.reset_env(i, params[i])
        batch.run()
        loop = sk.ControlLoop(np.zeros((n, 2), dtype=np.float32), np.float32(0.0), np.int64(batch.task.end_index + 1),
                              np.zeros((n, 2)), np.zeros(n), np.zeros(n))
        batch.buffers.mode[:] = sk.MODE_STEP
        batch.run_controlled(self.compiled(n), loop, parallel=n > 1)
        steps = np.maximum(batch.buffers.k, 1)
        diverged = batch.buffers.flags[:, sk.FLAG_DIVERGED]
        mean = -loop.reward * batch.task.reward_scale / steps  # the reward's contour term, per period
        return np.where(diverged, np.inf, loop.peak), np.where(diverged, np.inf, mean)

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
