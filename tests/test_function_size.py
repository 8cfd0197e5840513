"""Functions a reader can hold: no function of the four packages with more than 60 statements.

Complexity is held by ruff (``C901``, max-complexity 15, ``pyproject.toml``, ``make lint``); length here, by
walking every module's syntax tree with :mod:`ast` and counting statements (the lines they start on), which
``ruff format`` cannot change by wrapping a long call; a nested function's statements count for the function that
holds it too.  Compiled numba kernels (decorated ``njit``, ``jit``, ``overload`` and the like) are exempt: a
kernel inlines its steps on purpose (a call between two compiled functions passes every array of a record).
"""

from __future__ import annotations

import ast

from package_layout import ROOT, TOP

MAX_STATEMENTS = 60
#: Decorators of compiled numba code (by their last name: ``numba.njit``, ``njit(cache=True)``, ...).
KERNEL_DECORATORS = {
    "njit",
    "jit",
    "overload",
    "overload_method",
    "overload_attribute",
    "register_jitable",
    "intrinsic",
    "vectorize",
    "guvectorize",
    "generated_jit",
    "cfunc",
}


def _decorator_name(node: ast.expr) -> str:
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute):
        return node.attr
    return node.id if isinstance(node, ast.Name) else ""


def _is_kernel(fn: ast.FunctionDef) -> bool:
    return any(_decorator_name(d) in KERNEL_DECORATORS for d in fn.decorator_list)


def statements(fn: ast.FunctionDef) -> int:
    """The statements of ``fn``, by the lines they start on: its ``def``, every statement of its body (a nested
    function's count for the function that holds it too), not its docstring.  A formatter that wraps a long call
    over several lines does not change the count."""
    lines = {node.lineno for node in ast.walk(fn) if isinstance(node, ast.stmt)}
    body = fn.body[0] if fn.body else None
    if isinstance(body, ast.Expr) and isinstance(body.value, ast.Constant) and isinstance(body.value.value, str):
        lines.discard(body.lineno)
    return len(lines)


def long_functions(source: str, name: str = "<source>") -> list[tuple[str, int]]:
    """(``name:line function``, statements) of every non-kernel function of ``source`` over the limit."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _is_kernel(node):
            n = statements(node)
            if n > MAX_STATEMENTS:
                out.append((f"{name}:{node.lineno} {node.name}", n))
    return out


def _function(statements_: int, decorator: str = "") -> str:
    """A function of ``statements_`` statements (def line and return included), padded with a docstring,
    blank lines, comments and a statement wrapped over three lines, which count once."""
    body = "\n".join(f"    x{k} = {k}  # a trailing comment" for k in range(statements_ - 2))
    return (
        f'{decorator}def f():\n    """A docstring\n    of three\n    lines."""\n\n    # only a comment\n\n'
        f"{body}\n\n    return (\n        x0\n    )\n"
    )


def test_the_counter_counts_statements_only():
    assert long_functions(_function(MAX_STATEMENTS)) == []
    assert long_functions(_function(MAX_STATEMENTS + 1)) == [("<source>:1 f", MAX_STATEMENTS + 1)]
    assert long_functions(_function(MAX_STATEMENTS + 40, "@numba.njit(cache=True)\n")) == []  # a kernel
    assert long_functions(_function(MAX_STATEMENTS + 40, "@njit\n")) == []


def test_no_function_has_more_than_60_statements():
    found = []
    for top in TOP.values():
        for path in sorted(top.rglob("*.py")):
            found += long_functions(path.read_text(encoding="utf-8"), str(path.relative_to(ROOT)))
    assert not found, f"split these into named steps (<= {MAX_STATEMENTS} statements each): " + ", ".join(
        f"{where} ({n} statements)" for where, n in found
    )
