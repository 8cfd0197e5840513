"""Kharitonov polynomials and stability margins (vcnc_gym.analysis.kharitonov, vcnc_bench.reports.yadav2020).

Independent references: numpy's polynomial roots (eigenvalues of the
companion matrix) instead of the Routh array, python-control's closed loops
``feedback(G C)`` over a grid of the plant box, the textbook (ascending
powers) statement of Kharitonov's polynomials, and Yadav et al.'s numbers
(section 3.5, eqs. (31), (33), (35)).
"""

import numpy as np
import pytest

from vcnc_gym.analysis import (
    hurwitz,
    interval_polynomial,
    kharitonov_polynomials,
    robustly_stable,
    routh_first_column,
    stability_margin,
)

control = pytest.importorskip("control")
report = pytest.importorskip("vcnc_bench.reports.yadav2020")
from vcnc_baselines.feedback.pi_imc_hinf import controller_names, controller_tf  # noqa: E402


def roots_stable(poly) -> bool:
    return bool(np.all(np.roots(poly).real < 0.0))


def test_routh_agrees_with_roots_on_random_polynomials():
    rng = np.random.default_rng(0)
    verdicts = []
    for _ in range(600):
        n = rng.integers(2, 8)
        roots = rng.normal(-0.3, 1.0, n // 2) + 1j * rng.uniform(0.1, 2.0, n // 2)
        real = rng.normal(-0.3, 1.0, n - 2 * (n // 2))
        poly = np.real(np.poly(np.concatenate([roots, roots.conj(), real]))) * rng.choice([-1.0, 1.0])
        if np.min(np.abs(np.roots(poly).real)) < 1e-6:
            continue
        verdicts.append(hurwitz(poly))
        assert hurwitz(poly) == roots_stable(poly), poly
    assert 50 < sum(verdicts) < len(verdicts) - 50  # both verdicts well represented
    assert not hurwitz([1.0, 0.0, 4.0])  # roots +-2j: a zero in the first column
    assert routh_first_column([1.0, 6.0, 11.0, 6.0]).tolist() == pytest.approx([1.0, 6.0, 10.0, 6.0])


def test_kharitonov_polynomials_match_the_textbook_statement():
    """Eq. (4) indexes from the leading coefficient; the textbook from the constant one (c_0 + c_1 s + ...).

    Textbook: K1 = (l, l, u, u, ...), K2 = (u, u, l, l, ...), K3 = (l, u, u, l, ...), K4 = (u, l, l, u, ...)
    over c_0, c_1, ...; both give the same four polynomials for every degree.
    """
    rng = np.random.default_rng(1)
    for n in range(1, 9):
        lo = rng.uniform(1.0, 2.0, n + 1)
        hi = lo + rng.uniform(0.1, 1.0, n + 1)
        ours = {tuple(p) for p in kharitonov_polynomials(lo, hi)}
        asc_lo, asc_hi = lo[::-1], hi[::-1]
        textbook = set()
        for pattern in ("lluu", "uull", "luul", "ullu"):
            coeffs = [asc_hi[j] if pattern[j % 4] == "u" else asc_lo[j] for j in range(n + 1)]
            textbook.add(tuple(coeffs[::-1]))
        assert ours == textbook


def test_kharitonov_theorem_on_random_interval_cubics():
    """SM > 0 iff p3 is Hurwitz (roots), and then every sampled member of the box is Hurwitz (roots)."""
    rng = np.random.default_rng(2)
    seen = {True: 0, False: 0}
    for _ in range(300):
        lo = np.concatenate([[1.0], rng.uniform(0.5, 5.0, 3)])
        hi = lo * np.concatenate([[1.0], rng.uniform(1.0, 2.0, 3)])
        sm = stability_margin(lo, hi)
        p3 = kharitonov_polynomials(lo, hi)[2]
        assert (sm > 0) == roots_stable(p3) == robustly_stable(lo, hi)
        seen[sm > 0] += 1
        if sm > 0:
            members = rng.uniform(lo, hi, size=(50, 4))
            assert all(roots_stable(m) for m in members)
    assert min(seen.values()) > 30


def test_bad_interval_polynomials():
    with pytest.raises(ValueError, match="third-order"):
        stability_margin([1, 2, 3], [1, 2, 3])
    with pytest.raises(ValueError, match="contains 0"):
        robustly_stable([-1, 2, 3], [1, 2, 3])
    with pytest.raises(ValueError, match="alpha_i <= beta_i"):
        kharitonov_polynomials([1, 3, 3], [1, 2, 3])
    with pytest.raises(ValueError, match="positive coefficients"):
        stability_margin([1, 2, 3, -1], [1, 2, 3, 1])


@pytest.mark.parametrize("name", controller_names())
def test_clce_intervals_against_python_control_over_the_box(name):
    """The CLCE bounds from the four vertices equal the extremes over a 9 x 9 grid of python-control loops,
    and every loop of the grid is stable (roots), as Kharitonov's verdict says."""
    (a_lo, a_hi), (b_lo, b_hi) = report.plant_box()
    C = controller_tf(name)
    polys = []
    for a in np.linspace(a_lo, a_hi, 9):
        for b in np.linspace(b_lo, b_hi, 9):
            T = control.feedback(control.tf([b], [1.0, a, 0.0]) * C, 1)
            den = np.asarray(T.den[0][0], dtype=float)
            polys.append(den / den[0])
            assert np.all(T.poles().real < 0.0)
    lo, hi = interval_polynomial(np.array(polys))
    k = report.kharitonov_analysis(name)
    np.testing.assert_allclose(k["alpha"], lo, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(k["beta"], hi, rtol=1e-9, atol=1e-15)
    assert k["robustly_stable"] and all(k["hurwitz"])
    assert all(roots_stable(p) for p in k["polynomials"])


def test_stability_margins_of_section_3_5():
    sm = {name: report.kharitonov_analysis(name)["stability_margin"] for name in controller_names()}
    assert sm["pi"] == pytest.approx(7.5 * 3 * 38.33 - 6 * 45.65)  # 588.5; the paper's 588.6 rounds alpha_2 to 115
    assert sm["pi"] == pytest.approx(588.6, abs=0.2)
    assert sm["hinf-reduced"] == pytest.approx(410.43, abs=0.01)  # 13 x 41.25 - 125.82
    # IMC: alpha_2 = min(2 a + 0.21 b) = 2 x 7.5 + 0.21 x 3 = 15.63; the paper's eq. (33) writes
    # 16.575 = 2 x 7.5 + 0.21 x 7.5 (a's bound in b's place) and gets 145.46
    assert sm["imc"] == pytest.approx(9.5 * 15.63 - 12.0)
    assert 9.5 * (2 * 7.5 + 0.21 * 7.5) - 12.0 == pytest.approx(145.46, abs=0.01)
    assert sm["hinf"] is None  # a sixth-order CLCE: eq. (5) does not apply


def test_negative_margin_means_an_unstable_kharitonov_polynomial():
    """A PI with K_I = 200 (beta_3 = 1200 > alpha_1 alpha_2 = 862): SM < 0 and p3 has a right-half-plane root."""
    lo = np.array([1.0, 7.5, 3 * 38.33, 3 * 200.0])
    hi = np.array([1.0, 11.9, 6 * 38.33, 6 * 200.0])
    assert stability_margin(lo, hi) < 0
    assert not robustly_stable(lo, hi)
    assert np.max(np.roots(kharitonov_polynomials(lo, hi)[2]).real) > 0
