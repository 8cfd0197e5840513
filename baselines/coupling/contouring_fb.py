"""The contouring controller of Simba et al., eqs. (2)-(7): feedback linearisation in the path frame.

Simba et al. control their current-driven feed drives, eq. (1)
(:mod:`vcnc_gym.plants.current_feed_drive`), in two layers.

**Feedback linearisation**, eqs. (4)-(6): the current

.. math:: i_a = K_f^{-1} (M v + C \\dot x + F_c \\,\\mathrm{sgn}(\\dot x))        \\qquad (5)

turns each axis into a double integrator :math:`\\ddot x = v` (with the
nominal Table I parameters; :math:`\\dot x` is the measured table velocity,
:math:`\\mathrm{sgn}(0) = 0`).

**Contouring control in the path frame**, eqs. (2), (3), (7): the tracking
error :math:`e_w = x_d - x` is rotated into the frame of the path,
:math:`e_l = (e_t, e_n) = R^T e_w` with :math:`R` the rotation by the path
angle :math:`\\theta`, and

.. math::

    v = \\ddot x_d + R (K_P e_l + K_D \\dot e_l)
        + \\ddot\\theta \\Xi e_w - \\dot\\theta^2 e_w + 2 \\dot\\theta \\Xi \\dot e_w,
    \\qquad \\Xi = \\begin{bmatrix} 0 & 1 \\\\ -1 & 0 \\end{bmatrix}.          \\qquad (7)

Since :math:`\\dot R^T = \\dot\\theta \\Xi R^T`,
:math:`\\dot e_l = R^T (\\dot e_w + \\dot\\theta \\Xi e_w)` and
:math:`\\ddot e_l = R^T (\\ddot e_w + \\ddot\\theta \\Xi e_w
+ 2 \\dot\\theta \\Xi \\dot e_w - \\dot\\theta^2 e_w)`; with
:math:`\\ddot e_w = \\ddot x_d - v` the law (7) gives
:math:`\\ddot e_l + K_D \\dot e_l + K_P e_l = 0`: the tangential and the
normal errors are two decoupled second-order systems.  With Table I's
:math:`k_P = 70\\,000`, :math:`k_D = 240`: :math:`\\omega_n = 264.6` rad/s,
:math:`\\zeta = 0.454`.

Units.  Table I prints the gains in A/mm and A s/mm, but eq. (7) adds them to
:math:`\\ddot x_d`: they act on the virtual input v, an acceleration, so here
k_P is in 1/s^2 and k_D in 1/s (read as currents, 70 000 A/mm would put the
loop near 1.4e4 rad/s).  The gains are diagonal in the path frame, entry 1
on the tangential, entry 2 on the normal error.

What the observation does not give, and how it is computed
-----------------------------------------------------------
* :math:`e_w` is the observation's ``tracking_error``, :math:`\\dot e_w` is
  ``reference_velocity - velocity`` (no differentiation).
* :math:`\\theta` = atan2 of the ``reference_velocity``.  Where the reference
  is (nearly) at rest (speed below :data:`MIN_SPEED`), the direction of the
  farthest ``preview`` point from the reference point,
  :math:`x_d(t + p) - x_d(t)` = preview - tracking error, is used (the
  path's direction at the start), else the previous :math:`\\theta` is kept
  (the end of the path).
* :math:`\\dot\\theta = (\\dot x_d \\times \\ddot x_d) / |\\dot x_d|^2`
  (= curvature x feed) from ``reference_velocity`` and
  ``reference_acceleration``: exact for the reference; 0 below
  :data:`MIN_SPEED`.  On a polyline it is 0 on the segments: the frame turns
  in one control period at a sharp corner.
* :math:`\\ddot\\theta` is the backward difference of :math:`\\dot\\theta`
  over one decision period (the controller's memory; 0 at the first call of
  an episode).  The reference's jerk, which an exact value needs, is not
  observed.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from vcnc_gym.validation import per_axis, positive
from ..base import BaselinePolicy

__all__ = ["TABLE_I_FB", "MIN_SPEED", "ContouringFBPolicy", "contouring_feedback"]

#: Simba et al., Table I: feedback gains (both axes), as accelerations: k_P 1/s^2, k_D 1/s.
TABLE_I_FB = {"k_p": 70000.0, "k_d": 240.0}

#: Reference speed in mm/s below which the path angle is not taken from the
#: reference velocity and its rate is 0 (float32 velocity and acceleration
#: make the rate's rounding error about ``|a|`` 1e-7 / ``|v|`` rad/s).
MIN_SPEED = 1e-3


@njit(cache=True)
def contouring_feedback(obs, offsets, memory, k_p, k_d, dt, fb, frame):
    """The feedback of eq. (7) without x_d'' for a batch of observations (numba).

    Parameters
    ----------
    obs : (n, D) float32 or float64
        Observations.
    offsets : (5,) int64
        Offsets in ``obs`` of reference_velocity, reference_acceleration,
        tracking_error, velocity and the last preview point (see the module
        docstring for how theta and its rates are formed from them).
    memory : (n, 3) float64
        Per env: theta [rad] and theta_dot [rad/s] of the previous call, 1.0
        once called (0.0 at the start of an episode); updated.
    k_p, k_d : (2,) float64
        Gains on (tangential, normal) error, 1/s^2 and 1/s.
    dt : float
        Decision period, s.
    fb : (n, 2) float64
        Written: R (K_P e_l + K_D e_l') + theta'' Xi e_w - theta'^2 e_w + 2 theta' Xi e_w', mm/s^2.
    frame : (n, 3) float64
        Written: theta [rad], theta' [rad/s], theta'' [rad/s^2].
    """
    o_vd, o_ad, o_e, o_v, o_pre = offsets[0], offsets[1], offsets[2], offsets[3], offsets[4]
    for k in range(obs.shape[0]):
        vx, vy = float(obs[k, o_vd]), float(obs[k, o_vd + 1])
        ax, ay = float(obs[k, o_ad]), float(obs[k, o_ad + 1])
        ex, ey = float(obs[k, o_e]), float(obs[k, o_e + 1])
        dex, dey = vx - float(obs[k, o_v]), vy - float(obs[k, o_v + 1])
        called = memory[k, 2] > 0.0
        speed2 = vx * vx + vy * vy
        if speed2 > MIN_SPEED * MIN_SPEED:
            theta = math.atan2(vy, vx)
            th_d = (vx * ay - vy * ax) / speed2  # curvature x feed
        else:
            theta = memory[k, 0]
            cx, cy = float(obs[k, o_pre]) - ex, float(obs[k, o_pre + 1]) - ey  # x_d(t + p) - x_d(t)
            if not called and (cx != 0.0 or cy != 0.0):
                theta = math.atan2(cy, cx)
            th_d = 0.0
        th_dd = (th_d - memory[k, 1]) / dt if called else 0.0
        memory[k, 0] = theta
        memory[k, 1] = th_d
        memory[k, 2] = 1.0
        cos, sin = math.cos(theta), math.sin(theta)
        # e_l = R^T e_w and e_l' = R^T (e_w' + theta' Xi e_w), Xi (a, b) = (b, -a)        (eq. (3))
        wx, wy = dex + th_d * ey, dey - th_d * ex
        f_t = k_p[0] * (cos * ex + sin * ey) + k_d[0] * (cos * wx + sin * wy)
        f_n = k_p[1] * (-sin * ex + cos * ey) + k_d[1] * (-sin * wx + cos * wy)
        # R (K_P e_l + K_D e_l') + theta'' Xi e_w - theta'^2 e_w + 2 theta' Xi e_w'     (eq. (7))
        fb[k, 0] = cos * f_t - sin * f_n + th_dd * ey - th_d * th_d * ex + 2.0 * th_d * dey
        fb[k, 1] = sin * f_t + cos * f_n - th_dd * ex - th_d * th_d * ey - 2.0 * th_d * dex
        frame[k, 0] = theta
        frame[k, 1] = th_d
        frame[k, 2] = th_dd


class ContouringFBPolicy(BaselinePolicy):
    """Simba et al.'s contouring controller, eq. (7), with feedback linearisation, eq. (5).

    Parameters
    ----------
    layout : vcnc_gym.envs.layout.ObservationLayout
        Names the observation fields.
    decision_period : float
        Period T in s between two calls of :meth:`predict` (the backward
        difference of the path angle rate).
    nominal_parameters : array_like, (2, P)
        Nominal parameters of :mod:`vcnc_gym.plants.current_feed_drive`
        (m, c, f_c, k_f, i_max per axis): the model that eq. (5) inverts.
    plant : optional
        Must be ``"current_feed_drive"`` (the default).
    k_p : float or (float, float)
        Position gain of eq. (7) in 1/s^2, on (tangential, normal) error; > 0.
        Default 70 000 (Table I).
    k_d : float or (float, float)
        Velocity gain of eq. (7) in 1/s; > 0.  Default 240 (Table I).

    Notes
    -----
    Memory per env (reset on ``episode_start``): the path angle (rad) and its
    rate (rad/s) of the previous call, and whether there was one.
    """

    name = "contouring-fb"
    plants = ("current_feed_drive",)
    paper = "Simba et al."
    state_shape = (3,)  # theta [rad], theta_dot [rad/s] of the previous call, 1.0 once called

    def __init__(
        self, layout, decision_period, nominal_parameters, plant=None, k_p=TABLE_I_FB["k_p"], k_d=TABLE_I_FB["k_d"]
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        self.k_p = per_axis("k_p", k_p, rule=positive)
        self.k_d = per_axis("k_d", k_d, rule=positive)
        p = self.nominal_parameters
        self.m, self.c, self.f_c, self.k_f = (p[:, self.plant.index(n)] for n in ("m", "c", "f_c", "k_f"))
        lay = layout
        if not lay.preview_steps:
            raise ValueError(
                "contouring-fb reads the path direction from the observation's last preview point; "
                "the env's preview_steps is empty"
            )
        last_preview = lay.offset("preview") + 2 * (len(lay.preview_steps) - 1)
        self._offsets = np.array(
            [
                lay.offset("reference_velocity"),
                lay.offset("reference_acceleration"),
                lay.offset("tracking_error"),
                lay.offset("velocity"),
                last_preview,
            ],
            dtype=np.int64,
        )

    # -- eq. (5) -------------------------------------------------------------------
    def linearising_current(self, v, velocity) -> np.ndarray:
        """Eq. (5): the current in A, (..., 2), that gives the nominal axes the acceleration ``v`` (mm/s^2)."""
        return (self.m * v + self.c * velocity + self.f_c * np.sign(velocity)) / self.k_f

    def applied_acceleration(self, current, velocity) -> np.ndarray:
        """Inverse of eq. (5) after saturation: the virtual input v (mm/s^2) the current (A) really applies."""
        i = np.clip(current, -self.u_max, self.u_max)
        return (self.k_f * i - self.c * velocity - self.f_c * np.sign(velocity)) / self.m

    # -- the path frame and eq. (7) ------------------------------------------------------
    def _feedback(self, obs):
        """The feedback part of eq. (7), v - x_d'' in mm/s^2 (n, 2), and the path angle theta (n,) in rad."""
        n = obs.shape[0]
        fb = np.empty((n, 2))
        frame = np.empty((n, 3))
        contouring_feedback(obs, self._offsets, self._state, self.k_p, self.k_d, self.decision_period, fb, frame)
        return fb, frame[:, 0]

    def _command(self, obs):
        fb, _ = self._feedback(obs)
        v = self.layout.reference_acceleration(obs) + fb
        return self.linearising_current(v, self.layout.velocity(obs))
