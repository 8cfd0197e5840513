"""Matplotlib views of a contouring episode: the path and the contour error."""

from __future__ import annotations

import numpy as np


def render_contouring(env):
    """Draw reference and actual contour, and contour error over time.

    Returns an RGB array (H, W, 3) for ``render_mode="rgb_array"``; shows the
    figure in a window for ``"human"``.  Errors are drawn in um.
    """
    import matplotlib

    if env.render_mode == "rgb_array":
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if env._figure is None:
        env._figure, _ = plt.subplots(1, 2, figsize=(10, 4.5), dpi=80)
    fig = env._figure
    ax_path, ax_err = fig.axes
    ax_path.clear()
    ax_err.clear()
    ref = env.reference.position
    ax_path.plot(ref[:, 0], ref[:, 1], color="0.6", lw=2.5, label="reference")
    hist = env._history or {"t": [], "position": [], "contour_error": []}
    if hist["position"]:
        pos = np.asarray(hist["position"])
        ax_path.plot(pos[:, 0], pos[:, 1], color="C3", lw=1.0, label="actual")
    ax_path.set_xlabel("x [mm]")
    ax_path.set_ylabel("y [mm]")
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.legend(loc="best", fontsize=8)
    ax_path.set_title(f"{env.contour_name}: path")
    ax_err.plot(np.asarray(hist["t"]), 1e3 * np.asarray(hist["contour_error"]), color="C3", lw=1.0)
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("contour error [um]")
    ax_err.set_xlim(0.0, env.task.end_index * env.dt)
    ax_err.set_title("contour error")
    fig.tight_layout()
    if env.render_mode == "human":
        plt.pause(0.001)
        return None
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()  # pyright: ignore[reportAttributeAccessIssue]  (the Agg canvas)
