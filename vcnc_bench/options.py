"""Checks of ``vcnc-bench``'s program options, before anything is built: an option that does not apply, or a
number the reader would refuse later, is a ValueError naming the option (``main`` turns it into exit status 2).

- ``--circle D F`` applies to the ISO 230-4 circle only (``--program iso230-4``, ``iso230-4-ccw`` or
  ``iso230-4-cw``); D (mm) and F (mm/min) go through :mod:`vcnc_gym.validation` and within the G-code reader's
  ranges (:data:`vcnc_gym.gcode.interpreter.MAX_COORDINATE`, :data:`~vcnc_gym.gcode.interpreter.MAX_FEED`), so
  the program written for them is one the reader reads.
- ``--tolerance`` applies to ``--program`` only (a registered id has its own contour): ``sharp`` or a
  positive number of mm.
- ``--program NAME`` where NAME is both a shipped test piece and a file of the working folder is ambiguous:
  refused, naming both (``./NAME`` names the file).
- ``--plants N`` runs the registered ids' robust evaluation; the programs' envs are not registered ids:
  refused with ``--program``.
"""

from __future__ import annotations

from pathlib import Path

from vcnc_gym.gcode.interpreter import MAX_COORDINATE, MAX_FEED
from vcnc_gym.gcode.pieces import CIRCLE_MIN_DIAMETER, CIRCLE_MIN_FEED, PIECES
from vcnc_gym.validation import positive

__all__ = ["CIRCLE_PROGRAMS", "DEFAULT_TOLERANCE", "check_program_options", "program_tolerance"]

#: The ``--program`` names whose circle ``--circle D F`` sets.
CIRCLE_PROGRAMS = ("iso230-4", "iso230-4-ccw", "iso230-4-cw")

#: ``--tolerance`` when none is given, mm.
DEFAULT_TOLERANCE = 0.01


def program_tolerance(text: str | None) -> float | None:
    """The corner blending tolerance of ``--tolerance TEXT``: None for ``sharp``, else a number > 0 (mm);
    :data:`DEFAULT_TOLERANCE` when not given (None)."""
    if text is None:
        return DEFAULT_TOLERANCE
    if text == "sharp":
        return None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--tolerance must be a number of mm > 0 or 'sharp', got {text!r}") from None
    return positive("--tolerance", value, "mm")


def check_program_options(args) -> None:
    """ValueError naming the option when ``--circle``, ``--tolerance``, ``--program`` or ``--plants`` do not
    apply or hold a bad value (module docstring).  ``args`` is vcnc-bench's parsed namespace: ``program``
    (list or None), ``circle`` ((D, F) or None), ``tolerance`` (str or None: not given), ``plants``
    (int or None)."""
    programs = list(getattr(args, "program", None) or [])
    circle = getattr(args, "circle", None)
    tolerance = getattr(args, "tolerance", None)
    if circle is not None:
        if not any(p in CIRCLE_PROGRAMS for p in programs):
            raise ValueError(
                f"--circle D F sets the ISO 230-4 circle: it applies to --program "
                f"{' / '.join(CIRCLE_PROGRAMS)} only, got "
                f"{'no --program' if not programs else '--program ' + ', '.join(programs)}"
            )
        diameter = positive("--circle D (the circle's diameter)", circle[0], "mm")
        feed = positive("--circle F (the feed)", circle[1], "mm/min")
        if diameter < CIRCLE_MIN_DIAMETER or feed < CIRCLE_MIN_FEED:
            raise ValueError(
                f"--circle D F must be at least {CIRCLE_MIN_DIAMETER:g} mm and {CIRCLE_MIN_FEED:g} mm/min (the "
                f"program writes its numbers to six decimals: a smaller circle or feed would not be the one asked "
                f"for), got {diameter:g} and {feed:g}"
            )
        if diameter / 2.0 > MAX_COORDINATE:
            raise ValueError(
                f"--circle D must be at most {2 * MAX_COORDINATE:g} mm (the G-code reader's "
                f"coordinate range), got {diameter:g}"
            )
        if feed > MAX_FEED:
            raise ValueError(
                f"--circle F must be at most {MAX_FEED:g} mm/min (the G-code reader's feed range), got {feed:g}"
            )
    if tolerance is not None:
        if not programs:
            raise ValueError(
                "--tolerance is the corner blending tolerance of --program: a registered id "
                "(--env) has its own contour; drop --tolerance or add --program"
            )
        program_tolerance(tolerance)
    for name in programs:
        if name in PIECES or name in CIRCLE_PROGRAMS:
            if Path(name).exists():
                raise ValueError(
                    f"--program {name!r} names both a shipped test piece and the file {name!r} of "
                    f"this folder: write ./{name} for the file, or run from another folder for the "
                    "piece"
                )
    if programs and getattr(args, "plants", None) is not None:
        raise ValueError(
            "--plants N runs the robust evaluation of registered ids; the programs of --program are "
            "not registered ids: run them without --plants"
        )
