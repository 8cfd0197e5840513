"""Matplotlib views of a contouring episode: the path, its contour error magnified, and the contour error over time.

A contouring env with ``render_mode="rgb_array"`` or ``"human"`` keeps its episode's history (time, table
position, contour error; :class:`EpisodeHistory`) and draws it with a
:class:`ContourView`: one figure per env, made once, whose static part (the contour, the axes, their labels) is
drawn once into a background and whose moving part (the table's path, its marker, the error curve, the clock) is
drawn over a copy of that background at every frame (matplotlib's blitting).  A frame of a whole heart costs a few
milliseconds (``python benchmarks/render_timing.py``), against 140 ms when the axes were cleared and drawn again.

Frames are in simulated time: an env's ``metadata["render_fps"]`` is one frame per decision, ``1 /
decision_period`` (:func:`render_fps`), so a video of one frame per step, as ``gymnasium.wrappers.RecordVideo``
records, plays the episode in real time (a heart of 3.2 s at 1 ms decisions in a 3.3 s video at 1000 fps).  An
env draws a new frame every ``render_every`` decisions (:func:`default_render_every`: a new picture every
1/30 s of the episode) and returns the last one drawn in between, the same array, so that recording a whole
episode draws about 30 pictures per simulated second, not one per decision.
"""

from __future__ import annotations

import numpy as np

from ..validation import integer

__all__ = [
    "ContourView",
    "EpisodeHistory",
    "Renderer",
    "PICTURES_PER_SECOND",
    "MAGNIFIED_ERROR",
    "default_render_every",
    "render_every_argument",
    "render_fps",
]

#: New pictures per second of simulated time that the default frame skip draws (a video's usual 30 fps).
PICTURES_PER_SECOND = 30.0

#: The path panel shows the contour error magnified so that an error of the reward's clip (``error_clip``) or of
#: ten reward scales, whichever is smaller, spans this fraction of the contour's extent.
MAGNIFIED_ERROR = 0.04

#: Figure size, inches, and resolution: frames of 800 x 360 pixels (even sizes, as H.264's yuv420p needs).
FIGSIZE = (10.0, 4.5)
DPI = 80


def render_fps(decision_period: float) -> float:
    """Frames per second of video for one frame per decision of ``decision_period`` s: the episode in real time
    (an int when it is one, as Gymnasium's own envs give it)."""
    fps = 1.0 / decision_period
    return int(round(fps)) if abs(fps - round(fps)) < 1e-6 * fps else fps


def default_render_every(decision_period: float) -> int:
    """The decisions between two new pictures by default: about :data:`PICTURES_PER_SECOND` pictures per second
    of simulated time (33 on the 1 ms decisions of the heart's v2, 3 on the circle's 10 ms), at least 1."""
    return max(1, int(round(1.0 / (PICTURES_PER_SECOND * decision_period))))


def render_every_argument(render_every, decision_period: float) -> int:
    """``render_every=`` checked: an integer >= 1 (decisions between two new pictures), or None for
    :func:`default_render_every`."""
    if render_every is None:
        return default_render_every(decision_period)
    return integer("render_every", render_every, 1)


class EpisodeHistory:
    """What a view draws of one env's episode: per decision the time (s), the table's position (mm) and its
    contour error (mm).  A plain dict of lists (``data``), so that it
    pickles with the env."""

    def __init__(self, data: dict | None = None):
        self.data = data if data is not None else {"t": [], "position": [], "contour_error": []}

    def start(self, info_row: np.ndarray, columns: dict) -> None:
        """A new episode at time 0 from the kernel's info row of the env (columns: ``step_kernel.INFO_FIELDS``)."""
        for values in self.data.values():
            values.clear()
        self.append(0.0, info_row, columns)

    def append(self, time: float, info_row: np.ndarray, columns: dict) -> None:
        """One decision: the time and the kernel's info row of the env after it."""
        d = self.data
        pos = columns["position"][0]
        d["t"].append(float(time))
        d["position"].append((float(info_row[pos]), float(info_row[pos + 1])))
        d["contour_error"].append(float(info_row[columns["contour_error"][0]]))

    def __len__(self) -> int:
        return len(self.data["t"])


class ContourView:
    """The figure of one env's episode, drawn by blitting: the contour and the table's path with its contour
    error magnified (left), the contour error in um over time (right).

    Parameters
    ----------
    task : ContouringTask
        The env's task: its reference, contour name, reward scale and clip, episode's end.
    mode : str
        "rgb_array" (Agg, off screen) or "human" (a window of the interactive backend).
    """

    def __init__(self, task, mode: str):
        import matplotlib

        if mode == "rgb_array":
            matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        self.mode = mode
        ref = task.reference.position
        self._ref = ref
        self._projector, self._curve = task.projector, task.curve
        self._feet: list = []  # the closest contour point of each position drawn so far, mm
        self._shown: list = []  # each position with its contour error magnified, mm
        self._t_end = task.end_index * task.dt
        self._shown_error_um = 1e3 * min(task.error_clip, 10.0 * task.reward_scale)
        extent = float(np.max(np.ptp(ref, axis=0)))
        self._magnify = max(1.0, round(MAGNIFIED_ERROR * extent / (self._shown_error_um * 1e-3)))
        if mode == "rgb_array":
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.figure = Figure(figsize=FIGSIZE, dpi=DPI)
            FigureCanvasAgg(self.figure)
        else:
            self.figure = plt.figure(figsize=FIGSIZE, dpi=DPI)
        self._build(task.contour_name)
        self._background = None

    def _build(self, contour_name: str) -> None:
        """The axes, the static contour and the moving artists (animated: left out of the background)."""
        fig = self.figure
        ax_path, ax_err = fig.subplots(1, 2, gridspec_kw={"width_ratios": (1.0, 1.3)})
        self._axes = (ax_path, ax_err)
        ref = self._ref
        ax_path.plot(ref[:, 0], ref[:, 1], color="0.65", lw=2.5, label="contour")
        (self._trail,) = ax_path.plot([], [], color="C3", lw=1.0, label=f"table, error x{self._magnify:g}")
        (self._tool,) = ax_path.plot([], [], "o", color="C3", ms=5)
        lo, hi = ref.min(axis=0), ref.max(axis=0)
        pad = 0.08 * max(hi - lo) + 1e-9
        ax_path.set_xlim(lo[0] - pad, hi[0] + pad)
        ax_path.set_ylim(lo[1] - pad, hi[1] + pad)
        ax_path.set_aspect("equal", adjustable="box")
        ax_path.set_xlabel("x [mm]")
        ax_path.set_ylabel("y [mm]")
        ax_path.legend(loc="upper right", fontsize=7)
        ax_path.set_title(f"{contour_name}: path", fontsize=10)
        (self._error,) = ax_err.plot([], [], color="C3", lw=1.0)
        ax_err.set_xlim(0.0, self._t_end)
        ax_err.set_ylim(0.0, self._shown_error_um)
        ax_err.set_xlabel("time [s]")
        ax_err.set_ylabel("contour error [um]")
        ax_err.set_title("contour error", fontsize=10)
        ax_err.grid(alpha=0.3)
        self._clock = ax_err.text(0.02, 0.95, "", transform=ax_err.transAxes, va="top", fontsize=9)
        for artist in (self._trail, self._tool, self._error, self._clock):
            artist.set_animated(True)
        fig.tight_layout()

    def _ensure_background(self, peak_um: float) -> None:
        """The static part drawn once (again when the error outgrows the error axis: its top doubles)."""
        ax_err = self._axes[1]
        top = ax_err.get_ylim()[1]
        if self._background is not None and peak_um <= top:
            return
        while peak_um > top:
            top *= 2.0
        ax_err.set_ylim(0.0, top)
        canvas = self.figure.canvas
        canvas.draw()
        self._background = canvas.copy_from_bbox(self.figure.bbox)  # pyright: ignore[reportAttributeAccessIssue]  (the Agg canvas)

    def draw(self, history: EpisodeHistory) -> np.ndarray | None:
        """The frame of ``history`` so far: an RGB array (H, W, 3) uint8 in "rgb_array" mode, None in "human"
        (the window is updated)."""
        d = history.data
        t = np.asarray(d["t"])
        err_um = 1e3 * np.asarray(d["contour_error"])
        finite = err_um[np.isfinite(err_um)]
        self._ensure_background(float(finite.max()) if finite.size else 0.0)
        self._trail.set_data(*self._magnified(d).T)
        if d["position"]:
            x, y = d["position"][-1]
            self._tool.set_data([x], [y])
            self._clock.set_text(f"t = {t[-1]:.3f} s")
        else:
            self._tool.set_data([], [])
            self._clock.set_text("")
        self._error.set_data(t, err_um)
        canvas = self.figure.canvas
        canvas.restore_region(self._background)  # pyright: ignore[reportAttributeAccessIssue]  (the Agg canvas)
        ax_path, ax_err = self._axes
        ax_path.draw_artist(self._trail)
        ax_path.draw_artist(self._tool)
        ax_err.draw_artist(self._error)
        ax_err.draw_artist(self._clock)
        if self.mode == "human":
            canvas.blit(self.figure.bbox)
            canvas.flush_events()
            import matplotlib.pyplot as plt

            plt.pause(1e-3)
            return None
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()  # pyright: ignore[reportAttributeAccessIssue]  (the Agg canvas)

    def _magnified(self, d: dict) -> np.ndarray:
        """The table's positions (n, 2) moved away from their closest contour points by ``magnify - 1`` times
        their distance from them: the contour error magnified, the path's shape kept.  Each position is
        projected once (the projector's exact search), then kept."""
        positions = d["position"]
        done = len(self._feet)
        if len(positions) < done:  # a new episode
            self._feet, self._shown = [], []
            done = 0
        if len(positions) > done:
            new = np.asarray(positions[done:], dtype=np.float64)
            feet = new.copy()
            finite = np.isfinite(new).all(axis=1)
            if finite.any():
                _, u = self._projector.project(new[finite])
                feet[finite] = self._curve.points(np.atleast_1d(u))
            self._feet.extend(feet)
            self._shown.extend(feet + self._magnify * (new - feet))
        return np.asarray(self._shown).reshape(-1, 2)

    def close(self) -> None:
        import matplotlib.pyplot as plt

        plt.close(self.figure)


class Renderer:
    """The frames of one env's episode (an env with a ``render_mode``): a new picture of its history once ``every``
    decisions have passed since the last (and at the episode's end), the last one in between.

    The view (:class:`ContourView`) is made at the first picture; :meth:`close` closes its figure.
    """

    def __init__(self, task, mode: str, every: int):
        self.task, self.mode, self.every = task, mode, every
        self.view: ContourView | None = None
        self.frame = None
        self.drawn_at = -1  # the decision of the last picture; -1: none of this episode yet

    def restart(self) -> None:
        """A new episode: its first render draws."""
        self.drawn_at = -1

    def render(self, history: dict | None, done: bool):
        """The frame of ``history`` (a dict of :class:`EpisodeHistory`; None before the first reset: an empty
        picture): a new one when due, else the last, the same array ("rgb_array"); None in "human"."""
        h = EpisodeHistory(history)
        decision, drawn = len(h) - 1, self.drawn_at
        if drawn < 0 or decision < drawn or decision - drawn >= self.every or (done and decision > drawn):
            if self.view is None:
                self.view = ContourView(self.task, self.mode)
            self.frame, self.drawn_at = self.view.draw(h), decision
        return self.frame

    def close(self) -> None:
        if self.view is not None:
            self.view.close()
            self.view = None
