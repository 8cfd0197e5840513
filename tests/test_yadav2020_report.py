"""Yadav et al.'s Table 2 in our numbers (vcnc_bench.reports.yadav2020) against the paper's own numbers.

The paper's nominal row is reproduced by the continuous loop without the dead
time (section 4 evidently neglects it: with it the robust PI loop is
unstable); its rise times of the underdamped loops are 0-100 % rise times.
"""

import math

import numpy as np
import pytest

pytest.importorskip("control")
report = pytest.importorskip("vcnc_bench.reports.yadav2020")


@pytest.fixture(scope="module")
def rows():
    return {r["controller"]: r for r in report.table2(dead_time=0.0, n_plants=4, t_end=20.0)}


def test_nominal_row_of_table_2(rows):
    pi, imc, hinf = rows["pi"]["nominal"], rows["imc"]["nominal"], rows["hinf-reduced"]["nominal"]
    assert pi["overshoot"] == pytest.approx(41.2, rel=0.03)
    assert pi["settling_time"] == pytest.approx(0.88, rel=0.05)
    assert pi["rise_time_100"] == pytest.approx(0.14, rel=0.05)
    assert imc["overshoot"] < 0.6 and imc["settling_time"] == pytest.approx(5.84, rel=0.005)
    assert imc["rise_time"] == pytest.approx(3.36, rel=0.005)
    assert hinf["overshoot"] == pytest.approx(6.3, rel=0.01)
    assert hinf["settling_time"] == pytest.approx(2.09, rel=0.01)
    assert hinf["rise_time_100"] == pytest.approx(1.12, rel=0.02)
    assert rows["pi"]["stability_margin"] == pytest.approx(588.6, abs=0.2)


def test_uncertain_ranges_contain_the_nominal_and_the_vertices(rows):
    """The first four plants are the box's vertices; every range brackets those runs."""
    vertices = report.plant_samples(4)
    (a_lo, a_hi), (b_lo, b_hi) = report.plant_box()
    assert sorted(map(tuple, vertices)) == sorted([(a_lo, b_lo), (a_hi, b_lo), (a_lo, b_hi), (a_hi, b_hi)])
    for name in ("pi", "hinf-reduced"):
        r = rows[name]
        for a, b in vertices:
            m = report.loop_step_metrics(name, a, b, t_end=20.0)
            lo, hi = r["uncertain"]["settling_time"]
            assert lo <= m["settling_time"] <= hi
    samples = report.plant_samples(10)
    assert len({tuple(p) for p in samples}) == 10
    assert np.all((samples[:, 0] >= a_lo) & (samples[:, 0] <= a_hi) & (samples[:, 1] >= b_lo) & (samples[:, 1] <= b_hi))


def test_dead_time_makes_the_pi_loop_unstable():
    m = report.loop_step_metrics("pi", 9.7, 4850.0, dead_time=0.1, dt=0.01, t_end=10.0)
    assert not m["stable"] and m["settling_time"] == math.inf
    assert report.loop_step_metrics("imc", 9.7, 4850.0, dead_time=0.1, dt=0.01, t_end=10.0)["stable"]
    with pytest.raises(ValueError, match="dead_time"):
        report.loop_step_metrics("pi", 9.7, 4850.0, dead_time=-0.1)
    with pytest.raises(ValueError, match="whole number"):
        report.loop_step_metrics("pi", 9.7, 4850.0, dead_time=0.1, dt=0.03)


def test_tables_and_plot(rows, tmp_path):
    text = report.format_table2(list(rows.values()), "title")
    assert "588.5 / 588.6" in text and "| imc | nominal |" in text
    assert "| hinf | 6 |" in report.format_kharitonov()
    env_rows, traces = report.env_step_table(["hinf-reduced"], n_plants=1, duration=5.0)
    assert env_rows[0]["nominal"]["overshoot"] > 10.0  # the dead time: 17 % against 6.3 % without it
    assert len(traces["hinf-reduced"]) == 2
    report.plot_step_responses(traces, tmp_path / "steps.png")
    assert (tmp_path / "steps.png").stat().st_size > 1000


@pytest.mark.parametrize("controller, dead_time", [("hinf", 0.0), ("imc", 0.0), ("pi", 0.1)])
def test_step_responses_are_python_controls(controller, dead_time):
    """The report's step responses (a compiled recursion) against ``control.step_response`` of the same loop, the
    continuous one and the sampled one with the dead time, over 3 s."""
    import control

    from vcnc_baselines.feedback.pi_imc_hinf import controller_tf
    from vcnc_bench.reports.yadav2020 import _plant_tf, _step_response

    a, b = 2.0, 100.0
    G, C = _plant_tf(a, b), controller_tf(controller)
    if dead_time == 0.0:
        T = control.feedback(G * C, 1)
        t = np.linspace(0.0, 3.0, 1501)
    else:
        dt = 1e-3
        Gd = control.series(
            control.ss(control.tf([1.0], [1.0] + [0.0] * 100, dt)), control.ss(control.c2d(G, dt, "zoh"))
        )
        T = control.feedback(control.series(control.c2d(control.ss(C), dt, "tustin"), Gd), 1)
        t = np.arange(3001) * dt
    _, expected = control.step_response(T, t)
    got = _step_response(T, t)
    assert np.max(np.abs(got - np.asarray(expected).reshape(-1))) <= 1e-9 * max(1.0, np.max(np.abs(got)))
