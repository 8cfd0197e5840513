"""A lean PPO over the native vector env: ``vcnc-train --trainer lean``.

Stable-Baselines3's PPO spends, per agent decision, a few hundred
microseconds of Python whatever the number of envs (per-env info dicts,
``VecNormalize``, the rollout buffer's per-step copies, callbacks) and its
update walks small minibatches; the native vector env makes a decision of N
envs in one numba call (``ContouringVectorEnv.step_controlled``).  This
trainer keeps SB3's PPO -- the same :class:`ActorCriticPolicy` network and
optimiser, the same loss, advantage estimate (GAE), time-limit bootstrap and
``VecNormalize`` statistics (Schulman et al. 2017; SB3's
``OnPolicyAlgorithm.collect_rollouts`` and ``PPO.train``) -- and drops the
rest: the rollout is preallocated torch tensors filled from the env's arrays,
the policy's forward pass is written out (Gaussian with a state-independent
log std), and the envs' statistics are kept as arrays.

What it writes is what ``vcnc-train`` writes (``vcnc_agents.training``): the run
folder with config.yml (plus ``trainer: lean``), checkpoints (SB3
``model.zip`` + data-only ``vecnormalize.npz``), best/, final/,
evaluations.csv, monitor/ and summary.json; an agent is an SB3 PPO file that
:func:`vcnc_agents.load_agent` and ``vcnc-bench --policy ppo:PATH`` load without
unpickling anything.  ``vcnc-train --resume`` goes on with the trainer the run
was started with.

Two things differ from SB3's trainer on purpose:

- **Staggered starts** (residual mode with a compiled baseline, ``stagger``):
  before training, env i runs ``floor(i L / N)`` decisions of the baseline
  alone (L: the episode's length in decisions), so the N envs are spread
  along the contour.  Started together, N identical envs (nominal plant) are
  in phase: every rollout holds one stretch of the path, and a budget of B
  agent steps visits only its first B / N decisions.  The time is counted in
  the run's wall time (``stagger_s`` in summary.json), not its agent steps.
- Threads: numba steps the envs on all its threads (the vector env's
  :class:`~vcnc_gym.envs.contouring_vector_env.KernelPath` falls back to one
  when a core is taken) and torch runs the network on ``torch.get_num_threads()``.

Time is accounted per phase (summary.json ``time_shares``): env (the kernel
calls and resets), forward (the policy during the rollout), update (PPO's
epochs) and other (normalisation, GAE, logging, checkpoints, evaluation).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vcnc_gym.envs.history import DecisionHistory, agent_space

from .action_modes import ActionMode
from .config import normalize_kwargs
from .env_factory import make_eval_env
from .normalization import NormalizationStats
from .policy import evaluate_model
from .run_config import RunConfig
from .run_folder import best_of, checkpoint_files, read_evaluations, save_agent, save_model, write_evaluations
from .run_session import Session, TrainingResult, open_run, prepare_run, roll_back_to, start_folder
from .run_warning import note
from .vec_env import commission_drawn_plants, monitor_writers, native_batch, per_env_batch

__all__ = [
    "TRAINERS",
    "sb3_only",
    "check_trainer",
    "DecisionEnv",
    "RunningNormalizer",
    "PhaseClock",
    "learn",
    "train_lean",
]

#: The trainers of ``vcnc-train --trainer``: SB3's PPO (vcnc_agents.training) and this module's.
TRAINERS = ("sb3", "lean")


def sb3_only(config: RunConfig, vec_env: str = "native") -> str | None:
    """Why the run ``config`` needs SB3's trainer (an option the lean trainer does not have), or None."""
    h = config.hyperparams
    if vec_env != "native":
        return f"--vec-env {vec_env} is SB3's (the lean trainer steps its own envs)"
    if h.get("policy", "MlpPolicy") != "MlpPolicy":
        return f"policy {h['policy']!r} (the lean trainer runs MlpPolicy)"
    if h.get("use_sde"):
        return "use_sde (the lean trainer samples plain Gaussian actions)"
    return None


def check_trainer(
    trainer: str | None,
    env_id: str,
    recorded: str | None = None,
    *,
    resumed: bool = False,
    needs_sb3: str | None = None,
) -> str:
    """The trainer a run goes on with; ValueError, before the training starts, when it cannot.

    ``trainer`` is the one asked for (None: a resumed run's own, or for a new run ``"lean"``, the default, unless
    ``needs_sb3`` gives a reason for SB3's, :func:`sb3_only`); ``env_id`` the run's env and ``recorded`` the
    trainer its config records (:attr:`vcnc_agents.run_config.RunConfig.trainer`: None is SB3's, as before the lean
    trainer was).  A resumed run (``resumed``) goes on with the trainer it was started with.  Every id trains on
    both: the lean trainer steps the native vector env where the id has one, else N wrapped Gymnasium envs
    (:class:`DecisionEnv`).
    """
    if resumed:
        recorded = recorded or "sb3"
    if trainer is None:
        trainer = recorded or ("sb3" if needs_sb3 else "lean")
        if trainer == "sb3" and recorded is None:
            note(f"training {env_id} with SB3's PPO: {needs_sb3}")
    if trainer not in TRAINERS:
        raise ValueError(f"trainer must be one of {list(TRAINERS)}, got {trainer!r}")
    if recorded is not None and trainer != recorded:
        raise ValueError(
            f"the run was trained with the {recorded!r} trainer and goes on with it; drop --trainer {trainer}"
        )
    if trainer == "lean" and needs_sb3:
        raise ValueError(f"the lean trainer cannot train this run: {needs_sb3}; use --trainer sb3")
    return trainer


# -- the envs, as arrays -----------------------------------------------------------------------------------------
class DecisionEnv:
    """N envs of a run, one agent decision per :meth:`step`, everything as arrays (no per-env dicts).

    Residual mode with a compiled baseline runs a decision in one kernel call
    (``ContouringVectorEnv.step_controlled``); a baseline without a compiled
    form calls its batched ``predict`` every control period; direct mode is
    one ``step`` with the env's own action repeat.  An id without a native
    vector env (the feed override, the random contours) runs N Gymnasium envs,
    each wrapped by the action mode, in a ``SyncVectorEnv``
    (:func:`vcnc_agents.vec_env.per_env_batch`): the same decisions, slower.  A residual over a baseline
    commissioned per machine (``ff-pid@machine``) has the plants the envs drew at their reset commissioned before
    their next decision (:func:`vcnc_agents.vec_env.commission_drawn_plants`).  An ended env is reset at once
    (its last observation returned apart) and a Monitor row written.

    Parameters
    ----------
    env_id : str
        A registered VCNC id.
    n_envs : int
        Number of envs.
    mode : ActionMode
        The run's action mode.
    env_kwargs : dict
        The env arguments of the run.
    seed : int
        Env i is seeded ``seed + i``.
    monitor_dir : path, optional
        SB3 Monitor files ``<i>.monitor.csv`` (columns r, l, t, steps), as ``vcnc_agents.vec_env.VcncVecEnv`` writes.
    start_steps : int
        The run's agent steps when this session starts (the monitor's ``steps`` column).
    append : bool
        Append to existing monitor files (a resumed run).
    """

    def __init__(
        self,
        env_id: str,
        n_envs: int,
        mode: ActionMode,
        env_kwargs: dict,
        seed: int,
        *,
        monitor_dir=None,
        start_steps: int = 0,
        append: bool = False,
    ):
        from vcnc_gym.envs.registry import VECTOR_IDS

        self.native = env_id in VECTOR_IDS
        make = native_batch if self.native else per_env_batch
        self.venv, self.baseline, self.controller, self.repeat = make(env_id, n_envs, mode, env_kwargs)
        self.mode = mode
        self.n = n_envs
        self.observation_space = self.venv.single_observation_space
        self.action_space = self.venv.single_action_space
        self.history = None  # the per-env wrappers remember their own past (ResidualAction)
        if mode.history and self.native:
            self.history = DecisionHistory(mode.history, self.venv.layout, n_envs)
            self.observation_space = self.history.space(self.observation_space)
        self.price = mode.peak_price(self.venv, n_envs) if self.native else None  # else each wrapper prices its own
        self._seed = seed
        self._start = np.ones(n_envs, dtype=bool)
        self.steps = int(start_steps)
        self._returns = np.zeros(n_envs)
        self._lengths = np.zeros(n_envs, dtype=np.int64)
        self._t0 = time.time()
        self._writers = monitor_writers(monitor_dir, n_envs, env_id, self._t0, append)

    @property
    def decisions_per_episode(self) -> int:
        """The episode's natural length in agent decisions (the first env's, for per-env wrappers)."""
        if not self.native:  # control periods of the first env's episode, a decision every action_repeat of them
            return max(1, int(self.venv.envs[0].unwrapped.episode_steps) // self.mode.action_repeat)
        return max(1, int(self.venv.episode_steps) // self.repeat)

    def _seen(self, obs: np.ndarray) -> np.ndarray:
        """What the agents see of every env's observation: itself, then its remembered decisions (``history``)."""
        return obs if self.history is None else self.history.seen(obs)

    def reset(self) -> np.ndarray:
        obs, _ = self.venv.reset(seed=self._seed)
        self._start[:] = True
        self._obs = obs
        if self.history is not None:
            self.history.start(obs)
        if self.price is not None:
            self.price.restart()
        return self._seen(obs)

    def _decide(self, actions: np.ndarray, active=None):
        """(obs, summed rewards, terminated, truncated) of one decision of the envs (all, or ``active``); the peak's
        price (``peak_weight``), per env, is subtracted from the sum once per decision."""
        obs, total, te, tr, peak = self._periods(actions, active)
        if self.price is not None:
            total = total - self.repeat * self.price(peak, active)  # the caller divides by the repeat
        return obs, total, te, tr

    def _periods(self, actions: np.ndarray, active):
        """(obs, summed rewards, terminated, truncated, largest contour error (mm) of the decision) per env."""
        if self.history is not None:  # the observation each deciding env decides on joins its past
            self.history.push(self._obs, active)
        if self.controller is not None:
            if self._start.any():
                self.controller = commission_drawn_plants(self.baseline, self.venv, self.controller)
                self.baseline.reset(mask=self._start)
                self._start[:] = False
            obs, total, te, tr, info = self.venv.step_controlled(
                self.controller, actions, self.mode.correction, self.repeat, active=active
            )
            return obs, total, te, tr, info["contour_error_max"]
        if active is not None:
            raise ValueError("only a compiled residual baseline steps a subset of the envs")
        n = self.n
        total, te_all, tr_all, peak = np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n)
        obs = self._obs
        if self.native and self.baseline is not None and self._start.any():
            commission_drawn_plants(self.baseline, self.venv, None)
        for _ in range(self.repeat):
            base = None
            if self.baseline is not None:
                base, _ = self.baseline.predict(obs, episode_start=self._start)
                self._start[:] = False
            # per-env residual wrappers (no native vector env) take the agent's action and clip it themselves
            wrapped = not self.native and self.mode.mode == "residual"
            obs, r, te, tr, info = self.venv.step(actions if wrapped else self.mode.command(base, actions))
            if self.price is not None:
                peak = np.where(info["_contour_error"], np.maximum(peak, info["contour_error_max"]), peak)
            total += r
            te_all |= te
            tr_all |= tr
            if (te_all | tr_all).all():
                break
        return obs, total, te_all, tr_all, peak

    def stagger(self, obs: np.ndarray) -> np.ndarray:
        """Spread the envs along the episode: env i runs ``floor(i L / N)`` decisions of the baseline alone (which
        the history remembers as decisions with no correction).  ``obs`` is what :meth:`reset` returned."""
        if self.controller is None or self.n == 1:
            return obs
        obs = self._obs
        ahead = (np.arange(self.n) * self.decisions_per_episode) // self.n
        zero = np.zeros((self.n, 2), dtype=np.float32)
        for k in range(int(ahead.max())):
            obs, _, te, tr = self._decide(zero, active=ahead > k)
            done = te | tr
            if done.any():  # an episode shorter than its natural length: start it again
                obs, _ = self.venv.reset(options={"reset_mask": done})
                self._start[done] = True
                if self.history is not None:
                    self.history.start(obs, done)
                if self.price is not None:
                    self.price.restart(done)
            self._obs = obs
        return self._seen(obs)

    def step(self, actions: np.ndarray):
        """One decision: (obs, rewards (mean over the decision's control periods, float32), terminated,
        truncated, terminal observations (rows of the ended envs, in index order))."""
        obs, total, te, tr = self._decide(actions)
        rewards = (total / self.repeat).astype(np.float32)
        self.steps += self.n
        self._returns += rewards
        self._lengths += 1
        done = te | tr
        terminal = None
        if done.any():
            terminal = obs[done].copy() if self.history is None else self.history.seen(obs, done)  # ended rows only
            for i in np.flatnonzero(done):
                if self._writers is not None:
                    self._writers[i].write_row(
                        {
                            "r": round(float(self._returns[i]), 6),
                            "l": int(self._lengths[i]),
                            "t": round(time.time() - self._t0, 6),
                            "steps": self.steps,
                        }
                    )
            self._returns[done] = 0.0
            self._lengths[done] = 0
            obs, _ = self.venv.reset(options={"reset_mask": done})
            self._start[done] = True
            if self.history is not None:
                self.history.start(obs, done)
            if self.price is not None:
                self.price.restart(done)
        self._obs = obs
        return self._seen(obs), rewards, te, tr, terminal

    def close(self) -> None:
        if self._writers is not None:
            for w in self._writers:
                w.close()
        self.venv.close()


# -- VecNormalize's statistics ----------------------------------------------------------------------------------
class RunningNormalizer:
    """What SB3's ``VecNormalize`` does to observations and rewards in training, on arrays.

    Observations: ``clip((obs - mean) / sqrt(var + eps), +-clip_obs)`` with the
    running mean and variance of every observation seen (updated before
    normalising, as VecNormalize does); rewards: divided by the running standard
    deviation of the discounted return, clipped to ``+-clip_reward``.

    Parameters
    ----------
    stats : NormalizationStats
        The statistics to start from (a resumed run's, or :meth:`fresh`'s).
    n_envs : int
        Number of envs (one discounted return each).
    """

    def __init__(self, stats: NormalizationStats, n_envs: int):
        from stable_baselines3.common.running_mean_std import RunningMeanStd

        self.norm_obs, self.norm_reward = stats.norm_obs, stats.norm_reward
        self.clip_obs, self.clip_reward, self.epsilon, self.gamma = (
            stats.clip_obs,
            stats.clip_reward,
            stats.epsilon,
            stats.gamma,
        )
        self.obs_rms = RunningMeanStd(shape=stats.obs_mean.shape)
        self.obs_rms.mean, self.obs_rms.var, self.obs_rms.count = (
            stats.obs_mean.copy(),
            stats.obs_var.copy(),
            stats.obs_count,
        )
        self.ret_rms = RunningMeanStd(shape=())
        self.ret_rms.mean, self.ret_rms.var, self.ret_rms.count = (
            np.float64(stats.ret_mean),
            np.float64(stats.ret_var),
            stats.ret_count,
        )
        self.returns = np.zeros(n_envs)

    @classmethod
    def fresh(cls, hyperparams: dict, obs_size: int, n_envs: int) -> "RunningNormalizer":
        """Statistics of a new run from the entry's ``normalize`` (VecNormalize's defaults)."""
        kw = normalize_kwargs(hyperparams)
        kw = {"norm_obs": False, "norm_reward": False} if kw is None else kw
        return cls(
            NormalizationStats(
                norm_obs=bool(kw.get("norm_obs", True)),
                norm_reward=bool(kw.get("norm_reward", True)),
                obs_mean=np.zeros(obs_size),
                obs_var=np.ones(obs_size),
                obs_count=1e-4,
                ret_mean=0.0,
                ret_var=1.0,
                ret_count=1e-4,
                clip_obs=float(kw.get("clip_obs", 10.0)),
                clip_reward=float(kw.get("clip_reward", 10.0)),
                epsilon=float(kw.get("epsilon", 1e-8)),
                gamma=float(kw.get("gamma", 0.99)),
            ),
            n_envs,
        )

    def stats(self) -> NormalizationStats:
        return NormalizationStats(
            norm_obs=self.norm_obs,
            norm_reward=self.norm_reward,
            obs_mean=np.array(self.obs_rms.mean, dtype=float),
            obs_var=np.array(self.obs_rms.var, dtype=float),
            obs_count=float(self.obs_rms.count),
            ret_mean=float(self.ret_rms.mean),
            ret_var=float(self.ret_rms.var),
            ret_count=float(self.ret_rms.count),
            clip_obs=self.clip_obs,
            clip_reward=self.clip_reward,
            epsilon=self.epsilon,
            gamma=self.gamma,
        )

    def observe(self, obs: np.ndarray, update: bool = True) -> np.ndarray:
        """Normalised observations (float32); ``update`` adds them to the statistics first."""
        if not self.norm_obs:
            return obs.astype(np.float32)
        if update:
            self.obs_rms.update(obs)
        return np.clip(
            (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon), -self.clip_obs, self.clip_obs
        ).astype(np.float32)

    def reward(self, rewards: np.ndarray, done: np.ndarray) -> np.ndarray:
        """Normalised rewards (float32) of a decision; the returns of ended episodes restart."""
        if self.norm_reward:
            self.returns = self.returns * self.gamma + rewards
            self.ret_rms.update(self.returns)
            rewards = np.clip(rewards / np.sqrt(self.ret_rms.var + self.epsilon), -self.clip_reward, self.clip_reward)
        self.returns[done] = 0.0
        return rewards.astype(np.float32)


# -- the time of each phase --------------------------------------------------------------------------------------
class PhaseClock:
    """Wall time per phase: ``with clock("env"): ...``; :meth:`shares` as fractions of the measured total."""

    PHASES = ("env", "forward", "update", "other")

    def __init__(self):
        self.seconds = dict.fromkeys(self.PHASES, 0.0)
        self._phase = None

    def __call__(self, phase: str):
        self._phase = phase
        return self

    def __enter__(self):
        self._t0 = time.perf_counter()

    def __exit__(self, *exc):
        self.seconds[self._phase] += time.perf_counter() - self._t0

    def shares(self, wall: float) -> dict:
        """{phase: fraction of ``wall``}; "other" is whatever the named phases do not cover."""
        wall = max(wall, 1e-9)
        named = {k: self.seconds[k] / wall for k in ("env", "forward", "update")}
        named["other"] = max(0.0, 1.0 - sum(named.values()))
        return {k: round(v, 4) for k, v in named.items()}


# -- PPO ---------------------------------------------------------------------------------------------------------
def _spaces_only(observation_space, action_space, n_envs: int):
    """An SB3 VecEnv that holds only the spaces and the env count: what PPO needs to build its policy and to be
    saved (the lean trainer steps its :class:`DecisionEnv` itself)."""
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    class SpacesOnly(VecEnv):
        def _refuse(self, *args, **kwargs):
            raise RuntimeError("the lean trainer steps the envs itself")

        reset = step_async = step_wait = set_attr = env_method = _refuse

        def close(self):
            pass

        def get_attr(self, attr_name, indices=None):
            return [None for _ in self._get_indices(indices)]

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False for _ in self._get_indices(indices)]

    return SpacesOnly(n_envs, observation_space, action_space)


@dataclass
class _Rollout:
    obs: "object"
    actions: "object"
    logp: "object"
    values: "object"
    rewards: np.ndarray
    starts: np.ndarray


def _gae(rewards, values, starts, last_values, last_done, gamma, lam):
    """Advantages and returns of a rollout (T, N), as SB3's ``RolloutBuffer.compute_returns_and_advantage``."""
    t_len = rewards.shape[0]
    adv = np.zeros_like(rewards)
    last = np.zeros(rewards.shape[1], dtype=np.float32)
    for t in reversed(range(t_len)):
        if t == t_len - 1:
            nonterminal, next_values = 1.0 - last_done, last_values
        else:
            nonterminal, next_values = 1.0 - starts[t + 1], values[t + 1]
        delta = rewards[t] + gamma * next_values * nonterminal - values[t]
        last = delta + gamma * lam * nonterminal * last
        adv[t] = last
    return adv, adv + values


class LeanPPO:
    """SB3's PPO update on SB3's policy, the rollout collected from a :class:`DecisionEnv` as arrays.

    Parameters
    ----------
    model : stable_baselines3.PPO
        Holds the policy, its optimiser and the hyperparameters (n_steps,
        batch_size, n_epochs, gamma, gae_lambda, clip_range, ent_coef,
        vf_coef, max_grad_norm, target_kl, normalize_advantage, lr schedule).
    env : DecisionEnv
    normalizer : RunningNormalizer
    total_timesteps : int
        The run's total, for the schedules' progress.
    """

    def __init__(self, model, env: DecisionEnv, normalizer: RunningNormalizer, total_timesteps: int, clock: PhaseClock):
        import torch
        from stable_baselines3.common.distributions import DiagGaussianDistribution

        from stable_baselines3.common.torch_layers import FlattenExtractor

        policy = model.policy
        if not isinstance(policy.action_dist, DiagGaussianDistribution) or not isinstance(
            policy.pi_features_extractor, FlattenExtractor
        ):
            raise ValueError("the lean trainer runs MlpPolicy's Gaussian policies (no state-dependent exploration)")
        self.torch = torch
        self.model, self.policy, self.env, self.norm = model, policy, env, normalizer
        self.total = int(total_timesteps)
        self.clock = clock
        self.n_steps, self.n = model.n_steps, env.n
        obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
        self.buf = _Rollout(
            obs=torch.zeros((self.n_steps, self.n, obs_dim)),
            actions=torch.zeros((self.n_steps, self.n, act_dim)),
            logp=torch.zeros((self.n_steps, self.n)),
            values=torch.zeros((self.n_steps, self.n)),
            rewards=np.zeros((self.n_steps, self.n), dtype=np.float32),
            starts=np.zeros((self.n_steps, self.n), dtype=np.float32),
        )
        self.last_obs = None  # normalised, float32
        self.last_starts = np.ones(self.n, dtype=np.float32)
        self.stats = {}

    def _forward(self, obs_t):
        """(mean action, value) of normalised observations, no gradient."""
        p = self.policy
        latent_pi, latent_vf = p.mlp_extractor(obs_t)  # MlpPolicy's features extractor flattens: a no-op here
        return p.action_net(latent_pi), p.value_net(latent_vf).flatten()

    def evaluate(self, obs, actions):
        """(values, log-probabilities, entropies) of ``actions`` at normalised ``obs``, with gradients: the
        policy's ``evaluate_actions`` with the Gaussian's log-density and entropy written out."""
        p = self.policy
        mean, values = self._forward(obs)
        z = (actions - mean) * self.torch.exp(-p.log_std)
        logp = -0.5 * (z * z).sum(dim=1) - p.log_std.sum() - 0.5 * math.log(2 * math.pi) * z.shape[1]
        entropy = (0.5 + 0.5 * math.log(2 * math.pi) + p.log_std).sum().expand(len(logp))
        return values, logp, entropy

    def start(self, obs: np.ndarray) -> None:
        self.last_obs = self.norm.observe(obs)

    def collect(self) -> None:
        """One rollout of ``n_steps`` decisions of every env (SB3's ``collect_rollouts``)."""
        torch, p, b, clock = self.torch, self.policy, self.buf, self.clock
        p.set_training_mode(False)
        log_std = p.log_std.detach()
        std = log_std.exp()
        logp_const = -(log_std.sum() + 0.5 * math.log(2 * math.pi) * log_std.numel())
        low, high = self.env.action_space.low, self.env.action_space.high
        for t in range(self.n_steps):
            with clock("forward"), torch.no_grad():
                obs_t = torch.from_numpy(self.last_obs)
                mean, value = self._forward(obs_t)
                noise = torch.randn_like(mean)
                action = mean + std * noise
                logp = logp_const - 0.5 * (noise * noise).sum(dim=1)
            b.obs[t] = obs_t
            b.actions[t] = action
            b.logp[t] = logp
            b.values[t] = value
            b.starts[t] = self.last_starts
            a = np.clip(action.numpy(), low, high)
            with clock("env"):
                obs, rewards, te, tr, terminal = self.env.step(a)
            done = te | tr
            rewards = self.norm.reward(rewards, done)
            if terminal is not None:
                late = tr[done] & ~te[done]  # time limits: bootstrap the value of the last observation
                if late.any():
                    idx = np.flatnonzero(done)[late]
                    with clock("forward"), torch.no_grad():
                        v = self._forward(torch.from_numpy(self.norm.observe(terminal[late], update=False)))[1]
                    rewards[idx] += self.model.gamma * v.numpy()
            b.rewards[t] = rewards
            self.last_obs = self.norm.observe(obs)
            self.last_starts = done.astype(np.float32)
        with clock("forward"), torch.no_grad():
            last_values = self._forward(torch.from_numpy(self.last_obs))[1].numpy()
        adv, ret = _gae(
            b.rewards,
            b.values.numpy(),
            b.starts,
            last_values,
            self.last_starts,
            self.model.gamma,
            self.model.gae_lambda,
        )
        self.advantages, self.returns = torch.from_numpy(adv), torch.from_numpy(ret.astype(np.float32))

    def update(self, num_timesteps: int) -> None:
        """PPO's epochs over the rollout (SB3's ``PPO.train``)."""
        torch, p, m = self.torch, self.policy, self.model
        progress = 1.0 - num_timesteps / self.total
        lr = m.lr_schedule(progress)
        for group in p.optimizer.param_groups:
            group["lr"] = lr
        clip = m.clip_range(progress)
        clip_vf = m.clip_range_vf(progress) if m.clip_range_vf is not None else None
        p.set_training_mode(True)
        size = self.n_steps * self.n
        obs = self.buf.obs.reshape(size, -1)
        actions = self.buf.actions.reshape(size, -1)
        old_logp, old_values = self.buf.logp.reshape(size), self.buf.values.reshape(size)
        advantages, returns = self.advantages.reshape(size), self.returns.reshape(size)
        batch = min(m.batch_size, size)
        pg_losses, clip_fractions, kls = [], [], []
        go_on = True
        for _ in range(m.n_epochs):
            order = torch.randperm(size)
            for start in range(0, size, batch):
                idx = order[start : start + batch]
                values, logp, entropy = self.evaluate(obs[idx], actions[idx])
                adv = advantages[idx]
                if m.normalize_advantage and len(idx) > 1:
                    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                ratio = torch.exp(logp - old_logp[idx])
                pg_loss = -torch.min(adv * ratio, adv * torch.clamp(ratio, 1 - clip, 1 + clip)).mean()
                if clip_vf is not None:
                    values = old_values[idx] + torch.clamp(values - old_values[idx], -clip_vf, clip_vf)
                value_loss = torch.nn.functional.mse_loss(returns[idx], values)
                entropy_loss = -torch.mean(-logp) if entropy is None else -torch.mean(entropy)
                loss = pg_loss + m.ent_coef * entropy_loss + m.vf_coef * value_loss
                with torch.no_grad():
                    log_ratio = logp - old_logp[idx]
                    kl = torch.mean((torch.exp(log_ratio) - 1) - log_ratio).item()
                pg_losses.append(pg_loss.item())
                clip_fractions.append(torch.mean((torch.abs(ratio - 1) > clip).float()).item())
                kls.append(kl)
                if m.target_kl is not None and kl > 1.5 * m.target_kl:
                    go_on = False
                    break
                p.optimizer.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(p.parameters(), m.max_grad_norm)
                p.optimizer.step()
            if not go_on:
                break
        m._n_updates += m.n_epochs
        self.stats = {
            "policy_loss": float(np.mean(pg_losses)),
            "clip_fraction": float(np.mean(clip_fractions)),
            "approx_kl": float(np.mean(kls)),
            "learning_rate": float(lr),
        }


# -- the run -----------------------------------------------------------------------------------------------------
def learn(
    run_dir: Path,
    config: RunConfig,
    checkpoint,
    *,
    progress_bar: bool = True,
    device: str = "cpu",
    verbose: int = 0,
    stagger: bool = True,
) -> TrainingResult:
    """Train the run :func:`vcnc_agents.run_session.prepare_run` set up with the lean trainer (from ``checkpoint`` if
    not None); the run folder, its guarantees and the returned :class:`vcnc_agents.run_session.TrainingResult` are
    those of :func:`vcnc_agents.training.learn`, and so is the scaffolding (:mod:`vcnc_agents.run_session`).

    Parameters
    ----------
    run_dir, config, checkpoint
        As :func:`vcnc_agents.run_session.prepare_run` returns them.
    progress_bar : bool
        A tqdm bar of agent steps.
    device : str
        Torch device.
    verbose : int
        1: a line per evaluation.
    stagger : bool
        Spread the envs along the episode before training (see the module docstring).
    """
    check_trainer("lean", config.env_id, config.trainer)  # before the run folder is made
    config = config.with_trainer("lean")
    with open_run(run_dir, checkpoint) as stop:
        run = _LeanRun(run_dir, config, checkpoint, stop, device=device, verbose=verbose)
        run.eval_env = make_eval_env(config)
        try:
            run.prepare_folder()
            run.build()
            run.start(stagger)
            run.train(progress_bar)
            run.finish()
        finally:
            if run.env is not None:
                run.env.close()
            run.eval_env.close()
        return run.session.end(run.n, run.best, run.interrupted)


class _LeanRun:
    """One session of :func:`learn`, one method per step: the run folder (a new one, or the checkpoint resumed and
    the folder rolled back to it), the model and envs, the start (reset, stagger, the evaluation a kill cut
    short), the training loop with its checkpoints and evaluations, the last checkpoint and the final agent."""

    def __init__(self, run_dir, config: RunConfig, checkpoint, stop, *, device, verbose):
        self.run_dir, self.config, self.checkpoint, self.stop = run_dir, config, checkpoint, stop
        self.device, self.verbose = device, verbose
        self.policy_name, self.kwargs = config.ppo_arguments()
        self.mode = config.mode
        self.n_envs, self.total = config.n_envs, config.n_timesteps
        self.clock = PhaseClock()
        self.env = self.eval_env = self.model = self.norm = None
        self.interrupted = None

    def prepare_folder(self) -> None:
        """A fresh run: the folder cleared and its configuration written; a resumed one: its checkpoint loaded
        (on the evaluation env's spaces, as vcnc_agents.training does), then the folder rolled back to it.  The
        monitor files are opened (for appending) only after that (:func:`vcnc_agents.run_session.roll_back_to`)."""
        rolled_back = None
        if self.checkpoint is None:
            self.done = start_folder(self.run_dir, self.config)
            if self.config.init_from is not None:  # a warm start (vcnc_agents.warm_start): the agent's weights
                from .warm_start import load_init_agent

                self.model, stats = load_init_agent(
                    self.config,
                    env_space=self.eval_env.observation_space,
                    action_space=self.eval_env.action_space,
                    layout=self.eval_env.unwrapped.layout,
                    device=self.device,
                )
                self.norm = RunningNormalizer(stats, self.n_envs)
        else:
            from .model_file import load_ppo

            self.done, model_zip, norm_file = self.checkpoint
            space = agent_space(self.eval_env.observation_space, self.mode.history, self.eval_env.unwrapped.layout)
            self.model = load_ppo(
                model_zip,
                observation_space=space,
                action_space=self.eval_env.action_space,
                ppo_kwargs=self.kwargs,
                device=self.device,
            )
            self.norm = RunningNormalizer(NormalizationStats.load(norm_file), self.n_envs)
            rolled_back = roll_back_to(self.run_dir, self.config, self.done)
        self.session = Session(
            self.run_dir, self.config, self.done, vec_env="native", rolled_back=rolled_back, clock=self.clock
        )

    def build(self) -> None:
        """The training envs, the model (fresh unless resumed), the trainer and the evaluations logged so far."""
        from stable_baselines3 import PPO

        config, done, n_envs = self.config, self.done, self.n_envs
        self.env = env = DecisionEnv(
            config.env_id,
            n_envs,
            self.mode,
            config.env_kwargs,
            config.seed + done,
            monitor_dir=self.run_dir / "monitor",
            start_steps=done,
            append=self.checkpoint is not None,
        )
        if self.model is None:
            stub = _spaces_only(env.observation_space, env.action_space, n_envs)
            self.model = PPO(self.policy_name, stub, seed=config.seed, device=self.device, **self.kwargs)
            self.norm = RunningNormalizer.fresh(config.hyperparams, env.observation_space.shape[0], n_envs)
        self.model.num_timesteps = done
        self.ppo = LeanPPO(self.model, env, self.norm, self.total, self.clock)
        self.rows = read_evaluations(self.run_dir / "evaluations.csv")
        self.best = best_of(self.rows)
        # as the SB3 trainer's callback: the schedule is the grid of multiples of eval_freq, so an evaluation
        # that a kill cut short (its checkpoint saved, its row not written) is made up at the session's start
        self.last_eval = max((r["steps"] for r in self.rows), default=0)
        self.last_checkpoint = done

    def start(self, stagger: bool) -> None:
        """The envs reset (and staggered), the trainer started; the evaluation of the checkpoint resumed from, if a
        kill cut it short."""
        self.session.start_clock()  # set-up excluded, as vcnc_agents.training.learn's wall time
        t0 = time.perf_counter()
        with self.clock("env"):
            obs = self.env.reset()
            if stagger:  # every session: a resumed one starts its envs afresh, in phase
                obs = self.env.stagger(obs)
        self.session.row["stagger_s"] = round(time.perf_counter() - t0, 3)
        self.ppo.start(obs)
        eval_freq, done = self.config.eval_freq, self.done
        if eval_freq > 0 and done > 0 and done // eval_freq > self.last_eval // eval_freq:
            self.evaluate(done)
        self.n = done

    def train(self, progress_bar: bool) -> None:
        """Rollouts and updates up to the run's steps or a stop signal, with the checkpoints and evaluations due."""
        ppo, step = self.ppo, self.ppo.n_steps * self.n_envs
        checkpoint_freq, eval_freq, total = self.config.checkpoint_freq, self.config.eval_freq, self.total
        bar = _progress(progress_bar, total, self.done)
        while self.n < total:
            ppo.collect()
            if self.stop.signum is not None:  # the rollout is not trained: the checkpoint is the model as of n
                self.interrupted = self.stop.name
                break
            with self.clock("update"):
                ppo.update(self.n)
            n = self.n = self.n + step
            self.model.num_timesteps = n
            if bar is not None:
                bar.update(step)
            due_eval = eval_freq > 0 and n // eval_freq > self.last_eval // eval_freq and n < total
            if n < total and (due_eval or n // checkpoint_freq > self.last_checkpoint // checkpoint_freq):
                self.save_checkpoint(n)
            if due_eval:
                self.evaluate(n)
        if bar is not None:
            bar.close()

    def finish(self) -> None:
        """The last checkpoint; unless interrupted, the last evaluation (if not just made) and the final agent."""
        n = self.n
        self.save_checkpoint(n)
        if self.interrupted is None:
            if n != self.last_eval or not self.rows:
                self.evaluate(n)
            save_agent(self.run_dir / "final", self.model, self.norm.stats(), self.config, n)

    def save_checkpoint(self, n: int) -> None:
        model_zip, norm_file = checkpoint_files(self.run_dir / "checkpoints", n)
        model_zip.parent.mkdir(parents=True, exist_ok=True)
        self.norm.stats().save(norm_file)
        self.model.num_timesteps = n
        save_model(self.model, model_zip)
        self.last_checkpoint = n
        self.session.checkpointed(n, self.best)

    def evaluate(self, n: int) -> None:
        """One deterministic episode of the agent on the evaluation env, logged; the best agent kept."""
        self.last_eval = n
        stats = self.norm.stats()
        row = evaluate_model(self.model, stats, self.config, self.eval_env, n)
        score = row["score_um"]
        self.rows.append(row)
        write_evaluations(self.run_dir / "evaluations.csv", self.rows)
        if math.isfinite(score) and (self.best is None or score < self.best["score_um"]):
            self.best = row
            save_agent(self.run_dir / "best", self.model, stats, self.config, n, row)
        if self.verbose:
            print(
                f"eval at {n} steps: max {row['max_um']:.2f} um, RMS {row['rms_um']:.2f} um, diverged {row['diverged']}"
            )


def _progress(enabled: bool, total: int, done: int):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=done, unit="step", desc="lean PPO")


def train_lean(
    env_id: str | None = None,
    run_dir=None,
    *,
    progress_bar: bool = True,
    device: str = "cpu",
    verbose: int = 0,
    stagger: bool = True,
    **options,
):
    """:func:`vcnc_agents.run_session.prepare_run` (``options``: n_timesteps, seed, n_envs, config_file, action_mode,
    resume, checkpoint_freq, eval_freq) then :func:`learn`; the :class:`vcnc_agents.run_session.TrainingResult`."""
    run_dir, config, checkpoint = prepare_run(env_id, run_dir, **options)
    return learn(
        run_dir, config, checkpoint, progress_bar=progress_bar, device=device, verbose=verbose, stagger=stagger
    )
