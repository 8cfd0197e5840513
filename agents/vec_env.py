"""An SB3 ``VecEnv`` over the native vector env: N envs stepped by one kernel call per control period.

:class:`VcncVecEnv` is what ``vcnc-train`` trains on.  It runs an action mode
(:class:`vcnc_agents.action_modes.ActionMode`) over all N envs at once:

- **direct**: the agent's action is the plant command, held for the env's own
  ``action_repeat`` inside the compiled step;
- **residual**: every control period the baseline computes its command on
  the N observations, the command is
  ``clip(u_baseline / u_max + correction * a, -1, 1)``, and the agent's
  correction ``a`` is held for the mode's ``action_repeat`` periods.  A
  baseline with a compiled form (``BaselinePolicy.compiled``, e.g. SMC) runs
  inside the kernel: a whole decision of N envs is one numba call
  (``ContouringVectorEnv.step_controlled``).  Any other runs its batched
  ``predict`` once per control period, the same commands to the bit.

It gives what :class:`~vcnc_agents.action_modes.ResidualAction` on a single env
gives: the reward of a decision is the mean of the control periods' rewards
(over ``action_repeat``; less the episode peak's price with ``peak_weight``), ``info["contour_error_max"]`` the largest over the
decision, and an episode ending inside a decision ends the decision for that
env (the others run on).  SB3's conventions: an ended env is reset at once,
its last observation in ``info["terminal_observation"]``, and
``info["TimeLimit.truncated"]`` marks a truncation.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from .action_modes import ActionMode

__all__ = ["VcncVecEnv", "NativeBatch", "native_batch", "per_env_batch", "commission_drawn_plants", "monitor_writers"]


class NativeBatch(NamedTuple):
    """The native vector env of a run's training envs with the action mode's baseline.

    Attributes
    ----------
    venv
        The unwrapped native vector env (no autoreset), at ``action_repeat=1`` in residual mode.
    baseline
        The residual mode's batched baseline, None in direct mode.
    controller
        The baseline's compiled form for ``step_controlled``, None without one (or when not asked for).
    repeat : int
        Control periods per agent decision stepped by the caller (the action repeat in residual mode, else 1:
        the env repeats the action itself).
    """

    venv: object
    baseline: object
    controller: object
    repeat: int


def native_batch(
    env_id: str, n_envs: int, mode: ActionMode, env_kwargs: dict | None = None, *, compiled: bool = True
) -> NativeBatch:
    """Build ``n_envs`` envs of ``env_id`` as one native vector env for ``mode``: what :class:`VcncVecEnv` (SB3's
    trainer) and the lean trainer step.  ValueError when ``env_kwargs``' action_repeat contradicts the mode."""
    kwargs = dict(env_kwargs or {})
    residual = mode.mode == "residual"
    env_repeat = 1 if residual else mode.action_repeat
    if kwargs.get("action_repeat", env_repeat) != env_repeat:
        raise ValueError(
            f"{mode.mode} mode with action_repeat={mode.action_repeat} needs env_kwargs "
            f"action_repeat={env_repeat}, got {kwargs['action_repeat']}"
        )
    kwargs["action_repeat"] = env_repeat
    if mode.dial_rate:
        raise ValueError(
            f"dial_rate limits a feed override dial, and {env_id}'s native vector env has none (its "
            "action is the two axes)"
        )
    venv = gym.make_vec(
        env_id,
        num_envs=n_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=AutoresetMode.DISABLED,
        **kwargs,
    ).unwrapped
    baseline = mode.make_baseline(venv)
    controller = baseline.compiled(n_envs) if baseline is not None and compiled else None
    return NativeBatch(venv, baseline, controller, mode.action_repeat if residual else 1)


def commission_drawn_plants(baseline, venv, controller):
    """The controller to step after some envs of ``venv`` reset: a residual's baseline commissioned per machine
    (``ff-pid@machine``; :meth:`vcnc_baselines.servo.ServoPolicy.commission_again`) first identifies the plants
    those envs drew, so that its law fits each env's own machine; ``controller`` again for any other baseline, or
    when no plant changed."""
    again = getattr(baseline, "commission_again", None)
    fresh = again(venv) if again is not None else None
    return controller if fresh is None or controller is None else fresh


def per_env_batch(env_id: str, n_envs: int, mode: ActionMode, env_kwargs: dict | None = None) -> NativeBatch:
    """For an id without a native vector env (the feed override, the random contours): ``n_envs`` Gymnasium envs,
    each wrapped by the action mode (:meth:`ActionMode.wrap`: the residual's baseline and repeat per env), as one
    ``SyncVectorEnv`` that resets only the envs it is told to (``options={"reset_mask": ...}``).  The caller steps
    it with the agent's action itself (``baseline`` None, ``repeat`` 1): a step is a decision."""
    kwargs = dict(env_kwargs or {})
    kwargs.setdefault("action_repeat", 1 if mode.mode == "residual" else mode.action_repeat)
    venv = gym.vector.SyncVectorEnv(
        [lambda: mode.wrap(gym.make(env_id, **kwargs)) for _ in range(n_envs)], autoreset_mode=AutoresetMode.DISABLED
    )
    return NativeBatch(venv, None, None, 1)


#: The attributes ``get_attr`` answers, read from the vector env (the same for every env).
_SHARED_ATTRIBUTES = ("layout", "decision_period", "nominal_parameters", "plant", "dt", "episode_steps", "task")


class VcncVecEnv(VecEnv):
    """N envs of ``env_id`` as one SB3 ``VecEnv``, stepped through the native vector env.

    Parameters
    ----------
    env_id : str
        A registered vcnc_gym id.
    n_envs : int
        Number of envs, >= 1.
    mode : ActionMode
        Direct or residual (with its baseline, correction and action repeat).
    env_kwargs : dict, optional
        Arguments of the env (``randomize``, ``feedrate``, ...).  In residual
        mode the env runs at ``action_repeat=1`` (the baseline runs every
        control period) and the mode holds the agent's action.
    seed : int, optional
        Env i is seeded with ``seed + i`` at the first reset (as SB3's
        ``make_vec_env`` does).
    monitor_dir : path, optional
        Write one SB3 Monitor file per env, ``<monitor_dir>/<i>.monitor.csv``
        (episode return ``r``, length ``l`` in decisions, time ``t`` in s and
        ``steps``, the run's agent-step count at the episode's end), and put
        SB3's ``info["episode"]`` on each ended episode.
    start_steps : int
        The run's agent-step count when this VecEnv starts (a resumed
        session), for the ``steps`` column.
    append : bool
        Append to existing monitor files (a resumed run) instead of starting them.
    compiled : bool
        Residual mode: run the baseline inside the kernel when it has a
        compiled form (default); False calls its ``predict`` every period.
    """

    def __init__(
        self,
        env_id: str,
        n_envs: int,
        mode: ActionMode,
        env_kwargs: dict | None = None,
        seed: int | None = None,
        *,
        monitor_dir=None,
        start_steps: int = 0,
        append: bool = False,
        compiled: bool = True,
    ):
        self.mode = mode
        batch = native_batch(env_id, n_envs, mode, env_kwargs, compiled=compiled)
        self.venv, self.baseline, self.controller, self.repeat = batch
        self.env_id = env_id
        super().__init__(n_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self._seed = seed
        self._obs = None
        self._actions = None
        self._start = np.ones(n_envs, dtype=bool)
        self._steps = int(start_steps)
        self._returns = np.zeros(n_envs)
        self._lengths = np.zeros(n_envs, dtype=np.int64)
        self._t0 = time.time()
        self._writers = monitor_writers(monitor_dir, n_envs, env_id, self._t0, append)
        self.price = mode.peak_price(self.venv, n_envs)

    # -- SB3 VecEnv API ---------------------------------------------------------------
    def reset(self):
        seed = self._seed
        self._seed = None  # later resets continue each env's generator
        obs, _ = self.venv.reset(seed=seed)
        self._obs = obs
        self._start[:] = True
        if self.price is not None:
            self.price.restart()
        return obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        if self._obs is None:
            raise RuntimeError("step() called before reset()")
        if self.controller is not None:
            if self._start.any():
                self.controller = commission_drawn_plants(self.baseline, self.venv, self.controller)
                self.baseline.reset(mask=self._start)
                self._start[:] = False
            obs, total, terminated, truncated, last_info = self.venv.step_controlled(
                self.controller, self._actions, self.mode.correction, self.repeat
            )
            return self._finish(obs, total, terminated, truncated, last_info, last_info["contour_error_max"])
        n = self.num_envs
        a = self._actions
        total = np.zeros(n)
        peak = np.zeros(n)
        done = np.zeros(n, dtype=bool)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        last_info = None
        obs = self._obs
        if self.baseline is not None and self._start.any():
            commission_drawn_plants(self.baseline, self.venv, None)
        for _ in range(self.repeat):
            base = None
            if self.baseline is not None:
                base, _ = self.baseline.predict(obs, episode_start=self._start)
                self._start[:] = False
            command = self.mode.command(base, a)
            obs, reward, te, tr, info = self.venv.step(command)
            stepped = info["_contour_error"]
            total += reward
            peak = np.where(stepped, np.maximum(peak, info["contour_error_max"]), peak)
            terminated |= te
            truncated |= tr
            done |= te | tr
            last_info = info if last_info is None else _merge(last_info, info, stepped)
            if done.all():
                break
        return self._finish(obs, total, terminated, truncated, last_info, peak)

    def _finish(self, obs, total, terminated, truncated, last_info, peak):
        """SB3's step outputs from a decision's: mean reward, per-env infos, episode ends reset."""
        n = self.num_envs
        done = terminated | truncated
        infos = [{} for _ in range(n)]
        for key in (
            "contour_error",
            "position",
            "reference_position",
            "tracking_error",
            "command",
            "time",
            "diverged",
            "reward_contour",
            "reward_effort",
            "reward_divergence",
        ):
            values = last_info[key]
            for i in range(n):
                infos[i][key] = values[i]
        for i in range(n):
            infos[i]["contour_error_max"] = peak[i]
        rewards = total / self.repeat
        if self.price is not None:  # the episode's peak, priced (ActionMode.peak_weight)
            rewards = rewards - self.price(peak)
        rewards = rewards.astype(np.float32)
        self._steps += n
        self._returns += rewards
        self._lengths += 1
        if done.any():
            for i in np.flatnonzero(done):
                infos[i]["terminal_observation"] = obs[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                episode = {
                    "r": round(float(self._returns[i]), 6),
                    "l": int(self._lengths[i]),
                    "t": round(time.time() - self._t0, 6),
                }
                infos[i]["episode"] = episode
                if self._writers is not None:
                    self._writers[i].write_row({**episode, "steps": self._steps})
                self._returns[i] = 0.0
                self._lengths[i] = 0
            obs, _ = self.venv.reset(options={"reset_mask": done})
            self._start[done] = True
            if self.price is not None:
                self.price.restart(done)
        self._obs = obs
        return obs.copy(), rewards, done, infos

    def close(self) -> None:
        if self._writers is not None:
            for w in self._writers:
                w.close()
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list:
        if attr_name in _SHARED_ATTRIBUTES or hasattr(self.venv, attr_name):
            value = getattr(self.venv, attr_name)
            return [value for _ in self._get_indices(indices)]
        raise AttributeError(f"vcnc vector env has no attribute {attr_name!r}")

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        raise AttributeError(f"the envs' attributes are read-only here (tried to set {attr_name!r})")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        raise AttributeError(f"the native vector env runs no per-env methods (asked for {method_name!r})")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def seed(self, seed: int | None = None):
        self._seed = seed
        return [None if seed is None else seed + i for i in range(self.num_envs)]

    def get_images(self):
        raise NotImplementedError("the vector env does not render")


def _merge(previous: dict, info: dict, stepped: np.ndarray) -> dict:
    """Per env, the info of the last control period it was stepped in (the episode summary, a dict present only
    in the step an episode ends, is the step's own)."""
    out = {}
    for key, value in info.items():
        if key.startswith("_"):
            continue
        if key not in previous or isinstance(value, dict):
            out[key] = value
            continue
        mask = stepped.reshape((-1,) + (1,) * (np.ndim(value) - 1))
        out[key] = np.where(mask, value, previous[key])
    return out


def monitor_writers(monitor_dir, n_envs: int, env_id: str, t0: float, append: bool):
    """One SB3 Monitor file per env in ``monitor_dir`` (``0.monitor.csv`` ...), each row with the run's step count
    (``steps``); appended to when ``append`` (a resumed run).  None without a folder."""
    if monitor_dir is None:
        return None
    from stable_baselines3.common.monitor import ResultsWriter

    Path(monitor_dir).mkdir(parents=True, exist_ok=True)
    return [
        ResultsWriter(
            str(Path(monitor_dir) / f"{i}"),
            header={"t_start": t0, "env_id": env_id},
            extra_keys=("steps",),
            override_existing=not append,
        )
        for i in range(n_envs)
    ]
