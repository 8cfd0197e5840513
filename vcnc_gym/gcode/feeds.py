"""The feed plan of a part program: per-block feeds under the look-ahead, exact stops at sharp corners.

A CNC runs a program at the feed of each block (F), lowered where the path's
curvature asks more of the drives than they give, and changed with limited
acceleration and jerk: :class:`ProgramFeedrate` is the suite's look-ahead
(:class:`vcnc_gym.motion.LookaheadFeedrate`, with its limit
v_lim = min(F, sqrt(A_n / kappa), (J_n / kappa^2)^(1/3))) with F replaced by
the feed of the block at each arc length (at a boundary between two blocks,
and over a corner blend, the lower of the two).

Where the tangent turns between two blocks and no blend joins them (a sharp
program, ``tolerance=None``, or a corner at an arc), no feed above zero
keeps the normal acceleration bounded: the plan stops there, as a CNC's exact
stop mode (G61) does.  :class:`ProgramProfile` plans every section between
two stops with its own :class:`ProgramFeedrate`, from rest to rest, and
joins the plans end to end: one piecewise S(t), which
:func:`vcnc_gym.motion.interpolate` reads as every other plan.

A joint whose tangent turns by at most ``TANGENT_ANGLE`` is run through
(arcs tangent to lines, written with the program's few decimals): at the feed
V the velocity's direction jumps by V times the angle, 0.1 mm/s at 100 mm/s.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.nurbs import NurbsCurve
from ..motion import LookaheadFeedrate
from ..motion.jlap import JlapPlan, JlapSection
from ..motion.lookahead import DEFAULT_SPACING

__all__ = ["TANGENT_ANGLE", "KINK_ANGLE", "ProgramFeedrate", "ProgramProfile"]

#: Largest turn of the tangent between two blocks run through without a stop, rad (1 mrad = 0.057 deg).
TANGENT_ANGLE = 1e-3

#: Largest kink between two G01 moves that is run through, at the feed, when the corner blend at the tolerance
#: does not fit in the moves, rad (1 degree).  CAM systems write arcs and free-form curves as chords (a 1 mm
#: chord of a 100 mm radius turns by 0.57 degrees); a CNC's look-ahead passes such kinks without a stop (its
#: corner velocity tolerance), where the blend of a larger corner would eat more than the move.  At the feed V
#: the velocity's direction jumps by V times the angle: 1.7 mm/s at 100 mm/s and 1 degree.  A larger corner
#: whose blend does not fit is an error naming the move.
KINK_ANGLE = math.radians(1.0)

# block boundaries closer than this (relative to the section's length) to an arc-length sample are at it
_EDGE = 1e-9


class ProgramFeedrate(LookaheadFeedrate):
    """The look-ahead feed along one section of a program, with the feed of each block.

    Parameters
    ----------
    curve : NurbsCurve
        The section, no corner above ``KINK_ANGLE`` (the toolpath's kinks, run through).
    edges : (n + 1,) array
        Arc lengths of the block boundaries along the section, mm, from 0 to its length.
    feeds : (n,) array
        Programmed feed of each piece between two edges, mm/s.
    acceleration, jerk : float
        A_n = A_t (mm/s^2) and J_n = J_t (mm/s^3).
    spacing : float
        Arc length between the look-ahead's curvature samples, mm (LookaheadFeedrate's).
    cuts : (n + 1,) bool array or None
        Edges the plan cuts at (a section boundary of the look-ahead, acceleration zero there): where
        the feed changes, and at the ends of an arc whose curvature holds the feed below F.  On such a
        plateau of v_lim the look-ahead would otherwise find its end one grid point per round.
    """

    def __init__(
        self,
        curve: NurbsCurve,
        edges,
        feeds,
        acceleration: float,
        jerk: float,
        cuts=None,
        spacing: float = DEFAULT_SPACING,
    ):
        self.edges = np.asarray(edges, dtype=np.float64)
        self.feeds = np.asarray(feeds, dtype=np.float64)
        self.cuts = np.zeros(self.edges.size, dtype=bool) if cuts is None else np.asarray(cuts, dtype=bool)
        super().__init__(curve, float(np.max(self.feeds)), acceleration, jerk, acceleration, jerk, spacing=spacing)

    def _check_corners(self) -> None:
        inner, angle = self.curve.knot_turns()
        if not inner.size:
            return
        if np.max(angle) > KINK_ANGLE:  # the toolpath puts stops or blends there: a bug if reached
            raise ValueError(f"section with a corner of {math.degrees(float(np.max(angle))):.4g} degrees")

    def feed_limit(self, arc: np.ndarray) -> np.ndarray:
        """The block's feed at each arc length (mm), mm/s; at a block boundary the lower of the two."""
        scale = self.edges[-1] / self._arc[-1]  # the plan's arc is the section's, measured by quadrature
        s = np.asarray(arc) * scale
        tol = _EDGE * self.edges[-1]
        left = np.clip(np.searchsorted(self.edges, s - tol, side="right") - 1, 0, self.feeds.size - 1)
        right = np.clip(np.searchsorted(self.edges, s + tol, side="left") - 1, 0, self.feeds.size - 1)
        return np.minimum(self.feeds[left], self.feeds[right])

    def feed_cuts(self, arc: np.ndarray) -> tuple:
        """Grid indices of the edges in ``cuts`` (the first sample at each)."""
        s = np.asarray(arc) * (self.edges[-1] / self._arc[-1])
        tol = _EDGE * self.edges[-1]
        out = []
        for e in self.edges[1:-1][self.cuts[1:-1]]:
            i = int(np.searchsorted(s, e - tol, side="left"))
            if i < s.size and abs(s[i] - e) <= max(tol, 1e-6 * self.edges[-1]):
                out.append(i)
        return tuple(out)


class ProgramProfile:
    """The feed plan of a whole program: one :class:`ProgramFeedrate` per section between exact stops,
    joined end to end (module docstring).  ``plan(length)`` as every profile of :mod:`vcnc_gym.motion`.

    Parameters
    ----------
    sections : list of ProgramFeedrate
        In order along the path.
    """

    def __init__(self, sections: list):
        self.sections = list(sections)
        self._plan = None

    @property
    def feedrate(self) -> float:
        """The program's highest feed, mm/s."""
        return float(max(np.max(p.feeds) for p in self.sections))

    @property
    def lengths(self) -> np.ndarray:
        """Each section's length, mm."""
        return np.array([float(p.edges[-1]) for p in self.sections])

    def plan(self, length: float) -> JlapPlan:
        """The joined plan over ``length`` mm (the program's whole contour, within 1e-6 relative)."""
        total = float(np.sum(self.lengths))
        if not abs(total - length) <= 1e-6 * length:
            raise ValueError(
                f"this program's feed plan covers its own contour ({total:.6g} mm), not a {length:.6g} mm one"
            )
        if self._plan is not None and self._plan.length == length:
            return self._plan
        scale = length / total
        breaks, rows, sections = [0.0], [], []
        t0 = s0 = 0.0
        for p in self.sections:
            own = p.edges[-1] * scale
            sub = p.plan(float(p._arc[-1]))
            factor = own / sub.length  # the quadrature's length against the exact one: 1 to ~1e-12
            coeffs = np.array(sub.coeffs[:-1], dtype=np.float64)
            coeffs[:, 0] = coeffs[:, 0] * factor + s0
            coeffs[:, 1:] *= factor
            rows.append(coeffs)
            breaks.extend((sub.breaks[1:] + t0).tolist())
            for sec in sub.sections:
                sections.append(
                    JlapSection(
                        sec.kind,
                        sec.t_start + t0,
                        sec.t_end + t0,
                        sec.s_start * factor + s0,
                        sec.s_end * factor + s0,
                        sec.v_start * factor,
                        sec.v_end * factor,
                        sec.v_peak * factor,
                    )
                )
            t0 += sub.duration
            s0 += own
        coeffs = np.vstack(rows + [np.array([[length, 0.0, 0.0, 0.0]])])
        breaks = np.array(breaks)
        for a in (breaks, coeffs):
            a.flags.writeable = False
        self._plan = JlapPlan(length=length, breaks=breaks, coeffs=coeffs, sections=tuple(sections))
        return self._plan

    def __repr__(self) -> str:
        return f"ProgramProfile({len(self.sections)} sections, feeds {sorted(set(np.concatenate([p.feeds for p in self.sections]).tolist()))} mm/s)"
