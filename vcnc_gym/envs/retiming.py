"""A feed override: the reference re-timed online, as a CNC interpolator does when the operator turns the dial.

The reference of a contouring task is computed ahead, one packed sample per
control period (:func:`~vcnc_gym.envs.task.pack_reference`).  Under a feed
override ``s(t)`` in [0, 1] the interpolator walks the same path on a slower
clock: the reference time ``tau`` advances by ``s dt`` per control period, so
the path is the same and only its timing changes::

    x_r(t) = x_d(tau(t)),   dtau/dt = s(t),
    dx_r/dt = s v_d(tau),   d2x_r/dt2 = s^2 a_d(tau) + (ds/dt) v_d(tau).

The override moves toward its set value at a bounded rate (a CNC ramps its
override rather than stepping it, so the re-timed acceleration stays finite).
:func:`retime` writes the rows a step needs (the periods it runs, and the
preview beyond them with the set value held: the interpolator does not know
the operator's next move) and returns the clock after the committed periods.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import step_kernel as sk

__all__ = ["retime", "padded_reference", "lookahead_dial"]


def padded_reference(samples: np.ndarray, rows: int) -> np.ndarray:
    """``samples`` (K, REF_COLUMNS) extended to ``rows`` rows by holding the last one (the table at rest at the
    contour's end): the buffer a re-timed reference is written into, at the original timing until then."""
    out = np.empty((max(rows, samples.shape[0]), samples.shape[1]))
    out[: samples.shape[0]] = samples
    out[samples.shape[0] :] = samples[-1]
    return out


def lookahead_dial(samples: np.ndarray, feed: float, acceleration: float, reach: float | None = None) -> np.ndarray:
    """The override, sample by sample of the reference ``samples`` (K, REF_COLUMNS), that makes its feed a look-ahead's:
    along the arc s, ``v(s) = min(feed, sqrt(acceleration / |kappa(s)|))``, then ``v(s)^2`` limited to change by at
    most ``2 acceleration`` per mm of arc, backward (braking into each limit) and forward (accelerating out of it)
    (Altintas, Manufacturing Automation, 2nd ed. 2012, ch. 6), over the reference's own speed there (inf where it is
    at rest).  ``feed`` in mm/s, ``acceleration`` in mm/s^2 (normal and tangential).

    ``reach`` (x the reference's speed; the dial's top, ``max_override``): the look-ahead's speed limit also holds
    ``reach`` times the reference's own speed at each point, before the acceleration passes, so that the look-ahead
    starts and ends at rest where the reference does and no speed it plans is beyond the dial.  Without it (None,
    the tolerance ids' v1) the look-ahead is at its top feed from the first sample, and a dial clipped at the top
    afterwards makes the start ``reach`` times the reference's own ramp: ``reach^2`` times its acceleration, beyond
    ``acceleration`` (at 150 %, 2.25 times an S-curve's start)."""
    arc = samples[:, sk.REF_ARC]
    speed = np.hypot(samples[:, sk.REF_VELOCITY], samples[:, sk.REF_VELOCITY + 1])
    kappa = np.abs(samples[:, sk.REF_CURVATURE])
    v2 = np.minimum(feed, np.sqrt(acceleration / np.maximum(kappa, 1e-12))) ** 2
    if reach is not None:
        v2 = np.minimum(v2, (reach * speed) ** 2)
    ds = np.diff(arc)
    for i in range(1, v2.size):  # accelerating out of each limit
        v2[i] = min(v2[i], v2[i - 1] + 2.0 * acceleration * ds[i - 1])
    for i in range(v2.size - 2, -1, -1):  # braking into the next
        v2[i] = min(v2[i], v2[i + 1] + 2.0 * acceleration * ds[i])
    with np.errstate(divide="ignore"):
        return np.where(speed > 1e-9, np.sqrt(v2) / np.maximum(speed, 1e-300), np.inf)


@njit(cache=True)
def _write_row(original, out, n, tau, speed, dspeed, dt):
    """Row ``n`` of ``out``: the original reference (sampled every ``dt`` s) at fractional sample ``tau``, at
    override ``speed`` changing at ``dspeed`` per second.  Position by cubic Hermite interpolation of the
    samples' positions and velocities (exact at whole samples, error O(dt^4)); the rest linearly, the tangent
    renormalised.  At a whole sample the row is the original's, its velocity and acceleration scaled."""
    last = original.shape[0] - 1
    j = min(int(tau), last)
    f = tau - j if j < last else 0.0
    for c in range(sk.REF_COLUMNS):
        out[n, c] = original[j, c]
    if f > 0.0:
        g = 1.0 - f
        h00 = (1.0 + 2.0 * f) * g * g
        h10 = f * g * g * dt
        h01 = f * f * (3.0 - 2.0 * f)
        h11 = -f * f * g * dt
        for c in range(sk.REF_VELOCITY, sk.REF_COLUMNS):
            out[n, c] = g * original[j, c] + f * original[j + 1, c]
        for c in range(2):
            out[n, sk.REF_POSITION + c] = (
                h00 * original[j, sk.REF_POSITION + c]
                + h01 * original[j + 1, sk.REF_POSITION + c]
                + h10 * original[j, sk.REF_VELOCITY + c]
                + h11 * original[j + 1, sk.REF_VELOCITY + c]
            )
        norm = np.hypot(out[n, sk.REF_TANGENT], out[n, sk.REF_TANGENT + 1])
        if norm > 0.0:
            out[n, sk.REF_TANGENT] /= norm
            out[n, sk.REF_TANGENT + 1] /= norm
    if speed != 1.0 or dspeed != 0.0:
        for c in range(2):
            v = out[n, sk.REF_VELOCITY + c]
            out[n, sk.REF_ACCELERATION + c] = out[n, sk.REF_ACCELERATION + c] * speed * speed + v * dspeed
            out[n, sk.REF_VELOCITY + c] = v * speed


@njit(cache=True)
def retime(original, out, start, rows, committed, tau, speed, target, max_change, dt):
    """Write rows ``start`` .. ``start + rows - 1`` of ``out`` (those at or beyond its last row are skipped: the last
    row holds the contour's end, which the kernel reads as the end of the reference): the reference
    re-timed from the clock ``tau`` (samples of ``original``) and override ``speed`` of row ``start - 1``, the
    override moving toward ``target`` by at most ``max_change`` per control period (trapezoidal clock:
    ``tau_n = tau_{n-1} + (s_{n-1} + s_n) / 2``).

    Returns ``(tau, speed, end)`` at row ``start + committed - 1`` (the periods the step runs; the rows beyond
    are its preview, to be rewritten by the next step), ``end`` the first of those rows at which the clock has
    reached the reference's last sample, or -1."""
    last = original.shape[0] - 1
    end = -1
    state_tau = tau
    state_speed = speed
    for r in range(rows):
        n = start + r
        if n >= out.shape[0] - 1:
            break
        step = min(max_change, max(-max_change, target - speed))
        new = speed + step
        tau = min(tau + 0.5 * (speed + new), float(last))
        _write_row(original, out, n, tau, new, step / dt, dt)
        speed = new
        if r < committed:
            state_tau = tau
            state_speed = speed
            if end < 0 and tau >= last:
                end = n
    return state_tau, state_speed, end
