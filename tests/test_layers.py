"""The house's layers: every import of the four packages, lazy ones included, runs downward, and no module imports
itself round a loop (what ``farm-studio look`` draws: 0 upward arrows, 0 circles).

The order, from the ground: ``vcnc_gym`` (envs, plants, contours), ``baselines`` (the classical controllers),
``agents`` (training, and the agents that correct a baseline), ``vcnc_bench`` (the bench that runs them all, its
policy kinds in ``vcnc_bench/kinds``).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("vcnc_gym", "baselines", "agents", "vcnc_bench")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports() -> dict[str, set[str]]:
    """Module -> the project modules it imports anywhere in its text (top level or inside a function)."""
    modules = {_module_name(p): p for layer in LAYERS for p in (ROOT / layer).rglob("*.py")}
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
                    anchor = anchor[:len(anchor) - node.level + 1]
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
    assert "baselines.commissioning.design" in graph["baselines.servo"]
    assert "baselines.registry" in graph["vcnc_bench.kinds.baseline"]
    assert "agents" in graph["vcnc_bench.kinds.ppo"] and "agents.policy" in graph["vcnc_bench.kinds.ppo"]
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
                loops.append(path[path.index(dep):] + [dep])
            elif dep not in done:
                visit(dep, path + [dep])
        done.add(module)

    for module in sorted(graph):
        visit(module, [module])
    assert loops == []

