"""The env classes' signatures as ``help()`` and ``inspect.signature`` show them.

The env classes hand most of their arguments on: an env to :class:`~vcnc_gym.envs.task.ContouringTask`, a
G-code env to the program reader and the contouring env, an override env to the contouring env.  Writing the
22 task arguments again in every class would be five copies to keep in step; instead each class takes
``**kwargs`` and sets :func:`forwarded_signature` as its ``__init__.__signature__``, which shows every argument
it accepts, with its default, while ``gym.make(id, **kwargs)`` passes them as before.
``tests/test_signatures.py`` holds the signatures against the docstrings' argument lists.
"""

from __future__ import annotations

import inspect

__all__ = ["forwarded_signature"]


def forwarded_signature(init, *targets, drop=()) -> inspect.Signature:
    """``init``'s signature with its ``**kwargs`` replaced by the keyword arguments it forwards: those of
    ``targets`` (callables, in order) that ``init`` does not name itself, less ``drop`` (those it refuses or
    sets), each keyword-only with the target's default."""
    own = inspect.signature(init)
    params = [p for p in own.parameters.values() if p.kind is not p.VAR_KEYWORD]
    seen = {p.name for p in params} | set(drop) | {"self"}
    for target in targets:
        for p in inspect.signature(target).parameters.values():
            if p.name not in seen and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
                params.append(p.replace(kind=p.KEYWORD_ONLY))
                seen.add(p.name)
    return own.replace(parameters=params)
