"""The project's four top packages, by import name, and the repository folder each installs from.

Read from ``pyproject.toml`` (``[tool.setuptools]``'s ``packages`` and ``package-dir``), the one place the mapping
is written: the folders ``baselines/`` and ``agents/`` install as ``vcnc_baselines`` and ``vcnc_agents``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_SETUPTOOLS = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
#: Every package of the wheel, as pyproject.toml lists it.
PACKAGES: list[str] = _SETUPTOOLS["packages"]
#: Package -> the patterns of its data files, as pyproject.toml declares them.
PACKAGE_DATA: dict[str, list[str]] = _SETUPTOOLS.get("package-data", {})
_DIRS: dict[str, str] = _SETUPTOOLS.get("package-dir", {})
#: Import name -> folder, the four top packages from the ground floor up.
TOP = {name: ROOT / _DIRS.get(name, name) for name in ("vcnc_gym", "vcnc_baselines", "vcnc_agents", "vcnc_bench")}


def folder(package: str) -> Path:
    """The folder a (sub)package of :data:`PACKAGES` is built from."""
    top, _, rest = package.partition(".")
    return TOP[top].joinpath(*rest.split(".")) if rest else TOP[top]


def module_name(path: Path) -> str:
    """The import name of a ``.py`` file under one of the top folders (``baselines/servo.py`` ->
    ``vcnc_baselines.servo``)."""
    path = path.resolve()
    for name, top in TOP.items():
        if path.is_relative_to(top):
            parts = [name, *path.relative_to(top).with_suffix("").parts]
            return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
    raise ValueError(f"{path} is in none of the packages {sorted(TOP)}")
