"""Installed as users install it (issue 36): import names of the project's own, and a wheel that works read-only.

The repository's folders ``baselines/`` and ``agents/`` install as ``vcnc_baselines`` and ``vcnc_agents``
(``pyproject.toml``), so vcnc-gym installs beside OpenAI Baselines' top-level ``baselines`` or another package's
``agents`` without shadowing either.  The old import names are gone, with no alias (an alias would install the very
names that collide); a run's ``config.yml`` that names the residual wrapper by its old path is still read, with a
DeprecationWarning.

The install test builds the sdist and the wheel with ``python -m build`` (the wheel from the sdist, so the sdist is
complete too), checks the wheel's contents, and installs it into a fresh virtualenv that already holds a top-level
``baselines`` and ``agents`` of someone else's.  The virtualenv finds the dependencies (numpy, numba, torch, ...) in
the test's own environment through a ``.pth`` file of links that leaves vcnc-gym itself out, so nothing is
downloaded.  Its site-packages is then made read-only, and from a folder outside the repository, with numba's cache
left to find its own place: both other packages still import, ``gym.make`` + ``reset`` + ``step`` run,
``python -m vcnc_gym.warmup --ids`` compiles and a missing extra is named (CI: about 20 s); and, in the slow set
(``make test-all``), ``vcnc-bench`` runs one env, ``vcnc-train`` trains one PPO rollout and ``vcnc-datasets``
answers.
"""

from __future__ import annotations

import ast
import json
import os
import shutil
import stat
import subprocess
import sys
import sysconfig
import warnings
import zipfile
from pathlib import Path

import pytest

from package_layout import PACKAGE_DATA, PACKAGES, ROOT, TOP, folder

OLD_NAMES = ("baselines", "agents")
#: The folders whose Python files must not import the old names.
SOURCES = [*TOP.values(), ROOT / "tests", ROOT / "benchmarks", ROOT / "experiments", ROOT / "docs" / "_ext"]


def test_the_wheel_lists_every_package_folder():
    """pyproject.toml lists the packages by hand (a renamed folder cannot be found by setuptools' search): the list
    is every folder of the four packages that holds an ``__init__.py``, each under its import name, and the folders
    of package data (no Python file), each with its files in ``package-data``: setuptools ships the data of a
    listed package only, and warns at the install of one it would have to guess."""
    listed = {folder(p) for p in PACKAGES}
    found = {init.parent for top in TOP.values() for init in top.rglob("__init__.py")}
    data = [p for p in PACKAGES if not (folder(p) / "__init__.py").is_file()]
    assert listed - {folder(p) for p in data} == found
    assert {p.split(".")[0] for p in PACKAGES} == set(TOP)
    for p in data:
        assert folder(p).is_dir() and not list(folder(p).glob("*.py")), p
        assert p in PACKAGE_DATA, f"{p} is listed as a data package but declares no files in package-data"
    nested = [
        k for k, patterns in PACKAGE_DATA.items() for pat in patterns if "/" in pat and pat.split("/")[0].isidentifier()
    ]
    assert not nested, f"package-data reaches into a sub-folder named as a package: list it as a package: {nested}"


def _old_imports(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        elif (
            isinstance(node, ast.Call)
            and getattr(node.func, "attr", getattr(node.func, "id", ""))
            in ("import_module", "importorskip", "__import__")
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            names = [node.args[0].value]
        else:
            continue
        found += [f"{path.relative_to(ROOT)}:{node.lineno} {n}" for n in names if n.split(".")[0] in OLD_NAMES]
    return found


def test_no_code_imports_the_old_names():
    """From the repository's root ``baselines`` is still importable as a folder: an import of it would load a second
    copy of every module beside ``vcnc_baselines``'s.  No file imports it (statements, ``import_module``,
    ``importorskip``)."""
    found = [hit for top in SOURCES for path in sorted(top.rglob("*.py")) for hit in _old_imports(path)]
    assert found == []


def test_the_old_residual_wrapper_path_is_read_with_a_warning():
    from vcnc_agents.config import RESIDUAL_WRAPPER, action_mode_of

    old = {"env_wrapper": [{"agents.action_modes.ResidualAction": {"baseline": "smc", "correction": 0.2}}]}
    with pytest.warns(DeprecationWarning, match="vcnc_agents.action_modes.ResidualAction"):
        mode = action_mode_of(old)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert action_mode_of({"env_wrapper": [{RESIDUAL_WRAPPER: {"baseline": "smc", "correction": 0.2}}]}) == mode
    assert mode.mode == "residual" and mode.baseline == "smc"


# -- the wheel, installed ------------------------------------------------------------------------------------------

#: What the wheel must carry that is no Python file: the package reads each at run time.
DATA = (
    "vcnc_gym/gcode/programs/",
    "vcnc_agents/trained/VCNC-Heart-v1/model.zip",
    "vcnc_agents/trained/VCNC-Heart-v1/config.yml",
    "vcnc_agents/hyperparams/ppo.yml",
    "vcnc_baselines/optimal/solutions/",
    "vcnc_baselines/commissioning/shipped/machines/",
    "vcnc_gym/py.typed",  # the packages are typed (PEP 561)
    "vcnc_baselines/py.typed",
    "vcnc_agents/py.typed",
    "vcnc_bench/py.typed",
)
#: The cheapest env to compile (a single axis): the smoke test's.
ENV = "VCNC-Step-v0"
#: Someone else's top-level packages, already installed where vcnc-gym is installed.
OTHERS = {"baselines": "OpenAI's, say", "agents": "another package's"}


def _run(args, cwd, env, timeout=600):
    proc = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{' '.join(map(str, args))} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc


#: Runs a command with the folder "$1" mounted read-only (a mount namespace of its own): root writes into a folder
#: whatever its mode, so a read-only site-packages is a read-only mount.
_READ_ONLY = 'mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" "$1" && shift && exec "$@"'


def _read_only(site: Path) -> list[str]:
    """The prefix that runs a command with ``site`` read-only: none for a user other than root (the folder's mode
    holds); for root, ``unshare --mount`` with :data:`_READ_ONLY` where the kernel allows it, else a skip."""
    if os.geteuid() != 0:
        return []
    prefix = ["unshare", "--mount", "--", "sh", "-c", _READ_ONLY, "sh", str(site)]
    if (
        shutil.which("unshare") is None
        or subprocess.run([*prefix, "sh", "-c", f"! touch {site}/probe 2>/dev/null"], capture_output=True).returncode
    ):
        pytest.skip("root here, and no mount namespace to make site-packages read-only in")
    return prefix


def _dependencies_overlay(dest: Path) -> Path:
    """A folder of links to every entry of this environment's site-packages but vcnc-gym's own (its editable
    finder, .pth and metadata), for a fresh virtualenv to find the dependencies in without a download."""
    dest.mkdir()
    purelib = Path(sysconfig.get_paths()["purelib"])
    for entry in purelib.iterdir():
        name = entry.name.lower()
        if name.startswith(("__editable__", "vcnc_gym", "vcnc-gym")) or entry.suffix == ".pth":
            continue
        (dest / entry.name).symlink_to(entry)
    return dest


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(wheel path, the fresh venv's python, its environment variables, a work folder outside the repository, the
    venv's site-packages)."""
    tmp = tmp_path_factory.mktemp("wheel")
    dist = tmp / "dist"
    build = _run(
        [sys.executable, "-m", "build", "--no-isolation", "--outdir", dist, ROOT], cwd=tmp, env=os.environ, timeout=300
    )
    _BUILD_OUTPUT.append(build.stdout + build.stderr)
    wheel = next(dist.glob("vcnc_gym-*.whl"))
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=tmp, env=os.environ)
    python = venv / "bin" / "python"
    site = Path(
        _run(
            [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=tmp, env=os.environ
        ).stdout.strip()
    )
    for name, who in OTHERS.items():
        (site / name).mkdir()
        (site / name / "__init__.py").write_text(f"WHO = {who!r}\n")
    (site / "vcnc_test_dependencies.pth").write_text(f"{_dependencies_overlay(tmp / 'dependencies')}\n")
    _run(
        [sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-deps", "--no-index", wheel],
        cwd=tmp,
        env=os.environ,
    )
    for path in (site, *site.rglob("*")):  # read-only, as a system's site-packages
        if not path.is_symlink():
            path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith(("NUMBA_CACHE_DIR", "PYTHONPATH", "VIRTUAL_ENV", "PYTEST", "COV_"))
    }
    env.update(
        PATH=f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}",
        HOME=str(tmp / "home"),
        XDG_CACHE_HOME=str(tmp / "cache"),
        MPLBACKEND="Agg",
        PYTHONWARNINGS="ignore::DeprecationWarning",
    )
    work = tmp / "work"
    work.mkdir()
    yield wheel, python, env, work, site
    for path in (site, *site.rglob("*")):  # pytest may remove the folder
        if not path.is_symlink():
            path.chmod(path.stat().st_mode | stat.S_IWUSR)


#: What ``python -m build`` printed in the fixture :func:`installed`.
_BUILD_OUTPUT: list[str] = []


def test_the_build_gives_no_warning_of_setuptools(installed):
    """No package data outside a declared package, no deprecated license table: the warnings setuptools turns
    into errors later."""
    printed = "\n".join(_BUILD_OUTPUT)
    assert "absent from the `packages` configuration" not in printed
    assert "`project.license` as a TOML table is deprecated" not in printed
    assert not [line for line in printed.splitlines() if line.startswith("WARNING")]


def test_the_wheel_carries_what_the_packages_read_and_nothing_else(installed):
    wheel = installed[0]
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == set(TOP)  # no top-level baselines or agents, no tests, benchmarks, experiments or docs
    for data in DATA:
        assert any(n.startswith(data) for n in names), f"the wheel lacks {data}"
    assert not [n for n in names if "__pycache__" in n or n.endswith((".nbi", ".nbc", ".pyc"))]
    entry_points = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith("entry_points.txt"))).decode()
    assert "vcnc-train = vcnc_agents.cli:main" in entry_points and "[vcnc_bench.policy_kinds]" in entry_points


def test_the_installed_wheel_runs_beside_other_baselines_and_agents(installed):
    _, python, env, work, site = installed
    read_only = _read_only(site)
    code = f"""
import os, gymnasium as gym, numpy as np
import baselines, agents
assert (baselines.WHO, agents.WHO) == {tuple(OTHERS.values())!r}, (baselines.WHO, agents.WHO)
import vcnc_gym, vcnc_baselines, vcnc_agents, vcnc_bench
for m in (vcnc_gym, vcnc_baselines, vcnc_agents, vcnc_bench):
    assert m.__file__.startswith({str(site)!r}), m.__file__
assert not os.access(os.path.dirname(vcnc_gym.__file__), os.W_OK)
assert "VCNC-Heart-v1" in vcnc_agents.TRAINED
env = gym.make({ENV!r})
obs, _ = env.reset(seed=0)
obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
assert np.all(np.isfinite(obs)) and not terminated
print(vcnc_baselines.make("pi", env).predict(obs)[0])
"""
    _run([*read_only, python, "-c", code], cwd=work, env=env)
    out = _run([*read_only, python, "-m", "vcnc_gym.warmup", "--ids", ENV, "--jobs", "1"], cwd=work, env=env).stdout
    assert "done in" in out and "FAILED" not in out
    numba_cache = Path(env["XDG_CACHE_HOME"])
    assert any(numba_cache.rglob("*.nbi")), "numba found no writable cache folder"


@pytest.mark.slow  # 32 s in CI (the commands compile their laws and import torch afresh): make test-all
def test_the_installed_commands_run(installed):
    _, python, env, work, site = installed
    read_only, bin_dir = _read_only(site), python.parent
    _run(
        [
            *read_only,
            bin_dir / "vcnc-bench",
            "--env",
            ENV,
            "--policy",
            "pi",
            "--json",
            "bench.json",
            "--no-progress",
            "--jobs",
            "1",
        ],
        cwd=work,
        env=env,
    )
    records = json.loads((work / "bench.json").read_text())["records"]
    assert (ENV, "pi") in [(r.get("env"), r.get("policy")) for r in records]
    _run(
        [
            *read_only,
            bin_dir / "vcnc-train",
            "--env",
            ENV,
            "--timesteps",
            "1",
            "--n-envs",
            "2",
            "--no-progress",
            "--no-tensorboard",
            "--output",
            "run",
        ],
        cwd=work,
        env=env,
    )  # one PPO rollout
    assert (work / "run" / "config.yml").is_file() and (work / "run" / "final").is_dir()
    help_text = _run([*read_only, bin_dir / "vcnc-datasets", "--help"], cwd=work, env=env).stdout
    assert "vcnc-datasets" in help_text


def test_a_missing_extra_is_named(installed):
    """Without python-control the controllers' import names the extra to install."""
    _, python, env, work, site = installed
    proc = subprocess.run(
        [*_read_only(site), python, "-c", "import sys; sys.modules['control'] = None; import vcnc_baselines"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode != 0
    assert "pip install 'vcnc-gym[baselines]'" in proc.stderr.strip().splitlines()[-1]
