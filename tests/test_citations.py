"""The papers are cited by authors and year; "seed" means the random generator's seed only (issue 22)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: A paper named by its file number in the project's paper folder ("seed 002", "seed002", "Seed-003"), also broken
#: across two lines of a docstring, a comment or a Markdown quote ("seed" ending one line, "003" starting the next).
FILE_NUMBER = re.compile(r"\bseed(?:[ _-]?|[ \t]*\n[ \t#*>/\"']*)00[0-3]\b", re.IGNORECASE)
#: "seed" for a paper without its number: what a paper gives, has, states or simulates, its tables, controllers,
#: units or margins, "in the seed", the "seed QFT".
PAPER_SENSE = re.compile(
    r"\b(?:the|in\s+the)\s+[#*>]*\s*seed(?:'s)?(?:\s+(?:gives?|has|have|never|neglects|simulates|states|"
    r"tables?|controllers?|nomenclature|own|units|stability|model)\b|\)|\.$)|"
    r"(?<![a-z])seed[ _-]qft(?![a-z])|\bthe\s+seed's\b",
    re.IGNORECASE | re.MULTILINE,
)


def _tracked_texts() -> list[str]:
    return subprocess.run(
        ["git", "ls-files", "*.py", "*.md", "*.yml", "*.yaml", "*.toml", "*.txt", "*.nc", "*.cfg"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()


def _found(pattern: re.Pattern, name: str, text: str) -> list[str]:
    """``name:line: the text matched`` of every match, the line of its start."""
    return [f"{name}:{text.count(chr(10), 0, m.start()) + 1}: {m.group(0)!r}" for m in pattern.finditer(text)]


@pytest.mark.parametrize(
    "text",
    [
        "Purtojo et al. (seed 003)",
        "seed002's model",
        "e.g. seed\n   003's 1 um encoder",
        "# as in seed\n# 001, eq. (2)",
        "the seed's controllers (V/m)",
        "The seed never states an upper bound",
        "the\n  seed simulates air cutting",
        "margins (60 degrees in the seed)",
        "test_default_control_period_makes_seed_qft_loop_stable",
    ],
)
def test_the_patterns_catch_a_paper_called_seed(text):
    assert FILE_NUMBER.search(text) or PAPER_SENSE.search(text)


@pytest.mark.parametrize(
    "text",
    [
        "seed 0, learning rate 3e-4",
        "seed=1003",
        "The seed of the draws.",
        "another seed's noise",
        "seed\n\n003 steps",
        "runs/<env_id>_seed<seed>",
        "it sets the seed, device, logging",
    ],
)
def test_the_patterns_leave_a_generator_seed_alone(text):
    assert not FILE_NUMBER.search(text) and not PAPER_SENSE.search(text)


def test_no_paper_is_named_by_its_file_number():
    """Every tracked text file names the papers by their authors; only the references page keeps the file numbers,
    as the mapping to the project's paper folder."""
    files = _tracked_texts()
    assert len(files) > 100
    found = []
    for name in files:
        if name in ("docs/references.md", "tests/test_citations.py", "CHANGELOG.md"):
            continue
        text = (ROOT / name).read_text(errors="replace")
        found += _found(FILE_NUMBER, name, text) + _found(PAPER_SENSE, name, text)
    assert not found, "\n".join(found[:20])
    assert FILE_NUMBER.search((ROOT / "docs" / "references.md").read_text())  # the mapping is kept there
