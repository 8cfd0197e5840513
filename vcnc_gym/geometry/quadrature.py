"""Arc length of a parametric curve from its speed ``|C'(u)|``: adaptive Gauss-Legendre quadrature, vectorised.

The one arc-length integrator of the Python side, for every curve that can give its speed at an array of
parameters: :meth:`vcnc_gym.geometry.nurbs.NurbsCurve.arc_length` and
:func:`vcnc_gym.geometry.corners.bezier_arc_length` (Simba et al.'s eq. (21)) both call :func:`arc_length`.
The compiled kernels' arc length (the interpolator's, the look-ahead feed's) is
:func:`vcnc_gym.geometry.arclength.arc_between`: the same integral inside a numba loop, with an absolute tolerance.

Every interval between two breaks is cut in ``pieces`` equal pieces; a piece's ``nodes``-point Gauss-Legendre
value is compared with the sum over its two halves and the piece is bisected again until they agree to 1e-12
relative, or to the length of 4 floating-point steps of u (all a piece narrow for its ``|u|`` resolves).  A fixed rule
is not enough for curves whose speed is sharply peaked (large NURBS weight ratios, short spans): it was off by up to
~1e-4 relative on random rational curves.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["arc_length"]

_RULES: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _rule(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``nodes``-point Gauss-Legendre nodes and weights on [-1, 1] (numpy's ``leggauss``), computed once."""
    if nodes not in _RULES:
        _RULES[nodes] = np.polynomial.legendre.leggauss(nodes)
    return _RULES[nodes]


def arc_length(
    speed: Callable[[np.ndarray], np.ndarray],
    breaks: np.ndarray,
    *,
    pieces: int = 8,
    nodes: int = 16,
    max_bisections: int = 40,
) -> float:
    """The integral of ``speed`` from ``breaks[0]`` to ``breaks[-1]``: an arc length in mm.

    Parameters
    ----------
    speed : callable
        ``|C'(u)|`` (mm per unit of u) at a 1-D array of parameters, as an array of the same length.  A node never
        lands on an interval's right end (it is moved one float below it): at a break the curve's one-sided
        derivative on the right is the one taken, as a knot evaluates on its right span.
    breaks : array
        Ascending, distinct parameters where the speed may jump (knots, the ends); the integral is cut there.
    pieces : int
        Equal pieces per interval to start from.
    nodes : int
        Points of the Gauss-Legendre rule.
    max_bisections : int
        Levels of bisection after which the pieces still open are summed as they are.
    """
    x, w = _rule(nodes)
    breaks = np.asarray(breaks, dtype=np.float64)
    edges = np.concatenate(
        [np.linspace(s, e, pieces + 1)[:-1] for s, e in zip(breaks[:-1], breaks[1:])] + [breaks[-1:]]
    )

    def gauss(lo_e, hi_e):
        """Rule values of the pieces, and their resolution: the length of 4 floating-point steps of u."""
        half = 0.5 * (hi_e - lo_e)
        us = half[:, None] * x + 0.5 * (hi_e + lo_e)[:, None]
        us = np.minimum(us, np.nextafter(hi_e, lo_e)[:, None])  # a break evaluates on its right
        v = np.asarray(speed(us.reshape(-1)), dtype=np.float64).reshape(-1, x.size)
        resolution = 4.0 * np.max(v, axis=1) * np.spacing(np.maximum(np.abs(lo_e), np.abs(hi_e)))
        return half * (v @ w), resolution

    lo_e, hi_e = edges[:-1], edges[1:]
    whole, _ = gauss(lo_e, hi_e)
    total = 0.0
    for _ in range(max_bisections):
        if lo_e.size == 0:
            break
        mid = 0.5 * (lo_e + hi_e)
        left, res_left = gauss(lo_e, mid)
        right, res_right = gauss(mid, hi_e)
        halves = left + right
        # the rounding of the nodes to floats limits what a narrow piece can resolve
        done = np.abs(halves - whole) <= 1e-12 * np.abs(halves) + 1e-15 + res_left + res_right
        total += float(np.sum(halves[done]))
        keep = ~done
        lo_e = np.concatenate([lo_e[keep], mid[keep]])
        hi_e = np.concatenate([mid[keep], hi_e[keep]])
        whole = np.concatenate([left[keep], right[keep]])
    return total + float(np.sum(whole))
