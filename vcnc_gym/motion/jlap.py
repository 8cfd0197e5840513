"""Jerk-limited acceleration profiles (JLAPs) along a path, Simba et al.'s section III, Fig. 2.

Simba et al. drive their smoothed tool paths with JLAPs: every change of feed is
made of a constant-jerk ramp up to a constant acceleration, the constant
acceleration, and a constant-jerk ramp back to zero acceleration, so the
acceleration is continuous and starts and ends at zero; changes are joined by
constant-feed sections.  Along a corner-smoothed path
(:func:`vcnc_gym.geometry.corners.smooth_polyline`) the feed is held at the
corner speed min(v_max,a, v_max,j) of Simba et al.'s eq. (20) over each corner
segment of eq. (23) and reaches the programmed feedrate (50 mm/s, Simba et al.'s
section IV-A) on the straight parts where there is room.

One feed change
---------------
From v_0 to v_1 at rest acceleration, with Delta v = ``|v_1 - v_0|``:

* Delta v >= a_max^2 / j_max: jerk +-j_max for T_j = a_max / j_max, constant
  a_max for Delta v / a_max - T_j, jerk -+j_max for T_j; duration
  Delta v / a_max + a_max / j_max;
* otherwise the acceleration peaks at sqrt(Delta v j_max) < a_max: two jerk
  phases of sqrt(Delta v / j_max) each.

The acceleration profile is symmetric in time, so the change covers
(v_0 + v_1) / 2 times its duration.

A straight section between two held feeds (or rest) of length Delta s rises
to the highest peak feed v_c <= feedrate for which the two changes fit,
cruises at v_c if the feedrate is reached, and comes down.  Before that, a
forward and a backward pass lower every held feed that cannot be reached from
its neighbours within the section between them (never met on Simba et al.'s
path).  The time-optimal 1-DoF trajectory with the same limits and boundary
states is this one (tests/test_jlap.py checks the durations against ruckig).

Simba et al.'s limits (the paper gives none)
--------------------------------------------
* ``a_max`` = 4000 mm/s^2 (0.41 g).  The weakest drive is x: with the 5 A
  current limit chosen for Simba et al.'s plant (:mod:`vcnc_gym.plants.current_feed_drive`)
  and every Table I parameter at the unfavourable end of its uncertainty
  interval (k_f -10 %, f_c +20 %, c +30 %, m +10 %), it can accelerate at
  (k_f i_max - f_c - c 50 mm/s) / m = 9.98e3 mm/s^2 at the 50 mm/s feed
  (1.25e4 mm/s^2 nominal; y: 1.28e4 worst, 1.61e4 nominal).  We plan with
  about 40 % of that, leaving 60 % of the current to the feedback of eq. (7)
  and to the friction the feedforward does not know; a path acceleration
  bounded by a_max bounds each axis's by a_max too.
* ``j_max`` = 1.6e5 mm/s^3.  eq. (1) has no electrical dynamics, so the drive
  itself sets no jerk bound; the loop does: with Table I's k_P = 70 000 s^-2
  the contouring loop of eq. (7) has omega_n = sqrt(k_P) = 264.6 rad/s.  We ask
  the acceleration to take at least one natural period 2 pi / omega_n =
  23.7 ms to reach a_max: j_max <= a_max omega_n / (2 pi) = 1.68e5 mm/s^3,
  rounded down to 1.6e5 (a_max reached in 25 ms).
* ``feedrate`` = 50 mm/s, Simba et al.'s section IV-A.

With these limits and eps = 50 um the corner speeds of Simba et al.'s test path
are jerk-bound (n_opt = n_opt,j): 3.4, 6.6 and 11.5 mm/s at 30, 60 and 90
degrees.  No feed change of at most 50 mm/s reaches a_max (that takes
a_max^2 / j_max = 100 mm/s): Simba et al.'s changes are jerk-bound too, peaking at
sqrt(Delta v j_max) <= 2.83e3 mm/s^2; a_max enters through the corner speeds
of eq. (15) (not binding here) and would bound faster or larger changes.

The sharp path
--------------
Simba et al.'s linear path runs at a constant 50 mm/s: :func:`constant_feedrate`
is that plan, V = feedrate from t = 0 to length / feedrate (a step in feed at
both ends, as in the paper's linear case).

Representation
--------------
A :class:`JlapPlan` is piecewise cubic in time: ``breaks`` (K+1,) in s with
``breaks[0] = 0`` and ``breaks[K]`` the duration, and ``coeffs`` (K+1, 4) whose
row k < K holds [s_k, v_k, a_k / 2, j_k / 6] (mm, mm/s, mm/s^2, mm/s^3), so on
piece k s(t) = sum_m coeffs[k, m] (t - breaks[k])^m.  Row K is the rest after
the motion, [length, 0, 0, 0].  Before t = 0 the plan is at rest at s = 0.
The module-level numba kernels :func:`jlap_distance`, :func:`jlap_velocity`,
:func:`jlap_acceleration` and :func:`jlap_state` evaluate it from
``JlapPlan.kernel_args`` = (breaks, coeffs) inside compiled loops.

Examples
--------
>>> profile = JlapFeedrate(feedrate=50.0, a_max=4000.0, j_max=1.6e5)
>>> plan = profile.plan(100.0)            # rest to rest over 100 mm
>>> round(plan.duration, 6)               # 100 / 50 + 2 sqrt(50 / 1.6e5): a_max not reached
2.035355
>>> float(plan.velocity(1.0))
50.0
>>> constant_feedrate(200.0).duration     # the sharp path: 200 mm at 50 mm/s
4.0
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..plants.current_feed_drive import (  # limits beside their plant
    SIMBA_A_MAX,
    SIMBA_FEEDRATE,
    SIMBA_J_MAX,
)
from ..validation import positive as _positive

__all__ = [
    "PieceWriter",
    "SIMBA_A_MAX",
    "SIMBA_FEEDRATE",
    "SIMBA_J_MAX",
    "JlapFeedrate",
    "JlapPlan",
    "JlapSection",
    "constant_feedrate",
    "jlap_acceleration",
    "jlap_distance",
    "jlap_piece",
    "jlap_state",
    "jlap_velocity",
    "bisect_increasing",
    "transition_distance",
    "transition_pieces",
    "transition_time",
]


# --------------------------------------------------------------------------
# kernels: plain arrays in, plain floats out, no validation
# --------------------------------------------------------------------------


@njit(cache=True)
def jlap_piece(t, breaks):
    """Index k of the piece with breaks[k] <= t < breaks[k+1]; K for t >= breaks[K], -1 for t < 0."""
    last = breaks.shape[0] - 1
    if t >= breaks[last]:
        return last
    if t < breaks[0]:
        return -1
    lo = 0
    hi = last
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if t >= breaks[mid]:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True)
def jlap_state(t, breaks, coeffs, out):
    """Write [s (mm), V (mm/s), dV/dt (mm/s^2), jerk (mm/s^3)] of a plan at time t (s) to out[0:4].

    ``breaks`` and ``coeffs`` are ``JlapPlan.kernel_args``; at rest at s = 0
    before t = 0 and at s = length from the end of the motion on.
    """
    k = jlap_piece(t, breaks)
    if k < 0:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        out[3] = 0.0
        return
    tau = t - breaks[k]
    c0, c1, c2, c3 = coeffs[k, 0], coeffs[k, 1], coeffs[k, 2], coeffs[k, 3]
    out[0] = c0 + tau * (c1 + tau * (c2 + tau * c3))
    out[1] = c1 + tau * (2.0 * c2 + tau * 3.0 * c3)
    out[2] = 2.0 * c2 + 6.0 * c3 * tau
    out[3] = 6.0 * c3


@njit(cache=True)
def jlap_distance(t, breaks, coeffs):
    """Planned distance along the path S(t), mm (arguments as :func:`jlap_state`)."""
    k = jlap_piece(t, breaks)
    if k < 0:
        return 0.0
    tau = t - breaks[k]
    return coeffs[k, 0] + tau * (coeffs[k, 1] + tau * (coeffs[k, 2] + tau * coeffs[k, 3]))


@njit(cache=True)
def jlap_velocity(t, breaks, coeffs):
    """Commanded feed V(t), mm/s (arguments as :func:`jlap_state`)."""
    k = jlap_piece(t, breaks)
    if k < 0:
        return 0.0
    tau = t - breaks[k]
    return coeffs[k, 1] + tau * (2.0 * coeffs[k, 2] + tau * 3.0 * coeffs[k, 3])


@njit(cache=True)
def jlap_acceleration(t, breaks, coeffs):
    """Feed acceleration dV/dt, mm/s^2 (arguments as :func:`jlap_state`)."""
    k = jlap_piece(t, breaks)
    if k < 0:
        return 0.0
    return 2.0 * coeffs[k, 2] + 6.0 * coeffs[k, 3] * (t - breaks[k])


@njit(cache=True)
def _jlap_batch(ts, breaks, coeffs, out):
    """out[i] = [s, V, dV/dt, jerk] at ts[i]."""
    for i in range(ts.shape[0]):
        jlap_state(ts[i], breaks, coeffs, out[i])


# --------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------


# --------------------------------------------------------------------------
# one feed change
# --------------------------------------------------------------------------


def transition_time(dv: float, a_max: float, j_max: float) -> float:
    """Duration of a JLAP feed change of ``|dv|`` mm/s from and to zero acceleration, s.

    ``|dv|`` / a_max + a_max / j_max when a_max is reached (``|dv|`` >= a_max^2 / j_max),
    else 2 sqrt(``|dv|`` / j_max).
    """
    dv = abs(float(dv))
    if dv >= a_max * a_max / j_max:
        return dv / a_max + a_max / j_max
    return 2.0 * math.sqrt(dv / j_max)


def transition_distance(v0: float, v1: float, a_max: float, j_max: float) -> float:
    """Path covered by the JLAP feed change from v0 to v1 (mm/s), mm: (v0 + v1) / 2 times its duration."""
    return 0.5 * (v0 + v1) * transition_time(v1 - v0, a_max, j_max)


def transition_pieces(v0: float, v1: float, a_max: float, j_max: float) -> list[tuple[float, float]]:
    """(duration s, jerk mm/s^3) of the constant-jerk pieces of one feed change."""
    dv = v1 - v0
    if dv == 0.0:
        return []
    sign = 1.0 if dv > 0.0 else -1.0
    dv = abs(dv)
    if dv >= a_max * a_max / j_max:
        t_j = a_max / j_max
        t_a = dv / a_max - t_j
        return [(t_j, sign * j_max), (t_a, 0.0), (t_j, -sign * j_max)]
    t_j = math.sqrt(dv / j_max)
    return [(t_j, sign * j_max), (t_j, -sign * j_max)]


def bisect_increasing(f, lo: float, hi: float) -> float:
    """Largest x in [lo, hi] with f(x) <= 0 for f increasing and f(lo) <= 0 (to machine precision)."""
    if f(hi) <= 0.0:
        return hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if f(mid) <= 0.0:
            lo = mid
        else:
            hi = mid
    return lo


# --------------------------------------------------------------------------
# the plan
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class JlapSection:
    """One section of a plan: a straight part between held feeds, or a held feed.

    Attributes
    ----------
    kind : str
        ``"straight"`` (feed change, cruise, feed change), ``"corner"`` (the
        feed held over a corner segment of Simba et al.'s eq. (23)) or
        ``"constant"`` (the whole constant-feedrate plan).
    t_start, t_end : float
        Time span, s.
    s_start, s_end : float
        Path span, mm.
    v_start, v_end : float
        Feed at both ends, mm/s.
    v_peak : float
        Highest feed inside, mm/s.
    """

    kind: str
    t_start: float
    t_end: float
    s_start: float
    s_end: float
    v_start: float
    v_end: float
    v_peak: float

    @property
    def duration(self) -> float:
        """t_end - t_start, s."""
        return self.t_end - self.t_start


@dataclass(frozen=True)
class JlapPlan:
    """A feedrate plan along a path: piecewise cubic S(t) (module docstring, Representation).

    Made by :class:`JlapFeedrate` or :func:`constant_feedrate`; not validated again here.

    Attributes
    ----------
    length : float
        Path length covered, mm.
    breaks : (K+1,) float64 array
        Piece boundaries in time, s; breaks[K] is the duration.
    coeffs : (K+1, 4) float64 array
        Row k < K: [s, V, dV/dt / 2, jerk / 6] at breaks[k] (mm, mm/s, mm/s^2,
        mm/s^3); row K: [length, 0, 0, 0], the rest after the motion.
    sections : tuple of JlapSection
        The straight and corner sections, in order.
    """

    length: float
    breaks: np.ndarray
    coeffs: np.ndarray
    sections: tuple

    @property
    def duration(self) -> float:
        """Total motion time, s."""
        return float(self.breaks[-1])

    @property
    def kernel_args(self) -> tuple[np.ndarray, np.ndarray]:
        """(breaks, coeffs) for :func:`jlap_state` & co. (and, widened, the interpolator's
        :func:`vcnc_gym.motion.profile.plan_arrays`)."""
        return self.breaks, self.coeffs

    @property
    def v_peak(self) -> float:
        """The largest feed of the plan, mm/s."""
        return float(max(s.v_peak for s in self.sections))

    def state(self, t) -> np.ndarray:
        """[S, V, dV/dt, jerk] at t (s): shape t.shape + (4,), in mm, mm/s, mm/s^2, mm/s^3."""
        ts = np.asarray(t, dtype=np.float64)
        flat = np.ascontiguousarray(ts.reshape(-1))
        if not np.all(np.isfinite(flat)):
            raise ValueError("t must be finite (s)")
        out = np.empty((flat.size, 4))
        _jlap_batch(flat, self.breaks, self.coeffs, out)
        return out.reshape(ts.shape + (4,))

    def _column(self, t, j: int):
        out = self.state(t)[..., j]
        return float(out) if out.ndim == 0 else out

    def distance(self, t):
        """Planned distance along the path S(t), mm, for t in s (scalar or array)."""
        return self._column(t, 0)

    def velocity(self, t):
        """Commanded feed V(t), mm/s, for t in s (scalar or array); 0 before and after the motion."""
        return self._column(t, 1)

    def acceleration(self, t):
        """Feed acceleration dV/dt, mm/s^2, for t in s (scalar or array)."""
        return self._column(t, 2)

    def jerk(self, t):
        """Feed jerk d2V/dt2, mm/s^3, for t in s (scalar or array); piecewise constant."""
        return self._column(t, 3)


class PieceWriter:
    """Collects constant-jerk pieces, integrating (s, v, a) exactly piece by piece."""

    def __init__(self):
        self.t = 0.0
        self.breaks = [0.0]
        self.rows = []

    def add(self, duration: float, jerk: float, s: float, v: float, a: float) -> tuple[float, float, float]:
        if duration <= 0.0:
            return s, v, a
        self.rows.append([s, v, 0.5 * a, jerk / 6.0])
        self.t += duration
        self.breaks.append(self.t)
        d = duration
        return (
            s + v * d + 0.5 * a * d * d + jerk * d**3 / 6.0,
            v + a * d + 0.5 * jerk * d * d,
            a + jerk * d,
        )

    def finish(self, length: float, sections: list) -> JlapPlan:
        coeffs = np.array(self.rows + [[length, 0.0, 0.0, 0.0]], dtype=np.float64)
        breaks = np.array(self.breaks, dtype=np.float64)
        for a in (breaks, coeffs):
            a.flags.writeable = False
        return JlapPlan(length=length, breaks=breaks, coeffs=coeffs, sections=tuple(sections))


def constant_feedrate(length: float, feedrate: float = SIMBA_FEEDRATE) -> JlapPlan:
    """Simba et al.'s linear case: V = feedrate from t = 0 to the end, length / feedrate s.

    Parameters
    ----------
    length : float
        Path length, mm.
    feedrate : float
        The constant feed, mm/s (Simba et al.: 50).

    Raises
    ------
    ValueError
        If an argument is not a positive finite number.
    """
    length = _positive("length", length, "mm")
    feedrate = _positive("feedrate", feedrate, "mm/s")
    writer = PieceWriter()
    writer.add(length / feedrate, 0.0, 0.0, feedrate, 0.0)
    section = JlapSection("constant", 0.0, length / feedrate, 0.0, length, feedrate, feedrate, feedrate)
    return writer.finish(length, [section])


class ConstantFeedrate:
    """A constant feed from t = 0 to the end (no ramps): ``plan(length)`` is :func:`constant_feedrate`.

    Simba et al.'s linear case (50 mm/s) and Purtojo et al.'s circle (x = R sin(omega t),
    y = R cos(omega t): a constant feed R omega from the start).

    Parameters
    ----------
    feedrate : float
        The feed, mm/s.
    """

    def __init__(self, feedrate: float = SIMBA_FEEDRATE):
        self.feedrate = _positive("feedrate", feedrate, "mm/s")

    def plan(self, length: float) -> JlapPlan:
        return constant_feedrate(length, self.feedrate)

    def __repr__(self) -> str:
        return f"ConstantFeedrate(feedrate={self.feedrate!r} mm/s)"


class JlapPathFeedrate:
    """Simba et al.'s jerk-limited feedrate along one corner-smoothed path, corner speeds included.

    ``plan(length)`` plans ``path`` (a :class:`~vcnc_gym.geometry.SmoothedPolyline`)
    with :meth:`JlapFeedrate.plan_path`, at the limits the path's blends were
    designed for; ``length`` must be the path's.

    Parameters
    ----------
    path : SmoothedPolyline
    feedrate : float
        Programmed feed, mm/s (Simba et al.: 50).
    """

    def __init__(self, path, feedrate: float = SIMBA_FEEDRATE):
        self.path = path
        self.feedrate = _positive("feedrate", feedrate, "mm/s")
        self.planner = JlapFeedrate(self.feedrate, a_max=path.a_max, j_max=path.j_max)

    def plan(self, length: float) -> JlapPlan:
        plan = self.planner.plan_path(self.path)
        if not abs(plan.length - length) <= 1e-6 * max(1.0, length):
            raise ValueError(f"this JLAP profile plans its own path ({plan.length:.6g} mm), not a {length:.6g} mm one")
        return plan

    def __repr__(self) -> str:
        return (
            f"JlapPathFeedrate(feedrate={self.feedrate!r} mm/s, a_max={self.planner.a_max!r} mm/s^2, "
            f"j_max={self.planner.j_max!r} mm/s^3)"
        )


class JlapFeedrate:
    """Jerk-limited feedrate planner along a path's arc length (Simba et al., section III, Fig. 2).

    Parameters
    ----------
    feedrate : float
        Programmed feed, mm/s (Simba et al.: 50).
    a_max : float
        Feed acceleration limit, mm/s^2 (module docstring: 4000 for Simba et al.).
    j_max : float
        Feed jerk limit, mm/s^3 (module docstring: 1.6e5 for Simba et al.).

    Raises
    ------
    ValueError
        If an argument is not a positive finite number (message names it and its unit).
    """

    def __init__(self, feedrate: float = SIMBA_FEEDRATE, a_max: float = SIMBA_A_MAX, j_max: float = SIMBA_J_MAX):
        self.feedrate = _positive("feedrate", feedrate, "mm/s")
        self.a_max = _positive("a_max", a_max, "mm/s^2")
        self.j_max = _positive("j_max", j_max, "mm/s^3")

    def _reach(self, v0: float, distance: float) -> float:
        """Highest feed (<= feedrate) one JLAP change from v0 reaches within ``distance`` mm."""
        a, j = self.a_max, self.j_max
        return bisect_increasing(lambda v: transition_distance(v0, v, a, j) - distance, v0, self.feedrate)

    def plan(self, length: float, corners=()) -> JlapPlan:
        """Plan a rest-to-rest motion over ``length`` mm holding corner feeds.

        Parameters
        ----------
        length : float
            Path length, mm.
        corners : sequence of (s_start, s_end, v_limit)
            Path spans (mm) over which the feed is held constant at no more
            than v_limit (mm/s), in increasing order, disjoint, strictly
            inside (0, length).

        Returns
        -------
        JlapPlan

        Raises
        ------
        ValueError
            For a non-positive length, a corner span out of order, overlapping
            or touching an end, or a non-positive corner speed.
        """
        length = _positive("length", length, "mm")
        spans = []
        edge = 0.0
        for k, c in enumerate(corners):
            try:
                s0, s1, v = (float(x) for x in c)
            except (TypeError, ValueError):
                raise ValueError(f"corners[{k}] must be (s_start mm, s_end mm, v_limit mm/s), got {c!r}") from None
            if not (math.isfinite(s0) and math.isfinite(s1) and edge < s0 < s1 < length):
                raise ValueError(
                    f"corners[{k}] spans [{s0:g}, {s1:g}] mm: corner spans must be increasing, disjoint "
                    f"and strictly inside (0, {length:g}) mm"
                )
            _positive(f"corners[{k}] speed limit", v, "mm/s")
            spans.append((s0, s1, v))
            edge = s1
        a, j = self.a_max, self.j_max
        # held feeds at the ends of the straight sections: rest, each corner, rest
        held = [0.0] + [min(c[2], self.feedrate) for c in spans] + [0.0]
        starts = [0.0] + [c[1] for c in spans]  # straight section i runs from starts[i] to ends[i]
        ends = [c[0] for c in spans] + [length]
        gaps = [e - s for s, e in zip(starts, ends)]
        for i, gap in enumerate(gaps):  # forward pass
            held[i + 1] = min(held[i + 1], self._reach(held[i], gap))
        for i in reversed(range(len(gaps))):  # backward pass
            held[i] = min(held[i], self._reach(held[i + 1], gaps[i]))

        writer = PieceWriter()
        sections = []
        for i, gap in enumerate(gaps):
            v0, v1 = held[i], held[i + 1]
            t0 = writer.t
            cruise = gap - transition_distance(v0, self.feedrate, a, j) - transition_distance(self.feedrate, v1, a, j)
            if cruise >= 0.0:
                peak = self.feedrate
            else:  # no room for the feedrate: the highest peak whose two changes fill the gap, no cruise
                peak = bisect_increasing(
                    lambda v: transition_distance(v0, v, a, j) + transition_distance(v, v1, a, j) - gap,
                    max(v0, v1),
                    self.feedrate,
                )
                cruise = 0.0
            s, v, acc = starts[i], v0, 0.0
            for d, jerk in transition_pieces(v0, peak, a, j):
                s, v, acc = writer.add(d, jerk, s, v, acc)
            s, v, acc = writer.add(cruise / peak, 0.0, s, peak, 0.0)
            for d, jerk in transition_pieces(peak, v1, a, j):
                s, v, acc = writer.add(d, jerk, s, v, acc)
            sections.append(JlapSection("straight", t0, writer.t, starts[i], ends[i], v0, v1, peak))
            if i < len(spans):
                s0, s1 = spans[i][0], spans[i][1]
                t0 = writer.t
                writer.add((s1 - s0) / v1, 0.0, s0, v1, 0.0)
                sections.append(JlapSection("corner", t0, writer.t, s0, s1, v1, v1, v1))
        return writer.finish(length, sections)

    def plan_path(self, path) -> JlapPlan:
        """Plan along a corner-smoothed path, holding each corner's speed over its corner segment.

        Parameters
        ----------
        path : vcnc_gym.geometry.corners.SmoothedPolyline
            Its ``zones`` (mm) and ``corner_speeds`` (mm/s, Simba et al.'s eq. (20)).

        Raises
        ------
        ValueError
            If the path's blends were designed for a larger acceleration or
            jerk than this planner's limits (their corner speeds would break them).
        """
        if path.a_max > self.a_max or path.j_max > self.j_max:
            raise ValueError(
                f"the path's corner speeds were designed for a_max = {path.a_max:g} mm/s^2 and "
                f"j_max = {path.j_max:g} mm/s^3, above this planner's {self.a_max:g} and {self.j_max:g}"
            )
        corners = [(z[0], z[1], v) for z, v in zip(path.zones, path.corner_speeds)]
        return self.plan(path.length, corners)

    def __repr__(self) -> str:
        return f"JlapFeedrate(feedrate={self.feedrate:g}, a_max={self.a_max:g}, j_max={self.j_max:g})"
