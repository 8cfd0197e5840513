"""``vcnc-bench --program PART``: a user's G-code part programs and the standard test pieces on the bench.

Each program runs as ``VCNC-GCode-v1`` (``program=``, ``tolerance=``) under
the name ``GCode:<name>`` in the table, with every policy that applies to its
plant.  A program name of :data:`vcnc_gym.gcode.pieces.PIECES` runs the
shipped piece; ``iso230-4`` runs the ISO 230-4 circular test both ways
(``--circle D F``: diameter in mm and feed in mm/min; default the shipped 50 mm
at 3000 mm/min).  For every env whose program has a full circle, the ISO
230-4 figures of the table's path over that circle are reported beside max
and RMS contour error (:func:`circular_report`), and the bidirectional
circular deviation when both directions of one circle ran.
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np

from vcnc_gym.gcode.circular import circular_figures
from vcnc_gym.gcode.pieces import PIECES, circle_program, piece_path

__all__ = ["PROGRAM_PREFIX", "expand_programs", "program_recipes", "make_program_envs", "circular_report"]

#: Table names of program envs start with this.
PROGRAM_PREFIX = "GCode:"


def expand_programs(specs: list[str], circle: tuple[float, float] | None) -> list[tuple[str, object]]:
    """(name, program) pairs: a file path, a test piece name, or ``iso230-4`` (both directions)."""
    out = []
    for spec in specs:
        if spec == "iso230-4" or (circle is not None and spec in ("iso230-4-ccw", "iso230-4-cw")):
            directions = ("ccw", "cw") if spec == "iso230-4" else (spec.rsplit("-", 1)[1],)
            for d in directions:
                if circle is None:
                    out.append((f"iso230-4-{d}", piece_path(f"iso230-4-{d}")))
                else:
                    text = circle_program(circle[0], circle[1], d)
                    out.append((f"iso230-4-{d}-D{circle[0]:g}-F{circle[1]:g}", text))
        elif spec in PIECES:
            out.append((spec, piece_path(spec)))
        else:
            path = Path(spec)
            if not path.is_file():
                raise ValueError(
                    f"--program {spec!r}: no such file, and not a test piece ({', '.join(PIECES)}, iso230-4)"
                )
            out.append((path.stem, path))
    return out


def program_recipes(
    programs: list[tuple[str, object]], tolerance: float | None, plant: str | None = None, shop_floor: bool = False
) -> list[tuple[str, str, dict]]:
    """(table name, id, ``gym.make`` arguments) of ``VCNC-GCode-v1`` for each program, on ``plant`` (a plant's
    name) if given, on its shop floor if ``shop_floor``."""
    extra = ({} if plant is None else {"plant": plant}) | ({"shop_floor": True} if shop_floor else {})
    return [
        (PROGRAM_PREFIX + name, "VCNC-GCode-v1", {"program": program, "tolerance": tolerance, **extra})
        for name, program in programs
    ]


def make_program_envs(programs: list[tuple[str, object]], tolerance: float | None, plant: str | None = None) -> dict:
    """{table name: env} of ``VCNC-GCode-v1`` for each program, on ``plant`` (a plant's name) if given."""
    return {key: gym.make(env_id, **kwargs) for key, env_id, kwargs in program_recipes(programs, tolerance, plant)}


def _full_circle(env):
    """(move index, centre, radius, ccw) of the program's first full circle, or None."""
    path = getattr(getattr(env.unwrapped, "task", None), "path", None)
    program = getattr(path, "program", None)
    if program is None:
        return None
    for k, m in enumerate(program.moves):
        if m.kind == "arc" and abs(abs(m.sweep) - 2 * math.pi) < 1e-12:
            return k, m.centre, m.radius, m.sweep > 0
    return None


def _measured(env, result, k) -> np.ndarray:
    """The table positions at the steps whose reference point is on move ``k`` (the measured circle)."""
    u0, u1 = env.unwrapped.task.path.move_range(k)
    ref = env.unwrapped.reference
    index = np.clip(np.rint(result.time / env.unwrapped.dt).astype(int), 0, len(ref.u) - 1)
    on = (ref.u[index] >= u0) & (ref.u[index] <= u1)
    return result.position[on]


def circular_report(results: dict, envs: dict) -> tuple[list[str], list[dict]]:
    """Lines of the ISO 230-4 table and its records, for every env (by key) whose program has a full circle.

    ``results``: {env key: {policy label: EpisodeResult}}.
    """
    rows, circles = [], {}
    for key, by_policy in results.items():
        env = envs[key]
        found = _full_circle(env)
        if found is None:
            continue
        k, centre, radius, ccw = found
        for label, result in by_policy.items():
            pts = _measured(env, result, k)
            if len(pts) < 3:
                continue
            fig = circular_figures(pts, centre, radius)
            rows.append(
                {
                    "env": key,
                    "policy": label,
                    "direction": "ccw" if ccw else "cw",
                    "circular_deviation_um": fig.circular_deviation_um,
                    "radial_deviation_max_um": fig.radial_deviation_max_um,
                    "radial_deviation_min_um": fig.radial_deviation_min_um,
                    "max_contour_error_um": result.max_contour_error_um,
                    "rms_contour_error_um": result.rms_contour_error_um,
                    "points": fig.points,
                }
            )
            circles.setdefault((tuple(np.round(centre, 9)), round(radius, 9), label), []).append((ccw, pts))
    if not rows:
        return [], []
    bidirectional = {}
    for (centre, radius, label), runs in circles.items():
        if {ccw for ccw, _ in runs} == {True, False}:
            fig = circular_figures(np.vstack([p for _, p in runs]), centre, radius)
            bidirectional[(centre, radius, label)] = fig.circular_deviation_um
    lines = [
        "ISO 230-4 circular test from the table's path over the measured 360 degrees (um): G circular "
        "deviation (least-squares centre), F radial deviation (nominal centre), G(b) bidirectional "
        "(both directions of the same circle)",
        f"{'env':<34} {'policy':<12} {'dir':>4} {'G':>9} {'F_max':>9} {'F_min':>9} {'G(b)':>9} "
        f"{'max_um':>9} {'rms_um':>9}",
    ]
    for r in rows:
        key = (
            tuple(np.round(_full_circle(envs[r["env"]])[1], 9)),
            round(_full_circle(envs[r["env"]])[2], 9),
            r["policy"],
        )
        gb = bidirectional.get(key)
        r["bidirectional_circular_deviation_um"] = gb
        lines.append(
            f"{r['env']:<34} {r['policy']:<12} {r['direction']:>4} {r['circular_deviation_um']:9.2f} "
            f"{r['radial_deviation_max_um']:9.2f} {r['radial_deviation_min_um']:9.2f} "
            f"{'-' if gb is None else f'{gb:9.2f}':>9} {r['max_contour_error_um']:9.2f} "
            f"{r['rms_contour_error_um']:9.2f}"
        )
    return lines, rows
