"""Run one contouring episode with any SB3-style policy, and plot the results.

A policy is anything with Stable-Baselines3's ``predict(observation,
state=None, episode_start=None, deterministic=True) -> (action, state)``: a
classical controller of the ``vcnc_baselines`` package or a trained SB3 agent.
:func:`run_episode` drives it through one pass along the contour and keeps
the traces a person would plot; :func:`plot_contours` and
:func:`plot_contour_errors` draw them for several policies on one env.

Units: mm, s in the traces (as in the env); the summary metrics and the plots
are in um, and say so in their names and labels.

Example
-------
>>> import gymnasium as gym, vcnc_gym, vcnc_baselines
>>> from vcnc_gym.evaluation import run_episode
>>> env = gym.make("VCNC-Omega-v1")
>>> result = run_episode(vcnc_baselines.make("qft", env), env)   # doctest: +SKIP
>>> result.max_contour_error_um                             # doctest: +SKIP
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

__all__ = [
    "EpisodeResult",
    "run_episode",
    "sharp_corners",
    "plot_contours",
    "plot_contour_errors",
    "plot_trials",
]


@dataclass
class EpisodeResult:
    """One episode of one policy: summary metrics and per-step traces.

    Attributes
    ----------
    max_contour_error_um, mean_contour_error_um, rms_contour_error_um : float
        Maximum, mean and root-mean-square of the contour error over the
        episode's decision steps, in um.  ``inf`` if the plant diverged to a
        non-finite state.
    episode_steps : int
        Decision steps taken.
    wall_s : float
        Wall-clock time of the episode (reset included), s.
    diverged : bool
        True if the env ended the episode on its divergence bound.
    max_tracking_error_um : float
        Largest distance from the table to the current reference point, um.
        Not a score, a sanity check: a table that never leaves the contour's
        start has zero contour error but a large tracking error.
    terminated, truncated : bool
        How the episode ended (Gymnasium's flags of the last step).
    completed : bool
        True if the episode did its whole task: the env's final
        ``info["completed"]`` where it gives one (a positioning env: the
        step-response window ran out without divergence), else terminated
        and not diverged (a contouring env: the end of the contour reached).
        A contouring episode cut by a time limit is not complete, and its
        metrics cover only the part of the contour it ran.
    cycle_time_s : float
        Time at which the table reached the end of the contour (the env's
        ``info["cycle_time"]``), s; NaN if it did not.
    time : ndarray, (episode_steps,)
        Simulation time after each step, s.
    contour_error : ndarray, (episode_steps,)
        Contour error after each step, mm.
    position, reference_position : ndarray, (episode_steps, 2)
        Table position and reference point after each step, mm.
    command : ndarray, (episode_steps, 2)
        Axis commands applied during each step, V.
    """

    max_contour_error_um: float
    mean_contour_error_um: float
    rms_contour_error_um: float
    episode_steps: int
    wall_s: float
    diverged: bool
    max_tracking_error_um: float
    terminated: bool
    truncated: bool
    completed: bool
    cycle_time_s: float
    time: np.ndarray = field(repr=False)
    contour_error: np.ndarray = field(repr=False)
    position: np.ndarray = field(repr=False)
    reference_position: np.ndarray = field(repr=False)
    command: np.ndarray = field(repr=False)

    def metrics(self) -> dict:
        """The summary as a plain dict (JSON-ready apart from non-finite values)."""
        return {
            "max_contour_error_um": self.max_contour_error_um,
            "mean_contour_error_um": self.mean_contour_error_um,
            "rms_contour_error_um": self.rms_contour_error_um,
            "episode_steps": self.episode_steps,
            "wall_s": self.wall_s,
            "diverged": self.diverged,
            "max_tracking_error_um": self.max_tracking_error_um,
            "completed": self.completed,
            "cycle_time_s": self.cycle_time_s,
        }


def _error_metrics_um(err_mm: np.ndarray) -> tuple[float, float, float]:
    if err_mm.size == 0:
        return math.nan, math.nan, math.nan
    e = 1e3 * err_mm
    return float(np.max(e)), float(np.mean(e)), float(np.sqrt(np.mean(e * e)))


def run_episode(
    policy, env, seed: int | None = 0, *, progress: Callable[[int], object] | None = None, progress_every: int = 1000
) -> EpisodeResult:
    """Run one deterministic episode of ``policy`` on ``env`` and collect the traces.

    Parameters
    ----------
    policy : object
        With SB3's ``predict(observation, state=None, episode_start=None,
        deterministic=True) -> (action, state)``.  It is called once per
        decision step with the single (unbatched) observation,
        ``episode_start=np.array([True])`` on the first call and
        ``np.array([False])`` after, and the returned ``state`` passed back,
        as SB3's ``evaluate_policy`` does.
    env : gymnasium.Env
        A vcnc_gym contouring env, possibly wrapped (``gym.make``).
    seed : int or None
        Passed to ``env.reset``.
    progress : callable, optional
        Called with the number of steps done since its last call, every
        ``progress_every`` steps and at the end (e.g. ``tqdm.update``).
    progress_every : int
        Steps between two ``progress`` calls.

    Returns
    -------
    EpisodeResult
    """
    u = env.unwrapped
    capacity = int(getattr(u, "episode_steps", 0)) or 1024
    t_tr = np.empty(capacity)
    e_tr = np.empty(capacity)
    p_tr = np.empty((capacity, 2))
    r_tr = np.empty((capacity, 2))
    c_tr = np.empty((capacity, 2))

    wall0 = time.perf_counter()
    obs, _ = env.reset(seed=seed)
    if hasattr(policy, "plan"):  # a non-causal floor (baselines' oracle) plans with the plant it now runs on
        policy.plan(env)
    predict = policy.predict
    step = env.step
    state = None
    start = np.array([True])
    not_start = np.array([False])
    n = 0
    reported = 0
    terminated = truncated = diverged = False
    while True:
        action, state = predict(obs, state=state, episode_start=start, deterministic=True)
        start = not_start
        obs, _, terminated, truncated, info = step(action)
        if n == capacity:  # only if a wrapper or a non-default config runs longer than planned
            capacity *= 2
            t_tr, e_tr, p_tr, r_tr, c_tr = (
                np.resize(a, (capacity,) + a.shape[1:]) for a in (t_tr, e_tr, p_tr, r_tr, c_tr)
            )
        t_tr[n] = info["time"]
        e_tr[n] = info["contour_error"]
        p_tr[n] = info["position"]
        r_tr[n] = info["reference_position"]
        c_tr[n] = info["command"]
        n += 1
        if progress is not None and n - reported >= progress_every:
            progress(n - reported)
            reported = n
        if terminated or truncated:
            diverged = bool(info.get("diverged", False))
            completed = bool(info.get("completed", terminated and not diverged))
            cycle_time = float(info.get("cycle_time", math.nan))
            break
    wall = time.perf_counter() - wall0
    if progress is not None and n > reported:
        progress(n - reported)

    e_tr = e_tr[:n]
    mx, mean, rms = _error_metrics_um(e_tr)
    summary = info.get("episode_summary") if n else None
    if summary is not None and "step_contour_error_max" in info and not diverged:
        # a learnable id's decision spans several control periods: its summary holds every period's error, where
        # the trace holds the last period's of each decision
        mx, mean, rms = (1e3 * summary[k] for k in ("contour_error_max", "contour_error_mean", "contour_error_rms"))
    track = np.hypot(r_tr[:n, 0] - p_tr[:n, 0], r_tr[:n, 1] - p_tr[:n, 1])
    max_track = 1e3 * float(np.max(track)) if n else math.nan
    return EpisodeResult(
        max_contour_error_um=mx,
        mean_contour_error_um=mean,
        rms_contour_error_um=rms,
        episode_steps=n,
        wall_s=wall,
        diverged=diverged,
        max_tracking_error_um=max_track,
        terminated=bool(terminated),
        truncated=bool(truncated),
        completed=completed,
        cycle_time_s=cycle_time,
        time=t_tr[:n].copy(),
        contour_error=e_tr.copy(),
        position=p_tr[:n].copy(),
        reference_position=r_tr[:n].copy(),
        command=c_tr[:n].copy(),
    )


# -- geometry for the plots ------------------------------------------------------
def _reference_curvature(env) -> tuple[np.ndarray, np.ndarray]:
    """Points (K, 2) in mm of the reference path and the curve's curvature there, 1/mm (the env's packed
    reference: :func:`vcnc_gym.envs.task.pack_reference`)."""
    from .envs import step_kernel as sk

    samples = env.unwrapped.task.reference_arrays.samples
    return samples[:, sk.REF_POSITION : sk.REF_POSITION + 2], np.abs(samples[:, sk.REF_CURVATURE])


def sharp_corners(env, n: int = 3, min_separation: float = 0.1) -> list[tuple[np.ndarray, float]]:
    """The ``n`` points of largest curvature of the reference contour, well apart.

    Parameters
    ----------
    env : gymnasium.Env
        A vcnc_gym contouring env (its ``unwrapped.reference`` and ``curve``).
    n : int
        How many corners at most.
    min_separation : float
        Smallest distance between two corners, as a fraction of the diagonal
        of the contour's bounding box.

    Returns
    -------
    list of (point, curvature)
        Point (2,) in mm and curvature in 1/mm, sharpest first.
    """
    pts, kappa = _reference_curvature(env)
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    sep = min_separation * diag
    corners: list[tuple[np.ndarray, float]] = []
    for i in np.argsort(kappa)[::-1]:
        if kappa[i] <= 0.0:
            break
        p = pts[i]
        if all(np.hypot(*(p - q)) >= sep for q, _ in corners):
            corners.append((p.copy(), float(kappa[i])))
            if len(corners) == n:
                break
    return corners


def _colors(names):
    return {name: f"C{i % 10}" for i, name in enumerate(names)}


def _finite_path(res: EpisodeResult) -> np.ndarray:
    p = res.position
    return p[np.all(np.isfinite(p), axis=1)]


def _inset_half_width(results_by_policy, corner, radius: float = 3.0) -> float:
    """Half-width in mm of a zoom window at ``corner``: four times the largest contour
    error of any policy within ``radius`` mm of it, clipped to [0.1, 2.5] mm."""
    near = 0.0
    for res in results_by_policy.values():
        d = np.hypot(res.position[:, 0] - corner[0], res.position[:, 1] - corner[1])
        e = res.contour_error[d < radius]
        e = e[np.isfinite(e)]
        if e.size:
            near = max(near, float(e.max()))
    return float(np.clip(4.0 * near, 0.1, 2.5))


def plot_contours(
    results_by_policy: Mapping[str, EpisodeResult], env, path, *, n_insets: int = 3, title: str | None = None
):
    """Actual against reference contour for every policy on one env, with zoomed corners.

    The main panel shows the whole contour; up to ``n_insets`` zoomed insets
    (right of it, linked by :meth:`~matplotlib.axes.Axes.indicate_inset_zoom`)
    show the sharpest corners of the reference (:func:`sharp_corners`), each
    window sized to four times the largest contour error of any policy near
    that corner (between 0.2 mm and 5 mm wide), so that the error is visible.
    Inset ticks are offsets from the corner in um; the reference is the grey
    band with a dashed centre line.

    Parameters
    ----------
    results_by_policy : mapping of str to EpisodeResult
        Policy label -> its episode on ``env``.
    env : gymnasium.Env
        The env the episodes ran on (reference contour, name).
    path : str or path-like
        Where to write the figure (PNG by extension).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FixedLocator, FuncFormatter, MaxNLocator

    u = env.unwrapped
    ref = np.asarray(u.reference.position)
    colors = _colors(list(results_by_policy))
    corners = sharp_corners(env, n=n_insets)

    fig = plt.figure(figsize=(11.0, 7.0), dpi=110)
    ax = fig.add_axes((0.07, 0.09, 0.52, 0.82))
    ax.plot(ref[:, 0], ref[:, 1], color="0.55", lw=3.0, label="reference", zorder=1)
    for name, res in results_by_policy.items():
        p = _finite_path(res)
        ax.plot(
            p[:, 0],
            p[:, 1],
            color=colors[name],
            lw=1.0,
            label=f"{name} (max {res.max_contour_error_um:.3g} µm)",
            zorder=2,
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title or f"{env.spec.id if env.spec else u.contour_name}: actual and reference contour")
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, lw=0.3)

    # the insets: a column right of the main axes, square in display space
    fig.canvas.draw()
    bb = ax.get_position()
    fig_w, fig_h = fig.get_size_inches()
    k = max(1, len(corners))
    gap = 0.12
    h = (1.0 - gap * (k - 1)) / k  # axes-fraction height of one inset
    w = h * bb.height * fig_h / (bb.width * fig_w)
    corners = sorted(corners, key=lambda ck: -ck[0][1])  # top to bottom, like the insets
    for j, (c, kappa) in enumerate(corners):
        half = _inset_half_width(results_by_policy, c)
        ins = ax.inset_axes((1.1, 1.0 - (j + 1) * h - j * gap, w, h))
        ins.plot(ref[:, 0], ref[:, 1], color="0.55", lw=3.0, zorder=1)
        for name, res in results_by_policy.items():
            p = _finite_path(res)
            ins.plot(p[:, 0], p[:, 1], color=colors[name], lw=1.0, zorder=2)
        ins.plot(ref[:, 0], ref[:, 1], color="k", lw=0.6, ls="--", zorder=3)
        ins.set_xlim(c[0] - half, c[0] + half)
        ins.set_ylim(c[1] - half, c[1] + half)
        ins.set_aspect("equal", adjustable="box")
        # ticks as offsets from the corner in um: short labels, and the error reads directly
        ins.xaxis.set_major_formatter(FuncFormatter(lambda v, _, c0=c[0]: f"{1e3 * (v - c0):.0f}"))
        ins.yaxis.set_major_formatter(FuncFormatter(lambda v, _, c1=c[1]: f"{1e3 * (v - c1):.0f}"))
        offsets = np.asarray(MaxNLocator(4, symmetric=True).tick_values(-1e3 * half, 1e3 * half)) / 1e3
        offsets = offsets[np.abs(offsets) <= half * (1 + 1e-9)]
        ins.xaxis.set_major_locator(FixedLocator(c[0] + offsets))
        ins.yaxis.set_major_locator(FixedLocator(c[1] + offsets))
        ins.tick_params(labelsize=7)
        ins.set_xlabel("Δx (µm)", fontsize=7, labelpad=1)
        ins.set_ylabel("Δy (µm)", fontsize=7, labelpad=1)
        letter = "ABCDEFGH"[j]
        cx, cy = (0.0 if abs(v) < 5e-3 else float(v) for v in c)
        ins.set_title(f"{letter}: corner ({cx:.2f}, {cy:.2f}) mm, radius {1e3 / kappa:.0f} µm", fontsize=7)
        ax.indicate_inset_zoom(ins, edgecolor="0.3", alpha=0.4)
        ax.annotate(
            letter,
            (c[0] - half, c[1] + half),
            xytext=(2, -2),
            textcoords="offset points",
            ha="left",
            va="top",
            fontsize=8,
            color="0.2",
        )
    fig.savefig(path)
    plt.close(fig)


def plot_contour_errors(
    results_by_policy: Mapping[str, EpisodeResult], env, path, *, log: bool = True, title: str | None = None
):
    """Contour error (um) against time (s) for every policy on one env, one figure.

    Parameters
    ----------
    results_by_policy : mapping of str to EpisodeResult
        Policy label -> its episode on ``env``.
    env : gymnasium.Env
        The env the episodes ran on (for the title).
    path : str or path-like
        Where to write the figure (PNG by extension).
    log : bool
        Logarithmic error axis (default), so that the corners and the smooth
        stretches are both readable.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    u = env.unwrapped
    colors = _colors(list(results_by_policy))
    fig, ax = plt.subplots(figsize=(11.0, 4.8), dpi=110)
    for name, res in results_by_policy.items():
        e = 1e3 * res.contour_error
        ok = np.isfinite(e)
        if log:
            ok &= e > 0.0
        ax.plot(
            res.time[ok],
            e[ok],
            color=colors[name],
            lw=0.8,
            label=f"{name}: max {res.max_contour_error_um:.3g} µm, RMS {res.rms_contour_error_um:.3g} µm",
        )
    if log:
        ax.set_yscale("log")
        peaks = [
            r.max_contour_error_um
            for r in results_by_policy.values()
            if math.isfinite(r.max_contour_error_um) and r.max_contour_error_um > 0.0
        ]
        if peaks:  # three decades below the best policy's peak: the dips to zero say little
            ax.set_ylim(bottom=1e-3 * min(peaks))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("contour error (µm)")
    ax.set_title(title or f"{env.spec.id if env.spec else u.contour_name}: contour error")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_trials(trials, path, *, title: str | None = None):
    """Max and RMS contour error (um) against trial number, for a policy that learns across episodes.

    Parameters
    ----------
    trials : sequence of EpisodeResult
        One per trial, in order (trial 1 first).
    path : str or path-like
        Where to write the figure (PNG by extension).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    k = np.arange(1, len(trials) + 1)
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=110)
    ax.plot(k, [t.max_contour_error_um for t in trials], "o-", label="max")
    ax.plot(k, [t.rms_contour_error_um for t in trials], "s--", label="RMS")
    ax.set_xlabel("trial")
    ax.set_ylabel("contour error (µm)")
    ax.set_yscale("log")
    ax.set_xticks(k)
    ax.grid(True, which="both", lw=0.3)
    ax.legend()
    ax.set_title(title or "contour error per trial")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
