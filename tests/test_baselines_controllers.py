"""Unit tests of the classical baselines (Jahanpour et al. (2014)): QFT, sliding mode, fuzzy.

Each controller is checked against something independent of this package:
python-control and scipy for the linear filters, scikit-fuzzy for the fuzzy
inference, a simulated double integrator for the sliding-mode law.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import control
import numpy as np
import pytest
import scipy.signal as ss
from hypothesis import given, settings
from hypothesis import strategies as st

import vcnc_baselines
from vcnc_baselines.feedback import fuzzy as fz
from vcnc_baselines.feedback import qft
from vcnc_baselines.feedback.smc import SlidingModePolicy
from vcnc_gym.envs.layout import ObservationLayout
from vcnc_gym.plants import vcnc_feed_drive as plant

DT = 1e-4
LAYOUT = ObservationLayout()


def fake_env(dt=DT, parameters=None):
    """What the baselines read from ``env.unwrapped``, without building a contour."""
    return SimpleNamespace(
        unwrapped=SimpleNamespace(
            layout=LAYOUT,
            dt=dt,
            action_repeat=1,
            decision_period=dt,
            nominal_parameters=plant.nominal_parameters() if parameters is None else parameters,
        )
    )


def make_obs(n=None, *, e=0.0, v_ref=0.0, a_ref=0.0, v=0.0, x_ref=0.0):
    """Observations (float32) with the given fields, per axis (scalars or (..., 2))."""
    shape = (LAYOUT.size,) if n is None else tuple(np.atleast_1d(n)) + (LAYOUT.size,)
    obs = np.zeros(shape, dtype=np.float32)
    for name, val in (
        ("tracking_error", e),
        ("reference_velocity", v_ref),
        ("reference_acceleration", a_ref),
        ("velocity", v),
        ("reference_position", x_ref),
    ):
        obs[..., LAYOUT.slice(name)] = val
    return obs


# --------------------------------------------------------------------------
# QFT: discretisation of G, F and H
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def qft_policy():
    return vcnc_baselines.make("qft", fake_env())


def _freqs(dt, fraction=0.1, n=200):
    return np.logspace(-1, np.log10(fraction * np.pi / dt), n)


@pytest.mark.parametrize("which", ["G", "F", "H"])
def test_qft_discrete_response_matches_continuous_below_nyquist(qft_policy, which):
    sys_c = getattr(qft_policy, which)
    sys_d = getattr(qft_policy, which + "_d")
    assert sys_d.dt == pytest.approx(DT)
    w = _freqs(DT)
    resp_c = np.array([complex(sys_c(1j * wi)) for wi in w])
    resp_d = np.array([complex(sys_d(np.exp(1j * wi * DT))) for wi in w])
    rel = np.abs(resp_d - resp_c) / np.abs(resp_c)
    # Tustin: relative error of order (omega T)^2 / 12 < 1e-2 up to a tenth of Nyquist
    assert rel.max() < 0.02, rel.max()


@pytest.mark.parametrize("which", ["G", "F", "H"])
def test_qft_discretisation_is_tustin_exactly(qft_policy, which):
    # Tustin maps omega to the warped frequency (2/T) tan(omega T / 2) exactly.
    sys_c = getattr(qft_policy, which)
    sys_d = getattr(qft_policy, which + "_d")
    w = np.logspace(0, np.log10(0.9 * np.pi / DT), 50)
    warped = 2.0 / DT * np.tan(w * DT / 2.0)
    resp_c = np.array([complex(sys_c(1j * wi)) for wi in warped])
    resp_d = np.array([complex(sys_d(np.exp(1j * wi * DT))) for wi in w])
    np.testing.assert_allclose(resp_d, resp_c, rtol=1e-7)


def test_qft_paper_transfer_functions(qft_policy):
    G, F, H = qft_policy.G, qft_policy.F, qft_policy.H
    s = 1j * 37.0
    np.testing.assert_allclose(complex(G(s)), (22.36 * s + 61.21) / (0.0001 * s + 1.326))
    np.testing.assert_allclose(complex(F(s)), 8.72 / (0.001 * s**2 + 0.187 * s + 8.72))
    # H = (F - 1)/s, from python-control's own arithmetic
    H_ref = (F - 1) * control.tf([1], [1, 0])
    for w in (0.3, 30.0, 3e3):
        np.testing.assert_allclose(complex(H(1j * w)), complex(H_ref(1j * w)), rtol=1e-10)
    assert float(np.real(H(0))) == pytest.approx(-0.187 / 8.72)


def test_qft_policy_output_matches_scipy_filters():
    """u = G(H v_r + e) from the numba kernel vs scipy's bilinear + lfilter."""
    pol = vcnc_baselines.make("qft", fake_env())
    rng = np.random.default_rng(0)
    n = 400
    v_r = np.cumsum(rng.normal(0, 1.0, (n, 2)), axis=0)  # mm/s
    e = rng.normal(0, 1e-3, (n, 2))  # mm
    u = np.empty((n, 2))
    pol.reset(n_envs=1)
    for k in range(n):  # the unclipped command in V (the action would saturate at 5 V)
        u[k] = pol._command(make_obs(1, e=e[k], v_ref=v_r[k]))[0]
    # independent route: scipy's bilinear transform of the paper's polynomials
    fs = 1.0 / DT
    gb, ga = ss.bilinear([22.36, 61.21], [0.0001, 1.326], fs=fs)
    hb, ha = ss.bilinear([-0.001, -0.187], [0.001, 0.187, 8.72], fs=fs)
    e32 = make_obs(n, e=e, v_ref=v_r)  # the policy saw float32 values
    e_in, v_in = LAYOUT.tracking_error(e32), LAYOUT.reference_velocity(e32)
    w = ss.lfilter(hb, ha, v_in, axis=0) + e_in
    u_ref = ss.lfilter(gb, ga, w, axis=0)
    np.testing.assert_allclose(u, u_ref, rtol=1e-8, atol=1e-9)


# --------------------------------------------------------------------------
# QFT: robust stability, eq. (11)
# --------------------------------------------------------------------------
@pytest.mark.parametrize("axis", [0, 1])
def test_robust_stability_peak_meets_eq_11(axis):
    peak, w_peak, worst = qft.robust_stability_peak(axis=axis, full_output=True)
    assert 1.0 < peak <= qft.MU
    assert w_peak > 1e3  # a resonance near crossover, not the low-frequency |T| -> 1
    # python-control's own closed loop for the worst plant gives the same value
    num, den = plant.linear_transfer_function_coefficients(worst, axis)
    T = control.feedback(control.tf(num, den) * qft.controller_tf(), 1)
    assert abs(complex(T(1j * w_peak))) == pytest.approx(peak, rel=1e-9)
    # and nothing larger on a fine grid, for every vertex
    w = np.logspace(2, 5, 3000)
    for p in plant.uncertainty_vertices():
        n_, d_ = plant.linear_transfer_function_coefficients(p, axis)
        Tv = control.feedback(control.tf(n_, d_) * qft.controller_tf(), 1)
        mag = np.abs(Tv.frequency_response(w).magnitude).ravel()
        assert mag.max() <= peak * (1 + 1e-9)


def test_robust_stability_peak_detects_a_violation():
    # Twice the controller gain breaks eq. (11): the check can fail.
    assert qft.robust_stability_peak(((44.72, 122.42), (0.0001, 1.326)), axis=0, n_grid=2) > qft.MU


def test_discrete_peak_tends_to_continuous_one():
    cont = qft.robust_stability_peak(axis=0, n_grid=0)
    fine = qft.robust_stability_peak(axis=0, dt=1e-6, n_grid=0)
    coarse = qft.robust_stability_peak(axis=0, dt=1e-4, n_grid=0)
    assert fine == pytest.approx(cont, rel=0.01)
    assert coarse > cont  # the hold and the bilinear warping cost phase


def test_sampled_loop_stable_at_0p1_ms_not_at_1_ms():
    assert qft.sampled_loop_stable(dt=1e-4)
    assert not qft.sampled_loop_stable(dt=1e-3)
    r3 = max(qft.sampled_loop_spectral_radius(axis=a, dt=1e-3) for a in (0, 1))
    r4 = max(qft.sampled_loop_spectral_radius(axis=a, dt=1e-4) for a in (0, 1))
    assert 5.0 < r3 < 20.0  # a pole near |z| = 10
    assert r4 < 1.0


def test_qft_warns_when_decision_period_makes_loop_unstable():
    with pytest.warns(RuntimeWarning, match="unstable"):
        vcnc_baselines.make("qft", fake_env(dt=1e-3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        vcnc_baselines.make("qft", fake_env(dt=1e-4))


# --------------------------------------------------------------------------
# Fuzzy: against scikit-fuzzy
# --------------------------------------------------------------------------
def test_rule_table_is_table_1():
    # Table 1 is the Mac Vicar-Whelan table: label index = clip(i_e + i_de), NL..PL = -3..3
    i = np.arange(7)
    expected = np.clip(i[None, :] + i[:, None] - 3, 0, 6)
    np.testing.assert_array_equal(fz.RULE_TABLE, expected)
    assert fz.RULE_TABLE[0].tolist() == [0, 0, 0, 0, 1, 2, 3]  # row "NL": NL NL NL NL NM NS Z


@pytest.fixture(scope="module")
def skfuzzy_system():
    skf = pytest.importorskip("skfuzzy")
    from skfuzzy import control as ctrl

    x_in = np.linspace(-1.0, 1.0, 601)  # contains every triangle vertex (step 1/300)
    err = ctrl.Antecedent(x_in, "error")
    chg = ctrl.Antecedent(x_in, "change")
    out = ctrl.Consequent(fz.OUTPUT_GRID, "output", defuzzify_method="centroid")
    for k, label in enumerate(fz.LABELS):
        c = fz.CENTRES[k]
        tri = [c - fz.HALF_WIDTH, c, c + fz.HALF_WIDTH]
        err[label] = skf.trimf(x_in, tri)
        chg[label] = skf.trimf(x_in, tri)
        out[label] = skf.trimf(fz.OUTPUT_GRID, tri)
    rules = [
        ctrl.Rule(err[fz.LABELS[i]] & chg[fz.LABELS[j]], out[fz.LABELS[fz.RULE_TABLE[j, i]]])
        for j in range(7)
        for i in range(7)
    ]
    return ctrl.ControlSystemSimulation(ctrl.ControlSystem(rules))


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_fuzzy_inference_matches_skfuzzy(skfuzzy_system):
    pol = vcnc_baselines.make("fuzzy", fake_env())
    E, D, U = pol.scaling.error_scale, pol.scaling.rate_scale, pol.scaling.output_scale
    grid = np.linspace(-1.2, 1.2, 17)  # beyond +-1 as well: both clip to the universe
    ours = pol.surface(grid[:, None] * E * np.ones((1, grid.size)), grid[None, :] * D * np.ones((grid.size, 1)))
    ref = np.empty_like(ours)
    for a, en in enumerate(grid):
        for b, dn in enumerate(grid):
            skfuzzy_system.input["error"] = float(np.clip(en, -1, 1))
            skfuzzy_system.input["change"] = float(np.clip(dn, -1, 1))
            skfuzzy_system.compute()
            ref[a, b] = U * skfuzzy_system.output["output"]
    np.testing.assert_allclose(ours, ref, atol=1e-9 * U)
    assert np.ptp(ref) > 9.0  # the comparison spans the full +-5 V


def test_fuzzy_surface_shape():
    pol = vcnc_baselines.make("fuzzy", fake_env())
    S = pol.scaling
    assert pol.surface(0.0, 0.0) == pytest.approx(0.0, abs=1e-12)
    assert pol.surface(S.error_scale, S.rate_scale) == pytest.approx(S.output_scale)
    assert pol.surface(-10 * S.error_scale, 0.0) == pytest.approx(-S.output_scale)
    e = np.linspace(-2, 2, 81) * S.error_scale
    u = pol.surface(e, 0.0 * e)
    assert np.all(np.diff(u) >= -1e-12)  # monotone in the error
    np.testing.assert_allclose(u, -u[::-1], atol=1e-12)  # odd


# --------------------------------------------------------------------------
# Sliding mode
# --------------------------------------------------------------------------
def test_smc_equivalent_model_from_nominal_plant():
    pol = vcnc_baselines.make("smc", fake_env())
    p = plant.nominal_parameters()
    gain = p[:, plant.IDX_K_T] * p[:, plant.IDX_K_A] * p[:, plant.IDX_R_G]
    np.testing.assert_allclose(pol.m, p[:, plant.IDX_J] / gain)
    np.testing.assert_allclose(pol.c, p[:, plant.IDX_B] / gain)
    # one step by hand from Table 2's numbers: e = 0.01 mm, e_dot = 2 mm/s, a_d = 100 mm/s^2, v_d = 50 mm/s
    obs = make_obs(e=0.01, v_ref=50.0, v=48.0, a_ref=100.0)
    u = pol.predict(obs, episode_start=True)[0] * 5.0
    S = 200 * np.float32(0.01) + 2.0
    expected = pol.m * (100.0 + 200 * 2.0) + pol.c * 50.0 + 0.0 + 0.3 * S
    np.testing.assert_allclose(u, expected, rtol=1e-6)
    np.testing.assert_allclose(pol.disturbance_estimate[0], 30.0 * S * DT, rtol=1e-6)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-500.0, 500.0)), min_size=1, max_size=60))
def test_smc_projection_keeps_estimate_in_bounds(steps):
    pol = SlidingModePolicy(LAYOUT, 1e-2, plant.nominal_parameters(), rho=3000.0)
    lo, hi = np.array([-0.32, -0.54]), np.array([0.43, 0.58])
    for k, (e, ed) in enumerate(steps):
        pol.predict(make_obs(e=e, v_ref=ed), episode_start=k == 0)
        d = pol.disturbance_estimate[0]
        assert np.all(d >= lo) and np.all(d <= hi)


def test_smc_projection_stops_at_the_limits():
    pol = vcnc_baselines.make("smc", fake_env())
    for k in range(2000):
        pol.predict(make_obs(e=(1.0, -1.0)), episode_start=k == 0)
    np.testing.assert_array_equal(pol.disturbance_estimate[0], [0.43, -0.54])


def _simulate_smc(d_true, reference, T=2.0, x0_offset=0.05):
    """Axes m a + c v + d_true = u (exact ZOH), SMC in the loop; returns S, e, d_hat histories."""
    pol = vcnc_baselines.make("smc", fake_env())
    m, c = pol.m, pol.c
    plants = []
    for a in range(2):  # state (x, v), input u - d
        A = np.array([[0.0, 1.0], [0.0, -c[a] / m[a]]])
        B = np.array([[0.0], [1.0 / m[a]]])
        Ad, Bd, *_ = ss.cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), DT, method="zoh")
        plants.append((Ad, Bd))
    n = int(round(T / DT))
    t = np.arange(n) * DT
    xr, vr, ar = reference(t)
    state = np.stack([xr[0] - x0_offset, vr[0]], axis=-1)  # (2 axes, 2)
    hist_S, hist_e, hist_d = [], [], []
    for k in range(n):
        e = xr[k] - state[:, 0]
        obs = make_obs(e=e, v_ref=vr[k], a_ref=ar[k], v=state[:, 1], x_ref=xr[k])
        a, _ = pol.predict(obs, episode_start=k == 0)
        u = a.astype(float) * 5.0
        hist_S.append(pol.sliding_surface(obs))
        hist_e.append(e)
        for ax in range(2):
            Ad, Bd = plants[ax]
            state[ax] = Ad @ state[ax] + Bd[:, 0] * (u[ax] - d_true[ax])
        hist_d.append(pol.disturbance_estimate[0].copy())
    return np.array(hist_S), np.array(hist_e), np.array(hist_d)


def _sine(t):
    w = 2 * np.pi * 1.0
    x = np.stack([10 * np.sin(w * t), 8 * np.cos(w * t)], axis=1)
    v = np.stack([10 * w * np.cos(w * t), -8 * w * np.sin(w * t)], axis=1)
    a = np.stack([-10 * w**2 * np.sin(w * t), -8 * w**2 * np.cos(w * t)], axis=1)
    return x, v, a


def test_smc_surface_converges_and_estimate_finds_disturbance():
    d_true = np.array([0.25, -0.4])  # V, inside [d-, d+]; unknown to the controller
    S, e, d = _simulate_smc(d_true, _sine)
    assert np.abs(S[:10]).max() > 5.0  # starts off the surface (50 um error)
    assert np.abs(S[-2000:]).max() < 0.02 * np.abs(S[:10]).max()
    assert np.abs(e[-2000:]).max() < 1e-4  # below 0.1 um
    np.testing.assert_allclose(d[-1], d_true, rtol=0.02)


def test_smc_disturbance_beyond_limit_leaves_predicted_offset():
    # d_true above d+: the estimate sits at d+ and S settles at (d_true - d+)/K_s.
    d_true = np.array([0.6, -0.7])

    def ramp(t):
        v = np.array([20.0, -20.0])
        return t[:, None] * v, np.broadcast_to(v, (t.size, 2)), np.zeros((t.size, 2))

    S, e, d = _simulate_smc(d_true, ramp, T=1.0, x0_offset=0.0)
    np.testing.assert_array_equal(d[-1], [0.43, -0.54])
    np.testing.assert_allclose(S[-1], (d_true - d[-1]) / 0.3, rtol=0.01)
    np.testing.assert_allclose(e[-1], (d_true - d[-1]) / 0.3 / 200.0, rtol=0.01)


# --------------------------------------------------------------------------
# Registry, validation and the predict contract
# --------------------------------------------------------------------------
def test_names_and_unknown_name():
    assert {"fuzzy", "qft", "qft-g", "smc"} <= set(vcnc_baselines.names())
    assert vcnc_baselines.names() == sorted(vcnc_baselines.names())
    from vcnc_gym.plants import get_plant, plant_names

    for name in vcnc_baselines.names():  # every baseline applies to one of the suite's plants at least
        cls = vcnc_baselines.registry.policy_class(name)
        assert any(cls.designed_for(get_plant(p)) for p in plant_names()), name
    with pytest.raises(ValueError, match="unknown baseline"):
        vcnc_baselines.make("pid", fake_env())
    with pytest.raises(ValueError, match="unknown baseline"):
        vcnc_baselines.make(3, fake_env())


def test_qft_g_variant_is_qft_without_prefilter():
    env = fake_env()
    variant = vcnc_baselines.make("qft-g", env)
    assert isinstance(variant, vcnc_baselines.QFTPolicy)
    np.testing.assert_allclose(variant.F.num[0][0], variant.F.den[0][0])  # F = 1
    assert vcnc_baselines.make("qft", env).F.den[0][0].size == 3  # the paper's second-order F
    with pytest.raises(ValueError, match="fixes"):
        vcnc_baselines.make("qft-g", env, prefilter=((1.0,), (1.0,)))


@pytest.mark.parametrize(
    "name, params",
    [
        ("smc", {"lam": -200.0}),
        ("smc", {"lam": 0.0}),
        ("smc", {"K_s": -0.3}),
        ("smc", {"rho": float("nan")}),
        ("smc", {"rho": float("inf")}),
        ("smc", {"d_minus": "low"}),
        ("smc", {"d_minus": 0.2}),
        ("smc", {"d_plus": (0.4, 0.5, 0.6)}),
        ("smc", {"K_s": True}),
        ("smc", {"gain": 1.0}),
        ("fuzzy", {"error_scale": 0.0}),
        ("fuzzy", {"rate_scale": -1.0}),
        ("fuzzy", {"output_scale": "5 V"}),
        ("fuzzy", {"error_scale": float("nan")}),
        ("qft", {"prefilter": ((-1.0,), (1.0, 0.0, -1.0))}),  # unstable, F(0) = 1
        ("qft", {"prefilter": ((2.0,), (1.0, 1.0))}),  # F(0) = 2
        ("qft", {"prefilter": "F"}),
        ("qft", {"controller": ((1.0, 0.0, 0.0), (1.0, 1.0))}),  # improper
        ("qft", {"controller": ((np.inf, 1.0), (1.0, 1.0))}),
        ("qft", {"controller": ((1.0,), (0.0,))}),
        ("qft", {"method": 5}),
    ],
)
def test_bad_parameters_raise_value_error(name, params):
    with pytest.raises(ValueError):
        vcnc_baselines.make(name, fake_env(), **params)


def test_bad_env_raises_value_error():
    with pytest.raises(ValueError):
        vcnc_baselines.make("smc", SimpleNamespace(unwrapped=SimpleNamespace(layout=LAYOUT)))
    with pytest.raises(ValueError):
        vcnc_baselines.make("smc", fake_env(dt=-1.0))
    with pytest.raises(ValueError):
        vcnc_baselines.make("smc", fake_env(parameters=np.zeros((2, 3))))


def test_parameters_are_constructor_arguments_with_seed_defaults():
    pol = vcnc_baselines.make("smc", fake_env(), lam=(150.0, 180.0))
    np.testing.assert_array_equal(pol.lam, [150.0, 180.0])
    np.testing.assert_array_equal(vcnc_baselines.make("smc", fake_env()).K_s, [0.3, 0.3])
    assert vcnc_baselines.make("fuzzy", fake_env(), error_scale=0.02).scaling.error_scale == 0.02


def _sequence(n_steps, n_envs, seed, scale=1.0):
    """Random observations; scale = 1e-3 keeps every controller below saturation."""
    rng = np.random.default_rng(seed)
    size = (n_steps, n_envs, 2)
    return make_obs(
        (n_steps, n_envs),
        e=rng.normal(0, 5e-3 * scale, size),
        v_ref=rng.normal(0, 10 * scale, size),
        v=rng.normal(0, 10 * scale, size),
        a_ref=rng.normal(0, 1e5 * scale, size),
    )


@pytest.mark.parametrize("name", ["qft", "smc", "fuzzy"])
def test_predict_single_and_batched(name):
    seq = _sequence(30, 3, seed=1)
    batch = vcnc_baselines.make(name, fake_env())
    singles = [vcnc_baselines.make(name, fake_env()) for _ in range(3)]
    for k in range(seq.shape[0]):
        a, state = batch.predict(seq[k], episode_start=np.full(3, k == 0))
        assert a.shape == (3, 2) and a.dtype == np.float32 and state is None
        assert np.all(np.abs(a) <= 1.0)
        for i, pol in enumerate(singles):
            ai, _ = pol.predict(seq[k, i], episode_start=k == 0)
            assert ai.shape == (2,) and ai.dtype == np.float32
            np.testing.assert_array_equal(ai, a[i])


@pytest.mark.parametrize("name", ["qft", "smc"])
def test_episode_start_resets_only_that_env(name):
    seq = _sequence(40, 3, seed=2, scale=1e-3)
    pol = vcnc_baselines.make(name, fake_env())
    for k in range(20):
        pol.predict(seq[k], episode_start=np.full(3, k == 0))
    fresh = vcnc_baselines.make(name, fake_env())
    cont = vcnc_baselines.make(name, fake_env())
    for k in range(20):
        cont.predict(seq[k], episode_start=np.full(3, k == 0))
    differs = False
    for k in range(20, 40):
        a, _ = pol.predict(seq[k], episode_start=np.array([False, k == 20, False]))
        af, _ = fresh.predict(seq[k, 1], episode_start=k == 20)
        ac, _ = cont.predict(seq[k], episode_start=np.zeros(3, bool))
        np.testing.assert_array_equal(a[1], af)  # env 1 restarted from rest
        np.testing.assert_array_equal(a[[0, 2]], ac[[0, 2]])  # the others kept their memory
        differs = differs or not np.array_equal(a[1], ac[1])
        assert np.all(np.abs(a) < 1.0)  # unsaturated: the memory shows in the action
    assert differs  # the reset made a difference


def test_predict_rejects_wrong_shapes():
    pol = vcnc_baselines.make("fuzzy", fake_env())
    with pytest.raises(ValueError):
        pol.predict(np.zeros(5, dtype=np.float32))
    with pytest.raises(ValueError):
        pol.predict(np.zeros((2, LAYOUT.size), dtype=np.float32), episode_start=np.zeros(3, bool))


def test_action_saturates_at_u_max():
    pol = vcnc_baselines.make("fuzzy", fake_env())
    a, _ = pol.predict(make_obs(e=(5.0, -5.0)))
    np.testing.assert_array_equal(a, np.array([1.0, -1.0], dtype=np.float32))
