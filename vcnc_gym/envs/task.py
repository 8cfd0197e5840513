"""A contouring task and N machines running it: what the single and the vector env share.

:class:`ContouringTask` is one validated configuration: the contour, its
reference (computed once: it depends only on the curve, the feedrate and
``dt``), the projector's grid, the observation layout, the plant model and
the reward and episode settings.  :class:`ContouringBatch` holds the arrays
of N envs running that task and makes the one kernel call per step.
:class:`~vcnc_gym.envs.ContouringEnv` is a batch of one;
:class:`~vcnc_gym.envs.ContouringVectorEnv` a batch of N.
"""

from __future__ import annotations

import math

import numpy as np

from ..contour import ContourProjector
from ..geometry import SHAPES, NurbsCurve
from ..geometry.corners import SmoothedPolyline
from ..gcode.toolpath import Toolpath
from ..motion import ConstantFeedrate, JlapPathFeedrate, LookaheadFeedrate, SCurveFeedrate, interpolate
from ..plants import PlantModel, contract, get_plant
from . import step_kernel as sk
from ..validation import flag, integer, non_negative, positive, size
from .layout import ObservationLayout

__all__ = [
    "ContouringTask",
    "ContouringBatch",
    "RESET_OPTIONS",
    "PROFILES",
    "EPISODE_ENDS",
    "make_contour",
    "make_profile",
    "pack_reference",
]

#: The feedrate profiles of ``profile=``: Jahanpour et al.'s (2014) S-curve
#: (``feedrate``, ``ramp_time``), a constant feed from t = 0 (Simba et al.'s
#: linear case, Purtojo et al.'s circle), Simba et al.'s jerk-limited profile
#: along a corner-smoothed path, and a CNC look-ahead feed that keeps the path's
#: normal acceleration and jerk within limits
#: (:class:`~vcnc_gym.motion.LookaheadFeedrate`, its defaults: Jahanpour et
#: al.'s drives).
PROFILES = ("scurve", "constant", "jlap", "lookahead")

#: S-curve ramp time when ``ramp_time`` is not given, s (Jahanpour et al. (2014), section 3).
DEFAULT_RAMP_TIME = 0.12

#: How an episode ends (``episode_end=``): "tool" once the tool has reached the
#: end of the contour, or at the completion time limit (the v1 ids);
#: "reference" once the reference has reached it plus ``settling_time`` (v0).
EPISODE_ENDS = {"reference": sk.END_REFERENCE, "tool": sk.END_TOOL}

#: Defaults of the episode end (ours, measured in experiments/episode-ends/README.md): the settling time after the reference's end of v0, s; the
#: completion tolerance, mm of contour still ahead of the tool's closest point
#: when it counts as arrived, an in-position band: Jahanpour et al.'s QFT loop
#: comes to rest 11 um short of the heart's end (friction and the 3 um
#: backlash), the other baselines of Jahanpour et al. and Simba et al. within
#: 2.5 um; the completion time
#: limit after the reference's end, s (QFT arrives 38 ms after it).
DEFAULT_SETTLING_TIME = 0.01
DEFAULT_COMPLETION_TOLERANCE = 0.02
DEFAULT_COMPLETION_TIMEOUT = 0.1

#: Arc lengths ahead of the tool's closest point at which the observation shows
#: the contour, mm: out to 4 mm, twice the ~1.9 mm that Jahanpour et al.'s drives need
#: to brake from 100 mm/s (+-5 V, ~2.6e3 mm/s^2).
DEFAULT_CONTOUR_AHEAD = (0.25, 0.5, 1.0, 2.0, 4.0)

#: Memory of one env beyond its rows of the batch arrays, bytes: its numpy
#: Generator in the vector env (860 B measured with tracemalloc, numpy 2).
ENV_OVERHEAD_BYTES = 1024

#: What the action commands (``action=``): "voltage", the amplifier's input u / u_max of both axes (the papers'
#: setting, the v0 and v1 ids); "setpoint", a correction of up to ``setpoint_range`` mm per axis to the set-point
#: of the drive's own servo (:mod:`~vcnc_gym.envs.drive_servo`), closed inside the step every control period (the
#: v2 ids); "correction", a correction of up to ``correction`` x u_max added to a classical controller's command
#: (``base=``), which runs every control period inside the step.
ACTIONS = ("voltage", "setpoint", "correction")

#: How the observation is scaled (``observation_scale=``): "raw", the fields in their physical units; "unit", each
#: divided by a fixed constant of the task (``layout.fields[k].scale``) to order one.
OBSERVATION_SCALES = ("raw", "unit")

#: The keys ``reset(options=...)`` understands.
RESET_OPTIONS = ("parameters",)

#: The control periods an env accepts, s: dt is in seconds, so 1e-4 is 0.1 ms; a
#: value beyond either end is a unit slip (0.1 "ms" given as 0.1 s).
DT_RANGE = (1e-6, 1e-2)

#: Largest margin in mm of the projector's grid around the contour: a tool
#: farther out is searched from the nearest cell (exact, only slower), so a
#: large ``divergence_bound`` costs no memory.
_GRID_MARGIN_MAX = 50.0

#: Smallest bound in mm of the observation's position fields; a contour reaching
#: farther gets its extent plus the tracking bound plus this margin.
_POSITION_BOUND = 1000.0
_POSITION_MARGIN = 100.0


def make_contour(contour) -> tuple[NurbsCurve, SmoothedPolyline | Toolpath | None]:
    """The contour given by name (``geometry.SHAPES``), as a NurbsCurve, as a SmoothedPolyline or as a
    G-code program's :class:`~vcnc_gym.gcode.Toolpath`: (the curve, the smoothed path or toolpath, or None)."""
    if isinstance(contour, str) and contour in SHAPES:
        contour = SHAPES[contour]()
    if isinstance(contour, Toolpath):
        return contour.curve, contour
    if isinstance(contour, SmoothedPolyline):
        return contour.curve, contour
    if isinstance(contour, NurbsCurve):
        return contour, None
    raise ValueError(f"contour must be one of {sorted(SHAPES)}, a NurbsCurve or a SmoothedPolyline, got {contour!r}")


def make_profile(profile, feedrate, ramp_time, curve: NurbsCurve, path: SmoothedPolyline | Toolpath | None):
    """The feedrate profile of ``profile=``: one of :data:`PROFILES`, or a profile object of the user's own (any
    object with ``plan(length_mm) -> plan``, as :mod:`vcnc_gym.motion`'s profiles; its plan sets the feed, so
    ``feedrate`` and ``ramp_time`` do not apply)."""
    if not isinstance(profile, str) and callable(getattr(profile, "plan", None)):
        if ramp_time is not None:
            raise ValueError(
                "ramp_time (s) shapes the S-curve of profile='scurve'; a profile object plans its own feed"
            )
        return profile
    if profile not in PROFILES:
        raise ValueError(
            f"profile must be one of {list(PROFILES)} or a profile object with plan(length), got {profile!r}"
        )
    if profile != "scurve" and ramp_time is not None:
        raise ValueError(f"ramp_time (s) shapes the S-curve only; profile={profile!r} has no ramp time to set")
    if isinstance(path, Toolpath):  # a G-code program: its blocks' feeds
        return path.feedrate_profile(profile, ramp_time)
    if profile == "scurve":
        return SCurveFeedrate(feedrate=feedrate, ramp_time=DEFAULT_RAMP_TIME if ramp_time is None else ramp_time)
    if profile == "constant":
        return ConstantFeedrate(feedrate)
    if profile == "lookahead":
        return LookaheadFeedrate(curve, feedrate)
    if path is None:
        raise ValueError(
            "profile='jlap' plans along a corner-smoothed path: give contour='corners-smooth' or a "
            "SmoothedPolyline (geometry.smooth_polyline)"
        )
    return JlapPathFeedrate(path, feedrate)


class ContouringTask:
    """One validated contouring configuration, shared by every env that runs it.

    The arguments are those of :class:`~vcnc_gym.envs.ContouringEnv` (see
    its docstring for their meaning and units).
    """

    def __init__(
        self,
        contour="heart",
        plant="vcnc_feed_drive",
        feedrate: float = 100.0,
        ramp_time: float | None = None,
        profile: str = "scurve",
        dt: float = 1e-4,
        action_repeat: int = 1,
        randomize: bool = False,
        parameters=None,
        reward_scale: float = 0.01,
        effort_weight: float = 0.0,
        divergence_bound: float = 5.0,
        tracking_bound: float = 10.0,
        settling_time: float | None = None,
        preview_steps=(10, 50, 100),
        contour_ahead=DEFAULT_CONTOUR_AHEAD,
        episode_end: str = "tool",
        completion_tolerance: float = DEFAULT_COMPLETION_TOLERANCE,
        completion_timeout: float = DEFAULT_COMPLETION_TIMEOUT,
        max_episode_steps: int | None = None,
        plant_options: dict | None = None,
        shop_floor: dict | bool | None = None,
        action: str = "voltage",
        setpoint_range: float | None = None,
        servo_gains: dict | None = None,
        base: str | None = None,
        correction: float = 0.5,
        error_clip: float | None = None,
        observation_scale: str = "raw",
    ):
        self._set_contour_and_plant(contour, plant, shop_floor, plant_options)
        self._check_settings(
            dt,
            action_repeat,
            randomize,
            reward_scale,
            effort_weight,
            divergence_bound,
            tracking_bound,
            episode_end,
            settling_time,
            completion_tolerance,
            completion_timeout,
        )
        preview_steps = _as_tuple(preview_steps)
        contour_ahead = _as_tuple(contour_ahead)
        self._set_parameters(parameters)
        samples, reference_end = self._plan_reference(profile, feedrate, ramp_time, max_episode_steps)
        self._set_observation(preview_steps, contour_ahead, samples, reference_end)
        self._set_action(action, setpoint_range, servo_gains, base, correction, error_clip, observation_scale)
        # a decision of the set-point or correction actions is a compiled controller's loop of action_repeat kernel
        # steps of one control period each (step_kernel.step_controlled_serial): the kernel counts periods
        periods = self.action_repeat if self.controlled else 1
        self.config = sk.StepConfig(
            n_repeat=self.action_repeat // periods,
            reward_scale=self.reward_scale,
            effort_weight=self.effort_weight,
            divergence_bound=self.divergence_bound,
            tracking_bound=self.tracking_bound,
            episode_end=EPISODE_ENDS[self.episode_end],
            end_index=self.end_index,
            episode_steps=self.episode_steps * periods,
            max_steps=self.max_episode_steps * periods,
            completion_tolerance=self.completion_tolerance,
            progress_window=self.tracking_bound,
            dt=self.dt,
            error_clip=self.error_clip,
        )

    def _set_contour_and_plant(self, contour, plant, shop_floor, plant_options) -> None:
        """The contour (checked regular) and the plant model (on the shop floor if asked)."""
        self.curve, self.path = make_contour(contour)
        self.curve.check_regular()  # no cusp, no turn back (NurbsCurve.check_regular), before the feed is planned
        self.contour_name = contour if isinstance(contour, str) else getattr(self.path, "name", "custom")
        self.plant: PlantModel = get_plant(plant)
        if shop_floor is not None and shop_floor is not False:  # the machine with its sensor, delays, mode, forces
            from ..plants.shop_floor import shop_floor as on_the_shop_floor

            self.plant = on_the_shop_floor(self.plant, shop_floor)
        if plant_options is not None and not isinstance(plant_options, dict):
            raise ValueError(f"plant_options must be a dict of the plant's settings, got {plant_options!r}")
        self.plant_options = dict(plant_options or {})

    def _check_settings(
        self,
        dt,
        action_repeat,
        randomize,
        reward_scale,
        effort_weight,
        divergence_bound,
        tracking_bound,
        episode_end,
        settling_time,
        completion_tolerance,
        completion_timeout,
    ) -> None:
        """The scalar settings, checked (:mod:`vcnc_gym.validation`)."""
        self.dt = positive("dt", dt, "s")
        if not DT_RANGE[0] <= self.dt <= DT_RANGE[1]:
            raise ValueError(
                f"dt={dt!r} s is outside [{DT_RANGE[0]:g}, {DT_RANGE[1]:g}] s; dt is the control "
                f"period in seconds (0.1 ms is dt=1e-4)"
            )
        self.action_repeat = integer("action_repeat", action_repeat, 1)
        self.randomize = flag("randomize", randomize)
        self.reward_scale = positive("reward_scale", reward_scale, "mm")
        self.effort_weight = non_negative("effort_weight", effort_weight, "1")
        self.divergence_bound = positive("divergence_bound", divergence_bound, "mm")
        self.tracking_bound = positive("tracking_bound", tracking_bound, "mm")
        if episode_end not in EPISODE_ENDS:
            raise ValueError(f"episode_end must be one of {list(EPISODE_ENDS)}, got {episode_end!r}")
        self.episode_end = episode_end
        if episode_end == "tool" and settling_time is not None:
            raise ValueError(
                "settling_time (s) is the wait after the reference's end of episode_end='reference'; "
                "with episode_end='tool' the episode ends when the tool arrives (completion_timeout "
                "bounds the wait)"
            )
        self.settling_time = non_negative(
            "settling_time", DEFAULT_SETTLING_TIME if settling_time is None else settling_time, "s"
        )
        self.completion_tolerance = positive("completion_tolerance", completion_tolerance, "mm")
        self.completion_timeout = non_negative("completion_timeout", completion_timeout, "s")

    def _set_action(self, action, setpoint_range, servo_gains, base, correction, error_clip, scale) -> None:
        """What the action commands (:data:`ACTIONS`), the drive's servo or the base controller's name, the reward's
        clip and the observation's scale."""
        if action not in ACTIONS:
            raise ValueError(f"action must be one of {list(ACTIONS)}, got {action!r}")
        if base is not None:
            if not isinstance(base, str) or not base:
                raise ValueError(
                    f"base must be the name of a classical controller (vcnc_baselines.names()), got {base!r}"
                )
            if action == "voltage":
                raise ValueError(
                    "base= adds the agent's correction to a classical controller's command; it needs "
                    "action='correction' (or the learnable ids' default 'setpoint', which it replaces)"
                )
            action = "correction"
        elif action == "correction":
            raise ValueError("action='correction' corrects a classical controller's command: name it with base=")
        self.action = action
        self.base = base
        self.controlled = action != "voltage"
        self.correction = positive("correction", correction, "fraction of the input limit")
        if self.correction > 2:
            raise ValueError(f"correction must be at most 2 (fractions of the input limit), got {correction!r}")
        self.servo_gains = None
        if action == "setpoint":
            from .drive_servo import DriveServoGains, drive_servo_gains

            if servo_gains is None:
                self.servo_gains = drive_servo_gains(self.plant, self.nominal_parameters, self.dt)
            elif isinstance(servo_gains, dict):
                self.servo_gains = DriveServoGains.from_dict("servo_gains", servo_gains)
            else:
                raise ValueError(f"servo_gains must be a dict of the servo's gains, got {type(servo_gains).__name__}")
        elif servo_gains is not None or setpoint_range is not None:
            raise ValueError("servo_gains and setpoint_range set the drive's servo of action='setpoint'")
        u_max = self.plant.input_limits(self.nominal_parameters)
        self.setpoint_range = (
            None
            if action != "setpoint"
            else (
                positive("setpoint_range", setpoint_range, "mm")
                if setpoint_range is not None
                else float(np.min(u_max / self.servo_gains.kp))  # pyright: ignore[reportOptionalMemberAccess]
            )
        )
        self.error_clip = self.divergence_bound if error_clip is None else positive("error_clip", error_clip, "mm")
        if self.error_clip > self.divergence_bound:
            raise ValueError(f"error_clip={error_clip!r} mm is beyond divergence_bound={self.divergence_bound!r} mm")
        if scale not in OBSERVATION_SCALES:
            raise ValueError(f"observation_scale must be one of {list(OBSERVATION_SCALES)}, got {scale!r}")
        self.observation_scale = scale
        self.physical_layout = self.layout
        """The layout of the fields in their units, as the step kernel writes them (what a classical controller
        reads)."""
        self.layout = self.layout.scaled(self._unit_scales()) if scale == "unit" else self.layout

    def _unit_scales(self) -> dict:
        """The fixed constants that bring each observation field to order one (``observation_scale="unit"``), in
        the field's unit: the contour's extent, its top speed and acceleration, the reward's scale (ten times it for
        the tracking error and its tangential part), the preview's reach at the top speed, the farthest contour
        preview, the contour's largest curvature."""
        ref = self.reference
        speed = float(np.max(np.hypot(ref.velocity[:, 0], ref.velocity[:, 1])))
        accel = float(np.max(np.abs(ref.acceleration)))
        curvature = float(np.max(np.abs(self.reference_arrays.samples[:, sk.REF_CURVATURE])))
        steps = self.layout.preview_steps
        ahead = self.layout.contour_ahead
        error = self.reward_scale
        return {
            "reference_position": _round(float(np.max(np.abs(ref.position)))),
            "reference_velocity": _round(speed),
            "reference_acceleration": _round(accel),
            "tracking_error": _round(10 * error),
            "contour_error": _round(error),
            "tangential_error": _round(10 * error),
            "normal_error": _round(error),
            "velocity": _round(speed),
            "preview": _round(speed * self.dt * max(steps)) if steps else 1.0,
            "contour_preview": _round(max(ahead)) if ahead else 1.0,
            "contour_curvature": _round(curvature) if curvature > 0 else 1.0,
            "previous_action": 1.0,
        }

    def _set_parameters(self, parameters) -> None:
        """The plant's parameters: nominal, and the fixed ones if given."""
        self.nominal_parameters = self.plant.nominal()
        if parameters is not None and self.randomize:
            raise ValueError(
                "pass either parameters= (a fixed plant) or randomize=True (a plant drawn at every reset), not both"
            )
        self.fixed_parameters = None if parameters is None else self.check_parameters(parameters)

    def _plan_reference(self, profile, feedrate, ramp_time, max_episode_steps) -> tuple[np.ndarray, int]:
        """The feed plan and the reference (computed once), the projector, the episode's lengths; the
        reference's samples packed for the kernel and its last control period."""
        episode_end = self.episode_end
        self.feedrate_profile = make_profile(profile, feedrate, ramp_time, self.curve, self.path)
        self.reference = interpolate(self.curve, self.feedrate_profile, self.dt)
        samples = pack_reference(self.curve, self.reference)
        self.projector = ContourProjector(
            self.curve, margin=min(max(10.0, 2 * self.divergence_bound), _GRID_MARGIN_MAX)
        )
        reference_end = len(self.reference.t) - 1
        wait = self.settling_time if episode_end == "reference" else self.completion_timeout
        self.end_index = reference_end + math.ceil(wait / self.dt - 1e-9)
        """The control period at which the episode ends ("reference") or runs out of time ("tool")."""
        if self.action_repeat > self.end_index:
            raise ValueError(
                f"action_repeat={self.action_repeat} control periods is longer than the whole "
                f"episode ({self.end_index} periods of {self.dt:g} s)"
            )
        self.episode_steps = math.ceil(
            (self.end_index if episode_end == "reference" else reference_end) / self.action_repeat
        )
        """Natural episode length in decision steps (without divergence): "reference", to its end; "tool", to
        the reference's end (a tool that keeps up arrives within a few steps of it)."""
        self.time_limit_steps = math.ceil(self.end_index / self.action_repeat)
        """The most decision steps an episode can take (the completion time limit, or the end)."""
        self.max_episode_steps = (
            self.time_limit_steps
            if max_episode_steps is None
            else size(
                "max_episode_steps",
                max_episode_steps,
                ceiling=self.time_limit_steps,
                why=f"the episode ends at its completion time limit, {self.time_limit_steps} decisions, anyway",
            )
        )
        return samples, reference_end

    def _set_observation(self, preview_steps, contour_ahead, samples: np.ndarray, reference_end: int) -> None:
        """The observation layout and the reference's arrays: nothing shown beyond the contour's end (it would be
        its end point, silently)."""
        if isinstance(preview_steps, tuple):
            for s in preview_steps:
                size(
                    "preview_steps",
                    s,
                    ceiling=reference_end,
                    why=f"the reference's length in control periods of {self.dt:g} s: a point further ahead "
                    "is past the contour's end",
                )
        length = float(samples[-1, sk.REF_ARC])
        if isinstance(contour_ahead, tuple):
            for a in contour_ahead:
                if isinstance(a, (int, float, np.integer, np.floating)) and not isinstance(a, bool) and a > length:
                    raise ValueError(
                        f"contour_ahead must be at most {length:.6g} mm (the contour's length: a "
                        f"point further ahead is past its end), got {a!r}"
                    )
        extent = float(np.max(np.abs(self.reference.position)))
        self.layout = ObservationLayout(
            preview_steps=preview_steps,
            contour_ahead=contour_ahead,
            position_bound=max(_POSITION_BOUND, extent + self.tracking_bound + _POSITION_MARGIN),
        )
        self.reference_arrays = sk.ReferenceArrays(
            samples,
            np.array(self.layout.preview_steps, dtype=np.int64),
            np.array(self.layout.contour_ahead, dtype=np.float64),
        )
        self.contour_arrays = self.projector.arrays

    @property
    def contour_length(self) -> float:
        """Arc length of the contour, mm (as the reference's samples measure it: the progress' scale)."""
        return float(self.reference_arrays.samples[-1, sk.REF_ARC])

    @property
    def decision_period(self) -> float:
        """Time between two decisions in s: ``dt * action_repeat``."""
        return self.dt * self.action_repeat

    def check_parameters(self, parameters) -> np.ndarray:
        """One machine's parameters, (2, P), checked by the plant model: an array, or a dict as the reset's
        ``info["parameters"]`` gives them (name -> a value shared by both axes, or a per-axis pair)."""
        if isinstance(parameters, dict):
            parameters = _parameters_array(self.plant, parameters)
        p = self.plant.validate(parameters)
        if p.shape[0] != 1:
            raise ValueError(f"parameters must be one machine's (2, {self.plant.n_parameters}) array, got {p.shape}")
        return p[0].copy()

    def parameters_for_reset(self, rng: np.random.Generator, options) -> np.ndarray:
        """The plant of the next episode: ``options["parameters"]``, a draw, the fixed or the nominal one."""
        if options is not None:
            if not isinstance(options, dict):
                raise ValueError(f"reset options must be a dict, got {type(options).__name__}")
            unknown = sorted(set(options) - set(RESET_OPTIONS))
            if unknown:
                raise ValueError(f"unknown reset option(s) {unknown}; known: {list(RESET_OPTIONS)}")
            if "parameters" in options:
                return self.check_parameters(options["parameters"])
        if self.randomize:
            return self.plant.sample(rng)
        if self.fixed_parameters is not None:
            return self.fixed_parameters
        return self.nominal_parameters


def _parameters_array(plant: PlantModel, values: dict) -> np.ndarray:
    """The (2, P) array of a dict of ``plant``'s parameters (:meth:`PlantModel.to_dict`'s form); ValueError
    naming the missing or unknown names."""
    names = [p.name for p in plant.parameters]
    missing, unknown = sorted(set(names) - set(values)), sorted(set(values) - set(names))
    if missing or unknown:
        raise ValueError(f"parameters: missing {missing}, unknown {unknown}; {plant.name} has {names}")
    out = np.empty((2, len(names)))
    for j, name in enumerate(names):
        v = values[name]
        pair = v if isinstance(v, (tuple, list, np.ndarray)) else (v, v)
        if len(pair) != 2:
            raise ValueError(f"parameters[{name!r}] must be a number or an (x, y) pair, got {v!r}")
        try:
            out[:, j] = [float(pair[0]), float(pair[1])]
        except (TypeError, ValueError):
            raise ValueError(f"parameters[{name!r}] must be real numbers, got {v!r}") from None
    return out


def _round(value: float) -> float:
    """``value`` rounded up to 1, 2 or 5 times a power of ten: a scale a reader recognises (1 for a field that is
    zero all along, such as the acceleration of a constant feed along straight lines)."""
    if not value > 0 or not math.isfinite(value):
        return 1.0
    exponent = math.floor(math.log10(value))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10.0**exponent >= value * (1 - 1e-12):
            return m * 10.0**exponent
    return 10.0 ** (exponent + 1)


def _as_tuple(values):
    """A list or array argument as a tuple (the layout checks the entries)."""
    if isinstance(values, np.ndarray):
        return tuple(values.tolist())
    return tuple(values) if isinstance(values, list) else values


def pack_reference(curve: NurbsCurve, reference) -> np.ndarray:
    """The reference packed for the step kernel, (K, REF_COLUMNS): x_d, dx_d/dt, d2x_d/dt2, unit tangent, u,
    arc length (the cumulative chord of the samples, mm: short of the arc by sum kappa^2 c^3 / 24, below 1e-6 mm
    on the suite's contours) and signed curvature ``(x' y'' - y' x'') / |C'|^3`` in 1/mm at u."""
    der = curve.derivatives_array(reference.u, 2)
    d1, d2 = der[:, 1], der[:, 2]
    speed = np.hypot(d1[:, 0], d1[:, 1])
    curvature = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / speed**3
    arc = np.concatenate([[0.0], np.cumsum(reference.chord_lengths)])
    return np.ascontiguousarray(
        np.column_stack(
            [
                reference.position,
                reference.velocity,
                reference.acceleration,
                reference.tangent,
                reference.u,
                arc,
                curvature,
            ]
        )
    )


class ContouringBatch:
    """The arrays of ``n_envs`` envs running one :class:`ContouringTask`, and the kernel call.

    Parameters
    ----------
    task : ContouringTask
    n_envs : int
        Number of envs (machines), >= 1.
    reference : ReferenceArrays, optional
        The reference the kernel reads; default ``task.reference_arrays`` (a feed override,
        :class:`~vcnc_gym.envs.feed_override_env.FeedOverrideEnv`, gives a buffer it re-times).
    """

    def __init__(
        self,
        task: ContouringTask,
        n_envs: int,
        *,
        argument: str = "n_envs",
        reference: sk.ReferenceArrays | None = None,
    ):
        self.task = task
        self.reference_arrays = task.reference_arrays if reference is None else reference
        n = self.n_envs = size(
            argument,
            n_envs,
            bytes_each=self.bytes_per_env(task),
            why="each env's rows of the batch arrays, twice (the copies step returns), and its random generator",
        )
        layout = task.layout
        self.plant_arrays = task.plant.arrays(n, task.dt, **task.plant_options)
        self.parameters = np.repeat(task.nominal_parameters[None], n, axis=0)
        self.buffers = sk.EnvBuffers(
            mode=np.zeros(n, dtype=np.int8),
            action=np.zeros((n, 2)),
            k=np.zeros(n, dtype=np.int64),
            steps=np.zeros(n, dtype=np.int64),
            foot=np.full(n, np.nan),
            input_limit=np.zeros((n, 2)),
            previous_action=np.zeros((n, 2)),
            progress=np.zeros(n, dtype=np.int64),
            cycle_time=np.full(n, np.nan),
            reference_end=np.full(n, self.reference_arrays.samples.shape[0] - 1, dtype=np.int64),
            obs=np.zeros((n, layout.size), dtype=np.float32),
            reward=np.zeros(n),
            flags=np.zeros((n, sk.FLAG_SIZE), dtype=np.bool_),
            info=np.zeros((n, sk.INFO_SIZE)),
            obs_high=layout.high(),
            sensed=np.zeros((n, contract.SENSE_SIZE)),
            der=np.zeros((n, 3, 2)),
            episode=np.zeros((n, sk.EPISODE_SIZE)),
        )
        self.data = sk.StepData(
            self.plant_arrays, self.reference_arrays, task.contour_arrays, task.config, layout.offsets(), self.buffers
        )

    @staticmethod
    def bytes_per_env(task: ContouringTask) -> int:
        """Memory one env of a batch costs, bytes: twice its rows of the batch and plant arrays (the buffers,
        and the copies ``step`` returns), plus :data:`ENV_OVERHEAD_BYTES`."""
        arrays = task.plant.arrays(1, task.dt, **task.plant_options)
        rows = sum(a.nbytes for a in arrays if isinstance(a, np.ndarray))
        layout = task.layout
        rows += (
            layout.size * 4
            + (sk.INFO_SIZE + contract.SENSE_SIZE + sk.EPISODE_SIZE + 6 + 2 * 5 + 5) * 8
            + sk.FLAG_SIZE
            + 1
        )
        return 2 * rows + ENV_OVERHEAD_BYTES

    def reset_env(self, i: int, parameters: np.ndarray, rng: np.random.Generator | None = None) -> None:
        """Env ``i`` at the start of the contour, at rest, with plant ``parameters`` (2, P); marks it to observe.
        ``rng``, the env's generator, seeds the plant's random state (``PlantModel.seed_machine``), if it has one."""
        b = self.buffers
        self.parameters[i] = parameters
        self.plant_arrays.params[i] = parameters
        self.task.plant.reset_machine(self.plant_arrays, i, self.reference_arrays.samples[0, :2])
        if rng is not None and self.task.plant.seed_machine is not None:
            self.task.plant.seed_machine(self.plant_arrays, i, rng)
        b.input_limit[i] = self.task.plant.input_limits(parameters)
        b.k[i] = 0
        b.steps[i] = 0
        b.foot[i] = np.nan  # no previous foot: a global search
        b.previous_action[i] = 0.0
        b.progress[i] = 0
        b.cycle_time[i] = np.nan
        b.reference_end[i] = self.reference_arrays.samples.shape[0] - 1
        b.action[i] = 0.0
        b.episode[i] = 0.0
        b.mode[i] = sk.MODE_OBSERVE

    def run(self, parallel: bool = False) -> None:
        """One kernel call: every env in MODE_STEP steps, every env in MODE_OBSERVE observes."""
        (sk.step_parallel if parallel else sk.step_serial)(self.data)

    def run_controlled(self, controller, loop: sk.ControlLoop, parallel: bool = False) -> None:
        """One kernel call: every env in MODE_STEP makes one decision of ``loop.repeat`` control periods with
        ``controller`` (:mod:`~vcnc_gym.envs.controller_contract`) in the loop."""
        (sk.step_controlled_parallel if parallel else sk.step_controlled_serial)(self.data, controller, loop)
