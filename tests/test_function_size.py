"""Functions a reader can hold: no function of the four packages longer than 80 code lines.

Complexity is held by ruff (``C901``, max-complexity 15, ``pyproject.toml``, ``make lint``); length here, by
walking every module's syntax tree with :mod:`ast`.  A code line is a line of the function's source that is not
blank, not only a comment and not part of its docstring; a nested function's lines count for the function that
holds it too.  Compiled numba kernels (decorated ``njit``, ``jit``, ``overload`` and the like) are exempt: a
kernel inlines its steps on purpose (a call between two compiled functions passes every array of a record).
"""

from __future__ import annotations

import ast
import io
import tokenize

from package_layout import ROOT, TOP

MAX_CODE_LINES = 80
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


def _comment_or_blank_lines(source: str) -> set[int]:
    """Line numbers (1-based) holding no token but comments and newlines."""
    code = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in (
            tokenize.COMMENT,
            tokenize.NL,
            tokenize.NEWLINE,
            tokenize.INDENT,
            tokenize.DEDENT,
            tokenize.ENDMARKER,
        ):
            code.update(range(tok.start[0], tok.end[0] + 1))
    return set(range(1, source.count("\n") + 2)) - code


def code_lines(fn: ast.FunctionDef, not_code: set[int]) -> int:
    """Code lines of ``fn``: its lines (decorators excluded) less the blank, comment and docstring ones."""
    lines = set(range(fn.lineno, fn.end_lineno + 1)) - not_code
    body = fn.body[0] if fn.body else None
    if isinstance(body, ast.Expr) and isinstance(body.value, ast.Constant) and isinstance(body.value.value, str):
        lines -= set(range(body.lineno, body.end_lineno + 1))
    return len(lines)


def long_functions(source: str, name: str = "<source>") -> list[tuple[str, int]]:
    """(``name:line function``, code lines) of every non-kernel function of ``source`` over the limit."""
    tree = ast.parse(source)
    candidates = [
        node
        for node in ast.walk(tree)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        and not _is_kernel(node)
        and node.end_lineno - node.lineno + 1 > MAX_CODE_LINES
    ]
    not_code = _comment_or_blank_lines(source) if candidates else set()  # tokenized only where it can matter
    out = []
    for node in candidates:
        n = code_lines(node, not_code)
        if n > MAX_CODE_LINES:
            out.append((f"{name}:{node.lineno} {node.name}", n))
    return out


def _function(code_lines_: int, decorator: str = "") -> str:
    """A function of ``code_lines_`` code lines (def line and return included), padded with a docstring,
    blank lines, comment lines and trailing comments that must not count."""
    body = "\n".join(f"    x{k} = {k}  # a trailing comment" for k in range(code_lines_ - 2))
    return (
        f'{decorator}def f():\n    """A docstring\n    of three\n    lines."""\n\n    # only a comment\n\n'
        f"{body}\n\n    return (\n        x0\n    )\n"
    )


def test_the_counter_counts_code_lines_only():
    # the return spans 3 lines: 1 def + (n - 2) assignments + 3 = n + 2 code lines
    assert long_functions(_function(MAX_CODE_LINES - 2)) == []
    assert long_functions(_function(MAX_CODE_LINES - 1)) == [("<source>:1 f", MAX_CODE_LINES + 1)]
    assert long_functions(_function(MAX_CODE_LINES + 40, "@numba.njit(cache=True)\n")) == []  # a kernel
    assert long_functions(_function(MAX_CODE_LINES + 40, "@njit\n")) == []


def test_no_function_is_longer_than_80_code_lines():
    found = []
    for top in TOP.values():
        for path in sorted(top.rglob("*.py")):
            found += long_functions(path.read_text(encoding="utf-8"), str(path.relative_to(ROOT)))
    assert not found, "split these into named steps (<= 80 code lines each): " + ", ".join(
        f"{where} ({n} lines)" for where, n in found
    )
