"""The contouring MPC (baselines/predictive/mpcc.py) against independent computations: its linearised contour and
lag errors against the env's exact projection onto the whole contour (vcnc_gym.contour.ContourProjector), its QP
against a second solver (OSQP), its block prediction against stepping the model, and a closed loop."""

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym  # noqa: F401  (registers the ids)
import vcnc_baselines
from vcnc_baselines.predictive import mpcc as M
from vcnc_gym.envs import step_kernel as sk


@pytest.fixture(scope="module")
def override_env():
    env = gym.make("VCNC-OmegaOverride-v1")
    yield env
    env.close()


def _foot_arc(samples, u):
    """The arc (mm) of curve parameter ``u`` on the reference's samples (the path table's arc)."""
    keep = np.concatenate([[True], np.diff(samples[:, sk.REF_ARC]) > 0])
    return np.interp(u, samples[keep, sk.REF_U], samples[keep, sk.REF_ARC] - samples[0, sk.REF_ARC])


def test_linearised_errors_against_the_exact_projection(override_env):
    """Points up to 5 um off the omega (its 0.19 mm corners included): linearised about the exact foot point's arc,
    |e_c| is the exact distance and e_l is 0 (to the path table's chords, 0.07 um at the corners); about an arc
    off by delta, both move by at most Lam et al.'s second-order terms, kappa (|d| |delta| + delta^2)."""
    u = override_env.unwrapped
    samples, projector = u.task.reference_arrays.samples, u.task.projector
    path = M.path_table(samples, u.task.dt)
    rng = np.random.default_rng(0)
    arcs = np.concatenate([rng.uniform(1.0, path.length - 1.0, 40), [5.97, 45.18, 5.9, 45.1]])  # and the corners
    p, t = path.at(arcs)
    n = np.column_stack([-t[:, 1], t[:, 0]])
    d = rng.uniform(-5e-3, 5e-3, arcs.size)
    q = p + d[:, None] * n
    dist, foot_u = projector.project(q)
    foot = _foot_arc(samples, foot_u)
    kappa = np.abs(samples[:, sk.REF_CURVATURE]).max()
    e_c, e_l = M.linearised_errors(q, foot, foot, path)
    np.testing.assert_allclose(np.abs(e_c), dist, rtol=0, atol=2e-4)
    np.testing.assert_allclose(e_l, 0.0, atol=2e-4)
    assert np.max(dist) > 4e-3  # the points are off the path, not on it
    for delta in (-2e-2, 5e-3, 2e-2):
        e_c, e_l = M.linearised_errors(q, foot, foot + delta, path)
        bound = kappa * (np.abs(d) * abs(delta) + delta**2) + 2e-4
        assert np.all(np.abs(np.abs(e_c) - dist) <= bound)
        assert np.all(np.abs(e_l) <= bound)
    # the lag error is the arc between the foot point and theta, to first order
    e_c, e_l = M.linearised_errors(q, foot + 0.01, foot, path)
    np.testing.assert_allclose(e_l, -0.01, atol=2e-4)


def test_block_prediction_is_the_model_stepped_period_by_period(override_env):
    pol = vcnc_baselines.make("mpcc", override_env)
    model, pred = pol.models[1], pol.predictions[1]
    rng = np.random.default_rng(1)
    x0, z = rng.normal(size=model.n), rng.normal(size=pred.blocks.size)
    x, ends = x0.copy(), []
    for level, L in zip(z, pred.blocks):
        for _ in range(L):
            x = model.A @ x + model.B * level
        ends.append(model.C @ x)
    np.testing.assert_allclose(pred.Px @ x0 + pred.Su @ z, ends, rtol=1e-9, atol=1e-12)
    a = rng.normal(size=pred.blocks.size) * 100.0
    theta, v = 0.3, 20.0
    for m, L in enumerate(pred.blocks):  # the double integrator, period by period
        for _ in range(L):
            theta += v * pol.dt + 0.5 * a[m] * pol.dt**2
            v += a[m] * pol.dt
    np.testing.assert_allclose(0.3 + pred.times[-1] * 20.0 + pred.St[-1] @ a, theta, rtol=1e-12)
    np.testing.assert_allclose(20.0 + pred.Sv[-1] @ a, v, rtol=1e-12)


def _braking_qp(pol):
    """One call's QP with the tool 0.2 mm off the path at 50 mm/s and the progress capped at 30 mm/s: the input
    limits and the speed bounds are active."""
    path, b = pol.path, pol.n_blocks
    theta0, v0 = 5.5, 50.0
    p, t = path.at(theta0)
    y = p + 0.2 * np.array([-t[1], t[0]])
    x0 = np.stack(
        [
            np.linalg.pinv(m.measurement()) @ np.array([y[j], v0 * t[j]])[: m.measurement().shape[0]]
            for j, m in enumerate(pol.models)
        ]
    )
    theta_bar = theta0 + pol.predictions[0].times * v0
    return M.contouring_qp(
        pol.predictions,
        path,
        x0,
        theta0,
        v0,
        theta_bar,
        np.zeros(2),
        0.0,
        np.zeros((2, b)),
        pol.u_max,
        np.full(b, 30.0),
        pol.a_max,
        pol.weights,
    )


def test_qp_against_a_second_solver(override_env):
    """DAQP's minimiser of one call's QP against OSQP's (an ADMM method) on the same problem."""
    osqp = pytest.importorskip("osqp")
    from scipy import sparse

    pol = vcnc_baselines.make("mpcc", override_env)
    qp = _braking_qp(pol)
    z = M.solve_qp(qp)
    nz = qp.f.size
    A = sparse.csc_matrix(np.vstack([np.eye(nz), qp.G]))
    lower, upper = np.maximum(qp.lower, -1e30), np.minimum(qp.upper, 1e30)
    solver = osqp.OSQP()
    solver.setup(
        sparse.csc_matrix(np.triu(qp.H)),
        qp.f,
        A,
        lower,
        upper,
        eps_abs=1e-10,
        eps_rel=1e-10,
        max_iter=200000,
        polishing=True,
        verbose=False,
    )
    ref = solver.solve().x
    active = np.isclose(np.concatenate([z, qp.G @ z]), upper, atol=1e-7) | np.isclose(
        np.concatenate([z, qp.G @ z]), lower, atol=1e-7
    )
    assert active[:nz].any() and active[nz:].any()  # input limits and progress bounds both bind
    cost = lambda w: 0.5 * w @ qp.H @ w + qp.f @ w  # noqa: E731
    assert abs(cost(z) - cost(ref)) <= 1e-8 * abs(cost(ref))
    b = pol.n_blocks
    first = [0, b, 2 * b]  # the moves applied: the axes' inputs and the progress' acceleration of the first block
    np.testing.assert_allclose(z[first], ref[first], rtol=0, atol=1e-5)
    # the horizon's last blocks barely move the cost (their inputs act for a few ms before the horizon ends)
    np.testing.assert_allclose(z, ref, atol=2e-3 * np.abs(ref).max())


def test_it_runs_on_feed_override_ids_only_and_refuses_bad_arguments(override_env):
    from vcnc_bench.kinds.baseline import applies

    plain = gym.make("VCNC-Omega-v1")
    with pytest.raises(ValueError, match="feed-override id"):
        vcnc_baselines.make("mpcc", plain)
    assert applies("mpcc", override_env) and not applies("mpcc", plain)
    assert not applies("ff-pid", override_env)
    for name, value in (
        ("v_max", -1.0),
        ("progress_weight", float("nan")),
        ("a_max", 0.0),
        ("disturbance_time", -1e-3),
    ):
        with pytest.raises(ValueError, match=name):
            vcnc_baselines.make("mpcc", override_env, **{name: value})
    with pytest.raises(ValueError, match="blocks"):
        vcnc_baselines.make("mpcc", override_env, blocks=())


def test_first_steps_respect_the_input_limit_and_set_the_dial(override_env):
    """Fifty control periods from rest: the action is the axes' commands and the dial, within [-1, 1]; the
    progress and the tool leave the start together."""
    pol = vcnc_baselines.make("mpcc", override_env)
    obs, _ = override_env.reset(seed=0)
    for k in range(50):
        a, _ = pol.predict(obs, episode_start=k == 0)
        assert a.shape == (3,) and a.dtype == np.float32 and np.all(np.abs(a) <= 1.0)
        obs, _, term, trunc, info = override_env.step(a)
        assert not (term or trunc)
    assert 0.0 < pol.controller_state[0, 0] < 0.05 and info["contour_error"] < 5e-3


def _mpcc_steps(steps, max_override, v_max):
    """``steps`` control periods of ``mpcc`` from rest on the override omega with the dial's top ``max_override``:
    the tool's positions (mm), the overrides in force and the controller."""
    env = gym.make("VCNC-OmegaOverride-v1", max_override=max_override)
    pol = vcnc_baselines.make("mpcc", env, v_max=v_max)
    obs, _ = env.reset(seed=0)
    positions, overrides = [], []
    for k in range(steps):
        a, _ = pol.predict(obs, episode_start=k == 0)
        obs, _, term, trunc, info = env.step(a)
        positions.append(info["position"])
        overrides.append(info["override"])
        assert not (term or trunc)
    env.close()
    return np.array(positions), np.array(overrides), pol


def test_a_dial_to_150_percent_lets_it_run_ahead_of_the_programmed_feed():
    """On the 0-100 % dial the override in force stays at or under 1; on a dial to 150 % (its progress capped at 1.5
    x the programmed feed by default) the MPCC runs ahead of the programmed S-curve's start: an override over 1.2,
    never over 1.5, and the tool further along the omega's first leg after the same 600 periods."""
    p1, o1, pol = _mpcc_steps(600, 1.0, None)
    assert pol.max_override == 1.0 and pol.v_max == pytest.approx(100.0) and o1.max() <= 1.0
    p3, o3, pol = _mpcc_steps(600, 1.5, None)
    assert pol.v_max == pytest.approx(150.0)
    assert 1.2 < o3.max() <= 1.5 + 1e-12
    assert np.linalg.norm(p3[-1] - p3[0]) > 1.2 * np.linalg.norm(p1[-1] - p1[0])


def test_the_dial_s_top_is_the_env_s_and_a_look_ahead_under_it_is_refused():
    env = gym.make("VCNC-OmegaTolerance-v2", lookahead=None)
    assert vcnc_baselines.make("mpcc", env).max_override == env.unwrapped.max_override == 1.5
    with pytest.raises(ValueError, match="max_override is the env's dial top"):
        vcnc_baselines.make("mpcc", env, max_override=1.2)
    with pytest.raises(ValueError, match="lookahead="):
        vcnc_baselines.make("mpcc", gym.make("VCNC-OmegaTolerance-v2"))


@pytest.mark.slow
def test_an_episode_on_the_override_omega_finishes_within_the_input_limit():
    """The whole omega under the override (~7000 control periods, a QP each: a minute or more)."""
    from vcnc_gym.evaluation import run_episode

    env = gym.make("VCNC-OmegaOverride-v1")
    pol = vcnc_baselines.make("mpcc", env, v_max=60.0)
    result = run_episode(pol, env)
    assert result.completed and not result.diverged
    assert result.max_contour_error_um < 50.0
    assert result.cycle_time_s < 3.0 * env.unwrapped.task.reference.t[-1]


@pytest.mark.slow
def test_on_a_slow_path_it_runs_at_its_cap():
    """Purtojo et al.'s circle at 1 mm/s (a hundredth of the omega's feed), in its override version: with the
    progress rewards in proportion to the programmed feed (WEIGHTS_FEED) it runs at its 0.6 mm/s cap, finishing
    the 2 pi mm within 1 % of 2 pi / 0.6 s (with the omega's weights unscaled it crawled at 0.32 mm/s and ran out of
    the time limit), its max contour error within 3 um."""
    from benchmark_script import study_module
    from vcnc_gym.evaluation import run_episode

    override_env = study_module("feed-override", "feed_override").override_env

    env = override_env("VCNC-Circle-v1")
    policy = vcnc_baselines.make("mpcc", env, v_max=0.6)
    assert policy.weights[2] == pytest.approx(10.0 * M.WEIGHTS_FEED / 1.0, rel=1e-6)
    result = run_episode(policy, env)
    assert result.completed
    assert result.cycle_time_s == pytest.approx(2 * np.pi / 0.6, rel=0.01)
    assert result.max_contour_error_um < 3.0


def test_the_progress_cap_is_the_programmed_speed_an_override_can_run():
    """path_table's feed: on the S-curve omega, the running maximum of the programmed speed 1 ms ahead (the cap
    before look-ahead references were handled, bit for bit); on the look-ahead omega, never above the programmed
    speed 1 ms ahead before its final stop (an override cannot run a corner's slow-down faster), and down to the
    corners' 10 mm/s."""
    rows = {}
    for env_id in ("VCNC-Omega-v1", "VCNC-OmegaLookahead-v1"):
        u = gym.make(env_id).unwrapped
        s, dt = u.task.reference_arrays.samples, u.task.dt
        speed = np.hypot(s[:, sk.REF_VELOCITY], s[:, sk.REF_VELOCITY + 1])
        lead = int(round(1e-3 / dt))
        ahead = speed[np.minimum(np.arange(speed.size) + lead, speed.size - 1)]
        keep = np.concatenate([[True], np.diff(s[:, sk.REF_ARC]) > 0])
        rows[env_id] = (M.path_table(s, dt).feed, ahead[keep])
    feed, ahead = rows["VCNC-Omega-v1"]
    np.testing.assert_array_equal(feed, np.maximum.accumulate(ahead))
    feed, ahead = rows["VCNC-OmegaLookahead-v1"]
    before_stop = np.arange(feed.size) < np.flatnonzero(np.diff(ahead) > 0)[-1]
    assert np.all(feed[before_stop] <= ahead[before_stop] * (1 + 1e-9))
    cruise = np.flatnonzero(feed >= 99.0)[0]  # past the start's acceleration: the corners' slow-downs remain
    assert feed[cruise:][before_stop[cruise:]].min() < 11.0 and feed.max() == pytest.approx(100.0)


@pytest.mark.parametrize("time_constant", [M.DISTURBANCE_TIME, 0.0])
def test_disturbance_observer_finds_an_input_disturbance(override_env, time_constant):
    """The nominal model stepped here with a constant input disturbance the controller does not know (a Coulomb
    level its table misses), the command as the policy forms it (``u_lin + c - d_hat``, c = 0): the estimate
    settles on the disturbance within 1e-6 of it after 10 time constants, as a first-order observer with gain
    T / tau does; with the observer off it stays at 0."""
    pol = vcnc_baselines.make("mpcc", override_env, disturbance_time=time_constant)
    s, mem = pol._slots, np.zeros(pol.state_shape)
    truth = np.array([0.3, -0.2])  # input units
    u_lin = np.array([0.05, -0.04])
    x = [np.zeros(m.n) for m in pol.models]
    steps = int(10 * M.DISTURBANCE_TIME / pol.dt)
    for _ in range(steps):
        y = np.array([m.C @ xj for m, xj in zip(pol.models, x)])
        v = np.array([m.Cv @ xj for m, xj in zip(pol.models, x)])
        pol._estimate(mem, y, v)
        d_hat = mem[s["d"] : s["d"] + 2].copy()
        applied = u_lin - d_hat
        mem[s["u"] : s["u"] + 2] = applied + d_hat  # the policy's record: the command less (c - d_hat)
        mem[s["k"]] += 1
        x = [m.A @ xj + m.B * (applied[j] + truth[j]) for j, (m, xj) in enumerate(zip(pol.models, x))]
    expected = truth * (1.0 - (1.0 - pol.dt / time_constant) ** (steps - 1)) if time_constant else np.zeros(2)
    np.testing.assert_allclose(mem[s["d"] : s["d"] + 2], expected, rtol=1e-6, atol=1e-12)
    if time_constant:
        np.testing.assert_allclose(mem[s["d"] : s["d"] + 2], truth, rtol=1e-3)
