"""The LQ preview servo and the MPC (baselines/predictive) against independent computations: python-control's
discretisation, scipy's and python-control's Riccati solvers on the whole preview system written out here, a second
QP solver (scipy's bounded least squares), and closed loops."""

import control
import gymnasium as gym
import numpy as np
import pytest
from scipy import linalg, optimize

import vcnc_gym  # noqa: F401  (registers the ids)
import vcnc_baselines
from vcnc_baselines.predictive.design import (
    axis_model,
    input_weight_for_bandwidth,
    preview_design,
    closed_loop_bandwidth,
)
from vcnc_baselines.predictive.mpc import condensed_qp, solve_box_qp
from vcnc_gym.plants import get_plant

DT = 1e-4


def _model(delay=0.0, axis=0):
    return axis_model(get_plant("vcnc_feed_drive").linear_model(axis=axis), DT, delay)


def _simulate(model, u):
    x = np.zeros(model.n)
    y = []
    for uk in u:
        y.append(model.C @ x)
        x = model.A @ x + model.B * uk
    return np.array(y)


@pytest.mark.parametrize("periods", [0, 3])
def test_axis_model_is_python_controls_zoh_discretisation(periods):
    tf = get_plant("vcnc_feed_drive").linear_model(axis=1)
    model = _model(periods * DT, axis=1)
    u = np.random.default_rng(0).normal(size=60)
    reference = control.forced_response(control.c2d(tf, DT, "zoh"), U=u).outputs
    delayed = np.concatenate([np.zeros(periods), reference[: u.size - periods]])
    np.testing.assert_allclose(_simulate(model, u), delayed, rtol=1e-9, atol=1e-12 * np.abs(reference).max())
    assert model.delay_periods == periods


def _preview_system_here(model, M):
    """The augmented system of Katayama et al. (1985) with M preview states, written out independently."""
    n = model.n
    size = 1 + n + M
    A = np.zeros((size, size))
    A[0, 0] = 1.0
    A[0, 1 : 1 + n] = -model.C @ model.A
    A[1 : 1 + n, 1 : 1 + n] = model.A
    A[0, 1 + n] = 1.0  # e(k+1) gets Dr(k+1)
    for j in range(M - 1):
        A[1 + n + j, 2 + n + j] = 1.0  # the shift register
    B = np.zeros((size, 1))
    B[0, 0] = -model.C @ model.B
    B[1 : 1 + n, 0] = model.B
    Q = np.zeros((size, size))
    Q[0, 0] = 1.0
    return A, B, Q


@pytest.mark.parametrize("periods", [0, 2])
def test_preview_gains_against_riccati_of_the_whole_augmented_system(periods):
    model = _model(periods * DT)
    rho, M = 3e-6, 40
    design = preview_design(model, rho, preview=M)
    A, B, Q = _preview_system_here(model, M)
    P = linalg.solve_discrete_are(A, B, Q, np.array([[rho]]))
    K = np.linalg.solve(rho + B.T @ P @ B, B.T @ P @ A)[0]
    n1 = 1 + model.n
    scale = np.abs(K).max()
    np.testing.assert_allclose(design.K, K[:n1], rtol=1e-6, atol=1e-9 * scale)
    np.testing.assert_allclose(design.Kr, K[n1:], rtol=1e-6, atol=1e-9 * np.abs(K[n1:]).max())
    np.testing.assert_allclose(design.P, P[:n1, :n1], rtol=1e-6, atol=1e-9 * np.abs(P[:n1, :n1]).max())
    np.testing.assert_allclose(design.Pxw, P[:n1, n1:], rtol=1e-6, atol=1e-9 * np.abs(P[:n1, n1:]).max())
    K_dlqr, _, _ = control.dlqr(A, B, Q, np.array([[rho]]))
    np.testing.assert_allclose(design.Kr, np.asarray(K_dlqr)[0, n1:], rtol=1e-5, atol=1e-8 * np.abs(K[n1:]).max())


def test_bandwidth_rule_and_preview_on_the_nominal_model():
    """The weight puts the loop at the asked bandwidth; on the model itself, the preview removes the lag a
    feedback loop alone leaves on a smooth reference (a 5 Hz sine of 5 mm: 0.2 mm without the preview, 4 nm with
    it)."""
    model = _model()
    rho = input_weight_for_bandwidth(model, 1000.0)
    assert closed_loop_bandwidth(model, rho) == pytest.approx(1000.0, rel=1e-6)
    design = preview_design(model, rho)
    t = np.arange(3000) * DT
    r = 5.0 * np.sin(2 * np.pi * 5.0 * t) * (1 - np.exp(-t / 0.02)) ** 3  # mm, starting at rest

    def track(Kr):
        x = np.zeros(model.n)
        x_prev, u_prev, errors = x.copy(), 0.0, []
        for k in range(t.size):
            e = r[k] - model.C @ x
            window = np.diff(r[np.minimum(np.arange(k, k + Kr.size + 1), t.size - 1)])
            du = -design.K[0] * e - design.K[1:] @ (x - x_prev) - Kr @ window
            u_prev += du
            x_prev, x = x, model.A @ x + model.B * u_prev
            errors.append(e)
        return np.abs(errors[500:2500]).max()  # away from the end, where the reference stops dead

    with_preview, without = track(design.Kr), track(np.zeros(1))
    assert with_preview < 1e-6 * without
    assert without > 0.1  # mm: the feedback alone lags by 0.2 mm


def test_unblocked_unconstrained_mpc_is_the_lq_preview():
    model = _model()
    rho, M, N = 3e-6, 30, 12
    design = preview_design(model, rho, preview=M)
    qp = condensed_qp(model, design, blocks=[1] * N)
    longer = preview_design(model, rho, preview=N + M)
    rng = np.random.default_rng(1)
    for _ in range(3):
        X = rng.normal(size=1 + model.n) * np.array([1e-3, 1e-5, 1e-5])
        u_prev = rng.normal()
        R = rng.normal(size=N + M) * 1e-2
        z = qp.unconstrained(X, u_prev, R)
        du = -longer.K @ X - longer.Kr @ R
        assert z[0] - u_prev == pytest.approx(du, rel=1e-6, abs=1e-9 * abs(du))


def test_mpc_qp_against_a_second_solver():
    """DAQP's solution of the condensed box QP against scipy's bounded-variable least squares on the same
    problem (1/2 z'Hz + f'z = 1/2 |Lz + L^-1 f|^2 + const, H = L L')."""
    model = _model()
    design = preview_design(model, 3e-6)
    qp = condensed_qp(model, design)
    rng = np.random.default_rng(2)
    L = np.linalg.cholesky(qp.H)
    for trial in range(5):
        X = rng.normal(size=1 + model.n) * np.array([2e-2, 1e-4, 1e-4])
        R = rng.normal(size=qp.preview) * 1e-2
        f = qp.linear_term(X, rng.normal(), R)
        free = np.linalg.solve(qp.H, -f)
        bound = 0.3 * np.abs(free).max()
        lower, upper = -bound * np.ones(free.size), bound * np.ones(free.size) * (1.0 + 0.1 * trial)
        z = solve_box_qp(qp.H, f, lower, upper)
        ref = optimize.lsq_linear(L.T, -np.linalg.solve(L, f), bounds=(lower, upper), method="bvls", tol=1e-14).x
        assert np.any(np.isclose(ref, lower) | np.isclose(ref, upper))  # the bounds are active
        np.testing.assert_allclose(z, ref, rtol=1e-6, atol=1e-7 * bound)


def _run_pair(env, name, steps, **params):
    """The same policy's compiled law (float32 observations) and NumPy law (float64) from one trajectory."""
    compiled, numpy_law = vcnc_baselines.make(name, env, **params), vcnc_baselines.make(name, env, **params)
    obs, _ = env.reset(seed=0)
    worst = 0.0
    for k in range(steps):
        a, _ = compiled.predict(obs.astype(np.float32), episode_start=k == 0)
        b, _ = numpy_law.predict(obs.astype(np.float64), episode_start=k == 0)
        worst = max(worst, float(np.abs(a - b).max()))
        obs, *_ = env.step(a)
    return worst


def test_compiled_law_is_the_numpy_law():
    env = gym.make("VCNC-Heart-v1")
    assert _run_pair(env, "lq-preview", 200, input_weight=3e-6) < 1e-5
    # a model whose state the position and velocity do not determine (the rigid body and a 150 Hz mode, a period
    # of command delay): the Kalman estimator's path
    w = 2 * np.pi * 150.0
    mode = control.tf([2 * 0.05 * w, w * w], [1.0, 2 * 0.05 * w, w * w])
    plant = env.unwrapped.plant
    models = [plant.linear_model(axis=j) * mode for j in range(2)]
    assert _run_pair(env, "lq-preview", 100, models=models, delays=(DT, DT), input_weight=1e-5) < 1e-5


def test_bad_arguments_are_refused_by_name():
    env = gym.make("VCNC-Heart-v1")
    with pytest.raises(ValueError, match="models"):
        vcnc_baselines.make("lq-preview", env, models=[control.tf([1.0], [1.0, 0.0])], input_weight=1e-5)
    with pytest.raises(ValueError, match="delay"):
        axis_model(control.tf([1.0], [1.0, 1.0, 0.0]), DT, delay=1.0)
    with pytest.raises(ValueError, match="blocks"):
        vcnc_baselines.make("mpc", env, blocks=(1, 0), input_weight=1e-5)


@pytest.mark.slow
def test_closed_loop_on_the_heart():
    """Nominal heart: both within 2.5x ff-pid's max contour error (1.87 um), the MPC's bound active somewhere."""
    from vcnc_gym.evaluation import run_episode

    figures = {}
    for name in ("ff-pid", "lq-preview", "mpc"):
        env = gym.make("VCNC-Heart-v1")
        policy = vcnc_baselines.make(name, env)
        figures[name] = run_episode(policy, env).max_contour_error_um
        if name == "mpc":
            assert 0 < policy.solves < policy.calls
    assert figures["lq-preview"] < 2.5 * figures["ff-pid"]
    assert figures["mpc"] < 2.5 * figures["ff-pid"]


def test_the_estimator_reads_the_velocity_only_from_an_exact_sensor():
    """Purtojo et al.'s table reads a 1 um encoder (its velocity a difference of counts): position only, through the
    Kalman filter; Jahanpour et al.'s drive reads the exact state: the estimate is the measurement."""
    heart, circle = gym.make("VCNC-Heart-v1"), gym.make("VCNC-Circle-v1")
    exact = vcnc_baselines.make(
        "mpc", heart, input_weight=1e-5, models=[heart.unwrapped.plant.linear_model(axis=j) for j in range(2)]
    )
    assert exact.velocity and exact.axis_models[0].Cv is not None
    L = exact.estimator_gains[0]
    np.testing.assert_allclose(L @ exact.axis_models[0].measurement(), np.eye(2), atol=1e-12)
    quantised = vcnc_baselines.make("lq-preview", circle, input_weight=1.0)
    assert not quantised.velocity and quantised.axis_models[0].Cv is None
    assert quantised.estimator_gains[0].shape == (2, 1) and 0 < np.abs(quantised.estimator_gains[0]).max()


@pytest.fixture(scope="module")
def commissioned_lq():
    """``lq-preview`` on the shop-floor heart's commissioned model (rigid body, the identified mode, one period of
    command delay, a position-only sensor through the Kalman filter)."""
    env = gym.make("VCNC-HeartShop-v1")
    return vcnc_baselines.make("lq-preview", env, model="commissioned")


@pytest.mark.slow
def test_lq_loop_against_python_control(commissioned_lq):
    """The LQ servo's loop and its closed loop's stability (design.loop_response, closed_loop_stable) against the
    same controller and model interconnected by python-control, and the margin rule's weight (margin_weight)
    meeting the rule on python-control's response."""
    from vcnc_baselines.commissioning.design import GAIN_MARGIN, PHASE_MARGIN, margins
    from vcnc_baselines.predictive.design import closed_loop_stable, feedback_controller, loop_response, margin_weight

    policy = commissioned_lq
    assert policy.model == "commissioned"
    model, L, design = policy.axis_models[0], policy.estimator_gains[0], policy.designs[0]
    assert model.n == 5 and model.mode_states == 2 and model.delay_periods == 1  # rigid body, mode, delay
    Ac, Bc, Cc, Dc = feedback_controller(model, design, L)
    C = control.ss(Ac, Bc, Cc[None], Dc[None], DT)
    P = control.ss(model.A, model.B[:, None], model.measurement(), np.zeros((model.measurement().shape[0], 1)), DT)
    omega = np.array([3.0, 30.0, 300.0, 3000.0])
    loop = -(C * P)
    theirs = np.array([complex(np.squeeze(loop(np.exp(1j * w * DT)))) for w in omega])
    np.testing.assert_allclose(loop_response(model, design, L, omega), theirs, rtol=1e-8)
    poles = control.poles(control.feedback(P, C, sign=1))  # u = C y_m: positive feedback
    assert closed_loop_stable(model, design, L) == bool(np.all(np.abs(poles) < 1.0))
    record = policy.records[0]
    assert margin_weight(model, L, record.designs[0].margins.crossover, record.axes[0].mode_frequency) == pytest.approx(
        design.rho
    )
    # the rule's margins, read back from python-control's response at the crossover the grid found (its own
    # stability_margins roots the 13th-order polynomial at dt = 0.1 ms and finds crossings that are not there)
    grid = np.logspace(-1, np.log10(0.999 * np.pi / DT), 4000)
    m = margins(loop_response(model, design, L, grid), grid)
    assert m.meets() and m.phase_deg >= PHASE_MARGIN and m.gain_db >= GAIN_MARGIN
    at = complex(np.squeeze(loop(np.exp(1j * m.crossover * DT))))
    assert abs(at) == pytest.approx(1.0, abs=1e-3)
    assert 180.0 - abs(np.degrees(np.angle(at))) == pytest.approx(m.phase_deg, abs=0.05)


@pytest.mark.slow
def test_record_models_are_the_identified_responses(commissioned_lq):
    from vcnc_baselines.commissioning.identify import model_response
    from vcnc_baselines.predictive.lq_preview import record_models

    record = commissioned_lq.records[0]
    models, delays = record_models(record)
    f = np.array([1.0, 50.0, 150.0, 400.0])
    for tf, a in zip(models, record.axes):
        theirs = model_response((a.mass, a.damping, a.mode_frequency, a.mode_damping, 0.0), f)
        np.testing.assert_allclose(tf(2j * np.pi * f), theirs, rtol=1e-9)
    np.testing.assert_allclose(delays, [a.command_delay for a in record.axes])
    with pytest.raises(ValueError, match="model must be one of"):
        vcnc_baselines.make("lq-preview", gym.make("VCNC-HeartShop-v1"), model="identified")
