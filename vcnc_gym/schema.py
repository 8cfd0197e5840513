"""Checks of the files a user passes: one reading, one wording of the error, for every layer.

A file the suite reads back (a leaderboard's rows, a ``vcnc-train --seeds`` folder's ``seeds.json``, a
commissioning record, a stored floor) is checked on load as the suite builds it: each field its type and range.
What is wrong is a :class:`BadFile`, a ``ValueError`` whose message is one line naming the file, and the field or
the line::

    board.json: rows[3].max_um must be finite (um), got nan
    seeds.json: not JSON: Expecting ',' delimiter at line 4, column 2

:func:`read_json` reads and parses a file (refusing what is not UTF-8, not JSON, or nested deeper than
:data:`MAX_DEPTH`); the field rules (:func:`mapping`, :func:`sequence`, :func:`text`, :func:`number`,
:func:`choice`, :func:`maybe`, and the rules of :mod:`vcnc_gym.validation`) raise a ``ValueError`` naming the
field; :func:`checked` turns those into a :class:`BadFile` naming the file::

    with checked(path):
        data = mapping("the record", read_json(path), required=("axes",))
        dt = positive("dt", data["dt"], "s")
"""

from __future__ import annotations

import json
import math
import numbers
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from .validation import integer, real

__all__ = [
    "BadFile",
    "MAX_DEPTH",
    "read_json",
    "depth",
    "checked",
    "kind",
    "mapping",
    "sequence",
    "text",
    "number",
    "choice",
    "maybe",
    "count",
]

#: Deepest nesting of the objects and lists a file may hold (ours): the suite's own files nest at most 6 levels (a
#: leaderboard row's verdicts); a deeper file is not one of them, and the code that walks it must not recurse
#: without bound.
MAX_DEPTH = 32


class BadFile(ValueError):
    """A file that is not what it should be; ``str()`` is one line, ``"PATH: what is wrong"``.

    Attributes
    ----------
    path : Path
        The file.
    problem : str
        What is wrong, naming the field or the line.
    """

    def __init__(self, path, problem: str):
        self.path = Path(path)
        self.problem = " ".join(str(problem).split())  # one line, whatever the cause's message held
        super().__init__(f"{self.path}: {self.problem}")


def kind(value) -> str:
    """What a parsed JSON value is, in JSON's words ("an object", "a list", "a string", "null", ...)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"{str(value).lower()} (a boolean)"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, (list, tuple)):
        return "a list"
    if isinstance(value, str):
        return f"the string {_short(value)}"
    if isinstance(value, numbers.Real):
        return f"the number {value!r}"
    return type(value).__name__


def _short(value, most: int = 40) -> str:
    s = repr(value)
    return s if len(s) <= most else s[: most - 3] + "..."


def depth(value) -> int:
    """How deeply ``value`` nests objects and lists (a scalar: 0; ``[]``: 1), without recursion."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, dict):
            items = v.values()
        elif isinstance(v, (list, tuple)):
            items = v
        else:
            continue
        deepest = max(deepest, d)
        if d <= MAX_DEPTH:  # deeper is refused anyway: no need to walk it
            stack.extend((x, d + 1) for x in items)
    return deepest


def read_json(path, what: str = "") -> Any:
    """The parsed content of the JSON file ``path``; :class:`BadFile` if it cannot be read, is not UTF-8 text,
    is not JSON (the line and column named) or nests deeper than :data:`MAX_DEPTH`.  ``what``: what the file
    should be, for the messages ("a leaderboard's rows")."""
    path = Path(path)
    should = f" ({what})" if what else ""
    try:
        raw = path.read_bytes()
    except IsADirectoryError:
        raise BadFile(path, f"is a folder, not a file{should}") from None
    except OSError as exc:
        raise BadFile(path, f"cannot be read: {exc.strerror or exc}") from None
    try:
        text_ = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise BadFile(path, f"is not UTF-8 text{should}: byte {exc.start}") from None
    deep = BadFile(
        path,
        f"nests objects or lists deeper than {MAX_DEPTH} levels: "
        + (f"it is not {what}" if what else "no file of the suite does"),
    )
    try:
        data = json.loads(text_)
    except json.JSONDecodeError as exc:
        where = "empty" if not text_.strip() else f"{exc.msg} at line {exc.lineno}, column {exc.colno}"
        raise BadFile(path, f"is not JSON{should}: {where}") from None
    except RecursionError:  # the parser's own stack: deeper still
        raise deep from None
    if depth(data) > MAX_DEPTH:
        raise deep
    return data


@contextmanager
def checked(path):
    """Within it, a ``ValueError`` (a field rule's) becomes a :class:`BadFile` naming ``path``; a BadFile passes
    as it is."""
    try:
        yield
    except BadFile:
        raise
    except ValueError as exc:
        raise BadFile(path, str(exc)) from None


def mapping(name: str, value, required=(), known=None) -> dict:
    """``value`` if it is a JSON object holding every key of ``required`` (and, with ``known``, no key outside
    ``required`` and ``known``); else ValueError naming ``name`` and the key."""
    if not isinstance(value, dict):
        raise ValueError(f"{name} must be an object {{...}}, got {kind(value)}")
    missing = [k for k in required if k not in value]
    if missing:
        more = f" (nor {len(missing) - 1} other field(s) of {list(required)})" if len(missing) > 1 else ""
        raise ValueError(f"{name} has no field {missing[0]!r}{more}")
    if known is not None:
        extra = [k for k in value if k not in required and k not in known]
        if extra:
            raise ValueError(f"{name} has a field {_short(extra[0])} that is not one of {sorted({*required, *known})}")
    return value


def sequence(name: str, value, length: int | None = None, minimum: int = 0) -> list:
    """``value`` if it is a JSON list (of ``length`` items, or at least ``minimum``); else ValueError naming
    ``name``."""
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{name} must be a list [...], got {kind(value)}")
    if length is not None and len(value) != length:
        raise ValueError(f"{name} must hold {length} items, got {len(value)}")
    if len(value) < minimum:
        raise ValueError(f"{name} must hold at least {minimum} item(s), got {len(value)}")
    return list(value)


def text(name: str, value, empty: bool = False) -> str:
    """``value`` if it is a string (not empty unless ``empty``); else ValueError naming ``name``."""
    if not isinstance(value, str):
        raise ValueError(f"{name} must be a string, got {kind(value)}")
    if not empty and not value:
        raise ValueError(f"{name} must not be empty")
    return value


def number(name: str, value, unit: str = "", *, minimum: float | None = None, infinite: bool = False) -> float:
    """``value`` as a float if it is a real number (finite unless ``infinite``; at least ``minimum``); else
    ValueError naming ``name`` (:func:`vcnc_gym.validation.real`'s wording)."""
    if infinite and isinstance(value, float) and math.isinf(value):
        v = value
    else:
        v = real(name, value, unit)
    if minimum is not None and not v >= minimum:
        raise ValueError(f"{name} must be >= {minimum:g}{f' ({unit})' if unit else ''}, got {value!r}")
    return v


def count(name: str, value, minimum: int = 0, maximum: int | None = None) -> int:
    """``value`` if it is an integer in [minimum, maximum] (:func:`vcnc_gym.validation.integer`)."""
    return integer(name, value, minimum, maximum)


def choice(name: str, value, choices) -> str:
    """``value`` if it is one of ``choices``; else ValueError naming ``name`` and them."""
    if isinstance(value, (dict, list)) or value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}, got {kind(value)}")
    return value


def maybe(rule, name: str, value, *args, **kwargs):
    """None if ``value`` is None (JSON's null), else ``rule(name, value, *args, **kwargs)``."""
    return None if value is None else rule(name, value, *args, **kwargs)
