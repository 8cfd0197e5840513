"""The documentation's code runs: every Python block of the guides and of the getting-started page; and the
commands the README and the docs print exist: every option of ``vcnc-bench``, ``vcnc-train`` and ``vcnc-datasets``
is one of its parser's, every ``python -m MODULE`` imports and every script named is in the checkout.

A page's blocks run in order as one script, in a fresh interpreter (a guide
registers a controller or compiles a plant: nothing leaks into this process),
from a temporary folder.  A block captioned with a file name
(```` ```{code-block} python ```` with ``:caption: name.py``) is that
module: it is written beside the script, under a name carrying a hash of its
text (no clash with an installed module), and imported as ``name``; nothing
numba compiles for its types is cached (``_HEAD``).  ``diff`` and ``bash``
blocks are shown, not run.
"""

from __future__ import annotations

import hashlib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"

#: ```python ... ``` or ```{code-block} python ... ``` with its :option: lines
_FENCE = re.compile(
    r"^```(?:python|\{code-block\} python)[ \t]*\n((?::[\w-]+:[^\n]*\n)*)(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL
)

PAGES = [
    "getting-started.md",
    "guides/add-a-plant.md",
    "guides/add-a-contour.md",
    "guides/add-a-controller.md",
    "guides/add-a-training-option.md",
    "guides/add-a-shop-floor-effect.md",
]


def code_blocks(page: Path) -> list[tuple[str | None, str]]:
    """(module file name or None, code) of every Python block of ``page``, in order."""
    blocks = []
    for options, code in _FENCE.findall(page.read_text()):
        caption = re.search(r"^:caption:\s*(\S+\.py)\s*$", options, re.MULTILINE)
        blocks.append((caption.group(1) if caption else None, code))
    return blocks


def test_the_block_reader_finds_both_fence_kinds(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "intro\n```python\nx = 1\n```\n\n```{code-block} python\n:caption: mod.py\n\ny = 2\n```\n"
        "```diff\n+z\n```\n```bash\nmake\n```\n"
    )
    assert code_blocks(page) == [(None, "x = 1\n"), ("mod.py", "\ny = 2\n")]


#: Run before a page's code.  numba keeps one cache index per compiled function, shared by every
#: signature: a step kernel compiled for a guide's plant class, saved there, would name a module that no
#: other process can import, and every later load of that kernel would fail.  So nothing compiled for a
#: type of the guide's modules is saved (it compiles in the page's process only).
_HEAD = """import importlib, pickle, sys
sys.path.insert(0, ".")
import numba.core.caching as _caching

_GUIDE_MODULES = tuple(hashed.encode() for _, hashed in {modules!r})
_save_overload = _caching.Cache.save_overload


def _save_unless_guide_type(self, sig, data):
    try:
        blob = pickle.dumps(sig)
    except Exception:
        return
    if not any(name in blob for name in _GUIDE_MODULES):
        _save_overload(self, sig, data)


_caching.Cache.save_overload = _save_unless_guide_type
"""


def _script(page: Path, folder: Path) -> Path:
    modules, body = [], []
    for name, code in code_blocks(page):
        if name is None:
            body.append(code)
            continue
        stem = Path(name).stem
        hashed = f"{stem}_{hashlib.sha1(code.encode()).hexdigest()[:12]}"
        (folder / f"{hashed}.py").write_text(code)
        modules.append((stem, hashed))
    assert body, f"{page} has no Python block to run"
    head = (
        _HEAD.format(modules=tuple(modules))
        + "\n".join(f"sys.modules[{stem!r}] = importlib.import_module({hashed!r})" for stem, hashed in modules)
        + "\n"
    )
    script = folder / "page.py"
    script.write_text(head + "\n".join(body))
    return script


@pytest.mark.parametrize(
    "page", [pytest.param(p, marks=pytest.mark.slow) if "plant" in p or "effect" in p else p for p in PAGES]
)
def test_page_code_runs(page, tmp_path):
    script = _script(DOCS / page, tmp_path)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, f"{page}'s code failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}"


# -- the commands the pages print ----------------------------------------------------------------------------------

ROOT = DOCS.parent

#: A command line of the package's commands as the pages print it, up to the end of its line, code span or comment.
_COMMAND = re.compile(r"(vcnc-bench|vcnc-train|vcnc-datasets)((?:[ \t]+[^\s`#|]+)*)")


def _pages() -> list[Path]:
    """The README and every written page of docs/ (the generated env and API pages left out)."""
    generated = {"envs", "api", "_build"}
    return [ROOT / "README.md"] + [
        p for p in sorted(DOCS.rglob("*.md")) if not generated.intersection(p.relative_to(DOCS).parts)
    ]


def _options() -> dict[str, set[str]]:
    from vcnc_agents.arguments import parser as train_parser
    from vcnc_bench.arguments import bench_parser
    from vcnc_bench.datasets import _parser as datasets_parser

    parsers = {"vcnc-bench": bench_parser(), "vcnc-train": train_parser(), "vcnc-datasets": datasets_parser()}
    return {name: {s for a in p._actions for s in a.option_strings} for name, p in parsers.items()}


def test_the_pages_command_lines_use_their_parsers_options():
    options = _options()
    wrong = [
        f"{page.relative_to(ROOT)}: {m.group(1)} {option}"
        for page in _pages()
        for m in _COMMAND.finditer(page.read_text())
        for option in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", m.group(2))
        if option not in options[m.group(1)]
    ]
    assert not wrong, "options the commands do not have: " + "; ".join(wrong)


def test_the_pages_modules_and_scripts_exist():
    import importlib.util

    missing = []
    for page in _pages():
        text = page.read_text()
        for module in re.findall(r"python -m ([\w.]+)", text):
            if importlib.util.find_spec(module) is None:
                missing.append(f"{page.relative_to(ROOT)}: python -m {module}")
        for script in re.findall(r"python ((?:benchmarks|experiments|tests)/[\w/.-]+\.py)", text):
            if not Path(script).stem.isupper() and not (ROOT / script).is_file():  # NAME.py: a placeholder
                missing.append(f"{page.relative_to(ROOT)}: python {script}")
    assert not missing, "named but not in the checkout: " + "; ".join(missing)
