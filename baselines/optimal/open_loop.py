"""A recorded input sequence as a compiled controller: the command of step ``k`` is row ``k`` of a table.

The floor (:mod:`vcnc_baselines.optimal.oracle`) starts from the best causal controller's run on the exact plant.
Where that controller has no compiled form, or learns across episodes (ILC: its k-th trial is not the
policy's first), its applied commands are recorded and replayed as this controller, which the floor's
search then corrects like any other (:mod:`vcnc_baselines.optimal.rollout`).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit
from numba.extending import overload

from vcnc_gym.envs import controller_contract

__all__ = ["OpenLoopArrays", "open_loop", "OpenLoopPolicy"]

#: ``memory`` (N, 1) float64: decision steps since the episode's start; ``table`` (L, 2): the normalised command
#: per step, the last row held.
OpenLoopArrays = namedtuple("OpenLoopArrays", ["memory", "table"])


def open_loop(table: np.ndarray, n_envs: int) -> OpenLoopArrays:
    """The compiled form of ``table`` (L, 2) for ``n_envs`` envs, at step 0."""
    return OpenLoopArrays(np.zeros((n_envs, 1)), np.ascontiguousarray(table, dtype=np.float64))


@njit(cache=True)
def _open_loop_command(controller, i, out):
    k = int(controller.memory[i, 0])
    row = min(k, controller.table.shape[0] - 1)
    out[0] = controller.table[row, 0]
    out[1] = controller.table[row, 1]
    controller.memory[i, 0] = k + 1


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, OpenLoopArrays):
        return lambda controller, i, obs, o, out: _open_loop_command(controller, i, out)


class OpenLoopPolicy:
    """``table`` (L, 2) replayed: SB3's ``predict`` returning row k (float32 as recorded) at the k-th call since
    each env's ``episode_start``; ``reset(n_envs=..., mask=...)`` and :meth:`compiled` as a baseline's."""

    def __init__(self, table: np.ndarray):
        self.table = np.asarray(table)
        self._state = np.zeros((1, 1))

    def reset(self, n_envs: int | None = None, mask=None) -> None:
        if n_envs is not None and n_envs != self._state.shape[0]:
            self._state = np.zeros((n_envs, 1))
        elif mask is None:
            self._state[:] = 0.0
        else:
            self._state[np.asarray(mask, dtype=bool)] = 0.0

    def compiled(self, n_envs: int) -> OpenLoopArrays:
        self.reset(n_envs=n_envs)
        self._state[:] = 0.0
        return OpenLoopArrays(self._state, np.ascontiguousarray(self.table, dtype=np.float64))

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation)
        n = 1 if obs.ndim == 1 else obs.shape[0]
        if self._state.shape[0] != n:
            self.reset(n_envs=n)
        elif episode_start is not None:
            self.reset(mask=np.broadcast_to(np.asarray(episode_start, dtype=bool).reshape(-1), (n,)))
        k = np.minimum(self._state[:, 0].astype(np.int64), len(self.table) - 1)
        self._state[:, 0] += 1
        action = self.table[k]
        return (action[0] if obs.ndim == 1 else action), state
