"""Interval polynomials: Kharitonov's four polynomials, a Routh-Hurwitz test, the stability margin.

An interval polynomial (Yadav et al. (2020), eq. (3))

.. math::

    P(s) = a_0 s^n + a_1 s^{n-1} + \\dots + a_n, \\qquad \\alpha_i \\le a_i \\le \\beta_i,

has every member Hurwitz (all roots in the open left half plane) if and only
if its four Kharitonov polynomials are (Kharitonov, 1978; Yadav et al. (2020), eq. (4)),
provided the leading coefficient cannot vanish.  For n = 3 with positive
coefficients the Routh criterion of one of them, ``p_3``, decides, and Yadav
et al. (after Hote et al., their ref. [14]) call the slack of that criterion the
stability margin, eq. (5):

.. math:: SM = \\alpha_1 \\alpha_2 - \\beta_0 \\beta_3 .

Coefficient arrays are in descending powers of s (``numpy.roots`` order),
index ``i`` is the coefficient of ``s^(n - i)`` as in eq. (3).

Example
-------
The robust PI loop of Yadav et al. (2020), eq. (17): ``s^3 + a s^2 + b K_P s + b K_I``
with ``a >= 7.5``, ``3 <= b <= 6``:

>>> import numpy as np
>>> alpha = np.array([1.0, 7.5, 3 * 38.33, 3 * 45.65])
>>> beta = np.array([1.0, 11.9, 6 * 38.33, 6 * 45.65])
>>> round(stability_margin(alpha, beta), 1)
588.5
>>> robustly_stable(alpha, beta)
True
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "interval_polynomial",
    "kharitonov_polynomials",
    "routh_first_column",
    "hurwitz",
    "robustly_stable",
    "stability_margin",
]

#: Which bound each Kharitonov polynomial takes at coefficient index i (mod 4),
#: Yadav et al. (2020), eq. (4): False = lower (alpha), True = upper (beta).
_PATTERNS = (
    (False, False, True, True),  # p1 = alpha_0 s^n + alpha_1 s^(n-1) + beta_2 s^(n-2) + beta_3 ...
    (False, True, True, False),  # p2 = alpha_0, beta_1, beta_2, alpha_3, ...
    (True, False, False, True),  # p3 = beta_0, alpha_1, alpha_2, beta_3, ...
    (True, True, False, False),  # p4 = beta_0, beta_1, alpha_2, alpha_3, ...
)


def _bounds(alpha, beta) -> tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(alpha, dtype=np.float64)
    hi = np.asarray(beta, dtype=np.float64)
    if lo.ndim != 1 or lo.shape != hi.shape or lo.size < 2:
        raise ValueError(
            f"alpha and beta must be 1-D coefficient arrays of the same length >= 2, "
            f"got shapes {lo.shape} and {hi.shape}"
        )
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError("alpha and beta must be finite")
    if np.any(lo > hi):
        raise ValueError(
            f"every interval needs alpha_i <= beta_i; violated at indices {np.nonzero(lo > hi)[0].tolist()}"
        )
    return lo, hi


def interval_polynomial(polynomials) -> tuple[np.ndarray, np.ndarray]:
    """The coefficient intervals of a family of polynomials of one degree.

    Parameters
    ----------
    polynomials : array_like, (m, n + 1)
        m polynomials, descending powers of s.  When the coefficients are
        affine in the uncertain parameters, the polynomials at the vertices
        of the parameter box give the exact intervals.

    Returns
    -------
    alpha, beta : numpy.ndarray, (n + 1,)
        Elementwise minimum and maximum.
    """
    p = np.asarray(polynomials, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] < 1 or p.shape[1] < 2:
        raise ValueError(f"polynomials must be an (m, n + 1) array with n >= 1, got shape {p.shape}")
    return p.min(axis=0), p.max(axis=0)


def kharitonov_polynomials(alpha, beta) -> np.ndarray:
    """The four Kharitonov polynomials of Yadav et al. (2020), eq. (4).

    Parameters
    ----------
    alpha, beta : array_like, (n + 1,)
        Lower and upper bounds of the coefficients, descending powers of s.

    Returns
    -------
    numpy.ndarray, (4, n + 1)
        Rows ``p_1 .. p_4`` in descending powers of s.
    """
    lo, hi = _bounds(alpha, beta)
    index = np.arange(lo.size) % 4
    return np.array([np.where(np.array(pattern)[index], hi, lo) for pattern in _PATTERNS])


def routh_first_column(poly) -> np.ndarray:
    """First column of the Routh array of a polynomial (descending powers of s).

    Returns the ``n + 1`` entries, or fewer when a zero appears in the
    first column (the array cannot go on: the polynomial is not Hurwitz).
    """
    c = np.trim_zeros(np.asarray(poly, dtype=np.float64), "f")
    if c.size == 0 or not np.all(np.isfinite(c)):
        raise ValueError(f"poly must be a finite, non-zero coefficient array, got {poly!r}")
    n = c.size - 1
    width = n // 2 + 1
    upper = np.zeros(width + 1)
    lower = np.zeros(width + 1)
    upper[: c[0::2].size] = c[0::2]
    lower[: c[1::2].size] = c[1::2]
    column = [upper[0]]
    for _ in range(n):
        column.append(lower[0])
        if lower[0] == 0.0:
            break
        nxt = np.zeros_like(upper)
        nxt[:-1] = (lower[0] * upper[1:] - upper[0] * lower[1:]) / lower[0]
        upper, lower = lower, nxt
    return np.array(column)


def hurwitz(poly) -> bool:
    """True if every root of ``poly`` (descending powers of s) has a negative real part.

    By the Routh criterion: all ``n + 1`` entries of the first column of the
    Routh array are non-zero and of one sign.
    """
    column = routh_first_column(poly)
    n = np.trim_zeros(np.asarray(poly, dtype=np.float64), "f").size - 1
    return column.size == n + 1 and bool(np.all(column > 0.0) or np.all(column < 0.0))


def robustly_stable(alpha, beta) -> bool:
    """Kharitonov's test: every polynomial with ``alpha_i <= a_i <= beta_i`` is Hurwitz.

    Raises
    ------
    ValueError
        If the leading coefficient's interval contains zero (the degree could
        drop, and the theorem does not apply).
    """
    lo, hi = _bounds(alpha, beta)
    if lo[0] <= 0.0 <= hi[0]:
        raise ValueError(f"the leading coefficient's interval [{lo[0]}, {hi[0]}] contains 0")
    return all(hurwitz(p) for p in kharitonov_polynomials(lo, hi))


def stability_margin(alpha, beta) -> float:
    """Stability margin of a third-order interval polynomial, Yadav et al. (2020), eq. (5).

    ``SM = alpha_1 alpha_2 - beta_0 beta_3``: the Routh condition
    ``a_1 a_2 > a_0 a_3`` at its worst corner (Kharitonov's ``p_3``).  For
    coefficients that are all positive (``alpha_i > 0``), the family is
    robustly stable if and only if ``SM > 0``.

    Raises
    ------
    ValueError
        If the polynomial is not of degree 3, or a lower bound is not
        positive (eq. (5) presumes positive coefficients).
    """
    lo, hi = _bounds(alpha, beta)
    if lo.size != 4:
        raise ValueError(
            f"the stability margin of eq. (5) is defined for third-order polynomials "
            f"(4 coefficients), got {lo.size} coefficients"
        )
    if np.any(lo <= 0.0):
        raise ValueError(f"eq. (5) presumes positive coefficients; alpha = {lo.tolist()}")
    return float(lo[1] * lo[2] - hi[0] * hi[3])
