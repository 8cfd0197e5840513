"""Reinforcement-learning agents on the vcnc-gym envs: Stable-Baselines3 PPO.

- :func:`train`: SB3's PPO on a VCNC env with the hyperparameters of
  ``agents/hyperparams/ppo.yml`` (RL Zoo's format), VecNormalize,
  checkpoints, resume, TensorBoard; one folder per run.  The console script
  ``vcnc-train`` runs the same PPO by default through the lean trainer
  (:func:`vcnc_agents.lean_ppo.train_lean`, same run folder and agents) and
  this one with ``--trainer sb3``.
- :class:`ActionMode`, :class:`ResidualAction`: the agent's action is the
  amplifier command ("direct") or a correction of a baseline's ("residual"),
  with action repeat.
- :func:`load_agent`: a trained agent as a policy with SB3's ``predict`` on
  the plain env, what ``vcnc-bench --policy ppo:PATH`` runs; it runs no code
  from the agent's files and checks the env is the one it was trained for.
- :class:`NormalizationStats`: VecNormalize statistics as a data-only ``.npz``.
- ``agents/trained/<env id>/``: the shipped agents, one per current contouring id (the specialists), and
  ``agents/trained/generalist-<plant>/``: agents trained on random contours (:data:`GENERALISTS`).

Example
-------
>>> import gymnasium as gym, vcnc_gym
>>> from vcnc_agents import load_agent, TRAINED
>>> env = gym.make("VCNC-Heart-v1")
>>> agent = load_agent(TRAINED["VCNC-Heart-v1"], env)      # doctest: +SKIP
"""

from pathlib import Path

from vcnc_gym.extras import require_extra

# ruff: noqa: E402  (the imports below follow the extra's check on purpose)
require_extra("agents", "vcnc_agents")  # Stable-Baselines3, torch, ...: the extra named if one is missing

from .action_modes import ACTION_MODES, ActionMode, ResidualAction
from .normalization import NormalizationStats
from .policy import AgentPolicy, env_signature, load_agent
from .training import RunWarning, TrainingResult, train

_SHIPPED = sorted(p for p in (Path(__file__).parent / "trained").iterdir() if p.is_dir())

#: Env id -> folder of the agent shipped for it (every folder of ``agents/trained`` named by an id).
TRAINED = {folder.name: folder for folder in _SHIPPED if folder.name.startswith("VCNC-")}

#: Plant name -> folder of the generalist shipped for it (``agents/trained/generalist-<plant>``): trained on
#: ``VCNC-RandomContour-v1``, it runs on any contouring env of that plant (:data:`vcnc_agents.policy.ANY_CONTOUR_IDS`).
GENERALISTS = {
    folder.name.removeprefix("generalist-"): folder for folder in _SHIPPED if folder.name.startswith("generalist-")
}

__all__ = [
    "train",
    "TrainingResult",
    "RunWarning",
    "load_agent",
    "AgentPolicy",
    "env_signature",
    "NormalizationStats",
    "ActionMode",
    "ResidualAction",
    "ACTION_MODES",
    "TRAINED",
    "GENERALISTS",
]
