"""Feedforward tables: the plant's inverse dynamics, and ZPETC's modified reference, computed from the reference.

Both are computed once, when a controller is built, from the env's reference samples and the plant's *nominal*
:class:`~vcnc_gym.plants.contract.InverseDynamics`:

- :func:`~vcnc_baselines.inverse_model.inverse_feedforward`: the input that makes the nominal model follow the
  reference (:mod:`vcnc_baselines.inverse_model`, which the commissioning's identification run uses too; imported
  here with :func:`~vcnc_baselines.inverse_model.linear_inverse` and
  :func:`~vcnc_baselines.inverse_model.path_force_feedforward`);
- :func:`zpetc_reference`: Tomizuka (1987)'s zero-phase-error tracking controller of a discretised closed
  loop ``G_c(z^-1) = z^-d B_a B_u / A``: ``r(k) = A B_u* / (B_a B_u(1)^2) x_d(k + d + s)``, ``B_u`` the
  closed loop's unacceptable zeros (:func:`split_zeros`), ``B_u*`` its coefficients reversed.
"""

from __future__ import annotations

import control
import numpy as np
from scipy import signal

from vcnc_gym.plants.contract import InverseDynamics

from ..inverse_model import (
    inverse_feedforward,
    linear_inverse,
    path_force_feedforward,
    reference_motion,
    smooth_sign,
)

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
