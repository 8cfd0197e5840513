"""Hyperparameters in RL Zoo's YAML format, and what our trainer makes of them.

``agents/hyperparams/ppo.yml`` holds one entry per env id, in the format of
RL Baselines3 Zoo, so the same file drives both trainers::

    vcnc-train --env VCNC-Heart-v0
    python -m rl_zoo3.train --algo ppo --env VCNC-Heart-v0 --gym-packages vcnc_gym \\
        --conf-file agents/hyperparams/ppo.yml

An entry has the Zoo's keys: ``n_timesteps``, ``n_envs``, ``policy``,
``normalize`` (bool or a dict string such as ``"{'norm_obs': True,
'norm_reward': True}"``), ``env_kwargs``, ``env_wrapper`` (the residual
action mode is ``agents.action_modes.ResidualAction`` with its arguments) and
every other key a PPO constructor argument; ``policy_kwargs`` may be a Python
expression string (``"dict(net_arch=[64, 64])"``) and a float hyperparameter
may be a linear schedule ``"lin_3e-4"``, as in the Zoo.
"""

from __future__ import annotations

import ast
import copy
import math
from pathlib import Path
from typing import Any

import yaml

from .action_modes import ActionMode

__all__ = [
    "DEFAULT_CONFIG",
    "RESIDUAL_WRAPPER",
    "load_hyperparameters",
    "action_mode_of",
    "with_action_mode",
    "normalize_kwargs",
    "ppo_arguments",
]

#: The hyperparameter file shipped with the package.
DEFAULT_CONFIG = Path(__file__).parent / "hyperparams" / "ppo.yml"

#: The import path of the residual wrapper, as the Zoo's ``env_wrapper`` names it.
RESIDUAL_WRAPPER = "agents.action_modes.ResidualAction"

#: Keys of a Zoo entry that are not PPO constructor arguments.
_ZOO_KEYS = ("n_timesteps", "n_envs", "policy", "normalize", "env_kwargs", "env_wrapper")


def load_hyperparameters(env_id: str, path=DEFAULT_CONFIG) -> dict:
    """The entry of ``env_id`` in the YAML file ``path`` (a deep copy).

    Raises FileNotFoundError for a missing file and ValueError for a file
    without that entry (naming the ones it has).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"hyperparameter file {str(path)!r} does not exist")
    table = yaml.safe_load(path.read_text()) or {}
    if not isinstance(table, dict) or env_id not in table:
        have = ", ".join(table) if isinstance(table, dict) else "nothing"
        raise ValueError(f"{path} has no entry for {env_id!r} (it has: {have})")
    entry = table[env_id]
    if not isinstance(entry, dict):
        raise ValueError(f"the entry of {env_id!r} in {path} must be a mapping, got {type(entry).__name__}")
    return copy.deepcopy(entry)


def _wrappers(spec) -> list[tuple[str, dict]]:
    """The Zoo's ``env_wrapper`` value as a list of (import path, kwargs)."""
    if spec is None:
        return []
    items = spec if isinstance(spec, list) else [spec]
    out = []
    for item in items:
        if isinstance(item, str):
            out.append((item, {}))
        elif isinstance(item, dict) and len(item) == 1:
            (name, kwargs), = item.items()
            out.append((name, dict(kwargs or {})))
        else:
            raise ValueError(f"env_wrapper entries must be 'module.Class' or {{'module.Class': {{kwargs}}}}, got {item!r}")
    return out


def action_mode_of(hyperparams: dict) -> ActionMode:
    """The action mode an entry describes: residual if it wraps in ResidualAction, else direct.

    Raises ValueError for a wrapper other than ResidualAction, which the
    evaluation of a trained agent could not reproduce.
    """
    wrappers = _wrappers(hyperparams.get("env_wrapper"))
    others = [name for name, _ in wrappers if name != RESIDUAL_WRAPPER]
    if others or len(wrappers) > 1:
        raise ValueError(f"env_wrapper may only be one {RESIDUAL_WRAPPER}, got {[n for n, _ in wrappers]}")
    if wrappers:
        kwargs = dict(wrappers[0][1])
        known = {k: kwargs.pop(k) for k in ("baseline", "correction", "action_repeat") if k in kwargs}
        return ActionMode("residual", baseline_params=kwargs, **known)
    repeat = (hyperparams.get("env_kwargs") or {}).get("action_repeat", 1)
    return ActionMode("direct", action_repeat=repeat)


def with_action_mode(hyperparams: dict, mode: ActionMode) -> dict:
    """A copy of ``hyperparams`` whose env_wrapper and env_kwargs describe ``mode``."""
    h = copy.deepcopy(hyperparams)
    env_kwargs = dict(h.get("env_kwargs") or {})
    h.pop("env_wrapper", None)
    if mode.mode == "residual":
        env_kwargs.pop("action_repeat", None)
        h["env_wrapper"] = [{RESIDUAL_WRAPPER: {"baseline": mode.baseline, "correction": mode.correction,
                                                "action_repeat": mode.action_repeat, **mode.baseline_params}}]
    else:
        env_kwargs["action_repeat"] = mode.action_repeat
    if env_kwargs:
        h["env_kwargs"] = env_kwargs
    else:
        h.pop("env_kwargs", None)
    return h


def normalize_kwargs(hyperparams: dict) -> dict | None:
    """VecNormalize keyword arguments of an entry, or None without normalisation.

    As in the Zoo, ``gamma`` follows the entry's discount factor.
    """
    value = hyperparams.get("normalize", False)
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            raise ValueError(f"normalize must be a bool or a dict literal, got {value!r}") from None
    if value is False or value is None:
        return None
    kwargs = {} if value is True else dict(value)
    if "gamma" in hyperparams:
        kwargs["gamma"] = hyperparams["gamma"]
    return kwargs


def _linear(initial: float):
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def ppo_arguments(hyperparams: dict) -> tuple[str, dict[str, Any]]:
    """(policy name, PPO keyword arguments) of an entry, schedules and policy_kwargs evaluated."""
    kwargs = {k: v for k, v in hyperparams.items() if k not in _ZOO_KEYS}
    for key, value in list(kwargs.items()):
        if isinstance(value, str) and value.startswith("lin_"):
            initial = float(value[4:])
            if not math.isfinite(initial) or initial <= 0:
                raise ValueError(f"{key}: a linear schedule needs a positive start, got {value!r}")
            kwargs[key] = _linear(initial)
    if isinstance(kwargs.get("policy_kwargs"), str):
        import torch

        namespace = {"__builtins__": {}, "dict": dict, "list": list, "nn": torch.nn, "th": torch}
        try:
            kwargs["policy_kwargs"] = eval(kwargs["policy_kwargs"], namespace)  # the Zoo's convention
        except Exception as exc:
            raise ValueError(f"policy_kwargs {kwargs['policy_kwargs']!r} is not a valid expression: {exc}") from None
    return hyperparams.get("policy", "MlpPolicy"), kwargs
