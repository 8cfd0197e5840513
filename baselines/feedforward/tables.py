"""Feedforward tables: the plant's inverse dynamics, and ZPETC's modified reference, computed from the reference.

Both are computed once, when a controller is built, from the env's reference samples (``x_d``, ``v_d``,
``a_d`` per control period; jerk and snap by central differences of ``a_d``) and the plant's *nominal*
:class:`~vcnc_gym.plants.contract.InverseDynamics`:

- :func:`inverse_feedforward`: the input that makes the nominal model follow the reference,
  ``u_ff[k] = sum_n c_n x_d^(n)`` evaluated at ``t_k + dt/2 + T_d`` (the middle of the zero-order-hold
  period the input is held over, plus the dead time), with the Coulomb friction of the direction of motion
  and the Stribeck curve at the reference's speed (where the inverse has one) switched at the reference's
  velocity reversals and the drive moved across the backlash gap there, both
  over a short zero-phase transition (``friction_time``, ``backlash_time``);
- :func:`zpetc_reference`: Tomizuka (1987)'s zero-phase-error tracking controller of a discretised closed
  loop ``G_c(z^-1) = z^-d B_a B_u / A``: ``r(k) = A B_u* / (B_a B_u(1)^2) x_d(k + d + s)``, ``B_u`` the
  closed loop's unacceptable zeros (:func:`split_zeros`), ``B_u*`` its coefficients reversed.
"""

from __future__ import annotations

import control
import numpy as np
from scipy import signal

from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.plants.contract import INVERSE_ORDER, InverseDynamics

__all__ = [
    "reference_motion",
    "smooth_sign",
    "inverse_feedforward",
    "linear_inverse",
    "closed_loop",
    "split_zeros",
    "zpetc_filter",
    "zpetc_reference",
    "path_force_feedforward",
]


def reference_motion(samples: np.ndarray, dt: float) -> np.ndarray:
    """Position and its first four derivatives per control period, (K, 2, 5): mm, mm/s, ..., mm/s^4.

    Position, velocity and acceleration are the reference's own (the interpolator's exact values); jerk
    and snap are central differences of the acceleration (:func:`numpy.gradient`)."""
    x = samples[:, sk.REF_POSITION : sk.REF_POSITION + 2]
    v = samples[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
    a = samples[:, sk.REF_ACCELERATION : sk.REF_ACCELERATION + 2]
    jerk = np.gradient(a, dt, axis=0)
    snap = np.gradient(jerk, dt, axis=0)
    return np.stack([x, v, a, jerk, snap], axis=2)


def smooth_sign(velocity: np.ndarray, dt: float, duration: float) -> np.ndarray:
    """sgn(velocity) per column, each change spread over ``duration`` s by a zero-phase Hann window (the
    table is computed ahead, so the transition may start before the reversal): 0 at rest, +-1 in motion."""
    s = np.sign(velocity)
    n = int(round(duration / dt))
    if n < 2:
        return s
    window = np.hanning(n + 2)[1:-1]
    window /= window.sum()
    padded = np.concatenate([np.repeat(s[:1], n, axis=0), s, np.repeat(s[-1:], n, axis=0)])
    out = np.stack([np.convolve(padded[:, j], window, mode="same") for j in range(s.shape[1])], axis=1)
    return out[n : n + s.shape[0]]


def _at(values: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """``values`` (K, 2) read at the fractional sample ``k + shift[j]`` per axis (linear, ends held)."""
    k = np.arange(values.shape[0], dtype=np.float64)
    return np.column_stack([np.interp(k + shift[j], k, values[:, j]) for j in range(2)])


def inverse_feedforward(
    inverse: InverseDynamics,
    samples: np.ndarray,
    dt: float,
    *,
    friction_time: float = 1e-3,
    backlash_time: float = 16e-3,
    motion: bool = True,
    friction: bool = True,
    backlash: bool = True,
) -> np.ndarray:
    """The nominal model's input along the reference, (K, 2) in the plant's input unit (row k: the input
    held over control period k).

    Parameters
    ----------
    inverse : InverseDynamics
        The plant's nominal inverse dynamics.
    samples : ndarray, (K, REF_COLUMNS)
        The env's packed reference.
    dt : float
        Control period, s.
    friction_time, backlash_time : float
        Durations (s) over which the Coulomb level and the drive's side of the backlash gap change at a
        velocity reversal of the reference (:func:`smooth_sign`).
    motion, friction, backlash : bool
        The terms to include: the reference's own motion through the linear part, the Coulomb friction, the
        backlash crossing (the last two when the plant has them).
    """
    reference = reference_motion(samples, dt)
    velocity = reference[:, :, 1]
    s = smooth_sign(velocity, dt, friction_time)
    derivatives = reference[:, :, 1 : 1 + INVERSE_ORDER] * (1.0 if motion else 0.0)
    if backlash and np.any(inverse.backlash > 0):  # the drive leads the table by D_b / 2 in the direction of motion
        side = 0.5 * inverse.backlash * smooth_sign(velocity, dt, backlash_time)
        lead = [np.gradient(side, dt, axis=0)]
        for _ in range(INVERSE_ORDER - 1):
            lead.append(np.gradient(lead[-1], dt, axis=0))
        derivatives = derivatives + np.stack(lead, axis=2)
    u = np.einsum("kjn,jn->kj", derivatives, inverse.coefficients)
    if friction:
        u = u + np.maximum(s, 0.0) * inverse.coulomb[:, 0] + np.maximum(-s, 0.0) * inverse.coulomb[:, 1]
        level, vs = inverse.stribeck[:, 0], inverse.stribeck[:, 1]
        if np.any(level > 0):  # the Stribeck curve along the reference's speed, switched as the Coulomb level
            u = u + level * np.exp(-((velocity / np.where(level > 0, vs, 1.0)) ** 2)) * s
    return _at(u, 0.5 + inverse.delay / dt)


def linear_inverse(inverse: InverseDynamics, positions: np.ndarray, dt: float) -> np.ndarray:
    """The linear part of ``inverse`` applied to a sampled motion ``positions`` (K, 2) mm, its derivatives by
    central differences, read at ``k + 1/2 + T_d / dt`` as :func:`inverse_feedforward` reads the reference:
    (K, 2) in the plant's input unit (the oracle's learning update applies it to a trial's error)."""
    derivatives = [np.gradient(positions, dt, axis=0)]
    for _ in range(INVERSE_ORDER - 1):
        derivatives.append(np.gradient(derivatives[-1], dt, axis=0))
    u = np.einsum("kjn,jn->kj", np.stack(derivatives, axis=2), inverse.coefficients)
    return _at(u, 0.5 + inverse.delay / dt)


# -- ZPETC ------------------------------------------------------------------------------------------
def closed_loop(inverse: InverseDynamics, axis: int, dt: float, kp: float, kd: float, ki: float):
    """The discretised closed loop from the loop reference r to the position x of one axis, a python-control
    discrete transfer function (sample time ``dt``).

    The nominal axis ``m x'' + c x' = u(t - T_d)`` under zero-order hold (its dead time ``n_d`` whole samples):
    ``x = N_x / (D z^n_d) u`` and ``v = N_v (z - 1) / (D z^n_d) u`` (python-control's ``c2d`` of
    ``1 / (m s^2 + c s)`` and ``1 / (m s + c)``), under the servo law of :mod:`vcnc_baselines.servo` with ZPETC's
    offsets, ``u_k = K_p (r_k - x_k) + K_d ((r_k - r_{k-1}) / T - v_k) + K_i I_k``,
    ``I_{k+1} = I_k + T (r_k - x_k)``.  With ``C = K_p (z - 1) + K_i T``, by polynomial algebra (a state-space
    conversion loses the coefficients of a long dead time)::

        x / r = N_x (C T z + K_d (z - 1)^2) / (T z ((z - 1) D z^n_d + C N_x + K_d N_v (z - 1)^2))
    """
    m, c = inverse.mass[axis], inverse.damping[axis]
    nd = int(round(inverse.delay[axis] / dt))
    position = control.c2d(control.tf([1.0], [m, c, 0.0]), dt, "zoh")
    velocity = control.c2d(control.tf([1.0], [m, c]), dt, "zoh")
    nx, d = (np.asarray(a, dtype=float) for a in (position.num[0][0], position.den[0][0]))
    nv = np.asarray(velocity.num[0][0], dtype=float)  # over (z - e^{-c T / m}); D = (z - 1)(z - e^{-c T / m})
    one = np.array([1.0, -1.0])  # z - 1
    C = np.polyadd(kp * one, [ki * dt])
    delayed = np.concatenate([d, np.zeros(nd)])  # D z^n_d
    num = np.polymul(nx, np.polyadd(dt * np.polymul(C, [1.0, 0.0]), kd * np.polymul(one, one)))
    den = np.polyadd(np.polyadd(np.polymul(one, delayed), np.polymul(C, nx)), kd * np.polymul(nv, np.polymul(one, one)))
    den = dt * np.polymul([1.0, 0.0], den)
    return control.tf(np.trim_zeros(num, "f"), den, dt)


def split_zeros(zeros: np.ndarray, radius: float = 0.5):
    """Tomizuka's acceptable and unacceptable zeros: unacceptable are those on or outside the unit circle and
    those on the left half of the z-plane beyond ``radius`` (the sampling zeros near -1, whose inverse rings
    at the Nyquist frequency)."""
    zeros = np.asarray(zeros, dtype=complex)
    bad = (np.abs(zeros) >= 1.0) | ((zeros.real < 0.0) & (np.abs(zeros) > radius))
    return zeros[~bad], zeros[bad]


def zpetc_filter(loop) -> tuple[np.ndarray, np.ndarray, int]:
    """ZPETC of a discrete closed loop: ``(b, a, preview)`` with ``r(k) = (b / a)(z^-1) x_d(k + preview)``.

    ``loop`` is a discrete SISO transfer function ``N(z) / D(z)``; in powers of ``z^-1`` it is
    ``z^-d B(z^-1) / A(z^-1)`` with ``d = deg D - deg N``.  With ``B = b_0 B_a B_u`` (``B_u`` the
    unacceptable zeros' factors ``prod(1 - z_u z^-1)``), Tomizuka (1987) eq. (14):
    ``r(k) = A(z^-1) B_u*(z^-1) / (b_0 B_a(z^-1) B_u(1)^2) x_d(k + d + s)``,
    ``B_u*(z^-1) = prod(z^-1 - z_u)`` of degree ``s``."""
    num = np.trim_zeros(np.real_if_close(np.asarray(loop.num[0][0], dtype=float)), "f")
    den = np.asarray(loop.den[0][0], dtype=float)
    d = den.size - num.size
    zeros = np.roots(num) if num.size > 1 else np.zeros(0)
    good, bad = split_zeros(zeros)
    b_a = num[0] * np.real(np.poly(good)) if good.size else np.array([num[0]])
    b_u = np.real(np.poly(bad)) if bad.size else np.array([1.0])  # prod(1 - z_u z^-1), ascending powers of z^-1
    b_u_star = b_u[::-1]  # prod(z^-1 - z_u)
    gain = np.sum(b_u) ** 2
    b = np.convolve(den / den[0], b_u_star)
    a = b_a / den[0] * gain
    return b, a, d + (b_u.size - 1)


def zpetc_reference(filters, positions: np.ndarray) -> np.ndarray:
    """ZPETC's loop reference r (K, 2) for the reference positions ``positions`` (K, 2), mm: each axis filtered
    by its ``(b, a, preview)`` of :func:`zpetc_filter`, the reference held at its ends (at rest before and
    after)."""
    K = positions.shape[0]
    out = np.empty_like(positions)
    for j, (b, a, preview) in enumerate(filters):
        ahead = positions[np.minimum(np.arange(K) + preview, K - 1), j]
        zi = signal.lfilter_zi(b, a) * ahead[0]
        out[:, j] = signal.lfilter(b, a, ahead, zi=zi)[0]
    return out


def path_force_feedforward(force, samples: np.ndarray, dt: float, delay) -> np.ndarray:
    """The input (K, 2) that cancels a process force along the path, ``F_j v_j / |v|`` per axis with ``F`` (2,)
    the identified force in input units (:func:`vcnc_baselines.commissioning.identify.friction_levels`: a cutting
    force against the path's motion shares itself among the axes as the motion does), ``v`` the reference
    velocity, read ahead as :func:`inverse_feedforward` reads it (``delay`` (2,) s); zero where the reference
    stands still (below a thousandth of its peak speed)."""
    v = samples[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
    speed = np.hypot(v[:, 0], v[:, 1])
    floor = 1e-3 * max(float(speed.max()), 1e-12)
    share = np.where(speed[:, None] > floor, v / np.maximum(speed, floor)[:, None], 0.0)
    u = share * np.asarray(force, dtype=np.float64)
    return _at(u, 0.5 + np.asarray(delay, dtype=np.float64) / dt)
