"""Sphinx extension: a cross-reference to a public name finds the object where the API pages document it.

The API pages document every object once, in the module that defines it (``ignore-module-all``), while the code's
docstrings name objects as a user imports them: ``vcnc_gym.envs.ContouringEnv`` (defined in
``vcnc_gym.envs.contouring_env``), ``vcnc_agents.load_agent``, or a method a class inherits (``:meth:`from_env```
in a controller's docstring, defined on ``vcnc_baselines.base.BaselinePolicy``).  Sphinx's Python domain looks
for the name as written and finds nothing.  This extension runs when it finds nothing (``missing-reference``):
it imports the object the name denotes, in the referring module and class, and links to the documented object
that *is* it.  It only adds links to the project's own objects; a name that denotes none stays unresolved, and
with ``-n`` (nitpicky) Sphinx reports it.
"""

from __future__ import annotations

import importlib

#: The packages whose objects the API pages document.
PACKAGES = ("vcnc_gym", "vcnc_baselines", "vcnc_agents", "vcnc_bench")


def _locate(path: str):
    """The object at dotted ``path`` (the longest importable module prefix, then attributes), or None."""
    parts = path.split(".")
    if parts[0] not in PACKAGES:
        return None
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except Exception:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj
    return None


def _unwrap(obj):
    """A bound or class method's function, a property's getter, else the object itself."""
    return getattr(obj, "__func__", getattr(obj, "fget", obj))


def _same(a, b) -> bool:
    """Whether two located objects are one (a method reached through a subclass is its function)."""
    return a is b or _unwrap(a) is _unwrap(b)


def _documented_as(obj, last: str, objects) -> str | None:
    """The documented name (a key of the Python domain's objects) that denotes ``obj``; None if there is none."""
    matches = [name for name in objects if name.rsplit(".", 1)[-1] == last]
    found = [name for name in matches if _same(_locate(name), obj)]
    return found[0] if len(found) == 1 else None


def resolve(app, env, node, contnode):
    """``missing-reference``: the documented object the reference's name denotes where it is written."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    module, cls = node.get("py:module"), node.get("py:class")
    paths = [target]
    if module:
        if cls:
            paths.append(f"{module}.{cls}.{target}")
        paths.append(f"{module}.{target}")
    domain = env.get_domain("py")
    for path in paths:
        obj = _locate(path)
        if obj is None:
            continue
        name = _documented_as(obj, target.rsplit(".", 1)[-1], domain.objects)
        if name is not None:
            return domain.resolve_xref(env, node["refdoc"], app.builder, "obj", name, node, contnode)
    return None


def setup(app):
    app.connect("missing-reference", resolve)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
