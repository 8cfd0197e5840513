"""The NCT-identified X-Y table of Purtojo et al. (fuzzy NCTF control on a circle), as numba kernels.

Each axis (x, y) of a machine is the simplified model of Purtojo et al., eq. (3),

.. math::

    G(s) = \\frac{X(s)}{U(s)} = K \\frac{\\alpha}{s (s + \\alpha)},
    \\qquad K = h_{max} / u_r, \\quad \\alpha = -m,

with the numbers of eq. (4): ``K = 50.7``, ``alpha = 1.475 1/s`` on the x
axis and ``K = 53.1``, ``alpha = 3.156 1/s`` on the y axis.  In the time
domain, with ``v`` the table velocity,

.. math::

    \\dot v = \\alpha (K \\,\\mathrm{sat}(u) - v), \\qquad \\dot x = v .

The input
---------
Purtojo et al. names the input only as the motor input, with ``u_r`` the rated
motor input: the stepwise input of the identification experiment is ``u_r``
(section III), the fuzzy compensator's output spans ``+-u_r`` (section II-B)
and ``K = h_max / u_r`` (eq. (3)).  It gives ``u_r`` no number and no unit.
The input here is therefore the motor command **in units of the rated
input**: ``u = 1`` is ``u_r`` (unit ``"u_r"``), so ``K`` is in mm/s per
``u_r`` and ``h_max = K u_r`` is the top speed of the stepwise experiment
(50.7 mm/s on x, 53.1 mm/s on y).  The input saturates at ``+-u_r``
(parameter ``u_r``, 1), the range the paper's controller never leaves.

The sensor
----------
Purtojo et al., section III: "1 um sensor resolution is used".  The position
sensor is modelled as a mid-tread quantiser of step ``resolution``
(0.001 mm), ``q(x) = resolution * round(x / resolution)``: what the
controller sees (``SENSE_MEASURED``); the true position (``SENSE_POSITION``)
is what the contour error is scored on.  There is no tachometer: the
velocity the plant reports (``SENSE_VELOCITY``) is the encoder's count
difference over the last control period, ``(q(x_k) - q(x_{k-1})) / dt``
(0 just after a reset).  The true velocity is kept in the state.

Uncertainty
-----------
Purtojo et al. gives one identified model and no uncertainty.  We chose
+-10 % on ``K`` and ``alpha`` of each axis (the spread of a model read off
one open-loop experiment; our choice, not the paper's), so that
``randomize=True`` draws a table the NCTF design has not seen; nominal
values are eq. (4) exactly (the interval midpoints).  ``u_r`` and the
sensor resolution are fixed.

Integration
-----------
Exact zero-order hold: the command is held over the control period ``dt``
and the linear ODE is solved in closed form,
``v1 = E v0 + (1 - E) K u``, ``x1 = x0 + g v0 + (dt - g) K u`` with
``E = exp(-alpha dt)`` and ``g = (1 - E) / alpha``: the kernel is the ZOH
discretisation of eq. (3) (``control.c2d(G, dt, "zoh")``) up to rounding.

Layouts
-------
state : (N, 2, 3) float64
    ``state[k, i] = (x [mm], v [mm/s], q_prev [mm])``: true position, true
    velocity and the sensor reading at the start of the last control period.
params : (N, 2, 4) float64
    ``(K [mm/s per u_r], alpha [1/s], u_r [u_r], resolution [mm])`` per axis.
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

__all__ = [
    "PARAMETERS",
    "MODEL",
    "NctTableArrays",
    "IDX_K",
    "IDX_ALPHA",
    "IDX_U_R",
    "IDX_RESOLUTION",
    "S_X",
    "S_V",
    "S_Q_PREV",
    "UNCERTAINTY",
    "quantise",
    "zoh_velocity_lag",
    "step_axis",
]

_EQ_4 = "Purtojo et al., eq. (4)"

#: Relative half-width of the uncertainty intervals of K and alpha (our choice; Purtojo et al. gives none).
UNCERTAINTY = 0.10


def _interval(x_value: float, y_value: float) -> tuple:
    return tuple((v * (1.0 - UNCERTAINTY), v * (1.0 + UNCERTAINTY)) for v in (x_value, y_value))


#: The per-axis parameters, in the order of the last axis of a parameter array.
PARAMETERS = (
    Parameter(
        "K",
        "mm/s per u_r",
        nominal=(50.7, 53.1),
        interval=_interval(50.7, 53.1),
        source=f"{_EQ_4}; +-10 % interval chosen here (Purtojo et al. give none)",
        description="velocity gain K = h_max / u_r, eq. (3)",
        physical_range=(0.01, 10000),
        range_source="ours: 0.01 mm/s to 10 m/s at the rated input",
    ),
    Parameter(
        "alpha",
        "1/s",
        nominal=(1.475, 3.156),
        interval=_interval(1.475, 3.156),
        source=f"{_EQ_4}; +-10 % interval chosen here (Purtojo et al. give none)",
        description="velocity pole alpha = -m, eq. (3)",
        physical_range=(0.001, 10000),
        range_source="ours: velocity-loop poles from 1 ms to 1000 s",
    ),
    Parameter(
        "u_r",
        "u_r",
        nominal=(1.0, 1.0),
        source="Purtojo et al., sections II-B and III (no number given)",
        description="rated motor input: the input limit, the unit of the input",
        physical_range=(0.001, 1000),
        range_source="ours: a rated input in V or in per-unit",
    ),
    Parameter(
        "resolution",
        "mm",
        nominal=(0.001, 0.001),
        source="Purtojo et al., section III (1 um sensor)",
        description="position sensor resolution",
        physical_range=(1e-07, 1),
        range_source="ours: position sensors resolve 0.1 nm (interferometers) to 1 mm",
    ),
)
IDX_K, IDX_ALPHA, IDX_U_R, IDX_RESOLUTION = range(len(PARAMETERS))

#: Per-axis state entries: true position, true velocity, sensor reading at the start of the last period.
S_X, S_V, S_Q_PREV = 0, 1, 2

#: The arrays of N machines (the contract's plant namedtuple): ``state`` (N, 2, 3),
#: ``params`` (N, 2, 4) and the control period ``dt`` [s].
NctTableArrays = namedtuple("NctTableArrays", ["state", "params", "dt"])


def _linear_coefficients(params: np.ndarray, axis: int):
    """Input-to-position transfer function of eq. (3): ``K alpha / (s^2 + alpha s)`` [mm per u_r]."""
    p = params[axis]
    return np.array([p[IDX_K] * p[IDX_ALPHA]]), np.array([1.0, p[IDX_ALPHA], 0.0])


def _make_arrays(n_machines: int, dt: float) -> NctTableArrays:
    """Arrays of N tables at rest at the origin, nominal parameters."""
    params = np.repeat(MODEL.nominal()[None], n_machines, axis=0)
    return NctTableArrays(np.zeros((n_machines, 2, 3)), params, float(dt))


def _reset_machine(arrays: NctTableArrays, k: int, position) -> None:
    """Table ``k`` at rest at ``position`` (2,) mm; the sensor reads it (velocity reading 0)."""
    for i in range(2):
        x = float(position[i])
        arrays.state[k, i, S_X] = x
        arrays.state[k, i, S_V] = 0.0
        arrays.state[k, i, S_Q_PREV] = quantise(x, arrays.params[k, i, IDX_RESOLUTION])


#: This plant, as the envs and baselines see it.
def _inverse_dynamics(params: np.ndarray) -> contract.InverseDynamics:
    """Eq. (3) of Purtojo et al. inverted: ``u = (a / alpha + v) / K`` in units of u_r (no friction term)."""
    return contract.InverseDynamics.from_linear(MODEL, params)


#: Moving mass of one axis of the X-Y table, kg: Purtojo et al. identifies no mass (its model is velocity over
#: motor input), so this is ours, a small laboratory X-Y table's carriage; used only to convert a force on the
#: table into the motor input that produces it (:func:`_force_gain`).
MOVING_MASS = 10.0


def _force_gain(params: np.ndarray) -> np.ndarray:
    """Rated inputs per newton on the table, per axis: a force F [N] accelerates the carriage by 1000 F / M
    mm/s^2 (``MOVING_MASS``), which eq. (3)'s ``dv/dt = alpha (K u - v)`` produces from ``1000 / (M alpha K)``
    u_r per N."""
    return 1e3 / (MOVING_MASS * params[:, MODEL.index("alpha")] * params[:, MODEL.index("K")])


MODEL = PlantModel(
    name="nct_xy_table",
    source="Purtojo et al., eqs. (3)-(4) and section III",
    parameters=PARAMETERS,
    state_names=("x [mm]", "v [mm/s]", "q_prev [mm]"),
    input_name="motor input (fraction of the rated input u_r)",
    input_unit="u_r",
    input_limit="u_r",
    make_arrays=_make_arrays,
    reset_machine=_reset_machine,
    linear_coefficients=_linear_coefficients,
    inverse_dynamics=_inverse_dynamics,
    force_gain=_force_gain,
    # the position-loop bandwidth ceiling: the best max contour error of ff-pid, zpetc and ff-ccc on the nominal
    # plant of its ids over a grid (python experiments/classical-opponents/tune_servo.py)
    servo_bandwidth=30.0,
    # Purtojo et al. give no path limits (their 1 mm circle runs at 1 mm/s): 30 mm/s^2 is 40 % of the slower (x)
    # axis's acceleration at the rated input from rest, K alpha u_r = 50.7 x 1.475 = 75 mm/s^2 (Jahanpour et al.'s
    # 1000 mm/s^2 is 38 % of their drives' ~2.6e3), and the jerk keeps the same 30 1/s ratio to it as theirs
    path_limits=(30.0, 900.0),
    # the table runs its 1 mm circle at 1 mm/s and tops out at 50 mm/s with the rated input on a 0.7 s time
    # constant: its random contours are a tenth of the defaults' size (0.5-3 mm lines, 0.2-2 mm arcs) at 0.5-2 mm/s
    random_contour={
        "line_min": 0.5,
        "line_max": 3.0,
        "radius_min": 0.2,
        "radius_max": 2.0,
        "feed_min": 30.0,
        "feed_max": 120.0,
    },
)


# --------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------


@numba.njit(cache=True)
def quantise(x, resolution):
    """Sensor reading of position ``x`` [mm]: the nearest multiple of ``resolution`` [mm] (ties upwards)."""
    return resolution * math.floor(x / resolution + 0.5)


@numba.njit(cache=True)
def zoh_velocity_lag(alpha, dt):
    """Exact ZOH coefficients of ``v' = alpha (K u - v)``, ``x' = v`` over ``dt``: the velocity lags the
    velocity target ``K u`` (mm/s, held) with rate ``alpha`` (1/s).

    Returns ``(E, g, q)`` with ``v1 = E v0 + alpha g K u`` and ``x1 = x0 + g v0 + q K u``:
    :func:`~vcnc_gym.plants.exact_zoh.first_order`'s ``E`` and ``g``, and ``q = dt - g`` (``alpha`` times
    its ``q``; :func:`vcnc_gym.plants.cncmt_axis.zoh_acceleration_input` keeps that ``q``, its input being an
    acceleration).
    """
    e, g, q = first_order(alpha, dt)
    return e, g, alpha * q


@numba.njit(cache=True)
def step_axis(state, k, i, u, params, dt):
    """Advance axis ``i`` of table ``k`` by ``dt`` with command ``u`` [u_r] held (saturated at +-u_r)."""
    u_r = params[k, i, IDX_U_R]
    if u > u_r:
        u = u_r
    elif u < -u_r:
        u = -u_r
    ku = params[k, i, IDX_K] * u
    e, g, q = zoh_velocity_lag(params[k, i, IDX_ALPHA], dt)
    x = state[k, i, S_X]
    v = state[k, i, S_V]
    state[k, i, S_Q_PREV] = quantise(x, params[k, i, IDX_RESOLUTION])
    state[k, i, S_X] = x + g * v + q * ku
    state[k, i, S_V] = e * v + params[k, i, IDX_ALPHA] * g * ku  # 1 - E = alpha g, without cancellation


@overload(contract.advance, jit_options={"cache": True})
def _advance(plant, k, command):
    if contract.is_plant(plant, NctTableArrays):

        def impl(plant, k, command):
            for i in range(2):
                step_axis(plant.state, k, i, command[i], plant.params, plant.dt)

        return impl


@overload(contract.sense, jit_options={"cache": True})
def _sense(plant, k, out):
    if contract.is_plant(plant, NctTableArrays):

        def impl(plant, k, out):
            for i in range(2):
                x = plant.state[k, i, S_X]
                q = quantise(x, plant.params[k, i, IDX_RESOLUTION])
                out[contract.SENSE_POSITION + i] = x
                out[contract.SENSE_MEASURED + i] = q
                out[contract.SENSE_VELOCITY + i] = (q - plant.state[k, i, S_Q_PREV]) / plant.dt

        return impl
