"""The robust QFT controller of Jahanpour et al. (2014), section 2c, and its robustness checks.

Jahanpour, Honari-Torshizi and Gharib (2014) design, for both axes,
a two-degree-of-freedom loop (its Fig. 3)

.. math::

    u = G(s) \\, (F(s) \\, r - y), \\qquad
    G(s) = \\frac{22.36 s + 61.21}{0.0001 s + 1.326}, \\qquad
    F(s) = \\frac{8.72}{0.001 s^2 + 0.187 s + 8.72},

with r the axis position command (mm), y the table position (mm) and u the
amplifier command (V), saturated at +-5 V (Table 3).  The loop is designed to
keep the robust-stability bound of eq. (11),

.. math:: \\left| \\frac{P(j\\omega) G(j\\omega)}{1 + P(j\\omega) G(j\\omega)} \\right| < \\mu = 1.2,

over the plant set P(s) = r_g K_t K_a / (s (J s + B)) with r_g, K_t, K_a and B
in the intervals of section 2c.

Implementation
--------------
The observation carries absolute positions as float32 (about 8 nm of
quantisation at 100 mm).  Through G's high-frequency gain (2.2e5 V/mm) such
noise would reach the amplifier as volts, so the policy never forms ``F r - y``
from absolute positions.  Instead it uses the exact identity

.. math::

    F r - y = (F - 1) r + (r - y) = H(s) \\, v_r + e, \\qquad
    H(s) = \\frac{F(s) - 1}{s},

where e = r - y is the observed tracking error and v_r = dr/dt the observed
reference velocity.  H(s) = -(0.001 s + 0.187)/(0.001 s^2 + 0.187 s + 8.72)
is proper and stable because F(0) = 1; its zero initial state is the steady
state of an axis at rest, so resetting the filter states to zero at the start
of an episode is exact when the reference starts at rest.

G(s) and H(s) are discretised once with the Tustin (bilinear) transform at the
env's decision period, using :func:`control.c2d`.  Tustin maps the stable
left-half plane onto the unit disc, keeps G's and H's DC gains exactly and
matches their frequency responses to within (omega T)^2/12 in relative terms
well below the Nyquist frequency.  The two discrete systems are joined with
:func:`control.series` into one 2-input (v_r, e), 1-output (u) state-space
model, stepped per axis by :func:`vcnc_baselines.linear.lti_step`.

Robustness figures (computed by the functions below)
----------------------------------------------------
* Continuous loop, eq. (11), over the 64 vertices and a 5^4 grid of the
  box: peak ``|T|`` = 1.170 on x (at about 9.7e3 rad/s) and 1.141 on y, both
  below mu = 1.2.
* The sampled loop (zero-order-hold plant, Tustin G) is stable on every
  vertex at 0.1 ms (largest pole modulus 0.99973, the slow pole of G's zero
  at 2.7 rad/s) and unstable at 1 ms, the paper's interpolation period
  (a pole at ``|z|`` = 10.7 on x, 9.8 on y): G lifts the crossover to about
  8.6e3 rad/s.  At 0.1 ms the hold's delay and the bilinear warping cost
  about 27 degrees of phase there (nominal x: phase margin 57 -> 30
  degrees, gain margin infinite -> 1.96): the sampled peak of ``|T|`` is about 4.0
  (x) and 3.3 (y), and the nominal closed-loop pair has a damping ratio of
  about 0.23.  Eq. (11) holds for the sampled loop only from about
  dt = 1e-5 s on.

What the pre-filter does to the contour
---------------------------------------
From r to y the loop is about F(s) (``|T|`` is close to 1 far beyond F's
bandwidth), and F is a critically damped second-order filter with
omega_n = 93.4 rad/s: the table lags the command by F's delay,
0.187/8.72 = 21 ms, i.e. 2.1 mm at 100 mm/s, equally on both axes.  On a
path of curvature radius R the filtered path cuts inside by about
v^2 / (R omega_n^2), so the QFT's contour error is dominated by F (about
0.2 mm on the heart at 100 mm/s; with F = 1 the same G gives about 16 um).
This is the paper's design as published, kept as is.
"""

from __future__ import annotations

import itertools
import warnings
from collections import namedtuple

import control
import numpy as np
from numba import njit
from numba.extending import overload
from scipy.optimize import minimize_scalar

from vcnc_gym.envs import controller_contract
from vcnc_gym.plants import vcnc_feed_drive as feed_drive
from vcnc_gym.validation import polynomial
from ..base import BaselinePolicy
from ..linear import DiscreteLTI, discretize, lti_advance

__all__ = [
    "QFT_CONTROLLER",
    "QFT_PREFILTER",
    "MU",
    "QFTPolicy",
    "QFTArrays",
    "controller_tf",
    "prefilter_tf",
    "reference_velocity_filter_tf",
    "plant_parameter_sets",
    "robust_stability_peak",
    "sampled_loop_spectral_radius",
    "sampled_loop_stable",
]

#: G(s) of Jahanpour et al. (2014), section 2c, (numerator, denominator), highest power first; V/mm.
QFT_CONTROLLER = ((22.36, 61.21), (0.0001, 1.326))
#: F(s) of Jahanpour et al. (2014), section 2c, (numerator, denominator); dimensionless, F(0) = 1.
QFT_PREFILTER = ((8.72,), (0.001, 0.187, 8.72))
#: Robust-stability bound mu of Jahanpour et al. (2014), eq. (11).
MU = 1.2


# -- transfer functions ------------------------------------------------------
def _as_tf(name: str, value) -> control.TransferFunction:
    """A continuous SISO proper transfer function from a TransferFunction or a (num, den) pair."""
    if isinstance(value, control.TransferFunction):
        if value.ninputs != 1 or value.noutputs != 1:
            raise ValueError(f"{name} must be SISO")
        if value.isdtime(strict=True):
            raise ValueError(f"{name} must be a continuous-time transfer function")
        num, den = (np.asarray(c, dtype=float) for c in (value.num[0][0], value.den[0][0]))
    else:
        if isinstance(value, (str, bytes)):
            raise ValueError(f"{name} must be a (numerator, denominator) pair or a TransferFunction, got {value!r}")
        try:
            num, den = value
        except (TypeError, ValueError):
            raise ValueError(
                f"{name} must be a (numerator, denominator) pair or a TransferFunction, got {value!r}"
            ) from None
    num = polynomial(f"{name} numerator", num)
    den = polynomial(f"{name} denominator", den)
    if num.size > den.size:
        raise ValueError(f"{name} must be proper (numerator degree {num.size - 1} > denominator degree {den.size - 1})")
    return control.tf(num, den)


def controller_tf(controller=QFT_CONTROLLER) -> control.TransferFunction:
    """The feedback controller G(s) in V/mm (Jahanpour et al. (2014), section 2c)."""
    return _as_tf("controller", controller)


def prefilter_tf(prefilter=QFT_PREFILTER) -> control.TransferFunction:
    """The pre-filter F(s) (Jahanpour et al. (2014), section 2c); checked stable with F(0) = 1.

    Raises
    ------
    ValueError
        If F is not proper, not stable (a pole with real part >= 0) or does
        not have unit DC gain (then F r would not follow a constant r).
    """
    F = _as_tf("prefilter", prefilter)
    poles = F.poles()
    if poles.size and np.max(poles.real) >= 0.0:
        raise ValueError(f"prefilter must be stable; it has poles {poles}")
    num, den = F.num[0][0], F.den[0][0]
    dc = num[-1] / den[-1] if den[-1] != 0 else np.inf
    if not np.isfinite(dc) or abs(dc - 1.0) > 1e-9:
        raise ValueError(f"prefilter must have unit DC gain F(0) = 1, got F(0) = {dc}")
    return F


def reference_velocity_filter_tf(prefilter=QFT_PREFILTER) -> control.TransferFunction:
    """H(s) = (F(s) - 1)/s in s, the filter applied to the reference velocity.

    With F = n/d and F(0) = 1, n - d has no constant term, so it divides by s
    exactly: H = ((n - d)/s)/d.  For the paper's F,
    H(s) = -(0.001 s + 0.187)/(0.001 s^2 + 0.187 s + 8.72).
    """
    F = prefilter_tf(prefilter)
    num, den = np.asarray(F.num[0][0], float), np.asarray(F.den[0][0], float)
    diff = np.polysub(num, den)  # n - d; its constant term is zero up to rounding (F(0) = 1)
    h_num = diff[:-1] if diff.size > 1 else np.array([0.0])  # exact division by s
    return control.tf(h_num, den)


# -- the policy ----------------------------------------------------------------
class QFTPolicy(BaselinePolicy):
    """QFT two-degree-of-freedom controller of Jahanpour et al. (2014), section 2c, per axis.

    Parameters
    ----------
    layout : vcnc_gym.envs.layout.ObservationLayout
        Names the observation fields.
    decision_period : float
        Period in s at which :meth:`predict` is called; G and H are
        discretised (Tustin) at it.
    nominal_parameters : array_like, (2, P)
        Nominal feed-drive parameters; ``u_max`` (V) scales the action and the
        nominal plant is used to warn when the sampled loop is unstable.
    controller : (num, den) or control.TransferFunction
        G(s) in V/mm, coefficients highest power first.  Default: Jahanpour et al.'s
        G(s) = (22.36 s + 61.21)/(0.0001 s + 1.326), used on both axes.
    prefilter : (num, den) or control.TransferFunction
        F(s), stable with F(0) = 1.  Default: Jahanpour et al.'s
        F(s) = 8.72/(0.001 s^2 + 0.187 s + 8.72).
    method : str
        Discretisation method of :func:`control.c2d` for G and H
        (default ``'tustin'``).

    Notes
    -----
    u = G(H v_r + e) in V with e = x_d - x (mm) and v_r = dx_d/dt (mm/s) read
    from the observation; see the module docstring for why this equals
    G(F r - y).  The command is saturated at +-u_max by the action clip; G has
    no integrator, so there is nothing to wind up.  Memory per env: the three
    states of the discrete (H, G) cascade of each axis.
    """

    name = "qft"
    plants = ("vcnc_feed_drive",)
    paper = "Jahanpour et al. (2014)"

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        controller=QFT_CONTROLLER,
        prefilter=QFT_PREFILTER,
        method: str = "tustin",
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        if not isinstance(method, str):
            raise ValueError(f"method must be a string, got {method!r}")
        self.G = controller_tf(controller)
        self.F = prefilter_tf(prefilter)
        self.H = reference_velocity_filter_tf(prefilter)
        self.method = method
        dt = self.decision_period
        try:
            self.G_d = discretize(self.G, dt, method)
            self.F_d = discretize(self.F, dt, method)
            self.H_d = discretize(self.H, dt, method)
        except Exception as exc:
            raise ValueError(f"cannot discretise with method {method!r}: {exc}") from None
        # W: (v_r, e) -> w = H v_r + e, then u = G w.
        Hd = self.H_d
        W = control.ss(Hd.A, np.hstack([Hd.B, np.zeros((Hd.nstates, 1))]), Hd.C, np.hstack([Hd.D, np.ones((1, 1))]), dt)
        self.K_d = control.series(W, self.G_d)
        self._lti = DiscreteLTI(self.K_d)
        self.state_shape = (2, self._lti.nx)
        radius = max(
            sampled_loop_spectral_radius(self.G, axis, dt, parameter_sets=self.nominal_parameters[None], method=method)
            for axis in (0, 1)
        )
        if radius >= 1.0:
            warnings.warn(
                f"the QFT loop sampled at {dt:g} s is unstable on the nominal plant "
                f"(closed-loop pole at |z| = {radius:.3g}); use a shorter decision period",
                RuntimeWarning,
                stacklevel=2,
            )

    def _command(self, obs):
        n = obs.shape[0]
        e = self.layout.tracking_error(obs)  # (n, 2) mm
        v_r = self.layout.reference_velocity(obs)  # (n, 2) mm/s
        inputs = np.stack([v_r, e], axis=-1).reshape(n * 2, 2)
        x = self._state.reshape(n * 2, self._lti.nx)  # a view: advanced in place
        return self._lti.step(x, inputs).reshape(n, 2)

    def _compiled_arrays(self) -> QFTArrays:
        """The compiled form (:mod:`vcnc_gym.envs.controller_contract`) around the current memory."""
        lti = self._lti
        n = self._state.shape[0]
        return QFTArrays(
            self._state,
            lti.A,
            lti.B,
            lti.C,
            lti.D,
            self.u_max,
            np.zeros((n, 2)),
            np.zeros((n, lti.ny)),
            np.zeros((n, lti.nx)),
        )


#: The compiled controller's arrays: the memory x (N, 2, nx), the (H, G) cascade's discrete state-space
#: matrices, u_max (V, (2,)) and per-env scratch (inputs (N, 2), output (N, 1), next state (N, nx)).
QFTArrays = namedtuple("QFTArrays", ["x", "A", "B", "C", "D", "u_max", "inputs", "y", "xn"])


@njit(cache=True, _nrt=False)
def _qft_command(q, i, obs, o, out):
    """:meth:`QFTPolicy._command` and ``predict``'s normalisation for env ``i``, in the same floating-point
    operations (:func:`~vcnc_baselines.linear.lti_advance` on the inputs (v_r, e) of each axis)."""
    inputs = q.inputs[i]
    for j in range(2):
        inputs[0] = np.float64(obs[o.reference_velocity + j])
        inputs[1] = np.float64(obs[o.tracking_error + j])
        lti_advance(q.A, q.B, q.C, q.D, q.x[i, j], inputs, q.y[i], q.xn[i])
        out[j] = np.float32(min(max(q.y[i, 0] / q.u_max[j], -1.0), 1.0))


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, QFTArrays):
        return lambda controller, i, obs, o, out: _qft_command(controller, i, obs, o, out)


# -- robustness analysis -------------------------------------------------------
def plant_parameter_sets(axis: int, n_grid: int = 5, vertices=None) -> np.ndarray:
    """Plant parameter sets of one axis: the box vertices plus a grid over the box.

    Parameters
    ----------
    axis : int or {"x", "y"}
        0 (x) or 1 (y).
    n_grid : int
        Grid points per uncertain parameter, end points included (0: vertices only).
    vertices : array_like, (V, 2, P), optional
        Vertices of the uncertainty box; default the plant's 64 vertices
        (Jahanpour et al. (2014), section 2c: r_g, K_t, K_ax, K_ay, B_x, B_y).

    Returns
    -------
    ndarray, (N, 2, P)
        Parameter arrays of both axes; only row ``axis`` varies.  The first V
        rows are the vertices themselves.
    """
    axis = _axis_index(axis)
    V = feed_drive.uncertainty_vertices() if vertices is None else np.asarray(vertices, dtype=float)
    if V.ndim != 3 or V.shape[1:] != (2, len(feed_drive.PARAMETER_NAMES)):
        raise ValueError(f"vertices must have shape (V, 2, {len(feed_drive.PARAMETER_NAMES)}), got {V.shape}")
    rows = V[:, axis, :]
    lo, hi = rows.min(axis=0), rows.max(axis=0)
    varying = np.flatnonzero(hi > lo)
    sets = [V]
    if n_grid and varying.size:
        axes = [np.linspace(lo[k], hi[k], int(n_grid)) for k in varying]
        grid = np.array(list(itertools.product(*axes)))
        G = np.repeat(V[:1], grid.shape[0], axis=0)
        G[:, axis, varying] = grid
        sets.append(G)
    return np.concatenate(sets)


def _axis_index(axis) -> int:
    if isinstance(axis, str):
        if axis.lower() not in ("x", "y"):
            raise ValueError(f"axis must be 0, 1, 'x' or 'y', got {axis!r}")
        return "xy".index(axis.lower())
    if axis not in (0, 1) or isinstance(axis, bool):
        raise ValueError(f"axis must be 0, 1, 'x' or 'y', got {axis!r}")
    return int(axis)


def _loop_polynomials(G, axis, parameter_sets, dt, method):
    """(num_L, den_L) of L = P G per parameter set; discrete (ZOH P, ``method`` G) when dt is given."""
    G = controller_tf(G)
    if dt is not None:
        Gd = control.c2d(G, dt, method=method)
        gn, gd = np.asarray(Gd.num[0][0], float), np.asarray(Gd.den[0][0], float)
    else:
        gn, gd = np.asarray(G.num[0][0], float), np.asarray(G.den[0][0], float)
    out = []
    for p in parameter_sets:
        pn, pd = feed_drive.linear_transfer_function_coefficients(p, axis)
        if dt is not None:
            Pd = control.c2d(control.tf(pn, pd), dt, method="zoh")
            pn, pd = np.asarray(Pd.num[0][0], float), np.asarray(Pd.den[0][0], float)
        out.append((np.polymul(pn, gn), np.polymul(pd, gd)))
    return out


def _complementary_sensitivity(num, den, omega, dt):
    x = np.exp(1j * omega * dt) if dt is not None else 1j * omega
    L = np.polyval(num, x) / np.polyval(den, x)
    return np.abs(L / (1.0 + L))


def robust_stability_peak(
    G=QFT_CONTROLLER,
    axis=0,
    dt=None,
    *,
    n_grid: int = 5,
    vertices=None,
    omega=None,
    method: str = "tustin",
    full_output: bool = False,
):
    """Worst-case peak of ``|P G / (1 + P G)|`` over the uncertainty box, Jahanpour et al.'s eq. (11).

    Parameters
    ----------
    G : (num, den) or control.TransferFunction
        Continuous controller G(s) in V/mm; default Jahanpour et al.'s.
    axis : int or {"x", "y"}
        The feed-drive axis.
    dt : float, optional
        If given, the sampled loop instead: P discretised with a zero-order
        hold and G with ``method`` at period dt (s), evaluated on the unit
        circle up to the Nyquist frequency pi/dt.
    n_grid : int
        Points per uncertain parameter of the interior grid added to the
        vertices (see :func:`plant_parameter_sets`).
    vertices : array_like, (V, 2, P), optional
        Box vertices; default the plant's 64.
    omega : array_like, optional
        Frequency grid in rad/s; default 4000 log-spaced points from 0.01
        rad/s to 1e6 rad/s (or to pi/dt).  The largest value found is then
        refined by a bounded scalar search between its grid neighbours.
    method : str
        Discretisation method of G when dt is given.
    full_output : bool
        Also return the frequency (rad/s) and the parameters of the worst case.

    Returns
    -------
    peak : float
        max ``|T(j omega)|`` over plants and frequencies; eq. (11) asks for < mu = 1.2.
    omega_peak : float
        Only with ``full_output``: the frequency of the peak, rad/s.
    parameters : ndarray, (2, P)
        Only with ``full_output``: the worst plant.

    Notes
    -----
    A type-1 loop has ``|T|`` -> 1 at low frequency, so the peak is >= 1; a peak
    above 1 is a real resonance of the closed loop.  The discrete peak is only
    meaningful when the sampled loop is stable
    (:func:`sampled_loop_spectral_radius` < 1).
    """
    axis = _axis_index(axis)
    sets = plant_parameter_sets(axis, n_grid, vertices)
    loops = _loop_polynomials(G, axis, sets, dt, method)
    w_max = 1e6 if dt is None else np.pi / dt
    w = np.logspace(-2, np.log10(w_max), 4000) if omega is None else np.asarray(omega, dtype=float)
    mags = np.array([_complementary_sensitivity(n, d, w, dt) for n, d in loops])
    k, j = np.unravel_index(np.argmax(mags), mags.shape)
    best, w_best = mags[k, j], w[j]
    # refine on the three worst plants
    for kk in np.argsort(mags.max(axis=1))[-3:]:
        jj = int(np.argmax(mags[kk]))
        lo, hi = w[max(jj - 1, 0)], w[min(jj + 1, w.size - 1)]
        if hi > lo:
            res = minimize_scalar(
                lambda lw: -_complementary_sensitivity(*loops[kk], np.array([10.0**lw]), dt)[0],
                bounds=(np.log10(lo), np.log10(hi)),
                method="bounded",
                options={"xatol": 1e-10},
            )
            if -res.fun > best:
                best, w_best, k = -res.fun, 10.0**res.x, kk
    if full_output:
        return float(best), float(w_best), sets[k].copy()
    return float(best)


def sampled_loop_spectral_radius(
    G=QFT_CONTROLLER, axis=0, dt=1e-4, *, parameter_sets=None, method: str = "tustin"
) -> float:
    """Largest closed-loop pole modulus ``|z|`` of the sampled loop over a plant set.

    The loop is the ZOH-discretised plant P(z) (Jahanpour et al. (2014), eq. (1)) in unity
    feedback with G discretised by ``method`` at ``dt``; the poles are those
    of :func:`control.feedback` (P G, 1).

    Parameters
    ----------
    G : (num, den) or control.TransferFunction
        Continuous controller in V/mm; default Jahanpour et al.'s G(s).
    axis : int or {"x", "y"}
        Feed-drive axis.
    dt : float
        Sampling period, s.
    parameter_sets : array_like, (N, 2, P), optional
        Plants to check; default the 64 vertices of the uncertainty box.

    Returns
    -------
    float
        max ``|z|`` over all closed-loop poles and plants; < 1 means stable.
    """
    axis = _axis_index(axis)
    sets = feed_drive.uncertainty_vertices() if parameter_sets is None else np.asarray(parameter_sets, dtype=float)
    Gd = control.c2d(controller_tf(G), dt, method=method)
    radius = 0.0
    for p in sets:
        pn, pd = feed_drive.linear_transfer_function_coefficients(p, axis)
        Pd = control.c2d(control.tf(pn, pd), dt, method="zoh")
        poles = control.feedback(Pd * Gd, 1).poles()
        radius = max(radius, float(np.max(np.abs(poles))))
    return radius


def sampled_loop_stable(G=QFT_CONTROLLER, dt=1e-4, *, axes=(0, 1), parameter_sets=None, method: str = "tustin") -> bool:
    """True if the sampled loop (ZOH plant, discretised G) is stable on every vertex of every axis."""
    return all(sampled_loop_spectral_radius(G, a, dt, parameter_sets=parameter_sets, method=method) < 1.0 for a in axes)
