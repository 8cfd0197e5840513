"""The training and evaluation envs of a run: the one place that builds them.

- :func:`make_training_venv`: the run's n_envs training envs as an SB3 VecEnv (the native vector env
  :class:`vcnc_agents.vec_env.VcncVecEnv`, or SB3's DummyVecEnv / SubprocVecEnv over Gymnasium envs), each with its
  Monitor file; the lean trainer's envs share their construction (:func:`vcnc_agents.vec_env.native_batch`).
- :func:`make_eval_env`: the plain env the evaluations run on (nominal plant, action_repeat=1).
- :func:`check_envs`: build them once before a run starts, so bad env or policy arguments fail early.

Each reads the run's :class:`vcnc_agents.run_config.RunConfig` (its env id, seed, n_envs, action mode and env
arguments).
"""

from __future__ import annotations

import multiprocessing
import signal
from pathlib import Path

import gymnasium as gym

import vcnc_gym  # noqa: F401  (registers the VCNC ids with Gymnasium)
from vcnc_gym.envs.registry import suite_env

from .action_modes import ActionMode
from .run_warning import note
from .signature import env_signature

__all__ = ["StepStamp", "make_training_venv", "make_eval_env", "eval_kwargs", "check_envs"]


class StepStamp(gym.Wrapper):
    """Writes the run's agent-step count into ``info["steps"]`` (a Monitor column).

    The training envs step in lock-step, so after this env's k-th step of a
    session that started at ``start`` steps, the run has counted
    ``start + k * stride`` agent steps (``stride`` = n_envs).
    """

    def __init__(self, env, start: int, stride: int):
        super().__init__(env)
        self._count = int(start)
        self._stride = int(stride)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._count += self._stride
        return obs, reward, terminated, truncated, dict(info, steps=self._count)


def _gym_env_factory(env_id: str, env_kwargs: dict, mode: ActionMode, start: int, stride: int):
    def make():
        if multiprocessing.parent_process() is not None:
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # a subprocess env: the main process handles Ctrl-C
        return StepStamp(mode.wrap(gym.make(env_id, **env_kwargs)), start, stride)

    return make


def make_training_venv(config, run_dir: Path, *, vec_env: str = "native", start_steps: int = 0, append: bool = False):
    """The run's training VecEnv (without normalisation): n_envs envs with their Monitor files.

    ``config`` is the run's :class:`vcnc_agents.run_config.RunConfig`.  Env i is seeded ``seed + start_steps + i``
    (a resumed session draws new plants); the Monitor files ``monitor/<i>.monitor.csv`` are appended to
    (``append``, a resumed run) or started, and record the run's step count
    at the end of every episode (column ``steps``).
    The one place that builds the training envs: ``vec_env="native"`` (the
    default) steps all envs with one kernel call per control period
    (:class:`vcnc_agents.vec_env.VcncVecEnv`, the residual baseline batched);
    "dummy" and "subproc" are SB3's per-env VecEnvs over Gymnasium envs.
    """
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    env_id, n_envs, seed = config.env_id, config.n_envs, config.seed + start_steps
    (run_dir / "monitor").mkdir(parents=True, exist_ok=True)
    if vec_env == "native" and suite_env(env_id).vector_entry_point is None:
        note(f"{env_id} has no native vector env: training on SB3's DummyVecEnv")
        vec_env = "dummy"
    if vec_env == "native" and config.mode.history:  # the lean trainer's DecisionEnv remembers on the native env
        note("an agent with history trains with SB3's PPO on DummyVecEnv (the residual wrapper remembers)")
        vec_env = "dummy"
    if vec_env == "native":
        from .vec_env import VcncVecEnv

        return VcncVecEnv(
            env_id,
            n_envs,
            config.mode,
            config.env_kwargs,
            seed=seed,
            monitor_dir=run_dir / "monitor",
            start_steps=start_steps,
            append=append,
        )
    cls = {"dummy": DummyVecEnv, "subproc": SubprocVecEnv}[vec_env]
    return make_vec_env(
        _gym_env_factory(env_id, config.env_kwargs, config.mode, start_steps, n_envs),
        n_envs=n_envs,
        seed=seed,
        vec_env_cls=cls,
        monitor_dir=str(run_dir / "monitor"),
        monitor_kwargs={"info_keywords": ("steps",), "override_existing": not append},
    )


def eval_kwargs(env_kwargs: dict) -> dict:
    """The task arguments of the plain env of the benchmark (nominal plant, action_repeat=1)."""
    return {k: v for k, v in env_kwargs.items() if k not in ("action_repeat", "randomize", "parameters")}


def make_eval_env(config):
    """The plain env the run's evaluations take (``config``: its :class:`vcnc_agents.run_config.RunConfig`)."""
    return gym.make(config.env_id, **eval_kwargs(config.env_kwargs))


def check_envs(config) -> dict:
    """Build the run's training and evaluation envs and its policy once; the env block of config.yml.

    ``config`` is the run's :class:`vcnc_agents.run_config.RunConfig`.  Raises ValueError naming env_kwargs or
    policy_kwargs when the env or the policy network cannot be built from them.
    """
    env_id, mode = config.env_id, config.mode
    env_kwargs = config.hyperparams.get("env_kwargs") or {}
    if not isinstance(env_kwargs, dict):
        raise ValueError(f"env_kwargs must be a mapping of env arguments, got {env_kwargs!r}")
    try:
        train_env = mode.wrap(gym.make(env_id, **env_kwargs))
        train_env.close()
        eval_env = gym.make(env_id, **eval_kwargs(env_kwargs))
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"env_kwargs {env_kwargs} do not make a {env_id} env for the {mode.mode} action mode: {exc}"
        ) from None
    policy, ppo_kwargs = config.ppo_arguments()
    policy_kwargs = ppo_kwargs.get("policy_kwargs")
    try:
        from vcnc_gym.envs.history import agent_space

        from .model_file import algorithm

        space = agent_space(eval_env.observation_space, mode.history, eval_env.unwrapped.layout)
        algorithm(policy).policy_aliases[policy](space, eval_env.action_space, lambda _: 3e-4, **(policy_kwargs or {}))
    except (TypeError, ValueError, AssertionError, AttributeError, KeyError) as exc:
        raise ValueError(f"policy_kwargs {policy_kwargs} do not make a policy: {exc}") from None
    signature = env_signature(eval_env)
    eval_env.close()
    return {"id": env_id, "kwargs": dict(env_kwargs), "signature": signature}
