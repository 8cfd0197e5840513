"""Load an SB3 PPO ``model.zip`` without running code from the file.

What is in a ``model.zip`` (Stable-Baselines3 2.x, ``save_util``):

- ``data``: JSON of the algorithm's attributes.  Values JSON cannot hold
  are stored as ``{":serialized:": <base64 cloudpickle>, ...}``; SB3's
  ``json_to_data`` **unpickles** each of them unless ``custom_objects`` names
  its key.  For a PPO these are ``policy_class``, ``observation_space``,
  ``action_space``, ``rollout_buffer_class``, ``lr_schedule``,
  ``clip_range`` (schedule objects), ``_last_obs``, ``_last_episode_starts``,
  ``_last_original_obs`` (numpy arrays), ``ep_info_buffer``,
  ``ep_success_buffer`` (deques) and, when they are not plain numbers or
  dicts, ``learning_rate``, ``clip_range_vf``, ``policy_kwargs``,
  ``action_noise``.
- ``policy.pth``, ``policy.optimizer.pth``, ``pytorch_variables.pth``:
  tensors, read by SB3 through ``torch.load``, which since torch 2.6 uses the
  restricted ``weights_only`` unpickler by default (tensors, numbers,
  strings and containers only; SB3 2.x never passes ``weights_only=False``).
- ``_stable_baselines3_version``, ``system_info.txt``: text, not read here.

:func:`load_ppo` reads ``data`` as JSON first and refuses the file unless
every key is an attribute a PPO saves (:data:`PPO_DATA_KEYS`), then passes
``custom_objects`` replacing *every* serialized entry with a value built here
(the spaces from the env the agent will run on, after checking the shapes the
file records as JSON; the policy class from its alias; schedules from the
run's checked hyperparameters; None for the rollout-time buffers, which a
loaded model rebuilds).  So ``cloudpickle`` never sees a byte of the file.
"""

from __future__ import annotations

import copy
import json
import pickle
import zipfile
from pathlib import Path

import numpy as np

__all__ = [
    "POLICIES",
    "algorithm",
    "load_ppo",
    "read_model_data",
    "check_model_data",
    "recorded_shape",
    "model_timesteps",
    "PPO_DATA_KEYS",
    "check_torch",
    "check_tensor_files",
]

#: The attributes a PPO model.zip may hold in ``data``; anything else is refused.
PPO_DATA_KEYS = frozenset(
    {
        "policy_class",
        "verbose",
        "policy_kwargs",
        "num_timesteps",
        "_total_timesteps",
        "_num_timesteps_at_start",
        "seed",
        "action_noise",
        "start_time",
        "learning_rate",
        "tensorboard_log",
        "_last_obs",
        "_last_episode_starts",
        "_last_original_obs",
        "_episode_num",
        "use_sde",
        "sde_sample_freq",
        "_current_progress_remaining",
        "_stats_window_size",
        "ep_info_buffer",
        "ep_success_buffer",
        "_n_updates",
        "observation_space",
        "action_space",
        "n_envs",
        "n_steps",
        "gamma",
        "gae_lambda",
        "ent_coef",
        "vf_coef",
        "max_grad_norm",
        "rollout_buffer_class",
        "rollout_buffer_kwargs",
        "batch_size",
        "n_epochs",
        "clip_range",
        "clip_range_vf",
        "normalize_advantage",
        "target_kl",
        "lr_schedule",
    }
)

#: Entries rebuilt when training goes on (or unused by predict): replaced by None.
_RUNTIME_ONLY = (
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
    "action_noise",
)

_MIN_TORCH = (2, 6)

#: The policies an entry may name: SB3's feed-forward PPO policy, and sb3-contrib's recurrent one (an LSTM before
#: the actor and the critic; ``RecurrentPPO``, SB3's trainer only), each with the class that trains and loads it
#: (:func:`algorithm`).
POLICIES = {"MlpPolicy": "stable_baselines3.PPO", "MlpLstmPolicy": "sb3_contrib.RecurrentPPO"}


def algorithm(policy: str):
    """The SB3 algorithm class that trains ``policy`` (a name of :data:`POLICIES`): ``PPO`` or sb3-contrib's
    ``RecurrentPPO``."""
    import importlib

    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {list(POLICIES)}, got {policy!r}")
    module, name = POLICIES[policy].rsplit(".", 1)
    return getattr(importlib.import_module(module), name)


def check_torch() -> None:
    """RuntimeError unless torch >= 2.6 (its ``torch.load`` defaults to the weights-only unpickler)."""
    import torch

    version = tuple(int(x) for x in torch.__version__.split("+")[0].split(".")[:2])
    if version < _MIN_TORCH:
        raise RuntimeError(
            f"loading a model.zip without running its code needs torch >= 2.6 "
            f"(weights-only torch.load by default), found {torch.__version__}"
        )


#: Largest ``data`` member (JSON) of a model.zip read, bytes: a PPO's is a few kB.
MAX_DATA_BYTES = 16 * 1024**2

#: Largest other member of a model.zip read, bytes: a policy of a few hundred thousand float32 weights is about
#: a MB; 256 MB is a network of 64 million weights.
MAX_MEMBER_BYTES = 256 * 1024**2


def read_model_data(path) -> dict:
    """The ``data`` JSON of an SB3 model.zip as a dict (nothing unpickled).

    Raises ValueError naming the file when it is not a zip, a member would inflate beyond
    :data:`MAX_DATA_BYTES` / :data:`MAX_MEMBER_BYTES` (checked on the declared sizes, before anything is
    inflated), it is damaged (CRC), lacks ``data`` or ``policy.pth``, or its ``data`` is not JSON.
    """
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():  # declared sizes, before anything is inflated (zipfile reads no more)
                limit = MAX_DATA_BYTES if info.filename == "data" else MAX_MEMBER_BYTES
                if info.file_size > limit:
                    raise ValueError(
                        f"{path}: member {info.filename!r} inflates to {info.file_size:,} bytes, more "
                        f"than an SB3 model holds (at most {limit:,}: "
                        f"{'MAX_DATA_BYTES' if info.filename == 'data' else 'MAX_MEMBER_BYTES'})"
                    )
            bad = archive.testzip()
            if bad is not None:
                raise ValueError(f"{path} is damaged: member {bad!r} fails its CRC check")
            names = set(archive.namelist())
            missing = [n for n in ("data", "policy.pth") if n not in names]
            if missing:
                raise ValueError(f"{path} is not an SB3 model: it lacks {', '.join(missing)}")
            text = archive.read("data").decode("utf-8")
    except (zipfile.BadZipFile, EOFError, OSError, UnicodeDecodeError, RuntimeError) as exc:
        raise ValueError(f"{path} is not a readable model.zip ({type(exc).__name__}: {exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: its data entry is not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: its data entry is not a JSON object")
    return data


#: The pickled entries :func:`load_ppo` rebuilds itself.
_REPLACED = frozenset(
    {
        "policy_class",
        "observation_space",
        "action_space",
        "rollout_buffer_class",
        "learning_rate",
        "lr_schedule",
        "clip_range",
        "clip_range_vf",
        "policy_kwargs",
        *_RUNTIME_ONLY,
    }
)


def check_model_data(data: dict, path) -> None:
    """ValueError unless ``data`` (a model.zip's JSON) holds only PPO attributes, every pickled one replaceable.

    So that :func:`load_ppo` unpickles nothing: a key a PPO does not save or
    a pickled entry it cannot rebuild is refused, as are Box spaces without
    a recorded shape.
    """
    unknown = sorted(set(data) - PPO_DATA_KEYS)
    if unknown:
        raise ValueError(f"{path} holds entries a PPO model does not save: {unknown}; refusing to load it")
    for key, value in data.items():
        if _serialized(value) and key not in _REPLACED:
            raise ValueError(
                f"{path}: entry {key!r} is pickled and this loader cannot rebuild it; refusing to unpickle it"
            )
    if not isinstance(data.get("policy_kwargs", {}), dict) and not _serialized(data.get("policy_kwargs")):
        raise ValueError(f"{path}: policy_kwargs must be a JSON object")
    for key in ("observation_space", "action_space"):
        recorded_shape(data, key, path)


def _serialized(value) -> bool:
    return isinstance(value, dict) and ":serialized:" in value


def recorded_shape(data: dict, key: str, path) -> tuple[int, ...]:
    """The shape a Box space entry of ``data`` records in plain JSON (``_shape``)."""
    entry = data.get(key)
    shape = entry.get("_shape") if isinstance(entry, dict) else None
    if (
        not isinstance(entry, dict)
        or "gymnasium.spaces.box.Box" not in str(entry.get(":type:"))
        or not isinstance(shape, list)
        or not all(isinstance(n, int) and n > 0 for n in shape)
    ):
        raise ValueError(f"{path}: {key} must be a gymnasium Box with a recorded shape, got {str(entry)[:120]!r}")
    return tuple(shape)


def load_ppo(
    path,
    *,
    observation_space,
    action_space,
    ppo_kwargs: dict,
    env=None,
    device: str = "cpu",
    policy: str = "MlpPolicy",
    **kwargs,
):
    """An SB3 PPO (or sb3-contrib's ``RecurrentPPO``, ``policy="MlpLstmPolicy"``) from ``path`` with nothing of
    the file unpickled.

    Parameters
    ----------
    path : path
        The model.zip.
    observation_space, action_space : gymnasium.spaces.Box
        The spaces the model will run on; the shapes recorded in the file
        must equal theirs.
    ppo_kwargs : dict
        The checked PPO arguments of the run (:func:`vcnc_agents.config.ppo_arguments`):
        ``learning_rate``, ``clip_range``, ``clip_range_vf`` and
        ``policy_kwargs`` replace the file's entries.
    env : VecEnv, optional
        The training env when training goes on.
    device : str
        Torch device.
    policy : str
        The run's policy name (:data:`POLICIES`), which says the algorithm and its policy class.
    **kwargs
        Passed to ``PPO.load`` (e.g. ``tensorboard_log``, ``verbose``).

    Raises
    ------
    ValueError
        For a damaged file, a key a PPO does not save, a serialized entry
        this loader cannot rebuild, or spaces of other shapes (naming them).
    """
    from stable_baselines3.common.buffers import RolloutBuffer

    algo = algorithm(policy)
    if policy == "MlpLstmPolicy":
        from sb3_contrib.common.recurrent.buffers import RecurrentRolloutBuffer as RolloutBuffer
    check_torch()
    data = read_model_data(path)
    check_model_data(data, path)
    for key, space in (("observation_space", observation_space), ("action_space", action_space)):
        shape = recorded_shape(data, key, path)
        if shape != tuple(space.shape):
            raise ValueError(
                f"{path}: the model's {key} has shape {shape}, the env's {tuple(space.shape)}: "
                "it was trained on another env configuration"
            )
    lr = ppo_kwargs.get("learning_rate", 3e-4)
    replacements = {
        "policy_class": algo.policy_aliases[policy],
        "observation_space": observation_space,
        "action_space": action_space,
        "rollout_buffer_class": RolloutBuffer,
        "learning_rate": lr,
        "lr_schedule": lr,  # rebuilt from learning_rate by PPO._setup_model
        "clip_range": ppo_kwargs.get("clip_range", 0.2),
        "clip_range_vf": ppo_kwargs.get("clip_range_vf"),
        "policy_kwargs": copy.deepcopy(ppo_kwargs.get("policy_kwargs", {})),
        **{k: None for k in _RUNTIME_ONLY},
    }
    custom = {k: v for k, v in replacements.items() if k in data}
    try:
        return algo.load(path, env=env, device=device, custom_objects=custom, **kwargs)
    except pickle.UnpicklingError as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(
            f"{path}: its tensor files (policy.pth, ...) hold more than tensors and are refused by "
            f"torch's weights-only reader ({reason})"
        ) from None
    except (RuntimeError, KeyError, ValueError, AssertionError) as exc:
        raise ValueError(
            f"{path} does not load as the PPO its config.yml describes "
            f"({type(exc).__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else ''})"
        ) from None


def check_tensor_files(path) -> None:
    """ValueError unless every ``.pth`` member of the model.zip at ``path`` reads with torch's weights-only
    unpickler (tensors, numbers, containers: no code runs); what :func:`load_ppo` will meet, checked first."""
    import io

    import torch

    check_torch()
    try:
        with zipfile.ZipFile(path) as z:
            for name in z.namelist():
                if name.endswith(".pth"):
                    try:
                        torch.load(io.BytesIO(z.read(name)), map_location="cpu", weights_only=True)
                    except pickle.UnpicklingError as exc:
                        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                        raise ValueError(
                            f"{path}: {name} holds more than tensors and is refused by torch's "
                            f"weights-only reader ({reason})"
                        ) from None
                    except (RuntimeError, EOFError) as exc:
                        raise ValueError(f"{path}: {name} is not a torch tensor file ({type(exc).__name__})") from None
    except (zipfile.BadZipFile, OSError) as exc:
        raise ValueError(f"{path} is not a readable model.zip ({type(exc).__name__}: {exc})") from None


def model_timesteps(path) -> int:
    """``num_timesteps`` recorded in a model.zip's data (ValueError if absent or damaged)."""
    n = read_model_data(path).get("num_timesteps")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"{path}: num_timesteps must be a count, got {n!r}")
    return int(n)
