"""ContouringEnv: a biaxial feed drive following a contour, judged by contour error."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ..contour import ContourProjector
from ..geometry import SHAPES, NurbsCurve
from ..geometry.nurbs import workspace_size
from ..motion import SCurveFeedrate, interpolate
from ..plants import vcnc_feed_drive as plant
from . import step_kernel as sk
from .layout import ObservationLayout

__all__ = ["ContouringEnv"]


class ContouringEnv(gym.Env):
    r"""Contour following with seed 000's virtual CNC (VCNC) feed drives.

    ## Description

    A biaxial (X-Y) machine table follows a contour, here a NURBS curve of
    seed 000 (the "heart" or the "omega", section 3a), at the S-curve feedrate
    of seed 000 (100 mm/s, 0.12 s ramps) laid out by the second-order Taylor
    interpolator, eqs. (8)-(10).  Each axis is the feed drive of seed 000,
    eq. (1), with the parameters of section 2c and Table 3: +-5 V amplifier
    saturation, 3 um backlash, asymmetric static and Coulomb friction
    (Karnopp stick-slip), integrated in closed form on substeps.  The policy
    commands the two amplifier voltages and is judged by the contour error:
    the shortest distance from the table to the whole contour, not to the
    current reference point.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: the normalised amplifier command per axis.

    | Num | Action            | Min | Max | Unit               |
    |-----|-------------------|-----|-----|--------------------|
    | 0   | x-axis command    | -1  | 1   | x 5 V (u_max)      |
    | 1   | y-axis command    | -1  | 1   | x 5 V (u_max)      |

    Values outside [-1, 1] are clipped: that is the amplifier's saturation.
    Wrong shapes and non-finite values raise ``ValueError``.

    ## Observation Space

    A flat float32 ``Box``; its fields are named by
    :class:`~vcnc_gym.envs.layout.ObservationLayout` (``env.unwrapped.layout``),
    so a policy reads ``layout.tracking_error(obs)`` instead of indices.  With
    the default three preview points:

    | Index | Field                  | Unit   | Meaning                                        |
    |-------|------------------------|--------|------------------------------------------------|
    | 0-1   | reference_position     | mm     | reference point x_d                            |
    | 2-3   | reference_velocity     | mm/s   | dx_d/dt                                        |
    | 4-5   | reference_acceleration | mm/s^2 | d2x_d/dt2                                      |
    | 6-7   | tracking_error         | mm     | x_d - x (seed 002 eq. (2))                     |
    | 8     | contour_error          | mm     | distance from the table to the whole contour   |
    | 9     | tangential_error       | mm     | tracking error along the path tangent (eq. (3))|
    | 10    | normal_error           | mm     | tracking error along the path normal (eq. (3)) |
    | 11-12 | velocity               | mm/s   | table velocity                                 |
    | 13-18 | preview                | mm     | x_d 1, 5, 10 ms ahead minus the table position |
    | 19-20 | previous_action        | 1      | the last action                                |

    Values beyond the layout's bounds are clipped, so every observation lies
    inside the space.

    ## Rewards

    ``reward = -contour_error / reward_scale - effort_weight * mean(action**2)``,
    with the contour error averaged over the step's control periods and
    ``reward_scale`` = 0.01 mm (10 um), so typical values are of order one.
    The effort term is off by default.  On divergence a terminal penalty of
    ``-(divergence_bound / reward_scale)`` per remaining decision step of the
    contour is added, so ending an episode early never pays.  Every term is in
    ``info`` ("reward_contour", "reward_effort", "reward_divergence").

    ## Starting State

    The table rests at the start of the contour with the backlash gap
    centred; the plant parameters are the nominal ones (interval midpoints),
    those given by ``parameters``, or, with ``randomize=True``, drawn
    uniformly from seed 000's intervals by the env's seeded generator.  The
    parameters in force are in the reset info.

    ## Episode End

    - Terminated once the reference has reached the end of the contour and
      ``settling_time`` has passed.
    - Terminated early with ``info["diverged"] = True`` when the contour
      error exceeds ``divergence_bound`` (default 5 mm), the tracking error
      exceeds ``tracking_bound`` (default 10 mm: the table has fallen that
      far behind or ahead of the reference), or the plant state stops being
      finite.  Without the tracking bound a table that never moves would
      score a perfect contour error, its start point lying on the contour.  The bound is that wide because the omega's
      corners (radius 0.19 mm) ask 100 mm/s for 5.4e4 mm/s^2, twenty times what
      the +-5 V drives can give (~2.6e3 mm/s^2): a stable tracking controller
      is thrown millimetres off the contour there without diverging.
    - Truncated by the ``TimeLimit`` of the registered id, set just above
      the natural length for the default arguments.  If you change ``dt``,
      ``feedrate``, ``ramp_time`` or ``action_repeat``, pass
      ``max_episode_steps=env.unwrapped.episode_steps`` (or larger) to
      ``gym.make`` as well; the env warns if the limit is too short.

    ## Arguments

    ``gym.make("VCNC-Heart-v0", **kwargs)`` with

    - ``contour``: "heart", "omega" or a :class:`NurbsCurve` (mm).
    - ``feedrate`` (mm/s, 100) and ``ramp_time`` (s, 0.12): the S-curve.
    - ``dt`` (s, 1e-4): the control period, at which the command is held
      and the reference is sampled.  At 1 ms seed 000's QFT loop is unstable
      (a closed-loop pole near |z| = 10); at 0.1 ms it is stable on every
      vertex of the uncertainty box.
    - ``action_repeat`` (1): control periods per decision.
    - ``randomize`` (False) / ``parameters`` (None, a (2, P) array of
      :mod:`vcnc_gym.plants.vcnc_feed_drive`): the plant in force.
    - ``substep`` (s, 1e-5): the plant's integration substep.
    - ``reward_scale`` (mm, 0.01), ``effort_weight`` (0.0),
      ``divergence_bound`` (mm, 5.0), ``tracking_bound`` (mm, 10.0),
      ``settling_time`` (s, 0.01).
    - ``preview_steps`` ((10, 50, 100)): preview offsets in control periods.
    - ``render_mode``: None, "human" or "rgb_array" (matplotlib).

    ## Version History

    - v0: initial release.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 4}

    def __init__(
        self,
        contour: str | NurbsCurve = "heart",
        feedrate: float = 100.0,
        ramp_time: float = 0.12,
        dt: float = 1e-4,
        action_repeat: int = 1,
        randomize: bool = False,
        parameters: np.ndarray | None = None,
        substep: float = plant.DEFAULT_SUBSTEP,
        reward_scale: float = 0.01,
        effort_weight: float = 0.0,
        divergence_bound: float = 5.0,
        tracking_bound: float = 10.0,
        settling_time: float = 0.01,
        preview_steps: tuple[int, ...] = (10, 50, 100),
        render_mode: str | None = None,
    ):
        self.curve = self._make_curve(contour)
        self.contour_name = contour if isinstance(contour, str) else "custom"
        dt = _positive("dt", dt)
        substep = _positive("substep", substep)
        self.reward_scale = _positive("reward_scale", reward_scale)
        self.divergence_bound = _positive("divergence_bound", divergence_bound)
        self.tracking_bound = _positive("tracking_bound", tracking_bound)
        self.settling_time = _non_negative("settling_time", settling_time)
        self.effort_weight = _non_negative("effort_weight", effort_weight)
        if isinstance(action_repeat, bool) or int(action_repeat) != action_repeat or action_repeat < 1:
            raise ValueError(f"action_repeat must be an integer >= 1, got {action_repeat!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.dt = dt
        self.action_repeat = int(action_repeat)
        self.n_substeps = max(1, math.ceil(dt / substep - 1e-9))
        self.randomize = bool(randomize)
        self.render_mode = render_mode

        # reference, computed once: it depends only on the curve, feedrate and dt
        self.feedrate_profile = SCurveFeedrate(feedrate=feedrate, ramp_time=ramp_time)
        self.reference = interpolate(self.curve, self.feedrate_profile, dt)
        tangent = self.curve.derivatives_array(self.reference.u, 1)[:, 1, :]
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        self._reference = np.ascontiguousarray(np.hstack([
            self.reference.position, self.reference.velocity, self.reference.acceleration, tangent,
        ]))
        self.projector = ContourProjector(self.curve, margin=max(10.0, 2 * self.divergence_bound))
        settle_periods = math.ceil(self.settling_time / dt)
        self._end_index = len(self.reference.t) - 1 + settle_periods
        self.episode_steps = math.ceil(self._end_index / self.action_repeat)
        """Natural episode length in decision steps (without divergence)."""

        # plant
        self.nominal_parameters = plant.nominal_parameters()
        self._fixed_parameters = None if parameters is None else self._check_parameters(parameters)
        self.parameters = self.nominal_parameters if parameters is None else self._fixed_parameters
        self._params = np.empty((1, 2, plant.N_PARAMETERS))
        self._state = np.zeros((1, 2, 3))

        # spaces
        self.layout = ObservationLayout(preview_steps=tuple(int(s) for s in preview_steps))
        if any(s < 1 for s in self.layout.preview_steps):
            raise ValueError(f"preview_steps must be positive integers, got {preview_steps!r}")
        self._obs_high = self.layout.high()
        self.observation_space = spaces.Box(-self._obs_high, self._obs_high, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._obs_offsets = np.array([self.layout.offset(f.name) for f in self.layout.fields], dtype=np.int64)
        self._preview = np.array(self.layout.preview_steps, dtype=np.int64)

        # scratch for the kernel
        self._der = np.empty((3, 2))
        self._work = np.empty(workspace_size(self.curve.degree, 2))
        self._voltage = np.zeros((1, 2))
        self._previous_action = np.zeros(2)
        self._obs_size = self.layout.size
        self._kernel_args = (
            self._voltage, self._state, self._params, self.dt, self.n_substeps,
            self._reference, self._preview, self._obs_offsets, self._obs_high, self._previous_action,
            *self.curve.kernel_args, *self.projector.arrays, self._der, self._work,
        )
        self._u_max = (1.0, 1.0)
        self._k = 0
        self._done = True
        self._warned_limit = False
        self._history: dict[str, list] | None = None
        self._figure = None

    # -- configuration helpers ----------------------------------------------
    @staticmethod
    def _make_curve(contour) -> NurbsCurve:
        if isinstance(contour, NurbsCurve):
            return contour
        if isinstance(contour, str) and contour in SHAPES:
            return SHAPES[contour]()
        raise ValueError(f"contour must be one of {sorted(SHAPES)} or a NurbsCurve, got {contour!r}")

    @staticmethod
    def _check_parameters(parameters) -> np.ndarray:
        return plant.validate_parameters(parameters, n_machines=None).reshape(2, plant.N_PARAMETERS).copy()

    @property
    def decision_period(self) -> float:
        """Time between two decisions in s: ``dt * action_repeat``."""
        return self.dt * self.action_repeat

    @property
    def u_max(self) -> float:
        """Amplifier saturation in V that action 1.0 maps to (seed 000, Table 3)."""
        return float(self.parameters[0, plant.IDX_U_MAX])

    # -- Gymnasium API ----------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start a pass along the contour; ``options={"parameters": array}`` sets the plant."""
        super().reset(seed=seed)
        if options and "parameters" in options:
            self.parameters = self._check_parameters(options["parameters"])
        elif self.randomize:
            self.parameters = plant.sample_parameters(self.np_random)
        elif self._fixed_parameters is not None:
            self.parameters = self._fixed_parameters
        else:
            self.parameters = self.nominal_parameters
        self._params[0] = self.parameters
        self._u_max = (float(self.parameters[0, plant.IDX_U_MAX]), float(self.parameters[1, plant.IDX_U_MAX]))
        plant.reset_feed_drives(self._state, self._reference[:1, sk.REF_POSITION:sk.REF_POSITION + 2])
        self._k = 0
        self._done = False
        self._previous_action[:] = 0.0
        self._voltage[:] = 0.0
        self._check_time_limit()

        obs = np.zeros(self.layout.size, dtype=np.float32)
        result = np.empty(sk.OUT_SIZE)
        sk.contouring_step(0, 0, *self._kernel_args, obs, result)
        info = {
            "parameters": plant.parameters_to_dict(self.parameters),
            "dt": self.dt,
            "decision_period": self.decision_period,
            "episode_steps": self.episode_steps,
            "contour_length": self.reference.length,
            "feedrate_fluctuation": self.reference.feedrate_fluctuation,
        }
        if self.render_mode is not None:
            self._history = {"t": [0.0], "position": [result[sk.OUT_POSITION:sk.OUT_POSITION + 2].copy()],
                             "contour_error": [0.0]}
        return obs, info

    def step(self, action):
        if self._done:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        if not isinstance(action, np.ndarray):
            action = np.asarray(action, dtype=np.float64)
        if action.shape != (2,):
            raise ValueError(f"action must have shape (2,), got {action.shape}")
        a0 = float(action[0])
        a1 = float(action[1])
        if not (math.isfinite(a0) and math.isfinite(a1)):
            raise ValueError(f"action must be finite, got {action!r}")
        a0 = min(1.0, max(-1.0, a0))
        a1 = min(1.0, max(-1.0, a1))
        self._voltage[0, 0] = a0 * self._u_max[0]
        self._voltage[0, 1] = a1 * self._u_max[1]
        self._previous_action[0] = a0
        self._previous_action[1] = a1

        obs = np.empty(self._obs_size, dtype=np.float32)
        result = np.empty(sk.OUT_SIZE)
        k = sk.contouring_step(self._k, self.action_repeat, *self._kernel_args, obs, result)
        self._k = k
        err = result[sk.OUT_CONTOUR_ERROR]
        lag = math.hypot(result[sk.OUT_TRACKING_ERROR], result[sk.OUT_TRACKING_ERROR + 1])
        diverged = (
            result[sk.OUT_FINITE] == 0.0
            or result[sk.OUT_CONTOUR_ERROR_MAX] > self.divergence_bound
            or lag > self.tracking_bound
        )
        r_contour = -min(result[sk.OUT_CONTOUR_ERROR_MEAN], self.divergence_bound) / self.reward_scale
        r_effort = -self.effort_weight * 0.5 * (a0 * a0 + a1 * a1)
        r_div = 0.0
        if diverged:
            remaining = max(0, self.episode_steps - math.ceil(k / self.action_repeat))
            r_div = -remaining * self.divergence_bound / self.reward_scale
            err = err if math.isfinite(err) else math.inf
        terminated = diverged or k >= self._end_index
        self._done = terminated
        info = {
            "contour_error": err,
            "contour_error_max": result[sk.OUT_CONTOUR_ERROR_MAX],
            "tracking_error": result[sk.OUT_TRACKING_ERROR:sk.OUT_TRACKING_ERROR + 2],
            "position": result[sk.OUT_POSITION:sk.OUT_POSITION + 2],
            "reference_position": result[sk.OUT_REFERENCE_POSITION:sk.OUT_REFERENCE_POSITION + 2],
            "command": result[sk.OUT_COMMAND:sk.OUT_COMMAND + 2],
            "time": k * self.dt,
            "reward_contour": r_contour,
            "reward_effort": r_effort,
            "reward_divergence": r_div,
            "diverged": diverged,
        }
        if self._history is not None:
            self._history["t"].append(k * self.dt)
            self._history["position"].append(info["position"].copy())
            self._history["contour_error"].append(err)
            frame = round(1.0 / (self.metadata["render_fps"] * self.decision_period))
            if self.render_mode == "human" and (terminated or len(self._history["t"]) % frame == 0):
                self.render()
        return obs, r_contour + r_effort + r_div, terminated, False, info

    def _check_time_limit(self):
        limit = getattr(self.spec, "max_episode_steps", None) if self.spec is not None else None
        if limit is not None and limit < self.episode_steps and not self._warned_limit:
            self._warned_limit = True
            gym.logger.warn(
                f"max_episode_steps={limit} is shorter than this configuration's episode "
                f"({self.episode_steps} steps): pass max_episode_steps={self.episode_steps} to gym.make"
            )

    # -- rendering ------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        from .rendering import render_contouring

        return render_contouring(self)

    def close(self):
        if self._figure is not None:
            import matplotlib.pyplot as plt

            plt.close(self._figure)
            self._figure = None


def _positive(name: str, value) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return v


def _non_negative(name: str, value) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0.0:
        raise ValueError(f"{name} must be non-negative and finite, got {value!r}")
    return v
