"""PositioningEnv: a biaxial machine driven to a set-point, judged by the position error (Yadav et al. (2020))."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numba import njit

from ..analysis.step_metrics import step_metrics
from ..plants import PlantModel, contract, get_plant
from ..motion.interpolator import MAX_REFERENCE_SAMPLES
from ..validation import flag, integer, positive, size
from .contouring_env import check_actions
from .layout import Field

__all__ = ["PositioningEnv", "PositioningLayout", "positioning_periods"]

#: The keys ``reset(options=...)`` understands.
RESET_OPTIONS = ("parameters",)


@dataclass(frozen=True)
class PositioningLayout:
    """The observation of :class:`PositioningEnv`: named fields, offsets, bounds.

    Parameters
    ----------
    n_pending : int
        Number of past actions in the ``pending_action`` field (those the
        plant's dead time has not fully applied yet), >= 0.
    position_bound : float
        Bound in mm of the ``setpoint`` and ``position_error`` fields.
    velocity_bound : float
        Bound in mm/s of the ``velocity`` field.
    """

    n_pending: int = 0
    position_bound: float = 200.0
    velocity_bound: float = 1.0e4
    fields: tuple[Field, ...] = field(init=False)

    def __post_init__(self):
        integer("n_pending", self.n_pending, 0)
        positive("position_bound", self.position_bound, "mm")
        positive("velocity_bound", self.velocity_bound, "mm/s")
        pb, vb = self.position_bound, self.velocity_bound
        object.__setattr__(
            self,
            "fields",
            (
                Field("setpoint", 2, "mm", pb, "the set-point r (x, y)"),
                Field("position_error", 2, "mm", pb, "r - x per axis, x as the position sensor reads it"),
                Field("velocity", 2, "mm/s", vb, "table velocity"),
                Field(
                    "pending_action",
                    2 * self.n_pending,
                    "1",
                    1.0,
                    f"the last {self.n_pending} actions (x, y), oldest first: the commands still in the "
                    f"plant's dead time",
                ),
            ),
        )

    @property
    def size(self) -> int:
        """Length of the observation vector."""
        return sum(f.size for f in self.fields)

    def slice(self, name: str) -> slice:
        """The slice of field ``name`` in the observation vector."""
        start = 0
        for f in self.fields:
            if f.name == name:
                return slice(start, start + f.size)
            start += f.size
        raise KeyError(f"no observation field {name!r}; fields are {[f.name for f in self.fields]}")

    def high(self) -> np.ndarray:
        """Upper bounds of the observation space (float32); low is -high."""
        return np.concatenate([np.full(f.size, f.bound, dtype=np.float32) for f in self.fields])

    def get(self, obs, name: str) -> np.ndarray:
        """Field ``name`` of one observation or a batch (..., size) as float64."""
        return np.asarray(obs, dtype=np.float64)[..., self.slice(name)]

    def setpoint(self, obs):
        """The set-point r in mm, (..., 2)."""
        return self.get(obs, "setpoint")

    def position_error(self, obs):
        """r - x in mm, (..., 2)."""
        return self.get(obs, "position_error")

    def velocity(self, obs):
        """Table velocity in mm/s, (..., 2)."""
        return self.get(obs, "velocity")

    def pending_action(self, obs):
        """The last ``n_pending`` actions, oldest first, (..., n_pending, 2)."""
        p = self.get(obs, "pending_action")
        return p.reshape(p.shape[:-1] + (self.n_pending, 2))

    def describe(self) -> str:
        """A Markdown table of the fields: index range, name, unit, meaning."""
        rows = ["| index | field | unit | meaning |", "|---|---|---|---|"]
        for f in self.fields:
            s = self.slice(f.name)
            rows.append(f"| {s.start}-{s.stop - 1} | {f.name} | {f.unit} | {f.description} |")
        return "\n".join(rows)


@njit(cache=True)
def positioning_periods(plant, k, command, n, setpoint, trajectory, start, sensed):
    """Advance machine ``k`` by ``n`` control periods with ``command`` (2,) held, through the plant contract.

    After each period the true position goes to ``trajectory[start + 1 + j]``
    (rows beyond the array are dropped) and the distance to ``setpoint`` (2,)
    [mm] is accumulated; ``sensed`` (SENSE_SIZE,) holds the last reading
    (with ``n = 0`` the plant is only read).  Returns the sum and the maximum
    of the distances [mm].  No validation.
    """
    err_sum = 0.0
    err_max = 0.0
    if n == 0:
        contract.sense(plant, k, sensed)
    for j in range(n):
        contract.advance(plant, k, command)
        contract.sense(plant, k, sensed)
        x = sensed[contract.SENSE_POSITION]
        y = sensed[contract.SENSE_POSITION + 1]
        err = math.hypot(setpoint[0] - x, setpoint[1] - y)
        err_sum += err
        err_max = max(err_max, err)
        row = start + 1 + j
        if row < trajectory.shape[0]:
            trajectory[row, 0] = x
            trajectory[row, 1] = y
    return err_sum, err_max


class PositioningEnv(gym.Env):
    r"""A step set-point on a biaxial machine, judged by the position error (Yadav et al. (2020)).

    ## Description

    Both axes of a machine table at rest at the origin are commanded, at
    t = 0, to a set-point ``r`` (10 mm on each axis by default): the step
    response of Yadav et al. (2020, section 4, Table 2).  The
    machine is a plant of :mod:`vcnc_gym.plants` (``plant=``), by default
    Yadav et al.'s CNCMT axis on both axes, eq. (2),
    ``G(s) = 4.85 / (s (s + 9.7)) e^{-0.1 s}`` (m/V; 4850 mm/(V s^2) here), with
    its 0.1 s dead time simulated exactly as a delay line of whole control
    periods.  The policy commands both axes' amplifiers and is judged by the
    distance from the table to the set-point.  At the end of an episode
    ``info["step_metrics"]`` holds each axis' overshoot, 2 % settling time and
    10-90 % rise time (Table 2's figures).

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: the normalised amplifier command per axis.

    ===  ==============  ===  ===  ============================================
    Num  Action          Min  Max  Unit
    ===  ==============  ===  ===  ============================================
    0    x-axis command  -1   1    x the plant's input limit (10 V, cncmt_axis)
    1    y-axis command  -1   1    x the plant's input limit (10 V, cncmt_axis)
    ===  ==============  ===  ===  ============================================

    Values outside [-1, 1] are clipped (the amplifier saturates); wrong
    shapes and non-finite values raise ``ValueError``.

    ## Observation Space

    A flat float32 ``Box`` whose fields are named by :class:`PositioningLayout`
    (``env.unwrapped.layout``; a policy reads ``layout.position_error(obs)``).
    With the default dead time (0.1 s) and control period (10 ms):

    =====  ==============  ====  =================================================
    Index  Field           Unit  Meaning
    =====  ==============  ====  =================================================
    0-1    setpoint        mm    the set-point r
    2-3    position_error  mm    r - x per axis, x as the position sensor reads it
    4-5    velocity        mm/s  table velocity
    6-25   pending_action  1     the last 10 actions (x, y), oldest first
    =====  ==============  ====  =================================================

    ``pending_action`` holds the last ``ceil(T_d / decision_period)``
    actions: the commands the dead time has not fully applied yet, which
    make the observation a Markov state of the delayed plant (no field when
    the plant has no dead time).  Positions are bounded by
    ``max |r| + divergence_bound``, velocities by 1e4 mm/s; values beyond
    are clipped (``info["observation_clipped"]`` counts them).

    ## Rewards

    ``reward = -mean distance to the set-point / reward_scale``, the distance
    ``|r - x|`` (both axes, true position) averaged over the step's control
    periods, ``reward_scale`` = 10 mm; a step starts near -1.4 and a settled
    machine earns 0.  On divergence a terminal penalty of
    ``-(divergence_bound / reward_scale)`` per remaining decision step is
    added, so ending early never pays.  The terms are in ``info``
    ("reward_error", "reward_divergence").

    ## Starting State

    The table rests at the origin, every command in the plant's dead time
    zero.  The plant parameters are the nominal ones (eq. (2)), those given
    by ``parameters``, or, with ``randomize=True``, drawn uniformly from the
    plant's uncertainty box by the env's seeded generator (for cncmt_axis
    Yadav et al.'s section 3.5 intervals, each axis independently); they are in
    the reset info.

    ## Episode End

    - Truncated after ``duration`` (15 s) of simulated time,
      ``env.unwrapped.episode_steps`` decisions: a time limit, not a terminal
      state (the observation has no clock).  ``max_episode_steps`` truncates
      earlier.
    - Terminated with ``info["diverged"] = True`` when the distance to the
      set-point exceeds ``divergence_bound`` (100 mm) or the plant state is
      not finite.  Yadav et al.'s robust PI loop does so: with the 0.1 s dead
      time it is unstable (its delay margin is 48 ms).
    - The last step's info holds ``"completed"`` (True when the whole window
      ran without divergence) and ``"step_metrics"``: per axis (``"x"``,
      ``"y"``) a dict of ``overshoot`` [%], ``settling_time`` [s] (2 % band;
      ``inf`` if not settled at the end), ``rise_time`` [s] (10-90 %) and
      ``rise_time_100`` [s] (0-100 %), from the true position at every
      control period (:func:`vcnc_gym.analysis.step_metrics`); ``None`` for
      an axis with a zero step.

    ## Arguments

    ``gym.make("VCNC-Step-v0", **kwargs)`` with

    - ``plant``: a module name of :mod:`vcnc_gym.plants` or a ``PlantModel``;
      default ``"cncmt_axis"`` (Yadav et al. (2020)).
    - ``setpoint`` ((10.0, 10.0) mm): the step per axis.
    - ``dt`` (s, 0.01): the control period, at which the command is held and
      the position recorded; the plant's dead time must be a whole number of
      it (ValueError otherwise).
    - ``action_repeat`` (1): control periods per decision.
    - ``duration`` (s, 15.0): the episode's simulated time (Yadav et al.'s
      slowest loop, IMC, settles within 14 s on the box).
    - ``randomize`` (False) / ``parameters`` (None, a (2, P) array, columns
      ``env.unwrapped.plant.parameter_names``): the plant in force; not both.
      ``reset(options={"parameters": p})`` sets it for one episode.
    - ``reward_scale`` (mm, 10.0), ``divergence_bound`` (mm, 100.0).
    - ``plant_options`` (None): the plant's own settings, e.g.
      ``{"max_dead_time": 0.2}`` (s) for a longer delay line.
    - ``max_episode_steps`` (None: the natural length): truncation, decisions.

    ``info`` of a step: ``position_error`` (2,) mm (true position),
    ``contour_error`` and ``contour_error_max`` (mm: the distance to the
    set-point at the end of the step and its maximum over the step; a
    set-point is the contour of a positioning task, so the suite's
    evaluation loop reads it unchanged), ``position`` and
    ``reference_position`` (the set-point) in mm, ``command`` (2,) in the
    plant's input unit (V) as sent (it reaches the table ``T_d`` later),
    ``time`` s, the reward terms, ``diverged``.

    ## Version History

    - v0: initial release (Yadav et al.'s step response on the CNCMT axis).
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        *,
        plant="cncmt_axis",
        setpoint=(10.0, 10.0),
        dt: float = 0.01,
        action_repeat: int = 1,
        duration: float = 15.0,
        randomize: bool = False,
        parameters=None,
        reward_scale: float = 10.0,
        divergence_bound: float = 100.0,
        plant_options: dict | None = None,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
    ):
        if render_mode is not None:
            raise ValueError(f"PositioningEnv has no render modes, got render_mode={render_mode!r}")
        self.render_mode = None
        self.plant: PlantModel = get_plant(plant)
        self.dt = positive("dt", dt, "s")
        self.action_repeat = integer("action_repeat", action_repeat, 1)
        self.duration = positive("duration", duration, "s")
        self.randomize = flag("randomize", randomize)
        self.reward_scale = positive("reward_scale", reward_scale, "mm")
        self.divergence_bound = positive("divergence_bound", divergence_bound, "mm")
        r = np.asarray(setpoint, dtype=np.float64) if not isinstance(setpoint, str) else np.array([np.nan])
        if r.shape != (2,) or not np.all(np.isfinite(r)):
            raise ValueError(f"setpoint must be two finite positions (x, y) in mm, got {setpoint!r}")
        if np.hypot(*r) >= self.divergence_bound:
            raise ValueError(f"setpoint {r.tolist()} mm lies beyond divergence_bound = {self.divergence_bound} mm")
        self.setpoint = r
        if plant_options is not None and not isinstance(plant_options, dict):
            raise ValueError(f"plant_options must be a dict of the plant's settings, got {plant_options!r}")
        if parameters is not None and self.randomize:
            raise ValueError(
                "pass either parameters= (a fixed plant) or randomize=True (a plant drawn at every reset), not both"
            )
        self.nominal_parameters = self.plant.nominal()
        self.fixed_parameters = None if parameters is None else self._check_parameters(parameters)
        self.parameters = self.nominal_parameters if self.fixed_parameters is None else self.fixed_parameters

        size(
            "duration / dt",
            math.ceil(self.duration / self.dt - 1e-9),
            ceiling=MAX_REFERENCE_SAMPLES,
            why=f"the control periods of an episode, at most MAX_REFERENCE_SAMPLES as for a contour's reference; "
            f"duration = {self.duration:g} s at dt = {self.dt:g} s",
        )
        self.episode_steps = math.ceil(self.duration / self.decision_period - 1e-9)
        """Natural episode length in decisions."""
        self.max_episode_steps = (
            self.episode_steps if max_episode_steps is None else integer("max_episode_steps", max_episode_steps, 1)
        )

        # the plant's arrays; a first reset checks the dead time against dt
        self._plant = self.plant.arrays(1, self.dt, **(plant_options or {}))
        self._set_plant(self.parameters)
        dead_time = max(self.plant.dead_time(self.parameters, axis) for axis in (0, 1))
        n_pending = size(
            "dead time / (dt * action_repeat)",
            math.ceil(dead_time / self.decision_period - 1e-9),
            minimum=0,
            ceiling=MAX_REFERENCE_SAMPLES,
            why=f"decisions held in flight by the {dead_time:g} s dead time, at most MAX_REFERENCE_SAMPLES",
        )
        self.layout = PositioningLayout(
            n_pending=n_pending, position_bound=float(np.max(np.abs(r))) + self.divergence_bound
        )
        high = self.layout.high()
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._pending = np.zeros((n_pending, 2))
        self._sensed = np.zeros(contract.SENSE_SIZE)
        self._trajectory = np.zeros((self.episode_steps * self.action_repeat + 1, 2))
        self._k = 0
        self._steps = 0
        self._done = True

    # -- configuration -----------------------------------------------------------------
    @property
    def decision_period(self) -> float:
        """Time between two decisions in s: ``dt * action_repeat``."""
        return self.dt * self.action_repeat

    @property
    def u_max(self) -> float:
        """The x axis' input limit that action 1.0 maps to, in ``plant.input_unit``."""
        return float(self.plant.input_limits(self.parameters)[0])

    def _check_parameters(self, parameters) -> np.ndarray:
        p = self.plant.validate(parameters)
        if p.shape[0] != 1:
            raise ValueError(f"parameters must be one machine's (2, {self.plant.n_parameters}) array, got {p.shape}")
        return p[0].copy()

    def _set_plant(self, parameters: np.ndarray) -> None:
        self._plant.params[0] = parameters
        self.plant.reset_machine(self._plant, 0, np.zeros(2))

    # -- Gymnasium API -------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Put the table at rest at the origin; ``options={"parameters": array}`` sets the plant for this episode."""
        super().reset(seed=seed)
        parameters = None
        if options is not None:
            if not isinstance(options, dict):
                raise ValueError(f"reset options must be a dict, got {type(options).__name__}")
            unknown = sorted(set(options) - set(RESET_OPTIONS))
            if unknown:
                raise ValueError(f"unknown reset option(s) {unknown}; known: {list(RESET_OPTIONS)}")
            if "parameters" in options:
                parameters = self._check_parameters(options["parameters"])
        if parameters is None:
            if self.randomize:
                parameters = self.plant.sample(self.np_random)
            else:
                parameters = self.nominal_parameters if self.fixed_parameters is None else self.fixed_parameters
        self._set_plant(parameters)
        self.parameters = parameters
        self._input_limit = self.plant.input_limits(parameters)
        self._pending[...] = 0.0
        self._trajectory[...] = 0.0
        self._k = 0
        self._steps = 0
        self._done = False
        positioning_periods(self._plant, 0, np.zeros(2), 0, self.setpoint, self._trajectory, 0, self._sensed)
        self._trajectory[0] = self._sensed[contract.SENSE_POSITION : contract.SENSE_POSITION + 2]
        info = {
            "parameters": self.plant.to_dict(parameters),
            "setpoint": self.setpoint.copy(),
            "dt": self.dt,
            "decision_period": self.decision_period,
            "episode_steps": self.episode_steps,
        }
        obs, _ = self._observation()
        return obs, info

    def step(self, action):
        """One decision: ``action`` (2,), the normalised amplifier commands, held for the decision period; returns
        ``(observation, reward, terminated, truncated, info)`` as Gymnasium's ``step``."""
        if self._done:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        a = np.clip(check_actions(action, (2,)), -1.0, 1.0)
        command = a * self._input_limit
        n = self.action_repeat
        err_sum, err_max = positioning_periods(
            self._plant, 0, command, n, self.setpoint, self._trajectory, self._k, self._sensed
        )
        self._k += n
        self._steps += 1
        if self._pending.shape[0]:
            self._pending[:-1] = self._pending[1:]
            self._pending[-1] = a

        position = self._sensed[contract.SENSE_POSITION : contract.SENSE_POSITION + 2].copy()
        error = self.setpoint - position
        distance = float(np.hypot(*error))
        finite = bool(np.all(np.isfinite(self._sensed[: contract.SENSE_SIZE])))
        diverged = not finite or not err_max <= self.divergence_bound
        r_error = (
            -min(err_sum / n, self.divergence_bound) / self.reward_scale
            if finite
            else -self.divergence_bound / self.reward_scale
        )
        r_div = 0.0
        if diverged:
            r_div = -max(0, self.episode_steps - self._steps) * self.divergence_bound / self.reward_scale
        terminated = diverged
        truncated = not terminated and (self._steps >= self.episode_steps or self._steps >= self.max_episode_steps)
        self._done = terminated or truncated

        obs, clipped = self._observation()
        info = {
            "position_error": error,
            "contour_error": distance if finite else math.inf,
            "contour_error_max": err_max if finite else math.inf,
            "position": position,
            "reference_position": self.setpoint.copy(),
            "command": np.clip(command, -self._input_limit, self._input_limit),
            "time": self._k * self.dt,
            "reward_error": r_error,
            "reward_divergence": r_div,
            "diverged": diverged,
            "observation_clipped": clipped,
        }
        if self._done:
            info["step_metrics"] = self.step_metrics()
            # the task is the whole step-response window: done when it ran to its end without diverging
            info["completed"] = bool(not diverged and self._steps >= self.episode_steps)
        return obs, r_error + r_div, terminated, truncated, info

    def _observation(self) -> tuple[np.ndarray, int]:
        s = self._sensed
        parts = [
            self.setpoint,
            self.setpoint - s[contract.SENSE_MEASURED : contract.SENSE_MEASURED + 2],
            s[contract.SENSE_VELOCITY : contract.SENSE_VELOCITY + 2],
            self._pending.reshape(-1),
        ]
        raw = np.concatenate(parts)
        high = self.observation_space.high  # pyright: ignore[reportAttributeAccessIssue]  (a Box)
        bad = ~np.isfinite(raw)
        raw[bad] = 0.0
        clipped = int(np.count_nonzero(bad)) + int(np.count_nonzero(np.abs(raw) > high))
        return np.clip(raw, -high, high).astype(np.float32), clipped

    # -- results ----------------------------------------------------------------------------
    @property
    def trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """Time [s] (K,) and true table position [mm] (K, 2) at every control period of the episode so far."""
        k = min(self._k, self._trajectory.shape[0] - 1)
        return np.arange(k + 1) * self.dt, self._trajectory[: k + 1].copy()

    def step_metrics(self) -> dict:
        """Overshoot [%], 2 % settling time [s], 10-90 % and 0-100 % rise times [s] per axis, so far.

        Returns
        -------
        dict
            ``{"x": {...}, "y": {...}}`` (:meth:`StepMetrics.as_dict`), ``None``
            for an axis whose step is zero.
        """
        t, x = self.trajectory
        out = {}
        for i, axis in enumerate(contract.AXES):
            if self.setpoint[i] == 0.0 or t.size < 2:
                out[axis] = None
            else:
                out[axis] = step_metrics(t, x[:, i], float(self.setpoint[i]), initial=0.0).as_dict()
        return out
