"""ContouringEnv: a biaxial machine following a contour, judged by contour error."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from . import step_kernel as sk
from .pickling import RebuiltOnUnpickle, batch_arrays, restore_arrays
from .signatures import forwarded_signature
from .decision import DecisionLoop, episode_summary
from .rendering import EpisodeHistory, Renderer, render_every_argument, render_fps
from .task import ContouringBatch, ContouringTask

__all__ = ["ContouringEnv", "check_actions", "step_info"]


class ContouringEnv(RebuiltOnUnpickle, gym.Env):
    r"""Contour following on a biaxial machine, judged by the contour error.

    ## Description

    A biaxial (X-Y) machine table follows a contour, a NURBS curve (Jahanpour
    et al.'s "heart" or "omega", section 3a, by default), at the S-curve
    feedrate of Jahanpour et al. (2014) (100 mm/s, 0.12 s ramps) laid out by the
    second-order Taylor interpolator, eqs. (8)-(10).  The machine is a plant
    of :mod:`vcnc_gym.plants` (``plant=``); by default Jahanpour et al.'s feed drive,
    eq. (1), with the parameters of section 2c and Table 3: +-5 V amplifier
    saturation, 3 um backlash, asymmetric static and Coulomb friction
    (Karnopp stick-slip), integrated in closed form on substeps.  The policy
    is judged by the contour error: the shortest distance from the table to
    the whole contour, not to the current reference point.

    Each id comes in two interfaces.  The v2 ids (``VCNC-Heart-v2``, ...) are
    the ones to learn on: as on a CNC, the drive closes its own servo loop
    every control period inside the step, and the policy, an outer loop
    deciding every 1 ms, moves the servo's set-point; the observation is
    scaled to order one and the reward is clipped at 100 um.  The v1 ids keep
    the papers' interface, the amplifier's voltage every 0.1 ms and the
    observation in physical units, for the classical controllers
    (:mod:`vcnc_baselines`) and the figures measured on them.

    ## Action Space

    ``Box(-1, 1, (2,), float32)`` in every version: one value per axis, whose
    meaning ``action`` sets.

    ===  ======  ===  ===  =====================================  =========================================
    Num  Axis    Min  Max  ``action="voltage"`` (v0, v1)          ``action="setpoint"`` (v2)
    ===  ======  ===  ===  =====================================  =========================================
    0    x       -1   1    amplifier command / input limit (5 V)  set-point correction / ``setpoint_range``
    1    y       -1   1    amplifier command / input limit (5 V)  set-point correction / ``setpoint_range``
    ===  ======  ===  ===  =====================================  =========================================

    - "voltage": the plant's input over its limit (5 V on Jahanpour et al.'s
      drives), held for ``action_repeat`` control periods.  Values outside
      [-1, 1] are clipped: that is the amplifier's saturation.
      ``env.unwrapped.plant`` names the input and its unit (``input_name``,
      ``input_unit``, ``input_limit``).
    - "setpoint": the drive's set-point is moved by ``a * setpoint_range`` mm
      per axis, held for the decision, and the drive's servo
      (:mod:`~vcnc_gym.envs.drive_servo`: the PID of the machine's
      commissioning record, with velocity feedforward and, on the shop floor,
      a notch at the structural mode) turns the shifted tracking error into
      the amplifier command every control period.  The action 0 is the servo
      alone, which finishes every contour.  ``setpoint_range`` defaults to the
      set-point error at which the servo's proportional term alone reaches the
      input limit, ``u_max / K_p`` of the stiffer axis
      (``env.unwrapped.task.setpoint_range``, mm; each id's page gives it):
      0.91 um on Jahanpour et al.'s ideal drives, 1.8 um on Simba et al.'s,
      28 um on Purtojo et al.'s table; on the shop floor, whose commissioned
      servos are softer, 104 um (Jahanpour et al.'s) and 406 um (Simba et al.'s).
    - "correction" (set by ``base=NAME``): the classical controller NAME runs
      every control period inside the step and the amplifier command is
      ``clip(u_c / u_max + correction * a, -1, 1)``, ``u_c`` its command: a
      correction learnt on top of a controller, with no extra package beyond
      the controllers' (``pip install 'vcnc-gym[baselines]'``).

    Wrong shapes, non-real and non-finite values raise ``ValueError``.

    ## Observation Space

    A flat float32 ``Box``; its fields are named by
    :class:`~vcnc_gym.envs.layout.ObservationLayout` (``env.unwrapped.layout``),
    so a policy reads ``layout.tracking_error(obs)`` instead of indices (the
    accessors return physical units under either scale).  With
    the default three preview points:

    =====  ======================  ======  ==============================================
    Index  Field                   Unit    Meaning
    =====  ======================  ======  ==============================================
    0-1    reference_position      mm      reference point x_d
    2-3    reference_velocity      mm/s    dx_d/dt
    4-5    reference_acceleration  mm/s^2  d2x_d/dt2
    6-7    tracking_error          mm      x_d - x (Simba et al., eq. (2))
    8      contour_error           mm      distance from the table to the whole contour
    9      tangential_error        mm      tracking error along the path tangent (eq. (3))
    10     normal_error            mm      tracking error along the path normal (eq. (3))
    11-12  velocity                mm/s    table velocity
    13-18  preview                 mm      x_d 1, 5, 10 ms ahead minus the table position
    19-28  contour_preview         mm      the contour 0.25, 0.5, 1, 2, 4 mm of arc beyond the table's closest point, minus the table position, along the tangent and normal there
    29-33  contour_curvature       1/mm    signed curvature of the contour at those points
    34-35  previous_action         1       the last action
    =====  ======================  ======  ==============================================

    The contour preview reaches twice the ~1.9 mm that Jahanpour et al.'s drives need
    to brake from 100 mm/s, so a policy can see a corner coming and slow
    down for it (``contour_ahead=``, mm; ``()`` for none).

    With ``observation_scale="unit"`` (v2) each field is divided by a fixed
    constant of the task, its ``scale`` (``layout.fields[k].scale``, in the
    field's unit; ``layout.describe()`` prints them with the fields), so that
    typical values are of order one, without running statistics inside the
    env: the contour's extent for the positions, the reference's top speed
    and acceleration, the reward's error clip for the contour and normal
    errors and ten times it for the tracking and tangential errors, the
    preview's reach at the top speed, the farthest contour preview, the
    contour's largest curvature.  On the v2 heart: 100 mm, 100 mm/s,
    2000 mm/s^2, 0.1 mm, 0.01 mm, 1 mm, 5 mm and 0.2 1/mm.  A scaled field
    is bounded at 100 times its scale.  ``"raw"`` (v0, v1) shows the
    physical units, bounded at 1000 mm, 1000 mm/s, 1e6 mm/s^2 and 10 mm.
    Under ``action="setpoint"`` and ``"correction"`` the previous action is
    the agent's own, not the amplifier command.

    The position bound is 1000 mm, or the contour's extent plus
    ``tracking_bound`` plus 100 mm if that is larger.  Values beyond the
    layout's bounds are clipped, so every observation lies inside the space;
    ``info["observation_clipped"]`` counts the entries clipped in a step.

    ## Rewards

    ``reward = -min(contour_error, error_clip) / reward_scale - effort_weight * mean(u**2)``,
    the contour error averaged over the decision's control periods (under the
    set-point and correction actions each period's is clipped, then averaged)
    and ``u`` the amplifier command over its limit: a monotone function of the
    contour error, 0 for none.
    In v2 ``reward_scale`` is 10 um and ``error_clip`` 100 um (2 um and 20 um
    on Purtojo et al.'s circle, whose contour errors are a few um): a
    decision earns between -10 and 0, so an episode's return is of the order
    of its number of decisions.  The clip lies above the peaks the drive's
    servo alone leaves (43-47 um on the shop floor), so lowering a peak pays;
    clipped at 10 um the reward saturated there and PPO left the shop-floor
    heart's peak where the servo had it.  In v0 and v1 ``reward_scale`` is 10 um and ``error_clip``
    the divergence bound, 5 mm (up to -500 a step).  The effort term is off
    by default.  On divergence a terminal penalty of
    ``-(error_clip / reward_scale)`` per remaining decision of the contour
    is added (-10 a decision in v2), so ending an episode early never pays
    more than finishing it.  Every term is in ``info`` ("reward_contour",
    "reward_effort", "reward_divergence", "reward_incomplete").

    The per-step contour error keys are named per step: under the set-point
    and correction actions ``info["step_contour_error_max"]`` and
    ``info["step_contour_error_mean"]`` (mm, over the decision's control
    periods); ``info["contour_error"]`` is the last period's.  The episode's
    figures are in ``info["episode_summary"]`` at its end (Episode End).

    ## Starting State

    The table rests at the start of the contour with the backlash gap
    centred, the drive's servo (v2) or the base controller with its memory
    cleared; the plant parameters are the nominal ones (interval midpoints),
    those given by ``parameters``, or, with ``randomize=True``, drawn
    uniformly from Jahanpour et al.'s intervals by the env's seeded generator.  The
    parameters in force are in the reset info, in a form
    ``reset(options={"parameters": info["parameters"]})`` takes back.

    ## Episode End

    - Terminated once the table has reached the end of the contour: the
      first control period, the reference's end or later, at which at most
      ``completion_tolerance`` (20 um) of contour lies ahead of the table's
      closest point.  ``info["completed"]`` is then True and
      ``info["cycle_time"]`` (s) the time it arrived; ``info["progress"]``
      (mm) is the arc length the table has passed at every step.
    - Terminated at the completion time limit, ``completion_timeout`` (0.1 s)
      after the reference's end, with ``info["completed"] = False`` and a
      penalty of ``-(untraversed length) / reward_scale``
      (``info["reward_incomplete"]``; under the set-point and correction
      actions divided by ``action_repeat``, as every period's reward is in
      the decision's mean).  Terminated, not truncated, on
      purpose: the limit is part of the task (a part has a cycle time, and
      running out of it ends the task at the cost of what is left), so a
      learner must not bootstrap past it; Gymnasium's truncation is for
      limits outside the task, such as ``max_episode_steps``, which sets
      ``truncated``.
    - Terminated early with ``info["diverged"] = True`` when the contour
      error exceeds ``divergence_bound`` (default 5 mm), the tracking error
      exceeds ``tracking_bound`` (default 10 mm: the table has fallen that
      far behind or ahead of the reference), or the plant state stops being
      finite.  Without the tracking bound a table that never moves would
      score a perfect contour error, its start point lying on the contour.  The bound is that wide because the omega's
      corners (radius 0.19 mm) ask 100 mm/s for 5.4e4 mm/s^2, twenty times what
      the +-5 V drives can give (~2.6e3 mm/s^2): a stable tracking controller
      is thrown millimetres off the contour there without diverging.
    - The natural length, ``env.unwrapped.episode_steps`` decision steps
      (to the reference's end), follows the configuration (``dt``,
      ``feedrate``, ``ramp_time``, ``action_repeat``): the ids register no fixed
      ``TimeLimit``.  ``max_episode_steps`` (an argument of the env, or of
      ``gym.make``) truncates earlier; the env warns when that cuts the
      contour short.

    However it ends, the last step's ``info["episode_summary"]`` holds the
    episode's figures (:data:`~vcnc_gym.envs.decision.SUMMARY_KEYS`): the
    max, mean and RMS contour error over every control period (mm), the
    cycle time (s, NaN unless completed), completed, diverged and the
    control periods run.  It is named so as not to clash with
    ``RecordEpisodeStatistics``' ``info["episode"]``.

    ## Arguments

    ``gym.make("VCNC-Heart-v2", **kwargs)`` with

    - ``contour``: a name of ``vcnc_gym.geometry.SHAPES`` ("heart", "omega",
      "circle", "corners", "corners-smooth"), a :class:`NurbsCurve` or a
      ``SmoothedPolyline`` (mm).
    - ``plant``: a module name of :mod:`vcnc_gym.plants`
      (:func:`vcnc_gym.plants.plant_names`) or a ``PlantModel``; default
      ``"vcnc_feed_drive"`` (Jahanpour et al. (2014)).
    - ``profile`` ("scurve"): the feedrate profile, one of "scurve" (Jahanpour
      et al.'s cubic S-curve: ``feedrate`` and ``ramp_time``), "constant" (the
      feed from t = 0, no ramps: Simba et al.'s linear path, Purtojo et al.'s circle),
      "jlap" (Simba et al.'s jerk-limited profile with the corner speeds of a
      corner-smoothed path, ``contour="corners-smooth"``) or "lookahead" (a
      CNC's look-ahead: ``feedrate`` along the path, slowed where its
      curvature asks more than the path limits give; the ``...Lookahead-v1``
      ids); or a profile object of your own, any object with
      ``plan(length_mm)`` as :mod:`vcnc_gym.motion`'s profiles (its plan sets
      the feed: ``feedrate`` and ``ramp_time`` do not apply).
    - ``feedrate`` (mm/s, 100) and ``ramp_time`` (s, S-curve only, default 0.12).
    - ``dt`` (s, 1e-4): the control period, at which the command is held
      and the reference is sampled.  At 1 ms Jahanpour et al.'s QFT loop is unstable
      (a closed-loop pole of magnitude near 10); at 0.1 ms it is stable on every
      vertex of the uncertainty box.
    - ``action_repeat`` (1; 10 in v2): control periods per decision.
    - ``randomize`` (False) / ``parameters`` (None, a (2, P) array of the
      plant, columns ``env.unwrapped.plant.parameter_names``): the plant in
      force; not both.  ``reset(options={"parameters": p})`` sets it for one
      episode.
    - ``reward_scale`` (mm, 0.01; 0.001 in v2), ``effort_weight`` (0.0),
      ``divergence_bound`` (mm, 5.0), ``tracking_bound`` (mm, 10.0).
    - ``error_clip`` (mm; None: ``divergence_bound``; 0.01 in v2): the
      contour error at which a control period's reward saturates, and the
      reward per remaining decision the divergence penalty charges.  At most
      ``divergence_bound``.
    - ``episode_end`` ("tool"): "tool" as above, or "reference" (v0: the
      episode ends ``settling_time``, s, default 0.01, after the
      reference's end); ``completion_tolerance`` (mm, 0.02) and
      ``completion_timeout`` (s, 0.1).
    - ``preview_steps`` ((10, 50, 100)): preview offsets in control periods; ``()``: no preview field (the
      controllers read their preview from the reference; ``contouring-fb`` refuses it).
    - ``contour_ahead`` ((0.25, 0.5, 1, 2, 4)): arc lengths, mm, of the
      contour preview.
    - ``observation_scale`` ("raw"; "unit" in v2): the fields in their
      physical units, or each divided by its fixed scale (Observation Space).
    - ``action`` ("voltage"; "setpoint" in v2): what the action commands,
      "voltage", "setpoint" or "correction" (Action Space); "correction" is
      set by ``base``.
    - ``setpoint_range`` (mm; None: ``u_max / K_p`` of the stiffer axis): the
      set-point correction of the action 1, ``action="setpoint"`` only.
    - ``servo_gains`` (None: the commissioning record of the id's nominal
      machine, shipped in ``vcnc_gym/envs/drive_servos.json``): the drive's
      servo of ``action="setpoint"``, a dict with per axis "kp" (input unit
      per mm), "kd" (per mm/s), "ki" (per mm s), "velocity_pole" (in [0, 1))
      and "notch" ((2, 5) biquad coefficients).
    - ``base`` (None): the name of a classical controller
      (``vcnc_baselines.names()``, e.g. "ff-pid", "zpetc", "ccc"; one with a
      compiled form) run every control period inside the step, the action a
      correction to its command (``action="correction"``).  The controllers
      come from the packages of the entry point group
      ``vcnc_gym.base_controllers`` (``vcnc_baselines``, the baselines extra);
      ``vcnc_gym`` itself names none.
    - ``correction`` (0.5, at most 2): the largest correction of ``base``'s
      command, a fraction of the input limit.
    - ``plant_options`` (None): the plant's own settings, e.g.
      ``{"substep": 1e-5}`` (s) for Jahanpour et al.'s integration substep.
    - ``shop_floor`` (None): the machine as it is on the shop floor
      (:mod:`vcnc_gym.plants.shop_floor`): True for the documented defaults
      or a dict of effect parameters (encoder resolution and noise, command
      and sensor delays, the first structural mode, the cutting force,
      Stribeck friction) over them; their parameters are appended to the
      plant's (``randomize`` draws them), the observation shows the
      quantised, noisy, delayed reading and ``info`` keeps the true contour
      error.  The ``...Shop-v1`` and ``...Shop-v2`` ids set it.
    - ``max_episode_steps`` (None: the natural length): truncation, decisions.
    - ``render_mode``: None, "human" or "rgb_array" (matplotlib; Rendering).
    - ``render_every`` (None: about 30 pictures per simulated second, every 33
      decisions of 1 ms): the decisions between two new pictures (Rendering).

    ## Rendering

    ``render_mode="rgb_array"`` gives 800 x 360 RGB frames: the contour with the
    table's path, its contour error magnified, and the contour error over
    time; ``"human"`` shows them in a window.  ``metadata["render_fps"]`` is
    one frame per decision, ``1 / decision_period`` (1000 in v2): a video of
    one frame per step, as ``gymnasium.wrappers.RecordVideo`` records it
    (``pip install 'vcnc-gym[video]'`` for its moviepy), plays the episode in
    real time.  A new picture is drawn every ``render_every`` decisions and at
    the episode's end, the last one returned in between, so recording a
    whole v2 heart (3 222 decisions, a 3.2 s video) draws about a hundred
    pictures of a few milliseconds each (``python benchmarks/render_timing.py``).

    ## Pickling

    ``pickle.dumps(env)`` (and ``copy.deepcopy``, and Gymnasium's
    ``AsyncVectorEnv``) saves the constructor's arguments, the random
    generator and the episode state; the unpickled env, rebuilt from them,
    continues the same episode to the bit (:mod:`vcnc_gym.envs.pickling`).
    Pickling is not a change of behaviour: no id's version changes.

    ## Version History

    - v2: the learnable version of every contouring id (``VCNC-Heart-v2``,
      ``VCNC-HeartShop-v2``, ...; ``vcnc_gym.envs.registry.LEARNABLE_IDS``):
      the machine, contour, reference and episode end of its v1, with
      ``action="setpoint"``, ``action_repeat=10`` (a decision every 1 ms, 10 ms
      on the circle), ``observation_scale="unit"``, ``reward_scale`` 10 um and
      ``error_clip`` 100 um (2 um and 20 um on the circle).  Why: Stable-Baselines3's
      PPO with its default settings did not learn v1 (nor v0): every episode
      diverged at decision 1 603 of 32 212 (0.16 s of the heart's 3.2 s),
      return -1.5e7, with 4 envs and ``VecNormalize`` too (a value loss of
      9.9e11).  The causes: the divergence penalty (500 per remaining
      decision) was a million times a typical step reward; the raw
      observation spanned 1e9 (contour errors of 1e-6 mm beside
      accelerations of 1e3 mm/s^2, bounds of 1e6); a decision every 0.1 ms
      made 32 212 decisions a heart, so 20 000 steps were less than one
      episode; and the raw voltage let an untrained Gaussian policy leave the
      10 mm tracking bound at once.  A real feed drive closes its own servo
      loop and a CNC's outer loop commands set-points; v2 does the same.
      The v1 ids stay current for the classical controllers, which command
      the amplifier every control period.  Changes that alter no episode, in
      every version: ``info["episode_summary"]`` at every episode's end, the
      per-step keys named per step under the learnable actions, and
      ``reset(options={"parameters": info["parameters"]})`` accepted.
    - The ``...Shop-v1`` ids (``VCNC-HeartShop-v1``, ``VCNC-OmegaLookaheadShop-v1``,
      ``VCNC-CornersSmoothShop-v1``, ``VCNC-CircleShop-v1``) start at v1: the v1 env
      of their ideal id with ``shop_floor`` set; the ideal ids do
      not change.
    - v1: the episode ends when the table has reached the end of the
      contour (or at a completion time limit, with a penalty for the
      untraversed length), no longer 10 ms after the reference's end: a
      table lagging the reference was scored only on the part it had
      traversed.  The cycle time is in ``info``.  The observation gained the
      contour ahead of the table ("contour_preview", "contour_curvature").
      Purtojo et al.'s circle: contour shown 0.05-0.4 mm ahead, 2 um band, 1 s limit.
      Fixes that change no episode a valid configuration can reach, so no
      new version: a non-finite plant state is rewarded with the
      divergence penalty (was NaN); a preview beyond the contour's end, a
      ``max_episode_steps`` beyond the time limit, a contour that turns back
      on itself and plant parameters outside their physical range are
      refused (were clamped or accepted).
    - v0: initial release.  The plant became an argument, the step one
      batched kernel and the ids lost their fixed ``TimeLimit`` (the natural
      length now follows the configuration) without changing any episode of
      the default configuration.  Still registered (``episode_end=
      "reference"``, ``contour_ahead=()``) for the figures measured on it.
    """

    #: ``render_fps`` is the default configuration's (one frame per decision of 0.1 ms: real time); each env sets
    #: its own, ``1 / decision_period`` (:func:`~vcnc_gym.envs.rendering.render_fps`).
    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10000}

    def __init__(self, *, render_mode: str | None = None, render_every: int | None = None, **kwargs):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.task = ContouringTask(**kwargs)
        self.render_every = render_every_argument(render_every, self.task.decision_period)
        self.metadata = {**type(self).metadata, "render_fps": render_fps(self.task.decision_period)}
        self._batch = self._make_batch()
        b = self._batch.buffers
        self._obs = b.obs[0]
        self._action = b.action[0]
        self._info = b.info[0]
        self._flags = b.flags[0]
        self._mode = b.mode
        self._data = self._batch.data
        self._run = sk.step_serial
        self._k = b.k
        self._reward = b.reward
        self._dt = self.task.dt
        self.layout = self.task.layout
        self._decision = DecisionLoop(self.task, 1) if self.task.controlled else None
        self._scale = self.layout.scale_vector().astype(np.float32) if self.layout.is_scaled else None
        self.observation_space = observation_space(self.layout)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.parameters = self.task.nominal_parameters
        self._done = True
        self._warned_limit = False
        self._history: dict[str, list] | None = None  # the episode a render draws (rendering.EpisodeHistory)
        if getattr(self, "_renderer", None) is not None:  # a subclass that builds its env again (a new contour)
            self._renderer.close()  # pyright: ignore[reportOptionalMemberAccess]
        self._renderer = None if render_mode is None else Renderer(self.task, render_mode, self.render_every)

    def _make_batch(self) -> ContouringBatch:
        """The batch of one env this env steps (a subclass may give it its own reference buffer)."""
        return ContouringBatch(self.task, 1)

    # -- the task, read-only ----------------------------------------------------------
    plant = property(lambda self: self.task.plant, doc="The plant model (vcnc_gym.plants.PlantModel).")
    curve = property(lambda self: self.task.curve, doc="The contour, a NurbsCurve in mm.")
    contour_name = property(lambda self: self.task.contour_name, doc="Name of the contour or 'custom'.")
    reference = property(lambda self: self.task.reference, doc="The reference (motion.Reference), sampled at dt.")
    feedrate_profile = property(lambda self: self.task.feedrate_profile, doc="The feedrate profile.")
    projector = property(lambda self: self.task.projector, doc="The exact contour-error projector.")
    dt = property(lambda self: self.task.dt, doc="Control period in s.")
    action_repeat = property(lambda self: self.task.action_repeat, doc="Control periods per decision.")
    decision_period = property(lambda self: self.task.decision_period, doc="dt * action_repeat in s.")
    episode_steps = property(
        lambda self: self.task.episode_steps, doc="Natural episode length in decision steps (without divergence)."
    )
    nominal_parameters = property(
        lambda self: self.task.nominal_parameters, doc="The plant's nominal (2, P) parameters."
    )
    divergence_bound = property(lambda self: self.task.divergence_bound, doc="mm")
    tracking_bound = property(lambda self: self.task.tracking_bound, doc="mm")
    reward_scale = property(lambda self: self.task.reward_scale, doc="mm")
    randomize = property(lambda self: self.task.randomize, doc="A plant drawn at every reset.")

    @property
    def u_max(self) -> float:
        """The x axis' input limit that action 1.0 maps to, in ``plant.input_unit`` (5 V, Jahanpour et al.'s
        Table 3)."""
        return float(self.plant.input_limits(self.parameters)[0])

    # -- Gymnasium API ----------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start a pass along the contour; ``options={"parameters": array}`` sets the plant for this episode."""
        super().reset(seed=seed)
        self.parameters = self.task.parameters_for_reset(self.np_random, options)
        self._batch.reset_env(0, self.parameters, self.np_random)
        if self._decision is not None:
            self._decision.reset_env(0, self.parameters)
        self._done = False
        self._check_time_limit()
        self._batch.run()
        info = {
            "parameters": self.plant.to_dict(self.parameters),
            "dt": self.dt,
            "decision_period": self.decision_period,
            "episode_steps": self.episode_steps,
            "contour_length": self.reference.length,
            "feedrate_fluctuation": self.reference.feedrate_fluctuation,
        }
        if self.render_mode is not None:
            history = EpisodeHistory()
            history.start(self._info, sk.INFO_FIELDS)
            self._history = history.data
            self._renderer.restart()  # pyright: ignore[reportOptionalMemberAccess]
            if self.render_mode == "human":
                self.render()
        return self._observation(), info

    def _observation(self) -> np.ndarray:
        """The observation the agent sees: the kernel's, scaled, with the agent's own last action under the
        learnable action types."""
        obs = self._obs.copy()
        if self._decision is not None:
            obs[self.layout.slice("previous_action")] = self._decision.last_action[0]
        if self._scale is not None:
            obs /= self._scale
        return obs

    def step(self, action):
        """One decision: ``action`` (2,) held for ``action_repeat`` control periods (the class docstring's Action
        Space); returns ``(observation, reward, terminated, truncated, info)`` as Gymnasium's ``step``, with
        ``info["episode_summary"]`` at the episode's end."""
        if self._done:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        a = check_actions(action, (2,))
        self._mode[0] = sk.MODE_STEP
        d = self._decision
        if d is None:
            self._action[:] = a
            self._run(self._data)
            reward = float(self._reward[0])
        else:
            before = self._batch.buffers.episode[0].copy()
            d.set_actions(a[None])
            self._batch.run_controlled(d.controller, d.loop)
            reward = float(d.rewards()[0])
        flags = self._flags.tolist()
        terminated, truncated = flags[sk.FLAG_TERMINATED], flags[sk.FLAG_TRUNCATED]
        self._done = terminated or truncated
        info = step_info(self._info, flags, int(self._k[0]) * self._dt)
        if d is not None:
            decision_info(info, before, self._batch.buffers.episode[0], d.loop.peak[0])
        if self._done:
            info["episode_summary"] = episode_summary(self._batch.buffers, 0)
        if self._history is not None:
            EpisodeHistory(self._history).append(info["time"], self._info, sk.INFO_FIELDS)
            if self.render_mode == "human":
                self.render()
        return self._observation(), reward, terminated, truncated, info

    # -- pickling (vcnc_gym.envs.pickling) ----------------------------------------
    def _episode_arrays(self) -> dict[str, np.ndarray]:
        """Every array of the episode state the kernel reads and writes, by name (the ones a pickle saves)."""
        arrays = batch_arrays(self._batch)
        if self._decision is not None:
            arrays.update(self._decision.arrays())
        return arrays

    def _episode_state(self) -> dict:
        return {
            "np_random": self._np_random,
            "np_random_seed": self._np_random_seed,
            "spec": self.spec,
            "arrays": {name: a.copy() for name, a in self._episode_arrays().items()},
            "parameters": self.parameters,
            "done": self._done,
            "warned_limit": self._warned_limit,
            "history": self._history,
        }

    def _restore_episode(self, state: dict) -> None:
        restore_arrays(self._episode_arrays(), state["arrays"])
        self._np_random, self._np_random_seed, self.spec = state["np_random"], state["np_random_seed"], state["spec"]
        self.parameters, self._done = state["parameters"], state["done"]
        self._warned_limit, self._history = state["warned_limit"], state["history"]

    def _check_time_limit(self):
        limits = [self.task.max_episode_steps]
        if self.spec is not None and self.spec.max_episode_steps is not None:
            limits.append(self.spec.max_episode_steps)
        if min(limits) < self.episode_steps and not self._warned_limit:
            self._warned_limit = True
            gym.logger.warn(
                f"max_episode_steps={min(limits)} is shorter than this configuration's episode "
                f"({self.episode_steps} steps): episodes will be truncated before the end of the contour"
            )

    # -- rendering ------------------------------------------------------------------
    def render(self):
        """The episode so far: an RGB array (H, W, 3) uint8 with ``render_mode="rgb_array"`` (a new picture once
        ``render_every`` decisions have passed since the last, and at the episode's end; the last one, the same
        array, in between), the window updated with ``"human"`` (the env draws it every ``render_every``
        decisions itself)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        return self._renderer.render(self._history, self._done)  # pyright: ignore[reportOptionalMemberAccess]

    def close(self):
        if self._renderer is not None:
            self._renderer.close()


ContouringEnv.__init__.__signature__ = forwarded_signature(ContouringEnv.__init__, ContouringTask.__init__)

_REAL_KINDS = ("f", "i", "u")


def check_actions(action, shape: tuple) -> np.ndarray:
    """``action`` as a float64 array of ``shape``; ValueError for another shape, a non-real or non-finite value."""
    if type(action) is np.ndarray and action.shape == shape == (2,) and action.dtype.kind == "f":
        # the common case, cheaply: one env's float action
        if math.isfinite(action[0]) and math.isfinite(action[1]):
            return action
    a = np.asarray(action)
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape}, got {a.shape}")
    if a.dtype.kind not in "iuf" or a.dtype == np.bool_:
        raise ValueError(f"action must hold real numbers, got dtype {a.dtype}")
    a = a.astype(np.float64, copy=False)
    if not np.isfinite(a).all():
        raise ValueError(f"action must be finite, got {action!r}")
    return a


_SCALARS = tuple((key, col) for key, (col, width) in sk.INFO_FIELDS.items() if width == 1)
_VECTORS = tuple((key, col, col + width) for key, (col, width) in sk.INFO_FIELDS.items() if width > 1)


def observation_space(layout) -> spaces.Box:
    """The Box of one env's observation: the layout's bounds, divided by the fields' scales."""
    high = layout.high()
    if layout.is_scaled:
        high = (high / layout.scale_vector()).astype(np.float32)
    return spaces.Box(-high, high, dtype=np.float32)


def decision_info(info: dict, before: np.ndarray, after: np.ndarray, peak: float) -> None:
    """A learnable action type's per-decision contour error keys, named per step: ``step_contour_error_max`` and
    ``step_contour_error_mean`` (mm, over the decision's control periods) replace the kernel's last period's."""
    del info["contour_error_max"], info["contour_error_mean"]
    periods = after[sk.EPISODE_PERIODS] - before[sk.EPISODE_PERIODS]
    info["step_contour_error_max"] = float(peak)
    info["step_contour_error_mean"] = float((after[sk.EPISODE_SUM] - before[sk.EPISODE_SUM]) / max(periods, 1.0))


def step_info(info_arr: np.ndarray, flags: list, time: float) -> dict:
    """The info dict of one env's step from its kernel info row and flags (one copy; the arrays are views of it)."""
    row = info_arr.copy()
    values = row.tolist()
    info = {key: values[col] for key, col in _SCALARS}
    for key, start, stop in _VECTORS:
        info[key] = row[start:stop]
    info["observation_clipped"] = int(info["observation_clipped"])
    info["diverged"] = flags[sk.FLAG_DIVERGED]
    info["completed"] = flags[sk.FLAG_COMPLETED]
    if not info["completed"]:
        del info["cycle_time"]  # only once the tool has arrived
    info["time"] = time
    return info
