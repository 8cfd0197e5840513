"""Tests of Jahanpour et al.'s biaxial feed drive (vcnc_gym.plants.vcnc_feed_drive).

Independent references: python-control's ZOH discretisation of eq. (1) for
the linear part, closed-form solutions of J w' = T - B w for friction, the
play operator's definition for backlash, and the numbers of Jahanpour et al. (2014),
section 2c and Table 3, typed in again here.
"""

import math

import numba
import numpy as np
import pytest

from vcnc_gym.plants import exact_zoh
from vcnc_gym.plants import vcnc_feed_drive as fd

control = pytest.importorskip("control")

DT = 1e-4
NSUB = fd.substeps_for(DT)
IX, IY = 0, 1


def simulate(params, voltages, dt=DT, n_substeps=NSUB, x0=None):
    """Run the kernel; return states before each step and after the last.

    params (N, 2, P) or (2, P); voltages (K, N, 2) or (K, 2).
    Returns (K + 1, N, 2, 3).
    """
    params = fd.validate_parameters(params)
    n = params.shape[0]
    v = np.asarray(voltages, dtype=np.float64)
    if v.ndim == 2:
        v = np.broadcast_to(v[:, None, :], (v.shape[0], n, 2))
    v = np.ascontiguousarray(v)
    state = np.empty((n, 2, 3))
    fd.reset_feed_drives(state, np.zeros((n, 2)) if x0 is None else np.asarray(x0, dtype=np.float64))
    out = np.empty((v.shape[0] + 1, n, 2, 3))
    out[0] = state
    for k in range(v.shape[0]):
        fd.step_feed_drives(state, v[k], params, dt, n_substeps)
        out[k + 1] = state
    return out


def k_motor(params, axis):
    return params[axis, fd.IDX_K_T] * params[axis, fd.IDX_K_A]


# ---------------------------------------------------------------- numbers


def test_numbers_match_jahanpour2014():
    p = fd.nominal_parameters()
    d = fd.parameters_to_dict(p)
    # section 2c midpoints
    assert d["r_g"] == pytest.approx((1.4 + 1.73) / 2, rel=1e-15)
    assert d["K_t"] == pytest.approx((0.42 + 0.52) / 2, rel=1e-15)
    assert d["K_a"] == pytest.approx(((5.71 + 7.07) / 2, (6.67 + 8.26) / 2), rel=1e-15)
    assert d["B"] == pytest.approx(((0.014 + 0.026) / 2, (0.02 + 0.037) / 2), rel=1e-15)
    # Table 3
    assert d["J"] == (0.0077736, 0.0098109)
    assert d["u_max"] == (5.0, 5.0)
    assert d["backlash"] == (0.003, 0.003)
    assert d["T_stat_pos"] == (2.6256, 2.7658)
    assert d["T_stat_neg"] == (-1.8672, -2.4520)
    assert d["T_coul_pos"] == (2.1529, 2.5228)
    assert d["T_coul_neg"] == (-1.4730, -2.3887)
    assert fd.PARAMETER_NAMES == (
        "r_g",
        "K_t",
        "K_a",
        "J",
        "B",
        "T_stat_pos",
        "T_stat_neg",
        "T_coul_pos",
        "T_coul_neg",
        "backlash",
        "u_max",
    )
    assert p.shape == (2, len(fd.PARAMETER_NAMES)) and p.dtype == np.float64
    assert fd.parameter_intervals() == {
        "r_g": (1.4, 1.73),
        "K_t": (0.42, 0.52),
        "K_a": ((5.71, 7.07), (6.67, 8.26)),
        "B": ((0.014, 0.026), (0.02, 0.037)),
    }
    fd.validate_parameters(p)


def test_substeps_for():
    assert fd.DEFAULT_SUBSTEP == 1e-5
    assert fd.substeps_for(1e-4) == 10
    assert fd.substeps_for(1e-3) == 100
    assert fd.substeps_for(1.5e-5) == 2
    assert fd.substeps_for(1e-6) == 1
    with pytest.raises(ValueError):
        fd.substeps_for(0.0)


def test_validate_parameters_rejects_bad_input():
    p = fd.nominal_parameters()
    with pytest.raises(ValueError):
        fd.validate_parameters(p[:, :-1])
    bad = p.copy()
    bad[1, fd.IDX_R_G] += 0.01  # r_g is shared by both axes
    with pytest.raises(ValueError):
        fd.validate_parameters(bad)
    bad = p.copy()
    bad[0, fd.IDX_T_STAT_POS] = 1.0  # below Coulomb
    with pytest.raises(ValueError):
        fd.validate_parameters(bad)
    assert fd.validate_parameters(p, n_machines=3).shape == (3, 2, fd.N_PARAMETERS)


# ---------------------------------------------------------------- linear part vs python-control


def _vertices_under_test():
    return [0, 21, 42, 63]  # all-low, two mixed corners, all-high


@pytest.mark.parametrize("vertex", _vertices_under_test())
@pytest.mark.parametrize("signal", ["step", "cosine"])
@pytest.mark.parametrize("n_substeps", [1, NSUB])
def test_linear_part_matches_python_control_zoh(vertex, signal, n_substeps):
    params = fd.without_nonlinearities(fd.uncertainty_vertices()[vertex])
    n_steps = 3000
    t = np.arange(n_steps) * DT
    if signal == "step":
        u = np.stack([np.full(n_steps, 2.0), np.full(n_steps, -3.0)], axis=1)
    else:  # velocity reverses every 25 ms
        u = np.stack([4.0 * np.cos(2 * np.pi * 20 * t), -3.0 * np.cos(2 * np.pi * 33 * t + 0.3)], axis=1)
    traj = simulate(params, u, n_substeps=n_substeps)
    if signal == "cosine":
        for axis in (IX, IY):
            w = traj[:, 0, axis, fd.S_W]
            assert np.count_nonzero(np.diff(np.sign(w[1:])) != 0) >= 4  # crossings exercised
    for axis in (IX, IY):
        num, den = fd.linear_transfer_function_coefficients(params, axis)
        sysd = control.c2d(control.tf(num, den), DT, "zoh")
        resp = control.forced_response(sysd, T=t, U=u[:, axis])
        y_ref = np.asarray(resp.outputs).ravel()
        y = traj[:-1, 0, axis, fd.S_XT]
        assert np.array_equal(traj[:, 0, axis, fd.S_XT], traj[:, 0, axis, fd.S_XM])  # no backlash
        scale = np.max(np.abs(y_ref))
        assert scale > 0.1  # mm: a real motion
        np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-9 * scale)


def test_transfer_function_coefficients():
    p = fd.nominal_parameters()
    num, den = fd.linear_transfer_function_coefficients(p, 1)
    assert num == pytest.approx([1.565 * 0.47 * 7.465], rel=1e-14)
    assert den == pytest.approx([0.0098109, 0.0285, 0.0], rel=1e-14)
    # DC velocity gain r_g K_t K_a / B [mm/s/V]
    g = control.tf(num, den) * control.tf([1, 0], [1])
    assert control.dcgain(control.minreal(g, verbose=False)) == pytest.approx(num[0] / den[1], rel=1e-9)


# ---------------------------------------------------------------- stick-slip friction


def test_below_static_friction_stays_exactly_at_rest():
    p = fd.nominal_parameters()
    u = np.array([0.999 * p[IX, fd.IDX_T_STAT_POS] / k_motor(p, IX), 0.999 * p[IY, fd.IDX_T_STAT_NEG] / k_motor(p, IY)])
    x0 = np.array([[1.25, -7.5]])
    traj = simulate(p, np.tile(u, (500, 1)), x0=x0)
    assert np.array_equal(traj[-1], traj[0])
    assert traj[0, 0, 0, fd.S_XT] == 1.25


def test_just_above_static_friction_moves():
    p = fd.nominal_parameters()
    u = np.array([1.001 * p[IX, fd.IDX_T_STAT_POS] / k_motor(p, IX), 1.001 * p[IY, fd.IDX_T_STAT_NEG] / k_motor(p, IY)])
    traj = simulate(p, np.tile(u, (500, 1)))
    assert traj[1, 0, IX, fd.S_W] > 0 and traj[1, 0, IY, fd.S_W] < 0
    assert traj[-1, 0, IX, fd.S_XT] > 0.01 and traj[-1, 0, IY, fd.S_XT] < -0.01


@pytest.mark.parametrize("axis", [IX, IY])
def test_asymmetric_breakaway(axis):
    p = fd.nominal_parameters()
    t_pos, t_neg = p[axis, fd.IDX_T_STAT_POS], p[axis, fd.IDX_T_STAT_NEG]
    assert abs(t_neg) < t_pos
    torque = 0.5 * (abs(t_neg) + t_pos)  # between the two thresholds
    u_mag = torque / k_motor(p, axis)
    for sign, moves in ((+1.0, False), (-1.0, True)):
        u = np.zeros((300, 2))
        u[:, axis] = sign * u_mag
        traj = simulate(p, u)
        x_t = traj[:, 0, axis, fd.S_XT]
        if moves:
            assert x_t[-1] < -1e-3
        else:
            assert np.all(x_t == 0.0) and np.all(traj[:, 0, axis, fd.S_W] == 0.0)


@pytest.mark.parametrize("vertex", [0, 63])
def test_coulomb_velocity_matches_closed_form(vertex):
    p = fd.uncertainty_vertices()[vertex]
    u = np.array([3.0, -3.0])
    n_steps = 20_000  # 20 s, > 35 mechanical time constants J/B
    dt = 1e-3
    traj = simulate(p, np.tile(u, (n_steps, 1)), dt=dt, n_substeps=fd.substeps_for(dt))
    t = np.arange(n_steps + 1) * dt
    for axis, coul in ((IX, fd.IDX_T_COUL_POS), (IY, fd.IDX_T_COUL_NEG)):
        jj, bb, r_g = p[axis, fd.IDX_J], p[axis, fd.IDX_B], p[axis, fd.IDX_R_G]
        w_inf = (k_motor(p, axis) * u[axis] - p[axis, coul]) / bb
        a = bb / jj
        w_ref = w_inf * -np.expm1(-a * t)
        x_ref = r_g * w_inf * (t + np.expm1(-a * t) / a)
        w = traj[:, 0, axis, fd.S_W]
        np.testing.assert_allclose(w, w_ref, rtol=1e-9, atol=1e-9 * abs(w_inf))
        np.testing.assert_allclose(traj[:, 0, axis, fd.S_XM], x_ref, rtol=1e-9, atol=1e-12)
        assert w[-1] == pytest.approx(w_inf, rel=1e-8)


@pytest.mark.parametrize("w0", [40.0, -25.0])
def test_coasting_stop_is_exact(w0):
    """With u = 0 a moving drive stops at the analytic time and distance and stays stuck."""
    p = fd.nominal_parameters()
    jj, bb, r_g = p[IX, fd.IDX_J], p[IX, fd.IDX_B], p[IX, fd.IDX_R_G]
    tc = p[IX, fd.IDX_T_COUL_POS] if w0 > 0 else p[IX, fd.IDX_T_COUL_NEG]
    t_stop = jj / bb * math.log1p(bb * w0 / tc)
    dist = jj / bb * (w0 - tc / bb * math.log1p(bb * w0 / tc)) * r_g
    params = fd.validate_parameters(p)
    state = np.zeros((1, 2, 3))
    state[0, IX, fd.S_W] = w0
    n_steps = int(t_stop / DT) + 50
    ws = np.empty(n_steps + 1)
    ws[0] = w0
    for k in range(n_steps):
        fd.step_feed_drives(state, np.zeros((1, 2)), params, DT, NSUB)
        ws[k + 1] = state[0, IX, fd.S_W]
    t = np.arange(n_steps + 1) * DT
    moving = t < t_stop
    assert np.all(ws[moving] * np.sign(w0) > 0) and np.all(ws[~moving] == 0.0)
    w_ref = (w0 + tc / bb) * np.exp(-bb / jj * t[moving]) - tc / bb
    np.testing.assert_allclose(ws[moving], w_ref, rtol=1e-9, atol=1e-9 * abs(w0))
    assert state[0, IX, fd.S_XM] == pytest.approx(dist, rel=1e-12)


@pytest.mark.parametrize("n_substeps", [1, 7])
def test_reversal_inside_one_period_is_exact(n_substeps):
    """Stop, break away backwards and backlash within one control period.

    Closed forms: stop time and distance under T = T_m - T_coul+, then motion
    from rest under T_m - T_coul- for the rest of the period; the table is
    left where the motor turned (minus D_b / 2) while the motor is in the gap.
    """
    p = fd.nominal_parameters()
    jj, bb, r_g = p[IX, fd.IDX_J], p[IX, fd.IDX_B], p[IX, fd.IDX_R_G]
    d_b = p[IX, fd.IDX_BACKLASH]
    dt, w0, u = 1e-3, 1.5, -4.0
    t_m = k_motor(p, IX) * u
    t1 = t_m - p[IX, fd.IDX_T_COUL_POS]  # braking torque while w > 0
    t2 = t_m - p[IX, fd.IDX_T_COUL_NEG]  # after break-away in - direction
    assert t_m < p[IX, fd.IDX_T_STAT_NEG]
    t_stop = jj / bb * math.log1p(bb * w0 / -t1)
    x_stop = r_g * jj / bb * (w0 + t1 / bb * math.log1p(bb * w0 / -t1))
    rest = dt - t_stop
    assert 0.1 * dt < t_stop < 0.9 * dt
    a = bb / jj
    x_end = x_stop + r_g * t2 / bb * (rest + math.expm1(-a * rest) / a)
    w_end = t2 / bb * -math.expm1(-a * rest)
    assert x_stop - x_end < d_b  # motor still inside the gap at the end
    state = np.zeros((1, 2, 3))
    state[0, IX] = (0.0, w0, -d_b / 2)  # gap closed, pushing forward
    fd.step_feed_drives(state, np.array([[u, 0.0]]), fd.validate_parameters(p), dt, n_substeps)
    x_m, w, x_t = state[0, IX]
    assert x_m == pytest.approx(x_end, rel=1e-12, abs=1e-15)
    assert w == pytest.approx(w_end, rel=1e-12)
    assert x_t == pytest.approx(x_stop - d_b / 2, rel=0, abs=1e-15)


def test_series_helpers_against_decimal():
    from decimal import Decimal, getcontext

    getcontext().prec = 50
    for z in [-1e-9, -3e-6, -2.6e-4, -0.05, -0.0999, -0.1001, -0.5, -3.0, 0.07, 2.0]:
        d = Decimal(z)
        phi1 = (d.exp() - 1) / d
        phi2 = (d.exp() - 1 - d) / (d * d)
        assert exact_zoh.phi1(z) == pytest.approx(float(phi1), rel=1e-14)
        assert exact_zoh.phi2(z) == pytest.approx(float(phi2), rel=1e-14)
    for x in [1e-12, 1e-7, 3e-4, 0.0099, 0.0101, 0.3, 5.0, 1e3]:
        d = Decimal(x)
        ln = (1 + d).ln()
        assert exact_zoh.log1p_ratio(x) == pytest.approx(float(ln / d), rel=1e-14)
        assert exact_zoh.log1p_rest(x) == pytest.approx(float((d - ln) / (d * d)), rel=1e-13)
    assert exact_zoh.phi1(0.0) == 1.0 and exact_zoh.phi2(0.0) == 0.5
    assert exact_zoh.log1p_ratio(0.0) == 1.0 and exact_zoh.log1p_rest(0.0) == 0.5


# ---------------------------------------------------------------- backlash


def test_backlash_play_after_reversal():
    p = fd.nominal_parameters()
    d_b = p[IX, fd.IDX_BACKLASH]
    n_half = 400
    u = np.zeros((2 * n_half, 2))
    u[:n_half, IX] = 4.0
    u[n_half:, IX] = -4.0
    traj = simulate(p, u)
    x_m = traj[:, 0, IX, fd.S_XM]
    x_t = traj[:, 0, IX, fd.S_XT]
    w = traj[:, 0, IX, fd.S_W]
    k_peak = int(np.argmax(x_m))
    assert n_half <= k_peak < 2 * n_half - 10
    # the turning point lies between samples; the held table position tells it
    x_turn = x_t[k_peak + 1] + d_b / 2
    assert x_m[k_peak] <= x_turn + 1e-12
    assert x_turn - x_m[k_peak] < 2e-5  # less than one step's travel near standstill
    # forward: steady offset D_b / 2, table lagging the motor
    fwd = (np.arange(len(x_m)) < k_peak) & (x_m > d_b)
    assert fwd.sum() > 50
    np.testing.assert_allclose(x_m[fwd] - x_t[fwd], d_b / 2, rtol=0, atol=1e-12)
    # after the reversal the table stays until the motor has travelled D_b
    after = np.arange(len(x_m)) > k_peak
    in_gap = after & (x_m > x_turn - d_b)
    pushed = after & (x_m < x_turn - d_b)
    assert in_gap.sum() >= 3 and pushed.sum() > 50
    assert np.all(x_t[in_gap] == x_t[k_peak + 1])
    assert np.all(x_t[in_gap] >= x_t[k_peak])
    np.testing.assert_allclose(x_t[pushed] - x_m[pushed], d_b / 2, rtol=0, atol=1e-12)
    # table velocity helper: zero in the gap, r_g w when pushed
    r_g = p[IX, fd.IDX_R_G]
    v_t = np.array([fd.table_velocity(x_m[k], w[k], x_t[k], r_g, d_b) for k in range(len(x_m))])
    assert np.all(v_t[in_gap] == 0.0)
    assert np.any(w[in_gap] != 0.0)  # the motor does move inside the gap
    np.testing.assert_array_equal(v_t[pushed], r_g * w[pushed])
    np.testing.assert_array_equal(v_t[fwd], r_g * w[fwd])


def test_table_velocities_batch_and_zero_backlash():
    p = fd.validate_parameters(fd.nominal_parameters(), n_machines=2).copy()
    p[1, :, fd.IDX_BACKLASH] = 0.0
    state = np.zeros((2, 2, 3))
    fd.reset_feed_drives(state, np.zeros((2, 2)))
    fd.step_feed_drives(state, np.full((2, 2), 4.0), p, DT, NSUB)
    out = np.empty((2, 2))
    fd.table_velocities(state, p, out)
    assert np.all(state[:, :, fd.S_W] > 0)
    np.testing.assert_array_equal(out[0], 0.0)  # still inside the gap after 0.1 ms
    np.testing.assert_array_equal(out[1], p[1, :, fd.IDX_R_G] * state[1, :, fd.S_W])


# ---------------------------------------------------------------- saturation


def test_saturation():
    p = fd.nominal_parameters()
    t = np.arange(1500) * DT
    s = np.sign(np.sin(2 * np.pi * 15 * t))
    sat = simulate(p, np.stack([5.0 * s, -5.0 * s], axis=1))
    big = simulate(p, np.stack([100.0 * s, -100.0 * s], axis=1))
    np.testing.assert_array_equal(big, sat)
    smaller = simulate(p, np.stack([4.9 * s, -4.9 * s], axis=1))
    assert not np.array_equal(smaller, sat)


# ---------------------------------------------------------------- substep convergence


@pytest.mark.parametrize("vertex", [0, 63])
def test_substep_convergence(vertex):
    p = fd.uncertainty_vertices()[vertex]
    t = np.arange(4000) * DT
    # reversing, partly below break-away, with stick phases at each reversal
    u = np.stack([3.0 * np.sin(2 * np.pi * 7 * t), -2.5 * np.sin(2 * np.pi * 11 * t + 0.4)], axis=1)
    a = simulate(p, u, n_substeps=NSUB)
    b = simulate(p, u, n_substeps=2 * NSUB)
    for axis in (IX, IY):
        x_a, x_b = a[:, 0, axis, fd.S_XT], b[:, 0, axis, fd.S_XT]
        w_a, w_b = a[:, 0, axis, fd.S_W], b[:, 0, axis, fd.S_W]
        assert np.count_nonzero(np.diff(np.sign(w_a[1:])) != 0) >= 4  # reversals happen
        motion = np.ptp(x_a)
        assert motion > 0.5  # mm
        assert np.max(np.abs(x_a - x_b)) < 0.01 * motion
        assert np.max(np.abs(x_a - x_b)) < 1e-5  # mm, i.e. 0.01 um
        assert np.max(np.abs(w_a - w_b)) < 0.01 * np.max(np.abs(w_a))


# ---------------------------------------------------------------- batching and numba use


def test_batch_equals_separate_machines():
    rng = np.random.default_rng(7)
    n = 6
    params = np.stack([fd.sample_parameters(rng) for _ in range(n)])
    params[2] = fd.without_nonlinearities(params[2], keep_saturation=True)
    volts = rng.uniform(-7.0, 7.0, size=(300, n, 2))
    volts[100:150] *= 0.2  # stick phases
    x0 = rng.uniform(-50, 50, size=(n, 2))
    batched = simulate(params, volts, x0=x0)
    for m in range(n):
        single = simulate(params[m], volts[:, m, :], x0=x0[m : m + 1])
        np.testing.assert_array_equal(batched[:, m], single[:, 0])
    assert len({batched[-1, m, 0, fd.S_XT] for m in range(n)}) == n


@numba.njit
def _env_like_loop(state, volts, params, dt, n_sub):
    for k in range(volts.shape[0]):
        fd.step_feed_drives(state, volts[k], params, dt, n_sub)


def test_callable_from_njit():
    p = fd.validate_parameters(fd.nominal_parameters())
    volts = np.random.default_rng(1).uniform(-5, 5, size=(200, 1, 2))
    s1 = np.zeros((1, 2, 3))
    _env_like_loop(s1, volts, p, DT, NSUB)
    s2 = simulate(p, volts)[-1]
    np.testing.assert_array_equal(s1, s2)


# ---------------------------------------------------------------- sampling and vertices


def _box_coords(p):
    return (p[0, fd.IDX_R_G], p[0, fd.IDX_K_T], p[0, fd.IDX_K_A], p[1, fd.IDX_K_A], p[0, fd.IDX_B], p[1, fd.IDX_B])


BOX = [(1.4, 1.73), (0.42, 0.52), (5.71, 7.07), (6.67, 8.26), (0.014, 0.026), (0.02, 0.037)]


def test_sample_parameters():
    rng = np.random.default_rng(123)
    samples = np.stack([fd.sample_parameters(rng) for _ in range(2000)])
    nominal = fd.nominal_parameters()
    fixed = [
        fd.IDX_J,
        fd.IDX_T_STAT_POS,
        fd.IDX_T_STAT_NEG,
        fd.IDX_T_COUL_POS,
        fd.IDX_T_COUL_NEG,
        fd.IDX_BACKLASH,
        fd.IDX_U_MAX,
    ]
    for p in samples:
        c = _box_coords(p)
        assert all(lo <= v <= hi for v, (lo, hi) in zip(c, BOX))
        assert p[0, fd.IDX_R_G] == p[1, fd.IDX_R_G] and p[0, fd.IDX_K_T] == p[1, fd.IDX_K_T]
        np.testing.assert_array_equal(p[:, fixed], nominal[:, fixed])
    coords = np.array([_box_coords(p) for p in samples])
    # roughly uniform: spread across the whole interval
    for c, (lo, hi) in zip(coords.T, BOX):
        assert np.mean(c) == pytest.approx((lo + hi) / 2, rel=0.02)
        assert c.min() < lo + 0.01 * (hi - lo) and c.max() > hi - 0.01 * (hi - lo)
    # per-axis draws are independent of each other
    assert abs(np.corrcoef(coords[:, 2], coords[:, 3])[0, 1]) < 0.1
    a = fd.sample_parameters(np.random.default_rng(5))
    b = fd.sample_parameters(np.random.default_rng(5))
    c = fd.sample_parameters(np.random.default_rng(6))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    fd.validate_parameters(samples)


def test_uncertainty_vertices():
    v = fd.uncertainty_vertices()
    assert v.shape == (64, 2, fd.N_PARAMETERS)
    corners = {_box_coords(p) for p in v}
    assert len(corners) == 64
    for c in corners:
        assert all(x in iv for x, iv in zip(c, BOX))
    np.testing.assert_allclose(v.mean(axis=0), fd.nominal_parameters(), rtol=1e-14)
    fd.validate_parameters(v)


def test_parameters_to_dict_plain_types():
    d = fd.parameters_to_dict(fd.uncertainty_vertices()[5])
    assert set(d) == set(fd.PARAMETER_NAMES)
    assert type(d["r_g"]) is float and type(d["K_t"]) is float
    assert isinstance(d["K_a"], tuple) and all(type(x) is float for x in d["K_a"])
    assert d["r_g"] == 1.73 and d["K_t"] == 0.42 and d["K_a"] == (7.07, 6.67)
