"""A part program as the suite's contour: one NURBS, corner blends, the feed plan.

:func:`build_toolpath` turns the moves of :mod:`vcnc_gym.gcode.interpreter`
into

- one :class:`~vcnc_gym.geometry.NurbsCurve`: G01 moves as straight Bezier
  segments, G02/G03 as exact rational quadratic arcs
  (:mod:`vcnc_gym.gcode.arcs`); interior knots of full multiplicity (every
  segment a Bezier piece), knot spans equal to the segments' arc lengths, so
  u is close to the arc length in mm;
- at every corner between two G01 moves, with a ``tolerance`` (mm), Simba et al.'s
  quintic Bezier blend (Simba et al., eqs. (12)-(23),
  :func:`vcnc_gym.geometry.corners.smooth_polyline`): the path passes the
  corner at ``tolerance`` from the programmed vertex, like a CNC's
  path-blending tolerance (G64 P on LinuxCNC, "smoothing tolerance" on others).
  The blend is designed for the look-ahead's acceleration and jerk.  With
  blends the whole curve is raised to degree 5 (arcs elevated exactly);
  without, it is of degree 2;
- an exact stop (the feed down to zero, :mod:`vcnc_gym.gcode.feeds`) at every
  other corner: all of them with ``tolerance=None`` (sharp), and, with a
  tolerance, the corners where an arc meets a line or another arc (Simba et al.'s
  blend joins two straight legs); a path that turns back on itself (a
  180-degree corner) is an error naming the line;
- the feed of every segment: its block's F; over a blend the lower F of its two blocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.corners import bezier_arc_length, blend_control_points, corner_length, design_corner
from ..geometry.nurbs import NurbsCurve
from . import arcs
from ..motion.lookahead import DEFAULT_SPACING, MAX_LIMIT_SAMPLES
from .feeds import KINK_ANGLE, TANGENT_ANGLE, ProgramFeedrate, ProgramProfile
from .interpreter import Move, Program
from .lexer import GCodeError

__all__ = ["Joint", "Toolpath", "build_toolpath", "corner_side", "PROFILES"]

#: Feed profiles a toolpath can be run with: the look-ahead with every block's feed and exact stops
#: (default), or, for a program with one feed, Jahanpour et al.'s S-curve or a constant feed from t = 0 (no stops).
PROFILES = ("lookahead", "scurve", "constant")


#: A joint whose tangent turns by more than pi minus this (rad) turns back on itself: an error.
U_TURN_ANGLE = 1e-6


@dataclass(frozen=True)
class Joint:
    """Where one move ends and the next begins.

    Attributes
    ----------
    lines : (int, int)
        Program lines of the two moves.
    angle : float
        How far the tangent turns there, rad (0: tangent, pi: a U-turn).
    kind : str
        ``"tangent"`` (<= TANGENT_ANGLE, run through), ``"blend"`` (Simba et al.'s blend), ``"kink"`` (a corner
        between two G01 moves of at most ``KINK_ANGLE`` whose blend does not fit: run through) or ``"stop"``
        (exact stop).
    """

    lines: tuple
    angle: float
    kind: str


@dataclass(frozen=True)
class _Segment:
    points: np.ndarray  # homogeneous (k + 1, 3)
    length: float  # arc length, mm
    feed: float  # mm/s
    move: int  # index of the move (the first of the two for a blend)
    blend: bool
    radius: float = math.inf  # an arc's radius, mm


@dataclass(frozen=True)
class Toolpath:
    """A program ready to run: its contour, corners and feeds.

    Attributes
    ----------
    program : Program
        The interpreted program.
    curve : NurbsCurve
        The whole contour, mm.
    tolerance : float or None
        The corner blending tolerance, mm (None: sharp, exact stops).
    joints : tuple of Joint
        One per pair of consecutive moves.
    edges : (n + 1,) array
        Arc lengths of the segment boundaries along the contour, mm (the curve's knots).
    feeds : (n,) array
        Programmed feed of each segment, mm/s.
    stops : tuple of int
        Indices into ``edges`` of the exact stops.
    segment_moves : (n,) int array
        The move (index into ``program.moves``) of each segment; for a blend, the first of its two moves.
    segment_blends : (n,) bool array
        True for the corner blends.
    acceleration, jerk : float
        Path acceleration (mm/s^2) and jerk (mm/s^3) limits of the blends and the look-ahead.
    spacing : float
        The look-ahead's curvature sample spacing, mm.
    """

    program: Program
    curve: NurbsCurve
    tolerance: float | None
    joints: tuple
    edges: np.ndarray
    feeds: np.ndarray
    stops: tuple
    segment_moves: np.ndarray
    segment_blends: np.ndarray
    acceleration: float
    jerk: float
    _sections: tuple
    spacing: float = DEFAULT_SPACING

    @property
    def name(self) -> str:
        return self.program.name

    @property
    def length(self) -> float:
        """Arc length of the contour, mm."""
        return float(self.edges[-1])

    @property
    def feed(self) -> float | None:
        """The program's one feed (mm/s), or None when it has several."""
        values = np.unique(self.feeds)
        return float(values[0]) if values.size == 1 else None

    def move_range(self, k: int) -> tuple[float, float]:
        """The parameter (u) range of move ``k``'s own segments on ``curve`` (blends excluded)."""
        mine = np.flatnonzero((self.segment_moves == k) & ~self.segment_blends)
        return float(self.edges[mine[0]]), float(self.edges[mine[-1] + 1])

    def feedrate_profile(self, profile: str = "lookahead", ramp_time: float | None = None):
        """The feed profile of ``profile`` (:data:`PROFILES`) for this program."""
        from ..motion import ConstantFeedrate, SCurveFeedrate

        if profile not in PROFILES:
            raise ValueError(f"profile must be one of {list(PROFILES)} for a G-code program, got {profile!r}")
        if profile != "scurve" and ramp_time is not None:
            raise ValueError(f"ramp_time (s) shapes the S-curve only; profile={profile!r} has no ramp time to set")
        if profile == "lookahead":
            return ProgramProfile(
                [
                    ProgramFeedrate(curve, edges, feeds, self.acceleration, self.jerk, cuts, self.spacing)
                    for curve, edges, feeds, cuts in self._sections
                ]
            )
        if self.feed is None:
            raise ValueError(
                f"profile={profile!r} runs one feed; this program has several "
                f"({sorted(set(self.feeds.tolist()))} mm/s): use profile='lookahead'"
            )
        if profile == "constant":
            return ConstantFeedrate(self.feed)
        return SCurveFeedrate(self.feed, 0.12 if ramp_time is None else ramp_time)


def _turn(a: np.ndarray, b: np.ndarray) -> float:
    return float(math.atan2(abs(a[0] * b[1] - a[1] * b[0]), float(np.dot(a, b))))


def _arc_pieces(m: Move) -> list[tuple[np.ndarray, float]]:
    centre = m.centre
    assert centre is not None  # an arc's
    a0 = math.atan2(m.start[1] - centre[1], m.start[0] - centre[0])
    segs = arcs.arc_segments(centre, m.radius, a0, m.sweep)
    each = m.radius * abs(m.sweep) / len(segs)
    return [(s, each) for s in segs]


def build_toolpath(
    program: Program, tolerance: float | None, acceleration: float, jerk: float, spacing: float = DEFAULT_SPACING
) -> Toolpath:
    """The contour and feeds of an interpreted program (module docstring).

    Parameters
    ----------
    program : Program
    tolerance : float or None
        Corner blending tolerance, mm (> 0), or None for sharp corners with exact stops.
    acceleration, jerk : float
        Path acceleration (mm/s^2) and jerk (mm/s^3) limits: of the blends' design and of the look-ahead.

    Raises
    ------
    GCodeError
        If a blend does not fit (the tolerance is too large for a move), naming the move's line.
    """
    moves = program.moves
    joints = []
    for k in range(len(moves) - 1):
        a, b = moves[k], moves[k + 1]
        angle = _turn(a.tangent(True), b.tangent(False))
        if angle >= math.pi - U_TURN_ANGLE:
            raise GCodeError(
                f"the path turns back on itself where the move of line {a.line} ends (a "
                f"180-degree corner: no contour to follow through it)",
                b.line,
                b.code,
                None,
            )
        if angle <= TANGENT_ANGLE:
            kind = "tangent"
        elif tolerance is not None and a.kind == b.kind == "line":
            # a blend passing the corner at the tolerance reaches at least tolerance / sin(turn / 2) along each
            # leg (it lies in the triangle of the vertex and its ends): a kink whose shorter leg is shorter
            # cannot be blended, and is known so without designing the blend (a CAM program's thousands of chords)
            short = tolerance / math.sin(0.5 * angle) >= min(a.length, b.length)
            kind = "kink" if angle <= KINK_ANGLE and short else "blend"
        else:
            kind = "stop"
        joints.append(Joint((a.line, b.line), angle, kind))

    while True:
        try:
            segments, stop_after = _segments(moves, joints, tolerance, acceleration, jerk)
            break
        except _NoFit as no_fit:  # kinks of CAM chords: run through (KINK_ANGLE), then build again
            kinks = [k for k in no_fit.joints if joints[k].angle <= KINK_ANGLE]
            if not kinks:
                raise no_fit.error from None
            for k in kinks:
                joints[k] = Joint(joints[k].lines, joints[k].angle, "kink")

    samples = sum(max(8, math.ceil(s.length / spacing)) + 1 for s in segments)
    if samples > MAX_LIMIT_SAMPLES:  # before the look-ahead samples it (its own check comes after the work)
        length = sum(s.length for s in segments)
        raise GCodeError(
            f"the program's path is {length:.6g} mm long in {len(segments)} segments: the look-ahead "
            f"samples its curvature every {spacing:g} mm and plans at most MAX_LIMIT_SAMPLES = "
            f"{MAX_LIMIT_SAMPLES:,} samples (vcnc_gym.motion.lookahead), about "
            f"{MAX_LIMIT_SAMPLES * spacing:g} mm of path; split the program into shorter contours"
        )
    degree = max(s.points.shape[0] - 1 for s in segments)
    degree = 5 if degree > 2 else 2
    lengths = np.array([s.length for s in segments])
    edges = np.concatenate([[0.0], np.cumsum(lengths)])
    curve = _curve([s.points for s in segments], edges, degree)
    feeds = np.array([s.feed for s in segments])
    cuts = [0] + stop_after + [len(segments)]
    sections = []
    for c0, c1 in zip(cuts[:-1], cuts[1:]):
        local = edges[c0 : c1 + 1] - edges[c0]
        section = curve if len(cuts) == 2 else _curve([s.points for s in segments[c0:c1]], local, degree)
        sections.append(
            (
                section,
                local,
                feeds[c0:c1],  # one section: the curve itself (its checks are cached)
                _cuts(segments[c0:c1], acceleration, jerk),
            )
        )
    segment_moves = np.array([s.move for s in segments])
    segment_blends = np.array([s.blend for s in segments])
    for a in (edges, feeds, segment_moves, segment_blends):
        a.flags.writeable = False
    return Toolpath(
        program=program,
        curve=curve,
        tolerance=tolerance,
        joints=tuple(joints),
        edges=edges,
        feeds=feeds,
        stops=tuple(stop_after),
        segment_moves=segment_moves,
        segment_blends=segment_blends,
        acceleration=acceleration,
        jerk=jerk,
        spacing=spacing,
        _sections=tuple(sections),
    )


def _segments(moves, joints, tolerance, acceleration, jerk):
    """(segments, stop_after) of the moves joined as ``joints`` says (:func:`build_toolpath`)."""
    segments: list[_Segment] = []
    stop_after: list[int] = []  # segment counts at which an exact stop falls
    failed = None
    k = 0
    while k < len(moves):
        m = moves[k]
        if m.kind == "arc":
            segments += [_Segment(p, length, m.feed, k, False, m.radius) for p, length in _arc_pieces(m)]
            k += 1
        else:
            run = [k]  # lines joined by blends
            while run[-1] < len(joints) and joints[run[-1]].kind == "blend":
                run.append(run[-1] + 1)
            try:
                segments += _lines(moves, run, tolerance, acceleration, jerk)
            except _NoFit as no_fit:  # go on: every move whose blends do not fit, in one pass
                failed = failed or no_fit
                failed.joints += [j for j in no_fit.joints if j not in failed.joints]
            k = run[-1] + 1
        if k - 1 < len(joints) and joints[k - 1].kind == "stop":
            stop_after.append(len(segments))
    if failed is not None:
        raise failed
    return segments, stop_after


class _NoFit(Exception):
    """The blends of a move do not fit: ``joints`` the blended corners at its ends, ``error`` the GCodeError."""

    def __init__(self, joints: list, error: GCodeError):
        super().__init__(str(error))
        self.joints, self.error = joints, error


def _cuts(segments: list, acceleration: float, jerk: float) -> np.ndarray:
    """Edges where the look-ahead must cut (:class:`~vcnc_gym.gcode.feeds.ProgramFeedrate`): the feed changes,
    or one side is an arc (not the same arc's next quarter) whose curvature holds the feed below its F."""
    cuts = np.zeros(len(segments) + 1, dtype=bool)

    def slow(s):
        k = 1.0 / s.radius
        return k > 0 and min(math.sqrt(acceleration / k), (jerk / k**2) ** (1.0 / 3.0)) < s.feed

    for e in range(1, len(segments)):
        a, b = segments[e - 1], segments[e]
        same_arc = a.move == b.move and math.isfinite(a.radius)
        cuts[e] = a.feed != b.feed or (not same_arc and (slow(a) or slow(b)))
    return cuts


#: Simba et al.'s corner designs (the optimal length ratio n of eqs. (16)-(20), a golden-section search of ~0.15 s)
#: are cached by the interior angle rounded to this many rad: the design is made at the rounded angle, the
#: blend itself at the exact one (l_t of eq. (13) from the exact angle: the path passes the corner at exactly
#: the tolerance); n is at an optimum, so a 5e-6 rad shift of its angle changes the corner speed by nothing
#: measurable.  Programs with many equal corners (a square's four) and random contours (angles drawn on a grid)
#: design each angle once.
ANGLE_QUANTUM = 1e-5
_DESIGNS: dict = {}
_MAX_DESIGNS = 100_000


def _design(theta: float, tolerance: float, acceleration: float, jerk: float):
    key = (round(theta / ANGLE_QUANTUM), tolerance, acceleration, jerk)
    design = _DESIGNS.get(key)
    if design is None:
        if len(_DESIGNS) >= _MAX_DESIGNS:
            _DESIGNS.clear()
        design = _DESIGNS[key] = design_corner(key[0] * ANGLE_QUANTUM, tolerance, acceleration, jerk)
    return design


def corner_side(turn: float, tolerance: float, acceleration: float, jerk: float) -> float:
    """How much of each leg Simba et al.'s blend of a corner takes, mm: the side l_s of eq. (22) of a corner
    where the tangent turns by ``turn`` rad, at ``tolerance`` mm (as :func:`build_toolpath` blends it)."""
    theta = math.pi - turn
    design = _design(theta, tolerance, acceleration, jerk)
    return max(corner_length(theta, tolerance, design.n), corner_length(theta, tolerance, max(design.n_a, design.n_j)))


def _lines(moves: list[Move], run: list[int], tolerance, acceleration, jerk) -> list[_Segment]:
    """Segments of consecutive G01 moves ``run`` joined by Simba et al.'s blends (one move: a straight segment).

    As :func:`vcnc_gym.geometry.corners.smooth_polyline` builds them (eqs. (12)-(23): control points on the
    legs, l_t from eq. (13), the corner segments' side l_s of eq. (22) must fit in every line), with the
    designs cached (``ANGLE_QUANTUM``)."""
    if len(run) == 1:
        m = moves[run[0]]
        return [_Segment(arcs.line_segment(m.start, m.end), m.length, m.feed, run[0], False)]
    vertices = [moves[run[0]].start] + [moves[i].end for i in run]
    dirs = [moves[i].tangent(False) for i in run]
    blends, sides = [], [0.0]
    for k in range(len(run) - 1):
        d_in, d_out = dirs[k], dirs[k + 1]
        theta = math.pi - _turn(d_in, d_out)  # the interior angle of Simba et al.'s Fig. 3
        try:
            design = _design(theta, tolerance, acceleration, jerk)
        except ValueError as exc:  # a corner sharper than the blend design reaches
            raise GCodeError(
                f"the corner where this move begins cannot be blended: {exc}",
                moves[run[k + 1]].line,
                moves[run[k + 1]].code,
            ) from None
        l_t = corner_length(theta, tolerance, design.n)
        l_s = max(l_t, corner_length(theta, tolerance, max(design.n_a, design.n_j)))
        ctrl = blend_control_points(vertices[k + 1], d_in, d_out, l_t, design.n)
        blends.append((ctrl, bezier_arc_length(ctrl)))
        sides.append(l_s)
    sides.append(0.0)
    failed = None
    for k, i in enumerate(run):
        need = sides[k] + sides[k + 1]
        if need >= moves[i].length:
            corners = [i - 1] * (k > 0) + [i] * (k < len(run) - 1)  # the joints at its ends (joint j: moves j, j+1)
            if failed is None:
                failed = _NoFit(
                    [],
                    GCodeError(
                        f"the corner blends do not fit: tolerance = {tolerance:g} mm is too large for this "
                        f"{moves[i].length:.6g} mm move; its corner segments take {need:.6g} mm (side l_s of Simba et "
                        f"al.'s eq. (22)); corners of at most {math.degrees(KINK_ANGLE):g} degree are run through",
                        moves[i].line,
                        f"tolerance={tolerance!r}",
                    ),
                )
            failed.joints += [j for j in corners if j not in failed.joints]
    if failed is not None:
        raise failed
    out = []
    start = np.asarray(vertices[0], dtype=np.float64)
    for k, i in enumerate(run):
        end = blends[k][0][0] if k < len(blends) else np.asarray(vertices[-1], dtype=np.float64)
        out.append(_Segment(arcs.line_segment(start, end), float(np.hypot(*(end - start))), moves[i].feed, i, False))
        if k < len(blends):
            ctrl, s_arc = blends[k]
            out.append(
                _Segment(arcs.homogeneous(ctrl, np.ones(6)), s_arc, min(moves[i].feed, moves[i + 1].feed), i, True)
            )
            start = ctrl[-1]
    return out


def _curve(pieces: list[np.ndarray], edges: np.ndarray, degree: int) -> NurbsCurve:
    """One NURBS of Bezier ``pieces`` (homogeneous), knot spans ``edges``' differences."""
    hom = [arcs.elevate(p, degree) for p in pieces]
    control = np.concatenate([hom[0]] + [h[1:] for h in hom[1:]])
    knots = np.concatenate(
        [np.full(degree + 1, edges[0])] + [np.full(degree, u) for u in edges[1:-1]] + [np.full(degree + 1, edges[-1])]
    )
    w = control[:, 2]
    return NurbsCurve(control[:, :2] / w[:, None], w, knots, degree)
