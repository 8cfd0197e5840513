"""An agent's memory of its last decisions: what lets a residual identify the machine it runs on.

Here, beside the observation's layout, because the trainers, the residual's wrapper and the bench's agents all
use it (``vcnc_agents`` imports it; it imports nothing but numpy and Gymnasium's spaces).

A residual that sees only the present instant cannot tell two plants of the uncertainty box apart when their
present observations agree.  With ``history=K`` (:class:`vcnc_agents.action_modes.ActionMode`), the agent's
observation at decision t is the env's observation followed by the fields :data:`HISTORY_FIELDS` of the
observations at the K decisions before it, newest first::

    [obs_t,  f(obs_{t-1}),  f(obs_{t-2}),  ...,  f(obs_{t-K})]

where f picks the command last applied (``previous_action``: the baseline's plus the correction, normalised), the
tracking and contour errors, the measured velocity and the reference acceleration (the input, the output and the
excitation from which an identification would estimate inertia, friction and a mode).  At an episode's first
decision the past is the first observation repeated (the machine at rest where it starts).  A decision is
``action_repeat`` control periods, so K decisions span ``K * action_repeat * dt`` seconds: 8 ms for K = 8 at the
heart's 0.1 ms and 10 periods, more than a period of the shop floor's 150 Hz mode (6.7 ms).

One class, :class:`DecisionHistory`, holds the past of N envs as arrays: :meth:`~DecisionHistory.start` at an
episode's start, :meth:`~DecisionHistory.push` of the observation each decision is made on,
:meth:`~DecisionHistory.seen` for what the agent sees.  The lean trainer's envs
(:class:`vcnc_agents.lean_ppo.DecisionEnv`), the residual's Gymnasium wrapper
(:class:`vcnc_agents.action_modes.ResidualAction`) and the evaluation of a trained agent
(:class:`vcnc_agents.policy.AgentPolicy`) use it, so an agent sees in the bench what it saw in training.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

__all__ = ["HISTORY_FIELDS", "history_columns", "DecisionHistory", "agent_space"]

#: The observation fields remembered per past decision (:class:`vcnc_gym.envs.layout.ObservationLayout` names).
HISTORY_FIELDS = ("previous_action", "tracking_error", "contour_error", "velocity", "reference_acceleration")


def history_columns(layout) -> np.ndarray:
    """The entries of the env's observation vector that one past decision keeps (int array, in
    :data:`HISTORY_FIELDS`' order)."""
    return np.concatenate([np.arange(layout.slice(n).start, layout.slice(n).stop) for n in HISTORY_FIELDS])


class DecisionHistory:
    """The fields of the last ``decisions`` agent decisions' observations of ``n_envs`` envs.

    Parameters
    ----------
    decisions : int
        K, the past decisions remembered (>= 1).
    layout : vcnc_gym.envs.layout.ObservationLayout
        The env's observation layout (where the remembered fields are).
    n_envs : int
        Number of envs (rows).

    Every method takes every env's observations, (n, layout.size), and a row selection (a bool mask or indices;
    None: every env).
    """

    def __init__(self, decisions: int, layout, n_envs: int):
        if isinstance(decisions, bool) or not isinstance(decisions, (int, np.integer)) or decisions < 1:
            raise ValueError(f"history must be an integer >= 1 (past decisions), got {decisions!r}")
        self.decisions = int(decisions)
        self.columns = history_columns(layout)
        self.observation_size = int(layout.size)
        self._bounds = np.tile(layout.high()[self.columns], self.decisions).astype(np.float32)
        self._past = np.zeros((int(n_envs), self.decisions, self.columns.size), dtype=np.float32)

    @property
    def n_envs(self) -> int:
        return self._past.shape[0]

    @property
    def size(self) -> int:
        """Entries the history adds to the observation: K x the remembered fields' entries."""
        return self.decisions * self.columns.size

    def space(self, base: spaces.Box) -> spaces.Box:
        """The agent's observation space: ``base`` (the env's, or the entries of it an agent sees) and the past's
        bounds (the remembered fields' own)."""
        return spaces.Box(
            np.concatenate([base.low, -self._bounds]).astype(np.float32),
            np.concatenate([base.high, self._bounds]).astype(np.float32),
            dtype=np.float32,
        )

    def _fields(self, obs, rows) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        if obs.shape != (self.n_envs, self.observation_size):
            raise ValueError(
                f"observations must have shape ({self.n_envs}, {self.observation_size}) (every env's), got {obs.shape}"
            )
        return obs[rows][:, self.columns]

    def start(self, obs, rows=None) -> None:
        """The envs of ``rows`` start an episode at their rows of ``obs`` (every env's observation, (n, size)):
        their past is that observation, K times."""
        rows = slice(None) if rows is None else rows
        self._past[rows] = self._fields(obs, rows)[:, None, :]

    def push(self, obs, rows=None) -> None:
        """The envs of ``rows`` decide on their rows of ``obs`` (every env's observation): it joins their past as
        the newest decision, and the oldest leaves."""
        rows = slice(None) if rows is None else rows
        f = self._fields(obs, rows)
        self._past[rows] = np.concatenate([f[:, None, :], self._past[rows][:, :-1]], axis=1)

    def past(self, rows=None) -> np.ndarray:
        """The remembered decisions of the envs of ``rows``, newest first, flattened: (m, :attr:`size`), float32."""
        rows = slice(None) if rows is None else rows
        p = self._past[rows]
        return p.reshape(p.shape[0], -1).copy()

    def seen(self, obs, rows=None, base=None) -> np.ndarray:
        """What the agents of ``rows`` see: ``base`` (their observation entries, default their rows of ``obs``)
        followed by their past (float32)."""
        rows = slice(None) if rows is None else rows
        base = np.asarray(obs, dtype=np.float32)[rows] if base is None else np.asarray(base, dtype=np.float32)
        return np.concatenate([base, self.past(rows)], axis=1)


def agent_space(space: spaces.Box, history: int, layout) -> spaces.Box:
    """The observation space of an agent that remembers ``history`` decisions on an env whose observation
    ``space`` (or the entries of it the agent sees) and ``layout`` are given: ``space`` itself for 0."""
    return space if not history else DecisionHistory(history, layout, 1).space(space)
