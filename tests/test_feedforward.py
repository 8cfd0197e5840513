"""The model-based controllers (vcnc_baselines.feedforward, vcnc_baselines.coupling.ccc, vcnc_baselines.optimal) against what no
one here wrote: python-control's simulation of the plants' linear models, its frequency responses, the exact
distance to a circle."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

control = pytest.importorskip("control")

import vcnc_baselines  # noqa: E402
import vcnc_gym  # noqa: E402,F401
from vcnc_baselines.feedforward.tables import closed_loop, inverse_feedforward, zpetc_filter  # noqa: E402
from vcnc_baselines.commissioning.design import pid_gains  # noqa: E402
from vcnc_baselines.servo import coupling_estimate  # noqa: E402
from vcnc_gym.envs import step_kernel as sk  # noqa: E402
from vcnc_gym.evaluation import run_episode  # noqa: E402
from vcnc_gym.plants import get_plant  # noqa: E402

PLANTS = ["vcnc_feed_drive", "current_feed_drive", "nct_xy_table", "cncmt_axis"]


@pytest.fixture(scope="module")
def heart():
    return gym.make("VCNC-Heart-v1")


@pytest.mark.parametrize("plant", PLANTS)
def test_inverse_dynamics_is_the_linear_model_inverted(plant):
    """c_n = den_n / num: the inverse's coefficients against the plant's transfer function's own."""
    model = get_plant(plant)
    inverse = model.inverse()
    for axis in (0, 1):
        tf = model.linear_model(axis=axis)
        s = 2j * np.pi * np.array([0.3, 3.0, 30.0])
        inverse_response = sum(inverse.coefficients[axis, n - 1] * s**n for n in range(1, 5))
        np.testing.assert_allclose(inverse_response * tf(s), 1.0, rtol=1e-12)
        assert inverse.delay[axis] == model.dead_time(axis=axis)


@pytest.mark.parametrize("plant", PLANTS)
def test_feedforward_makes_the_nominal_model_follow_the_reference(plant, heart):
    """python-control's ZOH simulation of the nominal linear model (dead time as whole samples), driven by the
    linear feedforward alone, reproduces the heart's reference within 0.05 um.  With a dead time T_d the first
    T_d of the reference cannot be followed by any input given from t = 0 on: there the delayed model receives
    the input a zero-dead-time table would have given before t = 0."""
    model = get_plant(plant)
    inverse = model.inverse()
    samples = heart.unwrapped.task.reference_arrays.samples
    dt = heart.unwrapped.dt
    u = inverse_feedforward(inverse, samples, dt, friction=False, backlash=False)
    undelayed = type(inverse)(inverse.coefficients, inverse.coulomb, inverse.backlash, np.zeros(2))
    before = inverse_feedforward(undelayed, samples, dt, friction=False, backlash=False)
    x_d = samples[:, sk.REF_POSITION : sk.REF_POSITION + 2]
    for axis in (0, 1):
        sampled = control.c2d(model.linear_model(axis=axis), dt, "zoh")
        delay = int(round(inverse.delay[axis] / dt))
        held = np.concatenate([before[:delay, axis], u[:, axis]])[: len(u)]
        response = control.forced_response(sampled, U=held).outputs
        error = x_d[:, axis] - x_d[0, axis] - response
        assert np.max(np.abs(error)) < 5e-5, f"axis {axis}: {np.max(np.abs(error)) * 1e3:.4f} um"


def test_stribeck_curve_precompensation_is_the_static_map_at_the_reference_speed(heart):
    """With a Stribeck curve in the inverse, the friction term away from the reversals is the Coulomb level of the
    direction plus F_s exp(-(v / v_s)^2) sgn v, v the reference's velocity half a period ahead (the table's read
    point), written out here from the reference's own velocity; without one, the Coulomb level alone."""
    import dataclasses

    inverse = heart.unwrapped.plant.inverse()
    stribeck = np.array([[0.3, 2.0], [0.1, 5.0]])
    curved = dataclasses.replace(inverse, delay=np.zeros(2), stribeck=stribeck)
    samples = heart.unwrapped.task.reference_arrays.samples
    dt = heart.unwrapped.dt
    friction = inverse_feedforward(curved, samples, dt, backlash=False) - inverse_feedforward(
        curved, samples, dt, friction=False, backlash=False
    )
    v = samples[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
    half = 0.5 * (v[:-1] + v[1:])  # the velocity at k + 1/2
    for axis in (0, 1):
        level, vs = stribeck[axis]
        moving = np.abs(half[:, axis]) > 1.0  # mm/s: away from the reversals' 1 ms transitions
        coulomb = np.where(half[:, axis] > 0, inverse.coulomb[axis, 0], inverse.coulomb[axis, 1])
        expected = coulomb + level * np.exp(-((half[:, axis] / vs) ** 2)) * np.sign(half[:, axis])
        np.testing.assert_allclose(friction[:-1, axis][moving], expected[moving], rtol=2e-3, atol=1e-6)
    with pytest.raises(ValueError, match="stribeck"):
        dataclasses.replace(inverse, stribeck=np.array([[0.3, 0.0], [0.0, 0.0]]))


def test_friction_and_backlash_precompensation_switch_at_reversals(heart):
    """The Coulomb level of the direction of motion, and the backlash lead, change sign where v_d does."""
    inverse = heart.unwrapped.plant.inverse()
    samples = heart.unwrapped.task.reference_arrays.samples
    dt = heart.unwrapped.dt
    base = inverse_feedforward(inverse, samples, dt, friction=False, backlash=False)
    friction = inverse_feedforward(inverse, samples, dt, backlash=False) - base
    v = samples[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
    moving = np.abs(v) > 1.0  # mm/s: away from the reversals' 1 ms transitions
    for axis in (0, 1):
        fwd, back = moving[:, axis] & (v[:, axis] > 0), moving[:, axis] & (v[:, axis] < 0)
        np.testing.assert_allclose(friction[fwd, axis], inverse.coulomb[axis, 0], rtol=1e-9)
        np.testing.assert_allclose(friction[back, axis], inverse.coulomb[axis, 1], rtol=1e-9)
    lash = inverse_feedforward(inverse, samples, dt, friction=False, backlash_time=16e-3) - base
    k = np.arange(len(v))
    for axis in (0, 1):
        reversals = np.flatnonzero(np.diff(np.sign(v[:, axis])) != 0)
        distance = np.min(np.abs(k[:, None] - reversals[None, :]), axis=1) * dt
        assert np.max(np.abs(lash[distance > 9e-3, axis])) < 1e-9  # only within the 16 ms transition
        assert np.max(np.abs(lash[:, axis])) > 0.05  # V: the gap is crossed there


def _simulate_loop(inverse, axis, dt, kp, kd, ki, r):
    """The servo law on the ZOH-discretised nominal axis, written out sample by sample (python-control's c2d)."""
    m, c = inverse.mass[axis], inverse.damping[axis]
    plant = control.c2d(control.ss([[0, 1], [0, -c / m]], [[0], [1 / m]], np.eye(2), 0), dt, "zoh")
    A, B = np.asarray(plant.A), np.asarray(plant.B)[:, 0]
    state, integral, previous, out = np.zeros(2), 0.0, 0.0, np.empty_like(r)
    for k, rk in enumerate(r):
        out[k] = state[0]
        u = kp * (rk - state[0]) + kd * ((rk - previous) / dt - state[1]) + ki * integral
        integral += dt * (rk - state[0])
        previous = rk
        state = A @ state + B * u
    return out


@pytest.mark.parametrize("plant", ["vcnc_feed_drive", "nct_xy_table"])
def test_zpetc_closed_loop_and_zero_phase(plant):
    """closed_loop() is the servo law's loop (a hand-written simulation, against python-control's forced
    response); ZPETC times that loop has zero phase (python-control's frequency response) and unit DC gain."""
    model = get_plant(plant)
    inverse = model.inverse()
    dt = 1e-4 if plant == "vcnc_feed_drive" else 1e-3
    w = 1000.0 if plant == "vcnc_feed_drive" else 30.0
    kp, kd, ki = pid_gains(inverse.mass, inverse.damping, w)
    loop = closed_loop(inverse, 0, dt, kp[0], kd[0], ki[0])
    r = np.cumsum(np.random.default_rng(0).normal(size=400)) * 1e-3
    np.testing.assert_allclose(
        control.forced_response(loop, U=r).outputs, _simulate_loop(inverse, 0, dt, kp[0], kd[0], ki[0], r), atol=1e-12
    )
    b, a, preview = zpetc_filter(loop)
    freqs = np.logspace(-1, np.log10(0.05 / dt), 30)  # Hz, up to a tenth of Nyquist
    z = np.exp(2j * np.pi * freqs * dt)
    zpetc = np.polyval(b[::-1], 1 / z) / np.polyval(a[::-1], 1 / z) * z**preview
    product = control.frequency_response(loop, 2 * np.pi * freqs).complex * zpetc
    np.testing.assert_allclose(np.angle(product), 0.0, atol=1e-9)
    assert np.all(np.abs(product) <= 1.0 + 1e-9) and abs(product[0] - 1.0) < 1e-6


def test_zpetc_handles_a_dead_time():
    """On Yadav et al.'s axis (0.1 s dead time) the loop's inverse is not causal: ZPETC previews 100 samples and
    more, and still has zero phase."""
    inverse = get_plant("cncmt_axis").inverse()
    kp, kd, ki = pid_gains(inverse.mass, inverse.damping, 1.0)
    loop = closed_loop(inverse, 0, 1e-3, kp[0], kd[0], ki[0])
    b, a, preview = zpetc_filter(loop)
    assert preview >= 101
    z = np.exp(2j * np.pi * np.array([0.01, 0.1]) * 1e-3)
    product = loop(z) * np.polyval(b[::-1], 1 / z) / np.polyval(a[::-1], 1 / z) * z**preview
    np.testing.assert_allclose(np.angle(product), 0.0, atol=1e-6)


def test_koren_lo_estimate_is_the_distance_to_a_circle_to_second_order():
    """Koren and Lo (1991): with C_x = sin(theta) - E_x / 2R, C_y = cos(theta) + E_y / 2R the estimate is
    eps_n + |E|^2 / 2R, the exact distance to a circle of radius R (eps_n + eps_t^2 / 2R + O(E^3 / R^2)) but for
    eps_n^2 / 2R: exact to second order in the tangential (lag) error, where Koren's fixed gains (the normal error
    eps_n) leave eps_t^2 / 2R."""
    rng = np.random.default_rng(3)
    R, n = 1.0, 2000
    phi = rng.uniform(0, 2 * np.pi, n)
    reference = R * np.column_stack([np.cos(phi), np.sin(phi)])  # counter-clockwise: turning left, kappa = 1/R
    tangent = np.column_stack([-np.sin(phi), np.cos(phi)])
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    e_t, e_n = rng.uniform(-0.02, 0.02, n), rng.uniform(-0.002, 0.002, n)  # mm: lag error >> normal error
    E = tangent * e_t[:, None] + normal * e_n[:, None]
    exact = np.linalg.norm(reference - E, axis=1) - R  # outside the circle: right of the counter-clockwise path
    variable, cx, cy = coupling_estimate(E, tangent, np.full(n, 1 / R), 1.0)
    fixed, _, _ = coupling_estimate(E, tangent, np.full(n, 1 / R), 0.0)
    size = np.linalg.norm(E, axis=1)
    np.testing.assert_allclose(
        variable,
        -E[:, 0] * (tangent[:, 1] - E[:, 0] / (2 * R)) + E[:, 1] * (tangent[:, 0] + E[:, 1] / (2 * R)),
        rtol=0,
        atol=1e-15,
    )
    assert np.all(np.abs(variable - exact) <= e_n**2 / (2 * R) + size**3 / R**2)
    assert np.all(np.abs(fixed - exact - (-(e_t**2) / (2 * R))) <= size**3 / R**2 + e_n**2 / R)
    assert np.max(np.abs(variable - exact)) < 0.05 * np.max(np.abs(fixed - exact))
    # Koren's fixed estimate is the env's normal error (-t_y E_x + t_x E_y), with the sign of exact distance
    np.testing.assert_allclose(fixed, -tangent[:, 1] * E[:, 0] + tangent[:, 0] * E[:, 1], rtol=0, atol=1e-15)


def test_strongest_causal_controller_reaches_2_um_on_the_heart(heart):
    """Issue 18's target: at most 2 um max contour error on VCNC-Heart-v1's nominal plant."""
    best = min(run_episode(vcnc_baselines.make(n, heart), heart).max_contour_error_um for n in ("zpetc", "ff-ccc"))
    assert best <= 2.0


def test_servo_controllers_refuse_a_positioning_env():
    env = gym.make("VCNC-Step-v0")
    with pytest.raises(ValueError, match="contouring env"):
        vcnc_baselines.make("ff-pid", env)


def test_servo_controller_follows_a_contour_drawn_at_reset():
    """VCNC-RandomContour-v1 draws its contour at reset: plan() (called by run_episode) rebuilds the table from
    the new reference, and ff-ccc follows every contour to within a few micrometres."""
    env = gym.make("VCNC-RandomContour-v1")
    policy = vcnc_baselines.make("ff-ccc", env)
    for seed in (3, 4):
        result = run_episode(policy, env, seed=seed)
        assert policy.reference is env.unwrapped.task.reference_arrays.samples
        assert result.completed and result.max_contour_error_um < 10.0, (seed, result.max_contour_error_um)
