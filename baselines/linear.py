"""Continuous designs, discretised once, stepped by a small numba kernel.

A linear controller is written down once as a continuous transfer function
(python-control), discretised with :func:`control.c2d` at the period at which
the policy is called, and run as the state-space recursion

.. math:: y_k = C x_k + D u_k, \\qquad x_{k+1} = A x_k + B u_k

for a batch of independent channels.  No difference equation is derived by
hand.
"""

from __future__ import annotations

import control
import numpy as np
from numba import njit

__all__ = ["discretize", "DiscreteLTI", "lti_step", "lti_response"]


def discretize(sys, dt: float, method: str = "tustin") -> control.StateSpace:
    """Discrete state-space model of a continuous system.

    Parameters
    ----------
    sys : control.TransferFunction or control.StateSpace
        Continuous-time system (time in s).
    dt : float
        Sampling period in s.
    method : str
        Any method of :func:`control.c2d`; ``'tustin'`` (bilinear, the
        default for controllers) or ``'zoh'`` (for plants driven by a
        sample-and-hold).

    Returns
    -------
    control.StateSpace
        Discrete system with ``sys.dt == dt``.
    """
    ss = control.ss(sys)
    return control.c2d(ss, dt, method=method)


@njit(cache=True, _nrt=False)
def _row(M, N, r, x, u):
    """Row ``r`` of M x + N u, summed in that order."""
    acc = 0.0
    for c in range(x.shape[0]):
        acc += M[r, c] * x[c]
    for c in range(u.shape[0]):
        acc += N[r, c] * u[c]
    return acc


@njit(cache=True, _nrt=False)
def lti_advance(A, B, C, D, x, u, y, xn):
    """One step of one copy of a discrete LTI system: y = C x + D u, then x <- A x + B u.

    ``x`` (nx,) is advanced in place, ``u`` (nu,) is the input, ``y`` (ny,) is
    written, ``xn`` (nx,) is scratch.  Allocates nothing, so the step kernel
    can run it (a compiled controller, :mod:`vcnc_gym.envs.controller_contract`).
    """
    for r in range(y.shape[0]):
        y[r] = _row(C, D, r, x, u)
    for r in range(x.shape[0]):
        xn[r] = _row(A, B, r, x, u)
    for r in range(x.shape[0]):
        x[r] = xn[r]


@njit(cache=True)
def lti_step(A, B, C, D, x, u, y):
    """One step of ``n`` independent copies of a discrete LTI system (:func:`lti_advance` for each).

    Parameters
    ----------
    A, B, C, D : ndarray, (nx, nx), (nx, nu), (ny, nx), (ny, nu)
        Discrete state-space matrices.
    x : ndarray, (n, nx)
        States, advanced in place to x_{k+1}.
    u : ndarray, (n, nu)
        Inputs u_k.
    y : ndarray, (n, ny)
        Outputs y_k, written in place.
    """
    xn = np.empty(x.shape[1])
    for i in range(x.shape[0]):
        lti_advance(A, B, C, D, x[i], u[i], y[i], xn)


@njit(cache=True)
def lti_response(A, B, C, D, u):
    """The response ``y`` (n, ny) of a discrete LTI system from rest to the input sequence ``u`` (n, nu): the
    recursion of :func:`lti_advance`, in C (python-control's ``forced_response`` steps it in Python, 11 us a
    sample)."""
    x = np.zeros(A.shape[0])
    xn = np.empty(A.shape[0])
    y = np.empty((u.shape[0], C.shape[0]))
    for k in range(u.shape[0]):
        lti_advance(A, B, C, D, x, u[k], y[k], xn)
    return y


class DiscreteLTI:
    """The matrices of a discrete state-space system, ready for :func:`lti_step`.

    Parameters
    ----------
    sys : control.StateSpace
        A discrete system (``sys.dt > 0``).
    """

    def __init__(self, sys: control.StateSpace):
        if not sys.isdtime(strict=True):
            raise ValueError("DiscreteLTI needs a discrete-time system")
        self.sys = sys
        self.dt = float(sys.dt)
        self.A = np.ascontiguousarray(sys.A, dtype=float)
        self.B = np.ascontiguousarray(sys.B, dtype=float)
        self.C = np.ascontiguousarray(sys.C, dtype=float)
        self.D = np.ascontiguousarray(sys.D, dtype=float)
        self.nx, self.nu = self.B.shape
        self.ny = self.C.shape[0]

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Outputs y_k for inputs u (n, nu); advances the states x (n, nx) in place."""
        y = np.empty((u.shape[0], self.ny))
        lti_step(self.A, self.B, self.C, self.D, x, np.ascontiguousarray(u, dtype=float), y)
        return y
