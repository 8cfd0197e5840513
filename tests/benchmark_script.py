"""The tests' one way to import a script of ``benchmarks/`` (not a package: the scripts run as files)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def benchmark_script(name: str, module_name: str | None = None):
    """``benchmarks/<name>.py`` as a fresh module (``module_name``: its name, default ``name``)."""
    spec = importlib.util.spec_from_file_location(module_name or name, BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
