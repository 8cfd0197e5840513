"""The examples in the docstrings (``>>>``) run, and print what they say: every module of the four packages that has
one, found by reading the sources (a new example runs without editing this file).

An example that needs what a test cannot have (a trained agent's 14 s load, a downloaded dataset) is marked
``# doctest: +SKIP`` where it stands.
"""

from __future__ import annotations

import doctest
import importlib

import pytest
from package_layout import TOP, module_name

#: Every module with a docstring example, by import name.
MODULES = sorted(module_name(p) for top in TOP.values() for p in top.rglob("*.py") if ">>>" in p.read_text())


def test_the_examples_are_found():
    assert len(MODULES) >= 10 and "vcnc_gym.motion.interpolator" in MODULES and "vcnc_baselines" in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_the_docstring_examples_run(name, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    module = importlib.import_module(name)
    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    result = doctest.testmod(module, optionflags=flags, report=True, verbose=False)
    assert result.failed == 0, f"{name}: {result.failed} of {result.attempted} examples fail (printed above)"
