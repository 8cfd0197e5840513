"""Tests of Simba et al.'s current-driven feed drive (vcnc_gym.plants.current_feed_drive).

Independent references: Table I of Simba et al. typed in again, python-control's
ZOH discretisation of the linear model, the closed-form solution of
m v' = F - c v for a coasting stop, and scipy's DOP853 integrator with event
location for the friction reversals.
"""

import math

import numpy as np
import pytest

from vcnc_gym.envs import ContouringEnv
from vcnc_gym.geometry.corners import polyline
from vcnc_gym.plants import current_feed_drive as cfd
from vcnc_gym.plants import get_plant

control = pytest.importorskip("control")
integrate = pytest.importorskip("scipy.integrate")

DT = 1e-4
MODEL = cfd.MODEL


def simulate(params, currents, dt=DT, x0=None):
    """Positions and velocities (K + 1, N, 2, 2) under currents (K, N, 2) or (K, 2) A."""
    params = MODEL.validate(params, allow_infinite_limit=True)
    n = params.shape[0]
    i = np.asarray(currents, dtype=np.float64)
    if i.ndim == 2:
        i = np.broadcast_to(i[:, None, :], (i.shape[0], n, 2))
    i = np.ascontiguousarray(i)
    state = np.zeros((n, 2, 2))
    if x0 is not None:
        state[...] = x0
    out = np.empty((i.shape[0] + 1, n, 2, 2))
    out[0] = state
    for k in range(i.shape[0]):
        cfd.step_feed_drives(state, i[k], params, dt)
        out[k + 1] = state
    return out


# ---------------------------------------------------------------- numbers


def test_numbers_are_table_1():
    d = MODEL.to_dict(MODEL.nominal())
    assert d["m"] == (0.088, 0.097)
    assert d["c"] == (0.559, 0.796)
    assert d["f_c"] == (48.0, 58.0)
    assert d["k_f"] == (235.62, 331.12)
    assert d["i_max"] == (5.0, 5.0)
    assert MODEL.input_unit == "A" and MODEL.input_limit == "i_max"
    assert cfd.PARAMETER_NAMES == ("m", "c", "f_c", "k_f", "i_max")
    lo, hi, names = MODEL.box()
    assert names == ("m_x", "m_y", "c_x", "c_y", "f_c_x", "f_c_y", "k_f_x", "k_f_y")
    # the nominal values are the midpoints of the chosen intervals
    np.testing.assert_allclose(0.5 * (lo + hi), [0.088, 0.097, 0.559, 0.796, 48, 58, 235.62, 331.12], rtol=1e-14)
    np.testing.assert_allclose((hi - lo) / (hi + lo), [0.1, 0.1, 0.3, 0.3, 0.2, 0.2, 0.1, 0.1], rtol=1e-12)
    assert get_plant("current_feed_drive") is MODEL


def test_linear_model_is_kf_over_ms2_plus_cs():
    for axis, (m, c, kf) in enumerate(((0.088, 0.559, 235.62), (0.097, 0.796, 331.12))):
        tf = MODEL.linear_model(axis=axis)
        expected = control.tf([kf], [m, c, 0.0])
        np.testing.assert_allclose(tf.num[0][0], expected.num[0][0], rtol=1e-15)
        np.testing.assert_allclose(tf.den[0][0], expected.den[0][0], rtol=1e-15)


# ---------------------------------------------------------------- linear part against python-control


@pytest.mark.parametrize("vertex", [0, 77, 255])
@pytest.mark.parametrize("signal", ["step", "cosine", "random"])
def test_frictionless_plant_is_the_zoh_discretisation(vertex, signal):
    params = cfd.without_friction(MODEL.vertices()[vertex])
    n = 2000
    t = DT * np.arange(n)
    rng = np.random.default_rng(3)
    if signal == "step":
        u = np.column_stack([np.full(n, 2.0), np.full(n, -1.5)])
    elif signal == "cosine":
        u = np.column_stack([3 * np.cos(2 * np.pi * 7 * t), -2 * np.sin(2 * np.pi * 11 * t)])
    else:
        u = rng.uniform(-8, 8, size=(n, 2))  # beyond i_max: saturation is off here
    traj = simulate(params, u)
    for axis in range(2):
        sysd = control.c2d(MODEL.linear_model(params, axis), DT, "zoh")
        y = control.forced_response(sysd, T=np.arange(n + 1) * DT, U=np.append(u[:, axis], 0.0)).outputs
        scale = np.max(np.abs(y))
        np.testing.assert_allclose(traj[:, 0, axis, cfd.S_X], y, rtol=0, atol=1e-10 * scale)


def test_saturation_clips_the_current():
    p = MODEL.nominal()
    a = simulate(p, np.tile([[7.0, -100.0]], (50, 1)))
    b = simulate(p, np.tile([[5.0, -5.0]], (50, 1)))
    np.testing.assert_array_equal(a, b)


# ---------------------------------------------------------------- friction: exact stops, no chattering


def test_stuck_below_the_coulomb_force_and_moving_just_above():
    p = MODEL.nominal()
    i_stick = np.array([48.0 / 235.62, -58.0 / 331.12])  # |k_f i| == f_c exactly: stays stuck
    traj = simulate(p, np.tile(i_stick, (200, 1)))
    assert np.all(traj[..., cfd.S_X] == 0.0) and np.all(traj[..., cfd.S_V] == 0.0)
    traj = simulate(p, np.tile(i_stick * (1 + 1e-6), (200, 1)))
    assert traj[-1, 0, 0, cfd.S_V] > 0.0 and traj[-1, 0, 1, cfd.S_V] < 0.0


@pytest.mark.parametrize("v0", [30.0, -0.01])
def test_coasting_stop_is_exact_and_final(v0):
    """With zero current the table stops at the closed-form time and place, then stays put."""
    m, c, fc = 0.088, 0.559, 48.0
    p = MODEL.nominal()
    x0 = np.zeros((1, 2, 2))
    x0[0, 0, cfd.S_V] = v0
    traj = simulate(p, np.zeros((400, 2)), x0=x0)
    # v(t) = (|v0| + fc/c) e^{-c t/m} - fc/c  reaches 0 at t* = (m/c) ln(1 + c |v0| / fc)
    s = abs(v0)
    t_stop = m / c * math.log1p(c * s / fc)
    x_stop = math.copysign((s + fc / c) * m / c * (1 - math.exp(-c * t_stop / m)) - fc / c * t_stop, v0)
    k_stop = math.ceil(t_stop / DT)
    v = traj[:, 0, 0, cfd.S_V]
    assert np.all(v[k_stop:] == 0.0) and np.all(np.sign(v[:k_stop]) == np.sign(v0))
    np.testing.assert_allclose(traj[k_stop:, 0, 0, cfd.S_X], x_stop, rtol=1e-12, atol=1e-15)


def reference_trajectory(params, currents, dt=DT):
    """Eq. (1) under a ZOH current by scipy's DOP853, stops located as events; (K + 1, 2) x and v of axis x."""
    m, c, fc, kf, imax = params[0]
    x, v = 0.0, 0.0
    out = [(x, v)]
    for i in currents:
        force = kf * min(imax, max(-imax, i))
        t, end = 0.0, dt
        while t < end:
            if v == 0.0:
                if abs(force) <= fc:
                    break
                direction = math.copysign(1.0, force)
            else:
                direction = math.copysign(1.0, v)

            def rhs(_, y, d=direction):
                return [y[1], (force - c * y[1] - fc * d) / m]

            def stop(_, y, d=direction):
                return y[1] if d > 0 else -y[1]

            stop.terminal, stop.direction = True, -1
            sol = integrate.solve_ivp(rhs, (t, end), [x, v], method="DOP853", rtol=1e-13, atol=1e-16, events=stop)
            x, v = sol.y[0, -1], sol.y[1, -1]
            if sol.status == 1:  # stopped
                x, v, t = sol.y_events[0][0][0], 0.0, sol.t_events[0][0]
            else:
                t = end
        out.append((x, v))
    return np.array(out)


def test_reversals_match_an_event_locating_integrator_without_chattering():
    """A 20 Hz current of 1.5 f_c / k_f: stick at every reversal, exact break-away, one sign change per reversal."""
    p = MODEL.nominal()
    n = 1500  # 0.15 s: three periods of the current
    t = DT * np.arange(n)
    amp = 1.5 * 48.0 / 235.62
    i = amp * np.sin(2 * np.pi * 20 * t)
    traj = simulate(p, np.column_stack([i, np.zeros(n)]))
    ref = reference_trajectory(p, i)
    np.testing.assert_allclose(traj[:, 0, 0, cfd.S_X], ref[:, 0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(traj[:, 0, 0, cfd.S_V], ref[:, 1], rtol=0, atol=1e-8)
    v = traj[:, 0, 0, cfd.S_V]
    # the table is stuck exactly (v == 0.0, x constant) wherever |k_f i| <= f_c after a stop,
    # and the velocity changes sign once per half period of the current: no chattering
    signs = np.sign(v[v != 0.0])
    assert np.count_nonzero(np.diff(signs)) == 5
    stuck = v == 0.0
    assert stuck.sum() > 100
    x = traj[:, 0, 0, cfd.S_X]
    runs = np.flatnonzero(stuck[1:] & stuck[:-1]) + 1
    np.testing.assert_array_equal(x[runs], x[runs - 1])


def test_reversal_inside_one_period():
    """Moving at +v0 with a large negative current: stop and break away inside one period."""
    m, c, fc, kf, _ = MODEL.nominal()[0]
    v0, i = 0.5, -5.0
    x0 = np.zeros((1, 2, 2))
    x0[0, 0, cfd.S_V] = v0
    traj = simulate(MODEL.nominal(), np.array([[i, 0.0]]), x0=x0)
    f1 = kf * i - fc  # while v > 0
    t1 = m / c * math.log1p(c * v0 / -f1)
    assert 0 < t1 < DT
    x1 = (v0 - f1 / c) * m / c * (1 - math.exp(-c * t1 / m)) + f1 / c * t1
    f2 = kf * i + fc  # after the break-away, v < 0
    r = DT - t1
    x_end = x1 + f2 / c * (r - m / c * (1 - math.exp(-c * r / m)))
    v_end = f2 / c * (1 - math.exp(-c * r / m))
    assert traj[1, 0, 0, cfd.S_X] == pytest.approx(x_end, rel=1e-12)
    assert traj[1, 0, 0, cfd.S_V] == pytest.approx(v_end, rel=1e-12)


# ---------------------------------------------------------------- batch, contract, env


def test_batch_equals_separate_machines():
    verts = MODEL.vertices()[[0, 100, 255]]
    rng = np.random.default_rng(0)
    i = rng.uniform(-6, 6, size=(300, 3, 2))
    together = simulate(verts, i)
    for k in range(3):
        alone = simulate(verts[k], i[:, k])
        np.testing.assert_array_equal(together[:, k], alone[:, 0])


def test_env_runs_the_plant_through_the_contract():
    env = ContouringEnv(contour=polyline([[0, 0], [5, 0], [5, 5]]), plant="current_feed_drive", feedrate=50)
    env.reset(seed=0)
    actions = np.tile(np.array([0.3, -0.2], dtype=np.float32), (40, 1))
    positions = [env.step(a)[4]["position"] for a in actions]
    traj = simulate(MODEL.nominal(), actions.astype(np.float64) * 5.0)
    np.testing.assert_array_equal(np.array(positions), traj[1:, 0, :, cfd.S_X])
    assert env.unwrapped.plant.input_unit == "A" and env.unwrapped.u_max == 5.0


@pytest.mark.parametrize(
    "name, value", [("m", 0.0), ("m", -0.1), ("c", -0.01), ("f_c", -1.0), ("k_f", 0.0), ("i_max", 0.0), ("f_c", np.nan)]
)
def test_bad_parameters_raise_value_error_naming_them(name, value):
    p = MODEL.nominal()
    p[1, MODEL.index(name)] = value
    with pytest.raises(ValueError, match=name):
        MODEL.validate(p)


def test_bad_shapes_and_options():
    with pytest.raises(ValueError, match=r"shape \(2, 5\)"):
        MODEL.validate(np.ones((2, 4)))
    with pytest.raises(ValueError, match="substep"):
        MODEL.arrays(1, DT, substep=1e-5)
    with pytest.raises(ValueError, match="dt"):
        MODEL.arrays(1, -1.0)
