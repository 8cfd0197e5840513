"""The standard test pieces as G-code programs (shipped in ``vcnc_gym/gcode/programs/``).

- **ISO 230-4 circular test** (ISO 230-4:2005, "Circular tests for
  numerically controlled machine tools"): a circle of the diameter and feed
  the user chooses, run counter-clockwise (G03) and clockwise (G02).  The
  standard evaluates 360 degrees of a path traversed at the programmed feed,
  with the start and end transients outside the data: the program runs a
  90-degree lead-in arc, the measured full circle, and a 90-degree lead-out
  arc, all on the same circle (``circle_program``; :data:`CIRCLE_LEAD` rad).
  The figures (circular deviation G, bidirectional circular deviation G(b),
  radial deviation F) are computed by :mod:`vcnc_gym.gcode.circular`.
- **Circle-diamond-square** (NAS 979, section 4.3.3.1; its successor ISO
  10791-7's test piece): the outer square, the diamond (the square turned by
  45 degrees, its vertices on the square's edge midpoints pulled in) and the
  circle inside the diamond, as one contour: square counter-clockwise, a
  straight link to the diamond, the diamond, a link to the circle, a full
  circle.  The standard cuts them at different depths; a biaxial contour has
  no depth, so the links are feed moves and count in the contour error.
- **Butterfly**: a free-form, the closed polar curve
  r(theta) = R (1 - 0.45 cos 2 theta - 0.15 cos 4 theta) (two wings, a pinched
  waist, concave and convex parts), written as a CAM system writes free-forms
  for a control without NURBS interpolation: tangent-continuous biarcs
  (Bolton 1975; Meek and Walton 1992) through points of the curve every
  ``step`` rad, each arc a G02/G03 with I/J to six decimals.

:data:`PIECES` names the shipped files; ``piece_path(name)`` finds one.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..validation import positive
from .interpreter import MAX_COORDINATE, MAX_FEED

__all__ = [
    "CIRCLE_LEAD",
    "CIRCLE_MIN_DIAMETER",
    "CIRCLE_MIN_FEED",
    "PIECES",
    "PROGRAM_DIR",
    "butterfly_program",
    "circle_diamond_square_program",
    "circle_program",
    "piece_path",
    "write_pieces",
]

PROGRAM_DIR = Path(__file__).parent / "programs"

#: Lead-in and lead-out arcs of the circular test, rad (outside the evaluated 360 degrees).
CIRCLE_LEAD = 0.5 * math.pi

#: Shipped programs: name -> (file name, summary).
PIECES = {
    "iso230-4-ccw": ("iso230-4-ccw.nc", "ISO 230-4 circular test, 50 mm diameter at 3000 mm/min, counter-clockwise"),
    "iso230-4-cw": ("iso230-4-cw.nc", "ISO 230-4 circular test, 50 mm diameter at 3000 mm/min, clockwise"),
    "circle-diamond-square": (
        "circle-diamond-square.nc",
        "NAS 979 / ISO 10791-7 circle-diamond-square, 60 mm square at 6000 mm/min",
    ),
    "butterfly": ("butterfly.nc", "butterfly free-form (polar curve as tangent biarcs), 78 mm across at 3000 mm/min"),
}


def piece_path(name: str) -> Path:
    """The path of a shipped program by its name in :data:`PIECES`."""
    if name not in PIECES:
        raise ValueError(f"unknown test piece {name!r}; known: {sorted(PIECES)}")
    return PROGRAM_DIR / PIECES[name][0]


#: The smallest step of the numbers the programs here write (six decimals), mm or mm/min.
_RESOLUTION = 1e-6
#: The smallest diameter (mm) and feed (mm/min) of :func:`circle_program`: a thousand steps of its numbers, so that
#: the circle written is the one asked for to 0.1 %.
CIRCLE_MIN_DIAMETER = 2000 * _RESOLUTION
CIRCLE_MIN_FEED = 1000 * _RESOLUTION


def _fixed(x: float) -> str:
    """``x`` as ``:g`` writes it where that has no exponent (``3000``), else to six decimals (G-code has none)."""
    s = f"{x:g}"
    return _num(x) if "e" in s else s


def _num(x: float, digits: int = 6) -> str:
    s = f"{x:.{digits}f}".rstrip("0")
    s = s + "0" if s.endswith(".") else s
    return "0.0" if s == "-0.0" else s


def circle_program(diameter: float = 50.0, feed: float = 3000.0, direction: str = "ccw") -> str:
    """ISO 230-4 circular test: lead-in, full circle, lead-out, centred at the origin (mm, mm/min).

    The tool starts on the circle at angle -90 degrees (the bottom), so the measured circle starts at 0
    degrees (ccw) or 180 degrees (cw), where the lead-in ends.
    """
    if direction not in ("ccw", "cw"):
        raise ValueError(f"direction must be 'ccw' or 'cw', got {direction!r}")
    # the program's numbers are written to six decimals (_num): a smaller circle or feed would not be the one asked
    # for (a diameter of 1e-9 mm writes a circle of radius 0, a feed of 1e-6 mm/min an F word the reader refuses)
    diameter = positive("the circle's diameter", diameter, "mm")
    feed = positive("the circle's feed", feed, "mm/min")
    if not CIRCLE_MIN_DIAMETER <= diameter <= 2 * MAX_COORDINATE:
        raise ValueError(
            f"the circle's diameter must be in [{CIRCLE_MIN_DIAMETER:g}, {2 * MAX_COORDINATE:g}] mm (the program "
            f"writes its coordinates to {_RESOLUTION:g} mm, at most {MAX_COORDINATE:g} mm from the centre), got "
            f"{diameter:g}"
        )
    if not CIRCLE_MIN_FEED <= feed <= MAX_FEED:
        raise ValueError(
            f"the circle's feed must be in [{CIRCLE_MIN_FEED:g}, {MAX_FEED:g}] mm/min (the program writes its F word "
            f"to {_RESOLUTION:g} mm/min), got {feed:g}"
        )
    r = 0.5 * diameter
    code = "G03" if direction == "ccw" else "G02"
    sign = 1.0 if direction == "ccw" else -1.0
    start = np.array([0.0, -r])
    lead_end = np.array([sign * r, 0.0])  # 90 degrees on
    out_end = np.array([0.0, r]) if direction == "ccw" else np.array([0.0, r])

    def ij(p):
        return f"I{_num(-p[0])} J{_num(-p[1])}"

    return "\n".join(
        [
            "%",
            f"(ISO 230-4 circular test: diameter {diameter:g} mm, F{feed:g} mm/min, {direction})",
            "(lead-in 90 deg, measured circle 360 deg, lead-out 90 deg, centre X0 Y0)",
            "N10 G21 G17 G90 G94 G40 G49 G80",
            f"N20 G00 X{_num(start[0])} Y{_num(start[1])}",
            f"N30 {code} X{_num(lead_end[0])} Y{_num(lead_end[1])} {ij(start)} F{_fixed(feed)} (lead-in)",
            f"N40 {code} X{_num(lead_end[0])} Y{_num(lead_end[1])} {ij(lead_end)} (measured circle)",
            f"N50 {code} X{_num(out_end[0])} Y{_num(out_end[1])} {ij(lead_end)} (lead-out)",
            "N60 M30",
            "%",
            "",
        ]
    )


def circle_diamond_square_program(size: float = 60.0, feed: float = 6000.0) -> str:
    """NAS 979 circle-diamond-square as one contour (module docstring), square side ``size`` mm, centred at
    the origin; the diamond's vertices 0.45 ``size`` from the centre, the circle's radius 0.3 ``size``."""
    h = 0.5 * size
    d = 0.45 * size
    r = 0.3 * size
    lines = [
        "%",
        f"(NAS 979 / ISO 10791-7 circle-diamond-square: square {size:g} mm, F{feed:g} mm/min)",
        "N10 G21 G17 G90 G94 G40",
        f"N20 G00 X{_num(-h)} Y{_num(-h)}",
    ]
    n = 30
    square = [(h, -h), (h, h), (-h, h), (-h, -h)]
    lines.append(f"N{n} G01 X{_num(square[0][0])} Y{_num(square[0][1])} F{feed:g} (square)")
    for x, y in square[1:]:
        n += 10
        lines.append(f"N{n} X{_num(x)} Y{_num(y)}")
    diamond = [(0.0, -d), (d, 0.0), (0.0, d), (-d, 0.0), (0.0, -d)]
    n += 10
    lines.append(f"N{n} X{_num(diamond[0][0])} Y{_num(diamond[0][1])} (link to the diamond)")
    for k, (x, y) in enumerate(diamond[1:]):
        n += 10
        lines.append(f"N{n} X{_num(x)} Y{_num(y)}" + (" (diamond)" if k == 0 else ""))
    n += 10
    lines.append(f"N{n} X0 Y{_num(-r)} (link to the circle)")
    n += 10
    lines.append(f"N{n} G03 X0 Y{_num(-r)} I0 J{_num(r)} (circle)")
    lines += [f"N{n + 10} M30", "%", ""]
    return "\n".join(lines)


def _butterfly(theta: np.ndarray, radius: float) -> np.ndarray:
    r = radius * (1.0 - 0.45 * np.cos(2 * theta) - 0.15 * np.cos(4 * theta))
    return np.column_stack([r * np.cos(theta), r * np.sin(theta)])


def _butterfly_tangent(theta: np.ndarray, radius: float) -> np.ndarray:
    r = radius * (1.0 - 0.45 * np.cos(2 * theta) - 0.15 * np.cos(4 * theta))
    dr = radius * (0.9 * np.sin(2 * theta) + 0.6 * np.sin(4 * theta))
    t = np.column_stack([dr * np.cos(theta) - r * np.sin(theta), dr * np.sin(theta) + r * np.cos(theta)])
    return t / np.hypot(t[:, 0], t[:, 1])[:, None]


def _biarc(p0, t0, p1, t1):
    """Two arcs (or a line) from p0 (tangent t0) to p1 (tangent t1), tangent where they meet: the
    equal-distance biarc (Bolton 1975): returns [(end, centre or None, ccw)]."""
    v = p1 - p0
    t = t0 + t1
    a = 2.0 * (1.0 - float(np.dot(t0, t1)))
    b = float(np.dot(v, t))
    c = float(np.dot(v, v))
    if a < 1e-12:  # parallel tangents: d = c / (4 v.t1)
        d = c / (4.0 * float(np.dot(v, t1)))
    else:
        d = (-b + math.sqrt(b * b + a * c)) / a  # the root > 0 of a d^2 + 2 b d - c = 0
    q0 = p0 + d * t0
    q1 = p1 - d * t1
    pm = 0.5 * (q0 + q1)
    out = []
    for start, tan, end in ((p0, t0, pm), (pm, (q1 - q0) / np.hypot(*(q1 - q0)), p1)):
        chord = end - start
        normal = np.array([-tan[1], tan[0]])
        denom = 2.0 * float(np.dot(normal, chord))
        if abs(denom) < 1e-12 * float(np.dot(chord, chord)):
            out.append((end, None, True))
            continue
        s = float(np.dot(chord, chord)) / denom
        out.append((end, start + s * normal, s > 0))
    return out


def butterfly_program(radius: float = 30.0, feed: float = 3000.0, step_deg: float = 6.0) -> str:
    """The butterfly (module docstring) (2.6 ``radius`` mm across) as tangent biarcs, counter-clockwise
    from its waist at theta = 0."""
    n = int(round(360.0 / step_deg))
    theta = np.linspace(0.0, 2.0 * math.pi, n + 1)
    pts = _butterfly(theta, radius)
    pts[-1] = pts[0]
    tans = _butterfly_tangent(theta, radius)
    tans[-1] = tans[0]
    lines = [
        "%",
        f"(butterfly free-form: r = R [1 - 0.45 cos 2t - 0.15 cos 4t], R = {radius:g} mm, "
        f"biarcs every {step_deg:g} deg, F{feed:g} mm/min)",
        "N10 G21 G17 G90 G94 G40",
        f"N20 G00 X{_num(pts[0][0])} Y{_num(pts[0][1])}",
    ]
    number = 30
    pos = pts[0]
    first = True
    for k in range(n):
        for end, centre, ccw in _biarc(pts[k], tans[k], pts[k + 1], tans[k + 1]):
            feed_word = f" F{feed:g}" if first else ""
            first = False
            if centre is None:
                lines.append(f"N{number} G01 X{_num(end[0])} Y{_num(end[1])}{feed_word}")
            else:
                code = "G03" if ccw else "G02"
                lines.append(
                    f"N{number} {code} X{_num(end[0])} Y{_num(end[1])} I{_num(centre[0] - pos[0])} "
                    f"J{_num(centre[1] - pos[1])}{feed_word}"
                )
            pos = end
            number += 10
    lines += [f"N{number} M30", "%", ""]
    return "\n".join(lines)


def write_pieces(directory: Path = PROGRAM_DIR) -> None:
    """Write the shipped programs (:data:`PIECES`) with their default sizes and feeds."""
    directory.mkdir(parents=True, exist_ok=True)
    texts = {
        "iso230-4-ccw": circle_program(direction="ccw"),
        "iso230-4-cw": circle_program(direction="cw"),
        "circle-diamond-square": circle_diamond_square_program(),
        "butterfly": butterfly_program(),
    }
    for name, text in texts.items():
        (directory / PIECES[name][0]).write_text(text)


if __name__ == "__main__":
    write_pieces()
