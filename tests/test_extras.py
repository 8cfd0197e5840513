"""A missing extra is named in the import error (issue 36): ``import vcnc_baselines`` / ``import vcnc_agents`` without it."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from vcnc_gym.extras import EXTRAS, missing_modules, require_extra


def import_hiding(module: str, package: str) -> subprocess.CompletedProcess:
    """``import package`` in a fresh interpreter in which ``module`` cannot be imported (``sys.modules[m] = None``)."""
    code = f"import sys; sys.modules[{module!r}] = None; import {package}"
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )


@pytest.mark.parametrize(
    ("package", "extra", "module"), [("vcnc_baselines", "baselines", "control"), ("vcnc_agents", "agents", "torch")]
)
def test_import_without_the_extra_names_it(package, extra, module):
    result = import_hiding(module, package)
    assert result.returncode != 0
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("ModuleNotFoundError: ")
    assert f"pip install 'vcnc-gym[{extra}]'" in last
    assert f"{package} needs the '{extra}' extra" in last


def test_missing_modules_are_named_by_distribution(monkeypatch):
    assert missing_modules("baselines") == []  # the test environment has every extra the tests use
    monkeypatch.setitem(sys.modules, "yaml", None)
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    assert missing_modules("agents") == ["stable-baselines3", "pyyaml"]
    with pytest.raises(
        ModuleNotFoundError, match=r"missing: stable-baselines3, pyyaml\): pip install 'vcnc-gym\[agents\]'"
    ) as error:
        require_extra("agents", "vcnc_agents")
    assert error.value.name == "stable_baselines3"
    with pytest.raises(ValueError, match="extra must be one of"):
        missing_modules("nope")


def test_the_extras_are_pyprojects():
    """EXTRAS lists, per extra, the distributions pyproject.toml's optional-dependencies give it."""
    import re
    import tomllib
    from pathlib import Path

    optional = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    for extra, modules in EXTRAS.items():
        declared = {re.split(r"[<>=\[ ;]", requirement, maxsplit=1)[0].lower() for requirement in optional[extra]}
        assert {distribution for _, distribution in modules} == declared, extra
