"""The ``baseline`` policy kind of vcnc-bench: every classical controller, on the plants it was designed for.

Found by the bench through the entry point ``baseline`` of the group
``vcnc_bench.policy_kinds`` (``pyproject.toml``), like any other package's kind; it lives with the bench, above
the controllers it runs, so that the layers import downward.  A bare baseline name
(``qft``) is a spec of this kind; by default the bench runs, on each env,
every baseline whose ``plants`` include the env's plant.
"""

from __future__ import annotations

from vcnc_baselines.feedback import qft
from vcnc_baselines.registry import FLOORS, in_default_table, make, names, policy_class

from ..policies import PolicyKind

__all__ = ["KIND", "applies"]


def applies(name: str, env) -> bool:
    """True if baseline ``name`` was designed for the plant of ``env`` (and, for a controller that follows a
    contour's reference, ``env`` has one), and the env takes the two axis commands a controller gives (not a
    third action such as ``VCNC-OmegaOverride-v1``'s feed override, nor a learnable id's set-point correction); a
    controller that sets the feed override itself (``mpcc``, ``sets_feed_override``) applies to the feed-override
    envs only."""
    cls = policy_class(name)
    u = env.unwrapped
    if getattr(cls, "sets_feed_override", False):  # mpcc: its own progress, through the feed override
        return (
            getattr(u, "retimes_reference", False)
            and getattr(u.action_space, "shape", None) == (3,)
            and cls.designed_for(u.plant)
        )
    if getattr(u.action_space, "shape", None) != (2,):
        return False
    if getattr(getattr(u, "task", None), "controlled", False):  # a learnable id's action: a set-point, not a command
        return False
    plant = getattr(u, "plant", None)
    if getattr(cls, "needs_reference", False) and not hasattr(getattr(u, "task", None), "reference_arrays"):
        return False
    return plant is not None and cls.designed_for(plant)


def _oracle(ctx) -> list[str]:
    """The oracle's wall time (its offline solve plus the episode) per env, when it ran."""
    rows = [
        (e, r.wall_s) for e in ctx.env_ids for label, r in ctx.results.get(e, {}).items() if label.startswith("oracle")
    ]
    if not rows:
        return []
    return [
        "oracle (non-causal floor: the best causal controller plus an input correction searched on the exact "
        "plant, baselines/optimal/oracle.py; a stored solution replayed, else solved), plan + episode:"
    ] + [f"  {e}: {wall:.2f} s" for e, wall in rows]


def _qft_stability(ctx) -> list[str]:
    """Jahanpour et al.'s eq. (11) for the QFT loop, when "qft" ran."""
    ran = [e for e in ctx.env_ids if "qft" in ctx.results.get(e, {})]
    if not ran:
        return []
    dts = sorted({ctx.envs[e].unwrapped.decision_period for e in ran})
    head = "QFT robust-stability peak max|T(jw)| over the uncertainty box, Jahanpour et al.'s eq. (11)"
    lines = [f"{head} (bound mu = {qft.MU:g}):"]
    for axis in ("x", "y"):
        parts = [f"{qft.robust_stability_peak(axis=axis):.3f} continuous"]
        parts += [f"{qft.robust_stability_peak(axis=axis, dt=dt):.3f} sampled at dt = {dt:g} s" for dt in dts]
        lines.append(f"  {axis}: " + ", ".join(parts))
    return lines


def _yadav2020_tables(env) -> dict | None:
    """Yadav et al.'s Table 2, continuous and through ``env``'s id, when ``env`` is on their plant (cncmt_axis): the
    report's 90 step responses, prepared where the env runs (:attr:`~vcnc_bench.policies.PolicyKind.prepare`)."""
    u = env.unwrapped
    if getattr(getattr(u, "plant", None), "name", None) != "cncmt_axis" or u.spec is None:
        return None
    from ..reports import yadav2020 as report

    rows, traces = report.env_step_table(env_id=u.spec.id)
    return {"continuous": report.table2(dead_time=0.0), "env_rows": rows, "traces": traces}


def _yadav2020(ctx) -> list[str]:
    """Yadav et al.'s section 3.5 margins and Table 2, when an env on its plant (cncmt_axis) ran."""
    ran = _plant_envs(ctx, "cncmt_axis")
    if not ran:
        return []
    from ..reports import yadav2020 as report

    tables = ctx.prepared.get(ran[0], {}).get(KIND.name) or _yadav2020_tables(ctx.envs[ran[0]])
    lines = [
        "Yadav et al. (2020), section 3.5: CLCE coefficient bounds over the box, Kharitonov, SM of eq. (5)",
        "",
        report.format_kharitonov(),
    ]
    lines.append(
        report.format_table2(
            tables["continuous"],
            "\nTable 2, continuous loop without the dead time (as the paper computes it); cells: ours / paper's",
        )
    )
    rows, traces = tables["env_rows"], tables["traces"]
    lines.append(
        report.format_table2(
            rows,
            f"\nTable 2 on {ran[0]} (dead time 0.1 s exact, nominal and 10 plants "
            f"across the box); cells: ours / paper's",
        )
    )
    if ctx.plots is not None:
        path = ctx.plots / f"{ran[0]}_step_responses.png"
        report.plot_step_responses(traces, path, setpoint=rows[0].get("setpoint_mm", 10.0))
        ctx.plots_written.append(path)
    return lines


def _plant_envs(ctx, plant: str) -> list[str]:
    return [e for e in ctx.env_ids if getattr(getattr(ctx.envs[e].unwrapped, "plant", None), "name", None) == plant]


def _simba(ctx) -> list[str]:
    """Simba et al.'s ratios (ILC/FB per path, smoothed/linear FB) and the cycle times of both paths."""
    ran = _plant_envs(ctx, "current_feed_drive")
    if not ran:
        return []
    from ..papers import PAPER_SIMBA_CYCLE_TIME_INCREASE_PERCENT, paper_figures

    lines = ["Simba et al., section IV: max contour error ratios, ours (paper)"]
    fb = {}
    for e in ran:
        res = ctx.results.get(e, {})
        if "contouring-fb" in res:
            fb[e] = res["contouring-fb"].max_contour_error_um
        for ilc in ("ilc", "ilc-q"):
            if "contouring-fb" in res and ilc in res:
                paper = paper_figures(e, "ilc").get("max_contour_error_um")
                paper_fb = paper_figures(e, "contouring-fb").get("max_contour_error_um")
                ratio = res[ilc].max_contour_error_um / fb[e]
                ref = f" ({paper / paper_fb:.2f})" if paper and paper_fb else ""
                lines.append(f"  {e}: {ilc} (last trial) / contouring-fb = {ratio:.2f}{ref}")
    if "VCNC-Corners-v1" in fb and "VCNC-CornersSmooth-v1" in fb:
        paper = (
            paper_figures("VCNC-CornersSmooth-v1", "contouring-fb")["max_contour_error_um"]
            / paper_figures("VCNC-Corners-v1", "contouring-fb")["max_contour_error_um"]
        )
        lines.append(
            f"  contouring-fb, smoothed / linear path = "
            f"{fb['VCNC-CornersSmooth-v1'] / fb['VCNC-Corners-v1']:.3f} ({paper:.2f})"
        )
    durations = {e: ctx.envs[e].unwrapped.reference.duration for e in ran}
    if "VCNC-Corners-v1" in durations and "VCNC-CornersSmooth-v1" in durations:
        lin, smooth = durations["VCNC-Corners-v1"], durations["VCNC-CornersSmooth-v1"]
        lines.append(
            f"  cycle time (reference): linear {lin:.4f} s, smoothed {smooth:.4f} s: "
            f"{100 * (smooth / lin - 1):+.2f} % "
            f"(paper's experiment {PAPER_SIMBA_CYCLE_TIME_INCREASE_PERCENT:+.2f} %)"
        )
    return lines


def _purtojo(ctx) -> list[str]:
    """Purtojo et al.'s circle figures of every policy that ran on its table, and the radial-error plot."""
    lines = []
    for e in _plant_envs(ctx, "nct_xy_table"):
        from ..reports import circle as circle_report

        path = ctx.plots / f"{e}_radial_error.png" if ctx.plots is not None else None
        lines += circle_report.bench_report(ctx.results.get(e, {}), label=e, plot_path=path, shown=ctx.shown.get(e))
        if path is not None:
            ctx.plots_written.append(path)
    return lines


def _make(name: str, env):
    """Baseline ``name`` for ``env``; a floor checks a stored solution against the bench's own episode
    (``check_by_episode``: :func:`vcnc_bench.runner.run_env` calls its ``confirm``) instead of a replay of its own."""
    return make(name, env, check_by_episode=True) if name in FLOORS else make(name, env)


KIND = PolicyKind(
    name="baseline",
    make=_make,
    names=names,
    defaults=lambda env: [n for n in names() if applies(n, env) and in_default_table(n)],
    extras=lambda env: [n for n in names() if applies(n, env) and not in_default_table(n)],
    report=lambda ctx: _qft_stability(ctx) + _yadav2020(ctx) + _simba(ctx) + _purtojo(ctx) + _oracle(ctx),
    prepare=_yadav2020_tables,
    description="the papers' classical controllers (vcnc_baselines.names())",
)
