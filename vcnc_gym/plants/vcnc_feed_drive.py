"""Biaxial feed drive of Jahanpour et al. (2014) (VCNC contouring with QFT), as numba kernels.

Each of the two axes (x, y) of a machine is the rigid feed drive of
Jahanpour et al. (2014), section 2a, eq. (1),

.. math::

    X_t(s) = \\frac{r_g}{s} \\frac{1}{J s + B} \\left[K_t K_a U_a(s) - T_d(s)\\right],

read in the time domain as

.. math::

    J \\dot\\omega = K_t K_a \\,\\mathrm{sat}(u) - B \\omega - T_f(\\omega, u),
    \\qquad \\dot x_m = r_g \\omega,
    \\qquad x_t = \\mathrm{play}_{D_b}(x_m),

with

- ``u`` the commanded voltage [V], clipped to ``[-u_max, u_max]`` by the
  amplifier (Table 3, "Saturation limits");
- ``omega`` the motor angular velocity [rad/s] and ``x_m = r_g * theta`` the
  motor-side linear position [mm];
- ``T_f`` a Karnopp stick-slip friction torque [N m] with asymmetric static
  and Coulomb levels (Table 3): a drive with ``omega == 0.0``
  (exactly) is stuck until the motor torque ``T_m = K_t K_a u`` exceeds
  ``T_stat_pos`` (break-away in + direction) or falls below ``T_stat_neg``
  (break-away in - direction); a moving drive feels ``T_coul_pos`` for
  ``omega > 0`` and ``T_coul_neg`` (a negative number) for ``omega < 0``;
- ``x_t`` the table position [mm], which follows ``x_m`` through a backlash
  (play / hysteresis operator) of width ``D_b`` (Table 3):
  ``x_t <- clip(x_t, x_m - D_b/2, x_m + D_b/2)``. The table is what is
  measured and what cuts. The cutting torque ``T_c`` of eq. (1) is zero (Jahanpour
  et al. simulate air cutting).

The uncertain parameters and their intervals are those of the paper's
section 2c: ``r_g`` and ``K_t`` are one value per machine shared by both
axes, ``K_a`` and ``B`` are per axis. Nominal values are the interval
midpoints.

Integration is exact for piecewise-constant torque: the input is held
constant over the control period ``dt`` (zero-order hold), which is split
into ``n_substeps`` equal substeps; in each substep the friction torque is
constant and the linear ODE is solved in closed form. A velocity zero
crossing inside a substep is located exactly; the drive stops there and, if
the motor torque breaks it away in the opposite direction, moves on for the
rest of that substep (the suite's one stick-slip routine,
:func:`vcnc_gym.plants.stick_slip.stick_slip`), so with friction and backlash set to zero the kernel
is the exact ZOH discretisation of eq. (1). Because the motor torque is
constant over a control period, a substep holds at most one stop and one
break-away after it, and the play operator is applied at the stop and at the
end of each substep (the motion between is monotone), so the result is exact
for any ``n_substeps >= 1`` up to rounding. Substeps would matter only for a
torque that varies within a period (e.g. a position-dependent cutting torque
``T_c``); ``DEFAULT_SUBSTEP`` keeps that margin for a few tens of ns per call.

Layouts
-------
state : (N, 2, 3) float64
    ``state[k, i] = (x_m [mm], omega [rad/s], x_t [mm])`` for machine ``k``
    and axis ``i`` (0 = x, 1 = y). See ``STATE_NAMES`` and the ``S_*``
    indices.
params : (N, 2, P) float64
    ``params[k, i, j]`` is parameter ``PARAMETER_NAMES[j]`` of axis ``i`` of
    machine ``k``; see the ``IDX_*`` indices. Shared parameters (``r_g``,
    ``K_t``) are stored on both axes with equal values.
voltage : (N, 2) float64
    Commanded voltage [V] per machine and axis.

Examples
--------
>>> import numpy as np
>>> from vcnc_gym.plants import vcnc_feed_drive as fd
>>> params = fd.nominal_parameters()[None]          # (1, 2, P)
>>> state = np.empty((1, 2, 3))
>>> fd.reset_feed_drives(state, np.zeros((1, 2)))
>>> fd.step_feed_drives(state, np.array([[5.0, -5.0]]), params, 1e-4,
...                     fd.substeps_for(1e-4))
>>> bool(state[0, 0, fd.S_W] > 0.0 and state[0, 1, fd.S_W] < 0.0)
True
"""

from __future__ import annotations

import math
from collections import namedtuple

import numba
import numpy as np
from numba.extending import overload

from . import contract
from .contract import Parameter, PlantModel
from .exact_zoh import first_order
from .stick_slip import STOPPED, STUCK, StickSlipAxis, stick_slip
from ..validation import positive

__all__ = [
    "PARAMETER_NAMES",
    "N_PARAMETERS",
    "IDX_R_G",
    "IDX_K_T",
    "IDX_K_A",
    "IDX_J",
    "IDX_B",
    "IDX_T_STAT_POS",
    "IDX_T_STAT_NEG",
    "IDX_T_COUL_POS",
    "IDX_T_COUL_NEG",
    "IDX_BACKLASH",
    "IDX_U_MAX",
    "STATE_NAMES",
    "S_XM",
    "S_W",
    "S_XT",
    "AXES",
    "PARAMETERS",
    "MODEL",
    "FeedDriveArrays",
    "PARAMETER_INTERVALS",
    "DEFAULT_DT",
    "DEFAULT_SUBSTEP",
    "substeps_for",
    "parameter_intervals",
    "nominal_parameters",
    "sample_parameters",
    "uncertainty_vertices",
    "parameters_to_dict",
    "without_nonlinearities",
    "validate_parameters",
    "linear_transfer_function_coefficients",
    "reset_feed_drives",
    "step_feed_drives",
    "table_velocity",
    "table_velocities",
]

# --------------------------------------------------------------------------
# The numbers, each with its source: the one declaration of this plant
# --------------------------------------------------------------------------

#: Axis order of axis 1 of every array.
AXES = contract.AXES

_SECTION_2C = "Jahanpour et al. (2014), section 2c"
_TABLE_3 = "Jahanpour et al. (2014), Table 3"

#: The per-axis parameters, in the order of the last axis of a parameter
#: array.  Uncertain ones carry the paper's intervals (section 2c; nominal =
#: midpoint; r_g and K_t are one value per machine), fixed ones Table 3's
#: values (J is "Total reflected inertia", printed kg/m^2 in the paper;
#: T_coul are the paper's "T_cont"; saturation limits -5, +5 V).
PARAMETERS = (
    Parameter(
        "r_g",
        "mm/rad",
        interval=((1.4, 1.73), (1.4, 1.73)),
        shared=True,
        source=_SECTION_2C,
        description="transmission gain (ball screw and gear)",
        physical_range=(0.01, 20),
        range_source="ours: ball-screw leads of 1-40 mm/rev through gear ratios 1-10 give 0.016-6.4 mm/rad",
    ),
    Parameter(
        "K_t",
        "N m/A",
        interval=((0.42, 0.52), (0.42, 0.52)),
        shared=True,
        source=_SECTION_2C,
        description="motor torque constant",
        physical_range=(0.005, 20),
        range_source="ours: feed-drive servo motors' torque constants span 0.01-10 N m/A",
    ),
    Parameter(
        "K_a",
        "A/V",
        interval=((5.71, 7.07), (6.67, 8.26)),
        source=_SECTION_2C,
        description="amplifier gain",
        physical_range=(0.01, 100),
        range_source="ours: current amplifiers' transconductance spans 0.05-50 A/V",
    ),
    Parameter(
        "J",
        "kg m^2",
        nominal=(0.0077736, 0.0098109),
        source=_TABLE_3,
        description="total reflected inertia",
        physical_range=(1e-06, 10),
        range_source="ours: rotor plus reflected table inertia, 1e-5 (small servo) to 1 kg m^2",
    ),
    Parameter(
        "B",
        "N m s/rad",
        interval=((0.014, 0.026), (0.02, 0.037)),
        source=_SECTION_2C,
        sign="nonnegative",
        description="viscous friction",
        physical_range=(0, 10),
        range_source="ours: 300 times the box's upper end; at 10 N m s/rad a 2000 rpm motor loses 2 kN m",
    ),
    Parameter(
        "T_stat_pos",
        "N m",
        nominal=(2.6256, 2.7658),
        source=_TABLE_3,
        sign="nonnegative",
        description="static friction, break-away in + direction",
        physical_range=(0, 100),
        range_source="ours: the continuous torque of the largest feed-drive servo motors",
    ),
    Parameter(
        "T_stat_neg",
        "N m",
        nominal=(-1.8672, -2.4520),
        source=_TABLE_3,
        sign="nonpositive",
        description="static friction, break-away in - direction",
        physical_range=(-100, 0),
        range_source="ours: the continuous torque of the largest feed-drive servo motors",
    ),
    Parameter(
        "T_coul_pos",
        "N m",
        nominal=(2.1529, 2.5228),
        source=_TABLE_3,
        sign="nonnegative",
        description="Coulomb friction while w > 0",
        physical_range=(0, 100),
        range_source="ours: the continuous torque of the largest feed-drive servo motors",
    ),
    Parameter(
        "T_coul_neg",
        "N m",
        nominal=(-1.4730, -2.3887),
        source=_TABLE_3,
        sign="nonpositive",
        description="Coulomb friction while w < 0",
        physical_range=(-100, 0),
        range_source="ours: the continuous torque of the largest feed-drive servo motors",
    ),
    Parameter(
        "backlash",
        "mm",
        nominal=(0.003, 0.003),
        source=_TABLE_3,
        sign="nonnegative",
        description="backlash width D_b",
        physical_range=(0, 1),
        range_source="ours: a worn machine's play is tenths of a mm",
    ),
    Parameter(
        "u_max",
        "V",
        nominal=(5.0, 5.0),
        source=_TABLE_3,
        description="amplifier saturation",
        physical_range=(0.1, 100),
        range_source="ours: amplifier commands are +-10 V in industry, +-100 V at most",
    ),
)

#: Names of the per-axis parameters, in the order of the last axis of a
#: parameter array.
PARAMETER_NAMES = tuple(p.name for p in PARAMETERS)
N_PARAMETERS = len(PARAMETER_NAMES)
(
    IDX_R_G,
    IDX_K_T,
    IDX_K_A,
    IDX_J,
    IDX_B,
    IDX_T_STAT_POS,
    IDX_T_STAT_NEG,
    IDX_T_COUL_POS,
    IDX_T_COUL_NEG,
    IDX_BACKLASH,
    IDX_U_MAX,
) = range(N_PARAMETERS)

#: Names of the per-axis state entries: motor-side position x_m [mm], motor
#: angular velocity w [rad/s], table position x_t [mm].
STATE_NAMES = ("x_m", "w", "x_t")
S_XM, S_W, S_XT = 0, 1, 2

#: Uncertainty intervals of Jahanpour et al. (2014), section 2c, keyed by name: shared ones
#: (lo, hi), per-axis ones ((lo_x, hi_x), (lo_y, hi_y)).  Derived from
#: ``PARAMETERS``.
PARAMETER_INTERVALS = {
    p.name: (p.interval[0] if p.shared else p.interval) for p in PARAMETERS if p.interval is not None
}

#: Default control period of the envs [s] (see DESIGN.md, "Control rate").
DEFAULT_DT = 1e-4

#: Default integration substep [s] (10 substeps at the default control period).
#: With the torques of this model constant over a control period the kernel is
#: exact for any substep count (stops, break-away and backlash are located
#: inside the substep), so this value is a margin, not an accuracy need: it
#: bounds the time resolution of anything later made to vary within a period
#: (a 1e-5 s delay of a break-away moves the table < 1 nm at the drives'
#: maximum acceleration K_t K_a u_max r_g / J ~ 5e3 mm/s^2). Cost: ~5 ns per
#: axis-substep.
DEFAULT_SUBSTEP = 1e-5


def substeps_for(dt: float) -> int:
    """Number of substeps for a control period.

    Parameters
    ----------
    dt : float
        Control period [s], > 0.

    Returns
    -------
    int
        ``ceil(dt / DEFAULT_SUBSTEP)`` (at least 1), with ratios within 1e-9
        of an integer rounded to it so that ``substeps_for(1e-4) == 10``.
    """
    dt = positive("dt", dt, "s")
    ratio = dt / DEFAULT_SUBSTEP
    nearest = round(ratio)
    if abs(ratio - nearest) <= 1e-9 * max(1.0, ratio):
        return max(1, int(nearest))
    return max(1, math.ceil(ratio))


def _check_friction(p: np.ndarray) -> None:
    ordered = (p[..., IDX_T_STAT_NEG] <= p[..., IDX_T_COUL_NEG]) & (p[..., IDX_T_COUL_POS] <= p[..., IDX_T_STAT_POS])
    if not np.all(ordered):
        raise ValueError("friction must satisfy T_stat_neg <= T_coul_neg <= 0 <= T_coul_pos <= T_stat_pos")


def linear_transfer_function_coefficients(params: np.ndarray, axis: int):
    """Voltage-to-table-position transfer function of Jahanpour et al. (2014), eq. (1).

    ``P(s) = r_g K_t K_a / (s (J s + B))`` [mm/V], friction, backlash and
    saturation ignored.

    Parameters
    ----------
    params : array_like
        Shape ``(2, N_PARAMETERS)`` (one machine); columns beyond those (a
        shop-floor plant's effects, :mod:`vcnc_gym.plants.shop_floor`) are
        not part of the linear model and are ignored.
    axis : int
        0 for x, 1 for y.

    Returns
    -------
    num, den : numpy.ndarray
        Polynomial coefficients in descending powers of s:
        ``num = [r_g K_t K_a]``, ``den = [J, B, 0]``; e.g. for
        ``control.tf(num, den)``.
    """
    p = np.asarray(params, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] != 2 or p.shape[1] < N_PARAMETERS:
        raise ValueError(f"params must have shape (2, {N_PARAMETERS}), got {p.shape}")
    if axis not in (0, 1):
        raise ValueError(f"axis must be 0 (x) or 1 (y), got {axis!r}")
    a = p[axis]
    num = np.array([a[IDX_R_G] * a[IDX_K_T] * a[IDX_K_A]])
    den = np.array([a[IDX_J], a[IDX_B], 0.0])
    return num, den


#: The arrays of N machines the env's step kernel holds (the contract's
#: plant namedtuple): ``state`` (N, 2, 3) as ``STATE_NAMES``, ``params``
#: (N, 2, P), the control period ``dt`` [s] and its ``n_substeps``.
FeedDriveArrays = namedtuple("FeedDriveArrays", ["state", "params", "dt", "n_substeps"])


def _make_arrays(n_machines: int, dt: float, substep: float = DEFAULT_SUBSTEP) -> FeedDriveArrays:
    """Arrays of N machines at rest at the origin, nominal; ``substep`` [s] the integration substep."""
    substep = positive("substep", substep, "s")
    params = np.repeat(MODEL.nominal()[None], n_machines, axis=0)
    return FeedDriveArrays(np.zeros((n_machines, 2, 3)), params, float(dt), max(1, math.ceil(dt / substep - 1e-9)))


def _reset_machine(arrays: FeedDriveArrays, k: int, position) -> None:
    """Machine ``k`` at rest at ``position`` (2,) mm with the backlash gap centred."""
    arrays.state[k, :, S_XM] = position
    arrays.state[k, :, S_W] = 0.0
    arrays.state[k, :, S_XT] = position


#: This plant, as the envs and baselines see it (:class:`~vcnc_gym.plants.contract.PlantModel`).
def _inverse_dynamics(params: np.ndarray) -> contract.InverseDynamics:
    """Eq. (1) of Jahanpour et al. (2014) inverted: ``u = (J a + B v) / (r_g K_t K_a) + T_coul / (K_t K_a)`` V,
    the Coulomb level of the direction of motion (Table 3), and the backlash ``D_b`` the drive must cross at a
    reversal (Table 3).  Static friction (break-away) is left to the feedback."""
    volts_to_torque = params[:, IDX_K_T] * params[:, IDX_K_A]  # N m per V
    coulomb = np.column_stack([params[:, IDX_T_COUL_POS], params[:, IDX_T_COUL_NEG]]) / volts_to_torque[:, None]
    return contract.InverseDynamics.from_linear(MODEL, params, coulomb, params[:, IDX_BACKLASH])


def _force_gain(params: np.ndarray) -> np.ndarray:
    """Volts per newton of force on the table, per axis: a force F [N] on the table is a torque F r_g / 1000
    [N m] on the motor (r_g in mm/rad), which the amplifier produces from ``r_g / (1000 K_t K_a)`` V per N
    (Jahanpour et al. (2014), eq. (1): the cutting torque T_c enters beside K_t K_a U_a)."""
    return 1e-3 * params[:, IDX_R_G] / (params[:, IDX_K_T] * params[:, IDX_K_A])


MODEL = PlantModel(
    name="vcnc_feed_drive",
    source="Jahanpour et al. (2014), eq. (1), section 2c and Table 3",
    parameters=PARAMETERS,
    state_names=("x_m [mm]", "w [rad/s]", "x_t [mm]"),
    input_name="amplifier voltage",
    input_unit="V",
    input_limit="u_max",
    make_arrays=_make_arrays,
    reset_machine=_reset_machine,
    check=_check_friction,
    linear_coefficients=linear_transfer_function_coefficients,
    inverse_dynamics=_inverse_dynamics,
    force_gain=_force_gain,
    # the position-loop bandwidth ceiling: the best max contour error of ff-pid, zpetc and ff-ccc on the nominal
    # plant of its ids over a grid (python experiments/classical-opponents/tune_servo.py)
    servo_bandwidth=1000.0,
    # the path limits the suite plans Jahanpour et al.'s moves with (motion.lookahead's JAHANPOUR2014_PATH_*):
    # 1000 mm/s^2 is 38 % of the drives' ~2.6e3 mm/s^2 at the +-5 V saturation
    path_limits=(1000.0, 3.0e4),
)


# --------------------------------------------------------------------------
# Parameter sets
# --------------------------------------------------------------------------


def parameter_intervals() -> dict:
    """Uncertainty intervals of Jahanpour et al. (2014), section 2c.

    Returns
    -------
    dict
        ``{"r_g": (lo, hi), "K_t": (lo, hi), "K_a": ((lo_x, hi_x), (lo_y,
        hi_y)), "B": (...)}`` in mm/rad, N m/A, A/V and kg m^2/s. A fresh
        copy; editing it changes nothing here.
    """
    return {k: tuple(tuple(v) if isinstance(v, tuple) else v for v in val) for k, val in PARAMETER_INTERVALS.items()}


def nominal_parameters() -> np.ndarray:
    """Nominal parameters of both axes, shape ``(2, N_PARAMETERS)``.

    Uncertain parameters at the midpoints of their intervals (section
    2c), fixed ones from Table 3 (``MODEL.nominal()``).
    """
    return MODEL.nominal()


def sample_parameters(rng: np.random.Generator) -> np.ndarray:
    """Draw one machine uniformly from the uncertainty box, shape ``(2, N_PARAMETERS)``.

    ``r_g`` and ``K_t`` are drawn once and shared by both axes; ``K_a`` and
    ``B`` are drawn per axis (section 2c): one ``rng.uniform``
    call over (r_g, K_t, K_a_x, K_a_y, B_x, B_y) (``MODEL.sample``).
    """
    return MODEL.sample(rng)


def uncertainty_vertices() -> np.ndarray:
    """All 64 corners of the 6-D box (r_g, K_t, K_a_x, K_a_y, B_x, B_y), shape ``(64, 2, N_PARAMETERS)``.

    Vertex ``m`` takes the upper bound of coordinate ``c`` when bit ``c`` of
    ``m`` is set (vertex 0 is all lower bounds, vertex 63 all upper bounds).
    """
    return MODEL.vertices()


def parameters_to_dict(params: np.ndarray) -> dict:
    """One machine's parameters as plain Python (shared ones floats, others (x, y)), e.g. for ``info``."""
    p = np.asarray(params, dtype=np.float64)
    if p.shape != (2, N_PARAMETERS):
        raise ValueError(f"params must have shape (2, {N_PARAMETERS}), got {p.shape}")
    return MODEL.to_dict(p)


def without_nonlinearities(params: np.ndarray, keep_saturation: bool = False) -> np.ndarray:
    """Copy of a parameter array with friction and backlash set to zero.

    What remains is the linear model of Jahanpour et al. (2014), eq. (1) (plus the
    amplifier saturation if ``keep_saturation``; otherwise ``u_max`` is set
    to ``inf``).

    Parameters
    ----------
    params : numpy.ndarray
        Shape ``(..., N_PARAMETERS)``.
    keep_saturation : bool
        Keep ``u_max`` [V] as it is.

    Returns
    -------
    numpy.ndarray
        A new array of the same shape.
    """
    p = np.array(params, dtype=np.float64, copy=True)
    p[..., [IDX_T_STAT_POS, IDX_T_STAT_NEG, IDX_T_COUL_POS, IDX_T_COUL_NEG, IDX_BACKLASH]] = 0.0
    if not keep_saturation:
        p[..., IDX_U_MAX] = np.inf
    return p


def validate_parameters(params, n_machines: int | None = None) -> np.ndarray:
    """Check a parameter array for the kernels: ``MODEL.validate`` with ``u_max = inf`` allowed.

    Returns a C-contiguous float64 ``(N, 2, P)`` array; raises ValueError on
    a wrong shape, non-finite entries, non-positive ``r_g``, ``K_t``,
    ``K_a``, ``J`` or ``u_max``, negative ``B`` or backlash, friction levels
    not ordered ``T_stat_neg <= T_coul_neg <= 0 <= T_coul_pos <=
    T_stat_pos``, or shared parameters that differ between the axes.
    """
    return MODEL.validate(params, n_machines, allow_infinite_limit=True)


# --------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------


@numba.njit(cache=True)
def _clip_play(x_t, x_m, half):
    lo = x_m - half
    if x_t < lo:
        return lo
    hi = x_m + half
    if x_t > hi:
        return hi
    return x_t


@numba.njit(cache=True)
def reset_feed_drives(state, positions):
    """Put all drives at rest at the given positions.

    Sets ``x_m = x_t = positions`` (backlash gap centred) and ``w = 0``
    (stuck).

    Parameters
    ----------
    state : numpy.ndarray
        (N, 2, 3) float64, overwritten: (x_m [mm], w [rad/s], x_t [mm]).
    positions : numpy.ndarray
        (N, 2) float64, table positions [mm].
    """
    for k in range(state.shape[0]):
        for i in range(2):
            state[k, i, S_XM] = positions[k, i]
            state[k, i, S_W] = 0.0
            state[k, i, S_XT] = positions[k, i]


@numba.njit(cache=True)
def step_feed_drives(state, voltage, params, dt, n_substeps):
    """Advance N biaxial feed drives by one control period, in place.

    Jahanpour et al. (2014), eq. (1) with saturation, Karnopp stick-slip friction and
    backlash (Table 3). The voltage is held constant over ``dt``
    and clipped to ``[-u_max, u_max]``; ``dt`` is split into ``n_substeps``
    equal substeps, each solved in closed form with velocity zero crossings
    located exactly. No validation (use ``validate_parameters``); callable
    from other ``@njit`` code.

    Parameters
    ----------
    state : numpy.ndarray
        (N, 2, 3) float64, (x_m [mm], w [rad/s], x_t [mm]); updated in place.
    voltage : numpy.ndarray
        (N, 2) float64, commanded voltage [V].
    params : numpy.ndarray
        (N, 2, N_PARAMETERS) float64, see ``PARAMETER_NAMES``.
    dt : float
        Control period [s].
    n_substeps : int
        Number of equal substeps, >= 1 (see ``substeps_for``).
    """
    for k in range(state.shape[0]):
        step_machine(state, k, voltage[k], params, dt, n_substeps)


@numba.njit(cache=True)
def step_machine(state, k, voltage, params, dt, n_substeps):
    """Advance both axes of machine ``k`` by one control period; ``voltage`` (2,) V. See ``step_feed_drives``."""
    h = dt / n_substeps
    for i in range(2):
        r_g = params[k, i, IDX_R_G]
        kt_ka = params[k, i, IDX_K_T] * params[k, i, IDX_K_A]
        jj = params[k, i, IDX_J]
        inv_j = 1.0 / jj
        axis = StickSlipAxis(
            jj,
            params[k, i, IDX_B],
            inv_j,
            params[k, i, IDX_T_STAT_POS],
            params[k, i, IDX_T_STAT_NEG],
            params[k, i, IDX_T_COUL_POS],
            params[k, i, IDX_T_COUL_NEG],
        )
        half = 0.5 * params[k, i, IDX_BACKLASH]
        u_max = params[k, i, IDX_U_MAX]

        u = voltage[i]
        if u > u_max:
            u = u_max
        elif u < -u_max:
            u = -u_max
        t_m = kt_ka * u
        zoh = first_order(axis.damping * inv_j, h)

        x_m = state[k, i, S_XM]
        w = state[k, i, S_W]
        x_t = state[k, i, S_XT]

        for _ in range(n_substeps):
            mode, w, travel, rest = stick_slip(axis, w, t_m, h, zoh)
            if mode == STUCK:
                continue
            x_m += r_g * travel
            if mode == STOPPED:
                # the play operator at the stop, where the motion may reverse
                x_t = _clip_play(x_t, x_m, half)
                if w == 0.0:
                    continue
                x_m += r_g * rest
            x_t = _clip_play(x_t, x_m, half)

        state[k, i, S_XM] = x_m
        state[k, i, S_W] = w
        state[k, i, S_XT] = x_t


@numba.njit(cache=True)
def table_velocity(x_m, w, x_t, r_g, backlash):
    """Table velocity of one axis [mm/s].

    ``r_g * w`` while the motor pushes the table (the backlash gap is closed
    on the side the motor moves towards), else 0 (the motor travels inside
    the gap and the table stands still).

    Parameters
    ----------
    x_m, w, x_t : float
        Motor position [mm], motor velocity [rad/s], table position [mm].
    r_g : float
        Transmission gain [mm/rad].
    backlash : float
        Backlash width D_b [mm].
    """
    half = 0.5 * backlash
    if w > 0.0:
        if x_t <= x_m - half:
            return r_g * w
    elif w < 0.0:
        if x_t >= x_m + half:
            return r_g * w
    return 0.0


@numba.njit(cache=True)
def table_velocities(state, params, out):
    """Table velocities [mm/s] of N biaxial drives into ``out`` (N, 2).

    See ``table_velocity``.
    """
    for k in range(state.shape[0]):
        for i in range(2):
            out[k, i] = table_velocity(
                state[k, i, S_XM],
                state[k, i, S_W],
                state[k, i, S_XT],
                params[k, i, IDX_R_G],
                params[k, i, IDX_BACKLASH],
            )


# --------------------------------------------------------------------------
# The contract's kernels for FeedDriveArrays
# --------------------------------------------------------------------------


@overload(contract.advance, jit_options={"cache": True})
def _advance(plant, k, command):
    if contract.is_plant(plant, FeedDriveArrays):

        def impl(plant, k, command):
            step_machine(plant.state, k, command, plant.params, plant.dt, plant.n_substeps)

        return impl


@overload(contract.sense, jit_options={"cache": True})
def _sense(plant, k, out):
    if contract.is_plant(plant, FeedDriveArrays):

        def impl(plant, k, out):
            for i in range(2):
                x_t = plant.state[k, i, S_XT]
                out[contract.SENSE_POSITION + i] = x_t
                out[contract.SENSE_MEASURED + i] = x_t
                out[contract.SENSE_VELOCITY + i] = table_velocity(
                    plant.state[k, i, S_XM],
                    plant.state[k, i, S_W],
                    x_t,
                    plant.params[k, i, IDX_R_G],
                    plant.params[k, i, IDX_BACKLASH],
                )

        return impl
