"""Look-ahead feedrate: the feed scheduled by the curvature ahead, with jerk-limited changes.

Real CNC interpolators do not run a contour at one programmed feed: they look
ahead along the path, slow down where the curvature would ask more of the
drives than they can give, and plan every change of feed with limited
acceleration and jerk.  This is that scheme, in the form of the real-time
look-ahead NURBS interpolators (e.g. Lin, Tsai and Yau, "Development of a
dynamics-based NURBS interpolator with real-time look-ahead algorithm",
Int. J. Machine Tools and Manufacture 47(15), 2246-2262, 2007): a
curvature-limited feed, critical points at its minima, forward and backward
(bidirectional) scans of the speeds there, and jerk-limited feed changes
between them (Erkorkmaz and Altintas 2001, Jahanpour et al.'s ref. [17]; the changes
are those of Simba et al.'s JLAPs, :mod:`vcnc_gym.motion.jlap`).

1. The speed limit along the arc length s
-----------------------------------------
On a path of curvature kappa(s) (1/mm) the feed V (mm/s) gives the normal
acceleration V^2 kappa, and, at constant feed and curvature, the jerk
kappa^2 V^3 (the acceleration kappa V^2 turns with the tangent at the rate
kappa V).  So

    v_lim(s) = min(F, sqrt(A_n / kappa(s)), (J_n / kappa(s)^2)^(1/3))

keeps V^2 kappa <= A_n and kappa^2 V^3 <= J_n, with F the programmed feed.
The jerk bound is an approximation: the whole jerk of the path is
(dA/dt - kappa^2 V^3) T + (3 kappa V A + kappa_s V^3) N (T, N the unit
tangent and normal, A = dV/dt, kappa_s = dkappa/ds); the terms 3 kappa V A
(a feed change inside a curve) and kappa_s V^3 (a varying curvature) are not
bounded here.  Where the curvature jumps (at the knots of a C1 curve such as
Jahanpour et al.'s quadratic omega: 0.148 -> 0.261 1/mm at s = 21.0 mm) the normal
acceleration steps and no feed above zero bounds its jerk.

kappa is sampled on a grid of about ``spacing`` mm of arc (uniform in u in
every knot span, both sides of every knot, the local maxima of kappa refined
by golden-section search in u to the resolution of u), the arc length
between neighbours by the interpolator's 5-point Gauss-Legendre rule
(:mod:`vcnc_gym.motion.interpolator`; neighbours never straddle a knot); at a
knot v_lim is the lower of the two sides.

2. Critical points and the bidirectional scan
---------------------------------------------
The path is cut at the local minima of v_lim below F (minima not separated by
a rise of more than 1e-6 relative are one: a circle's constant curvature is
one minimum, not its rounding noise).  Each cut is a critical point with the
speed limit w = v_lim there; the path starts and ends at rest.  Every section
between two cuts is planned as one JLAP straight section of Simba et al.: a
jerk-limited change from the speed at its start to a peak, a cruise, a
change down to the speed at its end, acceleration zero at both ends
(:func:`vcnc_gym.motion.jlap.transition_distance`), the peak no higher than
the section's cap c, the largest v_lim inside it.  A forward scan lowers every
critical speed that cannot be reached from the one before within the section
between them, a backward scan every one from which the next cannot be reached
(as :meth:`vcnc_gym.motion.jlap.JlapFeedrate.plan` does for Simba et al.'s
corners).

3. Below the limit between the critical points
----------------------------------------------
A section's changes are time-optimal for its end speeds, so they may cross
v_lim on its flanks (leaving a critical point faster than v_lim rises, or
reaching the next one by braking later than v_lim falls).  The plan's feed is
therefore compared with v_lim at every grid point (V(s) from S(t) = s solved
by Newton's method in t), and a section where it exceeds v_lim is cut at the
violations nearest to its two ends, on either side of its highest v_lim: the
outer parts get the cap min v_lim over themselves, so they are below v_lim for
good, and the middle part keeps its cap.  Scans and check are repeated until
no grid point is above v_lim (within 1e-9 relative); every round turns at
least one violating grid point into a cut, so it ends.  The cost is an
acceleration zero at every cut: the feed climbs a slowly rising v_lim in
steps instead of riding it.

4. The plan
-----------
Constant-jerk pieces, a piecewise cubic S(t): a
:class:`~vcnc_gym.motion.jlap.JlapPlan` (:class:`LookaheadPlan` adds the
sampled limit), which :func:`vcnc_gym.motion.interpolate` reads as every other
plan (:mod:`vcnc_gym.motion.profile`).  Tangential acceleration and jerk stay
within A_t and J_t exactly, V <= F, and V(s) <= v_lim(s) at every grid point;
between grid points v_lim may dip below the grid's values by its variation
over one spacing (the maxima of kappa are on the grid; on the omega and the
heart V^2 kappa and kappa^2 V^3 stay within 1e-9 of A_n and J_n on a grid ten
times finer).  Measured on the references at dt = 0.1 ms, the path's whole
acceleration reaches 1325 mm/s^2 on both contours (braking inside a curve),
and the whole jerk (differences of the acceleration command) 4.9e4 mm/s^3 on
the omega and 4.4e4 on the heart, away from the omega's knots, where its
normal acceleration steps by up to 500 mm/s^2 (the S-curve's: 5.4e4 mm/s^2
and 3.0e7 mm/s^3 on the omega).  On a straight line (kappa = 0) the plan is
the rest-to-rest JLAP of :class:`~vcnc_gym.motion.jlap.JlapFeedrate`, the
time-optimal jerk-limited motion, and every section is time-optimal for its
end speeds and peak (tests/test_lookahead.py checks both against ruckig).

With the defaults the omega takes 0.986 s and the heart 3.286 s (Jahanpour et al.'s
S-curve: 0.631 and 3.221 s); no feed below v_lim with ``|dV/dt|`` <= A_t, jerk
unbounded, can do them in less than 0.862 and 3.243 s (the bidirectional
acceleration-only scan of v^2 on the same grid).

Jahanpour et al.'s limits (the paper gives none)
------------------------------------------------
Jahanpour et al.'s drive (eq. (1), Table 3, section 2c; :mod:`vcnc_gym.plants.vcnc_feed_drive`)
accelerates the table at r_g (K_t K_a u_max - T_coul - B v / r_g) / J with the
full 5 V; at the 100 mm/s feed, against Coulomb and viscous friction, that is
2332 (x) and 2105 (y) mm/s^2 at the nominal plant and 1437 and 1262 mm/s^2 at
the weakest vertex of the uncertainty box; braking, friction helps: 3470 and
2543 mm/s^2 on y (2543 mm/s^2 is the 1.97 mm braking distance from 100 mm/s).

* ``normal_acceleration`` = ``tangential_acceleration`` = 1000 mm/s^2
  (``JAHANPOUR2014_PATH_ACCELERATION``): 79 % of the weakest axis's worst case
  (1262), 48 % of its nominal (2105), so at the nominal plant about half of
  the 5 V stays for the feedback and the friction.  The two bounds are
  separate: where both are reached at once (braking inside a curve) the
  path's acceleration is up to sqrt(2) x 1000 mm/s^2; each axis's acceleration
  is at most the path's.
* ``normal_jerk`` = ``tangential_jerk`` = 3e4 mm/s^3 (``JAHANPOUR2014_PATH_JERK``).
  Eq. (1) has no electrical dynamics (the torque follows the voltage at
  once), so the drive sets no jerk bound; the loops do.  As for Simba et al.'s
  limits (:mod:`vcnc_gym.motion.jlap`) the acceleration is asked to take at
  least one period of the slowest feedback loop of Jahanpour et al.'s controllers to
  build up, the sliding-mode surface of bandwidth lambda = 200 rad/s (Jahanpour et al.'s
  Table 2; the fuzzy loop is near 300 rad/s, the QFT's crosses over near
  8.6e3 rad/s): J <= A lambda / (2 pi) = 3.18e4 mm/s^3, rounded down to 3e4
  (1000 mm/s^2 reached in 33 ms).  On a curve this bounds the turning rate
  kappa V of the acceleration at A_n to J_n / A_n = 30 rad/s.
* ``feedrate`` = 100 mm/s, Jahanpour et al.'s section 3.

For comparison, Jahanpour et al.'s S-curve (100 mm/s, T_a = 0.12 s) asks for a
tangential acceleration of 1.5 V / T_a = 1250 mm/s^2 and a jerk of
6 V / T_a^2 = 4.2e4 mm/s^3, and at the omega's 0.19 mm corners (kappa up to
5.37 1/mm) for a normal acceleration of 5.4e4 mm/s^2, 21 times what the
drives give even braking.  With the defaults those corners pass at
(J_n / kappa^2)^(1/3) = 10.1 mm/s (the jerk bound; the acceleration bound
alone would allow sqrt(A_n / kappa) = 13.7 mm/s), the heart's tightest
curves (kappa = 0.183 1/mm) at sqrt(A_n / kappa) = 74.0 mm/s.

Examples
--------
>>> from vcnc_gym.geometry import omega
>>> from vcnc_gym.motion import LookaheadFeedrate, interpolate
>>> profile = LookaheadFeedrate(omega())
>>> ref = interpolate(omega(), profile, 1e-4)
>>> round(ref.duration, 3)                  # s (the S-curve's: 0.631 s)
0.986
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..geometry.arclength import curve_curvature, curve_speed, gauss_arc
from ..geometry.nurbs import SECOND, NurbsCurve, curve_derivatives_into, workspace_size
from ..validation import positive
from .jlap import JlapPlan, JlapSection, bisect_increasing, PieceWriter, transition_pieces, transition_distance
from .profile import plan_arrays

__all__ = [
    "DEFAULT_SPACING",
    "MAX_LIMIT_SAMPLES",
    "JAHANPOUR2014_FEEDRATE",
    "JAHANPOUR2014_PATH_ACCELERATION",
    "JAHANPOUR2014_PATH_JERK",
    "LookaheadFeedrate",
    "LookaheadPlan",
]

#: Programmed feed of Jahanpour et al.'s experiments, mm/s (section 3).
JAHANPOUR2014_FEEDRATE = 100.0
#: Normal and tangential path acceleration limit for Jahanpour et al.'s drives, mm/s^2 (module docstring).
JAHANPOUR2014_PATH_ACCELERATION = 1000.0
#: Normal and tangential path jerk limit for Jahanpour et al.'s drives, mm/s^3 (module docstring).
JAHANPOUR2014_PATH_JERK = 3.0e4
#: Default arc length between the samples of the curvature, mm: 1/19 of the
#: omega's tightest radius (0.186 mm).  Samples are uniform in u in each knot
#: span, at most this far apart: 7 400 on the omega, 52 000 on the heart.
DEFAULT_SPACING = 0.01
#: The most curvature samples a profile may take (about 64 bytes each while
#: planning: 64 MB), e.g. 10 m of path at the default spacing.
MAX_LIMIT_SAMPLES = 1_000_000

# V above v_lim by more than this (relative) at a grid point is a violation
_TOUCH = 1e-9
# local minima of v_lim not separated by a rise of more than this (relative) are one
_PLATEAU = 1e-6
# a corner: the unit tangent turns across a knot by more than this, rad
_CORNER_ANGLE = 1e-6


# --------------------------------------------------------------------------
# kernels: plain arrays in, no validation
# --------------------------------------------------------------------------


@njit(cache=True)
def _limit_samples(control_points, weights, knots, degree, u_arc, u_eval, s_out, kappa_out):
    """Arc length from u_arc[0] to every u_arc[i] (mm; 5-point Gauss-Legendre between neighbours,
    which never straddle a knot) into ``s_out``, the curvature at u_eval[i] (1/mm) into ``kappa_out``."""
    ders = np.empty((3, 2))
    work = np.empty(workspace_size(degree, SECOND))
    s = 0.0
    for i in range(u_arc.shape[0]):
        if i > 0 and u_arc[i] > u_arc[i - 1]:
            s += gauss_arc(control_points, weights, knots, degree, u_arc[i - 1], u_arc[i], ders, work)
        s_out[i] = s
        curve_derivatives_into(control_points, weights, knots, degree, u_eval[i], SECOND, ders, work)
        kappa_out[i] = curve_curvature(ders, curve_speed(ders))


@njit(cache=True)
def _feed_at_distances(breaks, coeffs, distances, out):
    """The planned feed V (mm/s) where S(t) reaches each of ``distances`` (mm, ascending); ``breaks``,
    ``coeffs`` as :mod:`vcnc_gym.motion.profile`.  The pieces are walked in order and S(t) = s is
    solved in the piece's time by Newton's method (dS/dt = V >= 0) safeguarded by bisection."""
    last = breaks.shape[0] - 1
    k = 0
    for i in range(distances.shape[0]):
        s = distances[i]
        while k < last and coeffs[k + 1, 0] <= s:
            k += 1
        if k == last:  # at the end of the motion, at rest
            out[i] = 0.0
            continue
        c = coeffs[k]
        lo = 0.0
        hi = breaks[k + 1] - breaks[k]
        tau = 0.5 * hi
        for _ in range(100):  # Newton on S(tau) = s (slope V >= 0), safeguarded by bisection
            f = c[0] + tau * (c[1] + tau * (c[2] + tau * (c[3] + tau * c[4]))) - s
            v = c[1] + tau * (2.0 * c[2] + tau * (3.0 * c[3] + tau * 4.0 * c[4]))
            if f < 0.0:
                lo = tau
            else:
                hi = tau
            if abs(f) <= 1e-13 * (1.0 + abs(s)) or not lo < hi:
                break
            step = tau - f / v if v > 0.0 else lo - 1.0
            tau = step if lo < step < hi else 0.5 * (lo + hi)
            if tau == lo or tau == hi:
                break
        out[i] = c[1] + tau * (2.0 * c[2] + tau * (3.0 * c[3] + tau * 4.0 * c[4]))


# --------------------------------------------------------------------------
# the plan
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class LookaheadPlan(JlapPlan):
    """A look-ahead plan: a :class:`~vcnc_gym.motion.jlap.JlapPlan` (piecewise cubic S(t),
    one ``"straight"`` section per pair of cuts) with the speed limit it was planned under.

    Attributes
    ----------
    limit_arc : (n,) float64 array
        Arc lengths of the curvature samples, mm, non-decreasing (a knot appears twice).
    limit_speed : (n,) float64 array
        v_lim at those samples, mm/s (module docstring, section 1).
    """

    limit_arc: np.ndarray
    limit_speed: np.ndarray

    def feed_at(self, s) -> np.ndarray:
        """The planned feed V (mm/s) where the path is at arc length ``s`` (mm, array)."""
        ss = np.asarray(s, dtype=np.float64)
        order = np.argsort(ss.reshape(-1), kind="stable")
        flat = np.ascontiguousarray(ss.reshape(-1)[order])
        out = np.empty_like(flat)
        _feed_at_distances(*plan_arrays(self), flat, out)
        result = np.empty_like(out)
        result[order] = out
        return result.reshape(ss.shape)


def _add(writer: PieceWriter, duration: float, jerk: float, s: float, v: float, a: float):
    """:meth:`PieceWriter.add`, skipping a piece too short to move the clock (rounding leftovers)."""
    if writer.t + duration <= writer.t:
        return s, v, a
    return writer.add(duration, jerk, s, v, a)


def _reach(v0: float, distance: float, cap: float, a: float, j: float) -> float:
    """Highest feed (<= cap) one JLAP change from v0 reaches within ``distance`` mm."""
    return bisect_increasing(lambda v: transition_distance(v0, v, a, j) - distance, v0, max(v0, cap))


def _write(cuts_s, speeds, caps, a: float, j: float, length: float) -> JlapPlan:
    """One JLAP straight section per pair of cuts: change, cruise, change, the peak <= its cap."""
    writer = PieceWriter()
    sections = []
    for i, cap in enumerate(caps):
        s0, s1, v0, v1 = cuts_s[i], cuts_s[i + 1], speeds[i], speeds[i + 1]
        gap = s1 - s0
        t0 = writer.t
        cruise = gap - transition_distance(v0, cap, a, j) - transition_distance(cap, v1, a, j)
        if cruise >= 0.0:
            peak = cap
        else:  # no room for the cap: the highest peak whose two changes fill the gap
            peak = bisect_increasing(
                lambda v: transition_distance(v0, v, a, j) + transition_distance(v, v1, a, j) - gap,
                max(v0, v1),
                max(v0, v1, cap),
            )
            cruise = 0.0
        s, v, acc = s0, v0, 0.0
        for d, jerk in transition_pieces(v0, peak, a, j):
            s, v, acc = _add(writer, d, jerk, s, v, acc)
        if cruise > 0.0:
            s, v, acc = _add(writer, cruise / peak, 0.0, s, peak, 0.0)
        for d, jerk in transition_pieces(peak, v1, a, j):
            s, v, acc = _add(writer, d, jerk, s, v, acc)
        sections.append(JlapSection("straight", t0, writer.t, s0, s1, v0, v1, peak))
    return writer.finish(length, sections)


def _critical_points(v_lim: np.ndarray, feedrate: float) -> list[int]:
    """Grid indices of the local minima of v_lim below the feedrate (not the ends), minima not
    separated by a rise of more than ``_PLATEAU`` merged into the lowest of them."""
    inner = np.arange(1, v_lim.size - 1)
    v = v_lim[inner]
    minima = inner[(v < feedrate) & (v <= v_lim[inner - 1]) & (v <= v_lim[inner + 1])]
    if not minima.size:
        return []
    between = np.maximum.reduceat(v_lim, minima)  # max of v_lim from each minimum up to the next
    kept = [int(minima[0])]
    rise = v_lim[minima[0]]  # max of v_lim from the last kept minimum on
    for j in range(1, minima.size):
        i, k = int(minima[j]), kept[-1]
        rise = max(rise, between[j - 1], v_lim[i])
        if rise > max(v_lim[k], v_lim[i]) * (1.0 + _PLATEAU):
            kept.append(i)
            rise = v_lim[i]
        elif v_lim[i] < v_lim[k]:
            kept[-1] = i
            rise = v_lim[i]
    return kept


def _schedule(
    arc: np.ndarray,
    v_lim: np.ndarray,
    length: float,
    feedrate: float,
    a: float,
    j: float,
    max_rounds: int = 100_000,
    extra_cuts=(),
) -> JlapPlan:
    """Sections 2 and 3 of the module docstring: cuts, scans, check, cuts at the violations; ``extra_cuts``
    (grid indices) are cut too (where a G-code program's feed changes between blocks)."""
    cuts = sorted(set([0] + _critical_points(v_lim, feedrate) + [int(c) for c in extra_cuts] + [v_lim.size - 1]))
    bounded = [False] * (len(cuts) - 1)  # True: the section's cap is the least v_lim inside it
    for _ in range(max_rounds):
        caps = [
            float(v_lim[c0 : c1 + 1].min() if low else v_lim[c0 : c1 + 1].max())
            for c0, c1, low in zip(cuts[:-1], cuts[1:], bounded)
        ]
        speeds = [0.0] + [float(min(v_lim[c], caps[i], caps[i + 1])) for i, c in enumerate(cuts[1:-1])] + [0.0]
        gaps = [float(arc[c1] - arc[c0]) for c0, c1 in zip(cuts[:-1], cuts[1:])]
        for i, gap in enumerate(gaps):  # forward scan
            speeds[i + 1] = min(speeds[i + 1], _reach(speeds[i], gap, caps[i], a, j))
        for i in reversed(range(len(gaps))):  # backward scan
            speeds[i] = min(speeds[i], _reach(speeds[i + 1], gaps[i], caps[i], a, j))
        plan = _write([float(arc[c]) for c in cuts], speeds, caps, a, j, length)
        feed = np.empty_like(arc)
        _feed_at_distances(*plan_arrays(plan), arc, feed)
        over = feed > v_lim * (1.0 + _TOUCH)
        if not np.any(over):
            return plan
        new_cuts, new_bounded = [0], []
        for c0, c1, low in zip(cuts[:-1], cuts[1:], bounded):
            bad = np.flatnonzero(over[c0 : c1 + 1]) + c0
            top = c0 + int(np.argmax(v_lim[c0 : c1 + 1]))
            left = bad[(bad < top) & (arc[bad] > arc[c0])]
            right = bad[(bad > top) & (arc[bad] < arc[c1])]
            parts = []  # (end cut, bounded) of the pieces of this section
            if left.size:  # rising side: cut at the violation nearest c0
                parts.append((int(left[0]), True))
            if right.size:  # falling side: at the one nearest c1
                parts += [(int(right[-1]), low), (c1, True)]
            else:
                parts.append((c1, low))
            for cut, flag in parts:
                new_cuts.append(cut)
                new_bounded.append(flag)
        if new_cuts == cuts:
            raise RuntimeError("the look-ahead found feeds above the limit it cannot cut at")
        cuts, bounded = new_cuts, new_bounded
    raise RuntimeError(f"the look-ahead did not settle in {max_rounds} rounds")


# --------------------------------------------------------------------------
# the profile
# --------------------------------------------------------------------------


class LookaheadFeedrate:
    """Curvature-limited, jerk-limited look-ahead feedrate along one curve (module docstring).

    ``plan(length)`` plans ``curve`` (the length must be the curve's, as
    :func:`vcnc_gym.motion.interpolate` passes it): V^2 kappa <= A_n,
    kappa^2 V^3 <= J_n, ``|dV/dt|`` <= A_t, ``|d2V/dt2|`` <= J_t, V <= F, from rest
    to rest.  The curvature is sampled when the profile is made, the plan
    when it is first asked for (then kept): about 0.05 s for the omega and
    0.2 s for the heart together (once numba's kernels are compiled).

    Parameters
    ----------
    curve : NurbsCurve or SmoothedPolyline
        The path (a ``SmoothedPolyline``'s ``curve``); regular
        (``NurbsCurve.check_regular``) and without corners (a unit tangent
        that jumps at a knot).
    feedrate : float, default 100.0
        Programmed feed F, mm/s (Jahanpour et al. (2014), section 3).
    normal_acceleration : float, default 1000.0
        A_n, mm/s^2 (``JAHANPOUR2014_PATH_ACCELERATION``, module docstring).
    normal_jerk : float, default 3e4
        J_n, mm/s^3 (``JAHANPOUR2014_PATH_JERK``), as kappa^2 V^3.
    tangential_acceleration : float, default 1000.0
        A_t, mm/s^2: bound on the feed's rate dV/dt.
    tangential_jerk : float, default 3e4
        J_t, mm/s^3: bound on d2V/dt2.
    spacing : float, default 0.01
        Arc length between the curvature samples, mm (``DEFAULT_SPACING``).

    Raises
    ------
    TypeError
        If ``curve`` is not a NurbsCurve (nor has one as ``curve``).
    ValueError
        If a limit or ``spacing`` is not a finite real number > 0 (the
        message names it and its unit); if the curve is not regular, has a
        corner (named by its u and angle), or would need more than
        ``MAX_LIMIT_SAMPLES`` samples at this spacing.

    Examples
    --------
    >>> from vcnc_gym.geometry import NurbsCurve
    >>> line = NurbsCurve([[0, 0], [100, 0]], [1, 1], [0, 0, 1, 1], 1)
    >>> plan = LookaheadFeedrate(line).plan(100.0)
    >>> round(plan.duration, 6)     # 100 / 100 + 100 / 1000 + 1000 / 3e4, s
    1.133333
    """

    def __init__(
        self,
        curve,
        feedrate: float = JAHANPOUR2014_FEEDRATE,
        normal_acceleration: float = JAHANPOUR2014_PATH_ACCELERATION,
        normal_jerk: float = JAHANPOUR2014_PATH_JERK,
        tangential_acceleration: float = JAHANPOUR2014_PATH_ACCELERATION,
        tangential_jerk: float = JAHANPOUR2014_PATH_JERK,
        *,
        spacing: float = DEFAULT_SPACING,
    ):
        if not isinstance(curve, NurbsCurve) and isinstance(getattr(curve, "curve", None), NurbsCurve):
            curve = curve.curve
        if not isinstance(curve, NurbsCurve):
            raise TypeError(f"curve must be a NurbsCurve (or a SmoothedPolyline), got {type(curve).__name__}")
        self.curve = curve
        self.feedrate = positive("feedrate", feedrate, "mm/s")
        self.normal_acceleration = positive("normal_acceleration", normal_acceleration, "mm/s^2")
        self.normal_jerk = positive("normal_jerk", normal_jerk, "mm/s^3")
        self.tangential_acceleration = positive("tangential_acceleration", tangential_acceleration, "mm/s^2")
        self.tangential_jerk = positive("tangential_jerk", tangential_jerk, "mm/s^3")
        self.spacing = positive("spacing", spacing, "mm")
        curve.check_regular()
        self._check_corners()
        self._arc, self._kappa_samples = self._samples()
        self._plan = None

    def _check_corners(self) -> None:
        inner, angle = self.curve.knot_turns()
        if not inner.size:
            return
        k = int(np.argmax(angle))
        if angle[k] > _CORNER_ANGLE:
            raise ValueError(
                f"the curve has a corner at u = {inner[k]!r}: its tangent turns by {math.degrees(angle[k]):.4g} "
                "degrees there, and no feed above zero keeps the normal acceleration V^2 kappa bounded through "
                "it; blend the corners first (vcnc_gym.geometry.smooth_polyline)"
            )

    def _samples(self) -> tuple[np.ndarray, np.ndarray]:
        """(arc length mm, curvature 1/mm) on the grid of section 1 of the module docstring."""
        curve = self.curve
        lo, hi = curve.u_range
        knots = np.unique(curve.knots[(curve.knots >= lo) & (curve.knots <= hi)])
        u_arc, u_eval, inside = [], [], []
        for a, b in zip(knots[:-1], knots[1:]):
            probe = np.linspace(a, np.nextafter(b, a), 65)
            speed = float(np.max(np.hypot(*curve.derivatives_array(probe, 1)[:, 1].T)))
            n = max(8, math.ceil(speed * (b - a) / self.spacing))
            if sum(len(x) for x in u_arc) + n + 1 > MAX_LIMIT_SAMPLES:
                raise ValueError(
                    f"the curve needs more than MAX_LIMIT_SAMPLES = {MAX_LIMIT_SAMPLES} curvature samples at "
                    f"spacing={self.spacing!r} mm; pass a larger spacing"
                )
            us = np.linspace(a, b, n + 1)
            u_arc.append(us)
            u_eval.append(np.concatenate([us[:-1], [np.nextafter(b, a)]]))  # the span's end from the left
            inside.append(np.r_[False, np.ones(n - 1, dtype=bool), False])
        u_arc, u_eval, inside = (np.concatenate(x) for x in (u_arc, u_eval, inside))
        u_arc = self._refine_maxima(u_arc, inside)
        u_eval = np.where(inside, u_arc, u_eval)
        arc = np.empty_like(u_arc)
        kappa = np.empty_like(u_arc)
        _limit_samples(*curve.kernel_args, u_arc, u_eval, arc, kappa)
        return arc, kappa

    def _refine_maxima(self, u: np.ndarray, inside: np.ndarray) -> np.ndarray:
        """``u`` with every sample that is a local maximum of kappa inside its knot span, where v_lim < F,
        moved onto the maximum (golden-section search between its neighbours, to the resolution of u)."""
        kappa = self._curvature_at(u)
        peak = (kappa[1:-1] > kappa[:-2]) & (kappa[1:-1] >= kappa[2:])  # never two neighbours
        i = np.flatnonzero(inside[1:-1] & peak & (self.speed_limit(kappa[1:-1]) < self.feedrate)) + 1
        if not i.size:
            return u
        lo, hi = u[i - 1].copy(), u[i + 1].copy()
        g = 0.5 * (3.0 - math.sqrt(5.0))
        x1, x2 = lo + g * (hi - lo), hi - g * (hi - lo)
        f1, f2 = self._curvature_at(x1), self._curvature_at(x2)
        for _ in range(120):  # the bracket shrinks by 0.618 per pass
            if not np.any((x1 > lo) & (x2 < hi) & (x1 < x2)):
                break
            right = f1 < f2  # the maximum lies in [x1, hi], else in [lo, x2]
            lo, hi = np.where(right, x1, lo), np.where(right, hi, x2)
            x1, x2 = np.where(right, x2, lo + g * (hi - lo)), np.where(right, hi - g * (hi - lo), x1)
            fresh = self._curvature_at(np.where(right, x2, x1))
            f1, f2 = np.where(right, f2, fresh), np.where(right, fresh, f1)
        best = np.where(f1 >= f2, x1, x2)
        better = np.maximum(f1, f2) > kappa[i]
        out = u.copy()
        out[i[better]] = best[better]
        return out

    def _curvature_at(self, us: np.ndarray) -> np.ndarray:
        d = self.curve.derivatives_array(us, 2)
        speed = np.hypot(d[:, 1, 0], d[:, 1, 1])
        return np.abs(d[:, 1, 0] * d[:, 2, 1] - d[:, 1, 1] * d[:, 2, 0]) / speed**3

    def speed_limit(self, kappa) -> np.ndarray:
        """v_lim = min(F, sqrt(A_n / kappa), (J_n / kappa^2)^(1/3)), mm/s, for curvatures kappa (1/mm)."""
        k = np.asarray(kappa, dtype=np.float64)
        with np.errstate(divide="ignore"):
            return np.minimum.reduce(
                [
                    np.full_like(k, self.feedrate),
                    np.sqrt(self.normal_acceleration / k),
                    np.cbrt(self.normal_jerk / k**2),
                ]
            )

    def feed_limit(self, arc: np.ndarray) -> np.ndarray:
        """The programmed feed at arc lengths ``arc`` (mm), mm/s: F everywhere here; a G-code program's
        feed per block in :class:`vcnc_gym.gcode.feeds.ProgramFeedrate`."""
        return np.full_like(arc, self.feedrate)

    def feed_cuts(self, arc: np.ndarray) -> tuple:
        """Grid indices the plan must cut at besides the minima of v_lim: none here; where a G-code
        program's feed changes between blocks in :class:`vcnc_gym.gcode.feeds.ProgramFeedrate`."""
        return ()

    def plan(self, length: float) -> LookaheadPlan:
        """The look-ahead plan over the curve, whose arc length ``length`` (mm) must be.

        Raises
        ------
        ValueError
            If ``length`` is not the curve's (within 1e-6 relative).
        """
        length = positive("length", length, "mm")
        if not abs(self._arc[-1] - length) <= 1e-6 * length:
            raise ValueError(
                f"this look-ahead profile plans its own curve ({self._arc[-1]:.6g} mm), not a {length:.6g} mm one"
            )
        if self._plan is None or self._plan.length != length:
            arc = self._arc * (length / self._arc[-1])
            v_lim = np.minimum(self.speed_limit(self._kappa_samples), self.feed_limit(arc))
            knot = np.flatnonzero(arc[1:] == arc[:-1])  # both sides of a knot: the lower limit
            v_lim[knot] = v_lim[knot + 1] = np.minimum(v_lim[knot], v_lim[knot + 1])
            plan = _schedule(
                arc,
                v_lim,
                length,
                self.feedrate,
                self.tangential_acceleration,
                self.tangential_jerk,
                extra_cuts=self.feed_cuts(arc),
            )
            for a in (arc, v_lim):
                a.flags.writeable = False
            self._plan = LookaheadPlan(
                length=plan.length,
                breaks=plan.breaks,
                coeffs=plan.coeffs,
                sections=plan.sections,
                limit_arc=arc,
                limit_speed=v_lim,
            )
        return self._plan

    def __repr__(self) -> str:
        return (
            f"LookaheadFeedrate(feedrate={self.feedrate:g} mm/s, normal_acceleration={self.normal_acceleration:g} "
            f"mm/s^2, normal_jerk={self.normal_jerk:g} mm/s^3, tangential_acceleration="
            f"{self.tangential_acceleration:g} mm/s^2, tangential_jerk={self.tangential_jerk:g} mm/s^3)"
        )
