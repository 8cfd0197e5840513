"""G-code reader (vcnc_gym.gcode): geometry against independent computations, every bad-program case,
a property-based fuzz of the reader, the feeds, the test pieces and the env."""

from __future__ import annotations

import cmath
import re
import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geomdl_curve import geomdl_curve
from vcnc_gym.gcode import GCodeError, read_program, read_program_text
from vcnc_gym.gcode.pieces import PIECES, circle_program, piece_path

pytest.importorskip("pygcode")


def _arc_points(tp, k, n=257):
    lo, hi = tp.move_range(k)
    return tp.curve.points(np.linspace(lo, hi, n))


# ------------------------------------------------------------------ geometry


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-40, 40),
    st.floats(-40, 40),
    st.floats(-30, 30),
    st.floats(-30, 30),
    st.floats(0.05, 2 * math.pi - 0.05),
    st.booleans(),
)
def test_ij_arc_on_its_radius_with_the_programs_centre_and_sweep(x0, y0, i, j, sweep, ccw):
    """An I/J arc: every point on the circle about start + (I, J) to 1e-9 mm, its length r |sweep| with the
    sweep computed here from the words (complex arithmetic), end point as programmed."""
    r = math.hypot(i, j)
    if r < 0.5:
        return
    c = complex(x0 + i, y0 + j)
    z0 = complex(x0, y0)
    z1 = c + (z0 - c) * cmath.exp(1j * (sweep if ccw else -sweep))
    text = (
        f"G21 G90 G17\nG00 X{x0:.12f} Y{y0:.12f}\n{'G03' if ccw else 'G02'} X{z1.real:.12f} Y{z1.imag:.12f} "
        f"I{i:.12f} J{j:.12f} F600\n"
    )
    tp = read_program(text, None)
    (m,) = tp.program.moves
    pts = _arc_points(tp, 0)
    np.testing.assert_allclose(np.abs(pts[:, 0] + 1j * pts[:, 1] - c), r, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pts[-1], [z1.real, z1.imag], atol=1e-9)
    # the sweep from the words: the angle from start to end about the centre, in the direction of travel
    turn = cmath.phase((z1 - c) / (z0 - c)) % (2 * math.pi)
    expected = turn if ccw else 2 * math.pi - turn
    assert abs(abs(m.sweep) - expected) < 1e-9
    assert abs(tp.curve.arc_length() - r * expected) < 1e-9 * max(1.0, r)
    # the direction: the cross product of radius and tangent at the middle
    mid = tp.curve.derivatives(0.5 * sum(tp.move_range(0)), 1)
    cross = (mid[0, 0] - c.real) * mid[1, 1] - (mid[0, 1] - c.imag) * mid[1, 0]
    assert (cross > 0) == ccw


@pytest.mark.parametrize("code,sign", [("G02", 1), ("G02", -1), ("G03", 1), ("G03", -1)])
def test_r_arcs_both_signs(code, sign):
    """R > 0: the short arc, R < 0: the long one; the centre from circle intersections computed here."""
    p0, p1, radius = np.array([3.0, -1.0]), np.array([10.0, 4.0]), 6.5
    tp = read_program(f"G0 X{p0[0]} Y{p0[1]}\n{code} X{p1[0]} Y{p1[1]} R{sign * radius} F1200\n", None)
    (m,) = tp.program.moves
    # independent: the two centres at distance R from both points; the short arc's centre is on the right of
    # the chord for a clockwise arc
    d = np.linalg.norm(p1 - p0)
    h = math.sqrt(radius**2 - (d / 2) ** 2)
    left = np.array([-(p1 - p0)[1], (p1 - p0)[0]]) / d
    centres = [(p0 + p1) / 2 + h * left, (p0 + p1) / 2 - h * left]
    short_ccw, short_cw = centres[0], centres[1]
    expect = {("G03", 1): short_ccw, ("G02", 1): short_cw, ("G03", -1): short_cw, ("G02", -1): short_ccw}[(code, sign)]
    np.testing.assert_allclose(m.centre, expect, atol=1e-12)
    half = math.asin(d / 2 / radius)
    assert abs(abs(m.sweep) - (2 * half if sign > 0 else 2 * math.pi - 2 * half)) < 1e-12
    pts = _arc_points(tp, 0)
    np.testing.assert_allclose(np.linalg.norm(pts - expect, axis=1), radius, atol=1e-9)


def test_full_circle_and_geomdl():
    """A G02 back to its start point with I/J is a full circle; the NURBS evaluated by geomdl lies on it."""
    tp = read_program("G0 X25 Y0\nG02 X25 Y0 I-25 J0 F3000\n", None)
    (m,) = tp.program.moves
    assert m.sweep == -2 * math.pi
    g, a, b = geomdl_curve(tp.curve)
    vs = np.linspace(0, 1, 401)
    pts = np.array(g.evaluate_list(vs.tolist()))
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), 25.0, atol=1e-9)
    np.testing.assert_allclose(tp.curve.points(a + vs * (b - a)), pts, atol=1e-9)
    # clockwise: the angle decreases
    ang = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    assert ang[-1] - ang[0] == pytest.approx(-2 * math.pi, abs=1e-9)


def test_units_distance_modes_and_feeds():
    """G20 (inch) equals the mm program scaled by 25.4; G91 equals G90; F mm/min and in/min in mm/s."""
    mm = read_program("G21 G90\nG0 X0 Y0\nG1 X25.4 Y0 F600\nG3 X50.8 Y25.4 I0 J25.4\nG1 Y50.8 F1200\n", 0.01)
    inch = read_program(
        "G20 G90\nG0 X0 Y0\nG1 X1 Y0 F23.62204724409449\nG3 X2 Y1 I0 J1\nG1 Y2 F47.24409448818898\n", 0.01
    )
    rel = read_program("G21 G91\nG0 X0 Y0\nG1 X25.4 Y0 F600\nG3 X25.4 Y25.4 I0 J25.4\nG1 Y25.4 F1200\n", 0.01)
    us = np.linspace(*mm.curve.u_range, 101)
    for other in (inch, rel):
        np.testing.assert_allclose(other.curve.points(us), mm.curve.points(us), atol=1e-9)
        np.testing.assert_allclose(other.program.feeds, mm.program.feeds, rtol=1e-12)
    np.testing.assert_allclose(mm.program.feeds, [10.0, 10.0, 20.0])


def test_corner_blend_passes_at_the_tolerance():
    """A 90-degree G01 corner blended at 20 um: the path's closest approach to the vertex is 20 um (1e-9)."""
    tp = read_program("G0 X0 Y0\nG1 X30 Y0 F3000\nG1 X30 Y30\n", 0.02)
    assert [j.kind for j in tp.joints] == ["blend"]
    (blend,) = np.flatnonzero(tp.segment_blends)
    us = np.linspace(tp.edges[blend], tp.edges[blend + 1], 20001)
    assert abs(np.min(np.linalg.norm(tp.curve.points(us) - [30, 0], axis=1)) - 0.02) < 1e-9


def test_feed_plan_follows_the_blocks_and_stops_at_sharp_corners():
    """The look-ahead plan never exceeds a block's F, and reaches rest at the exact stop of a sharp corner."""
    from vcnc_gym.motion import interpolate

    tp = read_program("G0 X0 Y0\nG1 X20 Y0 F3000\nG1 X20 Y20 F1200\nG3 X0 Y20 R10\nG1 X0 Y0 F6000\n", None)
    assert [j.kind for j in tp.joints] == ["stop", "tangent", "tangent"]
    plan = tp.feedrate_profile().plan(tp.length)
    t = np.linspace(0, plan.duration, 20001)
    s, v = plan.distance(t), plan.velocity(t)
    seg = np.clip(np.searchsorted(tp.edges, s, side="right") - 1, 0, len(tp.feeds) - 1)
    assert np.all(v <= tp.feeds[seg] * (1 + 1e-9) + 1e-9)
    stop = tp.edges[tp.stops[0]]
    near = np.abs(s - stop) < 1e-6
    assert near.any() and np.all(v[near] < 1e-2)
    ref = interpolate(tp.curve, tp.feedrate_profile(), 1e-4)
    assert np.max(np.hypot(*ref.velocity.T)) <= 100.0 + 1e-6


def test_ignored_words_are_listed_and_zero_moves_warn():
    text = (
        "%\nO42 (part)\nN10 G21 G17 G90 G40\nN20 T1 M6\nN30 S1000 M3\nN40 G0 X0 Y0 Z5\nN50 G1 Z-1 F100\n"
        "N60 G1 X10 F600\nN70 G1 X10\nN80 Y10\nN90 G0 Z5\nN100 M30\nN110 G1 X0\n%"
    )
    with pytest.warns(UserWarning, match="zero length"):
        p = read_program_text(text)
    assert len(p.moves) == 2 and p.moves[0].number == 60
    words = {w for _, w, _ in p.ignored}
    assert {"O42", "T1", "M06", "S1000", "M03", "Z5", "Z-1", "G40", "M30", "N110 G1 X0"} <= words
    assert len(p.warnings) == 1 and "line 9" in p.warnings[0]


# ------------------------------------------------------------------ bad programs

BAD = [
    # (program, line, word, message fragment)
    ("G1 X10 Y0\n", 1, "G01", "before any F"),
    ("G1 X10 F0\n", 1, "F0", "must be > 0"),
    ("G18\nG1 X1 F1\n", 1, "G18", "XZ plane"),
    ("G19\n", 1, "G19", "YZ plane"),
    ("G1 X1 F10\nG41 X2\n", 2, "G41", "not supported"),
    ("G1 X1 F10\nG4 P1\n", 2, "G04", "not supported"),
    ("G1 X1 F10\nG1 X2 Q1\n", 2, "Q1", "not supported"),
    ("G1 X1 F10\nG1 X2 R1\n", 2, "R1", "no meaning in G01"),
    ("G0 X0\nG2 X10 Y0 F10\n", 2, None, "needs I/J"),
    ("G0 X0\nG2 X10 Y0 I5 R5 F10\n", 2, "R5", "both R and I/J"),
    ("G0 X0 Y0\nG2 X10 Y0 I4 J0 F10\n", 2, "I4", "radii disagree"),
    ("G0 X0 Y0\nG2 X10 Y0 R4 F10\n", 2, "R4", "shorter than half the chord"),
    ("G0 X0 Y0\nG2 X0 Y0 R4 F10\n", 2, "R4", "full circle needs I/J"),
    ("G0 X0 Y0\nG2 X0 Y0 I0 J0 F10\n", 2, "I0", "centre on the start point"),
    ("G0 X0 Y0\nG2 X10 Y0 R0 F10\n", 2, "R0", "must not be 0"),
    ("G1 X1.2.3 F10\n", 1, ".3", "cannot be lexed"),
    ("G1 X1.2.3\n", 1, ".3", "cannot be lexed"),
    ("G1 X1..2 F10\n", 1, ".2", "cannot be lexed"),
    ("G1 X F10\n", 1, "X", "cannot be lexed"),
    ("G1 X1 X2 F10\n", 1, "X2", "cannot be lexed"),
    ("G1 G2 X1 F10\n", 1, "G01 G02", "cannot be lexed"),
    ("G1 X1 F10 (open\n", 1, "(", "unbalanced"),
    ("G1 X1 F10 )\n", 1, ")", "unbalanced"),
    ("X10 Y10\n", 1, "X10", "without a motion mode"),
    ("G1 X10 F10\nG0 X20\nG1 X30\n", 2, "X20", "between cutting moves"),
    ("G21 G90\nG0 X5 Y5\nM30\n", None, None, "no cutting move"),
    ("G1 I5 F10\n", 1, "I5", "no meaning without an arc"),
    ("G1 X1 F10 #5\n", 1, "#5", "cannot be lexed"),
    ("G1 X1 F10 E2\n", 1, "E2", "not supported"),
    ("G1 X10 F10\nG3 X20 R5\nG1 Y-5\n", 3, "G01", "turns back on itself"),
    ("G1 X10 F10\nG1 X0\n", 2, "G01", "turns back on itself"),
    ("Oabc\nG1 X1 F10\n", 1, "Oabc", "is not a word"),
]


@pytest.mark.parametrize("text,line,word,fragment", BAD)
def test_bad_programs_name_the_line_and_the_word(text, line, word, fragment):
    with pytest.raises(GCodeError, match=fragment) as info:
        read_program(text, None)
    assert info.value.line == line
    assert info.value.word == word
    if line is not None:
        assert re.match(rf"line {line}\b", str(info.value))


def test_blend_that_does_not_fit_names_the_line():
    with pytest.raises(GCodeError, match="do not fit") as info:
        read_program("G0 X0 Y0\nG1 X1 Y0 F600\nG1 X1 Y1\nG1 X0 Y1\n", 2.0)
    assert info.value.line in (2, 3, 4) and info.value.word == "tolerance=2.0"


# ------------------------------------------------------------------ fuzz

_WORDS = st.one_of(
    st.sampled_from(
        [
            "G0",
            "G1",
            "G2",
            "G3",
            "G17",
            "G18",
            "G20",
            "G21",
            "G90",
            "G91",
            "G94",
            "G40",
            "G64",
            "M3",
            "M30",
            "T1",
            "S100",
            "N5",
            "(c)",
            ";c",
            "%",
            "(",
            ")",
            "#1",
            "G1.5",
            "X",
            "E3",
            "+",
            "..",
            "-",
        ]
    ),
    st.builds(
        lambda letter, v: f"{letter}{v}",
        st.sampled_from("XYIJRFZ"),
        st.one_of(st.integers(-60, 60), st.floats(-60, 60, allow_nan=False).map(lambda x: f"{x:.3f}")),
    ),
)
_LINES = st.lists(st.lists(_WORDS, min_size=0, max_size=6).map(" ".join), min_size=1, max_size=12)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_LINES, st.sampled_from([None, 0.01]))
def test_fuzz_reader_raises_value_error_or_returns_a_valid_contour(lines, tolerance):
    """Any text: a ValueError (GCodeError or a plain ValueError) or a toolpath whose contour starts at the
    first move's start and ends at the last move's end, through every move's end point."""
    text = "\n".join(lines)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tp = read_program(text, tolerance)
    except ValueError as e:
        assert str(e)
        return
    moves = tp.program.moves
    lo, hi = tp.curve.u_range
    np.testing.assert_allclose(tp.curve.point(lo), moves[0].start, atol=1e-7)
    np.testing.assert_allclose(tp.curve.point(hi), moves[-1].end, atol=1e-7)
    assert np.all(np.isfinite(tp.curve.control_points)) and tp.length > 0
    assert np.all(tp.feeds > 0)


# ------------------------------------------------------------------ test pieces and the env


def test_shipped_pieces_are_the_generators_output():
    from vcnc_gym.gcode import pieces

    assert piece_path("iso230-4-cw").read_text() == circle_program(direction="cw")
    assert piece_path("circle-diamond-square").read_text() == pieces.circle_diamond_square_program()
    assert piece_path("butterfly").read_text() == pieces.butterfly_program()
    for name in PIECES:
        tp = read_program(piece_path(name), 0.01)
        assert all(j.angle < 1e-3 or j.kind != "tangent" for j in tp.joints)


def test_butterfly_biarcs_are_tangent_and_on_the_curve():
    tp = read_program(piece_path("butterfly"), 0.01)
    assert {j.kind for j in tp.joints} == {"tangent"}
    assert max(j.angle for j in tp.joints) < 1e-5
    # every move ends on r = R (1 - 0.45 cos 2t - 0.15 cos 4t) every other move (the biarcs' knots)
    ends = np.array([m.end for m in tp.program.moves[1::2]])
    t = np.arctan2(ends[:, 1], ends[:, 0])
    r = 30 * (1 - 0.45 * np.cos(2 * t) - 0.15 * np.cos(4 * t))
    np.testing.assert_allclose(np.hypot(ends[:, 0], ends[:, 1]), r, atol=2e-6)


def test_gcode_env_runs_a_program_text_and_checks():
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import vcnc_gym  # noqa: F401

    text = "G21 G90\nG0 X0 Y0\nG1 X10 Y0 F3000\nG2 X20 Y0 R5\nG1 X20 Y-5\n"
    env = gym.make("VCNC-GCode-v1", program=text, tolerance=0.01)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped.toolpath.program.moves[1].code == "G02"
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(env.unwrapped.reference.position[0], [0, 0], atol=1e-12)
    with pytest.raises(ValueError, match="program's"):
        gym.make("VCNC-GCode-v1", program=text, feedrate=10.0)
    vec = gym.make_vec("VCNC-GCode-v1", num_envs=2, vectorization_mode="vector_entry_point", program=text)
    o, _ = vec.reset(seed=0)
    np.testing.assert_array_equal(o[0], obs)


def test_iso230_4_figures_against_a_known_path():
    """An ellipse-like path r = R + a cos 2 theta, shifted by (dx, dy): G = 2 a about its own centre, and the
    radial deviation about the nominal circle includes the shift; two directions together (G(b))."""
    from vcnc_gym.gcode.circular import circular_figures, least_squares_circle

    theta = np.linspace(0, 2 * np.pi, 3601)[:-1]
    R, a, shift = 25.0, 0.004, np.array([0.002, -0.001])
    pts = (R + a * np.cos(2 * theta))[:, None] * np.column_stack([np.cos(theta), np.sin(theta)]) + shift
    c, r = least_squares_circle(pts)
    np.testing.assert_allclose(c, shift, atol=1e-12)
    assert abs(r - R) < 1e-12
    fig = circular_figures(pts, [0, 0], R)
    assert fig.circular_deviation_um == pytest.approx(2 * a * 1e3, rel=1e-6)
    nominal = np.hypot(*pts.T) - R
    assert fig.radial_deviation_max_um == pytest.approx(1e3 * nominal.max(), rel=1e-12)
    # both directions: the second path 1 um larger all round
    both = circular_figures(
        np.vstack([pts, pts + 0.001 * (pts - shift) / np.hypot(*(pts - shift).T)[:, None]]), [0, 0], R
    )
    assert both.circular_deviation_um == pytest.approx(2 * a * 1e3 + 1.0, rel=1e-3)


def test_random_contour_env_is_reproducible_and_each_vector_env_has_its_own():
    import gymnasium as gym

    import vcnc_gym  # noqa: F401

    env = gym.make("VCNC-RandomContour-v1")
    obs1, info1 = env.reset(seed=3)
    obs2, info2 = env.reset(seed=4)
    obs3, info3 = env.reset(seed=3)
    assert info1["program"] == info3["program"] != info2["program"]
    np.testing.assert_array_equal(obs1, obs3)
    tp = env.unwrapped.toolpath if hasattr(env.unwrapped, "toolpath") else env.unwrapped.task.path
    assert 4 <= len(tp.program.moves) <= 8
    vec = gym.make_vec("VCNC-RandomContour-v1", num_envs=2)
    _, infos = vec.reset(seed=3)
    assert infos["program"][0] == info1["program"] and infos["program"][1] == info2["program"]


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_random_programs_follow_their_distributions(seed):
    from vcnc_gym.gcode.random_contour import RandomContourSpec, random_program

    spec = RandomContourSpec()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tp = read_program(random_program(np.random.default_rng(seed), spec), 0.01)
    moves = tp.program.moves
    assert spec.moves_min <= len(moves) <= spec.moves_max
    for m in moves:
        if m.kind == "line":
            assert spec.line_min - 1e-5 <= m.length <= spec.line_max + 1e-5
        else:
            assert spec.radius_min - 1e-5 <= m.radius <= spec.radius_max + 1e-5
            assert math.radians(spec.sweep_min) - 1e-5 <= abs(m.sweep) <= math.radians(spec.sweep_max) + 1e-5
    for j, (a, b) in zip(tp.joints, zip(moves[:-1], moves[1:])):
        if a.kind == b.kind == "line":
            assert (
                j.kind == "blend"
                and math.radians(spec.turn_min) - 1e-5 <= j.angle <= math.radians(spec.turn_max) + 1e-5
            )
        else:
            assert j.kind == "tangent"
    assert 2000 / 60 - 1e-9 <= tp.feeds[0] <= 6000 / 60 + 1e-9


def test_deviation_plot_signs_and_magnifies_against_a_known_path(tmp_path):
    """On the ISO 230-4 circle (counter-clockwise, left normal inwards) a path r = R + a cos 2 theta has the signed
    deviation -a cos 2 theta (1e-9 mm); the magnification is of the 1-2-5 series; the plot is written."""
    from types import SimpleNamespace

    import gymnasium as gym

    import vcnc_gym  # noqa: F401
    from vcnc_gym.deviation_plot import contour_corners, magnification, plot_deviation, signed_deviation

    env = gym.make("VCNC-ISO230Circle-v1")
    theta = np.linspace(0.0, 2 * np.pi, 721)
    a = 0.0029
    p = (25.0 + a * np.cos(2 * theta))[:, None] * np.column_stack([np.cos(theta), np.sin(theta)])
    _, _, e = signed_deviation(env, p)
    np.testing.assert_allclose(e, -a * np.cos(2 * theta), atol=1e-9)
    assert magnification(0.003, 50.0) == 1000.0 and magnification(0.02, 50.0) == 100.0
    assert contour_corners(env) == []
    m = plot_deviation({"synthetic": SimpleNamespace(position=p)}, env, tmp_path / "dev.png")
    assert m == 1000.0 and (tmp_path / "dev.png").stat().st_size > 1000
    cds = gym.make("VCNC-CircleDiamondSquare-v1")
    assert len(contour_corners(cds)) == 8  # 9 line corners and the link to the circle, capped at MAX_INSETS


def test_bench_runs_programs_and_reports_iso230_4(monkeypatch, tmp_path, capsys):
    """vcnc-bench --program iso230-4 --circle D F: both directions run, the ISO table is printed and in the JSON
    (G(b) on both rows), the deviation plots are written; a missing program file is an argument error."""
    import json

    from test_bench import _install_pd

    import vcnc_bench as bench

    _install_pd(monkeypatch)
    out_json, plots = tmp_path / "bench.json", tmp_path / "plots"
    assert (
        bench.main(
            [
                "--jobs",
                "1",
                "--program",
                "iso230-4",
                "--circle",
                "10",
                "1200",
                "--policy",
                "pd:300",
                "--json",
                str(out_json),
                "--plots",
                str(plots),
                "--no-progress",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "ISO 230-4 circular test" in out
    iso = [r for r in json.loads(out_json.read_text())["records"] if r.get("table") == "iso230-4"]
    assert {r["direction"] for r in iso} == {"ccw", "cw"}
    for r in iso:
        assert r["bidirectional_circular_deviation_um"] >= 0.9 * r["circular_deviation_um"] > 0
        assert r["radial_deviation_min_um"] <= r["radial_deviation_max_um"]
    assert (plots / "GCode:iso230-4-ccw-D10-F1200_deviation.png").stat().st_size > 1000
    with pytest.raises(SystemExit):
        bench.main(["--program", str(tmp_path / "missing.nc"), "--no-progress"])


def test_blends_are_simba_smooth_polyline():
    """The reader's blends (designs cached by angle) lie on smooth_polyline's path to 1e-7 mm and back."""
    from vcnc_gym.contour import ContourProjector
    from vcnc_gym.geometry.corners import smooth_polyline

    vertices = [[0, 0], [30, 0], [30, 20], [5, 27.5], [12, 3.25]]
    text = "G0 X0 Y0\n" + "".join(f"G1 X{x} Y{y} F3000\n" for x, y in vertices[1:])
    tp = read_program(text, 0.02, acceleration=1000.0, jerk=3e4)
    ref = smooth_polyline(vertices, 0.02, 1000.0, 3e4).curve
    ours = tp.curve
    for a, b in ((ref, ours), (ours, ref)):
        pts = a.points(np.linspace(*a.u_range, 20001))
        d, _ = ContourProjector(b).project(pts)
        assert np.max(d) < 1e-7
    assert abs(ours.arc_length() - ref.arc_length()) < 1e-7


def test_random_contours_of_the_xy_table_keep_its_scale_and_path_limits():
    """Purtojo et al.'s table draws the contours its model declares (PlantModel.random_contour: 0.5-3 mm lines,
    0.2-2 mm arcs, 30-120 mm/min); the
    reference's speed, differenced from its positions, stays within the feed, its acceleration within the path
    limit (30 mm/s^2);
    a spec given as a dict (YAML) is the same spec; a misspelt field is named."""
    import gymnasium as gym

    import vcnc_gym  # noqa: F401
    from vcnc_gym.gcode import path_limits
    from vcnc_gym.gcode.random_contour import RandomContourSpec, spec_for

    spec = spec_for("nct_xy_table")
    assert (spec.line_min, spec.line_max, spec.radius_min, spec.radius_max, spec.feed_min, spec.feed_max) == (
        0.5,
        3.0,
        0.2,
        2.0,
        30.0,
        120.0,
    )
    env = gym.make("VCNC-RandomContour-v1", plant="nct_xy_table", dt=1e-3)
    for seed in (0, 1):
        env.reset(seed=seed)
        u = env.unwrapped
        for m in u.task.path.program.moves:
            if m.kind == "line":
                assert spec.line_min - 1e-5 <= m.length <= spec.line_max + 1e-5
            else:
                assert spec.radius_min - 1e-5 <= m.radius <= spec.radius_max + 1e-5
        xy = u.reference.position[:-1]  # the last sample is the curve's end, at any distance (Reference)
        speed = np.hypot(*np.diff(xy, axis=0).T) / u.dt
        assert speed.max() <= 1.001 * spec.feed_max / 60
        assert np.hypot(*u.reference.acceleration.T).max() < 1.05 * path_limits("nct_xy_table")[0] == 1.05 * 30.0
    assert spec_for("nct_xy_table", {"feed_min": 30.0, "feed_max": 120.0}) == RandomContourSpec(
        feed_min=30.0, feed_max=120.0
    )
    assert spec_for("vcnc_feed_drive") == RandomContourSpec()
    with pytest.raises(ValueError, match="feed_mni"):
        spec_for("nct_xy_table", {"feed_mni": 1.0})
