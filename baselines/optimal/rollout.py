"""Whole episodes of open-loop input sequences on the exact plant, through the env's own step kernel.

The floor (:mod:`vcnc_baselines.optimal.oracle`) is an input sequence, one normalised command ``u / u_max`` per
decision step, found offline on the plant instance the episode runs on.  :class:`Rollouts` holds a private
:class:`~vcnc_gym.envs.task.ContouringBatch` of that task whose machines are all set to one plant (its exact
parameters and, on the shop floor, the state of its sensor's noise generator right after the env's reset), and
:func:`rollout_serial` runs a whole episode of every machine in one numba call: at step ``k`` machine ``i``
is commanded ``inputs[i, min(k, L - 1)]`` (the last row held), stepped by the kernel every env runs
(:func:`vcnc_gym.envs.step_kernel._step_env`), and the contour error after the step is what
:func:`vcnc_gym.evaluation.run_episode` reports for it.  So a figure computed here is the figure of the
same sequence replayed through a ``gym.make`` env, to the bit (``tests/test_oracle.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from vcnc_gym.envs import controller_contract, step_kernel as sk
from vcnc_gym.envs.task import ContouringBatch

__all__ = ["Rollouts", "rollout_serial", "OUT_PEAK", "OUT_SQUARES", "OUT_STEPS", "OUT_COMPLETED", "OUT_DIVERGED"]

# columns of a rollout's summary (N, 5)
OUT_PEAK = 0  # mm, max contour error
OUT_SQUARES = 1  # mm^2, sum of squared contour errors
OUT_STEPS = 2  # decision steps run
OUT_COMPLETED = 3  # 1.0 if the tool reached the contour's end
OUT_DIVERGED = 4  # 1.0 if the episode diverged


@njit(cache=True)
def _rollout_env(plant, reference, c, cfg, o, b, i, controller, corrections, base, out, errors, tracking):
    last = corrections.shape[1] - 1
    peak = 0.0
    squares = 0.0
    k = 0
    one = np.float32(1.0)
    while b.mode[i] == sk.MODE_STEP:
        row = min(k, last)
        controller_contract.command(controller, i, b.obs[i], o, base[i])
        a0 = np.float32(base[i, 0]) + np.float32(corrections[i, row, 0])
        a1 = np.float32(base[i, 1]) + np.float32(corrections[i, row, 1])
        b.action[i, 0] = min(one, max(-one, a0))
        b.action[i, 1] = min(one, max(-one, a1))
        sk._step_env(plant, reference, c, cfg, o, b, i)
        e = b.info[i, sk.INFO_CONTOUR_ERROR]
        peak = max(peak, e)
        squares += e * e
        if k < errors.shape[1]:
            errors[i, k] = e
            tracking[i, k, 0] = b.info[i, sk.INFO_TRACKING_ERROR]
            tracking[i, k, 1] = b.info[i, sk.INFO_TRACKING_ERROR + 1]
        k += 1
        if b.flags[i, sk.FLAG_TERMINATED] or b.flags[i, sk.FLAG_TRUNCATED]:
            b.mode[i] = sk.MODE_IDLE
    out[i, OUT_PEAK] = peak
    out[i, OUT_SQUARES] = squares
    out[i, OUT_STEPS] = k
    out[i, OUT_COMPLETED] = 1.0 if b.flags[i, sk.FLAG_COMPLETED] else 0.0
    out[i, OUT_DIVERGED] = 1.0 if b.flags[i, sk.FLAG_DIVERGED] else 0.0


@njit(cache=True)
def rollout_serial(d, controller, corrections, out, errors, tracking):
    """A whole episode of every env of ``d`` in MODE_STEP under the compiled ``controller``
    (:mod:`~vcnc_gym.envs.controller_contract`) plus env ``i``'s correction ``corrections[i]`` ((N, L, 2),
    normalised, the last row held): at step k the action is ``clip(float32(u_c) + float32(c_k), -1, 1)`` in
    float32, what :class:`~vcnc_baselines.optimal.oracle.OraclePolicy` returns.  Writes ``out`` (N, 5) (the ``OUT_*``
    columns) and, for the first ``errors.shape[1]`` steps, the contour error ``errors`` (N, L') mm and the true
    tracking error ``tracking`` (N, L', 2) mm (pass arrays with 0 columns to skip the traces)."""
    plant, reference, contour, config, offsets, buffers = (
        d.plant,
        d.reference,
        d.contour,
        d.config,
        d.offsets,
        d.buffers,
    )
    base = np.zeros((buffers.mode.shape[0], 2))
    for i in range(buffers.mode.shape[0]):
        _rollout_env(
            plant, reference, contour, config, offsets, buffers, i, controller, corrections, base, out, errors, tracking
        )


class Rollouts:
    """A private batch of ``n`` machines of ``task``, each the plant ``parameters`` (2, P), for whole episodes
    of open-loop input sequences.

    Parameters
    ----------
    task : ContouringTask
    parameters : ndarray, (2, P)
        The exact plant.
    n : int
        Machines (candidates evaluated per call).
    noise_state : ndarray, optional
        The plant's random state right after the env's reset (the shop floor's ``rng`` row, uint64): copied into
        every machine, so that a closed-loop run here sees the noise the env's episode sees.  An open-loop
        sequence's true trajectory does not depend on it (the noise is the sensor's only).
    """

    def __init__(self, task, parameters: np.ndarray, n: int, noise_state=None):
        self.task = task
        self.controller = None
        self.parameters = np.asarray(parameters, dtype=np.float64)
        self.noise_state = noise_state
        self.batch = ContouringBatch(task, n)
        self.n = n
        self.evaluations = 0

    def reset(self) -> None:
        """Every machine at the contour's start, the exact plant, the env's noise state; observed, ready to step."""
        batch = self.batch
        for i in range(self.n):
            batch.reset_env(i, self.parameters)
            if self.noise_state is not None:
                batch.plant_arrays.rng[i] = self.noise_state
        batch.run()
        batch.buffers.mode[:] = sk.MODE_STEP

    def set_controller(self, policy) -> None:
        """Run ``policy`` (a baseline with a compiled form, or an
        :class:`~vcnc_baselines.optimal.open_loop.OpenLoopPolicy`) in the loop of every machine."""
        self.policy = policy
        self.controller = policy.compiled(self.n)
        if self.controller is None:
            raise ValueError(f"{type(policy).__name__} has no compiled form")

    def run(self, inputs: np.ndarray, traces: bool = False):
        """Whole episodes of the controller plus the corrections ``inputs`` (M <= n, L, 2): ``(summary (M, 5),
        errors (M, L), tracking (M, L, 2))``, the traces empty unless ``traces``."""
        inputs = np.ascontiguousarray(inputs, dtype=np.float64)
        self.policy.reset(mask=np.ones(self.n, dtype=bool))
        m = inputs.shape[0]
        if m > self.n:
            raise ValueError(f"inputs has {m} sequences, the rollouts hold {self.n} machines")
        self.reset()
        self.batch.buffers.mode[m:] = sk.MODE_IDLE
        if m < self.n:
            inputs = np.concatenate([inputs, np.repeat(inputs[:1], self.n - m, axis=0)])
        out = np.zeros((self.n, 5))
        length = inputs.shape[1] + 64 if traces else 0
        errors = np.zeros((self.n, length))
        tracking = np.zeros((self.n, length, 2))
        rollout_serial(self.batch.data, self.controller, inputs, out, errors, tracking)
        self.evaluations += m
        return out[:m], errors[:m], tracking[:m]


def figures(summary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Max and RMS contour error (mm) per rollout of ``summary`` (M, 5); inf where the episode diverged or the
    tool did not reach the contour's end (a sequence that does not finish the part is no solution)."""
    peak = summary[:, OUT_PEAK]
    rms = np.sqrt(summary[:, OUT_SQUARES] / np.maximum(summary[:, OUT_STEPS], 1))
    bad = (summary[:, OUT_DIVERGED] > 0) | (summary[:, OUT_COMPLETED] < 1) | ~np.isfinite(peak)
    return np.where(bad, np.inf, peak), np.where(bad, np.inf, rms)
