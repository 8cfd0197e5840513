"""Tests of Yadav et al.'s CNCMT axis (vcnc_gym.plants.cncmt_axis).

Independent references: python-control's ZOH discretisation of eq. (2)
followed by z^-n, python-control's Pade approximation of high order of the
continuous plant with its dead time, the closed-form response of
b / (s (s + a)) to a delayed step, and the numbers of Yadav et al. (2020) typed in again.
"""

import math

import numpy as np
import pytest

from vcnc_gym.plants import cncmt_axis as c
from vcnc_gym.plants import get_plant

control = pytest.importorskip("control")


def run(params, commands, dt, **options):
    """Positions (K + 1, 2) mm of one machine driven by ``commands`` (K, 2) V from rest at 0."""
    arrays = c.MODEL.arrays(1, dt, params, **options)
    c.MODEL.reset_machine(arrays, 0, np.zeros(2))
    out = np.empty((len(commands) + 1, 2))
    out[0] = arrays.state[0, :, c.S_X]
    for k, u in enumerate(np.asarray(commands, dtype=np.float64)):
        c.advance_machine(arrays.state, arrays.params, arrays.line, arrays.head, arrays.dt, 0, u)
        out[k + 1] = arrays.state[0, :, c.S_X]
    return out


def params_with(**values):
    p = c.MODEL.nominal()
    for name, v in values.items():
        p[:, c.MODEL.index(name)] = v
    return p


def test_numbers_of_yadav2020():
    d = c.MODEL.to_dict(c.MODEL.nominal())
    assert d["a"] == (9.7, 9.7) and d["b"] == (4850.0, 4850.0)  # eq. (2): 4.85 m/(V s^2)
    assert d["T_d"] == (0.1, 0.1)
    lo, hi, names = c.MODEL.box()
    assert names == ("a_x", "a_y", "b_x", "b_y")
    np.testing.assert_allclose(lo, [7.5, 7.5, 3000.0, 3000.0])  # section 3.5: alpha_1 = 7.5; 3 K_P, 6 K_I
    np.testing.assert_allclose(hi, [11.9, 11.9, 6000.0, 6000.0])
    assert get_plant("cncmt_axis") is c.MODEL
    G = c.MODEL.linear_model()
    np.testing.assert_allclose(G.num[0][0], [4850.0])
    np.testing.assert_allclose(G.den[0][0], [1.0, 9.7, 0.0])
    assert c.MODEL.dead_time() == 0.1


def test_table_1_gives_eq_2_only_with_a_pitch_of_5_cm():
    a, b = c.table1_coefficients()  # p = 0.05 m
    assert a == pytest.approx(9.7, abs=0.005) and b == pytest.approx(4.85, abs=0.005)
    a_mm, b_mm = c.table1_coefficients(p=0.005)  # Table 1 as printed: 5 mm
    assert a_mm == pytest.approx(38.79, abs=0.01) and b_mm == pytest.approx(1.939, abs=0.001)
    with pytest.raises(ValueError, match="unknown Table 1 parameter"):
        c.table1_coefficients(J=1.0)


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_kernel_is_the_zoh_discretisation(dt):
    """No dead time: positions equal control.c2d(G, dt, 'zoh') driven by the same held commands."""
    rng = np.random.default_rng(1)
    p = params_with(T_d=0.0)
    p[1, c.IDX_A], p[1, c.IDX_B] = 7.5, 3000.0  # the y axis on a vertex of the box
    u = rng.uniform(-5.0, 5.0, size=(300, 2))
    x = run(p, u, dt, max_dead_time=0.0)
    for axis in (0, 1):
        G = control.tf([p[axis, c.IDX_B]], [1.0, p[axis, c.IDX_A], 0.0])
        Gd = control.c2d(control.ss(G), dt, "zoh")
        ref = control.forced_response(Gd, U=u[:, axis]).outputs
        np.testing.assert_allclose(x[:-1, axis], ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))


def test_dead_time_is_a_delay_line_of_whole_periods():
    """T_d = 0.1 s at dt = 10 ms: exactly the ZOH plant times z^-10 (python-control)."""
    dt = 0.01
    rng = np.random.default_rng(2)
    u = rng.uniform(-2.0, 2.0, size=(200, 2))
    x = run(c.MODEL.nominal(), u, dt)
    Gd = control.c2d(control.ss(c.MODEL.linear_model()), dt, "zoh")
    delayed = control.series(control.ss(control.tf([1.0], [1.0] + [0.0] * 10, dt)), Gd)
    ref = control.forced_response(delayed, U=u[:, 0]).outputs
    np.testing.assert_allclose(x[:-1, 0], ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))
    assert np.all(x[:11] == 0.0)  # nothing moves before the dead time has passed
    assert x[11, 0] != 0.0


def test_delayed_step_against_pade_and_the_closed_form():
    """A 1 V step through the 0.1 s dead time: our exact line against a 12th-order Pade and the closed form."""
    dt = 1e-3
    t = np.arange(1001) * dt
    x = run(c.MODEL.nominal(), np.ones((1000, 2)), dt)[:, 0]
    a, b, td = 9.7, 4850.0, 0.1
    tau = np.maximum(t - td, 0.0)
    exact = b / a * (tau - (1.0 - np.exp(-a * tau)) / a)
    np.testing.assert_allclose(x, exact, rtol=1e-9, atol=1e-9)
    num, den = control.pade(td, 12)
    pade = control.step_response(c.MODEL.linear_model() * control.tf(num, den), t).outputs
    # within 1e-4 of the response (a line one period too long or short is off by 1.2e-3)
    assert np.max(np.abs(x - pade)) < 1e-4 * np.max(np.abs(x))
    # a 4th-order Pade is visibly worse than the 12th: the comparison has teeth
    num4, den4 = control.pade(td, 2)
    pade2 = control.step_response(c.MODEL.linear_model() * control.tf(num4, den4), t).outputs
    assert np.max(np.abs(x - pade2)) > 5 * np.max(np.abs(x - pade))


def test_saturation_at_u_max():
    dt = 0.01
    big = run(c.MODEL.nominal(), np.full((50, 2), 1e3), dt)
    limit = run(c.MODEL.nominal(), np.full((50, 2), 10.0), dt)
    np.testing.assert_array_equal(big, limit)
    assert np.all(run(c.MODEL.nominal(), np.full((50, 2), -1e3), dt) == -limit)


def test_reset_empties_the_delay_line():
    arrays = c.MODEL.arrays(1, 0.01)
    c.MODEL.reset_machine(arrays, 0, np.zeros(2))
    for _ in range(5):
        c.advance_machine(arrays.state, arrays.params, arrays.line, arrays.head, arrays.dt, 0, np.array([3.0, -3.0]))
    c.MODEL.reset_machine(arrays, 0, np.array([1.0, 2.0]))
    np.testing.assert_array_equal(arrays.state[0], [[1.0, 0.0], [2.0, 0.0]])
    for _ in range(10):  # 10 periods of zero command pending: the table does not move
        c.advance_machine(arrays.state, arrays.params, arrays.line, arrays.head, arrays.dt, 0, np.zeros(2))
    np.testing.assert_array_equal(arrays.state[0], [[1.0, 0.0], [2.0, 0.0]])


def test_bad_dead_times_are_refused():
    with pytest.raises(ValueError, match="T_d .s. must be nonnegative"):
        c.MODEL.validate(params_with(T_d=-0.1))
    with pytest.raises(ValueError, match="dead time >= 0"):
        c.delay_periods(-0.01, 0.01)
    with pytest.raises(ValueError, match="not a whole number of control periods"):
        c.MODEL.arrays(1, 0.003)  # 0.1 s / 3 ms = 33.3 periods
    arrays = c.MODEL.arrays(1, 0.01, params_with(T_d=0.05))
    c.MODEL.reset_machine(arrays, 0, np.zeros(2))  # 5 periods: fine
    arrays.params[0, 0, c.IDX_T_D] = 0.055
    with pytest.raises(ValueError, match="T_d of axis x = 0.055 s is not a whole number"):
        c.MODEL.reset_machine(arrays, 0, np.zeros(2))
    arrays.params[0, 0, c.IDX_T_D] = 0.2
    with pytest.raises(ValueError, match="max_dead_time"):
        c.MODEL.reset_machine(arrays, 0, np.zeros(2))
    longer = c.MODEL.arrays(1, 0.01, params_with(T_d=0.2), max_dead_time=0.2)
    c.MODEL.reset_machine(longer, 0, np.zeros(2))
    assert longer.line.shape == (1, 2, 20)
    assert c.delay_periods(0.1, 1e-3) == 100  # 0.1 / 1e-3 = 100.00000000000001: whole within 1e-9
    with pytest.raises(ValueError, match="unknown option"):
        c.MODEL.arrays(1, 0.01, dead_time=0.1)


def test_zoh_acceleration_input_series_and_closed_form_agree():
    for a, dt in [(9.7, 1e-4), (9.7, 1e-2), (11.9, 0.0084), (11.9, 0.0085)]:  # a dt on both sides of 0.1
        e, g, q = c.zoh_acceleration_input(a, dt)
        assert e == pytest.approx(math.exp(-a * dt), rel=1e-15)
        assert g == pytest.approx(-math.expm1(-a * dt) / a, rel=1e-13)
        assert q == pytest.approx((dt + math.expm1(-a * dt) / a) / a, rel=1e-9)
