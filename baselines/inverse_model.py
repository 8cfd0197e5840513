"""The nominal inverse model along a motion: the input that makes the nominal axes follow the reference.

Computed once, from the env's reference samples (``x_d``, ``v_d``, ``a_d`` per control period; jerk and snap by
central differences of ``a_d``) and the plant's *nominal* :class:`~vcnc_gym.plants.contract.InverseDynamics`:

- :func:`inverse_feedforward`: the input that makes the nominal model follow the reference,
  ``u_ff[k] = sum_n c_n x_d^(n)`` evaluated at ``t_k + dt/2 + T_d`` (the middle of the zero-order-hold
  period the input is held over, plus the dead time), with the Coulomb friction of the direction of motion
  and the Stribeck curve at the reference's speed (where the inverse has one) switched at the reference's
  velocity reversals and the drive moved across the backlash gap there, both
  over a short zero-phase transition (``friction_time``, ``backlash_time``);
- :func:`linear_inverse`: the linear part applied to any sampled motion (the oracle's learning update);
- :func:`path_force_feedforward`: the input that cancels a process force along the path.

The feedforward controllers (:mod:`vcnc_baselines.feedforward`) and the commissioning's identification run
(:mod:`vcnc_baselines.commissioning.identify`, whose axes follow the reference during the experiment) both use it;
it imports neither.
"""

from __future__ import annotations

import numpy as np

from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.plants.contract import INVERSE_ORDER, InverseDynamics

__all__ = ["reference_motion", "smooth_sign", "inverse_feedforward", "linear_inverse", "path_force_feedforward"]


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
