"""Model predictive contouring control (``mpcc``): a contouring MPC that chooses its own progress along the path.

Lam, Manzie and Good (2010) ("Model predictive contouring control", CDC) and, for a biaxial machine, Lam, Manzie
and Good (2013): the reference is not a function of time but the path ``p(theta)`` parametrised by its arc length
``theta`` (mm), and the progress ``theta`` is a state of the controller, a double integrator

.. math::

    \\theta(t + \\tau) = \\theta + \\tau v_\\theta + \\tfrac{1}{2} \\tau^2 a_\\theta, \\qquad
    v_\\theta(t + \\tau) = v_\\theta + \\tau a_\\theta

driven by a virtual input ``a_theta`` (mm/s^2) that the optimiser chooses beside the axes' inputs.  The cost
weighs the contour error ``e_c`` and the lag error ``e_l`` of the tool position ``q`` against the path point
``p(theta)``, in Lam et al.'s approximation: linearised about the predicted progress ``theta_bar`` of each stage
(the previous solution's, shifted by the control period), with ``t`` the path's unit tangent and
``n = (-t_y, t_x)`` its left normal there,

.. math::

    e_c = n(\\bar\\theta) \\cdot (q - p(\\bar\\theta)), \\qquad
    e_l = t(\\bar\\theta) \\cdot (q - p(\\bar\\theta)) - (\\theta - \\bar\\theta)

(:func:`linearised_errors`; near the path, ``|e_c|`` is the distance to the path and ``e_l`` the arc between the
tool's closest point and ``theta``, tested against :class:`vcnc_gym.contour.ContourProjector` in
``tests/test_mpcc.py``).  Per call, over the stages ``l`` of the horizon (block lengths ``L_l`` control periods,
the inputs held over a block), with ``u_j`` the linear part of axis ``j``'s input:

.. math::

    \\min \\sum_l L_l \\left(q_c e_c(l)^2 + q_l e_l(l)^2 - q_v v_\\theta(l) - q_\\theta \\theta(l)\\right)
        + \\sum_l \\left(r_u \\|u(l) - u(l-1)\\|^2 + r_a (a_\\theta(l) - a_\\theta(l-1))^2\\right)

The term ``q_theta theta(l)`` is ours, beside Lam et al.'s speed reward ``q_v v_theta``: summed over the stages
it weighs each advance by the time left in the horizon, so it ranks an early advance above a late one.  With
the speed reward alone, a plan that waits before a corner (or the path's end) and advances in the horizon's
tail earns as much as one that advances now, and the receding horizon then waits for ever: measured on the
omega, it stopped 2 mm before the second 0.19 mm corner (and, at the end, 1 mm before the last bend) and
never finished.

subject to ``|u_j(l) + c_j(l)| <= u_max`` (the plant's input limit on the whole command, ``c`` the Coulomb
pre-compensation), ``0 <= v_theta(l) <= min(v_max, m v_feed(theta_bar))`` (``v_feed`` the programmed feed as it
accelerates from rest, then its peak, with a look-ahead's slow-downs (:class:`PathTable`), ``m`` the dial's top
``max_override``: an override at 100 % runs the programmed feed slower, never faster, and a dial to 150 % as much
faster; and
``sqrt(2 a_max (length - theta_bar))``, the speed from which the progress still stops at the path's end),
``theta(l) <= length`` (the path's) and ``|a_theta| <= a_max``.  The axes' model is each axis' nominal linear model discretised at the control period
(:func:`.design.axis_model`, the one ``mpc`` and ``lq-preview`` use), over a block ``x <- A^L x + sum_i A^i B u``;
its state is estimated from the measured position and velocity (:func:`.design.estimator_gain`).  The problem is
condensed (the inputs only) and solved as one dense QP per control period by DAQP (the solver ``mpc`` measured
fastest at its size, :mod:`.mpc`), re-linearised about the previous solution's shifted progress; the first call
re-linearises :data:`FIRST_ITERATIONS` times about its own solution.  Where the progress' bounds cannot all be met
(a speed cap or the path's end closer than full braking reaches with the inputs held over whole blocks) they are
relaxed to what full braking reaches, and if DAQP still finds the QP infeasible they become soft constraints.

The horizon (:data:`DEFAULT_BLOCKS`): 40 ms, seven short blocks for the servo loop (1 to 8 control periods), then
1 ms and 2 ms blocks (30 blocks, 90 variables).  Braking from 100 mm/s to the ~22 mm/s at which the omega's
0.19 mm corners ask the drives' ~2.6e3 mm/s^2 sideways (``sqrt(a r)``) takes ~30 ms at that acceleration: a
shorter horizon sees the corner too late to brake for it; the 1 ms blocks are 0.1 mm of path at 100 mm/s, so a
corner's 0.6 mm of turn falls on several stages once it is near.

Integral action
---------------
The model has neither the friction the Coulomb table misses nor a process force, and the progress' reward ends
at the path's end: without integral action the tool stopped 29 um short of the heart's end at 60 mm/s (the
planned speed, and with it the Coulomb pre-compensation, is zero there) and never finished, and on the shop floor
it trailed by 45-52 um.  An input disturbance ``d`` per axis is estimated as offset-free MPC does (Pannocchia and
Rawlings 2003): the plant is taken as ``x(k+1) = A x(k) + B (u(k) - c(k) + d)``, and each call the input that
explains the last step's surprise, ``b' (x(k|k) - x(k|k-1)) / b' b`` (``b`` the input's column into the plant's
states), is added to ``d`` with gain ``T / disturbance_time`` (a first-order disturbance observer of time constant
:data:`DISTURBANCE_TIME`, 5 ms); the command is ``u = u_lin + c - d``, its bound ``|u| <= u_max`` in the QP.
With it the heart at 60 mm/s finishes (5.24 s, 5.84 um max).  It is on by default only where the plant's position
sensor is exact (:func:`.design.sensor_noise`): a count difference makes the surprise noise (a 1 um count over a
1 ms period is 1000 mm/s^2, 13 V on Purtojo et al.'s table), and on the circle at 1 ms the observer drove the
contour error to 292 um; on the shop floor's heart it did not make the MPCC finish either (59.5 um at 100 mm/s).

How it acts on the env
----------------------
It sets the progress itself, so it runs on a feed-override id (``VCNC-OmegaOverride-v1``,
:class:`~vcnc_gym.envs.feed_override_env.FeedOverrideEnv`, with no look-ahead under its dial; its dial's top, up to
150 %, is the controller's ``max_override``), the third action its override dial: the dial is set
so that the interpolator's clock (its arc ``s_c``, found from the observed reference point on the programmed path)
follows ``theta``: override ``= (v_theta + (theta + 0.2 mm - s_c) / tau_c) / v_ref(s_c)`` (``v_ref`` the
programmed reference's speed at the clock), ``tau_c`` = 20 ms (the override reaches its dial at a bounded rate; a
clock ahead of the tool costs nothing, one behind it costs time).  A plain
contouring id ends its episode ``completion_timeout`` (0.1 s) after its reference's end and measures the cycle
time from its own clock, so a controller that runs slower than the programmed feed cannot finish there:
:meth:`MPCCPolicy.from_env` refuses it.

What it reads: the programmed path and feed (the reference samples ``env.unwrapped.task.reference_arrays.samples``
as the interpolator computed them before the override, the geometry the env gives every model-based controller),
the nominal plant's linear model and its commissioning record's Coulomb levels; the observation's reference point,
tracking error and velocity.  No true plant, nothing beyond the programmed path.

Cost per step (``python benchmarks/mpcc_cost.py --steps 1500``, ``predict`` alone on the omega's first 1500
periods, shared 2-core host, two runs): 3.2 and 4.0 ms per control period, 7.0 and 6.7 times ``mpc``'s 0.46 and
0.60 ms (which solves its two 10-variable QPs only where the unconstrained minimiser leaves the bounds); an omega
episode takes 25-70 s.  The
front on the omega is in ``experiments/feed-override/README.md``, "Contouring MPC"."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.envs.feed_override_env import MAX_OVERRIDE
from vcnc_gym.validation import integer, non_negative, positive, real
from ..base import BaselinePolicy
from .design import axis_model, estimator_gain, sensor_noise

__all__ = [
    "MPCCPolicy",
    "WEIGHTS_FEED",
    "PathTable",
    "path_table",
    "linearised_errors",
    "BlockPrediction",
    "block_prediction",
    "ContouringQP",
    "contouring_qp",
    "solve_qp",
    "DEFAULT_BLOCKS",
    "FIRST_ITERATIONS",
    "DISTURBANCE_TIME",
]

#: Block lengths of the horizon, control periods: seven short blocks (22 periods), then eight of 1 ms and fifteen
#: of 2 ms, to 40.2 ms (at 0.1 ms; module docstring).
DEFAULT_BLOCKS = (1, 1, 2, 2, 4, 4, 8) + (10,) * 8 + (20,) * 15
#: Re-linearisations of the first call about its own solution (later calls start from the shifted previous one).
FIRST_ITERATIONS = 4
#: The virtual input's scale in the QP, mm/s^2 per unit (the axes' inputs are in V, order 1).
_A_SCALE = 1000.0
#: The programmed feed (mm/s) at which the progress rewards' defaults were tuned (the omega's); on another feed ``F``
#: they are scaled by ``WEIGHTS_FEED / F``, so that a speed in proportion to the feed earns the same against the
#: errors (measured on Purtojo et al.'s circle at 1 mm/s: with the omega's weights unscaled the controller crawled
#: at 0.32 mm/s under a 0.6 mm/s cap and ran out of time).
WEIGHTS_FEED = 100.0
#: The clock's catch-up time constant, s, and how far ahead of the progress it is kept, mm: the override reaches
#: its dial at a bounded rate, so the clock follows ``theta`` through a slow loop, and a clock ahead costs nothing
#: (the episode ends when the tool arrives) where one behind costs the time it needs to catch up.
_CLOCK_TIME = 20e-3
_CLOCK_LEAD = 0.2
#: Axis speed (mm/s) over which the Coulomb pre-compensation turns from one level to the other (tanh).
_COULOMB_SPEED = 0.05
#: The input disturbance observer's time constant, s (module docstring, "Integral action").
DISTURBANCE_TIME = 5e-3


@dataclass(frozen=True)
class PathTable:
    """The programmed path by arc length: ``arc`` (K,) mm, strictly increasing from 0; ``point`` (K, 2) mm;
    ``tangent`` (K, 2) unit; ``feed`` (K,) mm/s, the programmed speed 1 ms after the reference passes each arc, which
    an override at 100 % cannot run faster than (1 ms ahead, so that the start, at rest, is not a zero feed; a dial
    to ``max_override`` runs up to that many times it): an S-curve's
    start, then its peak; a look-ahead's or a G-code program's slow-downs at corners too; its final stop held at
    the speed it stops from, where the progress' own bounds do the braking (the constraint ``theta <= length``);
    ``speed`` (K,) mm/s, the reference's own speed there."""

    arc: np.ndarray
    point: np.ndarray
    tangent: np.ndarray
    feed: np.ndarray
    speed: np.ndarray

    @property
    def length(self) -> float:
        return float(self.arc[-1])

    def at(self, theta):
        """``(p, t)`` at arc ``theta`` (mm, any shape): the point by linear interpolation, the tangent
        interpolated and normalised."""
        theta = np.clip(np.asarray(theta, dtype=np.float64), 0.0, self.length)
        p = np.stack([np.interp(theta, self.arc, self.point[:, c]) for c in range(2)], axis=-1)
        t = np.stack([np.interp(theta, self.arc, self.tangent[:, c]) for c in range(2)], axis=-1)
        return p, t / np.linalg.norm(t, axis=-1, keepdims=True)

    def feed_at(self, theta):
        return np.interp(theta, self.arc, self.feed)


def path_table(samples, dt: float) -> PathTable:
    """The :class:`PathTable` of an env's packed reference samples (K, ``REF_COLUMNS``) at control period ``dt``
    s: the rows where the arc advances (the S-curve's samples at rest repeat a point)."""
    s = np.asarray(samples, dtype=np.float64)
    if s.ndim != 2 or s.shape[1] != sk.REF_COLUMNS or s.shape[0] < 2:
        raise ValueError(
            f"samples must be an env's packed reference samples, (K >= 2, {sk.REF_COLUMNS}), got shape {s.shape}"
        )
    arc = s[:, sk.REF_ARC]
    speed = np.hypot(s[:, sk.REF_VELOCITY], s[:, sk.REF_VELOCITY + 1])
    lead = int(round(1e-3 / positive("dt", dt, "s")))
    ahead = speed[np.minimum(np.arange(speed.size) + lead, speed.size - 1)]
    # the programmed speed 1 ms ahead, its final stop held at the speed it stops from (theta <= length and the
    # braking bound stop the progress); where it runs at its peak so far, that peak (an S-curve's: the same bits)
    rises = np.flatnonzero(np.diff(ahead) > 0)
    stop = rises[-1] + 1 if rises.size else 0  # where the speed last rose: the final stop begins after it
    held = ahead.copy()
    held[stop:] = ahead[stop]
    peak = np.maximum.accumulate(ahead)
    feed = np.where(held >= peak * (1.0 - 1e-9), peak, held)
    keep = np.concatenate([[True], np.diff(arc) > 0])
    if keep.sum() < 2:
        raise ValueError("samples must move along a path (their arc length never increases)")
    return PathTable(
        arc=arc[keep] - arc[0],
        point=s[keep, sk.REF_POSITION : sk.REF_POSITION + 2],
        tangent=s[keep, sk.REF_TANGENT : sk.REF_TANGENT + 2],
        feed=feed[keep],
        speed=speed[keep],
    )


def linearised_errors(q, theta, theta_bar, path: PathTable):
    """Lam et al. (2010)'s contour and lag errors (mm) of tool positions ``q`` (..., 2) at progress ``theta``,
    linearised about ``theta_bar`` (module docstring): ``(e_c, e_l)``, ``e_c`` positive left of the path."""
    p, t = path.at(theta_bar)
    d = np.asarray(q, dtype=np.float64) - p
    e_c = -t[..., 1] * d[..., 0] + t[..., 0] * d[..., 1]
    e_l = t[..., 0] * d[..., 0] + t[..., 1] * d[..., 1] - (np.asarray(theta) - np.asarray(theta_bar))
    return e_c, e_l


@dataclass(frozen=True)
class BlockPrediction:
    """One axis' positions at the ends of the blocks: ``y(l) = Px[l] x0 + Su[l] u`` (mm), ``u`` the blocks' inputs;
    and the progress' ``theta(l) = theta0 + times[l] v0 + St[l] a``, ``v(l) = v0 + Sv[l] a`` (``a`` mm/s^2)."""

    Px: np.ndarray
    Su: np.ndarray
    St: np.ndarray
    Sv: np.ndarray
    times: np.ndarray
    blocks: np.ndarray


def block_prediction(model, blocks) -> BlockPrediction:
    """The :class:`BlockPrediction` of an :class:`.design.AxisModel` over blocks of ``blocks`` control periods."""
    blocks = np.asarray([integer("blocks", v, minimum=1) for v in blocks], dtype=np.int64)
    if blocks.size == 0:
        raise ValueError("blocks must hold at least one block length")
    b, n = blocks.size, model.n
    A_blocks, B_blocks = np.empty((b, n, n)), np.empty((b, n))
    for s, L in enumerate(blocks):
        A_L, B_L = np.eye(n), np.zeros(n)
        for _ in range(L):
            B_L = model.A @ B_L + model.B
            A_L = model.A @ A_L
        A_blocks[s], B_blocks[s] = A_L, B_L
    Px, Su = np.empty((b, n)), np.zeros((b, b))
    X, U = np.eye(n), np.zeros((n, b))  # x(l) = X x0 + U u
    for s in range(b):
        X = A_blocks[s] @ X
        U = A_blocks[s] @ U
        U[:, s] += B_blocks[s]
        Px[s], Su[s] = model.C @ X, model.C @ U
    tau = blocks * model.dt
    times = np.cumsum(tau)
    St, Sv = np.zeros((b, b)), np.zeros((b, b))
    for s in range(b):
        for m in range(s + 1):  # a(m) acts over block m, then the speed it left carries to the end of block s
            Sv[s, m] = tau[m]
            St[s, m] = 0.5 * tau[m] ** 2 + tau[m] * (times[s] - times[m])
    return BlockPrediction(Px, Su, St, Sv, times, blocks)


@dataclass(frozen=True)
class ContouringQP:
    """One call's QP: ``min 1/2 z' H z + f' z`` s.t. ``lower <= z <= upper`` (the first ``z.size`` bounds) and
    ``lower[z.size:] <= G z <= upper[z.size:]``; ``z = (u_x (b), u_y (b), a (b) / 1000 mm/s^2)``."""

    H: np.ndarray
    f: np.ndarray
    G: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


def contouring_qp(
    preds, path: PathTable, x0, theta0, v0, theta_bar, u_prev, a_prev, comp, u_max, v_cap, a_max, weights
) -> ContouringQP:
    """The condensed QP of one call (module docstring).

    Parameters
    ----------
    preds : (BlockPrediction, BlockPrediction)
        Per axis (the same blocks).
    path : PathTable
    x0 : (2, n)
        The axes' state estimates.
    theta0, v0 : float
        Progress (mm) and its speed (mm/s) now.
    theta_bar : (b,)
        The progress about which each block end's errors are linearised, mm.
    u_prev : (2,)
        The linear inputs applied last, V; ``a_prev`` the last virtual input, mm/s^2.
    comp : (2, b)
        The Coulomb pre-compensation over each block, input unit.
    u_max : (2,)
        Input limits.
    v_cap : (b,)
        Upper bound of ``v_theta`` at each block end, mm/s.
    a_max : float
        Bound of ``|a_theta|``, mm/s^2.
    weights : (q_c, q_l, q_v, q_t, r_u, r_a)
        Per mm^2, mm^2, mm/s, mm (per control period of a block), input unit^2, (1000 mm/s^2)^2.
    """
    q_c, q_l, q_v, q_t, r_u, r_a = weights
    pred = preds[0]
    b = pred.times.size
    w = pred.blocks.astype(np.float64)  # the stage weights: control periods per block
    p, t = path.at(theta_bar)
    nx, ny = -t[:, 1], t[:, 0]
    Sx, Sy = preds[0].Su, preds[1].Su
    y0 = np.stack([preds[j].Px @ x0[j] for j in range(2)])  # (2, b): positions with the inputs at zero
    St = pred.St * _A_SCALE
    base = theta0 + pred.times * v0
    # residuals r = J z + r0, rows: sqrt(q_c w) e_c, sqrt(q_l w) e_l
    J = np.zeros((2 * b, 3 * b))
    sc, sl = np.sqrt(q_c * w)[:, None], np.sqrt(q_l * w)[:, None]
    J[:b, :b], J[:b, b : 2 * b] = sc * nx[:, None] * Sx, sc * ny[:, None] * Sy
    J[b:, :b], J[b:, b : 2 * b], J[b:, 2 * b :] = sl * t[:, :1] * Sx, sl * t[:, 1:] * Sy, -sl * St
    d0 = y0.T - p
    r0 = np.concatenate(
        [
            sc[:, 0] * (nx * d0[:, 0] + ny * d0[:, 1]),
            sl[:, 0] * (t[:, 0] * d0[:, 0] + t[:, 1] * d0[:, 1] - (base - theta_bar)),
        ]
    )
    D = np.eye(b) - np.eye(b, k=-1)  # differences between blocks; the first against the previous input
    R = np.zeros((3 * b, 3 * b))
    f = 2.0 * J.T @ r0
    for j, (r, prev) in enumerate(((r_u, u_prev[0]), (r_u, u_prev[1]), (r_a, a_prev / _A_SCALE))):
        s = slice(j * b, (j + 1) * b)
        R[s, s] = r * D.T @ D
        f[j * b] -= 2.0 * r * prev
    f[2 * b :] -= (q_v * (w @ pred.Sv) + q_t * (w @ pred.St)) * _A_SCALE
    H = 2.0 * (J.T @ J + R)
    # what full braking reaches: the speed and end bounds never ask less (a QP that cannot meet them is infeasible)
    t_stop = np.minimum(pred.times, v0 / a_max)
    v_cap = np.maximum(v_cap, v0 - a_max * pred.times + 1e-9)
    theta_max = np.maximum(
        path.length,
        theta0 + v0 * t_stop - 0.5 * a_max * t_stop**2 + v0 * pred.blocks.max() * (pred.times[0] / pred.blocks[0]),
    )  # braking ends in a block
    lower = np.concatenate(
        [-u_max[0] - comp[0], -u_max[1] - comp[1], np.full(b, -a_max / _A_SCALE), -v0 * np.ones(b), np.full(b, -np.inf)]
    )
    upper = np.concatenate(
        [u_max[0] - comp[0], u_max[1] - comp[1], np.full(b, a_max / _A_SCALE), v_cap - v0, theta_max - base]
    )
    G = np.zeros((2 * b, 3 * b))
    G[:b, 2 * b :] = pred.Sv * _A_SCALE
    G[b:, 2 * b :] = St
    return ContouringQP(0.5 * (H + H.T), f, G, lower, upper)


def solve_qp(qp: ContouringQP) -> np.ndarray:
    """The QP's minimiser by DAQP (Arnstrom, Bemporad and Axehill 2022); RuntimeError if it fails."""
    import daqp

    scale = 1.0 / np.mean(np.diag(qp.H))
    upper = np.minimum(qp.upper, 1e30)
    lower = np.maximum(qp.lower, -1e30)
    lower = np.minimum(lower, upper)  # a bound made inconsistent by a cap below the speed now: hold it
    sense = np.zeros(upper.size, dtype=np.int32)
    z, _, flag, _ = daqp.solve(qp.H * scale, qp.f * scale, qp.G, upper, lower, sense)
    if flag < 1:  # infeasible: the progress' speed and end bounds (the general rows) made soft
        sense[qp.f.size :] = 8
        z, _, flag, _ = daqp.solve(qp.H * scale, qp.f * scale, qp.G, upper, lower, sense)
    if flag < 1:
        raise RuntimeError(f"DAQP failed on the MPCC's QP (exit flag {flag})")
    return np.asarray(z)


class MPCCPolicy(BaselinePolicy):
    """Model predictive contouring control with its own progress and the feed override (module docstring).

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant
        As :class:`~vcnc_baselines.base.BaselinePolicy`; the decision period must be the control period ``dt``.
    reference : ndarray, (K, REF_COLUMNS)
        The programmed path and feed: the env's packed reference samples before any override.
    dt : float
        The env's control period, s.
    v_max : float, optional
        Largest progress speed, mm/s; default ``max_override`` times the programmed feed's peak.
    contour_weight, lag_weight : float
        ``q_c``, ``q_l``, per um^2 and control period (default 4 and 1: on the omega at 100 mm/s, ``q_c`` 1 gave
        7.50 um max, 4 gave 3.97 um and 16 3.99 um, all in 0.687 s).
    progress_weight : float, optional
        ``q_v``, per mm/s and control period (default ``10 x 100 / F``, ``F`` the programmed feed's peak in mm/s:
        on the omega at 100 mm/s, 10, and 100 mm/s is worth 1000 um^2 of squared error; the feed is worth as much
        on any path, :data:`WEIGHTS_FEED`).
    advance_weight : float, optional
        ``q_theta``, per mm of progress and control period (default ``200 x 100 / F``; module docstring).
    input_weight, path_weight : float
        ``r_u`` per input unit^2 of change between blocks, ``r_a`` per (1000 mm/s^2)^2 (defaults 1e-3, 1e-2).
    a_max : float, optional
        Bound of the progress' acceleration, mm/s^2; default the slower drive's acceleration from rest at its
        input limit less its Coulomb level (nominal model).
    blocks : sequence of int
        The horizon's block lengths, control periods (:data:`DEFAULT_BLOCKS`).
    disturbance_time : float, optional
        s, the input disturbance observer's time constant (module docstring, "Integral action"); 0: none; default
        :data:`DISTURBANCE_TIME` where the plant's position sensor is exact, else none.
    max_override : float
        The dial's top, x the programmed feed, 1 to 1.5 (``from_env``: the env's own): the progress runs at most
        this many times the programmed feed at each point of the path (a CNC panel's override reaches 150 %, and
        the tolerance task's look-ahead opponents and agents are given as much).

    Attributes
    ----------
    solves, calls : int
        QPs solved and calls since construction.
    """

    name = "mpcc"
    #: A 90-variable QP per control period in Python: the bench runs it when named (``--policy mpcc``).
    in_default_table = False
    needs_reference = True
    #: It sets the env's feed override (a third action): feed-override ids only (vcnc_bench's ``applies``).
    sets_feed_override = True

    @classmethod
    def designed_for(cls, plant) -> bool:
        """A plant with a linear model per axis and declared inverse dynamics (its Coulomb levels)."""
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
        v_max=None,
        contour_weight=4.0,
        lag_weight=1.0,
        progress_weight=None,
        advance_weight=None,
        input_weight=1e-3,
        path_weight=1e-2,
        a_max=None,
        blocks=DEFAULT_BLOCKS,
        disturbance_time: float | None = None,
        max_override: float = 1.0,
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        self.dt = positive("dt", dt, "s")
        self.max_override = real("max_override", max_override, "x the programmed feed")
        if not 1.0 <= self.max_override <= MAX_OVERRIDE:
            raise ValueError(
                f"max_override must be in [1, {MAX_OVERRIDE:g}] (the dial's top, x the programmed feed), "
                f"got {max_override!r}"
            )
        if abs(self.decision_period - self.dt) > 1e-9 * self.dt:
            raise ValueError(
                f"mpcc is designed at the control period: it needs decision_period = dt ({self.dt} s), "
                f"got {self.decision_period} s"
            )
        self.path = path_table(reference, self.dt)
        peak = float(self.path.feed.max())
        self.v_max = self.max_override * peak if v_max is None else positive("v_max", v_max, "mm/s")
        # the progress rewards' defaults, tuned on the omega at 100 mm/s, in proportion to the programmed feed: a path
        # run at a hundredth of the speed earns as much for its feed as the omega does for its own
        scale = WEIGHTS_FEED / peak
        progress_weight = 10.0 * scale if progress_weight is None else progress_weight
        advance_weight = 200.0 * scale if advance_weight is None else advance_weight
        self.weights = (
            positive("contour_weight", contour_weight, "per um^2") * 1e6,
            positive("lag_weight", lag_weight, "per um^2") * 1e6,
            positive("progress_weight", progress_weight, "per mm/s"),
            positive("advance_weight", advance_weight, "per mm"),
            positive("input_weight", input_weight),
            positive("path_weight", path_weight),
        )
        models = [
            axis_model(
                self.plant.linear_model(self.nominal_parameters, axis=j),
                self.dt,
                self.plant.dead_time(self.nominal_parameters, axis=j),
            )
            for j in range(2)
        ]
        if models[0].n != models[1].n:
            raise ValueError("mpcc needs both axes' models of one order")
        self.models = models
        self.predictions = [block_prediction(m, blocks) for m in models]
        self.gains = [estimator_gain(m, 0.01 * self.u_max[j], 1e-5, 1.0) for j, m in enumerate(models)]
        self.coulomb = self._coulomb()
        self.a_max = self._drive_acceleration() if a_max is None else positive("a_max", a_max, "mm/s^2")
        if disturbance_time is None:  # the observer reads the state's surprise: only where the sensor is exact
            exact = not np.any(sensor_noise(self.plant, self.nominal_parameters) > 0)
            disturbance_time = DISTURBANCE_TIME if exact else 0.0
        self.disturbance_time = non_negative("disturbance_time", disturbance_time, "s")
        n, b = models[0].n, len(blocks)
        self.n_states, self.n_blocks = n, b
        # memory: theta, v, a_prev, u_prev (2), clock index, calls, the input disturbance (2), x_hat (2 n), the last
        # plan's theta (b)
        self._slots = {"theta": 0, "v": 1, "a": 2, "u": 3, "clock": 5, "k": 6, "d": 7, "x": 9, "plan": 9 + 2 * n}
        self.state_shape = (9 + 2 * n + b,)
        self.solves = 0
        self.calls = 0
        self._dial = np.zeros(0, dtype=np.float32)

    def _coulomb(self) -> np.ndarray:
        """(2, 2) the Coulomb levels per axis and direction (+, -), input unit: the nominal machine's commissioning
        record, else the plant's declared inverse."""
        from ..commissioning.record import nominal_record

        record = nominal_record(self.plant, self.nominal_parameters, self.dt)
        inverse = record.inverse(with_mode=False) if record is not None else self.plant.inverse(self.nominal_parameters)
        return np.asarray(inverse.coulomb, dtype=np.float64)

    def _drive_acceleration(self) -> float:
        """The slower axis' acceleration from rest at its input limit less its Coulomb level, mm/s^2 (over the
        first 1 ms of the nominal model; its dead time, if any, left out)."""
        out = []
        for j, m in enumerate(self.models):
            u = self.u_max[j] - abs(self.coulomb[j, 0])
            periods = max(1, int(round(1e-3 / self.dt)))
            x = np.zeros(m.n)
            ys = []
            for _ in range(periods + m.delay_periods + 1):
                x = m.A @ x + m.B * u
                ys.append(m.C @ x)
            moved = np.asarray(ys[m.delay_periods :])
            tt = self.dt * np.arange(1, moved.size + 1)
            out.append(2.0 * moved[-1] / tt[-1] ** 2)  # y = a t^2 / 2 from rest
        return float(min(out))

    @classmethod
    def from_env(cls, env, **params):
        """Build it for a feed-override env (module docstring: a plain contouring id cannot score a controller
        that sets its own progress); reads the programmed path and the override's slew rate."""
        u = getattr(env, "unwrapped", env)
        task = getattr(u, "task", None)
        if not getattr(u, "retimes_reference", False) or getattr(u.action_space, "shape", None) != (3,):
            raise ValueError(
                f"baseline 'mpcc' chooses its own progress and sets the feed override: it runs on a "
                f"feed-override id (VCNC-OmegaOverride-v1), got {type(u).__name__}; a plain contouring "
                "id ends the episode completion_timeout after its reference's end, which a controller "
                "slower than the programmed feed cannot meet"
            )
        if getattr(u, "lookahead", None) is not None:
            raise ValueError(
                "baseline 'mpcc' sets the override itself, 0 to max_override of the programmed feed: it "
                "runs on a feed-override env without a look-ahead under the dial (VCNC-OmegaOverride-v1, "
                f"or a tolerance id with lookahead=None), got lookahead={u.lookahead!r}"
            )
        if "max_override" in params and params["max_override"] != u.max_override:
            raise ValueError(f"max_override is the env's dial top ({u.max_override:g}), got {params['max_override']!r}")
        params["max_override"] = u.max_override
        return super().from_env(env, reference=task.reference_arrays.samples, dt=task.dt, **params)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """As :meth:`BaselinePolicy.predict`, the action (3,) or (n_envs, 3): the axes' normalised commands and
        the override dial (override = ``max_override`` (dial + 1) / 2)."""
        action, state = super().predict(observation, state, episode_start, deterministic)
        dial = self._dial if np.ndim(action) == 2 else self._dial[0:1]
        return np.concatenate([action, dial[..., None] if np.ndim(action) == 2 else dial], axis=-1), state

    # -- one call ----------------------------------------------------------------------------------------
    def _estimate(self, mem, y, v):
        """x(k|k) per axis (2, n) from the measured position ``y`` and velocity ``v`` (2,)."""
        s, n = self._slots, self.n_states
        x = mem[s["x"] : s["x"] + 2 * n].reshape(2, n)
        out = np.empty((2, n))
        gain = min(1.0, self.dt / self.disturbance_time) if self.disturbance_time > 0 else 0.0
        for j, m in enumerate(self.models):
            ym = np.array([y[j], v[j]])[: m.measurement().shape[0]]
            if mem[s["k"]] == 0:
                xm = np.linalg.pinv(m.measurement()) @ ym
            else:
                xm = m.A @ x[j] + m.B * mem[s["u"] + j]
            out[j] = xm + self.gains[j] @ (ym - m.measurement() @ xm)
            if mem[s["k"]] > 0 and gain > 0:  # the input the last step's surprise asks, integrated
                b = m.input_column
                mem[s["d"] + j] += gain * (b @ (out[j] - xm)[: b.size]) / (b @ b)
        mem[s["x"] : s["x"] + 2 * n] = out.ravel()
        return out

    def _theta_bar(self, mem):
        """The previous plan's progress at this call's block ends (the plan shifted by one control period)."""
        s, pred = self._slots, self.predictions[0]
        times = np.concatenate([[0.0], pred.times])
        plan = np.concatenate([[mem[s["theta"]]], mem[s["plan"] : s["plan"] + self.n_blocks]])
        if mem[s["k"]] == 0:
            return np.full(self.n_blocks, mem[s["theta"]])
        shifted = np.interp(pred.times + self.dt, times, plan)  # held beyond the plan's end
        return np.minimum(shifted, self.path.length)

    def _comp(self, theta_bar, v_bar):
        """(2, b) Coulomb pre-compensation at each block from the planned axis speeds ``t v``."""
        _, t = self.path.at(theta_bar)
        s = np.tanh(t.T * v_bar[None, :] / _COULOMB_SPEED)
        return self.coulomb[:, :1] * np.maximum(s, 0.0) + self.coulomb[:, 1:] * np.maximum(-s, 0.0)

    def _solve(self, mem, x0):
        """Solve (and on the first call re-linearise) the QP; returns ``(z, theta_bar)``."""
        s, pred, b = self._slots, self.predictions[0], self.n_blocks
        theta0, v0 = mem[s["theta"]], mem[s["v"]]
        theta_bar = self._theta_bar(mem)
        v_bar = np.full(b, v0)
        u_prev = mem[s["u"] : s["u"] + 2]
        for _ in range(FIRST_ITERATIONS if mem[s["k"]] == 0 else 1):
            v_cap = np.minimum(
                np.minimum(self.v_max, self.max_override * self.path.feed_at(theta_bar)),  # braking:
                np.sqrt(2.0 * self.a_max * np.maximum(self.path.length - theta_bar, 0.0)),
            )
            comp = self._comp(theta_bar, v_bar) - mem[s["d"] : s["d"] + 2, None]
            qp = contouring_qp(
                self.predictions,
                self.path,
                x0,
                theta0,
                v0,
                theta_bar,
                u_prev,
                mem[s["a"]],
                comp,
                self.u_max,
                v_cap,
                self.a_max,
                self.weights,
            )
            z = solve_qp(qp)
            self.solves += 1
            a = z[2 * b :] * _A_SCALE
            theta_bar = np.minimum(theta0 + pred.times * v0 + pred.St @ a, self.path.length)
            v_bar = v0 + pred.Sv @ a
        return z, theta_bar, comp

    def _step(self, mem, obs_row):
        lay, s, b = self.layout, self._slots, self.n_blocks
        r = lay.reference_position(obs_row[None])[0].astype(np.float64)
        y = r - lay.tracking_error(obs_row[None])[0].astype(np.float64)
        v = lay.velocity(obs_row[None])[0].astype(np.float64)
        x0 = self._estimate(mem, y, v)
        z, theta_plan, comp = self._solve(mem, x0)
        a0 = z[2 * b] * _A_SCALE
        u_lin = np.array([z[0], z[b]])
        u = u_lin + comp[:, 0]
        applied = np.clip(u / self.u_max, -1.0, 1.0).astype(np.float32).astype(np.float64) * self.u_max
        mem[s["u"] : s["u"] + 2] = applied - comp[:, 0]
        theta, vel = mem[s["theta"]], mem[s["v"]]
        mem[s["theta"]] = min(theta + self.dt * vel + 0.5 * self.dt**2 * a0, self.path.length)
        mem[s["v"]] = max(vel + self.dt * a0, 0.0) if mem[s["theta"]] < self.path.length else 0.0  # stopped at the end
        mem[s["a"]] = a0
        mem[s["plan"] : s["plan"] + b] = theta_plan
        mem[s["k"]] += 1
        return u, self._override(mem, r)

    def _override(self, mem, r):
        """The dial that makes the interpolator's clock follow ``theta``: the clock's arc from the observed
        reference point (the nearest programmed point at or after the last one found), then the override."""
        s, path = self._slots, self.path
        k = int(mem[s["clock"]])
        window = path.point[k : k + 400]
        k += int(np.argmin(np.sum((window - r) ** 2, axis=1)))
        mem[s["clock"]] = k
        speed = path.speed[k]  # the clock's speed at 100 %
        want = mem[s["v"]] + (mem[s["theta"]] + _CLOCK_LEAD - path.arc[k]) / _CLOCK_TIME
        m = self.max_override
        override = 1.0 if speed <= 1e-9 * path.feed[-1] else min(max(want / speed, 0.0), m)
        return 2.0 * override / m - 1.0  # the env's override is m (dial + 1) / 2

    def _command(self, obs):
        n = obs.shape[0]
        u = np.empty((n, 2))
        self._dial = np.empty(n, dtype=np.float32)
        with _one_blas_thread():
            for i in range(n):
                u[i], self._dial[i] = self._step(self._state[i], obs[i])
        self.calls += n
        return u


class _one_blas_thread:
    """BLAS on one thread while the QPs are built: at these sizes (90 x 135) OpenBLAS's threads on a loaded 2-core
    host made ``J' J`` 100 times slower (17 ms against 0.14 ms).  Through threadpoolctl when it is installed."""

    _libs = None

    def __enter__(self):
        if _one_blas_thread._libs is None:
            try:
                from threadpoolctl import ThreadpoolController

                _one_blas_thread._libs = ThreadpoolController().select(user_api="blas").lib_controllers
            except ImportError:
                _one_blas_thread._libs = []
        self._old = [lib.num_threads for lib in self._libs]
        for lib in self._libs:
            lib.set_num_threads(1)

    def __exit__(self, *exc):
        for lib, n in zip(self._libs, self._old):
            lib.set_num_threads(n)
