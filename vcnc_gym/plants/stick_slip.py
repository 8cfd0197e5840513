"""Stick-slip (Karnopp) friction of a rigid axis, solved exactly over an interval: one routine for every plant.

An axis moves by ``J w' = F - B w - T_f(w, F)`` with the drive ``F`` held over the interval: ``w`` the motor speed
(rad/s, torques in N m: Jahanpour et al. (2014), eq. (1)) or the table velocity (mm/s, forces in N: Simba et al.,
eq. (1)).  The friction is Karnopp's: an axis at rest (``w == 0.0`` exactly) stays stuck until ``F`` exceeds the
static level of a direction (``static_pos``, or falls below ``static_neg``); a moving axis feels the Coulomb
level of its direction (``coulomb_pos`` for ``w > 0``, ``coulomb_neg``, a negative number, for ``w < 0``).
Simba et al.'s single level ``f_c`` is ``(f_c, -f_c, f_c, -f_c)``.

:func:`stick_slip` advances one axis over an interval ``h`` with the force constant between events: the motion
by :func:`~vcnc_gym.plants.exact_zoh.first_order`, a stop located exactly where the velocity reaches zero (time
and travel by :func:`~vcnc_gym.plants.exact_zoh.log1p_ratio` and :func:`~vcnc_gym.plants.exact_zoh.log1p_rest`),
and, once stopped, the break-away test for the rest of the interval.  After a break-away the net force has the
sign of the motion, so an interval holds at most one stop and one break-away after it.  It returns the travel up
to the stop and the travel after it separately, so that a plant with backlash can apply its play operator at the
stop (where the motion reverses) as well as at the end.
"""

from __future__ import annotations

from typing import NamedTuple

import numba

from .exact_zoh import first_order, log1p_ratio, log1p_rest

__all__ = ["StickSlipAxis", "STUCK", "MOVED", "STOPPED", "stick_slip"]

#: What :func:`stick_slip` did over the interval: nothing (stuck at rest throughout) ...
STUCK = 0
#: ... moved without stopping (from motion, or broken away from rest at the start) ...
MOVED = 1
#: ... or came to rest inside it (and perhaps broke away again for the rest of it).
STOPPED = 2


class StickSlipAxis(NamedTuple):
    """One axis as :func:`stick_slip` takes it, in its own units (a torque's or a force's)."""

    inertia: float  #: J (kg m^2) or m (N s^2/mm)
    damping: float  #: viscous friction B (N m s/rad) or c (N s/mm), >= 0
    inv_inertia: float  #: 1 / inertia, computed once by the caller
    static_pos: float  #: break-away level in the + direction, >= coulomb_pos
    static_neg: float  #: break-away level in the - direction, <= coulomb_neg
    coulomb_pos: float  #: friction while w > 0, >= 0
    coulomb_neg: float  #: friction while w < 0, <= 0


@numba.njit(cache=True)
def _break_away(axis, drive):
    """(True, acceleration) if ``drive`` breaks the axis away from rest, else (False, 0.0)."""
    if drive > axis.static_pos:
        return True, (drive - axis.coulomb_pos) * axis.inv_inertia
    if drive < axis.static_neg:
        return True, (drive - axis.coulomb_neg) * axis.inv_inertia
    return False, 0.0


@numba.njit(cache=True, inline="always")
def stick_slip(axis, w, drive, h, zoh):
    """Advance one axis over ``h`` s under the constant ``drive``, exactly.

    Parameters
    ----------
    axis : StickSlipAxis
        Inertia, damping and friction levels.
    w : float
        Velocity at the start; ``0.0`` exactly means at rest (stuck unless ``drive`` breaks it away).
    drive : float
        The drive's torque or force, already saturated.
    h : float
        The interval, s.
    zoh : (E, g, q)
        ``first_order(damping / inertia, h)``, which a caller advancing several intervals of the same ``h``
        computes once.

    Returns
    -------
    mode : int
        ``STUCK``, ``MOVED`` or ``STOPPED``.
    w : float
        Velocity at the end of the interval (0.0 if stuck or stopped and not broken away again).
    travel : float
        Integral of the velocity over the interval (``MOVED``) or up to the stop (``STOPPED``); 0.0 if stuck.
    rest : float
        Integral of the velocity after the stop (``STOPPED`` and broken away again), else 0.0.
    """
    e, g, q = zoh
    if w == 0.0:
        moves, alpha = _break_away(axis, drive)
        if not moves:
            return STUCK, 0.0, 0.0, 0.0
        return MOVED, alpha * g, alpha * q, 0.0
    if w > 0.0:
        torque = drive - axis.coulomb_pos
    else:
        torque = drive - axis.coulomb_neg
    alpha = torque * axis.inv_inertia
    w_new = e * w + g * alpha
    if (w > 0.0 and w_new > 0.0) or (w < 0.0 and w_new < 0.0):
        return MOVED, w_new, g * w + q * alpha, 0.0
    # the velocity reaches zero inside the interval (the net force opposes w, so -torque has the sign of w)
    tau = axis.inertia * w / (-torque)  # > 0, the stop time without viscous friction
    x = axis.damping * w / (-torque)  # >= 0
    t_stop = tau * log1p_ratio(x)
    to_stop = tau * w * log1p_rest(x)
    rest = h - t_stop
    if rest > 0.0:
        moves, alpha = _break_away(axis, drive)
        if moves:
            _, g_r, q_r = first_order(axis.damping * axis.inv_inertia, rest)
            return STOPPED, alpha * g_r, to_stop, alpha * q_r
    return STOPPED, 0.0, to_stop, 0.0
