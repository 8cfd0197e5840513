"""VCNC-GCode-v1: a user's part program (G-code) as the contour, single and native vector env."""

from __future__ import annotations

from pathlib import Path

from ..gcode import ARC_RADIUS_TOLERANCE, GCodeError, path_limits, read_program
from ..gcode.pieces import piece_path
from .contouring_env import ContouringEnv
from .contouring_vector_env import ContouringVectorEnv
from .signatures import forwarded_signature

__all__ = ["GCodeEnv", "GCodeVectorEnv", "DEFAULT_PROGRAM", "gcode_task_kwargs"]

#: The program of ``gym.make("VCNC-GCode-v1")`` without ``program=``: the shipped ISO 230-4 circle, counter-clockwise.
DEFAULT_PROGRAM = "iso230-4-ccw"

#: Corner blending tolerance when none is given, mm (10 um: a finishing pass's).
DEFAULT_TOLERANCE = 0.01


def gcode_task_kwargs(
    program=None,
    tolerance=DEFAULT_TOLERANCE,
    *,
    plant="vcnc_feed_drive",
    acceleration=None,
    jerk=None,
    arc_tolerance=ARC_RADIUS_TOLERANCE,
    profile="lookahead",
    **kwargs,
) -> dict:
    """The :class:`~vcnc_gym.envs.task.ContouringTask` arguments of a program (GCodeEnv's docstring)."""
    for key in ("contour", "feedrate"):
        if key in kwargs:
            raise ValueError(
                f"{key}= is the program's: give program= (G-code text, a path, or a test piece name "
                f"of vcnc_gym.gcode.pieces.PIECES); its F words set the feed"
            )
    if program is None:
        program = DEFAULT_PROGRAM
    one_line = isinstance(program, str) and "\n" not in program
    if one_line:
        from ..gcode.pieces import PIECES

        if program in PIECES:
            program = piece_path(program)
            one_line = False
    a, j = path_limits(plant, acceleration, jerk)
    try:
        toolpath = read_program(program, tolerance, acceleration=a, jerk=j, arc_tolerance=arc_tolerance)
    except GCodeError as exc:
        if one_line and not Path(program).exists() and exc.line is not None:
            from ..gcode.pieces import PIECES

            raise GCodeError(
                f"program={program!r} is neither a file, a test piece ({', '.join(PIECES)}) nor "
                f"G-code that reads ({exc})"
            ) from None
        raise
    return {"contour": toolpath, "plant": plant, "profile": profile, **kwargs}


class GCodeEnv(ContouringEnv):
    r"""Contour following along a G-code part program (RS-274), judged by the contour error.

    Everything is :class:`~vcnc_gym.envs.ContouringEnv`'s (observation,
    action, reward, episode end) but the contour and the feed, which come
    from the program (:mod:`vcnc_gym.gcode`): G01 moves as straight lines,
    G02/G03 as exact arcs, corners between G01 moves blended by Simba et al.'s
    quintic Bezier curves at ``tolerance`` mm (``None``: sharp, an exact stop
    at each), the feed of each block (F) planned by the look-ahead within the
    plant's path acceleration and jerk.  G00 positions the start point only
    (a rapid between cuts is an error: one contour per episode).

    ## Arguments

    ``gym.make("VCNC-GCode-v1", program=..., plant=..., tolerance=...)`` with

    - ``program``: G-code text, a path to a file, or a test piece name of
      ``vcnc_gym.gcode.pieces.PIECES`` (default ``"iso230-4-ccw"``).
    - ``tolerance`` (mm, 0.01, or None): the corner blending tolerance.
    - ``plant`` ("vcnc_feed_drive"), and ``acceleration`` (mm/s^2) /
      ``jerk`` (mm/s^3): the path limits of the blends and the look-ahead;
      by default those the plant declares (``PlantModel.path_limits``:
      Jahanpour et al.'s 1000 and 3e4, Simba et al.'s 4000 and 1.6e5); a
      plant that declares none needs them given.
    - ``arc_tolerance`` (mm, LinuxCNC's 0.0283): largest difference of an
      I/J arc's two radii.
    - ``profile`` ("lookahead"; "scurve" or "constant" for a program with one feed).
    - every other argument of ContouringEnv but ``contour`` and ``feedrate``.

    ## Version History

    - v1: initial release (at the contouring ids' v1 episode end and observation).
    """

    def __init__(self, program=None, tolerance=DEFAULT_TOLERANCE, *, render_mode=None, **kwargs):
        super().__init__(render_mode=render_mode, **gcode_task_kwargs(program, tolerance, **kwargs))

    @property
    def toolpath(self):
        """The program's :class:`~vcnc_gym.gcode.Toolpath` (moves, joints, feeds, what was ignored)."""
        return self.task.path


class GCodeVectorEnv(ContouringVectorEnv):
    """N machines running one G-code program (:class:`GCodeEnv`'s arguments), one kernel call per step."""

    def __init__(self, num_envs: int = 1, program=None, tolerance=DEFAULT_TOLERANCE, **kwargs):
        vector = {
            k: kwargs.pop(k) for k in ("autoreset_mode", "parallel", "render_mode", "render_every") if k in kwargs
        }
        super().__init__(num_envs, **vector, **gcode_task_kwargs(program, tolerance, **kwargs))

    @property
    def toolpath(self):
        """The program's :class:`~vcnc_gym.gcode.Toolpath`."""
        return self.task.path


GCodeEnv.__init__.__signature__ = forwarded_signature(
    GCodeEnv.__init__, gcode_task_kwargs, ContouringEnv.__init__, drop=("contour", "feedrate")
)
GCodeVectorEnv.__init__.__signature__ = forwarded_signature(
    GCodeVectorEnv.__init__, gcode_task_kwargs, ContouringVectorEnv.__init__, drop=("contour", "feedrate")
)
