"""The tests' one way to import a script that is not in a package (the scripts run as files): a benchmark of
``benchmarks/``, a probe of ``tests/probes/``, or a study's analysis in ``experiments/<study>/``."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
PROBES = ROOT / "tests" / "probes"
EXPERIMENTS = ROOT / "experiments"


def _fresh(path: Path, module_name: str):
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def benchmark_script(name: str, module_name: str | None = None):
    """``benchmarks/<name>.py`` as a fresh module (``module_name``: its name, default ``name``)."""
    return _fresh(BENCHMARKS / f"{name}.py", module_name or name)


def probe_script(name: str, module_name: str | None = None):
    """``tests/probes/<name>.py`` as a fresh module (``module_name``: its name, default ``name``)."""
    return _fresh(PROBES / f"{name}.py", module_name or name)


def study_script(study: str, name: str, module_name: str | None = None):
    """``experiments/<study>/<name>.py`` as a fresh module (``module_name``: its name, default ``name``)."""
    return _fresh(EXPERIMENTS / study / f"{name}.py", module_name or name)


def study_module(study: str, name: str):
    """``experiments/<study>/<name>.py`` imported by its name, with the study's folder on ``sys.path``: a study's
    modules import each other by name, as they do when run from the checkout (``python experiments/STUDY/NAME.py``
    puts the script's folder first on the path)."""
    folder = str(EXPERIMENTS / study)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    return importlib.import_module(name)
