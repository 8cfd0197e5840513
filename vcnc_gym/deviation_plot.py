"""The deviation from the contour magnified along its normal, as a ballbar's polar plot draws it.

Micrometre errors on a 100 mm path are invisible at the path's scale: every
controller lies on the reference.  A ballbar's polar plot (ISO 230-4, Annex
A; Renishaw's QC20) draws the radial deviation magnified about the nominal
circle.  :func:`plot_deviation` does that for any contour: at each sample the
tool's closest point c(u) on the contour (the env's exact projector), the
contour's unit normal n(u) (the tangent turned left) and the signed deviation
e = (p - c) . n (> 0 on the left of the direction of travel), drawn at
c + M e n with a magnification M from the 1-2-5 series chosen so that the
largest deviation shown is about 6 % of the contour's extent; M and the
deviation one millimetre of the drawing stands for are on the axis label.

Insets: one per corner of the contour (every local maximum of the reference's
packed curvature above ``CORNER_CURVATURE``, and on a G-code program every
joint where the tangent turns), up to ``MAX_INSETS``, each showing the true
(unmagnified) path near the corner in a window four times the largest
deviation there (at least 20 um wide), ticks in um from the corner.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

__all__ = ["CORNER_CURVATURE", "MAX_INSETS", "contour_corners", "magnification", "plot_deviation", "signed_deviation"]

#: A local maximum of ``|curvature|`` above this (1/mm, a radius of 2 mm) is a corner.
CORNER_CURVATURE = 0.5
#: Most insets drawn.
MAX_INSETS = 8


def signed_deviation(env, positions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(foot points (k, 2), unit normals (k, 2), signed deviation (k,) mm) of tool ``positions`` (k, 2)."""
    u_env = env.unwrapped
    p = np.asarray(positions, dtype=np.float64)
    _, u = u_env.projector.track(p)
    der = u_env.curve.derivatives_array(u, 1)
    feet, tangent = der[:, 0], der[:, 1]
    tangent = tangent / np.hypot(tangent[:, 0], tangent[:, 1])[:, None]
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    return feet, normal, np.sum((p - feet) * normal, axis=1)


def magnification(max_deviation: float, extent: float, share: float = 0.06) -> float:
    """The 1-2-5 magnification that draws ``max_deviation`` (mm) at most ``share`` of ``extent`` (mm)."""
    if not max_deviation > 0:
        return 1.0
    target = share * extent / max_deviation
    exp = math.floor(math.log10(target))
    for m in (5, 2, 1):
        if m * 10**exp <= target:
            return float(m * 10**exp)
    return float(10**exp)


def contour_corners(env) -> list[np.ndarray]:
    """Corner points (mm) of the env's contour (module docstring), sharpest first."""
    from .envs import step_kernel as sk

    u_env = env.unwrapped
    path = getattr(u_env.task, "path", None)
    joints = getattr(path, "joints", None)
    if path is not None and joints is not None:
        ends = [m.end for m in path.program.moves[:-1]]
        order = sorted(range(len(joints)), key=lambda i: -joints[i].angle)
        return [np.asarray(ends[i]) for i in order if joints[i].kind != "tangent"][:MAX_INSETS]
    samples = u_env.task.reference_arrays.samples
    pts = samples[:, sk.REF_POSITION : sk.REF_POSITION + 2]
    kappa = np.abs(samples[:, sk.REF_CURVATURE])
    inner = np.arange(1, len(kappa) - 1)
    peaks = inner[
        (kappa[inner] > CORNER_CURVATURE) & (kappa[inner] >= kappa[inner - 1]) & (kappa[inner] > kappa[inner + 1])
    ]
    corners: list[np.ndarray] = []
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    for i in peaks[np.argsort(-kappa[peaks])]:
        if all(np.hypot(*(pts[i] - q)) > 0.02 * diag for q in corners):
            corners.append(pts[i].copy())
        if len(corners) == MAX_INSETS:
            break
    return corners


def _curve_near(u_env, point, radius: float) -> list[np.ndarray]:
    """The contour within ``radius`` mm of ``point``, densely sampled (2000 points per pass near it): the
    reference samples near the point give the parameter ranges."""
    from .envs import step_kernel as sk

    samples = u_env.task.reference_arrays.samples
    near = np.flatnonzero(np.hypot(*(samples[:, sk.REF_POSITION : sk.REF_POSITION + 2] - point).T) < radius)
    if not near.size:
        return []
    runs = np.split(near, np.flatnonzero(np.diff(near) > 1) + 1)
    lo_u, hi_u = u_env.curve.u_range
    out = []
    for run in runs:
        a = samples[max(run[0] - 1, 0), sk.REF_U]
        b = samples[min(run[-1] + 1, len(samples) - 1), sk.REF_U]
        out.append(u_env.curve.points(np.linspace(max(a, lo_u), min(b, hi_u), 2000)))
    return out


def plot_deviation(results_by_policy: Mapping, env, path, *, title: str | None = None):
    """The magnified deviation of every policy along ``env``'s contour, with an inset at every corner.

    Parameters
    ----------
    results_by_policy : mapping of str to EpisodeResult
    env : gymnasium.Env
        The contouring env the episodes ran on.
    path : str or Path
        The PNG to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    u_env = env.unwrapped
    curve = u_env.curve
    lo, hi = curve.u_range
    ref = curve.points(np.linspace(lo, hi, 4001))
    extent = float(np.max(ref.max(axis=0) - ref.min(axis=0)))
    drawn = {}
    largest = 0.0
    for label, res in results_by_policy.items():
        p = res.position[np.all(np.isfinite(res.position), axis=1)]
        if len(p) < 2:
            continue
        feet, normal, e = signed_deviation(env, p)
        drawn[label] = (p, feet, normal, e)
        largest = max(largest, float(np.max(np.abs(e))))
    m = magnification(largest, extent)
    corners = contour_corners(env)
    cols = min(4, max(1, len(corners)))
    rows = math.ceil(len(corners) / cols) if corners else 0
    fig = plt.figure(figsize=(4.0 * max(cols, 2) + 6.0, max(6.0, 3.2 * rows)))
    grid = fig.add_gridspec(max(rows, 1), max(cols, 1) + 2)
    ax = fig.add_subplot(grid[:, :2])
    ax.plot(ref[:, 0], ref[:, 1], color="0.6", lw=1.0, label="contour")
    for i, (label, (p, feet, normal, e)) in enumerate(drawn.items()):
        shown = feet + (m * e)[:, None] * normal
        ax.plot(
            shown[:, 0],
            shown[:, 1],
            lw=0.8,
            color=f"C{i % 10}",
            label=f"{label} (max {1e3 * np.max(np.abs(e)):.1f} µm)",
        )
    for k, c in enumerate(corners):
        ax.annotate(chr(ord("a") + k), (c[0], c[1]), fontsize=8, color="k")
    ax.set_aspect("equal")
    ax.set_xlabel(f"x (mm); deviation drawn x{m:g} along the normal: 1 mm of the drawing = {1e3 / m:.3g} µm")
    ax.set_ylabel("y (mm)")
    ax.set_title(title or f"{getattr(u_env, 'contour_name', 'contour')}: deviation from the contour x{m:g}")
    ax.legend(fontsize=7, loc="best")
    for k, c in enumerate(corners):
        ins = fig.add_subplot(grid[k // cols, 2 + k % cols])
        near = 0.0
        for p, feet, normal, e in drawn.values():
            close = np.hypot(*(p - c).T) < 3.0
            if close.any():
                near = max(near, float(np.max(np.abs(e[close]))))
        half = max(4.0 * near, 0.01)
        for piece in _curve_near(u_env, c, 3.0 * half):
            ins.plot(1e3 * (piece[:, 0] - c[0]), 1e3 * (piece[:, 1] - c[1]), color="0.6", lw=2.0)
        for i, (p, *_rest) in enumerate(drawn.values()):
            sel = np.hypot(*(p - c).T) < 2 * half * 1.5
            ins.plot(1e3 * (p[sel, 0] - c[0]), 1e3 * (p[sel, 1] - c[1]), lw=0.8, color=f"C{i % 10}")
        ins.set_xlim(-1e3 * half, 1e3 * half)
        ins.set_ylim(-1e3 * half, 1e3 * half)
        ins.set_aspect("equal")
        ins.tick_params(labelsize=6)
        ins.set_title(f"{chr(ord('a') + k)}: ({c[0]:.2f}, {c[1]:.2f}) mm, µm from it, x1", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return m
