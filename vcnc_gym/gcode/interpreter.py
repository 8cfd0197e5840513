"""Interpreting lexed blocks into moves: RS-274 modal state, arcs from I/J or R, units, feeds.

The rules are those of RS-274/NGC (Kramer, Proctor and Messina 2000, NIST IR
6556; the dialect of LinuxCNC and, for what is read here, of Fanuc-style
controls).  Within a block the order of execution is that of RS-274/NGC
table 8: feed (F), units (G20/G21), plane (G17), distance mode (G90/G91),
then the motion.

What is read
------------
- **G00** rapid positioning.  The env follows one contour at a programmed
  feed and has no "air" moves, so rapids are used only to position the tool:
  every rapid before the first cutting move moves the contour's start point
  (the env's table starts there, at rest); rapids after the last cutting move
  (retracts) are listed in ``Program.ignored``; a rapid that moves X or Y
  between two cutting moves would leave the contour, and is an error naming
  its line (split the program into one contour per part).
- **G01** straight feed move; **G02**/**G03** clockwise/counter-clockwise
  arcs in the XY plane (seen from +Z), with the centre's offsets **I**, **J**
  from the start point (incremental, RS-274's default), or the radius **R**:
  R > 0 for the arc of at most 180 degrees, R < 0 for the longer one.  A
  G02/G03 whose end point is its start point (to ``ZERO_LENGTH``, 1 nm)
  with I/J is a full circle; with R it is an error (no centre is defined).
- **G17** (the XY plane) only; G18/G19 are errors.  **G90**/**G91**
  absolute/incremental X and Y.  **G20**/**G21** inch/mm (mm at the start),
  applied to X, Y, I, J, R and F.  **G94** (feed per minute), the only feed
  mode: **F** in mm/min or in/min, turned into mm/s.
- **G40**, **G49**, **G80**, **G54**: cutter compensation off, tool length
  offset off, canned cycles off, the first work offset: with no compensation,
  no Z, no cycles and the program's coordinates taken as the machine's, they
  change nothing here; each is listed in ``Program.ignored``.
- **M**, **T**, **S**, **O** and **Z** words are listed in ``Program.ignored``
  (the machine is biaxial; spindle, coolant and tools are not simulated).
  **M02**/**M30** end the program: the lines after it are listed, not read.
- **N** line numbers are kept with each move.

Anything else (another G code, a letter not listed, a word a block does not
use, such as R on a G01 or K, P on an arc) is a :class:`GCodeError` naming
the line and the word, as are: a cutting move before any F; F <= 0; an arc
with neither or both of I/J and R, whose centre is at its start point, whose
R is shorter than half its chord beyond ``RADIUS_TOLERANCE``, or whose two
radii (start and end to the I/J centre) differ by more than the arc
tolerance; a program without a cutting move.

An I/J arc whose radii differ within the tolerance is made exact by moving
its centre onto the perpendicular bisector of its chord (the nearest such
point to the programmed centre), as a control that ends the arc on its
programmed end point must; ``Move.centre_shift`` records the shift.

Numbers beyond ``MAX_COORDINATE`` (X, Y, I, J, R, mm), ``MAX_FEED`` (F, mm/min) or
``MAX_LINE_NUMBER`` (N, a whole number >= 0) are errors naming the line and the word.

A cutting move that goes nowhere (a G01 to its own start point, within ``ZERO_LENGTH`` = 1 nm) is dropped
with a warning (``Program.warnings`` and Python's ``warnings``); a G01/G02/
G03 block without X or Y (a Z-only plunge) moves nothing in XY and is listed
in ``Program.ignored``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from .lexer import Block, GCodeError, Word, lex
from ..validation import non_negative

__all__ = [
    "ARC_RADIUS_TOLERANCE",
    "RADIUS_TOLERANCE",
    "ZERO_LENGTH",
    "MAX_COORDINATE",
    "MAX_FEED",
    "MM_PER_INCH",
    "Move",
    "Program",
    "interpret",
    "read_program_text",
]

#: mm per inch (exact, by the international yard and pound agreement of 1959).
MM_PER_INCH = 25.4

#: Largest difference of an I/J arc's start and end radii, mm: LinuxCNC's
#: CENTER_ARC_RADIUS_TOLERANCE_MM = 2 * 0.01 * sqrt(2) (src/emc/rs274ngc/interp_internal.hh).
ARC_RADIUS_TOLERANCE = 2 * 0.01 * math.sqrt(2.0)

#: How much half the chord of an R arc may exceed ``|R|``, mm (the arc is then a half circle):
#: LinuxCNC's RADIUS_TOLERANCE_MM = 0.00005 in (interp_internal.hh).
RADIUS_TOLERANCE = 0.00005 * MM_PER_INCH

#: A move shorter than this goes nowhere, mm: 1 nm, the least input increment of the finest increment system
#: of CNCs (FANUC's IS-E); absolute, so no other word of the program (a far rapid, a large R) changes it.
ZERO_LENGTH = 1e-6

#: Largest absolute value of X, Y, I, J and R read, mm (after G20's inch): 100 m, beyond any machine tool's travel; a
#: larger number (a typo, an overflow to inf) is an error naming its line and word.
MAX_COORDINATE = 1.0e5

#: Largest feed read, mm/min (after G20): 1e6 mm/min = 16.7 m/s, above any machine tool's rapid traverse.
MAX_FEED = 1.0e6

#: Largest N line number: 8 digits (FANUC's N99999999).
MAX_LINE_NUMBER = 99_999_999

# G codes by meaning (G numbers as floats, as pygcode gives them)
_MOTION = {0.0: "rapid", 1.0: "line", 2.0: "cw", 3.0: "ccw"}
_NO_OPS = {
    40.0: "cutter compensation off",
    49.0: "tool length offset off",
    80.0: "canned cycle off",
    54.0: "work offset 1 (taken as the machine's coordinates)",
}
_PLANES = {17.0, 18.0, 19.0}
_LISTED_LETTERS = {
    "M": "machine function",
    "T": "tool",
    "S": "spindle speed",
    "O": "program number",
    "Z": "Z axis (the machine is biaxial)",
}
_USED_LETTERS = {"G", "N", "F", "X", "Y", "I", "J", "R"}


@dataclass(frozen=True)
class Move:
    """One cutting move of the program, in mm and mm/s.

    Attributes
    ----------
    kind : str
        ``"line"`` (G01) or ``"arc"`` (G02/G03).
    start, end : (2,) float arrays
        Start and end points, mm.
    feed : float
        Programmed feed, mm/s.
    line : int
        Line of the program text, 1-based.
    number : int or None
        The block's N number.
    code : str
        "G01", "G02" or "G03".
    centre : (2,) float array or None
        Arc centre, mm (after the bisector correction).
    radius : float
        Arc radius, mm (0 for a line).
    sweep : float
        Signed swept angle, rad, counter-clockwise positive (G03 > 0, G02 < 0; +-2 pi for a full circle).
    centre_shift : float
        How far the centre was moved onto the chord's bisector, mm (I/J arcs; 0 otherwise).
    """

    kind: str
    start: np.ndarray
    end: np.ndarray
    feed: float
    line: int
    number: int | None
    code: str
    centre: np.ndarray | None = None
    radius: float = 0.0
    sweep: float = 0.0
    centre_shift: float = 0.0

    @property
    def length(self) -> float:
        """Path length, mm."""
        if self.kind == "line":
            return float(np.hypot(*(self.end - self.start)))
        return abs(self.sweep) * self.radius

    def tangent(self, at_end: bool) -> np.ndarray:
        """Unit tangent (direction of travel) at the start or the end."""
        if self.kind == "line":
            d = self.end - self.start
            return d / np.hypot(*d)
        p = (self.end if at_end else self.start) - self.centre
        t = np.array([-p[1], p[0]]) / np.hypot(*p)  # counter-clockwise
        return t if self.sweep > 0 else -t


@dataclass
class Program:
    """An interpreted program: its cutting moves and everything it did not run.

    Attributes
    ----------
    moves : list of Move
        The cutting moves, in order, each starting where the previous ended.
    start : (2,) float array
        Where the contour starts, mm (the last rapid's end before the first cut, or the origin).
    ignored : list of (int, str, str)
        (line, word or code, why) of every word read but not run.
    warnings : list of str
        Moves dropped (zero length).
    name : str
        The program's name (a file's stem, or "program").
    """

    moves: list
    start: np.ndarray
    ignored: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    name: str = "program"

    @property
    def feeds(self) -> np.ndarray:
        """The programmed feed of each move, mm/s."""
        return np.array([m.feed for m in self.moves])


def _fmt(word: Word | None) -> str:
    return "" if word is None else word.text


class _State:
    """The modal state of RS-274 that this reader follows."""

    def __init__(self):
        self.motion: str | None = None
        self.absolute = True
        self.scale = 1.0  # mm per program unit
        self.feed: float | None = None  # mm/s
        self.position = np.zeros(2)


def interpret(blocks: list[Block], *, arc_tolerance: float = ARC_RADIUS_TOLERANCE, name: str = "program") -> Program:
    """The moves of lexed blocks (module docstring for the rules).

    Parameters
    ----------
    blocks : list of Block
        From :func:`vcnc_gym.gcode.lexer.lex`.
    arc_tolerance : float
        Largest difference of an I/J arc's two radii, mm (default LinuxCNC's, ``ARC_RADIUS_TOLERANCE``).
    name : str
        The program's name.

    Raises
    ------
    GCodeError
        Naming the line and the word (module docstring).
    """
    arc_tolerance = non_negative("arc_tolerance", arc_tolerance, "mm")
    reader = _Interpreter(arc_tolerance)
    for index, block in enumerate(blocks):
        if reader.block(block):
            _skip_rest(blocks[index + 1 :], reader.ignored)
            break
    if not reader.moves:
        raise GCodeError("the program has no cutting move (G01, G02 or G03 with X/Y): nothing to contour")
    return Program(moves=reader.moves, start=reader.start, ignored=reader.ignored, warnings=reader.dropped, name=name)


def _errors(block: Block):
    """``err(msg, word=None)``: the GCodeError naming ``block``'s line and ``word``."""
    return lambda msg, word=None: GCodeError(msg, block.line, _fmt(word) or None, block.text)


class _Interpreter:
    """One pass over the blocks, one method per step of a block (RS-274/NGC's order of execution)."""

    def __init__(self, arc_tolerance: float):
        self.arc_tolerance = arc_tolerance
        self.state = _State()
        self.moves: list[Move] = []
        self.ignored: list[tuple[int, str, str]] = []
        self.dropped: list[str] = []
        self.start = np.zeros(2)
        self.rapid_after_cut: tuple[Block, Word | None] | None = None

    def block(self, block: Block) -> bool:
        """Run one block; True if it ends the program (M02/M30) and the blocks after it are to be skipped."""
        err = _errors(block)
        motion_word = self._g_words(block, err)
        ended = self._other_words(block, err)
        _check_ranges(block, self.state.scale, err)
        self._feed(block, err)
        x, y = block.get("X"), block.get("Y")
        i, j, r = block.get("I"), block.get("J"), block.get("R")
        arc_words = [w for w in (i, j, r) if w is not None]
        arc_to_start = motion_word is not None and motion_word.value in (2.0, 3.0) and bool(arc_words)
        if x is None and y is None and not arc_to_start:  # an arc back to the start point: a full circle (I/J)
            self._no_xy(block, motion_word, arc_words, err)  # or an error (R), in _arc
            return ended
        if self.state.motion is None:
            raise err("coordinates without a motion mode (no G00, G01, G02 or G03 in force)", x or y)
        target = self._target(x, y)
        word = motion_word or x or y
        assert word is not None  # X, Y or the G word of an arc back to its start (above)
        if self.state.motion == "rapid":
            self._rapid(block, target, word, arc_words, err)
            return ended
        self._check_cut(word, err)
        number = block.get("N")
        n = None if number is None else int(number.value)
        if self.state.motion == "line":
            if not self._line(block, target, n, arc_words, err):
                return False  # dropped: the block's M02/M30, if any, is not read (as before the split)
        else:
            self.moves.append(_arc(self.state, target, i, j, r, block, n, self.arc_tolerance, err))
        self.state.position = target
        return ended

    def _g_words(self, block: Block, err) -> Word | None:
        """The block's G words (1. feed, 2. units: table 8 puts feed mode and feed before units; F is converted
        with the block's units); its motion word, if any."""
        state, motion_word = self.state, None
        for g in block.all("G"):
            if g.value in (20.0, 21.0):
                state.scale = MM_PER_INCH if g.value == 20.0 else 1.0
            elif g.value in _PLANES:
                if g.value != 17.0:
                    raise err(
                        f"{g.text} selects the {'XZ' if g.value == 18.0 else 'YZ'} plane; only G17 (XY) "
                        "is supported on a biaxial machine",
                        g,
                    )
            elif g.value in (90.0, 91.0):
                state.absolute = g.value == 90.0
            elif g.value == 94.0:
                pass  # feed per minute: the only mode
            elif g.value in _NO_OPS:
                self.ignored.append((block.line, g.text, _NO_OPS[g.value]))
            elif g.value in _MOTION:
                motion_word = g
                state.motion = _MOTION[g.value]
            else:
                raise err(
                    f"{g.text} is not supported (read: G00-G03, G17, G20, G21, G90, G91, G94; "
                    f"G40, G49, G54, G80 listed as ignored)",
                    g,
                )
        return motion_word

    def _other_words(self, block: Block, err) -> bool:
        """The words listed as ignored, or an error for a letter not read; True if the block ends the program."""
        ended = False
        for w in block.words:
            if w.letter in _LISTED_LETTERS:
                self.ignored.append((block.line, w.text, _LISTED_LETTERS[w.letter]))
                if w.letter == "M" and w.value in (2.0, 30.0):
                    ended = True
            elif w.letter not in _USED_LETTERS:
                raise err(
                    f"word {w.text}: the letter {w.letter} is not supported (read: G, N, F, X, Y, I, J, R, "
                    f"and M, T, S, O, Z listed as ignored)",
                    w,
                )
        return ended

    def _feed(self, block: Block, err) -> None:
        f = block.get("F")
        if f is not None:
            if not f.value > 0:
                raise err(f"feed {f.text} must be > 0", f)
            self.state.feed = f.value * self.state.scale / 60.0

    def _no_xy(self, block: Block, motion_word, arc_words: list, err) -> None:
        """A block that moves nothing in XY."""
        if arc_words:
            raise err(f"word {arc_words[0].text} has no meaning without an arc move to X/Y", arc_words[0])
        if motion_word is not None and block.get("Z") is not None:
            self.ignored.append((block.line, motion_word.text, "no X or Y: nothing moves in XY"))

    def _target(self, x, y) -> np.ndarray:
        """The end point of the block's move, mm (absolute or incremental)."""
        state = self.state
        target = state.position.copy()
        for k, w in ((0, x), (1, y)):
            if w is not None:
                v = w.value * state.scale
                target[k] = v if state.absolute else target[k] + v
        return target

    def _rapid(self, block: Block, target: np.ndarray, word: Word, arc_words: list, err) -> None:
        """G00: before the first cut it sets the contour's start; after it, it is only allowed not to move."""
        if arc_words:
            raise err(f"word {arc_words[0].text} has no meaning in G00", arc_words[0])
        if self.moves:
            if np.hypot(*(target - self.state.position)) > ZERO_LENGTH:
                self.rapid_after_cut = (block, block.get("X") or block.get("Y"))
            self.ignored.append((block.line, word.text, "rapid after the cut"))
        else:
            self.start = target.copy()
        self.state.position = target

    def _check_cut(self, word: Word, err) -> None:
        """A cutting move needs a feed, and no rapid may have left the contour before it."""
        if self.state.feed is None:
            raise err(f"{_code(self.state.motion)} before any F word: no feed to cut at", word)  # pyright: ignore[reportArgumentType]  (a cut's motion is set)
        if self.rapid_after_cut is not None:
            b, w = self.rapid_after_cut
            raise GCodeError(
                "G00 moves X/Y between cutting moves: the env follows one continuous contour (the "
                "rapid would leave it); split the program into one contour per part",
                b.line,
                _fmt(w),
                b.text,
            )

    def _line(self, block: Block, target: np.ndarray, n: int | None, arc_words: list, err) -> bool:
        """A G01 move appended; False if it is dropped (zero length, with a warning)."""
        if arc_words:
            raise err(f"word {arc_words[0].text} has no meaning in G01", arc_words[0])
        if np.hypot(*(target - self.state.position)) <= ZERO_LENGTH:
            msg = f"line {block.line} ({block.text.strip()!r}): G01 to its own start point dropped (zero length)"
            self.dropped.append(msg)
            warnings.warn(msg, stacklevel=5)  # the caller of read_program_text, as before the split
            return False
        feed = self.state.feed
        assert feed is not None  # _check_cut
        self.moves.append(Move("line", self.state.position.copy(), target, feed, block.line, n, "G01"))
        return True


def _check_ranges(block: Block, scale: float, err) -> None:
    """GCodeError naming the word of ``block`` whose number is out of range (module docstring)."""
    for w in block.words:
        if w.letter in "XYIJR" and not abs(w.value) * scale <= MAX_COORDINATE:
            raise err(f"word {w.text}: |{w.letter}| must be at most {MAX_COORDINATE:g} mm (100 m)", w)
        if w.letter == "F" and not w.value * scale <= MAX_FEED:
            raise err(f"word {w.text}: the feed must be at most {MAX_FEED:g} mm/min", w)
        if w.letter == "N" and not (0 <= w.value <= MAX_LINE_NUMBER and w.value == int(w.value)):
            raise err(f"word {w.text}: a line number must be a whole number in [0, {MAX_LINE_NUMBER}]", w)


def _code(motion: str) -> str:
    return {"rapid": "G00", "line": "G01", "cw": "G02", "ccw": "G03"}[motion]


def _skip_rest(rest: list[Block], ignored: list) -> None:
    for b in rest:
        ignored.append((b.line, b.text.strip(), "after the program end (M02/M30)"))


def _arc(state: _State, end: np.ndarray, i, j, r, block: Block, number, tolerance: float, err) -> Move:
    """An arc move from the words (module docstring)."""
    ccw = state.motion == "ccw"
    code = "G03" if ccw else "G02"
    p0 = state.position.copy()
    chord = end - p0
    d = float(np.hypot(*chord))
    closed = d <= ZERO_LENGTH
    if r is not None and (i is not None or j is not None):
        raise err(f"{code} with both R and I/J: give one", r)
    if r is None and i is None and j is None:
        raise err(f"{code} needs I/J (centre offsets) or R (radius)", None)
    if r is not None:
        radius = abs(r.value) * state.scale
        if closed:
            raise err(f"{code} with {r.text} ends on its start point: a full circle needs I/J", r)
        if radius == 0.0:
            raise err(f"{code} with radius {r.text}: must not be 0", r)
        half = 0.5 * d
        h2 = radius * radius - half * half
        if h2 < 0.0:
            if half - radius > RADIUS_TOLERANCE:
                raise err(
                    f"{code} radius {r.text} is shorter than half the chord ({half / state.scale:.6g} in "
                    f"program units) by more than {RADIUS_TOLERANCE:g} mm: no arc joins the two points",
                    r,
                )
            h2 = 0.0
            radius = half
        normal = np.array([-chord[1], chord[0]]) / d  # left of the chord
        side = 1.0 if ccw == (r.value > 0) else -1.0
        centre = p0 + 0.5 * chord + side * math.sqrt(h2) * normal
        shift = 0.0
    else:
        offset = np.array([0.0 if i is None else i.value, 0.0 if j is None else j.value]) * state.scale
        programmed = p0 + offset
        r0 = float(np.hypot(*offset))
        if r0 <= ZERO_LENGTH:
            raise err(
                f"{code} centre offsets {_fmt(i)} {_fmt(j)} put the centre on the start point".replace("  ", " "),
                i or j,
            )
        r1 = float(np.hypot(*(end - programmed)))
        if abs(r1 - r0) > tolerance:
            raise err(
                f"{code} radii disagree: {r0:.6g} mm from the start point to the centre ({_fmt(i)} "
                f"{_fmt(j)}), {r1:.6g} mm from the end point, {abs(r1 - r0):.3g} mm apart; the arc "
                f"tolerance is {tolerance:.4g} mm",
                i or j,
            )
        if closed:
            centre, shift = programmed, 0.0
        else:
            mid = p0 + 0.5 * chord
            n = np.array([-chord[1], chord[0]]) / d
            centre = mid + float(np.dot(programmed - mid, n)) * n
            shift = float(np.hypot(*(centre - programmed)))
        radius = float(np.hypot(*(p0 - centre)))
    if closed:
        sweep = 2.0 * math.pi if ccw else -2.0 * math.pi
        end = p0
    else:
        a0 = math.atan2(p0[1] - centre[1], p0[0] - centre[0])
        a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
        sweep = (a1 - a0) % (2.0 * math.pi) if ccw else -((a0 - a1) % (2.0 * math.pi))
        if sweep == 0.0:  # end on the start point to rounding, not caught above: a full turn
            sweep = 2.0 * math.pi if ccw else -2.0 * math.pi
    return Move(
        "arc",
        p0,
        end.copy(),
        state.feed,  # pyright: ignore[reportArgumentType]  (a cut has a feed: _check_cut)
        block.line,
        number,
        code,
        centre=centre,
        radius=radius,
        sweep=sweep,
        centre_shift=shift,
    )


def read_program_text(text: str, *, arc_tolerance: float = ARC_RADIUS_TOLERANCE, name: str = "program") -> Program:
    """Lex (pygcode) and interpret a program text: :func:`lex` then :func:`interpret`."""
    return interpret(lex(text), arc_tolerance=arc_tolerance, name=name)
