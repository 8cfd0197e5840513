"""The house's layers: every import of the four packages, lazy ones included, runs downward, and no module imports
itself round a loop: 0 upward arrows, 0 circles (``pytest tests/test_layers.py``).

The order, from the ground: ``vcnc_gym`` (envs, plants, contours), ``vcnc_baselines`` (the classical controllers,
folder ``baselines/``), ``vcnc_agents`` (training, and the agents that correct a baseline, folder ``agents/``),
``vcnc_bench`` (the bench that runs them all, its
policy kinds in ``vcnc_bench/kinds``).

Within each package its parts (subpackages and top modules) import one way; within ``vcnc_agents`` the modules
stand on at most :data:`AGENTS_MAX_FLOORS` floors, its storage on leaves.
"""

from __future__ import annotations

import ast
import functools

import pytest
from package_layout import TOP, module_name

LAYERS = tuple(TOP)  # from the ground: vcnc_gym, vcnc_baselines, vcnc_agents, vcnc_bench


@functools.cache
def _imports() -> dict[str, set[str]]:
    """Module -> the project modules it imports anywhere in its text (top level or inside a function); read once
    per session (do not change what it returns)."""
    modules = {module_name(p): p for layer in LAYERS for p in TOP[layer].rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")
                    anchor = anchor[: len(anchor) - node.level + 1]
                    base = ".".join(anchor + ([base] if base else []))
                targets = [f"{base}.{a.name}" for a in node.names]  # a name, or a module of the package
            else:
                continue
            for t in targets:
                while t and t not in modules:  # "pkg.mod.Name" -> "pkg.mod"
                    t = t.rpartition(".")[0]
                if t and t != name:
                    found.add(t)
        graph[name] = found
    return graph


def _layer(module: str) -> int:
    return LAYERS.index(module.split(".")[0])


def test_every_import_runs_down_the_layers():
    graph = _imports()
    assert len(graph) > 100 and set(LAYERS) <= set(graph)
    # the reading sees relative, absolute and lazy imports
    assert "vcnc_baselines.commissioning.design" in graph["vcnc_baselines.servo"]
    assert "vcnc_baselines.registry" in graph["vcnc_bench.kinds.baseline"]
    assert "vcnc_agents" in graph["vcnc_bench.kinds.ppo"] and "vcnc_agents.policy" in graph["vcnc_bench.kinds.ppo"]
    upward = sorted(f"{m} -> {d}" for m, deps in graph.items() for d in deps if _layer(d) > _layer(m))
    assert upward == []


def test_no_module_imports_itself_round_a_loop():
    """Packages (their ``__init__``) count as modules: a module that imports its own package's face, which imports
    it back, is a loop too."""
    graph = _imports()
    done, loops = set(), []

    def visit(module, path):
        for dep in sorted(graph.get(module, ())):
            if dep in path:
                loops.append(path[path.index(dep) :] + [dep])
            elif dep not in done:
                visit(dep, path + [dep])
        done.add(module)

    for module in sorted(graph):
        visit(module, [module])
    assert loops == []


def _part(module: str) -> str:
    """The part of its package a module belongs to: the subpackage or top module right under the package (the
    package's own ``__init__`` is a part of its own)."""
    parts = module.split(".")
    return ".".join(parts[:2])


@pytest.mark.parametrize("package", LAYERS)
def test_the_parts_of_each_package_import_one_way(package):
    """Within a package, its parts (each subpackage and each top module: ``vcnc_baselines.commissioning``,
    ``vcnc_baselines.feedforward``, ``vcnc_baselines.servo``, ...) import one way, with no loop between two parts
    even when their modules make none: a module of a lower part that needs a higher part's code has that code moved
    down (the commissioning's identification and the feedforward controllers share
    ``vcnc_baselines.inverse_model``)."""
    graph = _imports()
    arrows: dict[str, set[str]] = {}
    for module, deps in graph.items():
        if module.split(".")[0] == package:
            for dep in deps:
                if dep.split(".")[0] == package and _part(dep) != _part(module):
                    arrows.setdefault(_part(module), set()).add(_part(dep))
    if package == "vcnc_baselines":  # the reading sees the parts' arrows
        assert {"vcnc_baselines.commissioning", "vcnc_baselines.inverse_model"} <= arrows["vcnc_baselines.feedforward"]
    done, loops = set(), []

    def visit(part, path):
        for dep in sorted(arrows.get(part, ())):
            if dep in path:
                loops.append(path[path.index(dep) :] + [dep])
            elif dep not in done:
                visit(dep, path + [dep])
        done.add(part)

    for part in sorted(arrows):
        visit(part, [part])
    assert loops == []


#: The most floors ``vcnc_agents`` (``agents/``) may stand on (it stood on 11): floor 1 is a module that imports no other
#: module of the package, and a module stands one floor above the highest it imports (:func:`_floors`).
AGENTS_MAX_FLOORS = 7

#: The storage and IO of ``vcnc_agents``: the run folder, the model file, the normalisation file, the env signature an
#: agent records and the run's warnings.  Each imports no module of the package but leaves.
AGENTS_STORAGE = (
    "vcnc_agents.run_folder",
    "vcnc_agents.model_file",
    "vcnc_agents.normalization",
    "vcnc_agents.signature",
    "vcnc_agents.run_warning",
)


def _floors(package: str) -> dict[str, int]:
    """Module of ``package`` -> its floor among the package's modules (1: imports none of them)."""
    graph = _imports()
    inside = {
        m: {d for d in deps if d == package or d.startswith(package + ".")}
        for m, deps in graph.items()
        if m == package or m.startswith(package + ".")
    }
    floors: dict[str, int] = {}

    def floor(module: str) -> int:
        if module not in floors:
            floors[module] = 1 + max((floor(d) for d in inside[module]), default=0)
        return floors[module]

    for module in inside:
        floor(module)
    return floors


def test_the_agents_package_stands_on_at_most_seven_floors_with_its_storage_on_leaves():
    floors = _floors("vcnc_agents")
    assert {
        "vcnc_agents",
        "vcnc_agents.cli",
        "vcnc_agents.training",
        "vcnc_agents.lean_ppo",
        "vcnc_agents.run_session",
    } <= set(floors)
    assert (
        floors["vcnc_agents.cli"] > floors["vcnc_agents.training"] > floors["vcnc_agents.run_session"] > 1
    )  # the reading sees
    too_high = {m: f for m, f in floors.items() if f > AGENTS_MAX_FLOORS}
    assert too_high == {}, f"above floor {AGENTS_MAX_FLOORS}: {too_high}"
    graph = _imports()
    for module in AGENTS_STORAGE:
        above_ground = sorted(d for d in graph[module] if d.startswith("vcnc_agents") and floors[d] > 1)
        assert above_ground == [], f"{module} is storage and imports {above_ground}"
