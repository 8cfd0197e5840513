"""Hyperparameters in RL Zoo's YAML format, checked, and what our trainer makes of them.

``agents/hyperparams/ppo.yml`` holds one entry per env id, in the format of
RL Baselines3 Zoo, so the same file drives both trainers::

    vcnc-train --env VCNC-Heart-v0
    python -m rl_zoo3.train --algo ppo --env VCNC-Heart-v0 --gym-packages vcnc_gym \\
        --conf-file agents/hyperparams/ppo.yml

An entry has the Zoo's keys: ``n_timesteps``, ``n_envs``, ``policy``,
``normalize`` (bool or a dict string such as ``"{'norm_obs': True,
'norm_reward': True}"``), ``env_kwargs``, ``env_wrapper`` (the residual
action mode is ``vcnc_agents.action_modes.ResidualAction`` with its arguments) and
every other key a PPO constructor argument; a float hyperparameter may be a
linear schedule ``"lin_3e-4"``, as in the Zoo.

``policy_kwargs`` may be a string, as in the Zoo (``"dict(net_arch=[64,
64], activation_fn=nn.Tanh)"``), but it is never ``eval``-ed: it is parsed
as a literal (numbers, strings, booleans, None, lists, tuples, dicts and
``dict(...)`` calls) in which the only names allowed are the activation
functions and optimisers of :data:`TORCH_NAMES`.

:func:`ppo_arguments` checks every PPO argument (type, range, spelling) so a
bad entry is refused with a message naming the key before a run starts.
"""

from __future__ import annotations

import ast
import copy
import difflib
import math
import numbers
import warnings
from pathlib import Path
from typing import Any

import yaml

from vcnc_gym.validation import flag, integer

from .action_modes import RESIDUAL_OPTIONS, ActionMode
from .model_file import POLICIES

__all__ = [
    "DEFAULT_CONFIG",
    "RESIDUAL_WRAPPER",
    "TORCH_NAMES",
    "load_hyperparameters",
    "action_mode_of",
    "with_action_mode",
    "normalize_kwargs",
    "ppo_arguments",
    "parse_policy_kwargs",
    "count",
]

#: The hyperparameter file shipped with the package.
DEFAULT_CONFIG = Path(__file__).parent / "hyperparams" / "ppo.yml"

#: The import path of the residual wrapper, as the Zoo's ``env_wrapper`` names it.
RESIDUAL_WRAPPER = "vcnc_agents.action_modes.ResidualAction"
#: Its path before the package was installed as ``vcnc_agents`` (0.2.0), still read in a run's config.yml
#: or a hyperparameter file with a DeprecationWarning, until 0.4.
_OLD_RESIDUAL_WRAPPER = "agents.action_modes.ResidualAction"

#: Keys of a Zoo entry that are not PPO constructor arguments and that vcnc-train understands.
_ZOO_KEYS = ("n_timesteps", "n_envs", "policy", "normalize", "env_kwargs", "env_wrapper")

#: Zoo keys vcnc-train does not implement (refused rather than ignored).
_UNSUPPORTED_ZOO_KEYS = (
    "frame_stack",
    "callback",
    "vec_env_wrapper",
    "normalize_kwargs",
    "eval_env_kwargs",
    "monitor_kwargs",
    "replay_buffer_class",
    "replay_buffer_kwargs",
)

#: PPO arguments vcnc-train sets itself.
_SET_BY_TRAINER = (
    "tensorboard_log",
    "verbose",
    "seed",
    "device",
    "env",
    "policy",
    "_init_setup_model",
    "rollout_buffer_class",
    "rollout_buffer_kwargs",
)

#: VecNormalize arguments an entry's ``normalize`` dict may hold.
_NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "epsilon", "gamma")


def _torch_names() -> dict[str, Any]:
    import torch

    activations = (
        "ReLU",
        "Tanh",
        "ELU",
        "LeakyReLU",
        "SiLU",
        "GELU",
        "Sigmoid",
        "Softplus",
        "Mish",
        "SELU",
        "Identity",
    )
    optimisers = ("Adam", "AdamW", "RMSprop", "SGD")
    names = {}
    for n in activations:
        for prefix in ("nn.", "th.nn.", "torch.nn."):
            names[prefix + n] = getattr(torch.nn, n)
    for n in optimisers:
        for prefix in ("th.optim.", "torch.optim.", "optim."):
            names[prefix + n] = getattr(torch.optim, n)
    return names


#: Names ``policy_kwargs`` may use (activation functions and optimisers), filled on first use.
TORCH_NAMES: dict[str, Any] = {}


def _named(name: str):
    if not TORCH_NAMES:
        TORCH_NAMES.update(_torch_names())
    if name not in TORCH_NAMES:
        raise ValueError(
            f"policy_kwargs may only name {', '.join(n for n in TORCH_NAMES if n.startswith(('nn.', 'th.optim.')))}; "
            f"got {name!r}"
        )
    return TORCH_NAMES[name]


# -- small checks ---------------------------------------------------------------------------
def count(name: str, value, minimum: int = 1) -> int:
    """``value`` as an int >= ``minimum``; a whole float (YAML's ``!!float 3e5``) is accepted.

    ValueError naming ``name`` otherwise (bools, NaN, fractions, strings).
    """
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        value = int(value)
    return integer(name, value, minimum)


def number(name: str, value, *, low=None, high=None, low_open=False, high_open=False, none=False):
    """A finite real in the given interval (a numeric string such as "3e-4" is read as a float)."""
    if value is None and none:
        return None
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise ValueError(f"{name} must be a number, got {value!r}") from None
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    v = float(value)
    if low is not None and (v < low or (low_open and v == low)):
        raise ValueError(f"{name} must be {'>' if low_open else '>='} {low}, got {value!r}")
    if high is not None and (v > high or (high_open and v == high)):
        raise ValueError(f"{name} must be {'<' if high_open else '<='} {high}, got {value!r}")
    return v


def _linear(initial: float):
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _rate(name: str, value, none: bool = False):
    """A positive float or a Zoo linear schedule ``"lin_<start>"`` (returned as a function)."""
    if value is None and none:
        return None
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            initial = float(value[4:])
        except ValueError:
            raise ValueError(f"{name}: a linear schedule is 'lin_<positive number>', got {value!r}") from None
        if not math.isfinite(initial) or initial <= 0:
            raise ValueError(f"{name}: a linear schedule needs a positive start, got {value!r}")
        return _linear(initial)
    return number(name, value, low=0.0, low_open=True)


#: Every PPO argument an entry may set and its check (value -> converted value).
_PPO_RULES = {
    "learning_rate": lambda v: _rate("learning_rate", v),
    "n_steps": lambda v: count("n_steps", v),
    "batch_size": lambda v: count("batch_size", v, 2),
    "n_epochs": lambda v: count("n_epochs", v),
    "gamma": lambda v: number("gamma", v, low=0.0, high=1.0, low_open=True),
    "gae_lambda": lambda v: number("gae_lambda", v, low=0.0, high=1.0),
    "clip_range": lambda v: _rate("clip_range", v),
    "clip_range_vf": lambda v: _rate("clip_range_vf", v, none=True),
    "normalize_advantage": lambda v: flag("normalize_advantage", v),
    "ent_coef": lambda v: number("ent_coef", v, low=0.0),
    "vf_coef": lambda v: number("vf_coef", v, low=0.0),
    "max_grad_norm": lambda v: number("max_grad_norm", v, low=0.0, low_open=True),
    "use_sde": lambda v: flag("use_sde", v),
    "sde_sample_freq": lambda v: count("sde_sample_freq", v, -1),
    "target_kl": lambda v: number("target_kl", v, low=0.0, low_open=True, none=True),
    "stats_window_size": lambda v: count("stats_window_size", v),
    "policy_kwargs": lambda v: parse_policy_kwargs(v),
}


# -- policy_kwargs without eval ------------------------------------------------------------------
def _literal(node: ast.AST, text: str):
    """The value of one node of a policy_kwargs expression; ValueError for anything but literals and TORCH_NAMES."""
    if isinstance(node, ast.Constant) and (node.value is None or isinstance(node.value, (bool, int, float, str))):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        v = _literal(node.operand, text)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"policy_kwargs: a sign applies to numbers only, got {ast.unparse(node)!r} in {text!r}")
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_literal(e, text) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, ast.Dict):
        if any(k is None for k in node.keys):
            raise ValueError(f"policy_kwargs: '**' is not allowed in {text!r}")
        return {_literal(k, text): _literal(v, text) for k, v in zip(node.keys, node.values)}
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args:
        if any(k.arg is None for k in node.keywords):
            raise ValueError(f"policy_kwargs: '**' is not allowed in {text!r}")
        return {k.arg: _literal(k.value, text) for k in node.keywords}
    if isinstance(node, (ast.Name, ast.Attribute)):
        return _named(ast.unparse(node))
    raise ValueError(
        f"policy_kwargs may hold only literals, dict(...) and the names of vcnc_agents.config.TORCH_NAMES; "
        f"{ast.unparse(node)!r} in {text!r} is none of them"
    )


def parse_policy_kwargs(value, policy: str = "MlpPolicy") -> dict:
    """``policy_kwargs`` of an entry as a dict, without ``eval``.

    A string is parsed (:mod:`ast`) as a literal expression in which
    ``dict(key=value, ...)`` and the names of :data:`TORCH_NAMES` (e.g.
    ``nn.ReLU``, ``th.optim.AdamW``) are the only non-literals; a mapping
    (from YAML) may name those classes as strings.  The keys are checked
    against the arguments of ``policy``'s class (:data:`POLICIES`: SB3's ``ActorCriticPolicy``, or sb3-contrib's
    ``RecurrentActorCriticPolicy`` with its LSTM's ``lstm_hidden_size``, ``n_lstm_layers``, ...).

    Raises ValueError for anything else (a call, an unknown name, an
    attribute of something not in the list, a misspelt key).
    """
    if isinstance(value, str):
        try:
            tree = ast.parse(value.strip(), mode="eval")
        except SyntaxError as exc:
            raise ValueError(f"policy_kwargs {value!r} is not a valid expression: {exc.msg}") from None
        kwargs = _literal(tree.body, value)
    elif isinstance(value, dict):
        kwargs = copy.deepcopy(value)
        for key in ("activation_fn", "optimizer_class"):
            if isinstance(kwargs.get(key), str):
                kwargs[key] = _named(kwargs[key])
    elif value is None:
        kwargs = {}
    else:
        raise ValueError(f"policy_kwargs must be a mapping or a dict expression string, got {value!r}")
    if not isinstance(kwargs, dict) or not all(isinstance(k, str) for k in kwargs):
        raise ValueError(f"policy_kwargs must give a dict with string keys, got {value!r}")
    import inspect

    from .model_file import algorithm

    known = set(inspect.signature(algorithm(policy).policy_aliases[policy].__init__).parameters) - {
        "self",
        "observation_space",
        "action_space",
        "lr_schedule",
        "features_extractor_class",
    }
    refuse_unknown("policy_kwargs", kwargs, known)
    return kwargs


def refuse_unknown(where: str, keys, known) -> None:
    unknown = sorted(set(keys) - set(known))
    if unknown:
        hints = []
        for k in unknown:
            close = difflib.get_close_matches(k, sorted(known), n=1)
            hints.append(f"{k!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
        raise ValueError(f"unknown key(s) in {where}: {', '.join(hints)}; known keys: {', '.join(sorted(known))}")


# -- the file ------------------------------------------------------------------------------------
def read_yaml(what: str, path):
    """The YAML document of the file ``path`` (``what`` names it in errors): FileNotFoundError if it is missing,
    ValueError if it is not a YAML text file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} {str(path)!r} does not exist")
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{what} {str(path)!r} is not valid YAML: {exc}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{what} {str(path)!r} is not a text file") from None


def load_hyperparameters(env_id: str, path=DEFAULT_CONFIG) -> dict:
    """The entry of ``env_id`` in the YAML file ``path`` (a deep copy).

    Raises FileNotFoundError for a missing file and ValueError for a file
    that is not YAML or has no mapping for that entry (naming the ones it has).
    """
    table = read_yaml("hyperparameter file", path)
    table = table or {}
    if not isinstance(table, dict) or env_id not in table:
        have = ", ".join(map(str, table)) if isinstance(table, dict) else "nothing (it is not a mapping)"
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
        elif isinstance(item, dict) and len(item) == 1 and isinstance(next(iter(item.values())) or {}, dict):
            ((name, kwargs),) = item.items()
            out.append((name, dict(kwargs or {})))
        else:
            raise ValueError(
                f"env_wrapper entries must be 'module.Class' or {{'module.Class': {{kwargs}}}}, got {item!r}"
            )
    if any(name == _OLD_RESIDUAL_WRAPPER for name, _ in out):
        warnings.warn(
            f"env_wrapper {_OLD_RESIDUAL_WRAPPER} is now {RESIDUAL_WRAPPER} (the package installs as "
            "vcnc_agents); the old path is read until vcnc-gym 0.4",
            DeprecationWarning,
            stacklevel=3,
        )
        out = [(RESIDUAL_WRAPPER if name == _OLD_RESIDUAL_WRAPPER else name, kwargs) for name, kwargs in out]
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
        known = {k: kwargs.pop(k) for k in ("action_repeat", *RESIDUAL_OPTIONS) if k in kwargs}
        return ActionMode("residual", baseline_params=kwargs, **known)
    env_kwargs = hyperparams.get("env_kwargs") or {}
    if not isinstance(env_kwargs, dict):
        raise ValueError(f"env_kwargs must be a mapping of env arguments, got {env_kwargs!r}")
    return ActionMode("direct", action_repeat=env_kwargs.get("action_repeat", 1))


def with_action_mode(hyperparams: dict, mode: ActionMode) -> dict:
    """A copy of ``hyperparams`` whose env_wrapper and env_kwargs describe ``mode``."""
    h = copy.deepcopy(hyperparams)
    env_kwargs = dict(h.get("env_kwargs") or {})
    h.pop("env_wrapper", None)
    if mode.mode == "residual":
        env_kwargs.pop("action_repeat", None)
        h["env_wrapper"] = [
            {
                RESIDUAL_WRAPPER: {
                    "baseline": mode.baseline,
                    "correction": mode.correction,
                    "action_repeat": mode.action_repeat,
                    **mode.baseline_params,
                    **({"history": mode.history} if mode.history else {}),
                    **({"peak_weight": mode.peak_weight} if mode.peak_weight else {}),
                    **({"dial_rate": mode.dial_rate} if mode.dial_rate else {}),
                }
            }
        ]
    else:
        env_kwargs["action_repeat"] = mode.action_repeat
    if env_kwargs:
        h["env_kwargs"] = env_kwargs
    else:
        h.pop("env_kwargs", None)
    return h


def normalize_kwargs(hyperparams: dict) -> dict | None:
    """VecNormalize keyword arguments of an entry, or None without normalisation.

    As in the Zoo, ``gamma`` follows the entry's discount factor.  Raises
    ValueError for a value that is not a bool or a dict (literal) of
    VecNormalize's arguments.
    """
    value = hyperparams.get("normalize", False)
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)  # literals only: no code runs
        except (ValueError, SyntaxError):
            raise ValueError(f"normalize must be a bool or a dict literal, got {value!r}") from None
    if value is False or value is None:
        return None
    if value is not True and not isinstance(value, dict):
        raise ValueError(f"normalize must be a bool or a dict literal, got {value!r}")
    kwargs = {} if value is True else dict(value)
    refuse_unknown("normalize", kwargs, _NORMALIZE_KEYS)
    for key in ("norm_obs", "norm_reward"):
        if key in kwargs:
            flag(f"normalize: {key}", kwargs[key])
    for key in ("clip_obs", "clip_reward", "epsilon"):
        if key in kwargs:
            kwargs[key] = number(f"normalize: {key}", kwargs[key], low=0.0, low_open=True)
    if "gamma" in hyperparams:
        kwargs["gamma"] = hyperparams["gamma"]
    if "gamma" in kwargs:
        kwargs["gamma"] = number("gamma", kwargs["gamma"], low=0.0, high=1.0, low_open=True)
    return kwargs


def ppo_arguments(hyperparams: dict) -> tuple[str, dict[str, Any]]:
    """(policy name, PPO keyword arguments) of an entry, every value checked.

    Schedules ``"lin_<x>"`` become functions, ``policy_kwargs`` a dict
    (:func:`parse_policy_kwargs`).  Raises ValueError naming the key for a
    misspelt or unsupported key, a value of the wrong type or out of range
    (n_steps: 0, gamma: 2.0, a negative or NaN learning rate, ...).
    """
    if not isinstance(hyperparams, dict):
        raise ValueError(f"hyperparameters must be a mapping, got {hyperparams!r}")
    unsupported = [k for k in hyperparams if k in _UNSUPPORTED_ZOO_KEYS or k in _SET_BY_TRAINER and k != "policy"]
    if unsupported:
        raise ValueError(
            f"vcnc-train does not support the hyperparameter(s) {unsupported} "
            "(it sets the seed, device, logging and buffers itself)"
        )
    refuse_unknown("the hyperparameters", hyperparams, set(_PPO_RULES) | set(_ZOO_KEYS))
    policy = hyperparams.get("policy", "MlpPolicy")
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {list(POLICIES)} (the observation is a flat vector), got {policy!r}")
    kwargs = {k: _PPO_RULES[k](v) for k, v in hyperparams.items() if k not in _ZOO_KEYS and k != "policy_kwargs"}
    if "policy_kwargs" in hyperparams:  # its keys are the policy class's arguments
        kwargs["policy_kwargs"] = parse_policy_kwargs(hyperparams["policy_kwargs"], policy)
    normalize_kwargs(hyperparams)
    return policy, kwargs
