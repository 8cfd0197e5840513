"""ISO 230-4 circular test figures from a measured path.

ISO 230-4:2005 (Test code for machine tools - Part 4: Circular tests for
numerically controlled machine tools), section 3, defines on the actual path
recorded over 360 degrees of a programmed circle:

- **circular deviation G**: the minimum radial separation of two concentric
  circles enveloping the actual path, their centre being the least-squares
  circle's (LSC) centre of the path (clause 3.4; the standard allows the LSC
  or the minimum-zone centre, we use the LSC);
- **bidirectional circular deviation G(b)**: the same for the clockwise and
  the counter-clockwise paths together (clause 3.5);
- **radial deviation F**: the deviation of the actual path from the nominal
  circle, centred on the nominal centre, max F_max (outwards, > 0) and min
  F_min (inwards, < 0) (clause 3.6).

The least-squares circle minimises sum (``|p_i - c|`` - r)^2: Gauss-Newton from
the algebraic (Kasa 1976) fit, to 1e-15 relative.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CircularFigures", "circular_figures", "least_squares_circle"]


def least_squares_circle(points) -> tuple[np.ndarray, float]:
    """Centre (2,) and radius of the geometric least-squares circle through ``points`` (n, 2), mm."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
        raise ValueError(f"points must be (n >= 3, 2) in mm, got shape {p.shape}")
    # Kasa: x^2 + y^2 = 2 a x + 2 b y + c, linear least squares
    a = np.column_stack([2 * p[:, 0], 2 * p[:, 1], np.ones(len(p))])
    sol, *_ = np.linalg.lstsq(a, np.sum(p * p, axis=1), rcond=None)
    c = sol[:2]
    for _ in range(50):  # Gauss-Newton on the radial residuals |p - c| - r, unknowns (c, r)
        d = p - c
        rho = np.hypot(d[:, 0], d[:, 1])
        r = float(np.mean(rho))
        jac = np.column_stack([-d / rho[:, None], -np.ones(len(p))])
        step, *_ = np.linalg.lstsq(jac, -(rho - r), rcond=None)
        c = c + step[:2]
        if np.max(np.abs(step[:2])) <= 1e-15 * max(1.0, r):
            break
    d = p - c
    return c, float(np.mean(np.hypot(d[:, 0], d[:, 1])))


@dataclass(frozen=True)
class CircularFigures:
    """ISO 230-4 figures of one direction (or both), um.

    Attributes
    ----------
    circular_deviation_um : float
        G (or G(b) for both directions), about the least-squares centre.
    radial_deviation_max_um, radial_deviation_min_um : float
        F_max and F_min about the nominal centre and radius.
    centre_offset_um : (2,) array
        Least-squares centre minus the nominal centre.
    points : int
        Samples evaluated.
    """

    circular_deviation_um: float
    radial_deviation_max_um: float
    radial_deviation_min_um: float
    centre_offset_um: np.ndarray
    points: int


def circular_figures(points, centre, radius: float) -> CircularFigures:
    """ISO 230-4's G and F of a measured path ``points`` (n, 2) around the nominal ``centre`` and ``radius``, mm."""
    p = np.asarray(points, dtype=np.float64)
    c0 = np.asarray(centre, dtype=np.float64)
    lsc, _ = least_squares_circle(p)
    rho = np.hypot(*(p - lsc).T)
    nominal = np.hypot(*(p - c0).T) - radius
    return CircularFigures(
        circular_deviation_um=1e3 * float(np.max(rho) - np.min(rho)),
        radial_deviation_max_um=1e3 * float(np.max(nominal)),
        radial_deviation_min_um=1e3 * float(np.min(nominal)),
        centre_offset_um=1e3 * (lsc - c0),
        points=len(p),
    )
