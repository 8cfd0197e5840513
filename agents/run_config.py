"""The configuration of a training run: checked options and the ``config.yml`` a run folder keeps.

As RL Zoo's ``exp_manager``: the hyperparameter entry of ``agents/hyperparams/ppo.yml`` (:mod:`vcnc_agents.config`)
plus the command line's options (env id, seed, n_envs, total steps, action mode, checkpoint and evaluation
periods) make a run's config (:func:`new_config`).  :class:`RunConfig` is its typed record: what travels from
:func:`vcnc_agents.run_session.prepare_run` to the trainers, the env factory and the callbacks (they read its
fields, never a dict), what ``RUN/config.yml`` holds (:meth:`RunConfig.to_dict`, written by
:mod:`vcnc_agents.run_folder`) and what a resume reads back (:meth:`RunConfig.read`, which checks every field and
keeps the ones it does not know, e.g. an agent's ``agent`` block).  Every check names the argument
(:mod:`vcnc_gym.validation`).  A new training option is a field here and its use (``docs/guides``, "add a
training option").
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from vcnc_gym.envs.registry import suite_env
from vcnc_gym.validation import size

from .action_modes import ActionMode
from .config import DEFAULT_CONFIG, action_mode_of, count, load_hyperparameters, ppo_arguments, with_action_mode
from .run_folder import read_run_config
from .run_warning import note

__all__ = [
    "RunConfig",
    "training_option",
    "TRAINING_OPTIONS",
    "OPTION_FIELDS",
    "ORDER",
    "check_option",
    "check_options",
    "new_config",
    "check_env_id",
    "check_seed",
    "check_training_options",
    "check_n_envs",
    "check_timesteps",
    "check_memory",
    "round_to_rollouts",
    "VEC_ENVS",
    "DEFAULT_CHECKPOINT_FREQ",
    "DEFAULT_EVAL_FREQ",
    "MAX_TIMESTEPS",
    "SEED_MAX",
]

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


def training_option(default: int, minimum: int, help: str):
    """A field of :class:`RunConfig` that is a training option: ``vcnc-train --NAME N`` (the flag and its help
    made from it, :mod:`vcnc_agents.arguments`), a keyword of :func:`vcnc_agents.training.train` and
    :func:`vcnc_agents.run_session.prepare_run`, a key of a sweep file, checked (an integer >= ``minimum``, the error
    naming it), recorded in config.yml, and changeable on resume (None: the run's, else ``default``)."""
    return field(default=None, metadata={"option": True, "default": default, "minimum": minimum, "help": help})


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
    trainer : str or None
        The trainer that trains it, "lean" (:mod:`vcnc_agents.lean_ppo`); None: SB3's (:mod:`vcnc_agents.training`).
    init_from : str or None
        The agent folder whose weights and normalisation the run started from (``--init-from``,
        :mod:`vcnc_agents.warm_start`); None: a fresh policy.
    extra : dict
        Keys this record does not interpret (an agent folder's ``agent``), kept as read.
    """

    env_id: str
    seed: int
    n_envs: int
    n_timesteps: int
    action_mode: dict
    hyperparams: dict
    checkpoint_freq: int | None = training_option(DEFAULT_CHECKPOINT_FREQ, 1, "agent steps between checkpoints")
    eval_freq: int | None = training_option(
        DEFAULT_EVAL_FREQ, 0, "agent steps between deterministic evaluations on the nominal plant, 0: only at the end"
    )
    env: dict | None = None
    config_file: str | None = None
    trainer: str | None = None
    init_from: str | None = None
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_dict(cls, data, *, source: str = "config") -> RunConfig:
        """The record of a config.yml's mapping; ValueError naming the field that is missing or of the wrong type."""
        if not isinstance(data, dict):
            raise ValueError(f"{source} must be a mapping, got {type(data).__name__}")
        missing = [
            k for k in ("env_id", "seed", "n_envs", "n_timesteps", "action_mode", "hyperparams") if k not in data
        ]
        if missing:
            raise ValueError(f"{source} lacks {', '.join(missing)}")
        if not isinstance(data["env_id"], str):
            raise ValueError(f"{source}: env_id must be a string, got {data['env_id']!r}")
        for key in ("seed", "n_envs", "n_timesteps"):
            count(f"{source}: {key}", data[key], 0 if key == "seed" else 1)
        for key in TRAINING_OPTIONS:
            if data.get(key) is not None:
                check_option(key, data[key], where=f"{source}: ")
        for key in ("action_mode", "hyperparams", "env"):
            if key in data and data[key] is not None and not isinstance(data[key], dict):
                raise ValueError(f"{source}: {key} must be a mapping, got {data[key]!r}")
        for key in ("config_file", "trainer", "init_from"):
            if data.get(key) is not None and not isinstance(data[key], str):
                raise ValueError(f"{source}: {key} must be a string, got {data[key]!r}")
        ActionMode(**data["action_mode"])  # a bad mode names its argument
        known = {f.name for f in fields(cls)} - {"extra"}
        return cls(
            **{k: v for k, v in data.items() if k in known}, extra={k: v for k, v in data.items() if k not in known}
        )

    def to_dict(self) -> dict:
        """The mapping config.yml holds (fields in :data:`ORDER`, absent optional ones left out, then ``extra``)."""
        out = {}
        for key in ORDER:
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        out.update(self.extra)
        return out

    @classmethod
    def read(cls, run_dir: Path) -> RunConfig:
        """The configuration of the run in ``run_dir`` (its config.yml); ValueError or FileNotFoundError saying
        why the run cannot be resumed."""
        data = read_run_config(run_dir)
        try:
            return cls.from_dict(data, source=str(run_dir / "config.yml"))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"cannot resume: {exc}") from None

    # -- what the trainers read ----------------------------------------------------------------------------------
    @property
    def mode(self) -> ActionMode:
        """The agent's action mode."""
        return ActionMode(**self.action_mode)

    @property
    def action_repeat(self) -> int:
        """Control periods per agent decision."""
        return int(self.action_mode["action_repeat"])

    @property
    def env_kwargs(self) -> dict:
        """The training env's arguments (the entry's ``env_kwargs``)."""
        return dict(self.hyperparams.get("env_kwargs") or {})

    def ppo_arguments(self) -> tuple[str, dict]:
        """(policy name, keyword arguments of SB3's ``PPO``) of the hyperparameter entry."""
        return ppo_arguments(self.hyperparams)

    @property
    def rollout_size(self) -> int:
        """Agent steps of one PPO rollout: n_steps x n_envs."""
        return self.ppo_arguments()[1].get("n_steps", 2048) * self.n_envs

    # -- the changes a run may make ------------------------------------------------------------------------------
    def with_options(self, **options) -> RunConfig:
        """The training options given (:data:`TRAINING_OPTIONS`; None or left out: the run's, or the option's
        default for a config.yml that recorded none), checked."""
        check_options(options)
        changed = {}
        for name in TRAINING_OPTIONS:
            given, recorded = options.get(name), getattr(self, name)
            changed[name] = (
                given
                if given is not None
                else recorded
                if recorded is not None
                else OPTION_FIELDS[name].metadata["default"]
            )
        return replace(self, **changed)

    def with_total(self, n_timesteps: int) -> RunConfig:
        """A new total of agent steps, checked and rounded up to whole rollouts (:class:`RunWarning`)."""
        total = round_to_rollouts("n_timesteps", check_timesteps(count("n_timesteps", n_timesteps)), self.rollout_size)
        return replace(self, n_timesteps=total, hyperparams=dict(self.hyperparams, n_timesteps=total))

    def with_env(self, env: dict) -> RunConfig:
        """The env block (:func:`vcnc_agents.env_factory.check_envs`) recorded."""
        return replace(self, env=env)

    def with_trainer(self, trainer: str | None) -> RunConfig:
        """The trainer recorded ("lean"; "sb3" records none, as before the lean trainer was)."""
        return replace(self, trainer=None if trainer == "sb3" else trainer)


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


#: The fields of :class:`RunConfig` that are training options (:func:`training_option`), by name.
OPTION_FIELDS = {f.name: f for f in fields(RunConfig) if f.metadata.get("option")}

#: The training options' names, in their fields' order: ``checkpoint_freq``, ``eval_freq``.
TRAINING_OPTIONS = tuple(OPTION_FIELDS)

#: The keys of config.yml in the order they are written.
ORDER = (
    "env_id",
    "seed",
    "n_envs",
    "n_timesteps",
    *TRAINING_OPTIONS,
    "action_mode",
    "env",
    "hyperparams",
    "config_file",
    "trainer",
    "init_from",
)


def check_option(name: str, value, *, where: str = "") -> int:
    """``value`` of the training option ``name`` checked (an integer >= its minimum); ValueError naming it."""
    return count(f"{where}{name}", value, OPTION_FIELDS[name].metadata["minimum"])


def check_options(options: dict) -> None:
    """Every training option given that is not None checked; TypeError naming one that is none."""
    unknown = sorted(set(options) - set(TRAINING_OPTIONS))
    if unknown:
        raise TypeError(
            f"unknown training option(s) {', '.join(unknown)}; the options are {', '.join(TRAINING_OPTIONS)}"
        )
    for name, value in options.items():
        if value is not None:
            check_option(name, value)


def check_training_options(*, vec_env, tensorboard, **options) -> None:
    """ValueError for a bad training option of :func:`vcnc_agents.training.train` (the run-independent ones; None =
    the run's): the :data:`TRAINING_OPTIONS` given, ``vec_env`` and ``tensorboard``."""
    check_options(options)
    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {vec_env!r}")
    if tensorboard and importlib.util.find_spec("tensorboard") is None:
        raise ValueError("tensorboard logging was asked for but tensorboard is not installed")


def round_to_rollouts(name: str, n_timesteps: int, rollout: int) -> int:
    total = -(-n_timesteps // rollout) * rollout
    if total != n_timesteps:
        note(
            f"{name} {n_timesteps} is rounded up to {total}: PPO trains whole rollouts of n_steps x n_envs = "
            f"{rollout} agent steps"
        )
    return total


def check_timesteps(n_timesteps: int) -> int:
    return size(
        "n_timesteps",
        n_timesteps,
        ceiling=MAX_TIMESTEPS,
        why="MAX_TIMESTEPS, 20 days at the 5 630 steps/s measured on 2 cores; resume a run to go further",
    )


def check_n_envs(n_envs: int, n_steps: int | None = None, observation_size: int | None = None) -> int:
    """``n_envs`` within the open-file limit (one Monitor file per env) and, with the rollout's size, memory."""
    import resource

    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    if soft != resource.RLIM_INFINITY:
        size(
            "n_envs",
            n_envs,
            ceiling=max(1, soft - RESERVED_FILES),
            why=f"each env keeps its Monitor file open and this process may open {soft} files (ulimit -n), "
            f"{RESERVED_FILES} kept for the rest",
        )
    if n_steps is not None and observation_size is not None:
        rollout = n_steps * (observation_size + 2 + 6) * 4  # float32 observation, action and 6 scalars per step
        size(
            "n_envs",
            n_envs,
            bytes_each=rollout + ENV_BYTES,
            why=f"each env fills n_steps = {n_steps} rows of PPO's rollout buffer ({observation_size} observation "
            "entries, 2 actions, 6 scalars in float32) and holds its Monitor file and batch rows",
        )
    return n_envs


def new_config(env_id, *, config_file, n_timesteps, seed, n_envs, action_mode, tolerance=None, **options) -> RunConfig:
    """A new run's config from the hyperparameter entry and the options, all checked but the envs
    (:func:`vcnc_agents.env_factory.check_envs` builds them and gives the env block, :meth:`RunConfig.with_env`);
    ``tolerance`` (mm, ``--tolerance``) goes into the entry's env_kwargs (a feed-override env's tolerance task)."""
    h = load_hyperparameters(env_id, config_file)
    ppo_arguments(h)  # refuse a bad entry before anything else
    if tolerance is not None:
        h["env_kwargs"] = {**(h.get("env_kwargs") or {}), "tolerance": tolerance}
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
    return RunConfig(
        env_id=env_id,
        seed=seed,
        n_envs=n_envs,
        n_timesteps=n_timesteps,
        action_mode=mode.to_dict(),
        hyperparams=h,
        config_file="agents/hyperparams/ppo.yml" if Path(config_file) == DEFAULT_CONFIG else str(config_file),
    ).with_options(**options)


def check_memory(config: RunConfig) -> None:
    """ValueError naming n_envs when the run's rollout buffer and envs would not fit in memory (needs the env
    block: the observation's size)."""
    n_steps = config.ppo_arguments()[1].get("n_steps", 2048)
    check_n_envs(config.n_envs, n_steps, math.prod(config.env["signature"]["observation_shape"]))
