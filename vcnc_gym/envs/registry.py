"""The suite's env ids: the one table they are registered from.

``import vcnc_gym`` registers every entry of :data:`SUITE` with Gymnasium,
with its single-env entry point (``gym.make``) and, where it has one, its
native vector entry point (``gym.make_vec(..., vectorization_mode=
"vector_entry_point")``).  No id registers a fixed ``max_episode_steps``: an
env's natural length follows its configuration (``env.unwrapped.episode_steps``).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field

from gymnasium.envs.registration import register, registry

__all__ = [
    "LEARNABLE",
    "LEARNABLE_IDS",
    "SuiteEnv",
    "SUITE",
    "LEGACY",
    "env_name",
    "ENV_IDS",
    "CONTOURING_IDS",
    "VECTOR_IDS",
    "register_envs",
    "suite_env",
]

_CONTOURING = "vcnc_gym.envs.contouring_env:ContouringEnv"
_CONTOURING_VECTOR = "vcnc_gym.envs.contouring_vector_env:ContouringVectorEnv"
_GCODE = "vcnc_gym.envs.gcode_env:GCodeEnv"
_GCODE_VECTOR = "vcnc_gym.envs.gcode_env:GCodeVectorEnv"
_RANDOM = "vcnc_gym.envs.random_contour_env:RandomContourEnv"
_OVERRIDE = "vcnc_gym.envs.feed_override_env:FeedOverrideEnv"
#: The tolerance task's ids: T = 10 um by default, the dial to 150 % (``MAX_OVERRIDE``) at 26/s (the
#: re-timed reference's extra acceleration at the omega's 100 mm/s is then 2600 mm/s^2, the top of the look-ahead
#: opponents' grid and about Jahanpour et al. (2014)'s drives' limit), the operator's override on a look-ahead as on a
#: CNC: the look-ahead through the dial (``lookahead``, top feed 150 mm/s, path acceleration 1937.5 mm/s^2, within the
#: dial's reach and from rest) is the fastest within 10 um on the nominal plant of the ideal omega (``python
#: experiments/tolerance/override_schedule.py --id VCNC-OmegaTolerance-v2``, refined by bisection).  With
#: VCNC-OmegaOverride-v1's dial alone (to 100 % at 10/s) three tries of agents took 1.08 s where the opponents take
#: 0.68 (experiments/tolerance/README.md).
_TOLERANCE = {"tolerance": 0.01, "max_override": 1.5, "override_rate": 26.0, "lookahead": (150.0, 1937.5)}
#: v1 of the omega's tolerance ids (``LEGACY``): the look-ahead at its top feed from the first sample, at the
#: 1500 mm/s^2 that v1's unrefined search found the fastest within 10 um.
_TOLERANCE_V1 = {"lookahead": (150.0, 1500.0), "lookahead_reach": False}
#: The heart's tolerance ids: the same dial, on the look-ahead that the bisection of ``python
#: experiments/tolerance/override_schedule.py --id VCNC-HeartTolerance-v1`` found the fastest within 10 um on the heart's
#: nominal plant (9.54 um in 2.1832 s; its per-plant refinement later found 2267 mm/s^2, 9.64 um, 0.3 ms faster).
_HEART_TOLERANCE = {**_TOLERANCE, "lookahead": (150.0, 2262.5)}


@dataclass(frozen=True)
class SuiteEnv:
    """One registered id: its keyword arguments, a one-line summary, its entry points."""

    id: str
    kwargs: dict = field(default_factory=dict)
    summary: str = ""
    entry_point: str = _CONTOURING
    vector_entry_point: str | None = _CONTOURING_VECTOR

    @property
    def contouring(self) -> bool:
        """True for a contour-following env (ContouringEnv): reward = -contour error along a contour."""
        return self.entry_point in (_CONTOURING, _GCODE)


#: The circle of Purtojo et al. is 1 mm across and driven at 1 mm/s: its contour is
#: shown 50-400 um ahead, arrives within 2 um (twice its sensor's 1 um) and is
#: given 1 s after the reference's end.
_CIRCLE = {
    "contour": "circle",
    "plant": "nct_xy_table",
    "profile": "constant",
    "feedrate": 1.0,
    "dt": 1e-3,
    "reward_scale": 1e-3,
    "tracking_bound": 0.5,
    "divergence_bound": 0.5,
}
_CIRCLE_V1 = {"contour_ahead": (0.05, 0.1, 0.2, 0.4), "completion_tolerance": 0.002, "completion_timeout": 1.0}

#: Purtojo et al.'s table on the shop floor (vcnc_gym.plants.shop_floor): its own 1 um sensor with 0.2 um of noise; no
#: cutting force (1 N is 1.3 u_r on its 10 kg carriage, beyond the motor's rating: a plotting or engraving table);
#: Stribeck friction of 0.05 N (7 % of the rated input), fading over 0.5 mm/s.
_CIRCLE_SHOP = {
    "encoder_resolution": 1e-3,
    "noise_std": 2e-4,
    "cutting_force": 0.0,
    "cutting_ripple": 0.0,
    "stribeck_force": 0.05,
    "stribeck_velocity": 0.5,
}

#: Every current env id of the suite (the contouring ids at v1: see ContouringEnv's Version History).
SUITE: tuple[SuiteEnv, ...] = (
    SuiteEnv(
        "VCNC-Heart-v1",
        {"contour": "heart", "plant": "vcnc_feed_drive"},
        "Jahanpour et al.'s 'heart' (cubic NURBS, 310 mm) at 100 mm/s on their feed drives",
    ),
    SuiteEnv(
        "VCNC-Omega-v1",
        {"contour": "omega", "plant": "vcnc_feed_drive"},
        "Jahanpour et al.'s 'omega' (quadratic NURBS, 51 mm, 0.19 mm corners) at 100 mm/s on their feed drives",
    ),
    SuiteEnv(
        "VCNC-HeartLookahead-v1",
        {"contour": "heart", "plant": "vcnc_feed_drive", "profile": "lookahead"},
        "the heart with a CNC look-ahead feed (100 mm/s, normal acceleration and jerk within Jahanpour et al.'s "
        "drives' reach): the classical baselines on a feasible reference",
    ),
    SuiteEnv(
        "VCNC-OmegaLookahead-v1",
        {"contour": "omega", "plant": "vcnc_feed_drive", "profile": "lookahead"},
        "the omega with a CNC look-ahead feed: its 0.19 mm corners at 10 mm/s, 0.99 s instead of 0.63 s",
    ),
    SuiteEnv(
        "VCNC-Corners-v1",
        {"contour": "corners", "plant": "current_feed_drive", "profile": "constant", "feedrate": 50.0},
        "Simba et al.'s test path (corners of 30, 60, 90 deg, sharp) at a constant 50 mm/s on their drives",
    ),
    SuiteEnv(
        "VCNC-CornersSmooth-v1",
        {"contour": "corners-smooth", "plant": "current_feed_drive", "profile": "jlap", "feedrate": 50.0},
        "Simba et al.'s test path, corners smoothed by quintic Bezier blends (50 um), jerk-limited 50 mm/s",
    ),
    SuiteEnv(
        "VCNC-Circle-v1",
        {**_CIRCLE, **_CIRCLE_V1},
        "Purtojo et al.'s circle, R = 1 mm at 1 mm/s (x = sin t, y = cos t), on their NCT-identified X-Y table",
    ),
    SuiteEnv(
        "VCNC-HeartShop-v1",
        {"contour": "heart", "plant": "vcnc_feed_drive", "shop_floor": True},
        "the heart on Jahanpour et al.'s drives on the shop floor: 0.1 um encoder with noise, a period of delay, "
        "a 150 Hz mode, a milling force and Stribeck friction (vcnc_gym.plants.shop_floor's defaults)",
    ),
    SuiteEnv(
        "VCNC-OmegaLookaheadShop-v1",
        {"contour": "omega", "plant": "vcnc_feed_drive", "profile": "lookahead", "shop_floor": True},
        "the look-ahead omega on Jahanpour et al.'s drives on the shop floor (the defaults)",
    ),
    SuiteEnv(
        "VCNC-CornersSmoothShop-v1",
        {
            "contour": "corners-smooth",
            "plant": "current_feed_drive",
            "profile": "jlap",
            "feedrate": 50.0,
            "shop_floor": True,
        },
        "Simba et al.'s smoothed corners on their drives on the shop floor (the defaults)",
    ),
    SuiteEnv(
        "VCNC-CircleShop-v1",
        {**_CIRCLE, **_CIRCLE_V1, "shop_floor": _CIRCLE_SHOP},
        "Purtojo et al.'s circle on their X-Y table with a noisy 1 um sensor, a period of delay, a 150 Hz mode "
        "and Stribeck friction, no cutting force (a light table: see _CIRCLE_SHOP)",
    ),
    SuiteEnv(
        "VCNC-GCode-v1",
        {"program": "iso230-4-ccw"},
        "a G-code part program (program=, text or path; default the ISO 230-4 circle, 50 mm at 3000 mm/min) "
        "on Jahanpour et al.'s feed drives: G01/G02/G03, Simba et al.'s corner blends at tolerance= mm, "
        "look-ahead feeds",
        entry_point=_GCODE,
        vector_entry_point=_GCODE_VECTOR,
    ),
    SuiteEnv(
        "VCNC-ISO230Circle-v1",
        {"program": "iso230-4-ccw"},
        "ISO 230-4 circular test, 50 mm diameter at 3000 mm/min counter-clockwise (the CW run: program="
        "'iso230-4-cw'), on Jahanpour et al.'s feed drives",
        entry_point=_GCODE,
        vector_entry_point=_GCODE_VECTOR,
    ),
    SuiteEnv(
        "VCNC-CircleDiamondSquare-v1",
        {"program": "circle-diamond-square"},
        "NAS 979 / ISO 10791-7 circle-diamond-square (60 mm square, 6000 mm/min, 10 um blends) on "
        "Jahanpour et al.'s feed drives",
        entry_point=_GCODE,
        vector_entry_point=_GCODE_VECTOR,
    ),
    SuiteEnv(
        "VCNC-Butterfly-v1",
        {"program": "butterfly"},
        "butterfly free-form as G-code biarcs (78 mm, 3000 mm/min) on Jahanpour et al.'s feed drives",
        entry_point=_GCODE,
        vector_entry_point=_GCODE_VECTOR,
    ),
    # not a CONTOURING_ID: its contour (env.unwrapped.task) changes at every reset, which those ids' tests rule out
    SuiteEnv(
        "VCNC-RandomContour-v1",
        {},
        "a new contour at every reset (random G-code: lines with Simba et al.'s blends, arcs; 33-100 mm/s "
        "look-ahead) on Jahanpour et al.'s feed drives; make_vec gives SyncVectorEnv, each env its own contours",
        entry_point=_RANDOM,
        vector_entry_point=None,
    ),
    # not a CONTOURING_ID either: a third action, the feed override (the classical ids' controllers take two)
    SuiteEnv(
        "VCNC-OmegaOverride-v1",
        {"contour": "omega", "plant": "vcnc_feed_drive"},
        "VCNC-Omega-v1 with a feed override (0-100 %) as a third action: the reference re-timed online, "
        "cycle time in the reward",
        entry_point=_OVERRIDE,
        vector_entry_point=None,
    ),
    SuiteEnv(
        "VCNC-OmegaOverrideShop-v1",
        {"contour": "omega", "plant": "vcnc_feed_drive", "shop_floor": True},
        "VCNC-OmegaOverride-v1 on the shop floor (vcnc_gym.plants.shop_floor's defaults): the tolerance task's "
        "shop-floor twin (tolerance=T)",
        entry_point=_OVERRIDE,
        vector_entry_point=None,
    ),
    # the tolerance task's own ids: the dial reaches the feeds and path accelerations the task's classical
    # opponents are searched over (experiments/tolerance/tolerance.py: up to 1.5 x the programmed feed and 2600 mm/s^2)
    SuiteEnv(
        "VCNC-OmegaTolerance-v2",
        {"contour": "omega", "plant": "vcnc_feed_drive", **_TOLERANCE},
        "the tolerance task on VCNC-OmegaOverride-v1's omega: the shortest cycle within T (10 um; tolerance=T), "
        "the operator's override (50-150 %, at 26/s) on a look-ahead of "
        f"{_TOLERANCE['lookahead'][0]:g} mm/s and {_TOLERANCE['lookahead'][1]:g} mm/s^2 from rest",
        entry_point=_OVERRIDE,
        vector_entry_point=None,
    ),
    SuiteEnv(
        "VCNC-OmegaToleranceShop-v2",
        {"contour": "omega", "plant": "vcnc_feed_drive", "shop_floor": True, **_TOLERANCE},
        "VCNC-OmegaTolerance-v2 on the shop floor (vcnc_gym.plants.shop_floor's defaults)",
        entry_point=_OVERRIDE,
        vector_entry_point=None,
    ),
    SuiteEnv(
        "VCNC-HeartTolerance-v1",
        {"contour": "heart", "plant": "vcnc_feed_drive", **_HEART_TOLERANCE},
        "the tolerance task on Jahanpour et al.'s heart (310 mm, 100 mm/s programmed) on their drives: the "
        "shortest cycle within T (10 um; tolerance=T), the operator's override (50-150 %, at 26/s) on a "
        f"look-ahead of {_HEART_TOLERANCE['lookahead'][0]:g} mm/s and {_HEART_TOLERANCE['lookahead'][1]:g} mm/s^2 "
        "from rest",
        entry_point=_OVERRIDE,
        vector_entry_point=None,
    ),
    SuiteEnv(
        "VCNC-HeartToleranceShop-v1",
        {"contour": "heart", "plant": "vcnc_feed_drive", "shop_floor": True, **_HEART_TOLERANCE},
        "VCNC-HeartTolerance-v1 on the shop floor (vcnc_gym.plants.shop_floor's defaults)",
        entry_point=_OVERRIDE,
        vector_entry_point=None,
    ),
    SuiteEnv(
        "VCNC-Step-v0",
        {"plant": "cncmt_axis"},
        "Yadav et al.'s step response: a 10 mm set-point on both axes of the CNCMT axis with its 0.1 s dead time",
        entry_point="vcnc_gym.envs.positioning_env:PositioningEnv",
        vector_entry_point=None,
    ),
)

#: What made a contouring id v0: its episode ended 10 ms after the reference's
#: end, and its observation had no contour preview.
_V0 = {"episode_end": "reference", "contour_ahead": ()}

#: The v0 contouring ids, still registered for the figures measured on them (the papers' tables in
#: docs/papers/, ``benchmarks/train_throughput.py``); no agent is shipped on them (``agents/trained``
#: holds agents of current ids only) and ``vcnc-bench`` runs the current ids.
LEGACY: tuple[SuiteEnv, ...] = tuple(
    SuiteEnv(
        e.id.replace("-v1", "-v0"),
        {**{k: v for k, v in e.kwargs.items() if k not in _CIRCLE_V1}, **_V0},
        e.summary + " (v0: ends with the reference, no contour preview)",
    )
    for e in SUITE
    if e.contouring
    and e.kwargs.get("profile") != "lookahead"
    and e.entry_point == _CONTOURING
    and "shop_floor" not in e.kwargs
)

#: The tolerance ids' v1, still registered for the figures measured on them (experiments/tolerance/README.md, the
#: fourth to the sixth try): their look-ahead at its top feed from the first sample (FeedOverrideEnv's
#: Version History).
LEGACY = LEGACY + tuple(
    SuiteEnv(
        e.id.replace("-v2", "-v1"),
        {**e.kwargs, **_TOLERANCE_V1},
        e.summary.replace("-v2", "-v1").split(": the shortest")[0]
        + f": v2's task on a look-ahead of {_TOLERANCE_V1['lookahead'][0]:g} mm/s and "
        f"{_TOLERANCE_V1['lookahead'][1]:g} mm/s^2 at its top feed from the first sample",
        entry_point=e.entry_point,
        vector_entry_point=None,
    )
    for e in SUITE
    if e.id.startswith("VCNC-OmegaTolerance")
)

#: What makes a contouring id's v2 learnable by a standard RL algorithm with its default settings (ContouringEnv's
#: Version History): the drive's servo closed inside the step and a set-point correction as the action, a decision
#: every 10 control periods (1 ms at the 0.1 ms of Jahanpour et al.'s and Simba et al.'s drives), the observation
#: scaled to order one by fixed constants, and a reward of -(contour error / 10 um) clipped at 100 um (-10 a
#: decision).  The clip lies above what the drive's servo alone leaves on every feasible contour (43-47 um at the
#: peaks of the shop-floor heart, omega and smoothed corners; ``benchmarks/learnability.py`` prints it), so an agent
#: that lowers a peak is paid for it; at 10 um (the tolerance task's T) the reward saturated at those peaks, and
#: SB3's PPO with its defaults left the shop-floor heart's max at 41.6 um after 1 M steps (12.0 um with the clip at
#: 100 um after 300 000).
_LEARNABLE = {
    "action": "setpoint",
    "action_repeat": 10,
    "observation_scale": "unit",
    "reward_scale": 0.01,
    "error_clip": 0.1,
}
#: Purtojo et al.'s circle (1 mm across at 1 mm/s, 1 ms control period): a decision every 10 ms, and the reward's
#: scale and clip five times finer (2 um and 20 um), for contour errors of 0.7-2.3 um under the servo alone.
_LEARNABLE_CIRCLE = {**_LEARNABLE, "reward_scale": 0.002, "error_clip": 0.02}

#: The learnable version (v2) of every contouring id: the same machine, contour, reference and episode end as its
#: v1, with the interface of :data:`_LEARNABLE`.  The v1 ids stay current for the classical controllers, which
#: command the amplifier every control period (``action="voltage"``) and read the physical observation.
LEARNABLE: tuple[SuiteEnv, ...] = tuple(
    SuiteEnv(
        e.id.replace("-v1", "-v2"),
        {**e.kwargs, **(_LEARNABLE_CIRCLE if e.kwargs.get("plant") == "nct_xy_table" else _LEARNABLE)},
        e.summary
        + "; learnable: a set-point correction to the drive's servo every "
        + ("10 ms" if e.kwargs.get("plant") == "nct_xy_table" else "1 ms")
        + ", a scaled observation, a clipped reward",
        entry_point=e.entry_point,
        vector_entry_point=e.vector_entry_point,
    )
    for e in SUITE
    if e.contouring
)

#: The learnable ids (v2), in the order of :data:`SUITE`.
LEARNABLE_IDS: tuple[str, ...] = tuple(e.id for e in LEARNABLE)

#: The current ids, in the order of :data:`SUITE`.
ENV_IDS: tuple[str, ...] = tuple(e.id for e in SUITE)

#: The contour-following ids (ContouringEnv), a subset of :data:`ENV_IDS`.
CONTOURING_IDS: tuple[str, ...] = tuple(e.id for e in SUITE if e.contouring)

#: The ids with a native vector env (``gym.make_vec(..., vectorization_mode="vector_entry_point")``).
VECTOR_IDS: tuple[str, ...] = tuple(e.id for e in SUITE if e.vector_entry_point is not None)


def env_name(env_id: str) -> str:
    """The id without its version: ``"VCNC-Heart-v1"`` -> ``"VCNC-Heart"``."""
    name, sep, version = env_id.rpartition("-v")
    return name if sep and version.isdigit() else env_id


def suite_env(env_id: str) -> SuiteEnv:
    """The :class:`SuiteEnv` of ``env_id`` (current or :data:`LEGACY`); ValueError naming the valid ids otherwise."""
    for e in SUITE + LEARNABLE + LEGACY:
        if e.id == env_id:
            return e
    raise ValueError(f"unknown env id {env_id!r}; valid ids are {', '.join(ENV_IDS)}")


def register_envs() -> None:
    """Register every id of :data:`SUITE`, :data:`LEARNABLE` and :data:`LEGACY` (once).

    ``gym.make`` notes that an id is out of date when a later version of its name is registered.  A current v1
    contouring id is not: it is the classical controllers' interface of the task whose v2 is the learnable one, so
    the note is silenced for the ids of :data:`SUITE` only (a v0 id still gets it)."""
    for e in SUITE + LEARNABLE + LEGACY:
        if e.id not in registry:
            register(id=e.id, entry_point=e.entry_point, vector_entry_point=e.vector_entry_point, kwargs=dict(e.kwargs))
    current = "|".join(re.escape(e.id) for e in SUITE)
    warnings.filterwarnings(
        "ignore", message=rf".*The environment ({current}) is out of date", category=DeprecationWarning
    )
