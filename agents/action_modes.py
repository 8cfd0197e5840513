"""What the agent's action means: the amplifier command ("direct") or a correction of a baseline's ("residual").

Two action modes, one description (:class:`ActionMode`) shared by training and
evaluation:

- **direct**: the agent's action is the normalised amplifier command
  u / u_max of both axes.  Its decision period is the env's own
  ``action_repeat`` (an env argument: ``gym.make(id, action_repeat=10)``),
  held inside the env's jitted step.
- **residual**: the agent's action a in [-1, 1]^2 corrects a classical
  baseline of the :mod:`vcnc_baselines` package::

      u / u_max = clip(u_baseline(obs_k) / u_max + correction * a, -1, 1)

  The baseline runs at every control period dt on the fresh observation; the
  agent decides every ``action_repeat`` control periods and its correction is
  held in between.  This is the :class:`ResidualAction` wrapper, which needs
  an env with ``action_repeat=1``.

:class:`ActionMode` turns a run's configuration into either form: a wrapper
for training (:meth:`ActionMode.wrap`) and a per-control-period command for
evaluating a trained agent on the plain env (:meth:`ActionMode.command`), so
an agent is benchmarked on the very env the baselines run on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from vcnc_gym.envs.history import DecisionHistory
from vcnc_gym.validation import real

__all__ = ["ActionMode", "ResidualAction", "PeakPrice", "DialSlew", "ACTION_MODES", "RESIDUAL_OPTIONS"]

#: The action modes and what the agent's action is in each.
ACTION_MODES = {
    "direct": "the normalised amplifier command u / u_max of both axes",
    "residual": "a correction, scaled by `correction`, added to a baseline's normalised command",
}


def _check_repeat(action_repeat) -> int:
    if isinstance(action_repeat, bool) or not isinstance(action_repeat, (int, np.integer)) or action_repeat < 1:
        raise ValueError(f"action_repeat must be an integer >= 1, got {action_repeat!r}")
    return int(action_repeat)


#: The fields of :class:`ActionMode` that only the residual mode takes (a config entry's wrapper arguments and
#: ``vcnc-train``'s options of the same names, besides ``action_repeat``).
RESIDUAL_OPTIONS = ("baseline", "correction", "history", "peak_weight", "dial_rate")

#: Most past decisions a residual agent may remember (ours): each adds the remembered fields (about ten entries) to
#: its observation, for every env of a batch, and the network's input grows alike; an episode is a few thousand
#: decisions, and the memories that help span a mode's period or two (8 decisions on the heart).
MAX_HISTORY = 1000


@dataclass(frozen=True)
class ActionMode:
    """How an agent's action becomes the amplifier command.

    Parameters
    ----------
    mode : str
        "direct" or "residual" (:data:`ACTION_MODES`).
    action_repeat : int
        Control periods per agent decision (>= 1).
    baseline : str
        Residual mode: the baseline name of :func:`vcnc_baselines.names` ("smc", "qft", ...).
    correction : float
        Residual mode: the largest correction, as a fraction of u_max (0 < correction <= 2).
    baseline_params : dict
        Residual mode: constructor parameters of the baseline (its paper's values if empty).
    history : int
        Residual mode: the past decisions the agent remembers (:mod:`vcnc_gym.envs.history`: their commands, errors,
        velocities and reference accelerations follow the env's observation); 0, the default: none.
    peak_weight : float
        Residual mode, training only: the price of the episode's largest contour error, in decisions
        (:class:`PeakPrice`: an episode's return loses ``peak_weight * e_max / reward_scale``, as many decisions'
        contour reward at e_max); 0, the default: the env's reward alone.
    dial_rate : float
        Residual mode on an env with a feed override dial (the third action component, -1 to 1): the largest change
        of the dial the agent turns, per second (1/s; :class:`DialSlew`).  0, the default: the dial goes where the
        agent puts it at each decision.
    """

    mode: str = "direct"
    action_repeat: int = 1
    baseline: str | None = None
    correction: float | None = None
    baseline_params: dict = field(default_factory=dict)
    history: int = 0
    peak_weight: float = 0.0
    dial_rate: float = 0.0

    def __post_init__(self):
        if self.mode not in ACTION_MODES:
            raise ValueError(f"action mode must be one of {sorted(ACTION_MODES)}, got {self.mode!r}")
        object.__setattr__(self, "action_repeat", _check_repeat(self.action_repeat))
        h = self.history
        if isinstance(h, bool) or not isinstance(h, (int, np.integer)) or h < 0:
            raise ValueError(f"history must be an integer >= 0 (past decisions remembered), got {h!r}")
        if h > MAX_HISTORY:
            raise ValueError(
                f"history must be at most {MAX_HISTORY:,} past decisions (each adds its commands, errors, velocity "
                f"and acceleration to the agent's observation, per env; an episode is a few thousand decisions), "
                f"got {h:,}"
            )
        object.__setattr__(self, "history", int(h))
        if not real("peak_weight", self.peak_weight, "decisions") >= 0:
            raise ValueError(f"peak_weight must be a number >= 0 (decisions), got {self.peak_weight!r}")
        object.__setattr__(self, "peak_weight", float(self.peak_weight))
        if not real("dial_rate", self.dial_rate, "1/s") >= 0:
            raise ValueError(f"dial_rate must be a number >= 0 (1/s of the dial's -1 to 1), got {self.dial_rate!r}")
        object.__setattr__(self, "dial_rate", float(self.dial_rate))
        if self.mode == "residual":
            import vcnc_baselines

            if self.baseline not in vcnc_baselines.names():
                raise ValueError(
                    f"residual mode needs a baseline among {vcnc_baselines.names()}, got {self.baseline!r}"
                )
            c = self.correction
            if not 0 < real("correction", c, "fraction of u_max") <= 2:
                raise ValueError(f"correction must be a number in (0, 2] (fraction of u_max), got {c!r}")
            object.__setattr__(self, "correction", float(c))
        elif (
            self.baseline is not None
            or self.correction is not None
            or self.baseline_params
            or self.history
            or self.peak_weight
            or self.dial_rate
        ):
            raise ValueError(
                "baseline, correction, baseline_params, history, peak_weight and dial_rate apply to the "
                "residual mode only"
            )

    # -- the two forms -----------------------------------------------------------------
    def wrap(self, env: gym.Env) -> gym.Env:
        """The env as the agent trains on it: residual wrapped, or direct with the env's repeat checked."""
        if self.mode == "residual":
            return ResidualAction(
                env,
                baseline=self.baseline,
                correction=self.correction,
                action_repeat=self.action_repeat,
                history=self.history,
                peak_weight=self.peak_weight,
                dial_rate=self.dial_rate,
                **self.baseline_params,
            )
        repeat = env.unwrapped.action_repeat
        if repeat != self.action_repeat:
            raise ValueError(
                f"direct mode with action_repeat={self.action_repeat} needs an env made with "
                f"action_repeat={self.action_repeat}, got {repeat}"
            )
        return env

    def make_baseline(self, env):
        """The residual's baseline for ``env`` (a control-period env), or None in direct mode."""
        if self.mode != "residual":
            return None
        import vcnc_baselines

        return vcnc_baselines.make(self.baseline, env, **self.baseline_params)

    def command(self, baseline_action: np.ndarray | None, agent_action: np.ndarray) -> np.ndarray:
        """Normalised command (float32, clipped to [-1, 1]) from the baseline's and the agent's actions, in float32
        arithmetic (the agent's action is read as float32, the action space's dtype; the compiled residual step,
        ``ContouringVectorEnv.step_controlled``, does the same operations)."""
        a = np.clip(np.asarray(agent_action, dtype=np.float32), -1.0, 1.0)
        if self.mode == "residual":
            axes = np.shape(baseline_action)[-1]
            if a.shape[-1] > axes:  # the env's further inputs (a feed override): the agent's own, passed through
                corrected = np.clip(baseline_action + self.correction * a[..., :axes], -1.0, 1.0)
                return np.concatenate([corrected.astype(np.float32), a[..., axes:]], axis=-1)
            a = baseline_action + self.correction * a
        return np.clip(a, -1.0, 1.0).astype(np.float32)

    def to_dict(self) -> dict:
        """Plain mapping for a run's config file; ``ActionMode(**d)`` rebuilds it."""
        d = {"mode": self.mode, "action_repeat": self.action_repeat}
        if self.mode == "residual":
            d.update(baseline=self.baseline, correction=self.correction, baseline_params=dict(self.baseline_params))
        if self.history:  # absent, as in every config.yml before it was: none
            d["history"] = self.history
        if self.peak_weight:  # the same
            d["peak_weight"] = self.peak_weight
        if self.dial_rate:  # the same
            d["dial_rate"] = self.dial_rate
        return d

    def dial_slew(self, env, n: int) -> "DialSlew | None":
        """The agent's dial for ``n`` envs like ``env`` (an unwrapped env: its control period and action space), or
        None when ``dial_rate`` is 0; ValueError if the env has no dial."""
        if not self.dial_rate:
            return None
        if tuple(env.action_space.shape) != (3,):
            raise ValueError(
                f"dial_rate limits a feed override dial (an action of 3 components), and "
                f"{type(env).__name__} takes {tuple(env.action_space.shape)}"
            )
        return DialSlew(self.dial_rate, env.dt, n)

    def peak_price(self, env, n: int) -> "PeakPrice | None":
        """The price of the episode's peak for ``n`` envs like ``env`` (an unwrapped env or native vector env: its
        ``task``'s reward scale and divergence bound), or None when ``peak_weight`` is 0."""
        if not self.peak_weight:
            return None
        task = getattr(env, "task", None)
        if task is None:
            raise ValueError(f"peak_weight needs a contouring env's reward, and {type(env).__name__} has no task")
        return PeakPrice(self.peak_weight, task.reward_scale, task.divergence_bound, n)


def _zero(values: np.ndarray, rows) -> None:
    """Set the per-env ``values`` of the envs ``rows`` (bool, (n,); None: all) to 0: an episode starts there."""
    if rows is None:
        values[:] = 0.0
    else:
        values[np.asarray(rows, dtype=bool)] = 0.0


class PeakPrice:
    """The price of a new episode maximum of the contour error, per env: a term of the training reward.

    The env's reward pays for the contour error of every control period, and so for the many periods, not for the
    few at the sharpest turn that set the max contour error (``experiments/adaptive/README.md``, "The second id, the memory's
    part and a recurrent policy").  This term prices the max itself: at each decision the reward loses
    ``weight * (m_new - m_old) / reward_scale``, with ``m`` the largest contour error of the episode so far
    (mm, clipped at the env's divergence bound as the env's reward is), so that over an episode the penalties sum
    to ``weight * min(e_max, bound) / reward_scale``: the episode's max priced as ``weight`` decisions at that error.

    Parameters
    ----------
    weight : float
        Decisions, >= 0.
    reward_scale, divergence_bound : float
        The env's (mm).
    n : int
        Envs.
    """

    def __init__(self, weight: float, reward_scale: float, divergence_bound: float, n: int):
        self.weight, self.scale, self.bound = float(weight), float(reward_scale), float(divergence_bound)
        self.peak = np.zeros(n)

    def __call__(self, decision_peak, rows=None) -> np.ndarray:
        """The penalties (>= 0, to subtract from the rewards) of a decision whose largest contour errors (mm) were
        ``decision_peak``, (n,); ``rows`` (bool, (n,)): the envs that decided (the others pay 0)."""
        new = np.minimum(np.maximum(self.peak, np.asarray(decision_peak, dtype=float)), self.bound)
        if rows is not None:
            new = np.where(rows, new, self.peak)
        penalty = self.weight * (new - self.peak) / self.scale
        self.peak = new
        return penalty

    def restart(self, rows=None) -> None:
        """A new episode for the envs ``rows`` (bool, (n,); None: all)."""
        _zero(self.peak, rows)


class DialSlew:
    """The feed override dial the agent turns, at a limited rate: the third component of its action, per env.

    A dial swung from one end to the other between two decisions (20 ms) steps the path acceleration by the
    override's whole rate times the feed, and through a shop-floor machine's 150 Hz mode that costs tens of um
    (``experiments/tolerance/README.md``, "The eighth step").  With a rate, the dial in force moves toward the agent's at most
    ``rate * dt`` per control period and starts every episode at 0 (the look-ahead's own plan on the tolerance
    ids); the env's override then follows that dial as it follows any.  The arithmetic is float32, the action
    space's dtype, so that the training wrapper (:class:`ResidualAction`) and the evaluation
    (:class:`vcnc_agents.policy.AgentPolicy`) turn the same dial to the bit.

    Parameters
    ----------
    rate : float
        Largest change of the dial (-1 to 1) per second, 1/s (> 0).
    dt : float
        The env's control period, s.
    n : int
        Envs.
    """

    def __init__(self, rate: float, dt: float, n: int):
        self.per_period = np.float32(rate * dt)
        self.dial = np.zeros(n, dtype=np.float32)

    def __call__(self, action: np.ndarray) -> np.ndarray:
        """The action in force for one control period: ``action`` ((3,) or (n, 3)) clipped to [-1, 1], its dial
        moved toward the agent's by at most ``rate * dt`` (float32)."""
        a = np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0)
        dial = self.dial.reshape(a.shape[:-1])
        dial = dial + np.clip(a[..., 2] - dial, -self.per_period, self.per_period)
        self.dial[:] = np.reshape(dial, -1)
        a[..., 2] = dial
        return a

    def restart(self, rows=None) -> None:
        """A new episode for the envs ``rows`` (bool, (n,); None: all): their dial at 0."""
        _zero(self.dial, rows)


class ResidualAction(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The agent corrects a classical baseline: residual action mode, with action repeat.

    Each :meth:`step` holds the agent's action a for ``action_repeat`` control
    periods; in each the baseline computes its command from the current
    observation and the env applies
    ``clip(u_baseline / u_max + correction * a, -1, 1)``.

    Parameters
    ----------
    env : gymnasium.Env
        A vcnc_gym contouring env made with ``action_repeat=1`` (the baseline
        runs at its control period), possibly wrapped (``gym.make``).
    baseline : str
        Baseline name of :func:`vcnc_baselines.names`, e.g. "smc" or "qft".
    correction : float
        Largest correction as a fraction of u_max, in (0, 2].
    action_repeat : int
        Control periods per agent decision.
    history : int
        Past decisions the agent remembers (:mod:`vcnc_gym.envs.history`), appended to the observation; 0: none.
    peak_weight : float
        The price of the episode's largest contour error, in decisions (:class:`PeakPrice`); 0: none.
    dial_rate : float
        The largest change of the agent's feed override dial per second, 1/s (:class:`DialSlew`); 0: none.
    **baseline_params
        Constructor parameters of the baseline.

    Notes
    -----
    The reward of a step is the mean of the env's rewards over its control
    periods (less :class:`PeakPrice`'s term with ``peak_weight``), so it has
    the scale of the direct mode's (whose env reward is the contour error
    averaged over the step); a divergence penalty, counted by the
    env in control periods, becomes the same penalty per remaining decision.
    ``info`` is the last control period's, with "contour_error_max" the
    largest over the step.  Usable as RL Zoo's ``env_wrapper``.  On an env
    with more inputs than the baseline's two axes (``VCNC-OmegaOverride-v1``'s
    feed override) the agent sets those directly: its action's further
    components pass through unchanged.
    """

    def __init__(
        self,
        env: gym.Env,
        baseline: str = "smc",
        correction: float = 0.2,
        action_repeat: int = 1,
        history: int = 0,
        peak_weight: float = 0.0,
        dial_rate: float = 0.0,
        **baseline_params,
    ):
        gym.utils.RecordConstructorArgs.__init__(
            self,
            baseline=baseline,
            correction=correction,
            action_repeat=action_repeat,
            history=history,
            peak_weight=peak_weight,
            dial_rate=dial_rate,
            **baseline_params,
        )
        super().__init__(env)
        self.mode = ActionMode(
            "residual",
            action_repeat=action_repeat,
            baseline=baseline,
            correction=correction,
            baseline_params=baseline_params,
            history=history,
            peak_weight=peak_weight,
            dial_rate=dial_rate,
        )
        if env.unwrapped.action_repeat != 1:
            raise ValueError(
                "ResidualAction runs the baseline every control period: make the env with "
                f"action_repeat=1 (got {env.unwrapped.action_repeat}) and give the wrapper the repeat"
            )
        self.baseline = self.mode.make_baseline(env)
        self.action_repeat = self.mode.action_repeat
        self._obs = None
        self._start = np.array([True])
        self.history = None
        if self.mode.history:
            self.history = DecisionHistory(self.mode.history, env.unwrapped.layout, 1)
            self.observation_space = self.history.space(env.observation_space)
        self.price = self.mode.peak_price(env.unwrapped, 1)
        self.slew = self.mode.dial_slew(env.unwrapped, 1)

    def _seen(self, obs):
        """The observation the agent sees: the env's, then the remembered decisions (with ``history``)."""
        return obs if self.history is None else self.history.seen(obs[None])[0]

    @property
    def decision_period(self) -> float:
        """Time between two agent decisions, s."""
        return self.env.unwrapped.dt * self.action_repeat

    @property
    def episode_steps(self) -> int:
        """Natural episode length in agent decisions."""
        return math.ceil(self.env.unwrapped.episode_steps / self.action_repeat)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        if hasattr(self.baseline, "plan"):  # a model-based baseline reads the reference: a new contour, a new table
            self.baseline.plan(self.env)
        self._obs = obs
        self._start = np.array([True])
        if self.history is not None:
            self.history.start(obs[None])
        if self.price is not None:
            self.price.restart()
        if self.slew is not None:
            self.slew.restart()
        return self._seen(obs), info

    def step(self, action):
        if self._obs is None:
            raise RuntimeError("step() called before reset()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.env.action_space.shape:  # (2,), or (3,) with a feed override (FeedOverrideEnv)
            raise ValueError(f"action must have shape {self.env.action_space.shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite, got {action!r}")
        total = 0.0
        peak = 0.0
        if self.history is not None:  # the observation this decision is made on joins the past
            self.history.push(self._obs[None])
        for _ in range(self.action_repeat):
            base, _ = self.baseline.predict(self._obs, episode_start=self._start)
            self._start = np.array([False])
            held = a if self.slew is None else self.slew(a)
            obs, reward, terminated, truncated, info = self.env.step(self.mode.command(base, held))
            self._obs = obs
            total += reward
            peak = max(peak, info["contour_error_max"])
            if terminated or truncated:
                break
        info = dict(info, contour_error_max=peak)
        reward = total / self.action_repeat
        if self.price is not None:
            reward -= float(self.price(np.array([peak]))[0])
        return self._seen(obs), reward, terminated, truncated, info
