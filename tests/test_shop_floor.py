"""The shop-floor wrapper (vcnc_gym/plants/shop_floor.py): each effect against an independent computation.

The structural mode against python-control (its first-order-hold discretisation and its frequency response),
the encoder's quantisation steps, the delays' exact sample shift, the tooth-passing frequency in the cutting
force's spectrum (numpy's FFT), the noise's standard deviation and its determinism from the reset's seed, and
every effect off giving the inner plant's observations to the bit.
"""

from __future__ import annotations

import control
import gymnasium as gym
import numpy as np
import pytest
from numba import njit

import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs.contouring_env import ContouringEnv
from vcnc_gym.plants import contract, get_plant
from vcnc_gym.plants import shop_floor as sf

DT = 1e-4
PLANT = "current_feed_drive"  # linear but for its Coulomb friction: the fastest plant to compile and run
SHOP_IDS = ("VCNC-HeartShop-v1", "VCNC-OmegaLookaheadShop-v1", "VCNC-CornersSmoothShop-v1", "VCNC-CircleShop-v1")


@njit(cache=True)
def _run(arrays, commands, true, measured, velocity, disturbance, drive):
    """Advance machine 0 through ``commands`` (K, 2); after each period record the true and measured position,
    the measured velocity, the input disturbance and the drive's position."""
    out = np.zeros(contract.SENSE_SIZE)
    for j in range(commands.shape[0]):
        contract.advance(arrays, 0, commands[j])
        contract.sense(arrays, 0, out)
        for i in range(2):
            true[j, i] = out[contract.SENSE_POSITION + i]
            measured[j, i] = out[contract.SENSE_MEASURED + i]
            velocity[j, i] = out[contract.SENSE_VELOCITY + i]
            disturbance[j, i] = arrays.memory[0, i, sf.M_DISTURBANCE]
            drive[j, i] = arrays.memory[0, i, sf.M_DRIVE]


def simulate(settings, commands, plant=PLANT, dt=DT, seed=None, effects=sf.EFFECTS):
    """One machine of ``plant`` on the shop floor with ``settings`` over every other effect off."""
    off = {name: value for name, value in sf.OFF.items() if name in {p.name for e in effects for p in e.parameters}}
    model = sf.shop_floor(plant, {**off, **settings}, effects=effects)
    arrays = model.arrays(1, dt, model.nominal())
    model.reset_machine(arrays, 0, np.zeros(2))
    if seed is not None:
        model.seed_machine(arrays, 0, np.random.default_rng(seed))
    K = commands.shape[0]
    out = [np.zeros((K, 2)) for _ in range(5)]
    _run(arrays, np.ascontiguousarray(commands, dtype=np.float64), *out)
    return dict(zip(("true", "measured", "velocity", "disturbance", "drive"), out))


def chirp(K, dt=DT, amplitude=2.0):
    """A swept sine command, 5-400 Hz, on both axes (y at half amplitude)."""
    t = np.arange(K) * dt
    f = 5.0 + (400.0 - 5.0) * t / t[-1]
    u = amplitude * np.sin(2.0 * np.pi * np.cumsum(f) * dt)
    return np.column_stack([u, 0.5 * u])


# -- the structural mode -------------------------------------------------------------------------------------------
def test_the_mode_is_python_controls_first_order_hold_of_the_two_mass_response():
    """The table follows the drive through M(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2): sample for sample,
    python-control's FOH discretisation of M driven by the drive's positions gives the table's."""
    f_n, zeta = 150.0, 0.05
    run = simulate({"mode_frequency": f_n, "mode_damping": zeta}, chirp(4000))
    M = sf.mode_response(f_n, zeta)
    Md = control.c2d(M, DT, method="foh")
    for axis in (0, 1):
        x_d = run["drive"][:, axis]
        u = np.concatenate([[0.0], x_d])  # the drive at rest at 0 before the first period
        expected = control.forced_response(Md, U=u).outputs[1:]
        scale = np.max(np.abs(x_d))
        assert scale > 1e-3
        np.testing.assert_allclose(run["true"][:, axis], expected, rtol=0, atol=1e-9 * scale)


def test_the_mode_s_frequency_response_is_python_controls():
    """Steady-state amplitude and phase of the table against a sinusoidal drive motion: M(j w) as python-control
    evaluates it, at, below and above the natural frequency (the resonance peak 1 / (2 zeta) included)."""
    f_n, zeta = 150.0, 0.05
    M = sf.mode_response(f_n, zeta)
    Md = control.c2d(M, DT, method="foh")
    t = np.arange(20000) * DT
    for f in (50.0, 150.0, 300.0):
        x_d = np.sin(2 * np.pi * f * t)
        y = control.forced_response(Md, U=x_d).outputs
        tail = slice(10000, None)  # after the mode's transient (decays as exp(-zeta w t): 1e-20 at 1 s)
        basis = np.exp(-2j * np.pi * f * t[tail])
        ratio = (y[tail] @ basis) / (x_d[tail] @ basis)
        expected = complex(M(2j * np.pi * f))
        assert abs(ratio - expected) < 0.01 * abs(expected), (f, ratio, expected)
    assert abs(abs(complex(M(2j * np.pi * f_n))) - np.sqrt(1 + 4 * zeta**2) / (2 * zeta)) < 1e-9


# -- the sensor ----------------------------------------------------------------------------------------------------
def test_quantisation_steps_are_the_encoder_resolution():
    r = 1e-3
    run = simulate({"encoder_resolution": r}, np.full((3000, 2), 1.0))
    m, x = run["measured"], run["true"]
    counts = m / r
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    assert np.all(np.abs(m - x) <= 0.5 * r + 1e-12)
    steps = np.abs(np.diff(counts[:, 0]))
    moved = steps[steps > 0.5]
    assert moved.size > 10 and np.allclose(moved, np.round(moved), atol=1e-6)
    # the velocity the controller sees is the count difference over the period
    np.testing.assert_allclose(run["velocity"][1:], np.diff(m, axis=0) / DT, rtol=1e-12, atol=1e-9)


def test_noise_has_its_standard_deviation_and_follows_the_seed():
    sigma = 2e-4
    commands = np.full((4000, 2), 0.5)
    a = simulate({"noise_std": sigma}, commands, seed=7)
    b = simulate({"noise_std": sigma}, commands, seed=7)
    c = simulate({"noise_std": sigma}, commands, seed=8)
    noise = a["measured"] - a["true"]
    assert abs(noise.std() / sigma - 1.0) < 0.05 and abs(noise.mean()) < 0.1 * sigma
    assert abs(np.corrcoef(noise[:, 0], noise[:, 1])[0, 1]) < 0.05  # the axes' noises independent
    np.testing.assert_array_equal(a["measured"], b["measured"])
    assert not np.array_equal(a["measured"], c["measured"])
    np.testing.assert_array_equal(a["true"], c["true"])  # the noise is in the reading only


# -- the delays ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("delay", [1, 3])
def test_the_command_delay_shifts_the_motion_by_whole_periods(delay):
    commands = chirp(2000)
    plain = simulate({}, commands)
    late = simulate({"command_delay": delay}, commands)
    np.testing.assert_array_equal(late["true"][:delay], 0.0)  # nothing commanded yet: the drive at rest
    np.testing.assert_array_equal(late["true"][delay:], plain["true"][:-delay])


def test_the_sensor_delay_shifts_the_reading_not_the_table():
    commands = chirp(1000)
    plain = simulate({"encoder_resolution": 1e-4}, commands)
    late = simulate({"encoder_resolution": 1e-4, "sensor_delay": 2}, commands)
    np.testing.assert_array_equal(late["true"], plain["true"])
    np.testing.assert_array_equal(late["measured"][2:], plain["measured"][:-2])
    np.testing.assert_array_equal(late["measured"][:2], 0.0)


# -- the process forces --------------------------------------------------------------------------------------------
def test_the_cutting_force_carries_the_tooth_passing_frequency():
    """spindle_speed teeth / 60: 6000 rpm and 4 teeth give 400 Hz, the largest line of the force's spectrum;
    its mean opposes the motion at cutting_force N through the plant's force gain (1 / k_f A per N)."""
    settings = {"cutting_force": 100.0, "cutting_ripple": 50.0, "spindle_speed": 6000.0, "teeth": 4.0}
    run = simulate(settings, np.tile([2.0, 0.0], (10000, 1)))
    d = run["disturbance"][2000:, 0]  # steady feed in +x
    spectrum = np.abs(np.fft.rfft(d - d.mean()))
    freqs = np.fft.rfftfreq(d.size, DT)
    assert freqs[np.argmax(spectrum)] == pytest.approx(6000.0 * 4 / 60.0, abs=freqs[1])
    k_f = get_plant(PLANT).nominal()[0, get_plant(PLANT).index("k_f")]
    assert d.mean() == pytest.approx(-100.0 / k_f, rel=0.02)
    np.testing.assert_array_equal(run["disturbance"][:, 1], 0.0)  # no motion along y: no force along y


def test_stribeck_friction_opposes_motion_and_fades_with_speed():
    settings = {"stribeck_force": 30.0, "stribeck_velocity": 1.0}
    k_f = get_plant(PLANT).nominal()[0, get_plant(PLANT).index("k_f")]
    for command, sign in ((1.0, -1.0), (-1.0, 1.0)):
        run = simulate(settings, np.full((3000, 2), command))
        d = run["disturbance"][:, 0]
        assert np.all(d * sign >= 0.0) and np.max(np.abs(d)) <= 30.0 / k_f
        assert abs(d[-1]) < 1e-6 * 30.0 / k_f  # ~100 mm/s: exp(-100^2) of it left


# -- the envs ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "plant, kwargs",
    [
        ("vcnc_feed_drive", {"contour": "heart"}),
        ("current_feed_drive", {"contour": "corners-smooth", "profile": "jlap", "feedrate": 50.0}),
        (
            "nct_xy_table",
            {
                "contour": "circle",
                "profile": "constant",
                "feedrate": 1.0,
                "dt": 1e-3,
                "reward_scale": 1e-3,
                "tracking_bound": 0.5,
                "divergence_bound": 0.5,
            },
        ),
    ],
)
def test_every_effect_off_gives_the_inner_plants_observations_to_the_bit(plant, kwargs):
    """The wrapper with every effect off is the plain plant: the same observations, rewards and infos."""
    plain = ContouringEnv(plant=plant, **kwargs)
    wrapped = ContouringEnv(plant=plant, shop_floor=dict(sf.OFF), **kwargs)
    rng = np.random.default_rng(0)
    o1, _ = plain.reset(seed=0)
    o2, _ = wrapped.reset(seed=0)
    np.testing.assert_array_equal(o1, o2)
    for _ in range(300):
        a = rng.uniform(-0.3, 0.6, 2).astype(np.float32)
        o1, r1, t1, u1, i1 = plain.step(a)
        o2, r2, t2, u2, i2 = wrapped.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert (r1, t1, u1, i1["contour_error"]) == (r2, t2, u2, i2["contour_error"])
        if t1 or u1:  # a random command may leave the circle's 0.5 mm bound
            break


def test_a_shop_id_is_deterministic_from_the_reset_seed():
    env = gym.make("VCNC-HeartShop-v1")
    actions = np.random.default_rng(1).uniform(-0.2, 0.8, (200, 2)).astype(np.float32)

    def episode(seed):
        obs = [env.reset(seed=seed)[0]]
        obs += [env.step(a)[0] for a in actions]
        return np.array(obs)

    a, b, c = episode(3), episode(3), episode(4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_the_observation_is_the_measurement_and_info_the_truth():
    env = gym.make("VCNC-HeartShop-v1")
    env.reset(seed=0)
    u = env.unwrapped
    r = u.plant.nominal()[0, u.plant.index("encoder_resolution")]
    for _ in range(100):
        _, _, _, _, info = env.step(np.array([0.6, 0.1], dtype=np.float32))
    m = info["measured_position"]
    np.testing.assert_allclose(m / r, np.round(m / r), atol=1e-6)
    assert not np.array_equal(m, info["position"])
    assert np.all(np.abs(m - info["position"]) < 1e-3)


def test_settings_and_randomisation():
    model = sf.shop_floor("vcnc_feed_drive", {"stribeck_force": 300.0, "cutting_force": 0.0})
    p = model.parameters[model.index("stribeck_force")]
    assert p.nominal == (300.0, 300.0) and p.interval[0] == pytest.approx((150.0, 450.0))
    assert model.parameters[model.index("cutting_force")].interval is None
    env = ContouringEnv(contour="heart", shop_floor=True, randomize=True)
    _, info = env.reset(seed=5)
    d = info["parameters"]
    assert 100.0 <= d["mode_frequency"][0] <= 200.0 and 5000.0 <= d["spindle_speed"] <= 7000.0
    with pytest.raises(ValueError, match="mode_frequncy"):
        sf.shop_floor("vcnc_feed_drive", {"mode_frequncy": 100.0})
    with pytest.raises(ValueError, match="physical range"):
        ContouringEnv(contour="heart", shop_floor={"command_delay": 20.0})


def test_shop_ids_are_registered_with_a_vector_env():
    for env_id in SHOP_IDS:
        assert env_id in vcnc_gym.envs.VECTOR_IDS
        assert env_id.replace("Shop", "") in vcnc_gym.ENV_IDS
    envs = gym.make_vec("VCNC-CircleShop-v1", num_envs=2, vectorization_mode="vector_entry_point")
    single = gym.make("VCNC-CircleShop-v1")
    obs, _ = envs.reset(seed=10)
    o1, _ = single.reset(seed=11)
    np.testing.assert_array_equal(obs[1], o1)
    for _ in range(20):
        a = np.array([[0.1, 0.2], [0.3, -0.1]], dtype=np.float32)
        obs, *_ = envs.step(a)
        o1, *_ = single.step(a[1])
    np.testing.assert_array_equal(obs[1], o1)


@pytest.mark.parametrize("baseline", ["smc", "ff-ccc"])
def test_compiled_baselines_run_on_a_shop_id_as_their_python_path(baseline, monkeypatch):
    """The residual mode's compiled controller on VCNC-HeartShop-v1 (randomised: the effects drawn too) gives
    its per-period Python path to the bit: the controllers read the observation only."""
    import test_vec_env as tv

    monkeypatch.setattr(tv, "ENV_ID", "VCNC-HeartShop-v1")
    actions = tv._actions(60)
    compiled = tv._run_vec(True, actions, baseline, 0.2, {"randomize": True})
    tv._assert_same(compiled, tv._run_vec(False, actions, baseline, 0.2, {"randomize": True}))


# -- the composition -----------------------------------------------------------------------------------------------
def test_the_effects_declare_the_parameters_and_the_switches():
    assert sf.EFFECT_PARAMETERS == tuple(p for e in sf.EFFECTS for p in e.parameters)
    assert set(sf.OFF) == {name for e in sf.EFFECTS for name in e.switches} and not any(sf.OFF.values())
    model = sf.shop_floor(PLANT)
    assert model.effects == sf.EFFECTS
    assert [p.name for p in model.parameters[-len(sf.EFFECT_NAMES) :]] == list(sf.EFFECT_NAMES)
    arrays = model.arrays(2, DT)
    assert [type(s) for s in arrays.effects] == [e.Arrays for e in sf.EFFECTS]
    # an effect's columns: its parameters in the plant's, its state in the plant's state arrays (no copies)
    s = arrays.effects[sf.EFFECTS.index(sf.CommandDelay)]
    assert s.params == model.index("command_delay")
    arrays.params[1, :, model.index("command_delay")] = 3.0
    views = sf.CommandDelay.views(arrays, s)
    assert views.params[1, 0, 0] == 3.0 and views.commands.shape == (2, sf.MAX_DELAY + 1, 2)
    views.commands[1, 2, 1] = 7.0
    assert arrays.fstate[1, s.commands + 2 * 2 + 1] == 7.0
    assert arrays.fstate.shape[1] == sum(e.sizes()[0] for e in sf.EFFECTS)


def test_a_composition_is_refused_with_an_error_naming_it():
    with pytest.raises(ValueError, match="effects must be a tuple of Effect subclasses"):
        sf.shop_floor(PLANT, effects=(object,))
    with pytest.raises(ValueError, match=r"\['command_delay'\] appear twice"):
        sf.shop_floor(PLANT, effects=(sf.CommandDelay, sf.CommandDelay))
    with pytest.raises(ValueError, match="unknown shop-floor setting.*noise_std"):
        sf.shop_floor(PLANT, {"noise_std": 0.0}, effects=(sf.CommandDelay,))
    with pytest.raises(ValueError, match="switches/counts.*not among its parameters"):
        type("Bad", (sf.Effect,), {"parameters": sf.CommandDelay.parameters, "switches": ("delay",)})
    with pytest.raises(ValueError, match="declares no force_gain.*stribeck_force"):
        sf.shop_floor("cncmt_axis", {**sf.OFF, "stribeck_force": 30.0})


@pytest.mark.slow
def test_a_subset_of_the_effects_is_the_whole_shop_floor_with_the_others_off():
    """Composing only the mode and the command delay (another kernel) gives the shop floor with every other effect
    off, to the bit."""
    settings = {"mode_frequency": 150.0, "mode_damping": 0.05, "command_delay": 2}
    commands = chirp(2000)
    whole = simulate(settings, commands)
    part = simulate(settings, commands, effects=(sf.CommandDelay, sf.StructuralMode))
    for key in ("true", "measured", "velocity", "drive"):
        np.testing.assert_array_equal(part[key], whole[key])
    assert np.ptp(part["true"] - part["drive"]) > 0.0  # the mode acted
