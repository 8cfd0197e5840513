"""The source papers' headline figures the bench prints beside ours: the only copy of them.

Keyed by (env id, policy label).  Units in the key names.
"""

from __future__ import annotations

__all__ = ["PAPER_TABLE_4", "PAPER_FEEDRATE", "paper_figures"]

#: Seed 000 (Jahanpour et al. 2014), Table 4 "Simulation results for the
#: contour following tasks with the designed controllers": maximum contour
#: error in um and the paper's "average contour error (%)", per contour and
#: controller (FC = "fuzzy", SMC = "smc", QFT = "qft").
PAPER_TABLE_4: dict[tuple[str, str], dict[str, float]] = {
    ("VCNC-Heart-v0", "fuzzy"): {"max_contour_error_um": 35.5, "average_contour_error_percent": 18.54},
    ("VCNC-Heart-v0", "smc"): {"max_contour_error_um": 13.16, "average_contour_error_percent": 3.25},
    ("VCNC-Heart-v0", "qft"): {"max_contour_error_um": 10.14, "average_contour_error_percent": 3.34},
    ("VCNC-Omega-v0", "fuzzy"): {"max_contour_error_um": 44.19, "average_contour_error_percent": 17.82},
    ("VCNC-Omega-v0", "smc"): {"max_contour_error_um": 28.22, "average_contour_error_percent": 9.46},
    ("VCNC-Omega-v0", "qft"): {"max_contour_error_um": 27.33, "average_contour_error_percent": 6.91},
}

#: Seed 000, section 3: the feedrate of every contour following task, mm/s.
PAPER_FEEDRATE = 100.0


def paper_figures(env_id: str, label: str) -> dict[str, float]:
    """The paper's figures for a policy on an env (empty if the paper has none)."""
    return dict(PAPER_TABLE_4.get((env_id, label), {}))
