"""A trained agent as a control-period policy: what ``vcnc-bench --policy ppo:PATH`` runs.

An agent is a folder (a run's ``best/`` or ``final/``, or a shipped agent in
``agents/trained/``) holding

- ``model.zip``: the SB3 PPO model;
- ``vecnormalize.pkl``: the observation normalisation (VecNormalize) it was trained with;
- ``config.yml``: the run's configuration, whose ``action_mode`` says what
  the action means (:class:`agents.action_modes.ActionMode`).

:class:`AgentPolicy` runs it on the plain env, the one the baselines run on
(``action_repeat=1``): it is called every control period, asks the network
for a new action every ``action_repeat`` calls and, in residual mode, adds the
held correction to its own copy of the baseline, exactly as the training
wrappers do.  Its ``predict`` has SB3's signature.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import yaml

from .action_modes import ActionMode

__all__ = ["AgentPolicy", "load_agent", "agent_files", "MODEL_FILE", "NORMALIZATION_FILE", "CONFIG_FILE"]

MODEL_FILE = "model.zip"
NORMALIZATION_FILE = "vecnormalize.pkl"
CONFIG_FILE = "config.yml"


def agent_files(path) -> tuple[Path, Path, Path]:
    """(model, normalisation, config) paths of an agent folder, or of its ``model.zip``.

    Raises FileNotFoundError naming what is missing.
    """
    p = Path(path)
    folder = p.parent if p.suffix == ".zip" else p
    if not folder.is_dir():
        raise FileNotFoundError(f"no agent at {str(path)!r}: not a folder or a model.zip in one")
    files = (p if p.suffix == ".zip" else folder / MODEL_FILE, folder / NORMALIZATION_FILE, folder / CONFIG_FILE)
    missing = [f.name for f in files if not f.is_file()]
    if missing:
        raise FileNotFoundError(f"agent folder {str(folder)!r} lacks {', '.join(missing)}")
    return files


class AgentPolicy:
    """A trained SB3 agent as a policy called every control period of the plain env.

    Parameters
    ----------
    model : stable_baselines3.common.base_class.BaseAlgorithm
        The trained model (its ``predict`` takes normalised observations).
    normalization : stable_baselines3.common.vec_env.VecNormalize or None
        The observation statistics of training (``normalize_obs`` is used).
    action_mode : ActionMode
        What the model's action means, and its decision period in control periods.
    env : gymnasium.Env
        The plain env (``action_repeat=1``) the policy will run on; builds
        the residual's baseline and checks the observation space.
    """

    def __init__(self, model, normalization, action_mode: ActionMode, env):
        u = env.unwrapped
        if u.action_repeat != 1:
            raise ValueError(f"an agent is evaluated on the plain env (action_repeat=1), got {u.action_repeat}")
        if model.observation_space.shape != u.observation_space.shape:
            raise ValueError(f"the agent observes shape {model.observation_space.shape}, "
                             f"the env gives {u.observation_space.shape}: it was trained with another layout")
        self.model = model
        self.normalization = normalization
        self.action_mode = action_mode
        self.baseline = action_mode.make_baseline(env)
        self._count = None  # control periods since the last decision, per env
        self._held = None   # the agent's held action, per env

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """Normalised amplifier command for one observation (obs_dim,) or a batch (n_envs, obs_dim).

        ``episode_start`` (bool per env) restarts the decision clock and the
        baseline's memory; ``state`` is passed through.
        """
        obs = np.asarray(observation, dtype=np.float32)
        single = obs.ndim == 1
        obs2 = obs.reshape(1, -1) if single else obs
        n = obs2.shape[0]
        if self._count is None or self._count.shape[0] != n:
            self._count = np.zeros(n, dtype=np.int64)
            self._held = np.zeros((n, 2), dtype=np.float32)
        if episode_start is not None:
            start = np.broadcast_to(np.asarray(episode_start, dtype=bool).reshape(-1), (n,))
            self._count[start] = 0
        decide = self._count % self.action_mode.action_repeat == 0
        if decide.any():
            x = obs2[decide]
            if self.normalization is not None:
                x = self.normalization.normalize_obs(x)
            self._held[decide], _ = self.model.predict(x, deterministic=deterministic)
        self._count += 1
        base = None
        if self.baseline is not None:
            base, _ = self.baseline.predict(obs2, episode_start=episode_start)
        action = self.action_mode.command(base, self._held)
        return (action[0] if single else action), state

    def __repr__(self) -> str:
        return f"AgentPolicy({type(self.model).__name__}, {self.action_mode})"


def load_agent(path, env, device: str = "cpu") -> AgentPolicy:
    """Load the agent in folder ``path`` (or ``path`` = its model.zip) for the plain ``env``.

    Raises FileNotFoundError for a missing file, ValueError for an agent
    that does not fit ``env``.
    """
    from stable_baselines3 import PPO

    model_file, norm_file, config_file = agent_files(path)
    config = yaml.safe_load(config_file.read_text()) or {}
    env_id = getattr(getattr(env.unwrapped, "spec", None), "id", None)
    trained_on = config.get("env_id")
    if env_id is not None and trained_on is not None and env_id != trained_on:
        raise ValueError(f"the agent in {str(path)!r} was trained on {trained_on}, not {env_id}")
    mode = ActionMode(**config.get("action_mode", {}))
    model = PPO.load(model_file, device=device)
    with open(norm_file, "rb") as f:
        normalization = pickle.load(f)
    normalization.training = False
    return AgentPolicy(model, normalization, mode, env)
