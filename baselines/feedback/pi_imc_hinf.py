"""Yadav et al.'s controllers as transfer functions: robust PI, IMC and H-infinity.

Yadav, Pathak and Gaur (2020) design three unity-feedback
controllers ``u = C(s) (r - x)`` for the CNCMT axis of eq. (2),
``G(s) = 4.85 / (s (s + 9.7)) e^{-0.1 s}`` (x in m, u in V):

- ``"pi"``: the robust PI controller ``K_P + K_I / s`` with ``K_P = 38.33``,
  ``K_I = 45.65`` (section 3.2), tuned on Kharitonov's ``p_3`` for a 10 dB
  gain margin and a 60 degree phase margin (eqs. (17)-(19);
  :func:`robust_pi_gains`);
- ``"imc"``: the IMC controller of eq. (23), ``(0.21 s + 2) / (s + 2)``,
  the unity-feedback form (eq. (21)) of ``Q(s) = G(s)^-1 / (mu s + 1)^lambda``
  (eq. (22)) with ``lambda = 2``, ``mu = 1`` (:func:`imc_controller` derives
  it);
- ``"hinf"``: the fourth-order mixed-sensitivity H-infinity controller of
  eq. (28) (weights of eq. (27), MATLAB ``hinfopt``);
- ``"hinf-reduced"``: its first-order reduction, eq. (29), ``20.97 / (s + 5.5)``.

:data:`PAPER_CONTROLLERS` holds the coefficients as printed, in the paper's V/m;
:func:`controller_tf` returns the python-control transfer function in V/mm,
the suite's unit (divided by :data:`~vcnc_gym.plants.cncmt_axis.METRE`).
Every other use (policies, analysis) goes through :func:`controller_tf`.
"""

from __future__ import annotations

import math

import control
import numpy as np

from vcnc_gym.plants.cncmt_axis import METRE, PAPER_NOMINAL
from vcnc_gym.validation import positive

__all__ = [
    "PAPER_CONTROLLERS",
    "CONTROLLER_SOURCES",
    "controller_names",
    "controller_tf",
    "imc_controller",
    "robust_pi_gains",
]

#: Yadav et al.'s controllers as printed: (numerator, denominator), highest power
#: of s first, in V/m (the paper's length unit).
PAPER_CONTROLLERS: dict[str, tuple[tuple[float, ...], tuple[float, ...]]] = {
    "pi": ((38.33, 45.65), (1.0, 0.0)),
    "imc": ((0.21, 2.0), (1.0, 2.0)),
    "hinf": ((20.12, 197.2, 19.52, 2.72e-13), (1.0, 14.23, 54.16, 5.879, 0.05339)),
    "hinf-reduced": ((20.97,), (1.0, 5.5)),
}

#: Where each controller is printed in Yadav et al. (2020).
CONTROLLER_SOURCES = {
    "pi": "Yadav et al. (2020), section 3.2 (K_P = 38.33, K_I = 45.65)",
    "imc": "Yadav et al. (2020), eq. (23) (lambda = 2, mu = 1)",
    "hinf": "Yadav et al. (2020), eq. (28)",
    "hinf-reduced": "Yadav et al. (2020), eq. (29)",
}


def controller_names() -> list[str]:
    """The names of Yadav et al.'s controllers."""
    return list(PAPER_CONTROLLERS)


def controller_tf(name: str, unit: str = "mm") -> control.TransferFunction:
    """Yadav et al.'s controller ``name`` as a continuous python-control transfer function.

    Parameters
    ----------
    name : str
        One of :func:`controller_names`: "pi", "imc", "hinf", "hinf-reduced".
    unit : str
        Length unit of the error it acts on: "mm" (the suite's; V/mm) or "m"
        (the paper's; V/m).

    Raises
    ------
    ValueError
        For an unknown controller or unit.
    """
    if not isinstance(name, str) or name not in PAPER_CONTROLLERS:
        raise ValueError(
            f"unknown controller of Yadav et al. (2020) {name!r}; known controllers are {controller_names()}"
        )
    if unit not in ("mm", "m"):
        raise ValueError(f"unit must be 'mm' (C in V/mm) or 'm' (C in V/m), got {unit!r}")
    num, den = PAPER_CONTROLLERS[name]
    scale = 1.0 / METRE if unit == "mm" else 1.0
    return control.tf([scale * c for c in num], list(den))


def imc_controller(
    mu: float = 1.0, lam: int = 2, a: float = PAPER_NOMINAL["a"], b: float = PAPER_NOMINAL["b"]
) -> control.TransferFunction:
    """The IMC controller of Yadav et al. (2020), eqs. (21)-(22), for ``G(s) = b / (s (s + a))``.

    ``Q = G^-1 / (mu s + 1)^lambda`` and ``C = Q / (1 - G Q)``, which is
    ``C = s (s + a) / (b ((mu s + 1)^lambda - 1))``; the common factor ``s``
    (``(mu s + 1)^lambda - 1`` has no constant term) is cancelled exactly.
    With the paper's ``lambda = 2``, ``mu = 1`` and eq. (2)'s ``a = 9.7``,
    ``b = 4.85`` this is ``(s + 9.7) / (4.85 s + 9.7) = (0.2062 s + 2) / (s + 2)``,
    eq. (23) printed with ``1 / 4.85`` rounded to 0.21.

    Parameters
    ----------
    mu : float
        Filter time constant [s], > 0.
    lam : int
        Filter order lambda, >= 2 (the smallest that makes Q proper).
    a : float
        Plant pole [1/s], > 0.
    b : float
        Plant gain; C comes out in V per (the length unit of b).

    Returns
    -------
    control.TransferFunction
        C(s), the unity-feedback IMC controller.
    """
    mu = positive("mu", mu, "s, the filter time constant")
    if isinstance(lam, bool) or not isinstance(lam, int) or lam < 2:
        raise ValueError(f"lam (lambda) must be an integer >= 2 (Q proper for a second-order G), got {lam!r}")
    a, b = positive("a", a, "1/s"), positive("b", b, "mm/(V s^2)")
    filt = np.polynomial.polynomial.polypow([1.0, mu], lam)[::-1]  # (mu s + 1)^lam, descending
    den = b * np.polysub(filt, [1.0])[:-1]  # b ((mu s + 1)^lam - 1) / s
    num = np.array([1.0, a])  # s (s + a) / s
    return control.tf(num, den)


def robust_pi_gains(
    gain_margin_db: float = 10.0,
    phase_margin_deg: float = 60.0,
    alpha_1: float = 7.5,
    b_low: float = 3.0,
    b_high: float = 6.0,
    ratio_digits: int | None = None,
) -> tuple[float, float]:
    """K_P and K_I of Yadav et al.'s robust PI design, eqs. (17)-(19).

    On Kharitonov's worst polynomial ``p_3 = s^3 + alpha_1 s^2 + b_low K_P s
    + b_high K_I`` the gain margin of eq. (11), ``alpha_1 alpha_2 / beta_3``,
    fixes ``K_P / K_I`` (eq. (18)) and the phase margin of eq. (15) then
    fixes ``K_I`` (eq. (19)).

    Parameters
    ----------
    gain_margin_db, phase_margin_deg : float
        The design margins (10 dB, 60 degrees in Yadav et al. (2020)).
    alpha_1, b_low, b_high : float
        The plant's interval bounds (7.5 1/s; 3 and 6 m/(V s^2)), section 3.5.
    ratio_digits : int, optional
        Round ``K_P / K_I`` to this many decimals before eq. (19), as the
        paper does (``K_P = 0.84 K_I``; ``ratio_digits=2``).

    Returns
    -------
    (K_P, K_I) : (float, float)
        In V/m and V/(m s).  Exact: (38.05, 45.12); with ``ratio_digits=2``:
        (38.33, 45.63), the paper's 38.33 and 45.65.
    """
    ratio = b_high * 10.0 ** (gain_margin_db / 20.0) / (alpha_1 * b_low)  # eq. (18)
    if ratio_digits is not None:
        ratio = round(ratio, ratio_digits)
    # eq. (19): (alpha_1 b_low K_P - b_high K_I)^2 = alpha_1^3 b_high K_I / tan^2(90 deg - PM)
    t = math.tan(math.radians(90.0 - phase_margin_deg))
    slack = alpha_1 * b_low * ratio - b_high
    if slack <= 0.0:
        raise ValueError("the gain margin leaves no positive Routh slack (alpha_1 alpha_2 <= beta_3)")
    k_i = alpha_1**3 * b_high / (t * t * slack * slack)
    return ratio * k_i, k_i
