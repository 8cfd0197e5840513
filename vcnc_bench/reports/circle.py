"""Purtojo et al.'s circle: its reference, a stand-alone closed loop, the paper's figures and the radial-error plot.

Purtojo et al. (section IV) drive the x axis of their X-Y table with a sine and the
y axis with a cosine of 1 mm amplitude, so that the table traces a 1 mm
radius circle, and reports (Fig. 6 and its text):

- RMS tracking error 0.0063 mm on x and 0.0037 mm on y;
- RMS radial error 0.0008 mm;
- radial error within 2 um, except the initial one of the x axis's transient.

The paper gives no frequency.  We take ``omega = 1 rad/s``
(:data:`DEFAULT_OMEGA`: the default of a Simulink Sine Wave block, which a
"1 mm amplitude sinusoidal input" with no frequency suggests; period 6.28 s,
feed ``R omega`` = 1 mm/s), one revolution, at the control period
:data:`DEFAULT_DT` = 1 ms (the paper gives none either).  The reference is
x = R sin(omega t), y = R cos(omega t) from t = 0: the x axis must start at
full feed from rest (its transient), the y axis at rest.

What is here
------------
:func:`circle_figures`
    The paper's four figures from any trace (time, true position, reference
    position); the radial error is ``|p - c| - R``, its magnitude the contour
    error of the env.  The transient excluded from the "within 2 um" figure
    is the first :data:`DEFAULT_TRANSIENT` s (our choice).
:func:`run_circle`
    One pass of any SB3-style policy around the circle: an episode of
    ``VCNC-Circle-v1`` (Purtojo et al.'s table, its 1 um sensor, a constant feed
    R omega from t = 0) through the one evaluation loop.
:func:`circle_reference`
    The exact sine/cosine reference, x = R sin(omega t), y = R cos(omega t),
    which the env's interpolated reference is checked against.
:func:`plot_radial_error`
    The circle's radial error against time (and the tracking errors), um.

Units: mm, s in the traces; um in the figures (named ``*_um``) and plots.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from vcnc_gym.validation import non_negative, positive

__all__ = [
    "nctf_main",
    "DEFAULT_RADIUS",
    "DEFAULT_OMEGA",
    "DEFAULT_DT",
    "DEFAULT_TRANSIENT",
    "CircleFigures",
    "PAPER_FIGURES",
    "circle_reference",
    "circle_figures",
    "run_circle",
    "comparison_table",
    "format_comparison",
    "bench_report",
    "plot_radial_error",
]

#: Circle radius, mm (Purtojo et al., section IV).
DEFAULT_RADIUS = 1.0
#: Angular frequency of the sine/cosine, rad/s (our choice; Purtojo et al. give none).
DEFAULT_OMEGA = 1.0
#: Control period, s (our choice; Purtojo et al. give none).
DEFAULT_DT = 1e-3
#: Start of the trace excluded from the "radial error within" figure, s (our choice).
DEFAULT_TRANSIENT = 1.0


@dataclass(frozen=True)
class CircleFigures:
    """Purtojo et al.'s figures of one circle run, um.

    Attributes
    ----------
    rms_x_um, rms_y_um : float
        RMS tracking error of the x and y axes (reference minus true position).
    rms_radial_um : float
        RMS radial error.
    max_radial_after_transient_um : float
        Largest ``|radial error|`` after the transient (the paper: "within 2 um").
    max_radial_um : float
        Largest ``|radial error|`` over the whole run.
    transient_s : float
        The excluded start, s.
    """

    rms_x_um: float
    rms_y_um: float
    rms_radial_um: float
    max_radial_after_transient_um: float
    max_radial_um: float = float("nan")
    transient_s: float = DEFAULT_TRANSIENT

    def as_dict(self) -> dict:
        return asdict(self)


#: Purtojo et al., section IV: RMS x 0.0063 mm, y 0.0037 mm, radial 0.0008 mm; radial error within 2 um.
PAPER_FIGURES = CircleFigures(rms_x_um=6.3, rms_y_um=3.7, rms_radial_um=0.8, max_radial_after_transient_um=2.0)


def circle_reference(
    radius: float = DEFAULT_RADIUS, omega: float = DEFAULT_OMEGA, dt: float = DEFAULT_DT, revolutions: float = 1.0
):
    """The sine/cosine reference sampled at ``dt``: x = R sin(omega t), y = R cos(omega t).

    Parameters
    ----------
    radius : float
        R, mm.
    omega : float
        rad/s.
    dt : float
        Sample period, s.
    revolutions : float
        Length of the reference in turns.

    Returns
    -------
    t : ndarray, (K,)
        s, ``0, dt, ..., 2 pi revolutions / omega`` (rounded to whole samples).
    position, velocity, acceleration : ndarray, (K, 2)
        mm, mm/s, mm/s^2.
    """
    r = positive("radius", radius, "mm")
    w = positive("omega", omega, "rad/s")
    dt = positive("dt", dt, "s")
    turns = positive("revolutions", revolutions, "turns")
    n = int(round(2.0 * np.pi * turns / w / dt))
    if n < 1:
        raise ValueError(f"the reference of {turns} turns at {w} rad/s is shorter than one period of {dt} s")
    t = dt * np.arange(n + 1)
    s, c = np.sin(w * t), np.cos(w * t)
    position = r * np.column_stack([s, c])
    velocity = r * w * np.column_stack([c, -s])
    acceleration = -r * w * w * np.column_stack([s, c])
    return t, position, velocity, acceleration


def _traces(name: str, a, n: int | None = None) -> np.ndarray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2 or (n is not None and arr.shape[0] != n):
        raise ValueError(f"{name} must have shape ({'n' if n is None else n}, 2) (mm), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (mm)")
    return arr


def circle_figures(
    time,
    position,
    reference_position,
    radius: float = DEFAULT_RADIUS,
    center=(0.0, 0.0),
    transient: float = DEFAULT_TRANSIENT,
) -> CircleFigures:
    """Purtojo et al.'s figures of a circle run.

    Parameters
    ----------
    time : array_like, (n,)
        Sample times, s.
    position, reference_position : array_like, (n, 2)
        True table position and reference point at those times, mm.
    radius : float
        Circle radius, mm.
    center : (float, float)
        Circle centre, mm.
    transient : float
        Samples with ``time < transient`` (s) are left out of
        ``max_radial_after_transient_um``.

    Returns
    -------
    CircleFigures
        The RMS are over all samples.
    """
    t = np.asarray(time, dtype=np.float64)
    if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)):
        raise ValueError(f"time must be a non-empty 1-D array of finite times (s), got shape {t.shape}")
    p = _traces("position", position, t.size)
    ref = _traces("reference_position", reference_position, t.size)
    r = positive("radius", radius, "mm")
    c = _traces("center", np.reshape(center, (1, 2)))[0]
    tr = non_negative("transient", transient, "s")
    after = t >= tr
    if not after.any():
        raise ValueError(f"no sample after the transient of {tr} s (the run ends at {t[-1]} s)")
    err = ref - p
    radial = np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) - r
    um = 1e3
    return CircleFigures(
        rms_x_um=float(um * np.sqrt(np.mean(err[:, 0] ** 2))),
        rms_y_um=float(um * np.sqrt(np.mean(err[:, 1] ** 2))),
        rms_radial_um=float(um * np.sqrt(np.mean(radial**2))),
        max_radial_after_transient_um=float(um * np.max(np.abs(radial[after]))),
        max_radial_um=float(um * np.max(np.abs(radial))),
        transient_s=tr,
    )


def comparison_table(figures: CircleFigures, paper: CircleFigures = PAPER_FIGURES) -> list[dict]:
    """Rows ``{"figure", "ours_um", "paper_um", "ratio"}`` (ours / paper) for the paper's four figures."""
    names = (
        ("RMS tracking error x", "rms_x_um"),
        ("RMS tracking error y", "rms_y_um"),
        ("RMS radial error", "rms_radial_um"),
        ("max |radial error| after the transient", "max_radial_after_transient_um"),
    )
    return [
        {
            "figure": label,
            "ours_um": getattr(figures, key),
            "paper_um": getattr(paper, key),
            "ratio": getattr(figures, key) / getattr(paper, key),
        }
        for label, key in names
    ]


def format_comparison(figures: CircleFigures, title: str = "", paper: CircleFigures = PAPER_FIGURES) -> str:
    """:func:`comparison_table` as aligned text lines (um), under ``title``."""
    lines = [title] if title else []
    for row in comparison_table(figures, paper):
        lines.append(
            f"  {row['figure']:<40} {row['ours_um']:8.2f} um   Purtojo et al.: {row['paper_um']:4.1f} um"
            f"   ratio {row['ratio']:5.2f}"
        )
    return "\n".join(lines)


def bench_report(
    results_by_policy,
    label: str = "circle",
    radius: float = DEFAULT_RADIUS,
    transient: float = DEFAULT_TRANSIENT,
    plot_path=None,
    shown=None,
) -> list[str]:
    """Purtojo et al.'s figures of every policy's circle run, as text lines, and optionally the radial-error plot.

    Parameters
    ----------
    results_by_policy : mapping name -> run
        Runs with ``time``, ``position`` and ``reference_position`` (e.g.
        :class:`~vcnc_gym.evaluation.EpisodeResult` of a circle env).
    label : str
        Names the env in the heading.
    radius, transient :
        See :func:`circle_figures`.
    plot_path : path, optional
        Where :func:`plot_radial_error` saves the plot of the runs.
    shown : collection of str, optional
        The policies the plot shows (default all; the figures are printed for all).

    Returns
    -------
    list of str
    """
    head = (
        f"Purtojo et al., section IV, on {label}: RMS tracking error x, y, RMS radial error and max |radial error| "
        f"after the first {transient:g} s"
    )
    lines = [head]
    for name, run in results_by_policy.items():
        f = circle_figures(run.time, run.position, run.reference_position, radius, (0.0, 0.0), transient)
        lines.append(format_comparison(f, f"{name}:"))
    plotted = {k: v for k, v in results_by_policy.items() if shown is None or k in shown}
    if plot_path is not None and plotted:
        plot_radial_error(plotted, radius, transient, path=plot_path)
    return lines


#: The env of Purtojo et al.'s circle.
CIRCLE_ID = "VCNC-Circle-v1"


def circle_layout():
    """The observation layout of :data:`CIRCLE_ID` (what a policy built outside an env reads)."""
    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)

    return gym.make(CIRCLE_ID).unwrapped.layout


def run_circle(
    policy, radius: float = DEFAULT_RADIUS, omega: float = DEFAULT_OMEGA, dt: float = DEFAULT_DT, **env_kwargs
):
    """One pass of ``policy`` around the sine/cosine circle: an episode of ``VCNC-Circle-v1``.

    The env of the registered id, with another radius (mm), frequency
    (rad/s: feed ``radius * omega`` mm/s from t = 0) or control period (s) if
    given, run by the one evaluation loop, :func:`vcnc_gym.evaluation.run_episode`.

    Returns
    -------
    vcnc_gym.evaluation.EpisodeResult
    """
    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)
    from vcnc_gym.evaluation import run_episode
    from vcnc_gym.geometry.shapes import circle

    radius = positive("radius", radius, "mm")
    omega = positive("omega", omega, "rad/s")
    env = gym.make(CIRCLE_ID, contour=circle(radius), feedrate=radius * omega, dt=dt, **env_kwargs)
    try:
        return run_episode(policy, env, seed=0)
    finally:
        env.close()


def plot_radial_error(
    runs,
    radius: float = DEFAULT_RADIUS,
    transient: float = DEFAULT_TRANSIENT,
    paper: CircleFigures = PAPER_FIGURES,
    path=None,
):
    """Radial error (top) and tracking errors (bottom) of circle runs against time, um.

    Parameters
    ----------
    runs : mapping name -> run
        Each run has ``time`` (n,), ``position`` and ``reference_position``
        (n, 2), in s and mm (an :class:`~vcnc_gym.evaluation.EpisodeResult`).
    radius : float
        mm; the circle is centred at the origin.
    transient : float
        s, marked on the plot; the paper's 2 um band is drawn after it.
    paper : CircleFigures
        For the band.
    path : str or os.PathLike, optional
        Where to save the figure (format by extension); the figure is then closed.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if not runs:
        raise ValueError("runs must name at least one run")
    fig, (ax_r, ax_t) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for name, run in runs.items():
        t = np.asarray(run.time)
        p = np.asarray(run.position)
        ref = np.asarray(run.reference_position)
        radial = 1e3 * (np.hypot(p[:, 0], p[:, 1]) - radius)
        ax_r.plot(t, radial, lw=0.8, label=name)
        ax_t.plot(t, 1e3 * (ref[:, 0] - p[:, 0]), lw=0.8, label=f"{name}: x")
        ax_t.plot(t, 1e3 * (ref[:, 1] - p[:, 1]), lw=0.8, label=f"{name}: y")
    band = paper.max_radial_after_transient_um
    ax_r.axhspan(-band, band, color="0.9", zorder=0, label=f"Purtojo et al.: within {band:g} um")
    for ax in (ax_r, ax_t):
        ax.axvline(transient, color="0.5", ls=":", lw=0.8)
        ax.legend(fontsize=7, loc="upper right")
        ax.grid(alpha=0.3)
    ax_r.set_ylabel("radial error |p| - R [um]")
    ax_t.set_ylabel("tracking error [um]")
    ax_t.set_xlabel("time [s]")
    ax_r.set_title(f"circle R = {radius:g} mm")
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=120)
        plt.close(fig)
    return fig


def nctf_main(argv=None) -> int:
    """The NCTF design on Purtojo et al.'s nominal table and its circle figures, printed.

    ``python -m vcnc_bench.reports.circle [--omega W] [--dt T] [--zero-rate nct|sample] [--plot PNG]``
    """
    import argparse

    from vcnc_baselines.feedback.nctf import DEFAULT_SETTINGS, NCTFPolicy
    from vcnc_gym.plants import get_plant

    parser = argparse.ArgumentParser(
        prog="python -m vcnc_bench.reports.circle", description="NCTF design and circle figures"
    )
    parser.add_argument("--omega", type=float, default=DEFAULT_OMEGA, help="circle frequency, rad/s")
    parser.add_argument("--dt", type=float, default=DEFAULT_DT, help="control period, s")
    parser.add_argument("--zero-rate", choices=("nct", "sample"), default=DEFAULT_SETTINGS.zero_rate)
    parser.add_argument("--plot", help="save the radial-error plot here (PNG)")
    args = parser.parse_args(argv)
    model = get_plant("nct_xy_table")
    policy = NCTFPolicy(circle_layout(), args.dt, model.nominal(), zero_rate=args.zero_rate)
    print(f"NCTF design at T = {args.dt:g} s (stepwise experiment on the nominal table, Purtojo et al.'s eq. (4)):")
    for axis, (n, c) in enumerate(zip(policy.nct, policy.compensators)):
        K, alpha = n.model()
        print(
            f"  {'xy'[axis]}: h_max {n.h_max:.3f} mm/s, A {n.A:.3f} mm, m {n.m:.4f} 1/s -> eq. (3): K {K:.2f}, "
            f"alpha {alpha:.4f}; h_s-res {c.h_s_res:.4g} mm/s, u_i-max {c.u_i_max:.4g}, "
            f"u_i-s-res {c.u_i_s_res:.4g} mm^2/s"
        )
    run = run_circle(policy, omega=args.omega, dt=args.dt)
    print(
        "\n".join(
            bench_report({"nctf": run}, f"VCNC-Circle-v1, R = 1 mm, omega = {args.omega:g} rad/s", plot_path=args.plot)
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(nctf_main())
