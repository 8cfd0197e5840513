"""Purtojo et al.'s X-Y table (vcnc_gym.plants.nct_xy_table): eq. (4), exact ZOH, the 1 um sensor, bad inputs."""

from __future__ import annotations

import control
import numpy as np
import pytest
from numba import njit

from vcnc_gym.plants import contract, get_plant, plant_names
from vcnc_gym.plants import nct_xy_table as nt

MODEL = get_plant("nct_xy_table")


@njit(cache=True)
def _run(plant, commands, out):
    """Sense (true, measured, velocity) before each command and after the last: out (n + 1, 6)."""
    sensed = np.empty(contract.SENSE_SIZE)
    for k in range(commands.shape[0] + 1):
        contract.sense(plant, 0, sensed)
        out[k] = sensed[:6]
        if k < commands.shape[0]:
            contract.advance(plant, 0, commands[k])


def run(commands, dt, params=None, start=(0.0, 0.0)):
    arrays = MODEL.arrays(1, dt, params)
    MODEL.reset_machine(arrays, 0, np.asarray(start, dtype=float))
    out = np.empty((len(commands) + 1, 6))
    _run(arrays, np.ascontiguousarray(commands, dtype=float), out)
    return out


def test_plant_is_discovered_and_declares_eq_4():
    assert "nct_xy_table" in plant_names()
    p = MODEL.nominal()
    np.testing.assert_array_equal(p[:, nt.IDX_K], [50.7, 53.1])
    np.testing.assert_array_equal(p[:, nt.IDX_ALPHA], [1.475, 3.156])
    np.testing.assert_array_equal(p[:, nt.IDX_RESOLUTION], [0.001, 0.001])
    assert MODEL.input_unit == "u_r" and MODEL.input_limit == "u_r"
    np.testing.assert_array_equal(MODEL.input_limits(p), [1.0, 1.0])
    lo, hi, names = MODEL.box()
    assert names == ("K_x", "K_y", "alpha_x", "alpha_y")
    np.testing.assert_allclose(hi / lo, 1.1 / 0.9)
    # the linear model is eq. (4) as a python-control transfer function
    for axis, (k, a) in enumerate(((50.7, 1.475), (53.1, 3.156))):
        G = MODEL.linear_model(axis=axis)
        ref = control.tf([k * a], [1.0, a, 0.0])
        w = np.logspace(-2, 3, 30)
        np.testing.assert_allclose(G(1j * w), ref(1j * w), rtol=1e-14)


@pytest.mark.parametrize("dt", [1e-6, 1e-3, 0.3])  # the series branch, the default period, the expm1 branch
def test_kernel_is_the_zoh_discretisation_of_eq_4(dt):
    rng = np.random.default_rng(1)
    n = 400
    commands = rng.uniform(-1.0, 1.0, (n, 2))  # within +-u_r: no saturation
    params = MODEL.vertices()[5]  # not the nominal plant
    out = run(commands, dt, params)
    for axis in (0, 1):
        Gd = control.c2d(control.ss(MODEL.linear_model(params, axis)), dt, "zoh")
        resp = control.forced_response(Gd, U=commands[:, axis])
        ours = out[:-1, contract.SENSE_POSITION + axis]
        scale = np.max(np.abs(resp.outputs))
        np.testing.assert_allclose(ours, resp.outputs, rtol=0, atol=1e-9 * scale)


def test_input_saturates_at_the_rated_input():
    dt = 1e-3
    big = run(np.full((200, 2), 7.5), dt)
    rated = run(np.full((200, 2), 1.0), dt)
    np.testing.assert_array_equal(big, rated)
    neg = run(np.full((200, 2), -1e9), dt)
    np.testing.assert_allclose(neg[:, :2], -rated[:, :2], atol=1e-15)
    # top speed of the stepwise input: h_max = K u_r (eq. (3))
    long = run(np.full((20000, 2), 1.0), dt)
    np.testing.assert_allclose(np.diff(long[-2:, :2], axis=0)[0] / dt, [50.7, 53.1], rtol=1e-6)


@pytest.mark.parametrize("resolution", [0.001, 0.005])
def test_sensor_quantises_the_position_and_differences_it(resolution):
    dt = 1e-3
    params = MODEL.nominal()
    params[:, nt.IDX_RESOLUTION] = resolution
    rng = np.random.default_rng(2)
    out = run(rng.uniform(-0.3, 0.3, (3000, 2)), dt, params, start=(0.0123456, -1.0))
    true = out[:, 0:2]
    meas = out[:, 2:4]
    # the reading is a multiple of the resolution, the nearest one to the true position
    counts = meas / resolution
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)
    assert np.all(np.abs(meas - true) <= 0.5 * resolution * (1 + 1e-9))
    np.testing.assert_allclose(meas, resolution * np.floor(true / resolution + 0.5), atol=1e-15)
    assert len(np.unique(np.round(counts[:, 0]))) > 10  # the trace spans many counts
    # velocity: the count difference over the last control period; 0 right after the reset
    np.testing.assert_array_equal(out[0, 4:6], [0.0, 0.0])
    np.testing.assert_allclose(out[1:, 4:6], np.diff(meas, axis=0) / dt, rtol=1e-12, atol=1e-12)
    # the true position is not quantised
    assert np.max(np.abs(meas - true)) > 0.1 * resolution


def test_reset_puts_the_table_at_rest_at_the_position():
    arrays = MODEL.arrays(3, 1e-3)
    MODEL.reset_machine(arrays, 1, np.array([0.25, 1.0]))
    np.testing.assert_array_equal(arrays.state[1, :, nt.S_X], [0.25, 1.0])
    np.testing.assert_array_equal(arrays.state[1, :, nt.S_V], [0.0, 0.0])
    np.testing.assert_array_equal(arrays.state[0], 0.0)


@pytest.mark.parametrize(
    "column, value, words",
    [
        ("resolution", 0.0, ("resolution", "mm", "positive")),
        ("resolution", -0.001, ("resolution", "mm", "positive")),
        ("K", -50.7, ("K", "positive")),
        ("alpha", 0.0, ("alpha", "1/s", "positive")),
        ("u_r", 0.0, ("u_r", "positive")),
        ("alpha", np.nan, ("finite", "alpha")),
    ],
)
def test_bad_parameters_raise_value_error(column, value, words):
    p = MODEL.nominal()
    p[1, MODEL.index(column)] = value
    with pytest.raises(ValueError) as err:
        MODEL.arrays(1, 1e-3, p)
    for w in words:
        assert w in str(err.value)


def test_env_rejects_a_zero_sensor_resolution_and_passes_the_checker():
    from gymnasium.utils.env_checker import check_env

    from vcnc_gym.envs import ContouringEnv

    p = MODEL.nominal()
    p[0, nt.IDX_RESOLUTION] = 0.0
    kwargs = dict(contour="circle", plant="nct_xy_table", feedrate=1.0, ramp_time=0.05, dt=1e-3)
    with pytest.raises(ValueError, match="resolution"):
        ContouringEnv(parameters=p, **kwargs)
    env = ContouringEnv(randomize=True, **kwargs)
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=3)
    obs, _, _, _, info = env.step(np.array([1.0, -1.0], dtype=np.float32))
    np.testing.assert_allclose(info["command"], [1.0, -1.0])  # action 1 is u_r
