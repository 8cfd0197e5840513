"""The research studies of ``experiments/<study>/`` (``docs/studies.md``): each folder answers for itself.

Every study folder has a README.md with the parts a reader needs (its question, the commands, what its data files
are, its conclusion), every file the README names exists, every ``vcnc-bench`` and ``vcnc-train`` option its
commands use is an option of today's command, and the installed packages import nothing from the studies (they are
not in the wheel: ``tests/test_packaging.py``).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from package_layout import ROOT, TOP

EXPERIMENTS = ROOT / "experiments"
STUDIES = sorted(p for p in EXPERIMENTS.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))
#: The parts of a study's README, in this order, each a second-level heading.
PARTS = ("Question", "Commands", "Data", "Conclusion")
#: A path named from the repository's root, or from the study's own folder.
ROOT_FOLDERS = ("experiments/", "agents/", "baselines/", "benchmarks/", "docs/", "tests/", "vcnc_gym/", "vcnc_bench/")
STUDY_FOLDERS = ("data/", "seeds/", "recipes/", "figures/")
#: What stands for a name in a command (``ID``, ``NAME``, a glob, ``seed{seed}``, ...): not a file to look for.
PLACEHOLDER = re.compile(r"\b(ID|NAME|GROUP|SEARCHED|PLANT|FOLDER|RUN|OUT|KEY|CPU|BENCH|JSON|PNG)\b|[*{}<>\[\]]|\.\.\.")


def _readme(study: Path) -> str:
    return (study / "README.md").read_text(encoding="utf-8")


def test_there_are_studies():
    assert {"tolerance", "adaptive", "ablations", "commissioning", "specialists", "generalists"} <= {
        s.name for s in STUDIES
    }


@pytest.mark.parametrize("study", STUDIES, ids=lambda p: p.name)
def test_a_study_s_readme_has_its_parts_in_order(study):
    assert (study / "README.md").is_file(), f"{study.relative_to(ROOT)} has no README.md"
    text = _readme(study)
    assert re.match(r"# \S", text), "the README starts with its title"
    found = [m.group(1).strip() for m in re.finditer(r"(?m)^## (.+)$", text)]
    missing = [p for p in PARTS if p not in found]
    assert not missing, f"{study.name}/README.md lacks the part(s) {missing}"
    assert [p for p in found if p in PARTS] == list(PARTS), f"{study.name}/README.md: parts out of order: {found}"
    for part in PARTS:  # each part says something
        body = text.split(f"\n## {part}\n", 1)[1].split("\n## ", 1)[0]
        assert body.strip(), f"{study.name}/README.md: '## {part}' is empty"


def _named_paths(text: str) -> set[str]:
    """The repository paths a Markdown text names: words starting with a folder of the repository or of a study,
    and the targets of its relative links and images."""
    names = set()
    for word in re.split(r"[\s`'\"(),;|]+", text):
        word = word.strip(".:").split("::")[0]
        if word.startswith(ROOT_FOLDERS + STUDY_FOLDERS) and not PLACEHOLDER.search(word):
            names.add(word)
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if not re.match(r"[a-z]+:", target) and not target.startswith("#"):
            names.add(target.split("#")[0])
    return names


@pytest.mark.parametrize("study", STUDIES, ids=lambda p: p.name)
def test_every_file_a_study_s_readme_names_exists(study):
    missing = [
        name
        for name in sorted(_named_paths(_readme(study)))
        if not (ROOT / name).exists() and not (study / name).exists()
    ]
    assert not missing, f"{study.name}/README.md names what is not there: {missing}"


def test_the_studies_index_names_every_study():
    index = (ROOT / "docs" / "studies.md").read_text(encoding="utf-8")
    missing = [s.name for s in STUDIES if f"experiments/{s.name}/README.md" not in index]
    assert not missing, f"docs/studies.md does not name {missing}"


def test_every_option_a_study_s_command_uses_exists():
    """``--option`` written after ``vcnc-bench`` or ``vcnc-train`` in a study's README or a paper's page is an option
    of today's command (a study's commands are meant to be run again)."""
    from vcnc_agents.arguments import parser as train_parser
    from vcnc_bench.arguments import bench_parser

    options = {
        name: {s for a in p._actions for s in a.option_strings}
        for name, p in (("vcnc-bench", bench_parser()), ("vcnc-train", train_parser()))
    }
    pages = [s / "README.md" for s in STUDIES] + sorted((ROOT / "docs" / "papers").glob("*.md"))
    unknown = []
    for page in pages:
        for command, line in re.findall(r"(vcnc-bench|vcnc-train)([^\n`|]*)", page.read_text(encoding="utf-8")):
            unknown += [
                f"{page.relative_to(ROOT)}: {command} {opt}"
                for opt in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", line)
                if opt not in options[command]
            ]
    assert unknown == []


def _imported(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_the_packages_import_nothing_from_the_studies():
    """The studies' modules (``experiments/*/*.py``) are run from the checkout and are not installed: no module of
    the four packages imports one of them."""
    study_modules = {p.stem for p in EXPERIMENTS.glob("*/*.py")} | {"experiments"}
    found = [
        f"{path.relative_to(ROOT)} imports {sorted(hit)}"
        for top in TOP.values()
        for path in sorted(top.rglob("*.py"))
        if (hit := _imported(path) & study_modules)
    ]
    assert found == []
