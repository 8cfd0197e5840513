"""Sphinx extension: the numpydoc types of parameters and attributes shown as text, not as cross-references.

A numpydoc type is prose for a reader: ``ndarray, (n_envs, 2)``, ``float, optional``, ``callable (arrays, k)
-> None``.  Napoleon turns it into a ``:type:`` or ``:vartype:`` field, and Sphinx's Python domain then makes a
cross-reference of every word in it (``n_envs``, ``2``, ``optional``), which resolves to nothing or, for a word
such as ``params`` that several classes have as an attribute, to several targets.  This extension runs after
napoleon and writes such a type as emphasised text, as napoleon writes the types of a Returns section.  A type
that holds a role (``:class:`~vcnc_gym.plants.PlantModel```) stays as written: that is a link its author asked for.

An attribute entry naming several attributes (``kp, kd, ki : ndarray``) becomes one entry per name, as napoleon
does for the parameters: Sphinx would read ``:ivar kp, kd, ki:`` as the attribute ``ki`` of type ``kp, kd,``.
"""

from __future__ import annotations

import re

#: ``:type name: text``, ``:vartype name: text`` and ``:rtype: text`` field lines, as napoleon writes them
_FIELD = re.compile(r"^(?P<head>\s*:(?:type|vartype)\s+[^:]+:|\s*:rtype:)\s*(?P<text>.+?)\s*$")


def _plain(text: str) -> str:
    """``text`` as emphasised text that no role reads (its ``*`` and backslashes escaped)."""
    escaped = text.replace("\\", "\\\\").replace("*", "\\*").replace("`", "\\`")
    return f"*{escaped}*"


#: ``:ivar a, b: text`` and ``:vartype a, b: text``: an attribute field naming several attributes
_SEVERAL = re.compile(r"^(?P<indent>\s*):(?P<kind>ivar|vartype) (?P<names>[^:]+,[^:]+):(?P<rest>.*)$")


def _one_entry_per_name(lines: list[str]) -> list[str]:
    """``:ivar a, b: text`` (with its continuation lines) as ``:ivar a: text`` and ``:ivar b: text``."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        m = _SEVERAL.match(lines[i])
        if not m:
            out.append(lines[i])
            i += 1
            continue
        body = [m.group("rest")]
        i += 1
        while i < len(lines) and lines[i].startswith(m.group("indent") + " ") and lines[i].strip():
            body.append(lines[i])
            i += 1
        for name in (n.strip() for n in m.group("names").split(",")):
            out.append(f"{m.group('indent')}:{m.group('kind')} {name}:{body[0]}")
            out.extend(body[1:])
    return out


def _attribute_as_written(what: str, lines: list[str]) -> None:
    """An attribute's docstring as its author wrote it.

    Napoleon reads the first line of an attribute's, a constant's or a property's docstring as ``type: text`` when
    it holds a colon, and moves what stands before the colon to a ``:type:`` field.  This project writes such a
    line as prose (``Corner blending tolerance, mm (10 um: a finishing pass's).``), so the two parts are joined
    again.
    """
    if what in ("attribute", "data", "property") and len(lines) >= 2 and lines[-1].startswith(":type: "):
        if lines[-2] == "":
            kind = lines[-1][len(":type: ") :]
            lines[:] = [f"{kind}: {lines[0]}" if lines[0] else kind] + lines[1:-2]


def plain_types(app, what, name, obj, options, lines: list[str]) -> None:
    """Rewrite the type fields of one docstring (autodoc-process-docstring, after napoleon's)."""
    _attribute_as_written(what, lines)
    lines[:] = _one_entry_per_name(lines)
    for i, line in enumerate(lines):
        m = _FIELD.match(line)
        if m and "`" not in m.group("text"):
            lines[i] = f"{m.group('head')} {_plain(m.group('text'))}"


def setup(app):
    # napoleon processes docstrings at the default priority (500); this runs after it
    app.connect("autodoc-process-docstring", plain_types, priority=600)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
