"""ContouringVectorEnv: N contouring envs stepped by one numba call.

``gym.make_vec("VCNC-Heart-v1", num_envs=N, vectorization_mode="vector_entry_point")``
returns this :class:`gymnasium.vector.VectorEnv`.  Its ``step`` is one call of
the same compiled body the single :class:`~vcnc_gym.envs.ContouringEnv` runs,
over all N envs at once and spread over the cores (numba ``prange``).  Each
env has its own plant parameters, random generator and episode; with the
same seeds env i gives bit-identical observations, rewards and flags to a
single env (``tests/test_vector_env.py``).
"""

from __future__ import annotations

import os
import time
from typing import Any

import numba
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..validation import flag, integer, positive
from . import controller_contract
from . import step_kernel as sk
from .contouring_env import check_actions, observation_space
from .decision import DecisionLoop, episode_summary
from .pickling import RebuiltOnUnpickle, batch_arrays, restore_arrays
from .rendering import EpisodeHistory, Renderer, render_every_argument, render_fps
from .signatures import forwarded_signature
from .task import ContouringBatch, ContouringTask

__all__ = ["ContouringVectorEnv", "KernelPath"]

#: Below this many envs one thread steps them all (a parallel launch costs more than it saves).
PARALLEL_MIN_ENVS = 16
#: numba's threading layer for the parallel kernels unless NUMBA_THREADING_LAYER names one.  numba's default here is
#: GNU OpenMP, and torch's wheel loads its own libgomp.so.1 under the same name: in one process (training, an agent
#: benchmarked) both run on one OpenMP runtime, and after parallel kernel calls torch's forward pass of a 64x64 MLP
#: on 256 observations ran 7-88x slower (``python benchmarks/numba_torch_threads.py``).  numba's own
#: workqueue pool shares nothing with torch.  It refuses parallel launches from two Python threads at once (this
#: package makes none).  Set before the first parallel launch, when numba reads it.
THREADING_LAYER = "workqueue"
if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = THREADING_LAYER
#: The automatic choice (``parallel=None``) tries the path it is not using once the calls since its last try took
#: this many times as long as that try: 1/(PROBE_RATIO + 1) of the time goes to trying a stalled path.
PROBE_RATIO = 50.0
#: Weight of a new call's time in the running estimate of its path's cost.
COST_WEIGHT = 0.2
#: Calls of a try of the other path; its first is not timed (threads asleep since the last try wake up late).
PROBE_CALLS = 8


class KernelPath:
    """The serial or the parallel kernel, whichever recently took less time per env control period.

    A parallel kernel call is a fork-join over numba's threads: it ends when
    the last thread does.  When another process holds a core, the thread
    waiting for it stalls every call by up to a scheduler time slice
    (milliseconds, against 0.05-1 ms of work per call): on a loaded 2-core
    machine 2 threads ran 2-20x slower than 1 (``benchmarks/vector_env.py``).
    So the vector env times its kernel calls, keeps a running cost per path
    (seconds per env control period, weight :data:`COST_WEIGHT`) and uses the
    cheaper; the other path is tried again (:data:`PROBE_CALLS` calls, the
    first not timed: threads asleep since the last try wake up late) once the
    calls since the last try took :data:`PROBE_RATIO` times as long as it
    did, so a machine that became idle (or busy) is noticed within a few
    tries, which take 1/(PROBE_RATIO + 1), about 2 %, of the time.  Both paths run the same body env by env, so the results do not
    depend on the path.  With one numba thread (``numba.set_num_threads(1)``)
    the serial path runs, without a parallel launch.
    """

    def __init__(self):
        self.cost = [None, None]  # seconds per env control period: serial, parallel (None: not yet timed)
        self.calls = [0, 0]  # calls made on each path: serial, parallel
        self._seen = [False, False]  # the first call of a path (compilation, cache load) is not timed
        self._since_probe = 0.0  # wall time of the calls on the cheaper path since the last try ended
        self._wait = None  # _since_probe that starts the next try: PROBE_RATIO x the last try's time
        self._trying = 0  # calls left of the current try
        self._try_path = False
        self._try_time = 0.0
        self._work = 1.0

    def choose(self, work: float) -> bool:
        """True for the parallel path for a call of ``work`` env control periods."""
        if numba.get_num_threads() == 1:
            return False
        self._work = work
        serial, parallel = self.cost
        if serial is None or parallel is None:
            return serial is not None  # time the serial path first, then the parallel one
        if self._trying:
            return self._try_path
        best = parallel < serial
        wait = self._wait if self._wait is not None else PROBE_RATIO * PROBE_CALLS * self.cost[not best] * work  # pyright: ignore[reportOperatorIssue]
        if self._since_probe >= wait:
            self._trying, self._try_path, self._try_time = PROBE_CALLS, not best, 0.0
            return not best
        return best

    def best(self) -> bool:
        """True when the parallel path is the cheaper one so far (for untimed calls: resets)."""
        serial, parallel = self.cost
        return numba.get_num_threads() > 1 and serial is not None and parallel is not None and parallel < serial

    def record(self, parallel: bool, seconds: float) -> None:
        """Account a call of the path :meth:`choose` returned that took ``seconds``."""
        if numba.get_num_threads() == 1:
            return
        self.calls[parallel] += 1
        if self._trying:
            self._trying -= 1
            self._try_time += seconds
            if self._trying < PROBE_CALLS - 1:  # the try's first call is not timed
                self._update(parallel, seconds)
            if not self._trying:
                self._since_probe, self._wait = 0.0, PROBE_RATIO * self._try_time
            return
        if not self._seen[parallel]:
            self._seen[parallel] = True
            return
        self._update(parallel, seconds)
        self._since_probe += seconds

    def _update(self, parallel: bool, seconds: float) -> None:
        """Running cost of a path; a call above twice the estimate counts as twice it (a call the OS preempted
        once must not send the choice to the other path, a path whose every call stalls still climbs)."""
        cost = seconds / self._work
        old = self.cost[parallel]
        self.cost[parallel] = cost if old is None else old + COST_WEIGHT * (min(cost, 2.0 * old) - old)  # pyright: ignore[reportCallIssue, reportArgumentType]


class ContouringVectorEnv(RebuiltOnUnpickle, VectorEnv):
    """``num_envs`` contouring envs of one configuration, stepped by one kernel call.

    Parameters
    ----------
    num_envs : int
        Number of envs N, >= 1.
    autoreset_mode : gymnasium.vector.AutoresetMode or str
        ``NEXT_STEP`` (Gymnasium's default: the step after an episode ends
        resets that env and returns its first observation with reward 0),
        ``SAME_STEP`` (the ending step resets it at once; the last
        observation and info are in ``info["final_obs"]`` and
        ``info["final_info"]``) or ``DISABLED`` (reset finished envs with
        ``reset(options={"reset_mask": mask})``).
    parallel : bool, optional
        True: spread the envs over numba's threads on every call; False: one
        thread.  Default (None): one thread below 16 envs, else whichever of
        the two recently stepped faster (:class:`KernelPath`: on a core
        another process uses, a parallel call waits for its thread).
    render_mode : str, optional
        "rgb_array": :meth:`render` draws env 0's episode (the other envs are not drawn); None (default): no
        rendering.
    render_every : int, optional
        Decisions between two new pictures of :meth:`render` (default: about 30 per simulated second, as
        :class:`~vcnc_gym.envs.ContouringEnv`'s).
    **kwargs
        The arguments of :class:`~vcnc_gym.envs.ContouringEnv` (contour,
        plant, feedrate, dt, action_repeat, randomize, parameters, ...).

    Notes
    -----
    ``reset(seed=s)`` seeds env i with ``s + i`` (as ``SyncVectorEnv`` does),
    or with ``seed[i]`` for a list.  ``reset(options=...)`` takes
    ``"parameters"`` ((2, P) for every env or (N, 2, P)) and
    ``"reset_mask"`` ((N,) bool: reset only those envs).  ``info`` follows
    Gymnasium's vector convention: one array per key, with a boolean mask
    ``"_key"`` of the envs it is valid for.

    ``pickle.dumps`` saves the constructor's arguments, every env's generator
    and episode state: the unpickled vector env continues the same episodes
    (:mod:`vcnc_gym.envs.pickling`).
    """

    #: ``render_fps`` is the default configuration's; each vector env sets its own, ``1 / decision_period``.
    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"], "render_fps": 10000}

    def __init__(
        self,
        num_envs: int = 1,
        *,
        autoreset_mode=AutoresetMode.NEXT_STEP,
        parallel: bool | None = None,
        render_mode: str | None = None,
        render_every: int | None = None,
        **kwargs,
    ):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(
                f"the vector env renders env 0 with render_mode='rgb_array' (or None), got {render_mode!r}; make a "
                "single env with render_mode='human' to watch one in a window"
            )
        self.task = ContouringTask(**kwargs)
        self._batch = ContouringBatch(self.task, num_envs, argument="num_envs")
        self.num_envs = self._batch.n_envs
        try:
            self.autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(
                f"autoreset_mode must be one of {[m.value for m in AutoresetMode]}, got {autoreset_mode!r}"
            ) from None
        self.render_every = render_every_argument(render_every, self.task.decision_period)
        self.metadata = {
            **self.metadata,
            "autoreset_mode": self.autoreset_mode,
            "render_fps": render_fps(self.task.decision_period),
        }
        self.parallel = self.num_envs >= PARALLEL_MIN_ENVS if parallel is None else flag("parallel", parallel)
        self._path = KernelPath() if parallel is None and self.parallel else None
        b = self._batch.buffers
        self._buffers = b
        self._decision = DecisionLoop(self.task, self.num_envs) if self.task.controlled else None
        self._scale = self.task.layout.scale_vector().astype(np.float32) if self.task.layout.is_scaled else None
        self.single_observation_space = observation_space(self.task.layout)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.layout = self.task.layout
        self.render_mode = render_mode
        self._renderer = None if render_mode is None else Renderer(self.task, render_mode, self.render_every)
        self._history: dict | None = None  # env 0's episode, drawn by render()
        self._rngs = [seeding.np_random(None)[0] for _ in range(self.num_envs)]
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._all = np.ones(self.num_envs, dtype=bool)
        self._started = False

    # -- the task, read-only ----------------------------------------------------------
    plant = property(lambda self: self.task.plant, doc="The plant model (vcnc_gym.plants.PlantModel).")
    dt = property(lambda self: self.task.dt, doc="Control period in s.")
    decision_period = property(lambda self: self.task.decision_period, doc="dt * action_repeat in s.")
    episode_steps = property(lambda self: self.task.episode_steps, doc="Natural episode length in decisions.")
    nominal_parameters = property(lambda self: self.task.nominal_parameters, doc="Nominal (2, P) parameters.")

    @property
    def parameters(self) -> np.ndarray:
        """The plant parameters in force, (N, 2, P) (a copy)."""
        return self._batch.parameters.copy()

    @property
    def np_random(self):
        """The generators of the envs, a list (env i draws its plant from ``np_random[i]``)."""
        return self._rngs

    # -- Gymnasium API ----------------------------------------------------------
    def reset(self, *, seed=None, options: dict[str, Any] | None = None):
        """Reset every env, or those of ``options["reset_mask"]``; see the class notes for seeds and options."""
        n = self.num_envs
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        mask = self._all if mask is None else self._check_mask(mask)
        seeds = self._seeds(seed)
        parameters = options.pop("parameters", None)
        if parameters is not None:
            p = np.asarray(parameters)
            per_env = [p] * n if p.ndim == 2 else list(p)
            if len(per_env) != n:
                raise ValueError(f"parameters must be (2, P) or ({n}, 2, P), got shape {p.shape}")
        b = self._buffers
        b.mode[:] = sk.MODE_IDLE
        for i in np.flatnonzero(mask):
            if seeds[i] is not None:
                self._rngs[i] = seeding.np_random(seeds[i])[0]
            opts = dict(options)
            if parameters is not None:
                opts["parameters"] = per_env[i]
            self._reset_env(i, self.task.parameters_for_reset(self._rngs[i], opts or None))  # pyright: ignore[reportArgumentType]  (an index)
        self._batch.run(self._observe_parallel())
        self._autoreset[mask] = False
        self._started = True
        self._record_env0(started=bool(mask[0]), stepped=False)
        return self._observations(), self._info(mask)

    # -- pickling (vcnc_gym.envs.pickling) ----------------------------------------
    def _episode_arrays(self) -> dict[str, np.ndarray]:
        arrays = batch_arrays(self._batch)
        if self._decision is not None:
            arrays.update(self._decision.arrays())
        return arrays

    def _episode_state(self) -> dict:
        return {
            "arrays": {name: a.copy() for name, a in self._episode_arrays().items()},
            "rngs": self._rngs,
            "autoreset": self._autoreset,
            "started": self._started,
            "spec": self.spec,
        }

    def _restore_episode(self, state: dict) -> None:
        restore_arrays(self._episode_arrays(), state["arrays"])
        self._rngs, self._autoreset = list(state["rngs"]), state["autoreset"].copy()
        self._started, self.spec = state["started"], state["spec"]

    def step(self, actions):
        if not self._started:
            raise RuntimeError("step() called before reset()")
        b = self._buffers
        b.action[...] = check_actions(actions, (self.num_envs, 2))
        resetting = self._autoreset.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP else None
        b.mode[:] = sk.MODE_STEP
        if resetting is not None and resetting.any():
            for i in np.flatnonzero(resetting):
                self._reset_env(i, self.task.parameters_for_reset(self._rngs[i], None))  # pyright: ignore[reportArgumentType]  (an index)
        elif self.autoreset_mode == AutoresetMode.DISABLED and self._autoreset.any():
            b.mode[self._autoreset] = sk.MODE_IDLE
        stepped = self._all if resetting is None else ~resetting
        if self.autoreset_mode == AutoresetMode.DISABLED:
            stepped = stepped & ~self._autoreset
        rewards, before = self._decide(resetting)
        terminated = b.flags[:, sk.FLAG_TERMINATED].copy()
        truncated = b.flags[:, sk.FLAG_TRUNCATED].copy()
        if not stepped.all():
            terminated[~stepped] = False
            truncated[~stepped] = False
            rewards[~stepped] = 0.0
        info = self._info(stepped)
        done = terminated | truncated
        self._decision_info(info, stepped, done, before)
        self._autoreset = done | (
            self._autoreset & ~stepped if self.autoreset_mode == AutoresetMode.DISABLED else False
        )
        obs = self._observations()
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            info["final_obs"] = np.full(self.num_envs, None, dtype=object)
            info["final_info"] = {k: v.copy() for k, v in info.items() if k != "final_obs"}
            info["_final_obs"] = done.copy()
            info["_final_info"] = done.copy()
            for i in np.flatnonzero(done):
                info["final_obs"][i] = obs[i].copy()
            b.mode[:] = sk.MODE_IDLE
            for i in np.flatnonzero(done):
                self._reset_env(i, self.task.parameters_for_reset(self._rngs[i], None))  # pyright: ignore[reportArgumentType]  (an index)
            self._batch.run(self._observe_parallel())
            obs[done] = self._observations()[done]
            self._autoreset[:] = False
        restarted = (resetting is not None and resetting[0]) or (
            self.autoreset_mode == AutoresetMode.SAME_STEP and done[0]
        )
        self._record_env0(started=bool(restarted), stepped=bool(stepped[0]))
        return obs, rewards, terminated, truncated, info

    def step_controlled(self, controller, actions, correction: float, repeat: int, active=None):
        """One decision of ``repeat`` control periods per env, a compiled controller in the loop: one kernel call.

        Each control period env i commands ``clip(u_c / u_max + correction * a_i, -1, 1)`` (float32), u_c the
        controller's command on the period's observation and ``a_i = clip(actions[i], -1, 1)`` held: the
        residual action mode (``vcnc_agents.action_modes``) without a Python call per period.  An env whose
        episode ends inside the decision stops there.  Only with ``autoreset_mode=AutoresetMode.DISABLED``:
        finished envs wait for ``reset(options={"reset_mask": ...})``.

        Parameters
        ----------
        controller : namedtuple
            A controller's compiled form, ``BaselinePolicy.compiled(num_envs)``
            (:mod:`~vcnc_gym.envs.controller_contract`).
        actions : array_like, (num_envs, 2)
            The agent's corrections, finite (clipped to [-1, 1], then float32).
        correction : float
            Largest correction as a fraction of u_max, > 0.
        repeat : int
            Control periods per decision, >= 1.
        active : array_like of bool, (num_envs,), optional
            Step only these envs; the others hold (reward 0, no flags), as finished ones do.

        Returns
        -------
        obs, rewards, terminated, truncated, info
            As :meth:`step`, but ``rewards`` is the sum of the periods' rewards, ``info`` each env's last
            period's, and ``info["contour_error_max"]`` the largest contour error of the decision (mm).
        """
        if self.autoreset_mode != AutoresetMode.DISABLED:
            raise ValueError(
                f"step_controlled needs autoreset_mode=AutoresetMode.DISABLED, this env has {self.autoreset_mode}"
            )
        if not self._started:
            raise RuntimeError("step_controlled() called before reset()")
        n = self.num_envs
        controller_contract.check_controller(controller, n)
        agent = check_actions(actions, (n, 2)).astype(np.float32)
        loop = sk.ControlLoop(
            agent,
            np.float32(positive("correction", correction, "fraction of u_max")),
            integer("repeat", repeat, 1),
            np.zeros((n, 2)),
            np.zeros(n),
            np.zeros(n),
        )
        stepped = ~self._autoreset if active is None else ~self._autoreset & self._check_mask(active, "active")
        b = self._buffers
        b.mode[:] = sk.MODE_STEP
        b.mode[~stepped] = sk.MODE_IDLE
        self._run(loop.repeat, controller, loop)
        terminated = b.flags[:, sk.FLAG_TERMINATED] & stepped
        truncated = b.flags[:, sk.FLAG_TRUNCATED] & stepped
        rewards = np.where(stepped, loop.reward, 0.0)
        info = self._info(stepped)
        info["contour_error_max"] = loop.peak
        self._autoreset = self._autoreset | terminated | truncated
        self._record_env0(started=False, stepped=bool(stepped[0]))
        return b.obs.copy(), rewards, terminated, truncated, info

    # -- rendering: env 0 (vcnc_gym.envs.rendering) -------------------------------------
    def render(self) -> tuple | None:
        """Env 0's episode so far, as a tuple of one RGB array (H, W, 3) uint8 (``render_mode="rgb_array"``): a
        new picture once ``render_every`` decisions have passed since the last, and at its episode's end; the
        last one in between.  The other envs are not drawn."""
        if self._renderer is None:
            return None
        return (self._renderer.render(self._history, bool(self._autoreset[0])),)

    def _record_env0(self, started: bool, stepped: bool) -> None:
        """Env 0's history for :meth:`render`: a new episode (``started``) or one more decision (``stepped``)."""
        if self._renderer is None:
            return
        row = self._buffers.info[0]
        if started or self._history is None:
            history = EpisodeHistory()
            history.start(row, sk.INFO_FIELDS)
            self._history = history.data
            self._renderer.restart()
        elif stepped:
            EpisodeHistory(self._history).append(self._buffers.k[0] * self.task.dt, row, sk.INFO_FIELDS)

    def close_extras(self, **kwargs):
        if self._renderer is not None:
            self._renderer.close()

    # -- the learnable action types (vcnc_gym.envs.decision) ---------------------------
    def _reset_env(self, i: int, parameters: np.ndarray) -> None:
        """Env ``i`` at the start of an episode on the plant ``parameters``, its controller's memory cleared."""
        self._batch.reset_env(i, parameters, self._rngs[i])
        if self._decision is not None:
            self._decision.reset_env(i, parameters)

    def _decide(self, resetting):
        """One decision of every env in MODE_STEP with ``self._buffers.action``'s actions; the envs just reset
        (``resetting``) observe.  Returns the rewards and the episode accumulators before the decision."""
        b = self._buffers
        d = self._decision
        if d is None:
            self._run(1)
            return b.reward.copy(), None
        before = b.episode.copy()
        d.set_actions(b.action, Ellipsis if resetting is None else ~resetting)
        self._run(d.repeat, d.controller, d.loop)
        if resetting is not None and resetting.any():  # the controlled loop steps only; the reset envs observe
            b.mode[~resetting] = sk.MODE_IDLE
            self._batch.run(self._observe_parallel())
        return d.rewards(), before

    def _decision_info(self, info: dict, stepped: np.ndarray, done: np.ndarray, before) -> None:
        """The learnable action types' per-decision keys (:func:`~vcnc_gym.envs.contouring_env.decision_info`) and
        the episode summary of every env whose episode ended (``info["episode_summary"]``, a dict of arrays)."""
        b = self._buffers
        if before is not None:
            ep = b.episode
            periods = np.maximum(ep[:, sk.EPISODE_PERIODS] - before[:, sk.EPISODE_PERIODS], 1.0)
            for key in ("contour_error_max", "contour_error_mean"):
                del info[key], info["_" + key]
            info["step_contour_error_max"] = self._decision.loop.peak.copy()  # pyright: ignore[reportOptionalMemberAccess]
            info["step_contour_error_mean"] = (ep[:, sk.EPISODE_SUM] - before[:, sk.EPISODE_SUM]) / periods
            info["_step_contour_error_max"] = stepped.copy()
            info["_step_contour_error_mean"] = stepped.copy()
        ended = done & stepped
        if ended.any():
            rows = [episode_summary(b, i) if ended[i] else None for i in range(self.num_envs)]
            keys = next(r for r in rows if r is not None).keys()
            summary = {k: np.array([np.nan if r is None else r[k] for r in rows]) for k in keys}
            for k in ("completed", "diverged"):
                summary[k] = summary[k] == 1.0
            summary.update({"_" + k: ended.copy() for k in keys})
            info["episode_summary"] = summary
            info["_episode_summary"] = ended.copy()

    def _observations(self) -> np.ndarray:
        """The observations the agents see: the kernel's, scaled, with each agent's last action under the learnable
        action types."""
        obs = self._buffers.obs.copy()
        if self._decision is not None:
            obs[:, self.task.layout.slice("previous_action")] = self._decision.last_action
        if self._scale is not None:
            obs /= self._scale
        return obs

    # -- helpers --------------------------------------------------------------------
    def _run(self, repeat: int, controller=None, loop=None) -> None:
        """One stepping kernel call (with ``controller`` in the loop if given) on the path of ``self._path``."""
        path = self._path
        parallel = self.parallel if path is None else path.choose(self.num_envs * repeat)
        t0 = time.perf_counter()
        if controller is None:
            self._batch.run(parallel)
        else:
            self._batch.run_controlled(controller, loop, parallel)  # pyright: ignore[reportArgumentType]
        if path is not None:
            path.record(parallel, time.perf_counter() - t0)

    def _observe_parallel(self) -> bool:
        """The path of an untimed call (observations after resets): the forced one, or the cheaper so far."""
        return self.parallel if self._path is None else self._path.best()

    def _seeds(self, seed) -> list:
        n = self.num_envs
        if seed is None:
            return [None] * n
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            if seed < 0:
                raise ValueError(f"seed must be >= 0, got {seed}")
            return [int(seed) + i for i in range(n)]
        seeds = list(seed)  # pyright: ignore[reportArgumentType]
        if len(seeds) != n:
            raise ValueError(f"seed must be an int or a sequence of {n} seeds, got {len(seeds)}")
        return seeds

    def _check_mask(self, mask, name: str = "reset_mask") -> np.ndarray:
        m = np.asarray(mask)
        if m.shape != (self.num_envs,) or m.dtype != np.bool_:
            raise ValueError(f"{name} must be a ({self.num_envs},) bool array, got {m.dtype} {m.shape}")
        return m

    def _info(self, valid: np.ndarray) -> dict:
        b = self._buffers
        info: dict[str, Any] = {}
        values = b.info.copy()  # one copy; the keys' arrays are views of it
        for key, (col, width) in sk.INFO_FIELDS.items():
            info[key] = values[:, col] if width == 1 else values[:, col : col + width]
            info["_" + key] = valid.copy()
        info["diverged"] = b.flags[:, sk.FLAG_DIVERGED].copy()
        info["_diverged"] = valid.copy()
        info["completed"] = b.flags[:, sk.FLAG_COMPLETED].copy()
        info["_completed"] = valid.copy()
        info["_cycle_time"] = valid & info["completed"]  # only once the tool has arrived
        info["time"] = b.k * self.task.dt
        info["_time"] = valid.copy()
        return info


ContouringVectorEnv.__init__.__signature__ = forwarded_signature(ContouringVectorEnv.__init__, ContouringTask.__init__)
