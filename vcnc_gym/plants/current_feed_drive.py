"""Biaxial current-driven feed drive of Simba et al., eq. (1) and Table I.

Each axis i (x, y) of a machine is the rigid table of Simba et al., eq. (1),

.. math::

    m \\ddot x + c \\dot x + f_c \\,\\mathrm{sgn}(\\dot x) = k_f \\,\\mathrm{sat}(i_a),

with ``x`` the table position [mm], ``i_a`` the amplifier current [A] (the
paper's text calls it "the input voltage", but its unit in Table I, N/A for
``k_f``, and eq. (5) make it a current), ``m`` the equivalent mass
[N s^2/mm], ``c`` the viscous friction [N s/mm], ``f_c`` the Coulomb friction
[N] and ``k_f`` the force-current ratio [N/A], all from Table I:

======  ==========  =======  =======  =====================================
name    unit        x        y        interval (our choice, see below)
======  ==========  =======  =======  =====================================
m       N s^2/mm    0.088    0.097    nominal +- 10 %
c       N s/mm      0.559    0.796    nominal +- 30 %
f_c     N           48       58       nominal +- 20 %
k_f     N/A         235.62   331.12   nominal +- 10 %
i_max   A           5        5        fixed (our choice, see below)
======  ==========  =======  =======  =====================================

What the paper does not give, and what we chose
-----------------------------------------------
* **Current limit** ``i_max`` = 5 A per axis.  The paper states no limit but
  says (section IV-B) that in its simulations the high curvature of the
  linear path's corners saturates the control inputs.  The contouring
  controller of eq. (7) asks about K_D ``|dv_d|`` m / k_f ~ 8.4 A on x at the
  30-degree corner at 50 mm/s (a 150-degree turn: ``|dv_d|`` ~ 97 mm/s) and
  ~4.7 A at the 90-degree one, so the paper's limit lies below ~8 A.  5 A gives
  (k_f i_max - f_c) / m ~ 1.3e4 mm/s^2 on x and 1.6e4 mm/s^2 on y, the
  1-1.5 g class of a machine-tool feed drive.  Chosen once from those two
  arguments, not fitted to the paper's contour errors.
* **Uncertainty intervals** (the paper gives none): the widths of Jahanpour et al.'s (2014)
  analogous quantities (section 2c: viscous friction B +-30 %, torque
  constant K_t and amplifier gain K_a about +-11 %) for ``c`` and ``k_f``;
  +-10 % on ``m`` for the workpiece and fixtures on the table; +-20 % on
  ``f_c`` (Coulomb friction drifts with temperature and lubrication).
  Nominal values are Table I's, the midpoints of the intervals.
* **Stiction**: eq. (1) has one friction level, so the break-away force
  equals the Coulomb force: a table at rest (``v == 0.0`` exactly) stays
  stuck while ``|k_f i| <= f_c``.
* **Sensor**: perfect (the paper names none): the measured position is the
  true one.

Integration
-----------
The current is held constant over the control period ``dt`` (zero-order
hold) and clipped to ``[-i_max, i_max]``.  With a constant current the
friction force is constant between velocity reversals, so every piece of
motion solves ``m v' = F - c v`` in closed form (:mod:`vcnc_gym.plants.exact_zoh`),
and the stops and break-aways are those of every plant's stick-slip routine
(:func:`vcnc_gym.plants.stick_slip.stick_slip`, with the static levels equal to
the Coulomb ones).  A velocity zero crossing inside the period is located exactly; the table stops there, stays
stuck if ``|k_f i| <= f_c`` and otherwise breaks away in the direction of the
force for the rest of the period.  After a break-away the net force
``k_f i - f_c sgn(v)`` has the sign of ``v``, so the velocity cannot cross
zero again within the period: one period holds at most one stop and one
break-away, and no substeps are needed.  With ``f_c = 0`` the kernel is the
exact ZOH discretisation of the linear model ``k_f / (m s^2 + c s)``.

Layouts
-------
state : (N, 2, 2) float64
    ``state[k, i] = (x [mm], v [mm/s])`` for machine ``k``, axis ``i``.
params : (N, 2, P) float64
    ``params[k, i, j]`` is parameter ``PARAMETER_NAMES[j]`` of axis ``i``.

Examples
--------
>>> import numpy as np
>>> from vcnc_gym.plants import current_feed_drive as cfd
>>> arrays = cfd.MODEL.arrays(1, 1e-4)
>>> cfd.step_feed_drives(arrays.state, np.array([[1.0, -1.0]]), arrays.params, arrays.dt)
>>> bool(arrays.state[0, 0, cfd.S_V] > 0.0 and arrays.state[0, 1, cfd.S_V] < 0.0)
True
"""

from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np
from numba.extending import overload

from . import contract
from .contract import Parameter, PlantModel

from .exact_zoh import first_order
from .stick_slip import STOPPED, STUCK, StickSlipAxis, stick_slip

__all__ = [
    "PARAMETERS",
    "PARAMETER_NAMES",
    "N_PARAMETERS",
    "IDX_M",
    "IDX_C",
    "IDX_F_C",
    "IDX_K_F",
    "IDX_I_MAX",
    "SIMBA_A_MAX",
    "SIMBA_J_MAX",
    "SIMBA_FEEDRATE",
    "STATE_NAMES",
    "S_X",
    "S_V",
    "CurrentFeedDriveArrays",
    "MODEL",
    "without_friction",
    "linear_transfer_function_coefficients",
    "advance_axis",
    "step_machine",
    "step_feed_drives",
]

_TABLE_I = "Simba et al., Table I"
_CHOICE = "our choice (Simba et al. give none; module docstring)"


def _interval(nominal, rel):
    return tuple((v * (1.0 - rel), v * (1.0 + rel)) for v in nominal)


#: The per-axis parameters, in the order of the last axis of a parameter
#: array: Table I's values as nominal, intervals and the current limit our
#: choice (see the module docstring).
PARAMETERS = (
    Parameter(
        "m",
        "N s^2/mm",
        nominal=(0.088, 0.097),
        interval=_interval((0.088, 0.097), 0.10),
        source=_TABLE_I + "; interval +-10 % " + _CHOICE,
        description="equivalent mass of the table",
        physical_range=(0.001, 100),
        range_source="ours: table masses from 1 kg to 100 t",
    ),
    Parameter(
        "c",
        "N s/mm",
        nominal=(0.559, 0.796),
        interval=_interval((0.559, 0.796), 0.30),
        source=_TABLE_I + "; interval +-30 % " + _CHOICE,
        sign="nonnegative",
        description="viscous friction coefficient",
        physical_range=(0, 100),
        range_source="ours: 100 times the box's upper end",
    ),
    Parameter(
        "f_c",
        "N",
        nominal=(48.0, 58.0),
        interval=_interval((48.0, 58.0), 0.20),
        source=_TABLE_I + "; interval +-20 % " + _CHOICE,
        sign="nonnegative",
        description="Coulomb friction force (also the break-away force)",
        physical_range=(0, 100000),
        range_source="ours: up to a 100 t table on a friction coefficient of 0.1",
    ),
    Parameter(
        "k_f",
        "N/A",
        nominal=(235.62, 331.12),
        interval=_interval((235.62, 331.12), 0.10),
        source=_TABLE_I + "; interval +-10 % " + _CHOICE,
        description="force-current conversion ratio",
        physical_range=(1, 10000),
        range_source="ours: linear motors' and ball-screw drives' force constants span 10-5000 N/A",
    ),
    Parameter(
        "i_max",
        "A",
        nominal=(5.0, 5.0),
        source=_CHOICE,
        description="amplifier current limit",
        physical_range=(0.01, 1000),
        range_source="ours: servo amplifiers' current limits span 0.1-500 A",
    ),
)

PARAMETER_NAMES = tuple(p.name for p in PARAMETERS)
N_PARAMETERS = len(PARAMETERS)
IDX_M, IDX_C, IDX_F_C, IDX_K_F, IDX_I_MAX = range(N_PARAMETERS)

#: The path limits Simba et al.'s drives are planned with (the paper gives none; derived in
#: :mod:`vcnc_gym.motion.jlap`'s docstring from this plant's 5 A limit and eq. (7)'s loop): path acceleration
#: mm/s^2, path jerk mm/s^3, and the programmed feed of their experiments, mm/s (section IV-A).
SIMBA_A_MAX = 4000.0
SIMBA_J_MAX = 1.6e5
SIMBA_FEEDRATE = 50.0

#: Per-axis state entries: table position x [mm], table velocity v [mm/s].
STATE_NAMES = ("x [mm]", "v [mm/s]")
S_X, S_V = 0, 1

#: The arrays of N machines (the contract's plant namedtuple): ``state``
#: (N, 2, 2), ``params`` (N, 2, P) and the control period ``dt`` [s].
CurrentFeedDriveArrays = namedtuple("CurrentFeedDriveArrays", ["state", "params", "dt"])


# --------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def advance_axis(x, v, force, m, c, f_c, h):
    """One axis over ``h`` s under a constant motor force, exactly; returns ``(x, v)``.

    Solves eq. (1), ``m v' = force - c v - f_c sgn(v)``, in closed form with
    the velocity zero crossing located exactly (module docstring).

    Parameters
    ----------
    x, v : float
        Position [mm] and velocity [mm/s] at the start.  ``v == 0.0`` means
        at rest (stuck unless ``|force| > f_c``).
    force : float
        Motor force ``k_f i`` [N], already saturated.
    m, c, f_c : float
        Mass [N s^2/mm], viscous friction [N s/mm], Coulomb friction [N].
    h : float
        Duration [s].
    """
    inv_m = 1.0 / m
    axis = StickSlipAxis(m, c, inv_m, f_c, -f_c, f_c, -f_c)  # one level: break-away = Coulomb
    mode, v, travel, rest = stick_slip(axis, v, force, h, first_order(c * inv_m, h))
    if mode == STUCK:
        return x, 0.0
    x += travel
    if v != 0.0 and mode == STOPPED:  # broken away again after the stop
        x += rest
    return x, v


@numba.njit(cache=True)
def step_machine(state, k, current, params, dt):
    """Advance both axes of machine ``k`` by ``dt`` s; ``current`` (2,) A, clipped to +-i_max."""
    for i in range(2):
        i_max = params[k, i, IDX_I_MAX]
        u = min(i_max, max(-i_max, current[i]))
        state[k, i, S_X], state[k, i, S_V] = advance_axis(
            state[k, i, S_X],
            state[k, i, S_V],
            params[k, i, IDX_K_F] * u,
            params[k, i, IDX_M],
            params[k, i, IDX_C],
            params[k, i, IDX_F_C],
            dt,
        )


@numba.njit(cache=True)
def step_feed_drives(state, current, params, dt):
    """Advance N biaxial drives by one control period ``dt`` [s], in place.

    Parameters
    ----------
    state : (N, 2, 2) float64
        (x [mm], v [mm/s]) per machine and axis.
    current : (N, 2) float64
        Commanded current [A], held over ``dt`` and clipped to ``+-i_max``.
    params : (N, 2, P) float64
        See ``PARAMETER_NAMES``.  No validation here (``MODEL.validate``).
    dt : float
        Control period [s].
    """
    for k in range(state.shape[0]):
        step_machine(state, k, current[k], params, dt)


@overload(contract.advance, jit_options={"cache": True})
def _advance(plant, k, command):
    if contract.is_plant(plant, CurrentFeedDriveArrays):

        def impl(plant, k, command):
            step_machine(plant.state, k, command, plant.params, plant.dt)

        return impl


@overload(contract.sense, jit_options={"cache": True})
def _sense(plant, k, out):
    if contract.is_plant(plant, CurrentFeedDriveArrays):

        def impl(plant, k, out):
            for i in range(2):
                out[contract.SENSE_POSITION + i] = plant.state[k, i, S_X]
                out[contract.SENSE_MEASURED + i] = plant.state[k, i, S_X]  # perfect sensor
                out[contract.SENSE_VELOCITY + i] = plant.state[k, i, S_V]

        return impl


# --------------------------------------------------------------------------
# The model
# --------------------------------------------------------------------------


def linear_transfer_function_coefficients(params: np.ndarray, axis: int):
    """Current-to-position transfer function of eq. (1) without Coulomb friction and saturation.

    ``P(s) = k_f / (m s^2 + c s)`` [mm/A].

    Parameters
    ----------
    params : (2, P) array
        One machine.
    axis : int
        0 (x) or 1 (y).

    Returns
    -------
    num, den : ndarray
        Descending powers of s: ``[k_f]`` and ``[m, c, 0]``.
    """
    a = np.asarray(params, dtype=np.float64)[axis]
    return np.array([a[IDX_K_F]]), np.array([a[IDX_M], a[IDX_C], 0.0])


def without_friction(params, keep_saturation: bool = False) -> np.ndarray:
    """Copy of a (..., P) parameter array with ``f_c = 0`` (and ``i_max = inf`` unless ``keep_saturation``).

    What remains is the linear model :func:`linear_transfer_function_coefficients`.
    """
    p = np.array(params, dtype=np.float64, copy=True)
    p[..., IDX_F_C] = 0.0
    if not keep_saturation:
        p[..., IDX_I_MAX] = np.inf
    return p


def _make_arrays(n_machines: int, dt: float) -> CurrentFeedDriveArrays:
    """N machines at rest at the origin with nominal parameters."""
    params = np.repeat(MODEL.nominal()[None], n_machines, axis=0)
    return CurrentFeedDriveArrays(np.zeros((n_machines, 2, 2)), params, float(dt))


def _reset_machine(arrays: CurrentFeedDriveArrays, k: int, position) -> None:
    """Machine ``k`` at rest at ``position`` (2,) mm."""
    arrays.state[k, :, S_X] = position
    arrays.state[k, :, S_V] = 0.0


#: This plant, as the envs and baselines see it.
def _inverse_dynamics(params: np.ndarray) -> contract.InverseDynamics:
    """Eq. (1) of Simba et al. inverted: ``i = (m a + c v + f_c sgn(v)) / k_f`` A (Table I)."""
    level = params[:, IDX_F_C] / params[:, IDX_K_F]
    return contract.InverseDynamics.from_linear(MODEL, params, np.column_stack([level, -level]))


def _force_gain(params: np.ndarray) -> np.ndarray:
    """Amperes per newton of force on the table, per axis: ``1 / k_f`` (Simba et al., eq. (1): the force is
    ``k_f i_a``)."""
    return 1.0 / params[:, MODEL.index("k_f")]


MODEL = PlantModel(
    name="current_feed_drive",
    source="Simba et al., eq. (1) and Table I",
    parameters=PARAMETERS,
    state_names=STATE_NAMES,
    input_name="amplifier current",
    input_unit="A",
    input_limit="i_max",
    make_arrays=_make_arrays,
    reset_machine=_reset_machine,
    linear_coefficients=linear_transfer_function_coefficients,
    inverse_dynamics=_inverse_dynamics,
    force_gain=_force_gain,
    # the position-loop bandwidth ceiling: the best max contour error of ff-pid, zpetc and ff-ccc on the nominal
    # plant of its ids over a grid (python experiments/classical-opponents/tune_servo.py)
    servo_bandwidth=2000.0,
    friction_time=0.0,  # a Coulomb switch at the reversal halves the smoothed corners' max (zpetc 4.3 against 12.9 nm at 1 ms)
    path_limits=(4000.0, 1.6e5),  # Simba et al.'s JLAP limits (motion.jlap's SIMBA_*)
)
