"""Baselines by name: ``baselines.make("qft", env)``.

The registry maps a name to a policy class; :func:`make` builds it for an env
from ``env.unwrapped`` (observation layout, decision period, nominal plant)
and the keyword parameters, whose defaults are the seed's values.
"""

from __future__ import annotations

import inspect

from .base import BaselinePolicy
from .fuzzy import FuzzyPolicy
from .qft import QFTPolicy
from .smc import SlidingModePolicy

__all__ = ["make", "names", "policy_class", "REGISTRY"]

#: Name -> policy class, one entry per classical controller of seed 000.
REGISTRY: dict[str, type[BaselinePolicy]] = {
    "qft": QFTPolicy,
    "smc": SlidingModePolicy,
    "fuzzy": FuzzyPolicy,
}

_FROM_ENV = ("layout", "decision_period", "nominal_parameters")


def names() -> list[str]:
    """Registered baseline names, sorted."""
    return sorted(REGISTRY)


def policy_class(name: str) -> type[BaselinePolicy]:
    """The class registered under ``name``; ValueError for an unknown name."""
    if not isinstance(name, str) or name not in REGISTRY:
        raise ValueError(f"unknown baseline {name!r}; known baselines are {names()}")
    return REGISTRY[name]


def make(name: str, env, **params) -> BaselinePolicy:
    """Build baseline ``name`` for ``env``.

    Parameters
    ----------
    name : str
        One of :func:`names`: "qft", "smc" or "fuzzy".
    env : gymnasium.Env or stable_baselines3 VecEnv
        A vcnc_gym contouring env (possibly wrapped; its ``unwrapped``
        supplies ``layout``, ``decision_period`` (s) and
        ``nominal_parameters`` (2, P)), or a VecEnv of them.
    **params
        Constructor parameters of the policy class (e.g. ``lam=150`` for
        "smc"); omitted ones take the seed's values.

    Returns
    -------
    BaselinePolicy
        With SB3's ``predict``.

    Raises
    ------
    ValueError
        For an unknown name, an unknown parameter or a bad parameter value.
    """
    cls = policy_class(name)
    accepted = [p for p in inspect.signature(cls.__init__).parameters if p not in ("self",) + _FROM_ENV]
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown} for baseline {name!r}; it accepts {accepted}")
    return cls.from_env(env, **params)
