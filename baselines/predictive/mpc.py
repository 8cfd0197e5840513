"""Model predictive control with the input limit (``mpc``): the LQ preview servo's model, cost and preview, solved
over a finite horizon as a box-constrained QP at every control period.

Per axis and call ``k``, with the augmented error system ``X(l+1) = Phi X(l) + Gamma Du(l) + G Dr(l+1)`` of
:mod:`~vcnc_baselines.predictive.design`, the input is chosen over ``H = sum(blocks)`` control periods, held constant
over each block (move blocking: ``b = len(blocks)`` decision variables ``z``, the linear input's level per block):

.. math::

    \\min_z \\; \\sum_{l=0}^{H-1} \\left(q e(k+l)^2 + \\rho \\Delta u(k+l)^2\\right)
        + X(k+H)' P X(k+H) + 2 X(k+H)' P_{xw} W(k+H)
    \\quad \\text{s.t.} \\quad -u_{max} - u_c(k+l) \\le z_{b(l)} \\le u_{max} - u_c(k+l)

with ``P``, ``P_xw`` the LQ preview's cost to go (:func:`.design.preview_design`) and ``W(k+H)`` the ``M``
reference increments after the horizon: the reference is previewed ``H + M`` control periods ahead, and without
blocking and with the bound inactive the first move is the LQ preview's with that preview (tested).  ``u_c`` is
``ff-pid``'s friction and backlash pre-compensation (:mod:`.lq_preview`), so the bound is the plant's input limit
on the whole command.  The QP is condensed once, at construction (``z`` only; the cost's Hessian is constant and
its linear term linear in ``X(k)``, ``u(k-1)`` and the previewed increments).

Explicit handling: the unconstrained minimiser ``z* = -H^-1 f`` is a matrix product; where it lies within the
bounds it is the QP's solution (exactly: the problem is convex), and only otherwise is the QP solved.

The solver is DAQP (Arnstrom, Bemporad and Axehill 2022: a dual active-set method for small dense QPs, the bounds
as simple bounds), chosen by measurement (``python benchmarks/mpc_solvers.py``: the ~2700 QPs the first 3000
control periods of ``VCNC-Omega-v1`` ask for, 10 variables and 10 bounds each, through each solver's Python
interface; two runs on the shared 2-core host): per solve OSQP took 3.7-4.0 times DAQP's time, PIQP 2.1-2.7
times, scipy's BVLS 10-20 times; DAQP's and OSQP's solutions agree with BVLS's to 1e-12 V, PIQP's to 1e-4 V (its
tolerance).  DAQP warm-started from the previous QP's active set took 1.16-1.25 times its cold time (reading the
multipliers back costs more than the iterations it saves at this size), so the policy solves cold.  ``tinympc``
(0.0.8) pins ``scipy < 1.12``, which does not install beside the suite's NumPy 2.

Cost: the unconstrained minimiser costs 0.2-0.3 DAQP solves; a ``predict`` call of one env 5-6 times
``lq-preview``'s compiled one (the NumPy estimator and preview around the solver), so an episode of the heart
(32 212 periods) took 75-95 s on the loaded host against ~10 s for ``lq-preview``.
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.validation import integer
from .design import augmented
from .lq_preview import LQPreviewPolicy

__all__ = ["MPCPolicy", "condensed_qp", "DEFAULT_BLOCKS"]

#: Block lengths of the default horizon, control periods: 40 periods (4 ms at 0.1 ms, ~4 / bandwidth at the
#: commissioned 1000 rad/s), the first four moves free, then longer holds.
DEFAULT_BLOCKS = (1, 1, 1, 1, 2, 2, 4, 4, 8, 16)


class CondensedQP:
    """One axis' condensed QP: ``min 1/2 z' H z + f' z`` with ``f = F_x X + F_u u_prev + F_r R`` (``R`` the
    ``horizon + M`` previewed reference increments, mm), and the unconstrained minimiser's maps
    ``z* = G_x X + G_u u_prev + G_r R``.

    Attributes
    ----------
    H : ndarray, (b, b)
    Fx, Fu, Fr : ndarray, (b, 1 + n), (b,), (b, horizon + M)
    Gx, Gu, Gr : ndarray
        ``-H^-1`` times them.
    blocks : ndarray of int, (b,)
        Block lengths, control periods.
    """

    def __init__(self, model, design, blocks):
        Phi, Gamma, G = augmented(model)
        n1 = Phi.shape[0]
        blocks = np.asarray(blocks, dtype=np.int64)
        N, b, M = int(blocks.sum()), blocks.size, design.preview
        # X(l) for l = 1 .. N as Sx X0 + Su Du + Sg rho, Du (N,), rho = Dr(k+1 .. k+N)
        Sx = np.zeros((N, n1, n1))
        Su = np.zeros((N, n1, N))
        Sg = np.zeros((N, n1, N))
        Xx, Xu, Xg = np.eye(n1), np.zeros((n1, N)), np.zeros((n1, N))
        for step in range(N):
            Xx, Xu, Xg = Phi @ Xx, Phi @ Xu, Phi @ Xg
            Xu[:, step] += Gamma
            Xg[:, step] += G
            Sx[step], Su[step], Sg[step] = Xx, Xu, Xg
        Q = np.zeros((n1, n1))
        Q[0, 0] = design.q
        weights = [Q] * (N - 1) + [design.P]
        T = np.repeat(np.eye(b), blocks, axis=0)  # (N, b): the input of each period from the blocks' levels
        E = T - np.vstack([np.zeros((1, b)), T[:-1]])  # Du = E z - e0 u_prev
        e0 = np.zeros(N)
        e0[0] = 1.0
        H_du = design.rho * np.eye(N)
        g_x, g_r = np.zeros((N, n1)), np.zeros((N, N + M))
        for step in range(N):
            W = weights[step]
            H_du += Su[step].T @ W @ Su[step]
            g_x += Su[step].T @ W @ Sx[step]
            g_r[:, :N] += Su[step].T @ W @ Sg[step]
        g_r[:, N:] = Su[N - 1].T @ design.Pxw  # the terminal cross term with the increments after the horizon
        self.H = 2.0 * E.T @ H_du @ E
        self.H = 0.5 * (self.H + self.H.T)
        self.Fx = 2.0 * E.T @ g_x
        self.Fu = -2.0 * E.T @ H_du @ e0
        self.Fr = 2.0 * E.T @ g_r
        Hinv = np.linalg.inv(self.H)
        self.Gx, self.Gu, self.Gr = -Hinv @ self.Fx, -Hinv @ self.Fu, -Hinv @ self.Fr
        self.blocks = blocks
        self.starts = np.concatenate([[0], np.cumsum(blocks)[:-1]])
        self.horizon = N
        self.preview = N + M

    def linear_term(self, X, u_prev, R):
        return self.Fx @ X + self.Fu * u_prev + self.Fr @ R

    def unconstrained(self, X, u_prev, R):
        return self.Gx @ X + self.Gu * u_prev + self.Gr @ R


def condensed_qp(model, design, blocks=DEFAULT_BLOCKS) -> CondensedQP:
    """The condensed QP of one axis (:class:`CondensedQP`) for a :class:`.design.AxisModel`, its
    :class:`.design.Preview` and the block lengths."""
    blocks = [integer("blocks", v, minimum=1) for v in blocks]
    if not blocks:
        raise ValueError("blocks must hold at least one block length")
    return CondensedQP(model, design, blocks)


def solve_box_qp(H, f, lower, upper, active=None):
    """``min 1/2 z' H z + f' z`` s.t. ``lower <= z <= upper`` with DAQP; ``active`` (int array, DAQP's ``sense``:
    1 where a bound was active at the last solve) warm-starts it and is updated.  Returns ``z``."""
    import daqp

    scale = 1.0 / np.mean(np.diag(H))  # the same minimiser, a Hessian of order 1
    sense = np.zeros(lower.size, dtype=np.int32) if active is None else active
    z, _, flag, info = daqp.solve(H * scale, f * scale, np.zeros((0, lower.size)), upper, lower, sense)
    if flag < 1:
        raise RuntimeError(f"DAQP failed on the MPC's QP (exit flag {flag})")
    if active is not None:
        lam = np.asarray(info["lam"])
        active[:] = (np.abs(lam) > 0).astype(np.int32)
    return np.asarray(z)


class MPCPolicy(LQPreviewPolicy):
    """Model predictive control with the input limit on the LQ preview servo's model, cost and preview (module
    docstring).

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant, reference, dt, bandwidth, input_weight, preview, model, models, delays, friction_time, backlash_time, velocity, input_noise, position_noise, velocity_noise
        As :class:`~.lq_preview.LQPreviewPolicy` (``preview``: the terminal cost's preview ``M`` beyond the horizon).
    blocks : sequence of int
        The horizon's block lengths, control periods (default :data:`DEFAULT_BLOCKS`, 40 periods in 10 blocks).

    Attributes
    ----------
    qps : list of :class:`CondensedQP`
        Per axis.
    solves, calls : int
        QPs solved (the unconstrained minimiser outside the bounds) and calls, since construction.
    """

    name = "mpc"
    #: A QP per env and period in Python: a heart episode takes a minute or more, so vcnc-bench's default table
    #: leaves it out (``--policy mpc``, ``--all``).
    in_default_table = False

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        *,
        reference,
        dt,
        blocks=DEFAULT_BLOCKS,
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
        super().__init__(
            layout,
            decision_period,
            nominal_parameters,
            plant,
            reference=reference,
            dt=dt,
            bandwidth=bandwidth,
            input_weight=input_weight,
            preview=preview,
            model=model,
            models=models,
            delays=delays,
            friction_time=friction_time,
            backlash_time=backlash_time,
            velocity=velocity,
            input_noise=input_noise,
            position_noise=position_noise,
            velocity_noise=velocity_noise,
        )
        self.qps = [condensed_qp(m, d, blocks) for m, d in zip(self.axis_models, self.designs)]
        self.solves = 0
        self.calls = 0

    def _bounds(self, k, j):
        """Per env and block, the linear input's bounds over the block's periods: (lower, upper), (N, b) each."""
        qp = self.qps[j]
        K = self.table.shape[0]
        comp = self.table[np.minimum(k[:, None] + np.arange(qp.horizon)[None, :], K - 1), j]
        lo = np.maximum.reduceat(-self.u_max[j] - comp, qp.starts, axis=1)
        hi = np.minimum.reduceat(self.u_max[j] - comp, qp.starts, axis=1)
        return lo, hi

    def _command(self, obs):
        k, e, dx, up, comp = self._estimate(obs)
        u_lin = np.empty((obs.shape[0], 2))
        R_all = self._preview_increments(k, max(qp.preview for qp in self.qps))
        for j, qp in enumerate(self.qps):
            n1 = qp.Gx.shape[1]
            X = np.column_stack([e[:, j], dx[:, j, : n1 - 1]])
            R = R_all[:, j, : qp.preview]
            z = X @ qp.Gx.T + up[:, j, None] * qp.Gu + R @ qp.Gr.T  # the unconstrained minimisers, (N, b)
            lo, hi = self._bounds(k, j)
            for i in np.flatnonzero(np.any((z < lo) | (z > hi), axis=1)):  # the QP where they leave the bounds
                z[i] = solve_box_qp(qp.H, qp.linear_term(X[i], up[i, j], R[i]), lo[i], hi[i])
                self.solves += 1
            u_lin[:, j] = z[:, 0]
        self.calls += obs.shape[0]
        return self._finish(k, u_lin, comp)

    def _compiled_arrays(self):
        return None  # a QP per step: the NumPy law (predict's float64 path) on every dtype
