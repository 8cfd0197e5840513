"""The optional extras of ``pip install vcnc-gym[...]``: an import that needs one names it.

``vcnc_baselines`` and ``vcnc_agents`` stand on packages that a plain ``pip install
vcnc-gym`` does not install (``pyproject.toml``'s
``[project.optional-dependencies]``).  Each checks its extra when it is
imported (:func:`require_extra`), so a missing package ends in a
``ModuleNotFoundError`` that says which extra to install, instead of one
naming a module (``No module named 'control'``) of someone else's.  G-code
reading checks ``pygcode`` the same way when it first lexes
(:mod:`vcnc_gym.gcode.lexer`).
"""

from __future__ import annotations

import importlib.util

__all__ = ["EXTRAS", "missing_modules", "require_extra"]

#: Extra -> (import name, distribution name) of each package it installs, as ``pyproject.toml`` lists them.
EXTRAS: dict[str, tuple[tuple[str, str], ...]] = {
    "baselines": (("scipy", "scipy"), ("control", "control"), ("daqp", "daqp"), ("threadpoolctl", "threadpoolctl")),
    "agents": (
        ("stable_baselines3", "stable-baselines3"),
        ("sb3_contrib", "sb3-contrib"),
        ("torch", "torch"),
        ("yaml", "pyyaml"),
        ("tqdm", "tqdm"),
        ("rich", "rich"),
    ),
    "gcode": (("pygcode", "pygcode"),),
    "datasets": (("minari", "minari"), ("h5py", "h5py")),
}


def missing_modules(extra: str) -> list[str]:
    """The distributions of ``extra`` whose module cannot be found (none imported: a lookup only)."""
    if extra not in EXTRAS:
        raise ValueError(f"extra must be one of {sorted(EXTRAS)}, got {extra!r}")
    missing = []
    for module, distribution in EXTRAS[extra]:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):  # a parent that fails, or a module without a spec
            found = False
        if not found:
            missing.append(distribution)
    return missing


def require_extra(extra: str, package: str) -> None:
    """ModuleNotFoundError naming ``extra`` and the command that installs it unless all its modules are found.

    Parameters
    ----------
    extra : str
        A key of :data:`EXTRAS` ("baselines", "agents", "gcode", "datasets").
    package : str
        What is being imported (for the message), e.g. ``"vcnc_baselines"``.
    """
    missing = missing_modules(extra)
    if missing:
        module = dict((d, m) for m, d in EXTRAS[extra])[missing[0]]
        raise ModuleNotFoundError(
            f"{package} needs the '{extra}' extra of vcnc-gym, which is not installed (missing: "
            f"{', '.join(missing)}): pip install 'vcnc-gym[{extra}]'",
            name=module,
        )
