"""Tests of Simba et al.'s controllers: contouring FB (eqs. (2)-(7)) and ILC (eqs. (8)-(11)).

Independent references: the analytic solution of the designed error dynamics
e'' + k_D e' + k_P e = 0 on a circle traversed at a varying speed, the plant's
own kernel, the learning law of eq. (11) written again here as a plain loop,
python-control's sampled loop for the convergence analysis, and Table I.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import control
import numpy as np
import pytest

import vcnc_baselines
from vcnc_baselines.coupling.contouring_fb import ContouringFBPolicy, contouring_feedback
from vcnc_baselines.learning.ilc import ILCPolicy, run_trials
from vcnc_gym.envs import ContouringEnv
from vcnc_gym.envs.layout import ObservationLayout
from vcnc_gym.evaluation import run_episode
from vcnc_gym.geometry import NurbsCurve
from vcnc_gym.geometry.corners import polyline
from vcnc_gym.plants import current_feed_drive as cfd

LAYOUT = ObservationLayout()
NOMINAL = cfd.MODEL.nominal()
M, C, FC, KF = (NOMINAL[:, cfd.MODEL.index(n)] for n in ("m", "c", "f_c", "k_f"))
I_MAX = 5.0
K_P, K_D = 70000.0, 240.0


def fake_env(dt=1e-4, parameters=NOMINAL):
    return SimpleNamespace(
        unwrapped=SimpleNamespace(
            layout=LAYOUT, decision_period=dt, nominal_parameters=parameters, plant="current_feed_drive"
        )
    )


def make_obs(x_d=0.0, v_d=0.0, a_d=0.0, e=0.0, v=0.0, preview=0.0):
    obs = np.zeros(LAYOUT.size)
    for name, val in (
        ("reference_position", x_d),
        ("reference_velocity", v_d),
        ("reference_acceleration", a_d),
        ("tracking_error", e),
        ("velocity", v),
        ("preview", preview),
    ):
        obs[LAYOUT.slice(name)] = val
    return obs


def test_gains_are_table_1():
    fb = vcnc_baselines.make("contouring-fb", fake_env())
    np.testing.assert_array_equal(fb.k_p, [70000.0, 70000.0])
    np.testing.assert_array_equal(fb.k_d, [240.0, 240.0])
    ilc = vcnc_baselines.make("ilc", fake_env())
    table_1 = (200, 0.2, 10, 30, 0.005, 1, None)
    assert (ilc.k_pl, ilc.k_il, ilc.k_dl, ilc.alpha, ilc.beta, ilc.q, ilc.q_cutoff) == table_1
    assert vcnc_baselines.make("ilc-q", fake_env()).q_cutoff == 20.0
    np.testing.assert_array_equal(fb.m, [0.088, 0.097])
    np.testing.assert_array_equal(fb.k_f, [235.62, 331.12])


# ------------------------------------------------------------------ feedback linearisation, eq. (5)


def test_linearising_current_gives_the_commanded_acceleration():
    fb = vcnc_baselines.make("contouring-fb", fake_env())
    v_cmd = np.array([1500.0, -2500.0])
    for vel in ([20.0, -35.0], [-3.0, 7.0]):
        i = fb.linearising_current(v_cmd, np.array(vel))
        state = np.zeros((1, 2, 2))
        state[0, :, cfd.S_V] = vel
        h = 1e-9  # the initial slope of the plant's velocity is the commanded acceleration
        cfd.step_feed_drives(state, i[None], NOMINAL[None], h)
        np.testing.assert_allclose((state[0, :, cfd.S_V] - vel) / h, v_cmd, rtol=1e-6)
        np.testing.assert_allclose(fb.applied_acceleration(i, np.array(vel)), v_cmd, rtol=1e-12)
    # beyond the limit the applied acceleration is that of +-i_max
    big = fb.linearising_current(np.array([1e6, -1e6]), np.zeros(2))
    np.testing.assert_allclose(fb.applied_acceleration(big, np.zeros(2)), [5 * KF[0] / M[0], -5 * KF[1] / M[1]])


# ------------------------------------------------------------------ the designed error dynamics, eq. (7)


class _NoFrameTerms(ContouringFBPolicy):
    """Eq. (7) without the theta-dot and theta-double-dot terms: with equal gains, a PD in world coordinates."""

    def _command(self, obs):
        lay = self.layout
        v = (
            lay.reference_acceleration(obs)
            + K_P * lay.tracking_error(obs)
            + K_D * (lay.reference_velocity(obs) - lay.velocity(obs))
        )
        return self.linearising_current(v, lay.velocity(obs))


def _circle_run(policy_class, dt=1e-5, n=3000):
    """A circle of radius 0.5 mm at 30 mm/s + 500 mm/s^2 t on the frictionless nominal plant; returns
    (t, e_l simulated (n, 2), e_l designed (n, 2))."""
    r, s0, acc = 0.5, 30.0, 500.0
    params = cfd.without_friction(NOMINAL, keep_saturation=True)
    pol = policy_class(LAYOUT, dt, params)

    def ref(t):
        s, ds = s0 * t + 0.5 * acc * t * t, s0 + acc * t
        phi = s / r
        cs, sn = math.cos(phi), math.sin(phi)
        tangent = np.array([-sn, cs])
        return (r * np.array([cs, sn]), ds * tangent, acc * tangent - ds * ds / r * np.array([cs, sn]), tangent)

    x_d, v_d, _, tangent = ref(0.0)
    state = np.zeros((1, 2, 2))
    state[0, :, cfd.S_X] = x_d - np.array([0.02, -0.01])
    state[0, :, cfd.S_V] = v_d + np.array([4.0, 3.0])
    e_sim = np.empty((n, 2))
    for k in range(n):
        x_d, v_d, a_d, tangent = ref(k * dt)
        x, v = state[0, :, cfd.S_X], state[0, :, cfd.S_V]
        e_w = x_d - x
        normal = np.array([-tangent[1], tangent[0]])
        e_sim[k] = (tangent @ e_w, normal @ e_w)
        if k == 0:
            theta_dot = s0 / r
            e_w_dot = v_d - v
            xi_e = np.array([e_w[1], -e_w[0]])
            de0 = np.array([tangent @ (e_w_dot + theta_dot * xi_e), normal @ (e_w_dot + theta_dot * xi_e)])
        obs = make_obs(x_d, v_d, a_d, e_w, v, preview=np.tile(x_d - x, 3))
        action, _ = pol.predict(obs, episode_start=k == 0)
        cfd.step_feed_drives(state, (action.astype(np.float64) * I_MAX)[None], params[None], dt)
    t = dt * np.arange(n)
    wn, zeta = math.sqrt(K_P), K_D / (2 * math.sqrt(K_P))
    wd = wn * math.sqrt(1 - zeta**2)
    e0 = e_sim[0]
    designed = np.exp(-zeta * wn * t)[:, None] * (
        np.cos(wd * t)[:, None] * e0 + np.sin(wd * t)[:, None] * (de0 + zeta * wn * e0) / wd
    )
    return t, e_sim, designed


def test_tangential_and_normal_errors_follow_the_designed_second_order_dynamics():
    """On the nominal linear plant, eq. (7) makes e_t and e_n two decoupled e'' + k_D e' + k_P e = 0."""
    _, e_sim, designed = _circle_run(ContouringFBPolicy)
    scale = np.max(np.abs(designed))
    assert np.max(np.abs(e_sim - designed)) < 0.01 * scale
    # without the frame terms (theta' = 100 rad/s here) the errors leave the designed response
    _, e_naive, _ = _circle_run(_NoFrameTerms)
    assert np.max(np.abs(e_naive - designed)) > 0.1 * scale


def test_path_angle_from_the_observation():
    fb = vcnc_baselines.make("contouring-fb", fake_env(dt=1e-3))
    memory = np.zeros((1, 3))

    def frame(obs):
        out, frame = np.empty((1, 2)), np.empty((1, 3))
        contouring_feedback(obs[None], fb._offsets, memory, fb.k_p, fb.k_d, 1e-3, out, frame)
        return tuple(frame[0])

    # at rest at the start: the preview chord x_d(t + p) - x_d(t) = preview - tracking error gives the direction
    assert frame(make_obs(e=[0.001, 0.0], preview=np.tile([0.001, 0.002], 3))) == pytest.approx((math.pi / 2, 0, 0))
    # on a circle of radius 2 mm at 10 mm/s: theta' = 5 rad/s; one period later 6 rad/s
    assert frame(make_obs(v_d=[0.0, 10.0], a_d=[-50.0, 0.0])) == pytest.approx((math.pi / 2, 5.0, 5.0 / 1e-3))
    assert frame(make_obs(v_d=[-10.0, 0.0], a_d=[0.0, -60.0])) == pytest.approx((math.pi, 6.0, 1.0 / 1e-3))
    # the reference stops at the end: theta is kept, its rate is 0
    assert frame(make_obs()) == pytest.approx((math.pi, 0.0, -6.0 / 1e-3))


def test_stuck_axis_error_stays_within_the_coulomb_dead_zone():
    """Along a y-parallel segment the x drive stands still: with sgn(0) = 0 in eq. (5) it stays stuck
    while m k_P |e_x| <= f_c, so the contour error there is at most f_c / (m k_P) = 7.8 um."""
    env = ContouringEnv(contour=polyline([(0, 0), (10, 0), (10, 20)]), plant="current_feed_drive", feedrate=50)
    out = run_episode(vcnc_baselines.make("contouring-fb", env), env)
    assert not out.diverged and out.max_contour_error_um < 200.0
    on_segment = (out.reference_position[:, 1] > 10.0) & (out.reference_position[:, 1] < 19.0)
    bound = FC[0] / (M[0] * K_P)
    assert np.max(np.abs(out.position[on_segment, 0] - 10.0)) <= bound * (1 + 1e-6)
    assert np.max(out.contour_error[on_segment]) <= bound * (1 + 1e-6)


# ------------------------------------------------------------------ ILC, eqs. (8)-(11)


def _sequence(n, seed):
    """Observations of a table near a straight reference along 30 degrees, small random errors."""
    rng = np.random.default_rng(seed)
    direction = np.array([math.cos(math.pi / 6), math.sin(math.pi / 6)])
    return [
        make_obs(
            x_d=direction * 0.05 * k,
            v_d=direction * 50.0,
            a_d=direction * 100.0,
            e=rng.normal(0, 0.004, 2),
            v=direction * 50.0 + rng.normal(0, 0.5, 2),
        )
        for k in range(n)
    ]


def test_trial_1_is_the_contouring_controller():
    seq = _sequence(60, 0)
    fb = vcnc_baselines.make("contouring-fb", fake_env())
    ilc = vcnc_baselines.make("ilc", fake_env())
    for k, obs in enumerate(seq):
        np.testing.assert_array_equal(
            ilc.predict(obs, episode_start=k == 0)[0], fb.predict(obs, episode_start=k == 0)[0]
        )


def _learned_input(seq, dt, fb):
    """Q[w_1 + L e_vn,1] of eqs. (9)-(11), Table I, written as a plain loop (q = 1)."""
    w, e = [], []
    for k, obs in enumerate(seq):
        i = fb.predict(obs, episode_start=k == 0)[0].astype(np.float64) * I_MAX
        vel = LAYOUT.velocity(obs)
        w.append((KF * i - C * vel - FC * np.sign(vel)) / M - LAYOUT.reference_acceleration(obs))
        t = LAYOUT.reference_velocity(obs) / np.linalg.norm(LAYOUT.reference_velocity(obs))
        n = np.array([-t[1], t[0]])
        e.append(n * (n @ LAYOUT.tracking_error(obs)))
    out = []
    total = np.zeros(2)
    for k in range(len(seq)):
        prev = e[k - 1] if k else e[0]
        law = np.zeros(2)
        for a in range(2):
            psi = 1 - min(1.0, max(-1.0, e[k][a] / 0.005)) / 30
            law[a] = psi * (200 * e[k][a] + 0.2 * total[a] * dt + 10 * (e[k][a] - prev[a]) / dt)
        total += e[k]
        out.append(w[k] + law)
    return np.array(out)


def test_second_trial_adds_the_learning_law_of_eq_11():
    dt = 1e-4
    seq = _sequence(80, 1)
    ilc = vcnc_baselines.make("ilc", fake_env(dt))
    fb = vcnc_baselines.make("contouring-fb", fake_env(dt))
    for k, obs in enumerate(seq):
        ilc.predict(obs, episode_start=k == 0)
    expected = _learned_input(seq, dt, vcnc_baselines.make("contouring-fb", fake_env(dt)))
    assert ilc.trials_done.tolist() == [0]
    for k, obs in enumerate(seq):
        a2 = ilc.predict(obs, episode_start=k == 0)[0].astype(np.float64)
        a1 = fb.predict(obs, episode_start=k == 0)[0].astype(np.float64)
        learned = (a2 - a1) * I_MAX * KF / M  # eq. (5): the extra current is m / k_f times the learned input
        np.testing.assert_allclose(learned, expected[k], rtol=2e-4, atol=2e-2)
    assert ilc.trials_done.tolist() == [1]
    assert np.max(np.abs(expected)) > 100.0  # the learned input is not negligible: the test can fail


def test_learning_survives_episode_start_and_reset_learning_forgets():
    seq = _sequence(40, 2)
    ilc = vcnc_baselines.make("ilc", fake_env())
    fb = vcnc_baselines.make("contouring-fb", fake_env())
    first = [ilc.predict(o, episode_start=k == 0)[0] for k, o in enumerate(seq)]
    second = [ilc.predict(o, episode_start=k == 0)[0] for k, o in enumerate(seq)]
    assert not np.array_equal(np.array(first), np.array(second))
    assert ilc.learns_across_episodes and not getattr(fb, "learns_across_episodes", False)  # vcnc-bench --trials
    ilc.reset_learning()
    again = [ilc.predict(o, episode_start=k == 0)[0] for k, o in enumerate(seq)]
    plain = [fb.predict(o, episode_start=k == 0)[0] for k, o in enumerate(seq)]
    np.testing.assert_array_equal(np.array(again), np.array(plain))
    np.testing.assert_array_equal(np.array(again), np.array(first))


def test_batched_trials_are_per_env():
    """Two envs whose episodes start at different calls learn like two separate policies."""
    seqs = [_sequence(30, 3), _sequence(30, 4)]
    batch = vcnc_baselines.make("ilc", fake_env())
    singles = [vcnc_baselines.make("ilc", fake_env()) for _ in range(2)]
    # env 0 runs episodes of 30 calls, env 1 of 20 (its episodes restart at calls 20 and 40)
    k1 = 0
    for call in range(60):
        k0 = call % 30
        obs = np.stack([seqs[0][k0], seqs[1][k1]])
        start = np.array([k0 == 0, k1 == 0])
        a, _ = batch.predict(obs, episode_start=start)
        for i, (pol, k) in enumerate(zip(singles, (k0, k1))):
            np.testing.assert_array_equal(a[i], pol.predict(obs[i], episode_start=start[i])[0])
        k1 = (k1 + 1) % 20
    assert batch.trials_done.tolist() == [1, 2]


def test_calls_after_an_ended_episode_are_not_part_of_the_trial():
    """A batch runs on after env 0's episode ended (vcnc_bench.robust): what env 0 learns is what a policy
    that saw only its episode learns."""
    seqs = [_sequence(30, 5), _sequence(30, 6)]
    batch = vcnc_baselines.make("ilc", fake_env())
    single = vcnc_baselines.make("ilc", fake_env())
    for trial in range(2):
        for k in range(30):
            obs = np.stack([seqs[0][min(k, 19)], seqs[1][k]])  # env 0's episode is 20 calls long
            a, _ = batch.predict(obs, episode_start=k == 0)
            if k < 20:
                np.testing.assert_array_equal(a[0], single.predict(obs[0], episode_start=k == 0)[0])
            if k == 19:
                batch.end_episodes(np.array([True, False]))
    batch.predict(np.stack([seqs[0][0], seqs[1][0]]), episode_start=True)
    single.predict(seqs[0][0], episode_start=True)
    assert batch.trials_done.tolist() == [2, 2] and single.trials_done.tolist() == [2]
    np.testing.assert_array_equal(batch._learned_len, [20, 30])
    np.testing.assert_array_equal(batch._learned[0, :20], single._learned[0, :20])


def test_learning_gain_against_python_control():
    """S_i of the sampled eq. (7) loop from python-control; Table I's q = 1 grows content above 38 Hz,
    the 20 Hz low-pass of ``ilc-q`` makes every frequency converge."""
    dt = 1e-4
    f = np.logspace(-1, np.log10(0.49 / dt), 3000)
    ilc = vcnc_baselines.make("ilc", fake_env(dt), k_pl=0.0, k_il=0.0, k_dl=0.0)
    loop = control.ss([[1, dt], [0, 1]], [[dt * dt / 2], [dt]], [[K_P, K_D]], 0, dt)
    s_i = np.abs(1.0 / (1.0 + np.squeeze(loop(np.exp(2j * np.pi * f * dt)))))
    np.testing.assert_allclose(ilc.learning_gain(f), s_i, rtol=1e-6)
    g = vcnc_baselines.make("ilc", fake_env(dt)).learning_gain(f)
    assert 1.2 < g.max() < 1.3 and 30 < f[np.argmax(g > 1)] < 40
    assert vcnc_baselines.make("ilc-q", fake_env(dt)).learning_gain(f).max() < 0.15


@pytest.fixture(scope="module")
def corner_env():
    # 10 mm legs with a 90- and a 60-degree corner, at 50 mm/s
    return ContouringEnv(
        contour=polyline([(0, 0), (10, 0), (10, 10), (10 - 10 * math.cos(math.radians(30)), 5)]),
        plant="current_feed_drive",
        feedrate=50,
    )


def test_ilc_q_error_falls_over_trials_on_the_nominal_plant(corner_env):
    res = run_trials(vcnc_baselines.make("ilc-q", corner_env), corner_env, 4)
    mx = [r.max_contour_error_um for r in res]
    rms = [r.rms_contour_error_um for r in res]
    assert not any(r.diverged for r in res)
    assert mx[-1] < 0.9 * mx[0] and rms[-1] < 0.9 * rms[0]
    # after the first learning step the trials settle: no growth (friction events move the peak by ~3 %)
    assert max(mx[2:]) < 1.05 * mx[1] and max(rms[2:]) < 1.05 * rms[1]


def test_ilc_removes_a_model_error_in_one_trial():
    """Table I's ILC (q = 1) on a smooth contour and a plant 10 % heavier and 10 % weaker than the
    nominal model (friction-free): the feedforward error is learned at once."""
    r2 = math.sqrt(0.5)
    circle = NurbsCurve(
        5 * np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]]),
        [1, r2, 1, r2, 1, r2, 1, r2, 1],
        [0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 4],
        2,
    )
    nominal = cfd.without_friction(NOMINAL, keep_saturation=True)
    plant = nominal.copy()
    plant[:, cfd.IDX_M] *= 1.1
    plant[:, cfd.IDX_K_F] *= 0.9
    env = ContouringEnv(contour=circle, plant="current_feed_drive", feedrate=50, parameters=plant)
    res = run_trials(ILCPolicy(env.layout, env.decision_period, nominal), env, 3)
    rms = [r.rms_contour_error_um for r in res]
    assert rms[1] < 0.2 * rms[0] and rms[2] < 0.2 * rms[0]


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    "name, params, match",
    [
        ("contouring-fb", {"k_p": 0.0}, "k_p"),
        ("contouring-fb", {"k_d": (240.0, -1.0)}, "k_d"),
        ("ilc", {"k_pl": -1.0}, "k_pl"),
        ("ilc", {"alpha": 1.0}, "alpha"),
        ("ilc", {"beta": 0.0}, "beta"),
        ("ilc", {"q": 0.0}, "q"),
        ("ilc", {"q": 1.5}, "q"),
        ("ilc", {"q_cutoff": 6000.0}, "Nyquist"),
        ("ilc", {"q_cutoff": "20 Hz"}, "q_cutoff"),
        ("ilc-q", {"q_cutoff": 10.0}, "fixes"),
    ],
)
def test_bad_parameters_raise_value_error(name, params, match):
    with pytest.raises(ValueError, match=match):
        vcnc_baselines.make(name, fake_env(), **params)


def test_wrong_plant_and_trial_count():
    env = SimpleNamespace(
        unwrapped=SimpleNamespace(
            layout=LAYOUT, decision_period=1e-4, plant="vcnc_feed_drive", nominal_parameters=cfd.MODEL.nominal()
        )
    )
    with pytest.raises(ValueError, match="current_feed_drive"):
        vcnc_baselines.make("ilc", env)
    with pytest.raises(ValueError, match="n_trials"):
        run_trials(vcnc_baselines.make("ilc", fake_env()), None, 0)
