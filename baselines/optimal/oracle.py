"""The optimal-control floor (``oracle``): the input sequence optimised on the exact plant, replayed.

For each env and each plant instance the oracle holds the best input it found offline with what no causal
controller may read: the exact plant (its true, possibly randomised parameters, saturation, friction, backlash
and shop-floor effects) and the whole reference.  It is the best causal controller of :mod:`vcnc_baselines` on that
plant (closed-loop, its compiled form in the loop) plus an additive correction of its command at every decision
step, found by :func:`vcnc_baselines.optimal.search.solve`: every candidate is a whole episode of the env's own step
kernel on the exact plant, starting from every causal controller that applies (QFT, contouring FB, ``ff-pid``,
... : the best is the start), then inverse-model learning with a population of gains, then a cross-entropy
search in windows around the largest contour errors.  The objective is the max contour error, then the RMS.
The start is kept where the search does not improve on it, so the floor is at or below every causal controller
of the suite on every plant by construction (``tests/test_oracle.py``).

The figure reported is the replay: :meth:`OraclePolicy.predict` returns the start's command plus the
correction, ``clip(float32(u_c) + float32(c_k), -1, 1)``, the arithmetic the search's kernel ran, so the
env's episode reproduces the searched figure to the bit (checked each time a stored solution is loaded: by a
rollout of its own, or, in the bench, by the bench's episode itself, ``check_by_episode``).

**Shop-floor noise.**  The feedback of the start sees the sensor's noise.  The oracle copies the plant's noise
generator state from the env right after its reset, so the search runs on the very noise realisation the
episode will see: the floor is deterministic per seed and keyed by it (a plant without noise is keyed without
it).  A solution does not carry over to another seed's noise (its replay stays a valid, not an optimal, input).

**Cache.**  A solve costs minutes (``python benchmarks/oracle_convergence.py``), so solutions are stored
(:mod:`vcnc_baselines.optimal.solutions`): the nominal plant of every contouring id is shipped; another plant or seed
is solved on first use and stored where the directory is writable; ``VCNC_ORACLE_RECOMPUTE=1`` solves again.
A stored solution whose starts do not include a causal controller registered since is solved again.

It is **non-causal** (:attr:`OraclePolicy.causal` is False): it reads the plant it runs on through
:meth:`OraclePolicy.plan`, which the evaluation loops (:func:`vcnc_gym.evaluation.run_episode`,
:func:`vcnc_bench.robust.run_plants`) call after every reset.  It is never counted as a controller: the
bench marks it in every table; it shows how much headroom every controller leaves.
"""

from __future__ import annotations

import time
import warnings
from types import SimpleNamespace

import numpy as np

from vcnc_gym.validation import flag, integer

from ..base import BaselinePolicy
from ..registry import make, register_floor
from ..servo import ServoPolicy
from . import solutions
from .open_loop import OpenLoopPolicy
from .rollout import Rollouts, figures
from .search import Solution, causal_names, solve

__all__ = ["OraclePolicy"]


class OraclePolicy(BaselinePolicy):
    """The best causal controller plus an input correction optimised on the exact plant: a non-causal floor.

    Parameters
    ----------
    layout, decision_period, nominal_parameters, plant
        As :class:`~vcnc_baselines.base.BaselinePolicy`.
    population, ilc_iterations, rounds, generations, windows, trials, seed
        The search's budget (:func:`vcnc_baselines.optimal.search.solve`); the defaults made the shipped solutions.
    cache : bool
        Read and write stored solutions (:mod:`vcnc_baselines.optimal.solutions`); default True.
    check_by_episode : bool
        Default False: :meth:`plan` replays every stored solution it loads (a rollout of the exact plant) and solves
        again one that does not reproduce its figure.  True: the caller's episode is the replay (the bench's,
        :func:`vcnc_bench.runner.run_env`): :meth:`plan` loads without a replay of its own, and the caller passes
        the episode's result to :meth:`confirm`, which says whether it reproduced the stored figure (if not, the
        next :meth:`plan` solves again).  It spares the rollout kernel's compile per plant and start (4-7 s
        each on a cold cache).
    extra_starts : dict, optional
        Label -> a causal policy from outside :mod:`vcnc_baselines` (a trained agent: ``vcnc_agents.load_agent``), run as a
        start too (its recorded commands, open-loop); a stored solution without these labels among its starts is
        solved again.  ``benchmarks/oracle_convergence.py`` passes the shipped specialist of each id.

    Attributes
    ----------
    solve_time_s : float
        Wall time of the last :meth:`plan`, s (loading a stored solution: its replay check).
    solutions : list of Solution
        Per env of the last :meth:`plan`.
    """

    name = "oracle"
    #: Not a controller: it reads the exact plant (:meth:`plan`).
    causal = False
    designed_for = ServoPolicy.designed_for  # every plant the causal designs it starts from apply to
    needs_reference = True
    state_shape = (0,)

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        *,
        population: int = 16,
        ilc_iterations: int = 8,
        rounds: int = 8,
        generations: int = 12,
        windows: int = 3,
        trials: int = 10,
        seed: int = 0,
        cache: bool = True,
        check_by_episode: bool = False,
        extra_starts=None,
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        for key, value, low in (
            ("population", population, 4),
            ("ilc_iterations", ilc_iterations, 0),
            ("rounds", rounds, 0),
            ("generations", generations, 1),
            ("windows", windows, 1),
            ("trials", trials, 1),
            ("seed", seed, 0),
        ):
            integer(key, value, low)
        self.search = {
            "population": int(population),
            "ilc_iterations": int(ilc_iterations),
            "rounds": int(rounds),
            "generations": int(generations),
            "windows": int(windows),
            "trials": int(trials),
            "seed": int(seed),
        }
        self.cache = flag("cache", cache)
        self.check_by_episode = flag("check_by_episode", check_by_episode)
        self._unchecked: list[str] = []  # keys loaded without a replay, for confirm()
        self._stale: dict[str, int] = {}  # per key, how many of its stored solutions an episode did not reproduce
        self.extra_starts = dict(extra_starts or {})
        for label, policy in self.extra_starts.items():
            if not isinstance(label, str) or not hasattr(policy, "predict"):
                raise ValueError(
                    f"extra_starts must map labels to policies with predict(), got {label!r}: {type(policy).__name__}"
                )
        self.solve_time_s = float("nan")
        self.solutions: list[Solution] = []
        self._starts: list = []
        self._corrections: list[np.ndarray] = []
        self._steps: list[int] = []  # per env, decision steps since its episode's start
        self._planned_for = None

    @classmethod
    def from_env(cls, env, **params):
        """As :meth:`BaselinePolicy.from_env`; refuses an env whose reference is re-timed while it runs (a feed
        override), and one without a contour (the positioning env): the floor is searched about a contour's reference
        fixed before the episode."""
        u = getattr(env, "unwrapped", env)
        vec = hasattr(env, "get_attr") and hasattr(env, "env_method")  # an SB3 VecEnv: checked by plan()
        if not vec and not hasattr(getattr(u, "task", None), "reference_arrays"):
            raise ValueError(
                f"baseline {cls.name!r} searches a correction along a contour's reference: it needs a contouring "
                f"env (env.unwrapped.task.reference_arrays), got {type(u).__name__}"
            )
        if getattr(u, "retimes_reference", False):
            raise ValueError(
                f"baseline {cls.name!r} searches a correction about a reference fixed before the "
                f"episode; {type(env.unwrapped).__name__} re-times its reference while it runs (a feed "
                "override): there is no floor there"
            )
        return super().from_env(env, **params)

    def _initial_state(self):
        return np.zeros(0)

    #: :meth:`plan` searches each plant apart (minutes each) and takes ``progress``: the bench's bar shows it.
    plans_per_plant = True

    def plan(self, env, progress=None) -> None:
        """Find (or load) the floor for the plants ``env`` holds now, after its reset:
        ``env.unwrapped.parameters``, (2, P) for a single env or (N, 2, P) for a vector env.  ``progress``, if
        given, is called with (plants done, plants) after each plant's floor is solved or loaded."""
        u = getattr(env, "unwrapped", env)
        task = getattr(u, "task", None)
        if task is None or not hasattr(u, "parameters") or not hasattr(u, "_batch"):
            raise ValueError(f"the oracle plans on a vcnc_gym contouring env, got {type(env).__name__}")
        params = np.asarray(u.parameters, dtype=np.float64)
        single = params.ndim == 2  # a single env: its episode can confirm a stored solution (check_by_episode)
        params = params[None] if single else params
        arrays = u._batch.plant_arrays
        noise = [int(arrays.rng[i]) if hasattr(arrays, "rng") else None for i in range(params.shape[0])]
        fingerprint = (id(task), params.tobytes(), tuple(noise))
        if fingerprint == self._planned_for:
            return
        t0 = time.perf_counter()
        current = set(causal_names(env)) | set(self.extra_starts)
        self.solutions, self._starts, self._corrections = [], [], []
        unchecked = []
        for i, p in enumerate(params):
            key = solutions.signature(env, p, noise[i])
            stored = solutions.load_all(key) if self.cache and not solutions.recompute_requested() else []
            # a causal controller registered since must be among the starts; an episode did not reproduce the first
            # self._stale[key] of them (confirm)
            stored = [x for x in stored if current <= {k.split("#")[0] for k in x.warm_starts}][
                self._stale.get(key, 0) :
            ]
            sol, start = None, None
            for candidate in stored:
                sol, start = candidate, self._start(env, candidate, task, p)
                if self.check_by_episode and single:
                    unchecked.append(key)
                    break
                replay = self._replay(task, p, noise[i], start, sol.correction)
                if replay == (sol.max_um, sol.rms_um):
                    break
                warnings.warn(
                    f"the stored floor {key} replays to {replay[0]:.6g} um, not its {sol.max_um:.6g} um: "
                    "the next stored solution, else solving again",
                    stacklevel=2,
                )
                sol, start = None, None
            if sol is None:
                sol = solve(env, p, noise_state=noise[i], extra_starts=self.extra_starts or None, **self.search)
                start = self._start(env, sol, task, p)
                if self.cache:
                    solutions.store(key, sol)
            self.solutions.append(sol)
            self._starts.append(start)
            self._corrections.append(np.asarray(sol.correction, dtype=np.float32))
            if progress is not None:
                progress(i + 1, params.shape[0])
        self.reset(n_envs=params.shape[0])
        self._steps = [0] * params.shape[0]
        self.solve_time_s = time.perf_counter() - t0
        self._planned_for = fingerprint
        self._unchecked = unchecked

    def confirm(self, result) -> bool:
        """With ``check_by_episode``: whether the episode just run after :meth:`plan` (``result``, a
        :class:`~vcnc_gym.evaluation.EpisodeResult` of a single env) reproduced the stored solution's max contour
        error to the bit and its RMS to 1e-9 (the episode sums the squares in another order).  If not, a warning,
        and the next :meth:`plan` tries the key's next stored solution (another CPU's, :func:`solutions.load_all`),
        else solves again: run the episode again, until this is True.  True when nothing was loaded unchecked."""
        if not self._unchecked:
            return True
        key, sol = self._unchecked[0], self.solutions[0]
        self._unchecked = []
        peak, rms = float(result.max_contour_error_um), float(result.rms_contour_error_um)
        if peak == sol.max_um and abs(rms - sol.rms_um) <= 1e-9 * max(abs(sol.rms_um), 1e-300):
            return True
        warnings.warn(
            f"the stored floor {key} replays to {peak:.6g} um, not its {sol.max_um:.6g} um: the next "
            "stored solution, else solving again",
            stacklevel=2,
        )
        self._stale[key] = self._stale.get(key, 0) + 1
        self._planned_for = None
        return False

    @staticmethod
    def _start(env, sol: Solution, task, parameters):
        """The solution's start, built as the search built it: an @machine design commissioned on the machine
        ``parameters`` (2, P) the floor was solved on (:func:`~vcnc_baselines.optimal.search.warm_starts`), whichever
        plants ``env`` holds (a vector env's, or the nominal one it was built with)."""
        if sol.table is not None:
            return OpenLoopPolicy(sol.table)
        start = make(sol.start, env)
        if hasattr(start, "plan"):
            start.plan(SimpleNamespace(task=task, parameters=parameters))
        return start

    @staticmethod
    def _replay(task, parameters, noise_state, start, correction) -> tuple[float, float]:
        """Max and RMS contour error (um) of ``start`` plus ``correction`` on the exact plant."""
        rollouts = Rollouts(task, parameters, 1, noise_state)
        rollouts.set_controller(start)
        summary, _, _ = rollouts.run(np.asarray(correction, dtype=np.float32)[None])
        start.reset(n_envs=1)
        peak, rms = figures(summary)
        if not np.isfinite(peak[0]):
            peak, rms = summary[:, 0], np.sqrt(summary[:, 1] / np.maximum(summary[:, 2], 1))
        return 1e3 * float(peak[0]), 1e3 * float(rms[0])

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self._planned_for is None:
            raise RuntimeError(
                "the oracle has no plan: call plan(env) after the env's reset (the evaluation loops "
                "of vcnc_gym and vcnc_bench do)"
            )
        obs = np.asarray(observation)
        single = obs.ndim == 1
        obs2 = obs.reshape(1, -1) if single else obs
        n = obs2.shape[0]
        if n != len(self._starts):
            raise ValueError(f"the oracle planned for {len(self._starts)} envs, got {n} observations")
        if episode_start is None:
            start = np.zeros(n, dtype=bool)
        else:
            start = np.asarray(episode_start, dtype=bool).reshape(-1)
            start = np.repeat(start, n) if start.size == 1 and n > 1 else start
        steps = self._steps
        action = np.empty((n, 2), dtype=np.float32)
        one = np.float32(1.0)
        for i in range(n):
            if start[i]:
                steps[i] = 0
            base, _ = self._starts[i].predict(obs2[i : i + 1], episode_start=start[i : i + 1], deterministic=True)
            base = np.asarray(base, dtype=np.float32).reshape(2)
            c = self._corrections[i]
            row = c[min(steps[i], len(c) - 1)]
            # the kernel's arithmetic (rollout._rollout_env): float32 sums, clipped to [-1, 1]
            action[i, 0] = min(one, max(-one, base[0] + row[0]))
            action[i, 1] = min(one, max(-one, base[1] + row[1]))
            steps[i] += 1
        return (action[0] if single else action), state


register_floor(OraclePolicy)
