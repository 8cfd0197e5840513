"""Exact zero-order-hold solutions of first-order motion, shared by every plant.

Every plant of the suite moves, between events (a stop, a break-away), by ``w' = alpha - a w`` with the input
(and so ``alpha``) held over the step: Jahanpour et al.'s drive (``w`` the motor speed), Simba et al.'s (the
table velocity, ``a = c / m``), Yadav et al.'s axis and Purtojo et al.'s table.  :func:`first_order` is its
exact solution over a step, :func:`log1p_ratio` and :func:`log1p_rest` the time and travel to a stop of the
same ODE; all accurate where the naive formulas cancel (``a h`` small, short stops).
"""

from __future__ import annotations

import math

import numba

__all__ = ["phi1", "phi2", "log1p_ratio", "log1p_rest", "first_order"]


@numba.njit(cache=True)
def phi1(z):
    """(e^z - 1) / z, = 1 at z = 0."""
    if z == 0.0:
        return 1.0
    return math.expm1(z) / z


@numba.njit(cache=True)
def phi2(z):
    """(e^z - 1 - z) / z^2, accurate for small ``|z|``."""
    if abs(z) < 0.1:
        # Taylor series: sum_k z^k / (k + 2)!
        return 1.0 / 2.0 + z * (
            1.0 / 6.0
            + z
            * (
                1.0 / 24.0
                + z
                * (
                    1.0 / 120.0
                    + z
                    * (1.0 / 720.0 + z * (1.0 / 5040.0 + z * (1.0 / 40320.0 + z * (1.0 / 362880.0 + z / 3628800.0))))
                )
            )
        )
    return (math.expm1(z) - z) / (z * z)


@numba.njit(cache=True)
def log1p_ratio(x):
    """log(1 + x) / x for x >= 0, = 1 at x = 0."""
    if x == 0.0:
        return 1.0
    return math.log1p(x) / x


@numba.njit(cache=True)
def log1p_rest(x):
    """(x - log(1 + x)) / x^2 for x >= 0, accurate for small x."""
    if x < 0.01:
        # sum_k (-1)^k x^k / (k + 2)
        return 0.5 + x * (
            -1.0 / 3.0 + x * (0.25 + x * (-0.2 + x * (1.0 / 6.0 + x * (-1.0 / 7.0 + x * (0.125 + x * (-1.0 / 9.0))))))
        )
    return (x - math.log1p(x)) / (x * x)


@numba.njit(cache=True)
def first_order(a, h):
    """Exact coefficients of the first-order ODE ``w' = alpha - a w`` over a time ``h`` with ``alpha`` held.

    ``w(h) = E w0 + g alpha`` and ``int_0^h w = g w0 + q alpha``: ``E = exp(-a h)``, ``g = (1 - E) / a``,
    ``q = (h - g) / a``, through :func:`phi1` and :func:`phi2` (exact as ``a h -> 0``, and for ``a = 0``).
    """
    z = -a * h
    e = math.exp(z)
    g = h * phi1(z)
    q = h * h * phi2(z)
    return e, g, q
