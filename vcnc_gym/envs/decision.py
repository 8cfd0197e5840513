"""A decision of the learnable action types: a compiled controller runs every control period inside the step.

With ``action="setpoint"`` the controller is the drive's own servo (:mod:`~vcnc_gym.envs.drive_servo`) and the
agent's action moves its set-point; with ``action="correction"`` it is a classical controller (``base=``), found
through the entry point group :data:`ENTRY_POINT_GROUP` (``vcnc_baselines`` fills it: ``vcnc_gym`` names no
controller), and the agent's action is added to its command.  Either way one decision is ``action_repeat`` control
periods in one kernel call (:func:`~vcnc_gym.envs.step_kernel.step_controlled_serial`), and its reward is the mean
of the periods' rewards.  :class:`DecisionLoop` holds the controller and the loop's arrays of a batch of envs; the
single and the vector env share it.
"""

from __future__ import annotations

from importlib import metadata

import numpy as np

from . import step_kernel as sk
from .drive_servo import servo_arrays

__all__ = ["DecisionLoop", "ENTRY_POINT_GROUP", "make_base", "episode_summary", "SUMMARY_KEYS"]

#: The entry point group of the packages that make a classical controller's compiled form for ``base=``: each entry
#: is a callable ``(name, task, n_envs) -> (policy, compiled)`` (``vcnc_baselines.registry.base_controller``).
ENTRY_POINT_GROUP = "vcnc_gym.base_controllers"

#: The episode summary's keys (``info["episode_summary"]`` at the end of every episode), with their units.
SUMMARY_KEYS = {
    "contour_error_max": "mm",
    "contour_error_mean": "mm",
    "contour_error_rms": "mm",
    "cycle_time": "s (NaN unless completed)",
    "completed": "bool",
    "diverged": "bool",
    "control_periods": "1",
}


def make_base(name: str, task, n_envs: int):
    """The classical controller ``name`` for ``task``, running every control period: (the policy, its compiled
    form for ``n_envs`` envs), from the first package of :data:`ENTRY_POINT_GROUP`."""
    entries = sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name)
    if not entries:
        raise ValueError(
            f"base={name!r} needs the classical controllers: pip install 'vcnc-gym[baselines]' (no package "
            f"provides the entry point group {ENTRY_POINT_GROUP!r})"
        )
    return entries[0].load()(name, task, n_envs)


class DecisionLoop:
    """The controller and the :data:`~vcnc_gym.envs.step_kernel.ControlLoop` of ``n_envs`` envs of ``task``."""

    def __init__(self, task, n_envs: int):
        self.task = task
        self.repeat = task.action_repeat
        u_max = task.plant.input_limits(task.nominal_parameters)
        if task.action == "setpoint":
            self.policy = None
            self.controller = servo_arrays(task.servo_gains, n_envs, u_max, task.dt)
            correction = 0.0  # the agent moves the servo's set-point, not its command
        else:
            self.policy, self.controller = make_base(task.base, task, n_envs)
            correction = task.correction
        self.loop = sk.ControlLoop(
            np.zeros((n_envs, 2), dtype=np.float32),
            np.float32(correction),
            self.repeat,
            np.zeros((n_envs, 2)),
            np.zeros(n_envs),
            np.zeros(n_envs),
        )
        self.last_action = np.zeros((n_envs, 2), dtype=np.float32)

    def reset_env(self, i: int, parameters: np.ndarray) -> None:
        """Env ``i`` starts an episode on a plant with ``parameters``: the controller's memory cleared."""
        if self.policy is None:
            c = self.controller
            c.memory[i] = 0.0
            c.setpoint[i] = 0.0
            c.u_max[i] = self.task.plant.input_limits(parameters)
        else:
            mask = np.zeros(self.loop.agent.shape[0], dtype=bool)
            mask[i] = True
            self.policy.reset(mask=mask)
        self.last_action[i] = 0.0

    def set_actions(self, actions: np.ndarray, envs=Ellipsis) -> None:
        """The agents' actions (N, 2), checked finite, clipped to [-1, 1] and held for the decision, for the envs
        ``envs`` selects (a mask; default all: an env just reset ignores its action, as Gymnasium's autoreset
        does)."""
        a = np.clip(actions[envs], -1.0, 1.0).astype(np.float32)
        self.last_action[envs] = a
        if self.policy is None:
            self.controller.setpoint[envs] = a * self.task.setpoint_range
        else:
            self.loop.agent[envs] = a

    def arrays(self) -> dict[str, np.ndarray]:
        """The loop's episode state by name, the arrays a pickle of the env saves: the controller's memory (and
        the servo's set-points and input limits), the held corrections, the agent's last actions."""
        c = self.controller
        out = {"decision.memory": c[0], "decision.agent": self.loop.agent, "decision.last_action": self.last_action}
        if self.policy is None:
            out.update({"decision.setpoint": c.setpoint, "decision.u_max": c.u_max})
        return out

    def rewards(self) -> np.ndarray:
        """The decision's reward per env: the mean of its control periods' rewards."""
        return self.loop.reward / self.repeat


def episode_summary(buffers, i: int) -> dict:
    """Env ``i``'s episode so far (:data:`SUMMARY_KEYS`): its contour error over every control period stepped, the
    cycle time, and whether it completed or diverged."""
    ep = buffers.episode[i]
    periods = int(ep[sk.EPISODE_PERIODS])
    n = max(periods, 1)
    return {
        "contour_error_max": float(ep[sk.EPISODE_MAX]),
        "contour_error_mean": float(ep[sk.EPISODE_SUM] / n),
        "contour_error_rms": float(np.sqrt(ep[sk.EPISODE_SQUARES] / n)),
        "cycle_time": float(buffers.cycle_time[i]),
        "completed": bool(buffers.flags[i, sk.FLAG_COMPLETED]),
        "diverged": bool(buffers.flags[i, sk.FLAG_DIVERGED]),
        "control_periods": periods,
    }
