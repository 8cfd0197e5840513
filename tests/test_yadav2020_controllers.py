"""Yadav et al.'s controllers (vcnc_baselines.feedback.pi_imc_hinf): transfer functions, discretisation, policies.

Independent references: python-control's continuous frequency responses,
its discrete simulation (``forced_response``) of the c2d system, and the
numbers of Yadav et al. (2020) (section 3.2, eqs. (17)-(19), (21)-(23), (28)-(29)).
"""

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym  # noqa: F401  (registers the ids)

control = pytest.importorskip("control")
vcnc_baselines = pytest.importorskip("vcnc_baselines")
from vcnc_baselines.feedback import pi_imc_hinf as ctl  # noqa: E402

NAMES = ctl.controller_names()


@pytest.fixture(scope="module")
def env():
    e = gym.make("VCNC-Step-v0")
    yield e
    e.close()


def test_printed_controllers():
    assert NAMES == ["pi", "imc", "hinf", "hinf-reduced"]
    pi = ctl.controller_tf("pi", unit="m")
    assert complex(pi(1j)) == pytest.approx(38.33 + 45.65 / 1j)
    assert complex(ctl.controller_tf("hinf-reduced", unit="m")(0)) == pytest.approx(20.97 / 5.5)
    assert complex(ctl.controller_tf("imc", unit="m")(0)) == pytest.approx(1.0)
    # V/mm is V/m over 1000
    for name in NAMES:
        w = 1.3j
        assert complex(ctl.controller_tf(name)(w)) == pytest.approx(
            complex(ctl.controller_tf(name, unit="m")(w)) / 1000
        )


def test_imc_is_eq_23_from_eqs_21_22():
    """C = Q / (1 - G Q), Q = G^-1 / (s + 1)^2 on eq. (2): (s + 9.7) / (4.85 s + 9.7), eq. (23) to its 2 digits."""
    derived = ctl.imc_controller(mu=1.0, lam=2)
    num, den = derived.num[0][0], derived.den[0][0]
    num, den = num / den[0], den / den[0]
    np.testing.assert_allclose(den, [1.0, 2.0], rtol=1e-12)
    np.testing.assert_allclose(num, [1 / 4.85, 2.0], rtol=1e-12)
    assert num[0] == pytest.approx(0.21, abs=0.005)
    # the loop with the derived C is (s + 1)^-2: the pole-zero cancellation of IMC, checked by python-control
    G = control.tf([4.85], [1.0, 9.7, 0.0])
    T = control.minreal(control.feedback(G * derived, 1), verbose=False)
    np.testing.assert_allclose(np.sort(T.poles().real), [-1.0, -1.0], atol=1e-5)
    with pytest.raises(ValueError, match="lam"):
        ctl.imc_controller(lam=1)
    with pytest.raises(ValueError, match="mu"):
        ctl.imc_controller(mu=0.0)


def test_robust_pi_design_of_section_3_2():
    kp, ki = ctl.robust_pi_gains(ratio_digits=2)  # K_P = 0.84 K_I as the paper rounds eq. (18)
    assert kp == pytest.approx(38.33, rel=2e-4) and ki == pytest.approx(45.65, rel=1e-3)
    kp_exact, ki_exact = ctl.robust_pi_gains()
    # the margins the design asked for hold on Kharitonov's p3 by eqs. (11) and (15)
    assert 20 * np.log10(7.5 * 3 * kp_exact / (6 * ki_exact)) == pytest.approx(10.0)
    pm = 90 - np.degrees(np.arctan(np.sqrt(7.5**3 * 6 * ki_exact) / (7.5 * 3 * kp_exact - 6 * ki_exact)))
    assert pm == pytest.approx(60.0)


def test_unknown_controller():
    with pytest.raises(
        ValueError,
        match=r"unknown controller of Yadav et al\. \(2020\) 'lqr'; "
        r"known controllers are .*'pi', 'imc', 'hinf', 'hinf-reduced'",
    ):
        ctl.controller_tf("lqr")
    with pytest.raises(ValueError, match="unit"):
        ctl.controller_tf("pi", unit="in")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_discrete_frequency_response_below_nyquist(name, dt):
    """Tustin: C_d(e^{jwT}) = C(j (2/T) tan(wT/2)) exactly, and close to C(jw) well below Nyquist."""
    C = ctl.controller_tf(name)
    Cd = ctl_policy(name, dt).discrete
    nyquist = np.pi / dt
    w = np.logspace(-2, np.log10(0.9 * nyquist), 200)
    zd = control.frequency_response(Cd, w)
    discrete = zd.magnitude * np.exp(1j * zd.phase)
    warped = np.squeeze(C(1j * (2 / dt) * np.tan(w * dt / 2)))
    np.testing.assert_allclose(discrete, warped, rtol=1e-7)
    low = w < 0.1 * nyquist  # warping (wT)^2 / 12 < 1 % there
    continuous = np.squeeze(C(1j * w))
    assert np.max(np.abs(discrete[low] / continuous[low] - 1)) < 0.02


def ctl_policy(name, dt):
    e = gym.make("VCNC-Step-v0", dt=dt)
    try:
        return vcnc_baselines.make(name, e)
    finally:
        e.close()


@pytest.mark.parametrize("name", NAMES)
def test_policy_runs_the_discretised_controller(env, name):
    """predict(obs) x u_max equals python-control's simulation of C_d on the same error sequence, per axis,
    for a batch of two envs, and episode_start resets the memory."""
    policy = vcnc_baselines.make(name, env)
    layout = env.unwrapped.layout
    rng = np.random.default_rng(3)
    errors = rng.uniform(-0.02, 0.02, size=(40, 2, 2))  # (time, env, axis) mm: small, no saturation
    obs = np.zeros((2, layout.size), dtype=np.float32)
    out = []
    for k in range(errors.shape[0]):
        obs[:, layout.slice("position_error")] = errors[k]
        action, _ = policy.predict(obs, episode_start=np.array([k == 0, k == 0]))
        out.append(action.astype(float) * env.unwrapped.u_max)
    out = np.array(out)
    for e in range(2):
        for axis in range(2):
            e32 = errors[:, e, axis].astype(np.float32).astype(float)
            ref = control.forced_response(policy.discrete, U=e32).outputs
            np.testing.assert_allclose(out[:, e, axis], ref, rtol=1e-5, atol=1e-6 * np.max(np.abs(ref)))
    # a new episode for env 1 only: its memory restarts, env 0's does not
    obs[:, layout.slice("position_error")] = errors[0]
    a_new, _ = policy.predict(obs, episode_start=np.array([False, True]))
    first, _ = vcnc_baselines.make(name, env).predict(obs[1], episode_start=True)
    np.testing.assert_allclose(a_new[1], first, rtol=1e-6)


def test_policies_refuse_other_envs_and_plants():
    contouring = gym.make("VCNC-Omega-v1")
    try:
        with pytest.raises(ValueError, match="designed for the plant"):
            vcnc_baselines.make("pi", contouring)
    finally:
        contouring.close()
    with pytest.raises(ValueError, match="unknown baseline 'lqr'"):
        vcnc_baselines.make("lqr", gym.make("VCNC-Step-v0"))
    step_env = gym.make("VCNC-Step-v0")
    with pytest.raises(ValueError, match="unknown parameter"):
        vcnc_baselines.make("pi", step_env, gain=2.0)
    # the plant carries a dead time, the policies a plain loop: nothing else is needed from the env
    assert {"pi", "imc", "hinf", "hinf-reduced"} <= set(vcnc_baselines.names())
    step_env.close()
