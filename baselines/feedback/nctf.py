"""The fuzzy-based NCTF controller of Purtojo et al., built the paper's way.

Purtojo, Rochardjo, Nugroho and Herianto (Purtojo et al.) control each axis of an
X-Y table with a nominal characteristic trajectory following (NCTF)
controller whose PI compensator is replaced by a 3x3 Mamdani fuzzy
compensator.  The design has three steps (section II, after its refs. [8],
[9]); each is a function here, run on the plant itself:

1. :func:`stepwise_experiment`: the open-loop experiment.  The table at rest
   is driven by the rated input ``u_r`` (section III, "The stepwise input
   value is the rated motor input") until it runs at its top speed, then the
   input is switched to zero and the table coasts to a stop.  Position is
   read by the 1 um sensor (the plant's ``SENSE_MEASURED``), velocity is the
   encoder's count difference; the experiment runs the plant's own kernels
   through the plant contract, not an env.
2. :func:`construct_nct`: the nominal characteristic trajectory (NCT) from
   the deceleration phase, in the phase plane of error ``e`` and error rate:
   ``e = x_stop - x`` and ``de/dt = -v`` while the table decelerates (Fig.
   1(b)).  Its parameters are ``h_max`` (the maximum error rate: the speed at
   which the deceleration starts), ``A`` (the error at the NCT's start: the
   distance coasted) and ``m`` (the gradient at the origin, a least-squares
   slope of the NCT near the origin).  Eq. (3) turns them into the model
   ``K = h_max / u_r``, ``alpha = -m`` (:meth:`NominalCharacteristicTrajectory.model`).
3. :func:`design_compensator`: the fuzzy compensator's membership functions
   from the NCT and the sensor resolution (section II-B, eqs. (1)-(2)).

The controller (Fig. 1(a)), per axis, every decision period ``T``::

    e     = x_d - x_measured                       (mm)
    de/dt = (e_k - e_{k-1}) / T                    (mm/s; v_d - v at the first step)
    u_p   = de/dt - n(e)                           (mm/s)
    u_i   = k_i * sum(u_p * T)                     (mm^2/s)
    u     = fuzzy(u_p, u_i)                        (in units of u_r, +-u_r)

with ``n(e) = clip(m e, -h_max, h_max)`` the NCT (the error rate the NCT
prescribes at error ``e``; for a plant of the form of eq. (3) the
deceleration curve is exactly this line through the origin, reaching
``h_max`` at ``A``).  ``u_p`` is zero on the NCT and positive when the error
falls more slowly than the NCT prescribes, which calls for more positive
input (the sign convention under which Table I reads "P, P -> P").

The fuzzy compensator (section II-A/B, Table I, Fig. 4)
--------------------------------------------------------
* Rules (Table I), output label for (u_p, u_i)::

           u_i:  N  Z  P
      u_p = N:   N  N  Z
      u_p = Z:   N  Z  P
      u_p = P:   Z  P  P

* ``u_p``: triangles N, Z, P over ``+-h_max``; Z has half-width ``h_s-res``,
  "the error rate at resolution sensor": read on the NCT at the error
  ``a_s-res`` = the resolution (1 um), ``h_s-res = |n(a_s-res)| = |m|
  a_s-res`` (the paper lists ``a_s-res`` and ``h_s-res`` among the NCT's
  parameters).  The other reading, the smallest error rate one sample
  period shows, ``a_s-res / T``, is ``zero_rate="sample"``.  N and P fall
  from 1 at ``-+h_max`` to 0 at the origin.
* ``u_i``: triangles over ``+-u_i-max``, ``u_i-max = 0.5 A h_max`` (eq. (1));
  Z has half-width ``u_i-s-res = 4 a_s-res h_s-res`` (eq. (2)).
* Output: z-shaped N (1 at ``-u_r`` to 0 at 0), singleton Z at 0, s-shaped P
  (0 at 0 to 1 at ``u_r``), over ``+-u_r``.
* Mamdani inference as scikit-fuzzy's ``skfuzzy.control`` does it: AND =
  min, min implication, max aggregation, centroid of the aggregated set on
  the output universe sampled at :data:`OUTPUT_POINTS` points (the clipped
  sets' crossings inserted, linear between points), computed by
  :func:`fuzzy_compensate` (numba).  Inputs beyond their universes are
  clipped to them.

What the paper leaves out, chosen here (:class:`NCTFSettings`, :data:`OUTPUT_POINTS`)
-------------------------------------------------------------------------------------
* ``integral_gain`` ``k_i``: eqs. (1)-(2) give ``u_i``'s universe as an area
  of the phase plane (mm x mm/s), while ``u_i`` is the time integral of
  ``u_p`` (mm).  We scale the integral by ``k_i = h_max`` (mm/s, per axis):
  the universe of eqs. (1)-(2) is kept verbatim and ``u_i`` saturates
  (is "fully P") when the integral reaches ``A / 2``.  The integral is
  clamped there (anti-windup: beyond it the fuzzy input is clipped anyway).
* ``OUTPUT_POINTS`` = 101: the output universe's sampling.  With a singleton
  Z and centroid defuzzification the singleton's weight is one sample
  spacing, so the sampling is part of the design; 101 is MATLAB's default
  for Mamdani systems.
* ``zero_rate`` = ``"nct"`` (the reading of ``h_s-res`` above).
* The experiment's durations (``on_time`` 8 s, ``off_time`` 10 s: at least
  10 time constants 1/alpha of either axis anywhere in the plant's
  uncertainty box, so the top speed and the stop are reached to 0.005 %),
  the NCT's near-origin fit region (``fit_fraction`` = 0.2 of ``A``) and its
  velocity window (``velocity_window`` = 50 ms: the 1 um sensor then
  resolves 0.02 mm/s, 0.04 % of ``h_max``).
* The sample period of the experiment and of the controller: the env's
  decision period (Purtojo et al. give none).

Everything is computed from the nominal plant the env declares; no number of
the paper's results is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from vcnc_gym.plants import contract, get_plant
from vcnc_gym.plants import nct_xy_table  # noqa: F401  (registers the plant's contract kernels)

from vcnc_gym.validation import positive
from ..base import BaselinePolicy

__all__ = [
    "LABELS",
    "RULE_TABLE",
    "OUTPUT_POINTS",
    "NCTFSettings",
    "DEFAULT_SETTINGS",
    "StepwiseExperiment",
    "NominalCharacteristicTrajectory",
    "FuzzyCompensator",
    "stepwise_experiment",
    "construct_nct",
    "design_compensator",
    "fuzzy_compensate",
    "output_memberships",
    "NCTFPolicy",
]

#: Linguistic values of every variable, index 0..2.
LABELS = ("N", "Z", "P")

#: Purtojo et al., Table I: output label index for (u_p label, u_i label), ``RULE_TABLE[u_p, u_i]``.
RULE_TABLE = np.array([[0, 0, 1], [0, 1, 2], [1, 2, 2]], dtype=np.int64)

#: Samples of the output universe [-u_r, u_r] (odd, so that the singleton Z at 0 is a sample).
OUTPUT_POINTS = 101


@dataclass(frozen=True)
class NCTFSettings:
    """The values Purtojo et al. leave out, in one place (see the module docstring).

    Parameters
    ----------
    integral_gain : float or None
        ``k_i`` in mm/s: ``u_i = k_i * integral(u_p dt)``.  None: ``h_max``
        of each axis.
    on_time, off_time : float
        Durations of the stepwise input ``u_r`` and of the coasting that
        follows, s.
    fit_fraction : float
        The NCT's gradient at the origin ``m`` is fitted on the deceleration
        samples with ``0 < e <= fit_fraction * A``.
    velocity_window : float
        The experiment's velocity is the sensor's position difference over
        this window, s (rounded to whole sample periods, at least one).
    zero_rate : str
        How ``h_s-res``, "the error rate at resolution sensor", is read:
        ``"nct"`` (default) the NCT's error rate at the error ``a_s-res``,
        ``|m| a_s-res``; ``"sample"`` the smallest error rate the sensor
        shows in one sample period, ``a_s-res / T``.
    """

    integral_gain: float | None = None
    on_time: float = 8.0
    off_time: float = 10.0
    fit_fraction: float = 0.2
    velocity_window: float = 0.05
    zero_rate: str = "nct"

    def __post_init__(self):
        if self.zero_rate not in ("nct", "sample"):
            raise ValueError(f"zero_rate must be 'nct' or 'sample', got {self.zero_rate!r}")


#: The settings used unless others are given.
DEFAULT_SETTINGS = NCTFSettings()


# --------------------------------------------------------------------------
# Step 1: the open-loop stepwise experiment
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class StepwiseExperiment:
    """Sensor records of the stepwise experiment on both axes.

    Attributes
    ----------
    time : ndarray, (n,)
        s, from 0 (at rest) in steps of ``dt``.
    position : ndarray, (n, 2)
        Sensor reading (quantised position), mm.
    input : ndarray, (n, 2)
        Input held over the period that starts at each sample, in units of u_r.
    switch_index : int
        First sample of the deceleration phase (the input is zero from it on).
    dt : float
        Sample period, s.
    u_r : ndarray, (2,)
        The stepwise input's value, the rated input.
    resolution : ndarray, (2,)
        Sensor resolution, mm.
    """

    time: np.ndarray
    position: np.ndarray
    input: np.ndarray
    switch_index: int
    dt: float
    u_r: np.ndarray
    resolution: np.ndarray


@njit(cache=True)
def _run_open_loop(plant, commands, out):
    """Apply ``commands`` (n, 2) to machine 0 of ``plant``; sensor readings before each step and after the last."""
    sensed = np.empty(contract.SENSE_SIZE)
    n = commands.shape[0]
    for k in range(n + 1):
        contract.sense(plant, 0, sensed)
        out[k, 0] = sensed[contract.SENSE_MEASURED]
        out[k, 1] = sensed[contract.SENSE_MEASURED + 1]
        if k < n:
            contract.advance(plant, 0, commands[k])


def stepwise_experiment(
    parameters=None, dt: float = 1e-3, settings: NCTFSettings = DEFAULT_SETTINGS, plant="nct_xy_table"
) -> StepwiseExperiment:
    """Run the open-loop stepwise experiment of Purtojo et al., section III, on both axes.

    Parameters
    ----------
    parameters : array_like, (2, P), optional
        The table's parameters; default nominal (eq. (4)).
    dt : float
        Sample period, s.
    settings : NCTFSettings
        ``on_time`` and ``off_time``, s.
    plant : str or PlantModel
        The plant module (Purtojo et al.'s ``"nct_xy_table"``).

    Returns
    -------
    StepwiseExperiment
    """
    model = get_plant(plant)
    dt = positive("dt", dt)
    on = int(round(positive("on_time", settings.on_time) / dt))
    off = int(round(positive("off_time", settings.off_time) / dt))
    if on < 2 or off < 2:
        raise ValueError(f"on_time and off_time must span at least 2 sample periods of {dt} s")
    arrays = model.arrays(1, dt, model.nominal() if parameters is None else parameters)
    model.reset_machine(arrays, 0, np.zeros(2))
    p = arrays.params[0]
    u_r = model.input_limits(p).copy()
    commands = np.zeros((on + off, 2))
    commands[:on] = u_r
    out = np.empty((on + off + 1, 2))
    _run_open_loop(arrays, commands, out)
    return StepwiseExperiment(
        time=dt * np.arange(on + off + 1),
        position=out,
        input=np.vstack([commands, np.zeros((1, 2))]),
        switch_index=on,
        dt=dt,
        u_r=u_r,
        resolution=p[:, model.index("resolution")].copy(),
    )


# --------------------------------------------------------------------------
# Step 2: the nominal characteristic trajectory
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class NominalCharacteristicTrajectory:
    """The NCT of one axis (Purtojo et al., Fig. 1(b)) and the data it was read from.

    Attributes
    ----------
    h_max : float
        Maximum error rate, mm/s: the speed at which the deceleration starts.
    A : float
        Maximum error at the NCT's start, mm: the distance coasted to the stop.
    m : float
        Gradient at the origin, 1/s (negative).
    u_r : float
        The stepwise input, in units of u_r.
    error, error_rate : ndarray
        The deceleration data in the phase plane: ``e = x_stop - x`` (mm) and
        ``de/dt = -v`` (mm/s), from the sensor readings, starting at ``(A, -h_max)``.
    """

    h_max: float
    A: float
    m: float
    u_r: float
    error: np.ndarray
    error_rate: np.ndarray

    def rate(self, e):
        """The NCT's error rate at error ``e`` (mm), mm/s: ``clip(m e, -h_max, h_max)``."""
        return np.clip(self.m * np.asarray(e, dtype=float), -self.h_max, self.h_max)

    def model(self) -> tuple[float, float]:
        """The simplified model of eq. (3) this NCT gives: ``(K = h_max / u_r, alpha = -m)``."""
        return self.h_max / self.u_r, -self.m


def construct_nct(
    experiment: StepwiseExperiment, axis: int, settings: NCTFSettings = DEFAULT_SETTINGS
) -> NominalCharacteristicTrajectory:
    """Construct one axis's NCT from the deceleration phase of the stepwise experiment.

    Parameters
    ----------
    experiment : StepwiseExperiment
    axis : int
        0 (x) or 1 (y).
    settings : NCTFSettings
        ``fit_fraction`` and ``velocity_window``.

    Returns
    -------
    NominalCharacteristicTrajectory

    Notes
    -----
    The velocity is the sensor's position difference over a window of ``w``
    samples, attributed to the window's middle (error taken as the mean of
    the window's two end readings).  ``h_max`` is that velocity over the
    last window before the switch; ``A`` the sensor's travel from the switch
    to the last sample (the table at rest); ``m`` the least-squares slope
    through the origin of the NCT's samples with ``0 < e <= fit_fraction A``.
    """
    if axis not in (0, 1):
        raise ValueError(f"axis must be 0 (x) or 1 (y), got {axis!r}")
    fraction = positive("fit_fraction", settings.fit_fraction)
    if fraction > 1.0:
        raise ValueError(f"fit_fraction must be in (0, 1], got {fraction}")
    ex = experiment
    w = max(1, int(round(positive("velocity_window", settings.velocity_window) / ex.dt)))
    s = ex.switch_index
    q = ex.position[:, axis]
    if s < w or q.size - s <= 2 * w:
        raise ValueError("the experiment is too short for the velocity window")
    h_max = (q[s] - q[s - w]) / (w * ex.dt)
    x_stop = q[-1]
    if not (h_max > 0.0 and x_stop > q[s]):
        raise ValueError(f"axis {'xy'[axis]} did not move under the stepwise input; no NCT can be read")
    decel = q[s:]
    velocity = (decel[w:] - decel[:-w]) / (w * ex.dt)
    error = x_stop - 0.5 * (decel[w:] + decel[:-w])
    A = x_stop - q[s]
    near = (error > 0.0) & (error <= fraction * A)
    if np.count_nonzero(near) < 2:
        raise ValueError("too few samples near the NCT's origin to fit its gradient")
    m = float(np.sum(error[near] * -velocity[near]) / np.sum(error[near] ** 2))
    # the NCT starts at (A, -h_max): the state at the switch
    return NominalCharacteristicTrajectory(
        h_max=float(h_max),
        A=float(A),
        m=m,
        u_r=float(ex.u_r[axis]),
        error=np.concatenate([[A], error]),
        error_rate=np.concatenate([[-h_max], -velocity]),
    )


# --------------------------------------------------------------------------
# Step 3: the fuzzy compensator
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class FuzzyCompensator:
    """Membership design of one axis's fuzzy compensator (Purtojo et al., section II-B).

    Attributes
    ----------
    h_max : float
        Range of ``u_p``, mm/s.
    h_s_res : float
        Half-width of ``u_p``'s Z: the NCT's error rate at the sensor resolution, mm/s.
    u_i_max : float
        Range of ``u_i``, ``0.5 A h_max`` (eq. (1)), mm^2/s.
    u_i_s_res : float
        Half-width of ``u_i``'s Z, ``4 a_s-res h_s-res`` (eq. (2)), mm^2/s.
    a_s_res : float
        Sensor resolution, mm.
    u_r : float
        Range of the output, the rated input.
    integral_gain : float
        ``k_i``, mm/s.
    """

    h_max: float
    h_s_res: float
    u_i_max: float
    u_i_s_res: float
    a_s_res: float
    u_r: float
    integral_gain: float

    @property
    def output_grid(self) -> np.ndarray:
        """The output universe, :data:`OUTPUT_POINTS` samples of [-u_r, u_r]."""
        return np.linspace(-self.u_r, self.u_r, OUTPUT_POINTS)

    def infer(self, u_p, u_i) -> np.ndarray:
        """Crisp output (units of u_r) for inputs ``u_p`` (mm/s) and ``u_i`` (mm^2/s) of any equal shape."""
        u_p = np.asarray(u_p, dtype=float)
        u_i = np.broadcast_to(np.asarray(u_i, dtype=float), u_p.shape)
        out = np.empty(u_p.size)
        grid = self.output_grid
        fuzzy_compensate(
            np.ascontiguousarray(u_p.ravel()),
            np.ascontiguousarray(u_i.ravel()),
            self.h_max,
            self.h_s_res,
            self.u_i_max,
            self.u_i_s_res,
            RULE_TABLE,
            grid,
            output_memberships(grid),
            out,
        )
        return out.reshape(u_p.shape)


def design_compensator(
    nct: NominalCharacteristicTrajectory,
    resolution: float,
    sample_period: float,
    settings: NCTFSettings = DEFAULT_SETTINGS,
) -> FuzzyCompensator:
    """The membership design of eqs. (1)-(2) from an axis's NCT and sensor.

    Parameters
    ----------
    nct : NominalCharacteristicTrajectory
    resolution : float
        Sensor resolution ``a_s-res``, mm.
    sample_period : float
        The controller's period ``T``, s (used by ``settings.zero_rate == "sample"``).
    settings : NCTFSettings
        ``zero_rate`` and ``integral_gain``.
    """
    a = positive("resolution", resolution)
    T = positive("sample_period", sample_period)
    h_s_res = float(abs(nct.rate(a))) if settings.zero_rate == "nct" else a / T
    k_i = nct.h_max if settings.integral_gain is None else positive("integral_gain", settings.integral_gain)
    return FuzzyCompensator(
        h_max=nct.h_max,
        h_s_res=h_s_res,
        u_i_max=0.5 * nct.A * nct.h_max,
        u_i_s_res=4.0 * a * h_s_res,
        a_s_res=a,
        u_r=nct.u_r,
        integral_gain=k_i,
    )


def output_memberships(grid: np.ndarray) -> np.ndarray:
    """The output sets sampled on ``grid`` (symmetric, odd length, 0 in the middle), (3, G).

    N: z-shaped, 1 at ``grid[0]`` to 0 at 0; Z: singleton at 0; P: s-shaped,
    0 at 0 to 1 at ``grid[-1]`` (scikit-fuzzy's ``zmf``/``smf`` formulas).
    """
    g = np.asarray(grid, dtype=float)
    r = g[-1]
    out = np.zeros((3, g.size))
    t = np.clip(g / r, 0.0, 1.0)  # P side
    out[2] = np.where(t <= 0.5, 2.0 * t**2, 1.0 - 2.0 * (t - 1.0) ** 2)
    out[0] = out[2][::-1]
    out[1, g.size // 2] = 1.0
    return out


@njit(cache=True)
def _input_memberships(x, span, zero, out):
    """Triangles N (1 at -span, 0 at 0), Z (half-width ``zero``), P of input ``x`` clipped to +-span."""
    if x < -span:
        x = -span
    elif x > span:
        x = span
    out[0] = -x / span if x < 0.0 else 0.0
    z = 1.0 - abs(x) / zero
    out[1] = z if z > 0.0 else 0.0
    out[2] = x / span if x > 0.0 else 0.0


@njit(cache=True)
def _aggregate(x, lo, mf_lo, mf_hi, h, cuts):
    """Aggregated output membership at ``x`` in a grid interval [lo, lo + h]: max of min(cut, linear mf)."""
    y = 0.0
    for o in range(3):
        v = mf_lo[o] + (mf_hi[o] - mf_lo[o]) * (x - lo) / h
        if v > cuts[o]:
            v = cuts[o]
        if v > y:
            y = v
    return y


@njit(cache=True)
def fuzzy_compensate(u_p, u_i, h_max, h_s_res, u_i_max, u_i_s_res, rules, grid, output_mf, out):
    """Mamdani inference of the 3x3 compensator (Table I) with centroid defuzzification, for a batch.

    Parameters
    ----------
    u_p : ndarray, (n,)
        Error-rate deviation from the NCT, mm/s (clipped to +-h_max).
    u_i : ndarray, (n,)
        Scaled integral of u_p, mm^2/s (clipped to +-u_i_max).
    h_max, h_s_res, u_i_max, u_i_s_res : float
        Ranges and Z half-widths of the two inputs.
    rules : ndarray of int, (3, 3)
        :data:`RULE_TABLE`.
    grid : ndarray, (G,)
        Increasing output universe.
    output_mf : ndarray, (3, G)
        Output sets sampled on ``grid`` (:func:`output_memberships`).
    out : ndarray, (n,)
        Crisp outputs, written in place.

    Notes
    -----
    As scikit-fuzzy's ``ControlSystemSimulation``: each output set is
    linear between grid samples and clipped at its rule strength; the
    points where a set crosses its clip level are added to the grid; the
    aggregate (max) is taken at the points and integrated as a
    piecewise-linear function (``skfuzzy.defuzz(..., "centroid")``).
    """
    mu_p = np.empty(3)
    mu_i = np.empty(3)
    cuts = np.empty(3)
    pts = np.empty(5)
    for n in range(u_p.size):
        _input_memberships(u_p[n], h_max, h_s_res, mu_p)
        _input_memberships(u_i[n], u_i_max, u_i_s_res, mu_i)
        for o in range(3):
            cuts[o] = 0.0
        for a in range(3):
            for b in range(3):
                s = min(mu_p[a], mu_i[b])
                o = rules[a, b]
                if s > cuts[o]:
                    cuts[o] = s
        num = 0.0
        den = 0.0
        for g in range(grid.size - 1):
            lo = grid[g]
            h = grid[g + 1] - lo
            mf_lo = output_mf[:, g]
            mf_hi = output_mf[:, g + 1]
            # the interval's points: its ends and each set's crossing of its cut level
            k = 0
            pts[k] = lo
            k += 1
            for o in range(3):
                a0 = mf_lo[o]
                a1 = mf_hi[o]
                c = cuts[o]
                if (a0 < c < a1) or (a1 < c < a0):
                    pts[k] = lo + (c - a0) * h / (a1 - a0)
                    k += 1
            pts[k] = lo + h
            k += 1
            # insertion sort of the (at most 5) points
            for i in range(1, k):
                v = pts[i]
                j = i - 1
                while j >= 0 and pts[j] > v:
                    pts[j + 1] = pts[j]
                    j -= 1
                pts[j + 1] = v
            x0 = pts[0]
            y0 = _aggregate(x0, lo, mf_lo, mf_hi, h, cuts)
            for i in range(1, k):
                x1 = pts[i]
                y1 = _aggregate(x1, lo, mf_lo, mf_hi, h, cuts)
                d = x1 - x0
                if d > 0.0:
                    den += 0.5 * d * (y0 + y1)
                    num += d / 6.0 * (x0 * (2.0 * y0 + y1) + x1 * (y0 + 2.0 * y1))
                x0 = x1
                y0 = y1
        out[n] = num / den if den > 0.0 else 0.0


# --------------------------------------------------------------------------
# The policy
# --------------------------------------------------------------------------


@njit(cache=True)
def _nctf_step(e, e_dot, m, h_max, k_i, T, u_i_max, h_s_res, u_i_s_res, integral, rules, grid, output_mf, out):
    """One NCTF period of both axes: u_p from the NCT, the integral (clamped), the fuzzy output."""
    up = np.empty(1)
    ui = np.empty(1)
    u = np.empty(1)
    for a in range(2):
        nct = m[a] * e[a]
        if nct > h_max[a]:
            nct = h_max[a]
        elif nct < -h_max[a]:
            nct = -h_max[a]
        up[0] = e_dot[a] - nct
        limit = u_i_max[a] / k_i[a]
        s = integral[a] + up[0] * T
        if s > limit:
            s = limit
        elif s < -limit:
            s = -limit
        integral[a] = s
        ui[0] = k_i[a] * s
        fuzzy_compensate(up, ui, h_max[a], h_s_res[a], u_i_max[a], u_i_s_res[a], rules, grid[a], output_mf[a], u)
        out[a] = u[0]


class NCTFPolicy(BaselinePolicy):
    """Fuzzy-based NCTF controller of Purtojo et al. (Fig. 1(a), Table I, eqs. (1)-(2)), per axis.

    At construction the controller is designed the paper's way on the
    env's nominal plant: :func:`stepwise_experiment` at the decision
    period, :func:`construct_nct` per axis, :func:`design_compensator`.

    Parameters
    ----------
    layout : vcnc_gym.envs.layout.ObservationLayout
        Names the observation fields.
    decision_period : float
        Period in s at which :meth:`predict` is called; also the
        experiment's sample period.
    nominal_parameters : array_like, (2, P)
        The nominal table (Purtojo et al.'s ``nct_xy_table`` parameters).
    plant : str or PlantModel, optional
        ``"nct_xy_table"``.
    integral_gain, on_time, off_time, fit_fraction, velocity_window, zero_rate :
        See :class:`NCTFSettings`.

    Attributes
    ----------
    experiment : StepwiseExperiment
    nct : tuple of NominalCharacteristicTrajectory
        x and y.
    compensators : tuple of FuzzyCompensator
        x and y.

    Notes
    -----
    Memory per env (``state_shape`` (3, 2)): the integral of ``u_p`` (mm),
    the previous tracking error (mm) and whether there is one (the first
    step of an episode takes ``de/dt = v_d - v`` from the observation).
    The controller reads the tracking error, i.e. the sensor's quantised
    position, never the true one.
    """

    name = "nctf"
    plants = ("nct_xy_table",)
    paper = "Purtojo et al."
    state_shape = (3, 2)

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        integral_gain=DEFAULT_SETTINGS.integral_gain,
        on_time=DEFAULT_SETTINGS.on_time,
        off_time=DEFAULT_SETTINGS.off_time,
        fit_fraction=DEFAULT_SETTINGS.fit_fraction,
        velocity_window=DEFAULT_SETTINGS.velocity_window,
        zero_rate=DEFAULT_SETTINGS.zero_rate,
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        if integral_gain is not None:
            integral_gain = positive("integral_gain", integral_gain)
        self.settings = NCTFSettings(
            integral_gain=integral_gain,
            on_time=positive("on_time", on_time),
            off_time=positive("off_time", off_time),
            fit_fraction=positive("fit_fraction", fit_fraction),
            velocity_window=positive("velocity_window", velocity_window),
            zero_rate=zero_rate,
        )
        self.experiment = stepwise_experiment(self.nominal_parameters, self.decision_period, self.settings, self.plant)
        self.nct = tuple(construct_nct(self.experiment, a, self.settings) for a in (0, 1))
        self.compensators = tuple(
            design_compensator(n, r, self.decision_period, self.settings)
            for n, r in zip(self.nct, self.experiment.resolution)
        )
        c = self.compensators
        self._m = np.array([n.m for n in self.nct])
        self._h_max = np.array([x.h_max for x in c])
        self._k_i = np.array([x.integral_gain for x in c])
        self._u_i_max = np.array([x.u_i_max for x in c])
        self._h_s_res = np.array([x.h_s_res for x in c])
        self._u_i_s_res = np.array([x.u_i_s_res for x in c])
        self._grid = np.array([x.output_grid for x in c])
        self._output_mf = np.array([output_memberships(g) for g in self._grid])

    def _command(self, obs):
        e = self.layout.tracking_error(obs)
        first_rate = self.layout.reference_velocity(obs) - self.layout.velocity(obs)
        T = self.decision_period
        out = np.empty((obs.shape[0], 2))
        for i in range(obs.shape[0]):
            st = self._state[i]
            e_dot = first_rate[i] if st[2, 0] == 0.0 else (e[i] - st[1]) / T
            _nctf_step(
                e[i],
                e_dot,
                self._m,
                self._h_max,
                self._k_i,
                T,
                self._u_i_max,
                self._h_s_res,
                self._u_i_s_res,
                st[0],
                RULE_TABLE,
                self._grid,
                self._output_mf,
                out[i],
            )
            st[1] = e[i]
            st[2] = 1.0
        return out
