"""FeedOverrideEnv: contour following where the policy also turns the feed override dial."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from . import step_kernel as sk
from .contouring_env import ContouringEnv, check_actions
from .retiming import lookahead_dial, padded_reference, retime
from .signatures import forwarded_signature
from .task import ContouringBatch
from ..validation import flag, non_negative, positive, real, size

__all__ = [
    "FeedOverrideEnv",
    "DEFAULT_OVERRIDE_RATE",
    "DEFAULT_TIME_COST",
    "DEFAULT_TIME_LIMIT",
    "MAX_TIME_LIMIT",
    "DEFAULT_VIOLATION_COST",
    "DEFAULT_PROGRESS_REWARD",
    "TOLERANCES",
    "MAX_OVERRIDE",
]

#: How fast the override follows its dial, 1/s: the whole range in 0.1 s.  The re-timed reference's extra
#: acceleration, rate x feed, is then 1e3 mm/s^2 at 100 mm/s, within the ~2.6e3 mm/s^2 of Jahanpour et al.
#: (2014)'s +-5 V drives.
DEFAULT_OVERRIDE_RATE = 10.0

#: What a second of cycle time costs, as mm of contour error held over that second: 1 um.  The omega's S-curve
#: at 100 mm/s throws the strongest causal controller hundreds of um off at each 0.19 mm corner; its look-ahead
#: feed (0.99 s instead of 0.63 s) brings that to 1.4 um (README): at 1 um per second, slowing down pays where
#: the error is microns, not where it is nanometres.
DEFAULT_TIME_COST = 1e-3

#: The largest override a dial may reach, 1 = 100 %: a CNC's operator panel runs its feed override to 120-150 %
#: (Heidenhain's to 150 %), and the tolerance task's classical opponents are searched up to 1.5 times the
#: programmed feed (experiments/tolerance/tolerance.py).  ``max_override`` is 1.0 by default (the dial of v1).
MAX_OVERRIDE = 1.5

#: Largest time limit, times the reference's duration at full feed: an override held below 1 % is a feed hold,
#: not a feed (and the re-timed reference holds a row per control period up to the limit).
MAX_TIME_LIMIT = 100.0

#: The time limit, as a multiple of the reference's duration at full feed: an override held below 1/3 runs out
#: of time (and pays for the contour left).
DEFAULT_TIME_LIMIT = 3.0

#: The tolerance task's price of a decision step over the contour tolerance T, in decision steps of time: a step
#: T or more over T costs as much as 100 steps of cycle time (less in proportion below T of excess).  A first try
#: that priced the excess without a bound (1 full-feed cycle per T of excess per step) gave steps of -200 beside a
#: time term of -0.0016: the agents learned to crawl and ran out of time (reproduction.md, "The tolerance task").
DEFAULT_VIOLATION_COST = 100.0

#: The contour tolerances of the tolerance task, mm: Heidenhain's bands, 5-10 um for high accuracy and
#: 10-20 um for finishing.
TOLERANCES = (0.005, 0.01, 0.02)

#: The tolerance task's reward for progress along the contour, in full-feed cycles per contour: a potential-based
#: shaping (Ng, Harada and Russell 1999; its sum is the same on every finished episode), so that moving on is
#: paid when it happens and not only through the cycle time's end.  Without it the agents of a second try held the
#: dial near 0 and ran out of time (reproduction.md, "The tolerance task").
DEFAULT_PROGRESS_REWARD = 10.0


class FeedOverrideEnv(ContouringEnv):
    r"""Contour following with a feed override: the policy commands both axes and sets the override.

    ## Description

    :class:`~vcnc_gym.envs.ContouringEnv`'s task (by default Jahanpour et
    al. (2014)'s omega at 100 mm/s on the S-curve, ``VCNC-Omega-v1``, whose
    0.19 mm corners ask twenty times the drives' acceleration) with a third
    input: the feed override of a CNC's operator panel, 0 to 100 %.  The
    reference is re-timed online (:mod:`vcnc_gym.envs.retiming`): the path
    stays the same, the clock along it runs at the override, which moves
    toward the dial at ``override_rate`` per second.  The preview in the
    observation is the re-timed reference with the dial held (what the
    interpolator knows).  Each second until the tool arrives costs as much as
    ``time_cost`` mm of contour error held over it, so the policy trades
    contour error against cycle time.

    ## Action Space

    ``Box(-1, 1, (3,), float32)``:

    ===  ==============  ===  ===  ======================================
    Num  Action          Min  Max  Unit
    ===  ==============  ===  ===  ======================================
    0    x-axis command  -1   1    x the plant's input limit (5 V)
    1    y-axis command  -1   1    x the plant's input limit (5 V)
    2    feed override   -1   1    dial: override = m (a + 1) / 2, 0 to m
    ===  ==============  ===  ===  ======================================

    with ``m = max_override`` (1.0: 0 to 100 %).  With ``lookahead=(F, A)``
    the dial is the operator's override on a look-ahead, as on a CNC, 50 to
    150 %: the override in force follows ``min(m, (1 + a / 2) L(tau))``,
    ``L`` the override that makes the reference's feed the look-ahead's of
    top feed F (mm/s) and path acceleration A (mm/s^2) at the reference's
    clock ``tau`` (:func:`~vcnc_gym.envs.retiming.lookahead_dial`); a = 0 is
    the look-ahead itself.  The look-ahead plans within the dial's reach
    (``lookahead_reach=True``): its speed is at most ``m`` times the
    reference's own, so it starts and ends at rest as the reference does, at
    most at A.

    ## Observation Space

    ContouringEnv's, field by field (``env.unwrapped.layout``); the reference
    fields are the re-timed reference's (its velocity is the feed times the
    override).  ``info["override"]`` is the override in force (1 = 100 %),
    ``info["reference_time"]`` the re-timed clock (s along the original
    reference).

    ## Rewards

    ContouringEnv's, plus ``-time_cost / reward_scale`` per step until the
    tool arrives (``info["reward_time"]``): with the default 1 um and 10 um,
    0.1 per step, against 0.1 per step for each um of mean contour error.

    **The tolerance task** (``tolerance=T``, mm): the shortest
    cycle time within a contour tolerance, a shop's objective.  Every term
    is in decision steps of time, normalised by the reference's duration at
    full feed (``d``: the decision period over that duration, so a cycle at
    full feed sums to 1):

    - ``-d`` per step until the tool arrives (``info["reward_time"]``): the
      episode's sum is minus its cycle time in full-feed cycles;
    - ``-violation_cost * d * min(1, (e_max - T) / T)`` per step whose max
      contour error ``e_max`` exceeds T (``info["reward_tolerance"]``): with
      the default 100, a step T over T costs 100 steps of time;
    - ``progress_reward * (arc passed in the step) / (contour length)``
      (``info["reward_progress"]``, default 10): a potential-based shaping
      (Ng, Harada and Russell 1999) whose sum is ``progress_reward`` on every
      finished episode, so the ranking of finished episodes is the cycle
      time's and the excess's; it pays for moving on when it happens;
    - the ends priced as if what was left were over T: on divergence
      ``-violation_cost * d`` per decision step the contour had left, at the
      time limit ``-violation_cost`` times the fraction of the contour left
      (they replace ContouringEnv's divergence and time-limit terms, which
      are in um of contour error; ``info["reward_divergence"]``,
      ``info["reward_incomplete"]``).

    ContouringEnv's contour-error term is left out; its effort term stays.
    ``info["tolerance_exceeded"]`` says whether the step exceeded T and
    ``info["violations"]`` counts the episode's steps that did: exceeding T
    is a failure, counted and reported, not an end (the part is finished,
    and scrapped).

    ## Episode End

    ContouringEnv's, with the reference's end where the re-timed clock
    reaches it, and the completion time limit at ``time_limit`` times the
    reference's duration at full feed (an override held below
    1 / ``time_limit`` runs out of time and pays for the contour left).

    ## Arguments

    Every argument of ContouringEnv but ``completion_timeout`` (set by
    ``time_limit``), plus ``override_rate`` (1/s, 10: the whole range in 0.1
    s), ``max_override`` (1, 1.0: the dial's top, up to MAX_OVERRIDE, 1.5 =
    150 %), ``lookahead`` ((F mm/s, A mm/s^2), None: the dial alone),
    ``lookahead_reach`` (True; False: the tolerance ids' v1 look-ahead,
    at its top feed from the first sample),
    ``time_cost`` (mm, None: 0.001 without a tolerance; refused with
    one), ``time_limit`` (1, 3.0), ``tolerance`` (mm, None: the contouring
    reward; T: the tolerance task), ``violation_cost`` (decision steps of
    time per step over T, 100.0) and ``progress_reward`` (full-feed cycles
    per contour, 10.0), both with a tolerance only.

    ## Version History

    - v1 (``VCNC-OmegaOverride-v1``): initial release; the omega
      of ``VCNC-Omega-v1`` with the override.  The ``tolerance`` argument
      came later; its default, None, leaves the env as it was.
    - v1 (``VCNC-OmegaOverrideShop-v1``): initial release; the
      same omega on the shop floor (``shop_floor=True``), the tolerance
      task's shop-floor twin.  The ``max_override`` argument came
      later, and so did ``lookahead``; their defaults, 1.0 and None, leave
      both ids as they were.
    - v1 (``VCNC-OmegaTolerance-v1``, ``VCNC-OmegaToleranceShop-v1``):
      initial release; the tolerance task's own ids (registry).
    - v2 (``VCNC-OmegaTolerance-v2``, ``VCNC-OmegaToleranceShop-v2``): the
      look-ahead (a = 0) plans within the dial's reach and from rest
      (``lookahead_reach``).  In v1 it was at its top feed from the first
      sample and the dial, clipped at 150 %, ran the start at 1.5 times the
      S-curve's own ramp: 2.25 times its acceleration, beyond the look-ahead's
      A.  That start set v1's largest contour error (6.26 um of the nominal
      omega's at 150 mm/s and 1500 mm/s^2; 1.86 um after it), the look-ahead
      opponents' tolerance and the agents' starting point.  v1 stays
      registered (``LEGACY``) for the figures measured on it.
    - v1 (``VCNC-HeartTolerance-v1``, ``VCNC-HeartToleranceShop-v1``):
      initial release; the tolerance task on the heart, with v2's
      look-ahead.
    """

    #: Classical controllers that read the reference ahead from a table computed once (feedforward, ZPETC, the
    #: oracle) refuse this env: its reference is re-timed while it runs.
    retimes_reference = True

    def __init__(
        self,
        *,
        override_rate: float = DEFAULT_OVERRIDE_RATE,
        max_override: float = 1.0,
        lookahead: tuple[float, float] | None = None,
        lookahead_reach: bool = True,
        time_cost: float | None = None,
        time_limit: float = DEFAULT_TIME_LIMIT,
        tolerance: float | None = None,
        violation_cost: float = DEFAULT_VIOLATION_COST,
        progress_reward: float = DEFAULT_PROGRESS_REWARD,
        render_mode: str | None = None,
        **kwargs,
    ):
        if "completion_timeout" in kwargs:
            raise ValueError(
                "completion_timeout (s) is set by time_limit (a multiple of the reference's duration "
                "at full feed) in FeedOverrideEnv"
            )
        self.override_rate = positive("override_rate", override_rate, "1/s")  # bool and str refused
        self.max_override = real("max_override", max_override, "x the programmed feed")
        if not 1.0 <= self.max_override <= MAX_OVERRIDE:
            raise ValueError(
                f"max_override must be in [1, {MAX_OVERRIDE:g}] (the dial's top, x the programmed feed: "
                f"a CNC's panel reaches 120-150 %), got {max_override!r}"
            )
        if lookahead is not None:
            if not isinstance(lookahead, (tuple, list)) or len(lookahead) != 2:
                raise ValueError(
                    f"lookahead must be None or a pair (top feed mm/s, path acceleration mm/s^2), got {lookahead!r}"
                )
            lookahead = (
                positive("lookahead[0]", lookahead[0], "mm/s (top feed)"),
                positive("lookahead[1]", lookahead[1], "mm/s^2 (path acceleration)"),
            )
        self.lookahead = lookahead
        self.lookahead_reach = flag("lookahead_reach", lookahead_reach)
        self.tolerance = None if tolerance is None else positive("tolerance", tolerance, "mm of contour error")
        self.violation_cost = non_negative("violation_cost", violation_cost, "decision steps of time per step over T")
        self.progress_reward = non_negative("progress_reward", progress_reward, "full-feed cycles per contour")
        if self.tolerance is not None and time_cost is not None:
            raise ValueError(
                "time_cost (mm of contour error per second) prices the contouring reward; with a "
                "tolerance the time term is the cycle time itself: leave time_cost out"
            )
        if self.tolerance is None:
            time_cost = DEFAULT_TIME_COST if time_cost is None else time_cost
            self.time_cost = non_negative("time_cost", time_cost, "mm of contour error per second")
        else:
            self.time_cost = None
        self.time_limit = real("time_limit", time_limit, "times the reference's duration at full feed")
        if not 1.0 <= self.time_limit <= MAX_TIME_LIMIT:
            raise ValueError(
                f"time_limit must be in [1, {MAX_TIME_LIMIT:g}] (times the reference's duration at "
                f"full feed; MAX_TIME_LIMIT: an override below 1 % is a feed hold), got {time_limit!r}"
            )
        probe = ContouringEnv(**kwargs)  # the reference's duration at full feed sets the time limit
        duration = float(probe.task.reference.t[-1])
        columns = probe.task.reference_arrays.samples.shape[1]
        dt = probe.task.dt
        probe.close()
        # the re-timed reference (and its copy) hold a row per control period up to the time limit: checked
        # against the memory before they are made
        size(
            f"time_limit={self.time_limit:g}: the re-timed reference's rows",
            math.ceil(self.time_limit * duration / dt) + 2,
            bytes_each=2 * 8 * columns,
            why="a row per control period up to the time limit",
        )
        super().__init__(render_mode=render_mode, completion_timeout=(self.time_limit - 1.0) * duration, **kwargs)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self._tau = 0.0
        self._speed = 1.0
        self._violations = 0
        self._progress = 0.0
        #: the time term of the tolerance task per decision step: the decision period over the full-feed duration
        self._step_time = self.task.action_repeat * dt / duration
        self._length = float(self.task.reference_arrays.samples[-1, sk.REF_ARC])  # mm of contour
        #: the look-ahead's override per sample of the original reference (None: the dial alone)
        self._planned = None if lookahead is None else self.lookahead_override(*lookahead)

    def lookahead_override(self, feed: float, acceleration: float) -> np.ndarray:
        """The override that makes this env's reference a look-ahead's of top feed ``feed`` (mm/s) and path
        acceleration ``acceleration`` (mm/s^2), per sample of the reference, within [0, ``max_override``]
        (:func:`~vcnc_gym.envs.retiming.lookahead_dial`, within the dial's reach unless ``lookahead_reach`` is
        False): what ``lookahead=(feed, acceleration)`` turns the dial to."""
        feed = positive("feed", feed, "mm/s (top feed)")
        acceleration = positive("acceleration", acceleration, "mm/s^2 (path acceleration)")
        reach = self.max_override if self.lookahead_reach else None
        return np.minimum(lookahead_dial(self._original, feed, acceleration, reach=reach), self.max_override)

    def _make_batch(self) -> ContouringBatch:
        task = self.task
        self._original = task.reference_arrays.samples
        self._lookahead = task.action_repeat + int(max(task.layout.preview_steps, default=0))
        # rows for every period up to the time limit and its preview, then the contour's end, never re-timed:
        # the kernel reads the last row as the end of the reference (the contour left, the completion)
        self._padded = padded_reference(self._original, task.end_index + self._lookahead + 2)
        self._buffer = self._padded.copy()
        return ContouringBatch(task, 1, reference=task.reference_arrays._replace(samples=self._buffer))

    @property
    def override(self) -> float:
        """The feed override in force, 1 = 100 %."""
        return self._speed

    def reset(self, *, seed: int | None = None, options=None):
        """As ContouringEnv's, the override at 100 % and the reference at its original timing."""
        self._buffer[:] = self._padded
        self._tau = 0.0
        self._speed = 1.0
        self._violations = 0
        self._progress = 0.0
        obs, info = super().reset(seed=seed, options=options)
        self._batch.buffers.reference_end[0] = np.iinfo(np.int64).max  # until the re-timed clock gets there
        return obs, info

    def _episode_arrays(self) -> dict[str, np.ndarray]:
        return {**super()._episode_arrays(), "reference.samples": self._buffer}  # the re-timed reference

    def _episode_state(self) -> dict:
        return {
            **super()._episode_state(),
            "tau": self._tau,
            "speed": self._speed,
            "violations": self._violations,
            "progress": self._progress,
        }

    def _restore_episode(self, state: dict) -> None:
        super()._restore_episode(state)
        self._tau, self._speed, self._violations = state["tau"], state["speed"], state["violations"]
        self._progress = state["progress"]

    def step(self, action):
        """One decision: ``action`` (3,), the axes' normalised commands and the feed override dial (the class
        docstring's Action Space); returns ``(observation, reward, terminated, truncated, info)`` as Gymnasium's
        ``step``."""
        if self._done:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        a = check_actions(action, (3,))
        a2 = min(1.0, max(-1.0, float(a[2])))
        if self._planned is None:
            dial = self.max_override * 0.5 * (a2 + 1.0)
        else:  # the operator's override (50-150 %) on the look-ahead, at the reference's clock
            j = min(int(self._tau), self._planned.size - 2)
            f = self._tau - j
            dial = min(self.max_override, (1.0 + 0.5 * a2) * ((1.0 - f) * self._planned[j] + f * self._planned[j + 1]))
        task = self.task
        k = int(self._k[0])
        self._tau, self._speed, end = retime(
            self._original,
            self._buffer,
            k + 1,
            self._lookahead,
            task.action_repeat,
            self._tau,
            self._speed,
            dial,
            self.override_rate * task.dt,
            task.dt,
        )
        if end >= 0:
            self._batch.buffers.reference_end[0] = end
        obs, reward, terminated, truncated, info = super().step(a[:2])
        info["override"] = self._speed
        info["reference_time"] = self._tau * task.dt
        if self.tolerance is not None:
            return obs, self._tolerance_reward(info), terminated, truncated, info
        r_time = -self.time_cost / task.reward_scale  # pyright: ignore[reportOptionalOperand]  (set without a tolerance)
        info["reward_time"] = r_time
        return obs, reward + r_time, terminated, truncated, info

    def _tolerance_reward(self, info: dict) -> float:
        """The tolerance task's reward (Rewards): time, the excess over T and the ends, in decision steps of time."""
        task, d, cost = self.task, self._step_time, self.violation_cost
        excess = max(0.0, info["contour_error_max"] - self.tolerance)
        exceeded = excess > 0.0
        self._violations += exceeded
        r_time = -d  # a step is taken only before the tool has arrived
        r_tolerance = -cost * d * min(1.0, excess / self.tolerance)  # pyright: ignore[reportOperatorIssue]  (the tolerance task)
        # the kernel's ends, in um of contour error, turned into steps over T: the steps the contour had left, the
        # fraction of the contour left
        steps_left = -info["reward_divergence"] * task.reward_scale / task.divergence_bound
        r_divergence = -cost * d * steps_left
        r_incomplete = -cost * (-info["reward_incomplete"] * task.reward_scale) / self._length
        r_progress = self.progress_reward * (info["progress"] - self._progress) / self._length
        self._progress = info["progress"]
        info.update(
            reward_time=r_time,
            reward_tolerance=r_tolerance,
            reward_divergence=r_divergence,
            reward_incomplete=r_incomplete,
            reward_progress=r_progress,
            tolerance_exceeded=exceeded,
            violations=self._violations,
        )
        return r_time + r_tolerance + r_progress + r_divergence + r_incomplete + info["reward_effort"]


FeedOverrideEnv.__init__.__signature__ = forwarded_signature(
    FeedOverrideEnv.__init__, ContouringEnv.__init__, drop=("completion_timeout",)
)
