"""The source papers' headline figures the bench prints beside ours: the only copy of them.

Keyed by (env name, policy label): the id without its version
(:func:`vcnc_gym.envs.registry.env_name`), the task the paper ran (the
versions differ in how an episode ends, not in the contour or the plant).  Units in the key names.  Yadav et
al.'s Table 2 and Purtojo et al.'s circle figures are printed in their own shape by the reports of
:mod:`vcnc_bench.kinds.baseline` (from ``vcnc_bench.reports.yadav2020`` and ``vcnc_bench.reports.circle``), which
hold them.
"""

from __future__ import annotations

from vcnc_gym.envs.registry import env_name

__all__ = ["PAPER_TABLE_4", "PAPER_SIMBA", "PAPER_SIMBA_CYCLE_TIME_INCREASE_PERCENT", "PAPER_FEEDRATE", "paper_figures"]

#: Jahanpour et al. (2014), Table 4 "Simulation results for the
#: contour following tasks with the designed controllers": maximum contour
#: error in um and the paper's "average contour error (%)", per contour and
#: controller (FC = "fuzzy", SMC = "smc", QFT = "qft").
PAPER_TABLE_4: dict[tuple[str, str], dict[str, float]] = {
    ("VCNC-Heart", "fuzzy"): {"max_contour_error_um": 35.5, "average_contour_error_percent": 18.54},
    ("VCNC-Heart", "smc"): {"max_contour_error_um": 13.16, "average_contour_error_percent": 3.25},
    ("VCNC-Heart", "qft"): {"max_contour_error_um": 10.14, "average_contour_error_percent": 3.34},
    ("VCNC-Omega", "fuzzy"): {"max_contour_error_um": 44.19, "average_contour_error_percent": 17.82},
    ("VCNC-Omega", "smc"): {"max_contour_error_um": 28.22, "average_contour_error_percent": 9.46},
    ("VCNC-Omega", "qft"): {"max_contour_error_um": 27.33, "average_contour_error_percent": 6.91},
}

#: Simba et al., section IV-B, simulation: maximum contour error in
#: um of the contouring feedback controller (FB, eq. (7)) and of ILC after its
#: trials, on the linear (sharp) and the smoothed path.  The ILC figure is
#: compared with the bench's last trial.
PAPER_SIMBA: dict[tuple[str, str], dict[str, float]] = {
    ("VCNC-Corners", "contouring-fb"): {"max_contour_error_um": 97.74},
    ("VCNC-Corners", "ilc"): {"max_contour_error_um": 88.92},
    ("VCNC-CornersSmooth", "contouring-fb"): {"max_contour_error_um": 17.78},
    ("VCNC-CornersSmooth", "ilc"): {"max_contour_error_um": 6.88},
}

#: Simba et al., section IV-C (experiment): cycle time of the smoothed path against the linear one, %.
PAPER_SIMBA_CYCLE_TIME_INCREASE_PERCENT = 1.36

#: Jahanpour et al. (2014), section 3: the feedrate of every contour following task, mm/s.
PAPER_FEEDRATE = 100.0


def paper_figures(env_id: str, label: str) -> dict[str, float]:
    """The paper's figures for a policy on an env (empty if the paper has none)."""
    key = (env_name(env_id), label)
    return dict(PAPER_TABLE_4.get(key, PAPER_SIMBA.get(key, {})))
