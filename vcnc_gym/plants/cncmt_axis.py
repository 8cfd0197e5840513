"""The CNC machine-tool (CNCMT) axis of Yadav et al. (2020), with its dead time, as numba kernels.

Yadav, Pathak and Gaur (2020) model one feed axis, eq. (2),

.. math::

    G(s) = \\frac{X_0(s)}{U(s)} = \\frac{b}{s (s + a)} e^{-T_d s},
    \\qquad b = 4.85, \\quad a = 9.7, \\quad T_d = 0.1\\ \\mathrm{s},

read in the time domain as

.. math::

    \\dot v = -a v + b \\,\\mathrm{sat}(u(t - T_d)), \\qquad \\dot x = v .

Both axes of a machine carry this model (the suite's plants are biaxial; Yadav et
al. model one axis and no second one to copy, so the y axis is a second copy of
the same drive, with its own draw of the uncertain parameters).

Units
-----
The input ``u`` is the command voltage of the power amplifier [V]: the
amplifier gain ``K_1`` is in V/V (Table 1) and Appendix A, eq. (36), writes
``E(s) = K_1 (U(s) - B(s))``.  The output is the table position.  Yadav et al.'s
nomenclature gives the lead-screw pitch ``p`` in m, so ``x_0 = p theta_0``
(eq. (44)) and eq. (2) are in m: ``b = 4.85 m/(V s^2)``.  The suite works in
mm, so ``b`` is stored as 4850 mm/(V s^2) and Yadav et al.'s controllers (V/m)
are divided by 1000 to act on mm (``vcnc_baselines.feedback.pi_imc_hinf``).

Saturation
----------
Yadav et al. (2020) gives no input limit.  ``u_max`` = 10 V, the usual +-10 V analog
command range of servo amplifiers (our choice).  At a 10 mm step none of
Yadav et al.'s controllers comes near it (robust PI, the largest, asks 38.33 V/m x
0.01 m = 0.38 V); it bounds what an agent can ask (top speed
``b u_max / a`` = 5 m/s at the nominal plant).

Uncertainty: eq. (2), section 3.5 and Table 1 disagree
---------------------------------------------------------
We follow eq. (2) and the interval coefficients of the Kharitonov analysis of
section 3.5, where the closed-loop coefficients are written with the two
plant coefficients ``a = K_1 K_2 n H_2 / (p^2 m + n^2 I_m)`` and
``b = K_1 K_2 n p / (p^2 m + n^2 I_m)`` (eq. (30)) and bounded by

- ``a >= 7.5`` (alpha_1 of eqs. (17), (31), (33), (35)),
- ``3 <= b <= 6`` m/(V s^2) (alpha_2 = 3 K_P and beta_3 = 6 K_I of eqs. (17), (31);
  beta_3 = 20.97 x 6 of eq. (35)).

Yadav et al. never state an upper bound of ``a`` (the stability margin of
eq. (5) uses only alpha_1); we take ``a <= 11.9``, the lower bound mirrored
about the nominal 9.7 (our choice).  The dead time ``T_d`` is fixed (Yadav et
al. neglect it in their robustness analysis and give it no interval).

Table 1 disagrees with both, in two ways:

1. *The nominal values.*  With Table 1's nominal values (K_1 = 2 V/V,
   K_2 = 4 N m/V, n = 2, H_2 = 0.1, m = 50 kg, I_m = 0.01 kg m^2) and the
   pitch p = 5 mm = 0.005 m as printed, eq. (1) gives a = 38.8 1/s and
   b = 1.94 m/(V s^2), not eq. (2)'s 9.7 and 4.85.  With p = 0.05 m (5 cm;
   the nomenclature's unit is m) it gives a = 9.697 and b = 4.848, eq. (2) to
   the printed digits: the table's "5 (mm)" is a unit slip.
2. *The intervals.*  Table 1's ranges (K_1 +-50 %, K_2 +-25 %, m +-40 %,
   I_m +-20 %) through eq. (1), with p = 0.05 m, span a in [2.69, 28.0]
   1/s and b in [1.35, 14.0] m/(V s^2), far wider than section 3.5's
   a >= 7.5, b in [3, 6].  Eq. (1) also ties b = (p / H_2) a = 0.5 a (p and
   H_2 are certain), while section 3.5 bounds a and b independently.

We keep eq. (2) as the nominal plant and section 3.5's box (a and b
independent), the numbers Yadav et al.'s stability margins are computed from.

Dead time
---------
Simulated exactly: ``T_d`` must be a whole number of control periods
(``n_d = T_d / dt``, accepted within a relative 1e-9 of an integer; anything
else, and a negative ``T_d``, is a ValueError), and the saturated command
enters a ring buffer of ``n_d`` entries per axis, part of the plant's arrays
(``line``, ``head``).  The plant applies, over a control period, the command
it was given ``n_d`` periods earlier, so with a zero-order hold the delay
is exact (no Pade approximation).  The buffer's capacity is fixed when the
arrays are made (plant option ``max_dead_time``, default the nominal 0.1 s);
a longer ``T_d`` at a reset is a ValueError naming that option.

Integration
-----------
Exact zero-order hold: the delayed command is held over ``dt`` and the linear
ODE solved in closed form, ``v1 = E v0 + b g u``, ``x1 = x0 + g v0 + b q u``,
``E = exp(-a dt)``, ``g = (1 - E) / a``, ``q = (dt - g) / a`` (series for
small ``a dt``): ``control.c2d(G, dt, "zoh")`` followed by ``z^-n_d``, up to
rounding (tests/test_yadav2020_plant.py).

Layouts
-------
state : (N, 2, 2) float64
    ``state[k, i] = (x [mm], v [mm/s])``.
params : (N, 2, 4) float64
    ``(a [1/s], b [mm/(V s^2)], T_d [s], u_max [V])`` per axis.
line : (N, 2, L) float64
    The delay line: saturated commands [V] not applied yet; L the capacity.
head : (N, 2) int64
    Slot of ``line`` holding the oldest command (the next one applied).
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
    "CncmtArrays",
    "IDX_A",
    "IDX_B",
    "IDX_T_D",
    "IDX_U_MAX",
    "S_X",
    "S_V",
    "METRE",
    "PAPER_NOMINAL",
    "TABLE_1",
    "delay_periods",
    "table1_coefficients",
    "zoh_acceleration_input",
    "advance_machine",
]

#: mm per m: Yadav et al. (2020)'s positions and controller gains are in m (see the module docstring).
METRE = 1000.0

_EQ_2 = "Yadav et al. (2020), eq. (2)"
_SEC_35 = "Yadav et al. (2020), section 3.5, eqs. (17), (31), (35)"

#: Eq. (2) in Yadav et al.'s own units: a [1/s], b [m/(V s^2)], T_d [s].
PAPER_NOMINAL = {"a": 9.7, "b": 4.85, "T_d": 0.1}

#: Yadav et al. (2020), Table 1: nominal value and relative uncertainty of the physical
#: parameters, SI units, with the pitch p = 0.05 m (printed "5 (mm)"; see the
#: module docstring).  Used only to document the disagreement with eq. (2).
TABLE_1 = {
    "K_1": (2.0, 0.50),  # power amplifier gain, V/V, +-50 %
    "K_2": (4.0, 0.25),  # servomotor gain, N m/V, +-25 %
    "m": (50.0, 0.40),  # mass of the workpiece, kg, +-40 %
    "I_m": (0.01, 0.20),  # equivalent inertia, kg m^2, +-20 %
    "p": (0.05, 0.0),  # pitch of the lead screw, m
    "n": (2.0, 0.0),  # gear ratio
    "H_2": (0.1, 0.0),  # tachogenerator gain
}

#: The per-axis parameters, in the order of the last axis of a parameter array.
PARAMETERS = (
    Parameter(
        "a",
        "1/s",
        nominal=(9.7, 9.7),
        interval=((7.5, 11.9), (7.5, 11.9)),
        source=f"{_EQ_2}; lower bound alpha_1 of {_SEC_35}; upper bound ours (7.5 mirrored about 9.7)",
        description="velocity-loop pole K_1 K_2 n H_2 / (p^2 m + n^2 I_m), eq. (30)",
        physical_range=(0.001, 10000),
        range_source="ours: velocity-loop poles from 0.1 ms to 1000 s",
    ),
    Parameter(
        "b",
        "mm/(V s^2)",
        nominal=(4850.0, 4850.0),
        interval=((3000.0, 6000.0), (3000.0, 6000.0)),
        source=f"{_EQ_2} (4.85 m/(V s^2)); interval 3-6 m/(V s^2) of {_SEC_35}",
        description="gain K_1 K_2 n p / (p^2 m + n^2 I_m), eq. (30)",
        physical_range=(1, 1e07),
        range_source="ours: 1 mm/(V s^2) to 10 km/(V s^2), 2000 times Yadav et al.'s 4.85 m/(V s^2) either way",
    ),
    Parameter(
        "T_d",
        "s",
        nominal=(0.1, 0.1),
        source=f"{_EQ_2} (T_d = 0.1 s 'for simulation')",
        sign="nonnegative",
        description="input dead time, a whole number of control periods",
        physical_range=(0, 10),
        range_source="ours: a dead time beyond 10 s is no servo axis",
    ),
    Parameter(
        "u_max",
        "V",
        nominal=(10.0, 10.0),
        source="ours (+-10 V servo command; Yadav et al. (2020) gives no limit)",
        description="amplifier command saturation",
        physical_range=(0.1, 100),
        range_source="ours: amplifier commands are +-10 V in industry, +-100 V at most",
    ),
)
IDX_A, IDX_B, IDX_T_D, IDX_U_MAX = range(len(PARAMETERS))

#: Per-axis state entries: position x [mm], velocity v [mm/s].
S_X, S_V = 0, 1

#: The arrays of N machines (the contract's plant namedtuple): ``state``
#: (N, 2, 2), ``params`` (N, 2, 4), the control period ``dt`` [s], the delay
#: line ``line`` (N, 2, L) [V] and its read slot ``head`` (N, 2).
CncmtArrays = namedtuple("CncmtArrays", ["state", "params", "dt", "line", "head"])

#: Relative distance of T_d / dt from an integer accepted as whole.
_WHOLE = 1e-9


def delay_periods(dead_time, dt: float, name: str = "T_d") -> int:
    """The dead time as a whole number of control periods.

    Parameters
    ----------
    dead_time : float
        Dead time [s], >= 0.
    dt : float
        Control period [s], > 0.
    name : str
        How to call the dead time in an error message.

    Returns
    -------
    int
        ``T_d / dt``, accepted within a relative 1e-9 of an integer.

    Raises
    ------
    ValueError
        For a negative or non-finite dead time, or one that is not a whole
        number of control periods (the delay line holds whole periods; no
        rounding).
    """
    if isinstance(dead_time, bool) or not isinstance(dead_time, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number of seconds, got {dead_time!r}")
    d = float(dead_time)
    if not math.isfinite(d) or d < 0.0:
        raise ValueError(f"{name} must be a finite dead time >= 0 s, got {dead_time!r}")
    ratio = d / dt
    n = round(ratio)
    if abs(ratio - n) > _WHOLE * max(1.0, ratio):
        raise ValueError(
            f"{name} = {d:g} s is not a whole number of control periods dt = {dt:g} s "
            f"({ratio:.6g} periods): the dead time is simulated exactly as a delay line of whole "
            f"periods; choose dt dividing {d:g} s (e.g. {d / max(1, math.ceil(ratio)):g} s)"
        )
    return int(n)


def table1_coefficients(**values) -> tuple[float, float]:
    """Eq. (1)'s plant coefficients from Table 1's physical parameters, in Yadav et al.'s units.

    Parameters
    ----------
    **values : float
        Any of ``K_1`` (V/V), ``K_2`` (N m/V), ``m`` (kg), ``I_m`` (kg m^2),
        ``p`` (m), ``n``, ``H_2``; the others take :data:`TABLE_1`'s nominal.

    Returns
    -------
    a, b : float
        ``a = K_1 K_2 n H_2 / (p^2 m + n^2 I_m)`` [1/s] and
        ``b = K_1 K_2 n p / (p^2 m + n^2 I_m)`` [m/(V s^2)], eq. (1).
    """
    unknown = sorted(set(values) - set(TABLE_1))
    if unknown:
        raise ValueError(f"unknown Table 1 parameter(s) {unknown}; known: {sorted(TABLE_1)}")
    v = {k: float(values.get(k, nominal)) for k, (nominal, _) in TABLE_1.items()}
    inertia = v["p"] ** 2 * v["m"] + v["n"] ** 2 * v["I_m"]
    drive = v["K_1"] * v["K_2"] * v["n"]
    return drive * v["H_2"] / inertia, drive * v["p"] / inertia


def _linear_coefficients(params: np.ndarray, axis: int):
    """Eq. (2) without its dead time: ``b / (s^2 + a s)`` [mm/V]."""
    p = params[axis]
    return np.array([p[IDX_B]]), np.array([1.0, p[IDX_A], 0.0])


def _delay(params: np.ndarray, axis: int) -> float:
    """The dead time T_d [s] of eq. (2)."""
    return float(params[axis, IDX_T_D])


def _make_arrays(n_machines: int, dt: float, max_dead_time: float | None = None) -> CncmtArrays:
    """Arrays of N machines at rest at the origin, nominal parameters.

    ``max_dead_time`` [s] sizes the delay line (default the nominal T_d,
    0.1 s); it must be a whole number of control periods, like T_d.
    """
    nominal = MODEL.nominal()
    if max_dead_time is None:
        capacity = delay_periods(float(np.max(nominal[:, IDX_T_D])), dt, "the nominal dead time T_d")
    else:
        capacity = delay_periods(max_dead_time, dt, "max_dead_time")
    return CncmtArrays(
        state=np.zeros((n_machines, 2, 2)),
        params=np.repeat(nominal[None], n_machines, axis=0),
        dt=float(dt),
        line=np.zeros((n_machines, 2, max(1, capacity))),
        head=np.zeros((n_machines, 2), dtype=np.int64),
    )


def _reset_machine(arrays: CncmtArrays, k: int, position) -> None:
    """Machine ``k`` at rest at ``position`` (2,) mm, its delay lines empty (zero command pending).

    Raises
    ------
    ValueError
        If machine ``k``'s ``T_d`` is not a whole number of control periods
        or longer than the delay line.
    """
    capacity = arrays.line.shape[2]
    for i in range(2):
        t_d = float(arrays.params[k, i, IDX_T_D])
        n = delay_periods(t_d, arrays.dt, f"T_d of axis {contract.AXES[i]}")
        if n > capacity:
            raise ValueError(
                f"T_d = {t_d:g} s needs {n} control periods of delay line, this plant's arrays hold "
                f"{capacity}: make them with plant_options={{'max_dead_time': {t_d:g}}}"
            )
        arrays.state[k, i, S_X] = float(position[i])
        arrays.state[k, i, S_V] = 0.0
    arrays.line[k] = 0.0
    arrays.head[k] = 0


#: This plant, as the envs and baselines see it.
def _inverse_dynamics(params: np.ndarray) -> contract.InverseDynamics:
    """Eq. (2) of Yadav, Pathak and Gaur (2020) inverted: ``u(t) = (a_x(t + T_d) + a v(t + T_d)) / b`` V."""
    return contract.InverseDynamics.from_linear(MODEL, params)


MODEL = PlantModel(
    name="cncmt_axis",
    source="Yadav et al. (2020), eq. (2) and section 3.5",
    parameters=PARAMETERS,
    state_names=("x [mm]", "v [mm/s]"),
    input_name="power amplifier command voltage",
    input_unit="V",
    input_limit="u_max",
    make_arrays=_make_arrays,
    reset_machine=_reset_machine,
    linear_coefficients=_linear_coefficients,
    delay=_delay,
    inverse_dynamics=_inverse_dynamics,
    # the position-loop bandwidth ceiling: the best max contour error of ff-pid, zpetc and ff-ccc on the nominal
    # plant of its ids over a grid (python experiments/classical-opponents/tune_servo.py)
    servo_bandwidth=1.0,
)


# --------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------


@numba.njit(cache=True)
def zoh_acceleration_input(a, dt):
    """Exact ZOH coefficients of ``v' = -a v + w``, ``x' = v`` over ``dt``, the input ``w`` an acceleration
    (mm/s^2, held; compare :func:`vcnc_gym.plants.nct_xy_table.zoh_velocity_lag`, whose input is a velocity):
    ``(E, g, q)`` with ``v1 = E v0 + g w`` and ``x1 = x0 + g v0 + q w`` (:func:`~vcnc_gym.plants.exact_zoh.first_order`)."""
    return first_order(a, dt)


@numba.njit(cache=True)
def advance_machine(state, params, line, head, dt, k, command):
    """Advance both axes of machine ``k`` by one control period ``dt`` [s]; ``command`` (2,) [V].

    The command is saturated at ``+-u_max``, pushed into the delay line and
    the command of ``T_d / dt`` periods ago is applied, held over ``dt``.
    No validation (the delay length is clamped to the line's capacity only to
    stay in bounds; :func:`delay_periods` is the check).
    """
    capacity = line.shape[2]
    for i in range(2):
        a = params[k, i, IDX_A]
        b = params[k, i, IDX_B]
        u_max = params[k, i, IDX_U_MAX]
        u = command[i]
        if u > u_max:
            u = u_max
        elif u < -u_max:
            u = -u_max
        n = min(int(params[k, i, IDX_T_D] / dt + 0.5), capacity)
        if n > 0:
            h = head[k, i]
            if h >= n:
                h = 0
            applied = line[k, i, h]
            line[k, i, h] = u
            h += 1
            head[k, i] = 0 if h == n else h
        else:
            applied = u
        e, g, q = zoh_acceleration_input(a, dt)
        w = b * applied
        x = state[k, i, S_X]
        v = state[k, i, S_V]
        state[k, i, S_X] = x + g * v + q * w
        state[k, i, S_V] = e * v + g * w


@overload(contract.advance, jit_options={"cache": True})
def _advance(plant, k, command):
    if contract.is_plant(plant, CncmtArrays):

        def impl(plant, k, command):
            advance_machine(plant.state, plant.params, plant.line, plant.head, plant.dt, k, command)

        return impl


@overload(contract.sense, jit_options={"cache": True})
def _sense(plant, k, out):
    if contract.is_plant(plant, CncmtArrays):

        def impl(plant, k, out):
            for i in range(2):
                x = plant.state[k, i, S_X]
                out[contract.SENSE_POSITION + i] = x
                out[contract.SENSE_MEASURED + i] = x
                out[contract.SENSE_VELOCITY + i] = plant.state[k, i, S_V]

        return impl
