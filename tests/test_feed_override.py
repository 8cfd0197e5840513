"""The feed override (VCNC-OmegaOverride-v1, vcnc_gym.envs.retiming) and the controller that runs under it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import vcnc_baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_agents.action_modes import ResidualAction
from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.envs.retiming import padded_reference, retime
from vcnc_gym.envs.task import pack_reference
from vcnc_gym.motion import SCurveFeedrate, interpolate

ID = "VCNC-OmegaOverride-v1"


def _front():
    """The feed-override study's front (``experiments/feed-override/feed_override.py``), imported when a test needs it."""
    from benchmark_script import study_module

    return study_module("feed-override", "feed_override")


@pytest.fixture(scope="module")
def omega():
    return gym.make("VCNC-Omega-v1").unwrapped


def _episode(env, policy, dial):
    """One episode of ``env`` under ``policy`` with the override dial held at ``dial`` (-1..1); the infos."""
    obs, _ = env.reset(seed=0)
    infos = []
    start = True
    while True:
        a, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, reward, terminated, truncated, info = env.step(np.r_[a, dial])
        infos.append((reward, info))
        if terminated or truncated:
            return infos, terminated, truncated


def test_full_override_is_the_omega_to_the_bit(omega):
    """At 100 % the override env is VCNC-Omega-v1: the same observations, rewards (plus the time cost) and
    cycle time under the same commands."""
    env = gym.make(ID).unwrapped
    policy = vcnc_baselines.make("ff-pid-online", omega)
    o1, _ = omega.reset(seed=0)
    o2, _ = env.reset(seed=0)
    assert np.array_equal(o1, o2)
    start = True
    while True:
        a, _ = policy.predict(o1, episode_start=start)
        start = False
        o1, r1, t1, _, i1 = omega.step(a)
        o2, r2, t2, _, i2 = env.step(np.r_[a, 1.0])
        assert np.array_equal(o1, o2)
        assert r2 == pytest.approx(r1 - env.time_cost / env.reward_scale, abs=1e-12)
        assert i2["override"] == 1.0
        if t1:
            break
    assert t2 and i1["cycle_time"] == i2["cycle_time"]


@pytest.mark.parametrize("s", [0.37, 0.5, 0.8])
def test_constant_override_is_the_slower_scurve(omega, s):
    """The reference re-timed at a constant override s is the interpolator's own S-curve at s times the feed
    with the ramp time over s (an independent computation: Taylor interpolation at the slower feed), within
    the interpolators' own differences (0.2 um, 0.1 mm/s)."""
    original = omega.task.reference_arrays.samples
    dt = omega.task.dt
    slow = pack_reference(
        omega.curve, interpolate(omega.curve, SCurveFeedrate(feedrate=100.0 * s, ramp_time=0.12 / s), dt)
    )
    n = slow.shape[0]
    out = padded_reference(original, n)
    retime(original, out, 1, n - 1, n - 1, 0.0, s, s, 0.1, dt)
    position = np.hypot(*(out[:n, :2] - slow[:, :2]).T)
    assert position.max() < 2e-4  # mm
    assert (
        np.abs(out[:n, sk.REF_VELOCITY : sk.REF_VELOCITY + 2] - slow[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]).max()
        < 0.1
    )  # mm/s: the two interpolations' timing differs by microseconds, and the
    # velocity turns at 2e4 (s = 0.37) to 5e4 deg/s in the 0.19 mm corners
    assert np.abs(out[:n, sk.REF_ARC] - slow[:, sk.REF_ARC]).max() < 1e-3


def test_half_override_doubles_the_time_and_zero_runs_out_of_it():
    """Held at 50 % the tool arrives at about twice the 0.63 s (the override ramps down from 100 % over 50 ms
    first), with the reference clock at its end; held at 0 the reference stops and the episode ends at the
    time limit, incomplete, paying for the contour left."""
    env = gym.make(ID).unwrapped
    policy = vcnc_baselines.make("ff-pid-online", env)
    duration = env.reference.t[-1]
    infos, terminated, _ = _episode(env, policy, 0.0)
    info = infos[-1][1]
    assert terminated and info["completed"] and info["override"] == 0.5
    assert info["reference_time"] == pytest.approx(duration)
    assert 2 * duration - 0.05 < info["cycle_time"] < 2 * duration + 0.01
    infos, terminated, _ = _episode(env, policy, -1.0)
    info = infos[-1][1]
    assert terminated and not info["completed"] and info["reward_incomplete"] < 0
    assert info["time"] == pytest.approx(env.time_limit * duration, abs=2 * env.dt)
    assert info["reference_time"] < 0.1


def test_bad_arguments_and_actions_are_named():
    env = gym.make(ID)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        env.step(np.zeros(2))
    for kwargs, word in (
        ({"time_limit": 0.5}, "time_limit"),
        ({"time_cost": -1.0}, "time_cost"),
        ({"override_rate": 0.0}, "override_rate"),
        ({"completion_timeout": 1.0}, "time_limit"),
    ):
        with pytest.raises(ValueError, match=word):
            gym.make(ID, **kwargs)
    with pytest.raises(ValueError, match="ff-pid-online"):
        vcnc_baselines.make("ff-pid", env)


def test_checkers_pass():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check

    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(ID).unwrapped, skip_render_check=True)
        sb3_check(gym.make(ID), warn=True)


def test_residual_action_passes_the_override_through():
    """A residual agent sets the override itself: the third component reaches the env unchanged."""
    env = ResidualAction(gym.make(ID, action_repeat=1), baseline="ff-pid-online", correction=0.1, action_repeat=10)
    assert env.action_space.shape == (3,)
    env.reset(seed=0)
    for _ in range(8):  # 8 ms: 100 % -> 92 % at 10 per second
        _, _, _, _, info = env.step(np.array([0.0, 0.0, -0.5], dtype=np.float32))
    assert info["override"] == pytest.approx(0.92)
    for _ in range(80):  # 88 ms: there (25 %)
        _, _, _, _, info = env.step(np.array([0.0, 0.0, -0.5], dtype=np.float32))
    assert info["override"] == pytest.approx(0.25)


def test_online_feedforward_is_the_tables_linear_part(omega):
    """ff-pid-online's feedforward from the observed reference equals ff-pid's table (its linear part, read
    half a period ahead: vcnc_baselines.feedforward.tables.inverse_feedforward) within the second-order term of
    reading ahead by v + a T / 2."""
    from vcnc_baselines.feedforward.tables import inverse_feedforward

    online = vcnc_baselines.make("ff-pid-online", omega)
    samples = omega.task.reference_arrays.samples
    table = inverse_feedforward(online.inverse, samples, omega.dt, friction=False, backlash=False)
    v = samples[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
    a = samples[:, sk.REF_ACCELERATION : sk.REF_ACCELERATION + 2]
    c = online.inverse.coefficients
    mine = c[:, 0] * (v + 0.5 * omega.dt * a) + c[:, 1] * a
    smooth = np.all(np.abs(np.diff(a, axis=0)) < 1e3, axis=1)  # away from the NURBS' acceleration steps
    rows = np.flatnonzero(smooth[:-1] & smooth[1:])
    assert np.abs(mine[rows] - table[rows]).max() < 0.05 * np.abs(table).max()


def _machines(env_id, n, seed=3):
    """``n`` plants of ``env_id``'s box (the nominal one left out) and an object holding them as an env does."""
    import types

    from vcnc_bench.robust import plant_set

    u = gym.make(env_id).unwrapped
    params = plant_set(u.plant, n, seed, nominal=u.nominal_parameters, max_vertices=0).parameters[1:]
    return u, params, types.SimpleNamespace(parameters=params, task=u.task)


def test_online_law_per_machine_fits_each_machines_model():
    """``ff-pid-online@machine`` identifies each plant: its feedforward's coefficients (the viscous term and the
    mass, per axis) are the plant's own inverse dynamics (the plant module's declared model at the drawn parameters,
    which the identification never reads) within 8 %, and less than half as far from them in sum as the nominal
    design's; the Coulomb levels within 2 %."""
    u, params, held = _machines("VCNC-OmegaTolerance-v2", 2)
    policy = vcnc_baselines.make("ff-pid-online@machine", u)
    nominal = vcnc_baselines.make("ff-pid-online", u)
    policy.plan(held)
    assert policy.coefficients.shape == (2, 2, 2) and nominal.coefficients.shape == (1, 2, 2)
    for i, p in enumerate(params):
        true = u.plant.inverse(p)
        np.testing.assert_allclose(policy.coefficients[i], true.coefficients[:, :2], rtol=0.08)
        np.testing.assert_allclose(policy.coulomb[i], true.coulomb, rtol=0.02)
        mine = np.abs(policy.coefficients[i] - true.coefficients[:, :2]).sum()
        assert mine < 0.5 * np.abs(nominal.coefficients[0] - true.coefficients[:, :2]).sum(), i


def test_online_law_per_machine_is_each_machines_law_alone_compiled_and_in_numpy():
    """On the shop floor (the notches act): the law of env i in a batch commissioned on two machines gives, to the
    bit, the commands and memory of the law commissioned on machine i alone, compiled (float32 observations) and in
    NumPy (float64); a batch of another size and another control period are refused by name."""
    u, params, held = _machines("VCNC-OmegaToleranceShop-v2", 2)
    both = vcnc_baselines.make("ff-pid-online@machine", u)
    both.plan(held)
    assert both.notched.all()
    rng = np.random.default_rng(4)
    obs = rng.normal(size=(40, 2, u.layout.size)) * rng.choice([1e-3, 1.0, 100.0], size=(1, 2, u.layout.size))
    alone = []
    for i in range(2):
        policy = vcnc_baselines.make("ff-pid-online@machine", u)
        policy.plan(type(held)(parameters=params[i : i + 1], task=u.task))
        alone.append(policy)
    for dtype in (np.float32, np.float64):
        for k, o in enumerate(obs.astype(dtype)):
            a, _ = both.predict(o, episode_start=np.array([k == 0] * 2))
            for i, policy in enumerate(alone):
                b, _ = policy.predict(o[i], episode_start=k == 0)
                np.testing.assert_array_equal(a[i], b, err_msg=f"{dtype.__name__}, env {i}, call {k}")
                np.testing.assert_array_equal(both.controller_state[i], policy.controller_state[0])
    with pytest.raises(ValueError, match="commissioned 2 machines and is given 3 envs"):
        both.predict(obs[0, :1].repeat(3, axis=0))
    with pytest.raises(ValueError, match="shipped record of the nominal machine"):  # none for 0.2 ms
        vcnc_baselines.make("ff-pid-online@machine", gym.make("VCNC-OmegaToleranceShop-v2", action_repeat=2))
    with pytest.raises(ValueError, match="control period"):
        both.identify_on(gym.make("VCNC-Omega-v1", dt=2e-4).unwrapped.task)
    with pytest.raises(ValueError, match="commissioning must be"):
        vcnc_baselines.make("ff-pid-online", u, commissioning="machines")


def test_running_out_of_time_pays_for_the_whole_contour_left():
    """The incomplete penalty counts the contour from the tool to the contour's end, however far the re-timed
    reference lags (the buffer's last row stays the contour's end)."""
    env = gym.make(ID).unwrapped
    policy = vcnc_baselines.make("ff-pid-online", env)
    infos, terminated, _ = _episode(env, policy, -0.96)  # 2 %: a few mm in the time limit
    info = infos[-1][1]
    assert terminated and not info["completed"]
    left = env.task.contour_length - info["progress"]
    assert left > 40.0
    assert info["reward_incomplete"] == pytest.approx(-left / env.reward_scale, rel=1e-6)


def test_operator_fixed_override_is_the_held_dial():
    """The report's operator points (experiments/feed-override/feed_override.py's FixedOverride) are ff-pid-online with
    the dial held: the same episode as the hand-written loop with that dial; the cap must lie in (0, 1]."""
    FixedOverride = _front().FixedOverride
    from vcnc_gym.evaluation import run_episode

    env = gym.make(ID).unwrapped
    infos, terminated, _ = _episode(env, vcnc_baselines.make("ff-pid-online", env), 2 * 0.6 - 1.0)
    result = run_episode(FixedOverride(vcnc_baselines.make("ff-pid-online", env), 0.6), env)
    assert terminated and result.completed
    assert result.cycle_time_s == infos[-1][1]["cycle_time"]
    assert result.max_contour_error_um == pytest.approx(1e3 * max(i["contour_error"] for _, i in infos), rel=1e-12)
    for bad in (0.0, 1.5):
        with pytest.raises(ValueError, match="override"):
            FixedOverride(vcnc_baselines.make("ff-pid-online", env), bad)


def test_the_front_keeps_exactly_the_points_nothing_beats():
    """experiments/feed-override/feed_override.py's pareto against a brute-force check of every pair: a point is on the
    front when no other finished point is at least as fast and strictly more accurate (ties in time: the lower
    error); unfinished runs (infinite cycle time) are never on it."""
    FrontPoint, pareto = _front().FrontPoint, _front().pareto

    rng = np.random.default_rng(0)
    points = [
        FrontPoint("p", str(k), float(t), float(m), 0.0, "planned")
        for k, (t, m) in enumerate(zip(rng.choice([0.7, 0.8, 0.9, 1.0, np.inf], 60), rng.uniform(1, 9, 60)))
    ]
    mine = pareto(points)
    brute = [
        p
        for p in points
        if np.isfinite(p.cycle_time_s)
        and not any(
            q is not p and np.isfinite(q.cycle_time_s) and q.cycle_time_s <= p.cycle_time_s and q.max_um < p.max_um
            for q in points
        )
    ]
    assert sorted(mine, key=lambda p: p.setting) == sorted(brute, key=lambda p: p.setting)
    assert [p.cycle_time_s for p in mine] == sorted(p.cycle_time_s for p in mine)


@pytest.mark.parametrize("env_id", ["VCNC-ISO230Circle-v1", "VCNC-CircleShop-v1"])
def test_an_ids_override_version_runs_its_own_reference(env_id):
    """The report's override version of a contouring id (experiments/feed-override/feed_override.py's override_env) holds that
    id's task: the same reference samples, plant and shop floor as gym.make(env_id) (a G-code id's program read
    as GCodeEnv reads it), in FeedOverrideEnv; a non-contouring id is refused by name."""
    override_env = _front().override_env

    base, over = gym.make(env_id).unwrapped, override_env(env_id).unwrapped
    assert type(over).__name__ == "FeedOverrideEnv" and over.action_space.shape == (3,)
    np.testing.assert_array_equal(over.task.reference_arrays.samples, base.task.reference_arrays.samples)
    assert over.task.plant.parameter_names == base.task.plant.parameter_names
    np.testing.assert_array_equal(over.task.nominal_parameters, base.task.nominal_parameters)
    with pytest.raises(ValueError, match="VCNC-OmegaOverride-v1"):
        override_env("VCNC-OmegaOverride-v1")


def test_an_ids_front_on_the_table():
    """experiments/feed-override/feed_override.py's id_front on Purtojo et al.'s circle: the planned runs at the programmed
    feed's fractions (1 mm/s and slower: a slower feed takes longer, by the feed's ratio to within the start and
    the end), the operator's override left out (ff-pid-online is not designed for the table), and each planned
    point the episode that gym.make(id, feedrate=f) gives."""
    import vcnc_baselines

    FEED_FRACTIONS, id_front = _front().FEED_FRACTIONS, _front().id_front
    from vcnc_gym.evaluation import run_episode

    lines = []
    points = id_front("VCNC-Circle-v1", policies=("ff-pid", "ff-pid-online"), mpcc=False, progress=lines.append)
    assert [p.kind for p in points] == ["planned"] * len(FEED_FRACTIONS)
    assert any("ff-pid-online is not designed for nct_xy_table" in line for line in lines)
    times = np.array([p.cycle_time_s for p in points])
    np.testing.assert_allclose(times * np.array(FEED_FRACTIONS), times[0], rtol=0.01)
    env = gym.make("VCNC-Circle-v1", feedrate=FEED_FRACTIONS[2])
    assert points[2].max_um == run_episode(vcnc_baselines.make("ff-pid", env), env).max_contour_error_um


def test_the_fronts_json_reads_back_and_replots(tmp_path):
    """--json's file read back by read_fronts gives the same points (FrontPoint equality, infinite cycle times
    included), and --replot draws them on one grid without running anything."""
    front = _front()
    FrontPoint, _write_json, main, read_fronts = front.FrontPoint, front._write_json, front.main, front.read_fronts

    fronts = {
        "VCNC-Heart-v1": [
            FrontPoint("ff-pid", "100 mm/s", 3.22, 1.9, 0.05, "planned"),
            FrontPoint("mpcc", "v_max 35 mm/s", float("inf"), 4.0, 0.3, "mpcc"),
        ],
        "VCNC-Circle-v1": [FrontPoint("zpetc", "1 mm/s", 6.284, 0.55, 0.1, "planned")],
    }
    _write_json(fronts, tmp_path / "f.json")
    assert read_fronts([tmp_path / "f.json"]) == fronts
    assert main(["--replot", str(tmp_path / "f.json"), "--plot", str(tmp_path / "grid.png")]) == 0
    assert (tmp_path / "grid.png").stat().st_size > 10_000
