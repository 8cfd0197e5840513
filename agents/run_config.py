"""The configuration of a training run: checked options and the ``config.yml`` a run folder keeps.

As RL Zoo's ``exp_manager``: the hyperparameter entry of ``agents/hyperparams/ppo.yml`` (:mod:`agents.config`)
plus the command line's options (env id, seed, n_envs, total steps, action mode, checkpoint and evaluation
periods) make a run's config (:func:`new_config`); :class:`RunConfig` is its typed record, what
``RUN/config.yml`` holds (:meth:`RunConfig.to_dict`) and what a resume reads back (:meth:`RunConfig.from_dict`,
which checks every field and keeps the ones it does not know, e.g. ``trainer`` or an agent's ``agent`` block).
Every check names the argument (:mod:`vcnc_gym.validation`).
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass, field, fields
from pathlib import Path

from vcnc_gym.envs.registry import suite_env
from vcnc_gym.validation import size

from .action_modes import ActionMode
from .config import (DEFAULT_CONFIG, action_mode_of, count, load_hyperparameters, ppo_arguments,
                     with_action_mode)
from .env_factory import check_envs
from .run_warning import note

__all__ = ["RunConfig", "new_config", "check_env_id", "check_seed", "check_training_options", "check_n_envs",
           "check_timesteps", "round_to_rollouts", "rollout_size", "VEC_ENVS", "DEFAULT_CHECKPOINT_FREQ",
           "DEFAULT_EVAL_FREQ", "MAX_TIMESTEPS", "SEED_MAX"]

DEFAULT_CHECKPOINT_FREQ = 50_000
DEFAULT_EVAL_FREQ = 20_000
SEED_MAX = 2**32 - 1

#: Most agent steps a run may ask for (ours): 20 days at the 5 630 steps/s measured on this project's 2 cores
#: (README, ``benchmarks/train_throughput.py``); a run meant to be longer is resumed with a larger total.
MAX_TIMESTEPS = 10**10

#: Files a training process keeps open besides its envs' Monitor files (torch, numba, tensorboard, the
#: interpreter), subtracted from ``ulimit -n``: the native vector env keeps one Monitor file open per env.
RESERVED_FILES = 256

#: Memory of one training env besides its share of PPO's rollout buffer, bytes: its Monitor file's 8 kB
#: write buffer and its rows of the vector env's arrays (3-4 kB, ``ContouringBatch.bytes_per_env``).
ENV_BYTES = 12_000


@dataclass(frozen=True)
class RunConfig:
    """A run's configuration, as ``RUN/config.yml`` holds it.

    Attributes
    ----------
    env_id : str
        The VCNC env id trained on.
    seed : int
        Seed of the envs and of PPO, in [0, 2**32 - 1].
    n_envs : int
        Parallel training envs.
    n_timesteps : int
        Total agent steps, a whole number of rollouts.
    action_mode : dict
        :meth:`ActionMode.to_dict` of the agent's action mode.
    hyperparams : dict
        The hyperparameter entry (RL Zoo's format) with the run's n_timesteps, n_envs and action mode.
    checkpoint_freq : int or None
        Agent steps between checkpoints (None in a config.yml written before it was recorded).
    eval_freq : int or None
        Agent steps between evaluations, 0 for only at the end (None as for checkpoint_freq).
    env : dict or None
        The env block: id, kwargs and observation/action signature.
    config_file : str or None
        The hyperparameter file the entry came from.
    extra : dict
        Keys this record does not interpret (``trainer``, an agent folder's ``agent``), kept as read.
    """

    env_id: str
    seed: int
    n_envs: int
    n_timesteps: int
    action_mode: dict
    hyperparams: dict
    checkpoint_freq: int | None = None
    eval_freq: int | None = None
    env: dict | None = None
    config_file: str | None = None
    extra: dict = field(default_factory=dict)

    #: The keys of config.yml in the order they are written.
    ORDER = ("env_id", "seed", "n_envs", "n_timesteps", "checkpoint_freq", "eval_freq", "action_mode", "env",
             "hyperparams", "config_file")

    @classmethod
    def from_dict(cls, data, *, source: str = "config") -> RunConfig:
        """The record of a config.yml's mapping; ValueError naming the field that is missing or of the wrong type."""
        if not isinstance(data, dict):
            raise ValueError(f"{source} must be a mapping, got {type(data).__name__}")
        missing = [k for k in ("env_id", "seed", "n_envs", "n_timesteps", "action_mode", "hyperparams")
                   if k not in data]
        if missing:
            raise ValueError(f"{source} lacks {', '.join(missing)}")
        if not isinstance(data["env_id"], str):
            raise ValueError(f"{source}: env_id must be a string, got {data['env_id']!r}")
        for key in ("seed", "n_envs", "n_timesteps"):
            count(f"{source}: {key}", data[key], 0 if key == "seed" else 1)
        for key in ("checkpoint_freq", "eval_freq"):
            if data.get(key) is not None:
                count(f"{source}: {key}", data[key], 0 if key == "eval_freq" else 1)
        for key in ("action_mode", "hyperparams", "env"):
            if key in data and data[key] is not None and not isinstance(data[key], dict):
                raise ValueError(f"{source}: {key} must be a mapping, got {data[key]!r}")
        ActionMode(**data["action_mode"])  # a bad mode names its argument
        known = {f.name for f in fields(cls)} - {"extra"}
        return cls(**{k: v for k, v in data.items() if k in known},
                   extra={k: v for k, v in data.items() if k not in known})

    def to_dict(self) -> dict:
        """The mapping config.yml holds (fields in :attr:`ORDER`, absent optional ones left out, then ``extra``)."""
        out = {}
        for key in self.ORDER:
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        out.update(self.extra)
        return out


def check_env_id(env_id: str) -> str:
    """``env_id`` if it is a VCNC env (a current id or a v0 id kept for its agents); ValueError naming the current
    ones otherwise."""
    return suite_env(env_id).id


def check_seed(seed) -> int:
    """``seed`` as an int in [0, 2**32 - 1] (what numpy and SB3 accept); ValueError otherwise."""
    v = count("seed", seed, 0)
    if v > SEED_MAX:
        raise ValueError(f"seed must be an integer in [0, {SEED_MAX}], got {seed!r}")
    return v


#: The training VecEnvs: the native vector env (one kernel call for all envs), SB3's DummyVecEnv, SubprocVecEnv.
VEC_ENVS = ("native", "dummy", "subproc")


def check_training_options(*, checkpoint_freq, eval_freq, vec_env, tensorboard) -> None:
    """ValueError for a bad training option of :func:`train` (the run-independent ones; None = the run's)."""
    if checkpoint_freq is not None:
        count("checkpoint_freq", checkpoint_freq)
    if eval_freq is not None:
        count("eval_freq", eval_freq, 0)
    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {vec_env!r}")
    if tensorboard and importlib.util.find_spec("tensorboard") is None:
        raise ValueError("tensorboard logging was asked for but tensorboard is not installed")


def round_to_rollouts(name: str, n_timesteps: int, rollout: int) -> int:
    total = -(-n_timesteps // rollout) * rollout
    if total != n_timesteps:
        note(f"{name} {n_timesteps} is rounded up to {total}: PPO trains whole rollouts of n_steps x n_envs = "
              f"{rollout} agent steps")
    return total


def rollout_size(config: dict) -> int:
    _, kwargs = ppo_arguments(config["hyperparams"])
    return kwargs.get("n_steps", 2048) * config["n_envs"]


def check_timesteps(n_timesteps: int) -> int:
    return size("n_timesteps", n_timesteps, ceiling=MAX_TIMESTEPS,
                why="MAX_TIMESTEPS, 20 days at the 5 630 steps/s measured on 2 cores; resume a run to go further")


def check_n_envs(n_envs: int, n_steps: int | None = None, observation_size: int | None = None) -> int:
    """``n_envs`` within the open-file limit (one Monitor file per env) and, with the rollout's size, memory."""
    import resource

    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    if soft != resource.RLIM_INFINITY:
        size("n_envs", n_envs, ceiling=max(1, soft - RESERVED_FILES),
             why=f"each env keeps its Monitor file open and this process may open {soft} files (ulimit -n), "
                 f"{RESERVED_FILES} kept for the rest")
    if n_steps is not None and observation_size is not None:
        rollout = n_steps * (observation_size + 2 + 6) * 4  # float32 observation, action and 6 scalars per step
        size("n_envs", n_envs, bytes_each=rollout + ENV_BYTES,
             why=f"each env fills n_steps = {n_steps} rows of PPO's rollout buffer ({observation_size} observation "
                 "entries, 2 actions, 6 scalars in float32) and holds its Monitor file and batch rows")
    return n_envs


def new_config(env_id, *, config_file, n_timesteps, seed, n_envs, action_mode, checkpoint_freq, eval_freq) -> dict:
    """A new run's config (:meth:`RunConfig.to_dict`) from the hyperparameter entry and the options, all checked."""
    h = load_hyperparameters(env_id, config_file)
    ppo_arguments(h)  # refuse a bad entry before anything else
    mode = action_mode if action_mode is not None else action_mode_of(h)
    h = with_action_mode(h, mode)
    n_timesteps = count("n_timesteps", n_timesteps if n_timesteps is not None else h.get("n_timesteps", 0))
    n_envs = check_n_envs(count("n_envs", n_envs if n_envs is not None else h.get("n_envs", 1)))
    n_timesteps = check_timesteps(n_timesteps)
    seed = check_seed(seed)
    _, kwargs = ppo_arguments(h)
    rollout = kwargs.get("n_steps", 2048) * n_envs
    if rollout < 2:
        raise ValueError("n_steps x n_envs must be at least 2 (PPO normalises advantages over a rollout)")
    n_timesteps = round_to_rollouts("n_timesteps", n_timesteps, rollout)
    h["n_timesteps"], h["n_envs"] = n_timesteps, n_envs
    env = check_envs(env_id, h, mode, kwargs)
    check_n_envs(n_envs, kwargs.get("n_steps", 2048), math.prod(env["signature"]["observation_shape"]))
    return RunConfig(env_id=env_id, seed=seed, n_envs=n_envs, n_timesteps=n_timesteps,
                     checkpoint_freq=DEFAULT_CHECKPOINT_FREQ if checkpoint_freq is None else checkpoint_freq,
                     eval_freq=DEFAULT_EVAL_FREQ if eval_freq is None else eval_freq,
                     action_mode=mode.to_dict(), env=env, hyperparams=h,
                     config_file="agents/hyperparams/ppo.yml" if Path(config_file) == DEFAULT_CONFIG
                     else str(config_file)).to_dict()
