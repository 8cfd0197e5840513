"""Documented arguments against the code, in the style of python-control's ``docstrings_test.py``: every argument
an env accepts is in ``inspect.signature`` and in its docstring's Arguments list, every argument listed there
exists, and the value lists written in prose are the code's; every ``--option`` the README or a command's
docstring names is an option of ``vcnc-bench`` or ``vcnc-train``, and every option has its help."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

import vcnc_gym  # noqa: F401
from vcnc_gym.envs import ContouringEnv
from vcnc_gym.envs.contouring_vector_env import ContouringVectorEnv
from vcnc_gym.envs.feed_override_env import FeedOverrideEnv
from vcnc_gym.envs.gcode_env import GCodeEnv, GCodeVectorEnv
from vcnc_gym.envs.random_contour_env import RandomContourEnv
from vcnc_gym.envs.task import EPISODE_ENDS, PROFILES, ContouringTask
from vcnc_gym.geometry import SHAPES

ROOT = Path(__file__).resolve().parents[1]


def _arguments_section(cls) -> str:
    doc = inspect.getdoc(cls) or ""
    assert "## Arguments" in doc, f"{cls.__name__} has no Arguments section"
    section = doc.split("## Arguments", 1)[1]
    return section.split("\n## ", 1)[0]


def _documented(cls) -> set[str]:
    """The identifiers written as ``name`` in the class's Arguments section."""
    return set(re.findall(r"``([a-z_][a-z0-9_]*)``", _arguments_section(cls)))


def _parameters(cls) -> list[str]:
    return [p for p in inspect.signature(cls).parameters if p != "self"]


def test_the_envs_signatures_show_every_argument_they_accept():
    """``**kwargs`` is not left in any env's signature, and each shows every argument of the task it builds."""
    task = set(_parameters(ContouringTask))
    for cls in (ContouringEnv, ContouringVectorEnv, GCodeEnv, GCodeVectorEnv, RandomContourEnv, FeedOverrideEnv):
        kinds = {p.kind for p in inspect.signature(cls).parameters.values()}
        assert inspect.Parameter.VAR_KEYWORD not in kinds, cls.__name__
    assert task | {"render_mode", "render_every"} == set(_parameters(ContouringEnv))
    assert task - {"contour", "feedrate"} <= set(_parameters(GCodeEnv))
    assert task - {"contour", "feedrate", "profile"} <= set(_parameters(RandomContourEnv))
    assert "completion_timeout" not in _parameters(FeedOverrideEnv)


def test_contouring_env_documents_exactly_its_arguments():
    documented = _documented(ContouringEnv)
    missing = sorted(set(_parameters(ContouringEnv)) - documented)
    assert missing == []
    # an argument-shaped name at the head of a bullet is a real argument
    heads = set(re.findall(r"^\s*- ``([a-z_][a-z0-9_]*)``", _arguments_section(ContouringEnv), re.M))
    assert heads and heads <= set(_parameters(ContouringEnv)), sorted(heads - set(_parameters(ContouringEnv)))


@pytest.mark.parametrize("cls", [GCodeEnv, RandomContourEnv, FeedOverrideEnv])
def test_a_derived_env_documents_its_own_arguments_and_what_it_takes_from_contouring_env(cls):
    own = set(_parameters(cls)) - set(_parameters(ContouringEnv))
    documented = _documented(cls)
    assert own <= documented, sorted(own - documented)
    assert "every other argument of ContouringEnv" in " ".join(
        _arguments_section(cls).split()
    ) or "Every argument of ContouringEnv" in _arguments_section(cls)
    refused = set(_parameters(ContouringEnv)) - set(_parameters(cls))
    assert refused <= documented, f"{cls.__name__} takes no {sorted(refused - documented)}: say so"


def _quoted_values(text: str) -> set[str]:
    return set(re.findall(r'(?<!=)"([a-z][a-z0-9_-]*)"', text))  # not an example's contour="..."


def test_the_value_lists_in_prose_are_the_codes():
    section = " ".join(_arguments_section(ContouringEnv).split())
    profile = section.split("``profile``", 1)[1].split("- ``", 1)[0]
    assert _quoted_values(profile) == set(PROFILES)
    contour = section.split("``contour``", 1)[1].split("- ``", 1)[0]
    assert _quoted_values(contour) == set(SHAPES)
    end = section.split("``episode_end``", 1)[1].split("- ``", 1)[0]
    assert set(EPISODE_ENDS) <= _quoted_values(end)
    render = section.split("``render_mode``", 1)[1]
    assert set(ContouringEnv.metadata["render_modes"]) <= _quoted_values(render)


def _options(parser) -> dict[str, object]:
    return {s: a for a in parser._actions for s in a.option_strings}


def _cli_parsers():
    from vcnc_agents.arguments import parser as train_parser
    from vcnc_bench.arguments import bench_parser

    return {"vcnc-bench": bench_parser(), "vcnc-train": train_parser()}


@pytest.mark.parametrize("command", ["vcnc-bench", "vcnc-train"])
def test_every_option_has_its_help(command):
    parser = _cli_parsers()[command]
    bare = [s for s, a in _options(parser).items() if s.startswith("--") and not (a.help or "").strip()]
    assert bare == []


def test_every_option_the_docs_name_exists():
    """``--option`` written after ``vcnc-bench`` or ``vcnc-train`` in the README, the commands' docstrings and the
    docs' pages is an option of that command."""
    import vcnc_agents.cli
    import vcnc_bench.cli

    options = {name: set(_options(p)) for name, p in _cli_parsers().items()}
    texts = [
        ROOT / "README.md",
        *sorted((ROOT / "docs").glob("*.md")),
        *sorted((ROOT / "docs" / "guides").glob("*.md")),
    ]
    sources = [(t.name, t.read_text()) for t in texts]
    sources += [("vcnc_bench.cli", vcnc_bench.cli.__doc__), ("vcnc_agents.cli", vcnc_agents.cli.__doc__)]
    unknown = []
    for name, text in sources:
        for command, line in re.findall(r"(vcnc-bench|vcnc-train)([^\n`|]*)", text):
            for opt in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", line):
                if opt not in options[command]:
                    unknown.append(f"{name}: {command} {opt}")
    assert unknown == []
