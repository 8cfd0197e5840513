"""G-code part programs (RS-274 as CNCs run it) as contours of the suite.

``read_program(program, tolerance=...)`` reads a program (its text or a file
path) in three steps, one module each:

1. :mod:`~vcnc_gym.gcode.lexer`: the text into blocks of words (pygcode; the
   module says why that library);
2. :mod:`~vcnc_gym.gcode.interpreter`: the blocks into moves (modal state,
   units, arcs from I/J or R, feeds; what is ignored is listed);
3. :mod:`~vcnc_gym.gcode.toolpath`: the moves into one NURBS contour (G01 as
   straight segments, G02/G03 as exact rational quadratic arcs,
   :mod:`~vcnc_gym.gcode.arcs`), Simba et al.'s corner blends at the tolerance,
   and the feed plan (:mod:`~vcnc_gym.gcode.feeds`: look-ahead with each
   block's feed, exact stops at the corners left sharp).

Bad programs raise :class:`GCodeError` (a ValueError) naming the line and the word.
"""

from __future__ import annotations

import os
from pathlib import Path

from .interpreter import ARC_RADIUS_TOLERANCE, MM_PER_INCH, Move, Program, interpret, read_program_text
from .lexer import MAX_LINE_LENGTH, MAX_LINES, MAX_PROGRAM_BYTES, GCodeError, lex
from .toolpath import PROFILES, Joint, Toolpath, build_toolpath

__all__ = [
    "ARC_RADIUS_TOLERANCE",
    "GCodeError",
    "Joint",
    "MM_PER_INCH",
    "Move",
    "PROFILES",
    "Program",
    "Toolpath",
    "build_toolpath",
    "decode",
    "interpret",
    "lex",
    "load_text",
    "path_limits",
    "read_program",
    "read_program_text",
]

#: File suffixes read as program files when ``program`` is a one-line string.
SUFFIXES = (".nc", ".ngc", ".gcode", ".tap", ".cnc", ".txt")


def path_limits(plant, acceleration: float | None = None, jerk: float | None = None) -> tuple[float, float]:
    """(acceleration mm/s^2, jerk mm/s^3) for ``plant`` (a name of :mod:`vcnc_gym.plants` or a ``PlantModel``):
    those given, else the ones the plant declares (``PlantModel.path_limits``)."""
    from ..plants import get_plant
    from ..validation import positive

    acceleration = None if acceleration is None else positive("acceleration", acceleration, "mm/s^2")
    jerk = None if jerk is None else positive("jerk", jerk, "mm/s^3")
    if acceleration is not None and jerk is not None:
        return acceleration, jerk
    model = get_plant(plant)
    if model.path_limits is None:
        raise ValueError(
            f"plant {model.name!r} declares no path acceleration and jerk limits "
            f"(PlantModel.path_limits); pass acceleration= (mm/s^2) and jerk= (mm/s^3)"
        )
    a, j = model.path_limits
    return float(a if acceleration is None else acceleration), float(j if jerk is None else jerk)


def load_text(program) -> tuple[str, str]:
    """(text, name) of ``program``: a path (``os.PathLike``, or a one-line str naming a file or ending in
    one of :data:`SUFFIXES`), or the program's text itself.

    A file larger than :data:`~vcnc_gym.gcode.lexer.MAX_PROGRAM_BYTES` is refused before it is read.  Its
    bytes are read as UTF-8; a line that is not UTF-8 (a comment written by an older post-processor) is read
    as ISO 8859-1 (Latin-1), in which every byte is a character: the lexer then names the line if the
    character stands outside a comment.

    Raises
    ------
    FileNotFoundError
        No such file.
    GCodeError
        A file too large or that cannot be read (permissions, a folder), naming it.
    """
    if isinstance(program, os.PathLike) or (
        isinstance(program, str)
        and "\n" not in program
        and (program.lower().endswith(SUFFIXES) or Path(program).is_file())
    ):
        path = Path(program)
        if not path.is_file():
            raise FileNotFoundError(f"program file {str(path)!r} not found")
        try:
            size = path.stat().st_size
            if size > MAX_PROGRAM_BYTES:
                raise GCodeError(
                    f"program file {str(path)!r} has {size:,} bytes: at most MAX_PROGRAM_BYTES = "
                    f"{MAX_PROGRAM_BYTES:,} are read ({MAX_LINES:,} lines of {MAX_LINE_LENGTH} "
                    "characters)"
                )
            with open(path, "rb") as f:
                data = f.read(MAX_PROGRAM_BYTES + 1)  # a file that grew since: still bounded
        except OSError as exc:
            raise GCodeError(f"program file {str(path)!r} cannot be read: {exc.strerror or exc}") from None
        if len(data) > MAX_PROGRAM_BYTES:
            raise GCodeError(
                f"program file {str(path)!r} has more than MAX_PROGRAM_BYTES = {MAX_PROGRAM_BYTES:,} bytes"
            )
        return decode(data), path.stem
    if not isinstance(program, str):
        raise TypeError(f"program must be G-code text or a path to a file, got {type(program).__name__}")
    return program, "program"


def decode(data: bytes) -> str:
    """A program's bytes as text: UTF-8, each line that is not UTF-8 as ISO 8859-1 (:func:`load_text`)."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        pass
    out = []
    for line in data.split(b"\n"):
        try:
            out.append(line.decode("utf-8"))
        except UnicodeDecodeError:
            out.append(line.decode("latin-1"))
    return "\n".join(out)


def read_program(
    program,
    tolerance: float | None = 0.01,
    *,
    acceleration: float = 1000.0,
    jerk: float = 3.0e4,
    arc_tolerance: float = ARC_RADIUS_TOLERANCE,
    spacing: float = 0.01,
) -> Toolpath:
    """A part program as a :class:`Toolpath` (contour and feeds).

    Parameters
    ----------
    program : str or os.PathLike
        The program's text, or a path to it.
    tolerance : float or None, default 0.01
        Corner blending tolerance, mm (Simba et al.'s blends between G01 moves); None: sharp corners with
        exact stops.
    acceleration, jerk : float
        Path limits of the blends and the look-ahead, mm/s^2 and mm/s^3 (default Jahanpour et al.'s drives').
    arc_tolerance : float
        Largest difference of an I/J arc's two radii, mm (default LinuxCNC's 0.0283 mm).
    spacing : float
        Arc length between the look-ahead's curvature samples, mm (its default, 0.01).

    Raises
    ------
    GCodeError
        A bad program, naming the line and the word.
    """
    from ..validation import non_negative, positive

    if tolerance is not None:
        tolerance = positive("tolerance (the corner blending tolerance; None for sharp corners)", tolerance, "mm")
    acceleration, jerk = positive("acceleration", acceleration, "mm/s^2"), positive("jerk", jerk, "mm/s^3")
    arc_tolerance, spacing = non_negative("arc_tolerance", arc_tolerance, "mm"), positive("spacing", spacing, "mm")
    text, name = load_text(program)
    return build_toolpath(
        read_program_text(text, arc_tolerance=arc_tolerance, name=name), tolerance, acceleration, jerk, spacing
    )
