"""Yadav et al.'s figures: Kharitonov robust stability and stability margins, Table 2's step metrics.

Section 3.5 of Yadav et al. (2020) closes each controller's loop around the interval
plant ``b / (s (s + a))`` (dead time neglected), bounds the coefficients of
the closed-loop characteristic equation (CLCE) ``s (s + a) D_C(s) + b N_C(s)``
and computes the stability margin of eq. (5) from them; Table 2 gives the
overshoot, settling and rise time of the step response for the nominal plant
and for 10 plants across the box.

Everything here is computed from :func:`~vcnc_baselines.feedback.pi_imc_hinf.controller_tf`
and the plant's box (:mod:`vcnc_gym.plants.cncmt_axis`), with the generic
tools of :mod:`vcnc_gym.analysis`:

- :func:`kharitonov_analysis`: coefficient intervals of the CLCE (exact: the
  coefficients are affine in ``a`` and ``b``, so their extremes lie at the
  box's four vertices), the four Kharitonov polynomials, the Routh test of
  each and eq. (5)'s margin (third-order CLCEs only);
- :func:`loop_step_metrics`: the metrics of one loop, continuous (python-control,
  no dead time, as the paper's Table 2 evidently is) or sampled at ``dt``
  with the dead time exact (``z^-n``), the plant held by a ZOH and the
  controller discretised by Tustin, what :class:`PositioningEnv` and the
  policies compute;
- :func:`table2`: Table 2 in our numbers, with the paper's beside them
  (:func:`format_table2`); :func:`env_step_table`: the same metrics from
  episodes of the registered policies on ``VCNC-Step-v0``;
  :func:`plot_step_responses`: the step responses.

``python -m vcnc_bench.reports.yadav2020`` prints the margins and Table 2
without and with the dead time.
"""

from __future__ import annotations

import argparse
import math

import control
import numpy as np

from vcnc_gym.analysis import (
    hurwitz,
    interval_polynomial,
    kharitonov_polynomials,
    robustly_stable,
    stability_margin,
    step_metrics,
)
from vcnc_gym.plants import cncmt_axis
from vcnc_gym.plants.cncmt_axis import IDX_A, IDX_B, IDX_T_D, MODEL
from vcnc_gym.validation import integer, non_negative

from vcnc_baselines.feedback.pi_imc_hinf import controller_names, controller_tf
from vcnc_baselines.linear import lti_response

__all__ = [
    "PAPER_TABLE_2",
    "PAPER_ROW",
    "plant_box",
    "plant_samples",
    "closed_loop_polynomial",
    "kharitonov_analysis",
    "loop_step_metrics",
    "table2",
    "format_kharitonov",
    "format_table2",
    "env_step_table",
    "plot_step_responses",
    "main",
]

#: Yadav et al. (2020), Table 2: nominal (OS %, ST s, RT s), uncertain ranges ((lo, hi) each) and SM.
PAPER_TABLE_2 = {
    "pi": {"nominal": (41.2, 0.88, 0.14), "uncertain": ((32.8, 45.3), (0.77, 1.33), (0.123, 0.27)), "sm": 588.6},
    "imc": {"nominal": (0.57, 5.84, 3.36), "uncertain": ((0.12, 1.27), (4.1, 7.08), (2.56, 3.98)), "sm": 145.46},
    "hinf": {"nominal": (6.3, 2.09, 1.12), "uncertain": ((0.598, 10.9), (1.34, 2.32), (1.02, 1.74)), "sm": 410.43},
}

#: Which row of :data:`PAPER_TABLE_2` each controller is compared with.  The
#: paper's H-infinity row is the reduced controller's: its SM is eq. (34)-(35)'s
#: (the CLCE of eq. (29)), and its nominal OS and ST are eq. (29)'s.
PAPER_ROW = {"pi": "pi", "imc": "imc", "hinf": "hinf", "hinf-reduced": "hinf"}

_METRICS = ("overshoot", "settling_time", "rise_time", "rise_time_100")


# -- the plant set -------------------------------------------------------------------
def plant_box() -> tuple[tuple[float, float], tuple[float, float]]:
    """The interval plant's box: ``((a_lo, a_hi) [1/s], (b_lo, b_hi) [mm/(V s^2)])`` (x axis of MODEL)."""
    params = {p.name: p for p in MODEL.parameters}
    return tuple(params["a"].interval[0]), tuple(params["b"].interval[0])


def plant_samples(n: int = 10) -> np.ndarray:
    """``n`` plants ``(a, b)`` across the box, (n, 2), in 1/s and mm/(V s^2).

    The paper's "10 uncertain samples between the lower and upper limit" are
    not listed; we take the box's four vertices (where the extremes of the
    metrics usually lie) and fill up with the first points of the 2-D Halton
    sequence (bases 2, 3, unscrambled, starting at its second point):
    deterministic and spread over the box.
    """
    n = integer("n (the number of plants)", n, 1)
    from scipy.stats import qmc

    (a_lo, a_hi), (b_lo, b_hi) = plant_box()
    unit = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)][:n]
    if n > 4:
        unit += qmc.Halton(d=2, scramble=False).random(n - 4 + 1)[1:].tolist()
    u = np.array(unit)
    return np.column_stack([a_lo + u[:, 0] * (a_hi - a_lo), b_lo + u[:, 1] * (b_hi - b_lo)])


def _plant_tf(a: float, b: float) -> control.TransferFunction:
    """``b / (s (s + a))`` in mm/V (eq. (2) without the dead time)."""
    return control.tf([b], [1.0, a, 0.0])


# -- Kharitonov ----------------------------------------------------------------------
def closed_loop_polynomial(controller: str, a: float, b: float) -> np.ndarray:
    """The CLCE ``s (s + a) D_C(s) + b N_C(s)``, descending powers of s (Yadav et al. (2020), eqs. (30), (32), (34)).

    ``C = N_C / D_C`` is :func:`controller_tf` (V/mm) and ``b`` is in
    mm/(V s^2), so the coefficients are the paper's (V/m and m/(V s^2)).
    """
    C = controller_tf(controller)
    num = np.asarray(C.num[0][0], dtype=np.float64)
    den = np.asarray(C.den[0][0], dtype=np.float64)
    return np.polyadd(np.polymul([1.0, a, 0.0], den), b * num)


def kharitonov_analysis(controller: str) -> dict:
    """Yadav et al. (2020), section 3.5, for one controller.

    Returns
    -------
    dict
        ``alpha``, ``beta``: the CLCE's coefficient bounds over the box
        (descending powers of s); ``polynomials``: the four Kharitonov
        polynomials (4, n + 1); ``hurwitz``: the Routh verdict on each;
        ``robustly_stable``: all four Hurwitz; ``stability_margin``: eq. (5)
        (``None`` unless the CLCE is of third order); ``paper_stability_margin``.
    """
    (a_lo, a_hi), (b_lo, b_hi) = plant_box()
    vertices = [closed_loop_polynomial(controller, a, b) for a in (a_lo, a_hi) for b in (b_lo, b_hi)]
    alpha, beta = interval_polynomial(vertices)
    polys = kharitonov_polynomials(alpha, beta)
    sm = stability_margin(alpha, beta) if alpha.size == 4 else None
    return {
        "controller": controller,
        "alpha": alpha,
        "beta": beta,
        "polynomials": polys,
        "hurwitz": [hurwitz(p) for p in polys],
        "robustly_stable": robustly_stable(alpha, beta),
        "stability_margin": sm,
        "paper_stability_margin": PAPER_TABLE_2[PAPER_ROW[controller]]["sm"],
    }


# -- step metrics ----------------------------------------------------------------------
def loop_step_metrics(
    controller: str,
    a: float,
    b: float,
    dead_time: float = 0.0,
    dt: float | None = None,
    t_end: float = 30.0,
    return_response: bool = False,
):
    """Step metrics of the unity-feedback loop of ``controller`` around ``b e^{-T_d s} / (s (s + a))``.

    Parameters
    ----------
    controller : str
        One of :func:`~vcnc_baselines.feedback.pi_imc_hinf.controller_names`.
    a, b : float
        The plant [1/s], [mm/(V s^2)].
    dead_time : float
        T_d [s], >= 0.
    dt : float, optional
        Sampling period [s].  ``None`` with ``dead_time = 0``: the continuous
        loop (python-control).  Otherwise the sampled loop: the plant by
        ``control.c2d(G, dt, "zoh")`` times ``z^-n`` (``n = T_d / dt``, a
        whole number), the controller by ``control.c2d(C, dt, "tustin")``;
        default ``dt`` 1 ms when ``dead_time > 0``.
    t_end : float
        Length of the simulated response [s].
    return_response : bool
        Also return ``(t, y, stable)``.

    Returns
    -------
    dict
        The :class:`~vcnc_gym.analysis.StepMetrics` fields and ``stable``
        (closed-loop poles inside the stability region); with
        ``return_response``, ``(metrics, t, y)``.
    """
    G = _plant_tf(a, b)
    C = controller_tf(controller)
    dead_time = non_negative("dead_time", dead_time, "s")
    if dt is None and dead_time == 0.0:
        T = control.feedback(G * C, 1)
        poles = T.poles()
        stable = bool(np.all(poles.real < 0.0))
        t = np.linspace(0.0, t_end, int(round(t_end / 2e-3)) + 1)  # crossings are interpolated between samples
    else:
        dt = 1e-3 if dt is None else float(dt)
        n = cncmt_axis.delay_periods(dead_time, dt, "dead_time")
        Gd = control.ss(control.c2d(G, dt, "zoh"))
        if n:
            Gd = control.series(control.ss(control.tf([1.0], [1.0] + [0.0] * n, dt)), Gd)
        Cd = control.c2d(control.ss(C), dt, "tustin")
        T = control.feedback(control.series(Cd, Gd), 1)
        stable = bool(np.all(np.abs(T.poles()) < 1.0))
        t = np.arange(int(round(t_end / dt)) + 1) * dt
    y = _step_response(T, t)
    m = step_metrics(t, y, 1.0, initial=0.0).as_dict()
    m["stable"] = stable
    return (m, t, y) if return_response else m


def _step_response(T, t: np.ndarray) -> np.ndarray:
    """The unit-step response of the loop ``T`` at the uniform times ``t`` (s), from rest: a continuous ``T``
    held exactly between samples (``c2d``'s "zoh": exact for a step), stepped by the compiled state-space
    recursion :func:`vcnc_baselines.linear.lti_response`.  It is ``control.step_response(T, t)`` to 1e-12 (tested),
    20 times faster on the continuous loops (python-control steps its recursion in Python)."""
    Td = control.ss(T if T.isdtime(strict=True) else control.c2d(control.ss(T), t[1] - t[0], "zoh"))
    return lti_response(Td.A, Td.B, Td.C, Td.D, np.ones((t.size, 1)))[:, 0]


def _row(controller: str, plants: np.ndarray, metrics_of) -> dict:
    """One row of Table 2: nominal metrics, min/max over ``plants``, SM, paper values."""
    nominal = metrics_of(controller, None)
    samples = [metrics_of(controller, p) for p in plants]
    stable = [s for s in samples if s["stable"]]
    ranges = {}
    for key in _METRICS:
        values = np.array([s[key] for s in stable], dtype=np.float64)
        values = values[~np.isnan(values)]
        ranges[key] = (float(np.min(values)), float(np.max(values))) if values.size else (math.nan, math.nan)
    k = kharitonov_analysis(controller)
    return {
        "controller": controller,
        "nominal": {key: nominal[key] for key in _METRICS},
        "nominal_stable": nominal["stable"],
        "uncertain": ranges,  # over the stable plants; nan where a metric is undefined on all of them
        "unstable_plants": int(sum(not s["stable"] for s in samples)),
        "n_plants": len(samples),
        "stability_margin": k["stability_margin"],
        "robustly_stable": k["robustly_stable"],
        "paper": PAPER_TABLE_2[PAPER_ROW[controller]],
    }


def table2(
    dead_time: float = 0.0, dt: float | None = None, n_plants: int = 10, controllers=None, t_end: float = 30.0
) -> list[dict]:
    """Yadav et al.'s Table 2 in our numbers.

    Parameters
    ----------
    dead_time : float
        T_d [s] in the loop; 0 reproduces the paper's Table 2 (its numbers are
        those of the loop without the dead time: with it the robust PI loop
        is unstable); 0.1 is eq. (2) as stated.
    dt : float, optional
        Sampling period [s] (see :func:`loop_step_metrics`).
    n_plants : int
        Plants across the box (:func:`plant_samples`).
    controllers : list of str, optional
        Default all four.
    t_end : float
        Length of each response [s].

    Returns
    -------
    list of dict
        One row per controller: ``nominal`` metrics, ``uncertain`` (min, max)
        per metric over the plants whose loop is stable (``unstable_plants``
        counts the others), ``stability_margin`` (eq. (5)),
        ``robustly_stable``, ``unstable_plants``, and ``paper``, the paper's
        row of Table 2 (the H-infinity row for both "hinf" and "hinf-reduced").
    """
    a0, b0 = (float(MODEL.nominal()[0, IDX_A]), float(MODEL.nominal()[0, IDX_B]))
    plants = plant_samples(n_plants)

    def metrics_of(name, plant):
        a, b = (a0, b0) if plant is None else plant
        return loop_step_metrics(name, a, b, dead_time=dead_time, dt=dt, t_end=t_end)

    return [_row(name, plants, metrics_of) for name in (controllers or controller_names())]


# -- formatting --------------------------------------------------------------------------
def _fmt(v: float, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    if isinstance(v, float) and math.isnan(v):
        return "n/a"
    return f"{v:.{digits}g}"


def format_kharitonov(controllers=None) -> str:
    """A Markdown table of section 3.5: coefficient bounds, Kharitonov verdict, SM beside the paper's."""
    rows = [
        "| controller | CLCE order | alpha (lower bounds) | beta (upper bounds) | 4 Kharitonov polys Hurwitz "
        "| SM eq. (5) | paper's SM |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in controllers or controller_names():
        k = kharitonov_analysis(name)
        rows.append(
            f"| {name} | {k['alpha'].size - 1} | {', '.join(_fmt(v, 4) for v in k['alpha'])} | "
            f"{', '.join(_fmt(v, 4) for v in k['beta'])} | {sum(k['hurwitz'])}/4 | "
            f"{_fmt(k['stability_margin'], 4)} | {k['paper_stability_margin']} |"
        )
    return "\n".join(rows)


def format_table2(rows: list[dict], title: str = "") -> str:
    """A Markdown table in Table 2's shape, ours beside the paper's ("ours / paper").

    Ranges are over the stable plants of each row; a metric undefined on all
    of them is "n/a" (e.g. the 0-100 % rise time of a response that never
    reaches the set-point).
    """
    out = [title] if title else []
    out += [
        "| controller | plant | OS (%) | ST (s) | RT 10-90 (s) | RT 0-100 (s) | SM, eq. (5), no dead time |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        p = r["paper"]
        n = r["nominal"]
        if r["nominal_stable"]:
            cells = [_fmt(n[k]) for k in _METRICS]
        else:
            cells = ["unstable"] * len(_METRICS)
        out.append(
            f"| {r['controller']} | nominal | {cells[0]} / {p['nominal'][0]} | "
            f"{cells[1]} / {p['nominal'][1]} | {cells[2]} / {p['nominal'][2]} | "
            f"{cells[3]} | {_fmt(r['stability_margin'], 4)} / {p['sm']} |"
        )
        u = r["uncertain"]
        rng = [f"{_fmt(u[k][0])}-{_fmt(u[k][1])}" if not math.isnan(u[k][0]) else "n/a" for k in _METRICS]
        unstable = f" ({r['unstable_plants']} unstable)" if r["unstable_plants"] else ""
        out.append(
            f"| | {r['n_plants']} plants{unstable} | {rng[0]} / {p['uncertain'][0][0]}-{p['uncertain'][0][1]} | "
            f"{rng[1]} / {p['uncertain'][1][0]}-{p['uncertain'][1][1]} | "
            f"{rng[2]} / {p['uncertain'][2][0]}-{p['uncertain'][2][1]} | {rng[3]} | |"
        )
    return "\n".join(out)


# -- through the env -------------------------------------------------------------------------
def env_step_table(
    controllers=None, n_plants: int = 10, dead_time: float | None = None, env_id: str = "VCNC-Step-v0", **env_kwargs
) -> tuple[list[dict], dict]:
    """Table 2's metrics from episodes of the registered policies on the positioning env.

    Each controller runs one episode on the nominal plant and one on each of
    :func:`plant_samples` (both axes the same plant, set by
    ``reset(options={"parameters": ...})``); the metrics are the x axis' of
    the final ``info["step_metrics"]``.

    Parameters
    ----------
    controllers : list of str, optional
        Baseline names; default the four of Yadav et al. (2020).
    n_plants : int
        Plants across the box.
    dead_time : float, optional
        T_d [s] of every plant; default the plant's (0.1 s).
    env_id : str
        A registered id on the cncmt_axis plant.
    **env_kwargs
        Passed to ``gym.make`` (e.g. ``dt=0.001``).

    Returns
    -------
    rows : list of dict
        As :func:`table2`, "stable" meaning "not diverged within the episode".
    traces : dict
        ``{controller: [(t, x), ...]}``, nominal first: time [s] and x
        position [mm] per episode, for :func:`plot_step_responses`.
    """
    import gymnasium as gym

    import vcnc_baselines
    from vcnc_gym.evaluation import run_episode

    nominal = MODEL.nominal()
    if dead_time is not None:
        nominal[:, IDX_T_D] = dead_time
    traces: dict[str, list] = {}
    steps = []

    def run(name, plant):
        p = nominal.copy()
        if plant is not None:
            p[:, IDX_A], p[:, IDX_B] = plant
        env = gym.make(env_id, parameters=p, **env_kwargs)
        try:
            result = run_episode(vcnc_baselines.make(name, env), env, seed=0)
            u = env.unwrapped
            t, x = u.trajectory
            m = dict(u.step_metrics()["x"])
            steps.append(float(u.setpoint[0]))
        finally:
            env.close()
        traces.setdefault(name, []).append((t, x[:, 0]))
        m["stable"] = not result.diverged
        return m

    plants = plant_samples(n_plants)
    rows = [_row(name, plants, run) for name in (controllers or controller_names())]
    for r in rows:
        r["setpoint_mm"] = steps[0]
    return rows, traces


def plot_step_responses(traces: dict, path=None, setpoint: float = 10.0):
    """One panel per controller: the nominal step response (bold) and the plants across the box.

    Parameters
    ----------
    traces : dict
        ``{controller: [(t [s], x [mm]), ...]}``, nominal first (:func:`env_step_table`).
    path : str or Path, optional
        Save the figure there (PNG).
    setpoint : float
        The step [mm], drawn dashed.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(traces)
    fig, axes = plt.subplots(1, len(names), figsize=(4 * len(names), 3.2), squeeze=False)
    for ax, name in zip(axes[0], names):
        for j, (t, x) in enumerate(traces[name]):
            shown = np.where(np.isfinite(x) & (np.abs(x) < 3 * abs(setpoint)), x, np.nan)  # gaps, not jumps
            ax.plot(
                t,
                shown,
                color="C0" if j == 0 else "0.6",
                lw=1.6 if j == 0 else 0.7,
                zorder=3 if j == 0 else 2,
                label="nominal" if j == 0 else ("plants" if j == 1 else None),
            )
        ax.axhline(setpoint, color="k", ls="--", lw=0.8)
        ax.set_title(name)
        ax.set_xlabel("time (s)")
        ax.set_ylim(-0.2 * abs(setpoint), 2.0 * abs(setpoint))
    axes[0][0].set_ylabel("x position (mm)")
    axes[0][0].legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=120)
    return fig


# -- command line ------------------------------------------------------------------------------
def main(argv=None) -> int:
    """Print section 3.5's margins and Table 2 (no dead time, then the stated 0.1 s), ours beside the paper's."""
    parser = argparse.ArgumentParser(prog="python -m vcnc_bench.reports.yadav2020", description=main.__doc__)
    parser.add_argument("--plants", type=int, default=10, help="plants across the box (default 10)")
    parser.add_argument(
        "--dead-time", type=float, default=None, help="only this dead time in s (default: 0, then 0.1 sampled at 1 ms)"
    )
    args = parser.parse_args(argv)
    print("Yadav et al. (2020), section 3.5: CLCE coefficient bounds over the box, Kharitonov, SM of eq. (5)\n")
    print(format_kharitonov())
    cases = (
        [(0.0, None), (0.1, 1e-3)] if args.dead_time is None else [(args.dead_time, 1e-3 if args.dead_time else None)]
    )
    for dead_time, dt in cases:
        how = "continuous" if dt is None else f"sampled at {dt:g} s, dead time exact"
        title = f"\nTable 2, dead time {dead_time:g} s ({how}); cells: ours / paper's"
        print(format_table2(table2(dead_time=dead_time, dt=dt, n_plants=args.plants), title))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
