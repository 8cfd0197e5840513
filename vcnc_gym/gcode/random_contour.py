"""Random part programs: a new contour at every reset, from documented distributions.

:func:`random_program` draws a G-code program (so every drawn contour is a
program a user could run, and ``info["program"]`` shows it) from a numpy
``Generator``; it is then read like any program (:func:`vcnc_gym.gcode.read_program`):
Simba et al.'s blends at the corners between two G01 moves, exact arcs, the
look-ahead feed.

The distributions (:class:`RandomContourSpec`, defaults):

- moves per program: uniform integer in [``moves_min``, ``moves_max``] = [4, 8];
- each move a G01 line with probability ``line_probability`` = 0.6, else a
  G02/G03 arc (each direction with probability 1/2);
- line length: uniform in [``line_min``, ``line_max``] = [5, 30] mm;
- between two lines a corner: the heading turns by a whole number of
  degrees uniform in [``turn_min``, ``turn_max``] = [20, 120], left or right
  with probability 1/2 (Simba et al.'s test path turns by 90 to 150 degrees;
  whole degrees so that Simba et al.'s corner designs, cached by angle in
  :mod:`vcnc_gym.gcode.toolpath`, are made once per angle); a move
  after or before an arc continues tangentially (no corner: arcs join their
  neighbours smoothly, as a CAM system writes them);
- arc radius: log-uniform in [``radius_min``, ``radius_max``] = [2, 20] mm;
  sweep uniform in [``sweep_min``, ``sweep_max``] = [30, 180] degrees;
- feed: one per program, uniform in [``feed_min``, ``feed_max``] =
  [2000, 6000] mm/min (33 to 100 mm/s, Jahanpour et al.'s 100 mm/s at the top);
- start at the origin, initial heading uniform in [0, 360) degrees.

Coordinates are written to 1e-6 mm (6 decimals), arcs with I/J.  The path
may cross itself (the contour error is the distance to the whole contour, so
a crossing costs nothing but a possibly shorter distance near it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RandomContourSpec", "spec_for", "random_program", "MAX_MOVES", "MAX_EXTENT"]


@dataclass(frozen=True)
class RandomContourSpec:
    """The distributions of :func:`random_program` (module docstring); lengths mm, angles degrees, feeds mm/min."""

    moves_min: int = 4
    moves_max: int = 8
    line_probability: float = 0.6
    line_min: float = 5.0
    line_max: float = 30.0
    turn_min: float = 20.0
    turn_max: float = 120.0
    radius_min: float = 2.0
    radius_max: float = 20.0
    sweep_min: float = 30.0
    sweep_max: float = 180.0
    feed_min: float = 2000.0
    feed_max: float = 6000.0

    def __post_init__(self):
        from ..validation import integer, positive, real

        set_ = object.__setattr__  # frozen: the checked values replace the given ones (4.0 -> 4 refused)
        set_(self, "moves_min", integer("spec moves_min", self.moves_min, 1, MAX_MOVES))
        set_(self, "moves_max", integer("spec moves_max", self.moves_max, 1, MAX_MOVES))
        for name in ("line", "turn", "radius", "sweep", "feed"):
            for end in ("min", "max"):
                field = f"{name}_{end}"
                set_(self, field, positive(f"spec {field}", getattr(self, field), _UNITS[name]))
        set_(self, "line_probability", real("spec line_probability", self.line_probability))
        pairs = [
            ("moves", self.moves_min, self.moves_max),
            ("line", self.line_min, self.line_max),
            ("turn", self.turn_min, self.turn_max),
            ("radius", self.radius_min, self.radius_max),
            ("sweep", self.sweep_min, self.sweep_max),
            ("feed", self.feed_min, self.feed_max),
        ]
        for name, lo, hi in pairs:
            if not lo <= hi:
                raise ValueError(f"spec {name}_min must be at most {name}_max, got {lo!r} > {hi!r}")
        if self.feed_min < MIN_FEED:
            raise ValueError(
                f"spec feed_min must be at least {MIN_FEED:g} mm/min (the program writes its F word to 0.1 mm/min: "
                f"a slower feed would not be the one drawn), got {self.feed_min!r}"
            )
        if self.turn_max >= 180.0 or self.sweep_max > 360.0:
            raise ValueError("spec turn_max must be < 180 degrees (no U-turn) and sweep_max <= 360 degrees")
        if math.floor(self.turn_max) < math.ceil(self.turn_min):
            raise ValueError(
                f"spec turn_min..turn_max ({self.turn_min:g}..{self.turn_max:g} degrees) holds no whole "
                "degree (turns are drawn in whole degrees)"
            )
        if not 0.0 <= self.line_probability <= 1.0:
            raise ValueError(f"spec line_probability must be in [0, 1], got {self.line_probability!r}")
        extent = self.moves_max * max(self.line_max, 2.0 * self.radius_max)
        if extent > MAX_EXTENT:
            raise ValueError(
                f"spec moves_max x the longest move (line_max, or an arc's chord up to 2 radius_max) "
                f"= {extent:g} mm: at most MAX_EXTENT = {MAX_EXTENT:g} mm, so that every contour "
                "stays within the observation's position bound (1000 mm)"
            )


#: Slowest feed of a random program (``feed_min``), mm/min: its F word is written to 0.1 mm/min, so that a feed of
#: 10 mm/min is written to within 0.5 % (and one below 0.05 mm/min as F0, which no reader accepts).
MIN_FEED = 10.0

#: Most moves a random program may have (``moves_max``).
MAX_MOVES = 1000

#: Largest reach of a random contour from its start, mm: moves_max x the longest move must not exceed it (the
#: observation bounds positions at 1000 mm; the defaults reach 8 x 40 = 320 mm).
MAX_EXTENT = 900.0

_UNITS = {"line": "mm", "turn": "degrees", "radius": "mm", "sweep": "degrees", "feed": "mm/min"}


def spec_for(plant, spec=None) -> RandomContourSpec:
    """The draws for ``plant`` (a name of :mod:`vcnc_gym.plants` or a ``PlantModel``): ``spec`` if given (a
    :class:`RandomContourSpec`, or a mapping of its fields, as a YAML configuration gives it), else the defaults
    with the fields the plant declares for its scale (``PlantModel.random_contour``)."""
    if spec is None:
        from ..plants import get_plant

        spec = dict(get_plant(plant).random_contour)
    if isinstance(spec, RandomContourSpec):
        return spec
    if isinstance(spec, dict):
        unknown = sorted(set(spec) - set(RandomContourSpec.__dataclass_fields__))
        if unknown:
            raise ValueError(
                f"spec has unknown field(s) {unknown}; RandomContourSpec's fields are "
                f"{list(RandomContourSpec.__dataclass_fields__)}"
            )
        return RandomContourSpec(**spec)
    raise ValueError(f"spec must be a RandomContourSpec or a dict of its fields, got {spec!r}")


def _n(x: float) -> str:
    s = f"{x:.6f}".rstrip("0")
    s = s + "0" if s.endswith(".") else s
    return "0.0" if s == "-0.0" else s


def random_program(rng: np.random.Generator, spec: RandomContourSpec = RandomContourSpec()) -> str:
    """A random program text drawn from ``rng`` (module docstring)."""
    n = int(rng.integers(spec.moves_min, spec.moves_max + 1))
    heading = rng.uniform(0.0, 2.0 * math.pi)
    feed = rng.uniform(spec.feed_min, spec.feed_max)
    pos = np.zeros(2)
    lines = ["(random contour, vcnc_gym.gcode.random_contour)", "G21 G17 G90 G94", "G00 X0.0 Y0.0"]
    previous = None
    for k in range(n):
        is_line = rng.random() < spec.line_probability
        feed_word = f" F{feed:.1f}" if k == 0 else ""
        if is_line:
            if previous == "line":
                degrees = rng.integers(math.ceil(spec.turn_min), math.floor(spec.turn_max) + 1)
                turn = math.radians(float(degrees)) * (1 if rng.random() < 0.5 else -1)
                heading += turn
            length = rng.uniform(spec.line_min, spec.line_max)
            pos = pos + length * np.array([math.cos(heading), math.sin(heading)])
            lines.append(f"G01 X{_n(pos[0])} Y{_n(pos[1])}{feed_word}")
            previous = "line"
        else:
            radius = math.exp(rng.uniform(math.log(spec.radius_min), math.log(spec.radius_max)))
            sweep = math.radians(rng.uniform(spec.sweep_min, spec.sweep_max))
            ccw = rng.random() < 0.5
            side = 1.0 if ccw else -1.0  # centre on the left (ccw) or the right (cw) of the heading
            centre = pos + side * radius * np.array([-math.sin(heading), math.cos(heading)])
            a0 = math.atan2(pos[1] - centre[1], pos[0] - centre[0])
            a1 = a0 + side * sweep
            end = centre + radius * np.array([math.cos(a1), math.sin(a1)])
            lines.append(
                f"{'G03' if ccw else 'G02'} X{_n(end[0])} Y{_n(end[1])} I{_n(centre[0] - pos[0])} "
                f"J{_n(centre[1] - pos[1])}{feed_word}"
            )
            pos = end
            heading += side * sweep
            previous = "arc"
    lines.append("M30")
    return "\n".join(lines) + "\n"
