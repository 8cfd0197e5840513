"""The papers are cited by authors and year; "seed" means the random generator's seed only (issue 22)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: A paper named by its file number in the project's paper folder ("seed 002", "seed002", "Seed-003").
FILE_NUMBER = re.compile(r"\bseed[ _-]?00[0-3]\b", re.IGNORECASE)


def test_no_paper_is_named_by_its_file_number():
    """Every tracked text file names the papers by their authors; only the references page keeps the file numbers,
    as the mapping to the project's paper folder."""
    files = subprocess.run(["git", "ls-files", "*.py", "*.md", "*.yml", "*.yaml", "*.toml", "*.txt", "*.nc", "*.cfg"],
                           cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    assert len(files) > 100
    found = [f"{name}:{k}: {line.strip()}" for name in files if name != "docs/references.md"
             for k, line in enumerate((ROOT / name).read_text(errors="replace").splitlines(), 1)
             if FILE_NUMBER.search(line) and name != "tests/test_citations.py"]
    assert not found, "\n".join(found[:20])
    assert FILE_NUMBER.search((ROOT / "docs" / "references.md").read_text())  # the mapping is kept there
