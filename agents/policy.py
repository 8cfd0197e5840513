"""A trained agent as a control-period policy: what ``vcnc-bench --policy ppo:PATH`` runs.

An agent is a folder (a run's ``best/`` or ``final/``, or a shipped agent in
``agents/trained/``) holding

- ``model.zip``: the SB3 PPO model;
- ``vecnormalize.npz``: the observation normalisation it was trained with
  (:class:`vcnc_agents.normalization.NormalizationStats`, plain numbers);
- ``config.yml``: the run's configuration, whose ``action_mode`` says what
  the action means (:class:`vcnc_agents.action_modes.ActionMode`) and whose
  ``env`` block records the env it was trained for (:func:`env_signature`).

Loading an agent runs no code from its folder: the YAML is read with
``yaml.safe_load``, the statistics with ``numpy.load(allow_pickle=False)``
and the model through :func:`vcnc_agents.model_file.load_ppo`, which unpickles
nothing of the file.

:class:`AgentPolicy` runs it on the plain env, the one the baselines run on
(``action_repeat=1``): it is called every control period, asks the network
for a new action every ``action_repeat`` calls and, in residual mode, adds the
held correction to its own copy of the baseline, exactly as the training
wrappers do.  Its ``predict`` has SB3's signature.
"""

from __future__ import annotations

import warnings

import numpy as np

from vcnc_gym.envs.history import DecisionHistory, agent_space

from .action_modes import ActionMode
from .normalization import NormalizationStats
from .run_folder import CONFIG_FILE, MODEL_FILE, NORMALIZATION_FILE, agent_files, evaluation_row, read_agent_config
from .signature import (
    ANY_CONTOUR_IDS,
    MACHINE_FIELDS,
    as_seen_through,
    check_env_signature,
    check_signature,
    env_signature,
    observation_pick,
)

__all__ = [
    "AgentPolicy",
    "load_agent",
    "evaluate_model",
    "agent_files",
    "agent_mismatch",
    "env_signature",
    "check_env_signature",
    "check_signature",
    "ANY_CONTOUR_IDS",
    "MACHINE_FIELDS",
    "MODEL_FILE",
    "NORMALIZATION_FILE",
    "CONFIG_FILE",
]


class AgentPolicy:
    """A trained SB3 agent as a policy called every control period of the plain env.

    Parameters
    ----------
    model : stable_baselines3.common.base_class.BaseAlgorithm
        The trained model (its ``predict`` takes normalised observations).
    normalization : NormalizationStats or None
        The observation statistics of training (``normalize_obs`` is used).
    action_mode : ActionMode
        What the model's action means, and its decision period in control periods.
    env : gymnasium.Env
        The plain env (``action_repeat=1``) the policy will run on; builds
        the residual's baseline and checks the observation space.
    pick : array of int, optional
        The entries of the env's observation the model sees, in its order
        (:func:`vcnc_agents.signature.observation_pick`: an agent trained
        with a smaller preview); None: all of them.  The baseline sees all.
    """

    def __init__(self, model, normalization, action_mode: ActionMode, env, pick=None):
        u = env.unwrapped
        if u.action_repeat != 1:
            raise ValueError(f"an agent is evaluated on the plain env (action_repeat=1), got {u.action_repeat}")
        if model.action_space.shape != u.action_space.shape:
            raise ValueError(
                f"the agent acts with shape {model.action_space.shape}, the env takes {u.action_space.shape}"
            )
        space = u.observation_space
        if pick is not None:
            space = type(space)(space.low[pick], space.high[pick], dtype=space.dtype)
        seen = agent_space(space, action_mode.history, u.layout).shape
        if model.observation_space.shape != seen:
            raise ValueError(
                f"the agent observes shape {model.observation_space.shape}, "
                f"the env gives {seen}: it was trained with another layout"
            )
        self.pick = pick
        self.model = model
        self.normalization = normalization
        self.action_mode = action_mode
        self.baseline = action_mode.make_baseline(env)
        self._count = None  # control periods since the last decision, per env
        self._held = None  # the agent's held action, per env
        self._layout = u.layout
        self._env = u
        # the agent's dial at its rate, per env (action_mode.dial_rate; None: none); an env without a dial is refused
        # here, not at the first step
        self.slew = action_mode.dial_slew(u, 1)
        self.history = None  # the remembered decisions, per env (action_mode.history)
        # a recurrent policy (sb3-contrib's RecurrentPPO): its LSTM states per env, and which envs start an episode
        self.recurrent = getattr(getattr(model, "policy", None), "lstm_actor", None) is not None
        self._lstm = None
        self._fresh = None
        self._actor = _deterministic_actor(model)

    def plan(self, env) -> None:
        """Hand ``env``'s reference to the residual's baseline (a model-based baseline rebuilds its table for a
        contour drawn at reset; the evaluation loops call this after every reset)."""
        if hasattr(self.baseline, "plan"):
            self.baseline.plan(env)

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
            self._held = np.zeros((n,) + tuple(self.model.action_space.shape), dtype=np.float32)
            if self.action_mode.history:
                self.history = DecisionHistory(self.action_mode.history, self._layout, n)
                self.history.start(obs2)
            if self.recurrent:
                layers, _, size = self.model.policy.lstm_hidden_state_shape
                self._lstm = tuple(np.zeros((layers, n, size), dtype=np.float32) for _ in range(2))
                self._fresh = np.ones(n, dtype=bool)
            self.slew = self.action_mode.dial_slew(self._env, n)
        if episode_start is not None:
            start = np.broadcast_to(np.asarray(episode_start, dtype=bool).reshape(-1), (n,))
            self._count[start] = 0
            if self.history is not None and start.any():
                self.history.start(obs2, start)
            if self.recurrent:
                self._fresh |= start
            if self.slew is not None:
                self.slew.restart(start)
        decide = self._count % self.action_mode.action_repeat == 0
        if decide.any():
            x = obs2[decide] if self.pick is None else obs2[decide][:, self.pick]
            if self.history is not None:  # the remembered decisions follow, then this one joins them
                x = self.history.seen(obs2, decide, base=x)
                self.history.push(obs2, decide)
            if self.normalization is not None:
                x = self.normalization.normalize_obs(x)
            if self.recurrent:  # its LSTM steps once per decision, from zeros where an episode starts
                state = tuple(h[:, decide] for h in self._lstm)
                self._held[decide], state = self.model.predict(
                    x, state=state, episode_start=self._fresh[decide], deterministic=deterministic
                )
                for h, new in zip(self._lstm, state):
                    h[:, decide] = new
                self._fresh[decide] = False
            elif deterministic and self._actor is not None:
                self._held[decide] = self._actor(x)
            else:
                self._held[decide], _ = self.model.predict(x, deterministic=deterministic)
        self._count += 1
        base = None
        if self.baseline is not None:
            base, _ = self.baseline.predict(obs2, episode_start=episode_start)
        held = self._held if self.slew is None else self.slew(self._held)
        action = self.action_mode.command(base, held)
        return (action[0] if single else action), state

    def __repr__(self) -> str:
        return f"AgentPolicy({type(self.model).__name__}, {self.action_mode})"


def _deterministic_actor(model):
    """SB3's deterministic ``model.predict`` of a batch, without its per-call bookkeeping (the eval-mode switch
    walks every module, the distribution object is built and dropped): for an :class:`ActorCriticPolicy` whose
    action distribution is a diagonal Gaussian without squashing, the mean action of the actor network, clipped to
    the action space, the same operations in the same order as SB3's, so the same numbers to the bit
    (``tests/test_agent_policy.py``); None for any other policy, which then goes through ``model.predict``."""
    import torch as th
    from gymnasium import spaces
    from stable_baselines3.common.distributions import DiagGaussianDistribution
    from stable_baselines3.common.policies import ActorCriticPolicy, BaseModel

    policy = getattr(model, "policy", None)
    if getattr(policy, "lstm_actor", None) is not None:  # recurrent: its actor reads the LSTM's state
        return None
    if (
        not isinstance(policy, ActorCriticPolicy)
        or type(policy.action_dist) is not DiagGaussianDistribution
        or policy.squash_output
        or not isinstance(policy.action_space, spaces.Box)
    ):
        return None
    policy.set_training_mode(False)
    low, high, shape = policy.action_space.low, policy.action_space.high, policy.action_space.shape

    def actor(x: np.ndarray) -> np.ndarray:
        with th.no_grad():
            obs = th.as_tensor(x, device=policy.device).float()
            features = BaseModel.extract_features(policy, obs, policy.pi_features_extractor)  # as get_distribution
            mean = policy.action_net(policy.mlp_extractor.forward_actor(features))
        return np.clip(mean.cpu().numpy().reshape((-1, *shape)), low, high)

    return actor


def evaluate_model(model, stats: NormalizationStats, config, env, steps: int) -> dict:
    """One deterministic episode of a model in training on the evaluation env, as both trainers take it: its
    evaluations.csv row (:func:`vcnc_agents.run_folder.evaluation_row`).

    ``model`` is the SB3 PPO model, ``stats`` its normalisation, ``config`` the run's
    :class:`vcnc_agents.run_config.RunConfig` (the action mode), ``env`` the plain env
    (:func:`vcnc_agents.env_factory.make_eval_env`) and ``steps`` the run's agent steps; the episode runs through
    :func:`vcnc_gym.evaluation.run_episode`, as the benchmark's, with seed 0.
    """
    from vcnc_gym.evaluation import run_episode

    return evaluation_row(steps, run_episode(AgentPolicy(model, stats, config.mode, env), env, seed=0))


def agent_mismatch(path, env) -> str | None:
    """Why the agent in ``path`` does not fit ``env`` (the message :func:`load_agent` would raise), or None.

    Reads only the agent's config.yml (no model); for choosing default
    policies, e.g. the bench's shipped agent at a non-default feedrate.
    """
    data = read_agent_config(agent_files(path)[2])
    recorded = (data.get("env") or {}).get("signature") or {"id": data.get("env_id")}
    try:
        if observation_pick(recorded, env) is not None:
            recorded = as_seen_through(recorded, env)
        check_signature(recorded, env_signature(env), what=f"the agent in {str(path)!r}")
    except ValueError as exc:
        return str(exc)
    return None


def load_agent(path, env, device: str = "cpu", allow_mismatch: bool = False) -> AgentPolicy:
    """Load the agent in folder ``path`` (or ``path`` = its model.zip) for the plain ``env``.

    Runs no code from the folder (see the module docstring).  The env must
    be the configuration the agent was trained for: its config.yml's ``env``
    block (:func:`env_signature`) is compared with ``env``.  An agent trained
    with a smaller preview (fewer ``preview_steps`` or ``contour_ahead``
    points, or none) runs on an env that gives more: it sees its own points
    (:func:`vcnc_agents.signature.observation_pick`).

    Parameters
    ----------
    path : path
        Agent folder (model.zip, vecnormalize.npz, config.yml) or its model.zip.
    env : gymnasium.Env
        The plain env (``action_repeat=1``) the agent will run on.
    device : str
        Torch device.
    allow_mismatch : bool
        Run an agent on an env configuration other than its own (another
        contour, feedrate, ...) with a warning instead of an error.  Shapes
        must still agree.

    Raises
    ------
    FileNotFoundError
        For a missing folder or file.
    ValueError
        For an empty path, a pickled normalisation file, damaged or foreign
        files, or an agent trained on another env configuration (naming the
        fields that differ).
    """
    from .config import ppo_arguments
    from .model_file import load_ppo

    model_file, norm_file, config_file = agent_files(path)
    data = read_agent_config(config_file)
    recorded = (data.get("env") or {}).get("signature")
    pick = observation_pick(recorded, env) if isinstance(recorded, dict) else None
    if pick is not None:  # trained with a smaller preview: it sees its own fields of this env's observation
        recorded = as_seen_through(recorded, env)
    if isinstance(recorded, dict):
        check_env_signature(recorded, env, what=f"the agent in {str(path)!r}", allow_mismatch=allow_mismatch)
    else:
        check_env_signature(
            {"id": data.get("env_id")}, env, what=f"the agent in {str(path)!r}", allow_mismatch=allow_mismatch
        )
        warnings.warn(
            f"{config_file} records no env configuration (an agent from an older vcnc-train): only its "
            "env id and observation size are checked",
            stacklevel=2,
        )
    stats = NormalizationStats.load(norm_file)
    space = env.unwrapped.observation_space
    if pick is not None:
        space = type(space)(space.low[pick], space.high[pick], dtype=space.dtype)
    try:
        mode = ActionMode(**data.get("action_mode", {}))
    except TypeError as exc:
        raise ValueError(f"{config_file}: action_mode is not an action mode ({exc})") from None
    space = agent_space(space, mode.history, env.unwrapped.layout)
    obs_shape = tuple(space.shape)
    if (stats.observation_size,) != obs_shape:
        raise ValueError(
            f"{norm_file} normalises {stats.observation_size} observation entries, the env gives "
            f"shape {obs_shape}: it belongs to another agent or env configuration"
        )
    policy_name, ppo_kwargs = ppo_arguments(data.get("hyperparams") or {})
    model = load_ppo(
        model_file,
        observation_space=space,
        action_space=env.unwrapped.action_space,
        ppo_kwargs=ppo_kwargs,
        device=device,
        policy=policy_name,
    )
    return AgentPolicy(model, stats, mode, env, pick=pick)
