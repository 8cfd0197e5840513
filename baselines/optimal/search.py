"""The floor's offline solve: the whole input sequence optimised on the exact plant.

:func:`solve` finds, for one plant instance of one task, the open-loop input sequence (the normalised command
``u / u_max`` per decision step) with the least max contour error (then RMS), every candidate a whole episode of
the exact simulator (:class:`~vcnc_baselines.optimal.rollout.Rollouts`: the env's own step kernel, the plant's true
saturation, friction, backlash and shop-floor effects).  Three stages, every figure the replayed one:

1. **Warm starts** (:func:`warm_starts`): every causal controller of :mod:`vcnc_baselines` that applies to the env
   runs closed-loop on the exact plant (with the env's noise realisation on the shop floor), and its applied
   commands are recorded; a learning controller (ILC) runs ``trials`` trials and each trial is a start.
   Replayed open-loop, a recorded sequence reproduces its run's true trajectory to the bit (the plant is
   deterministic given its input; the shop floor's noise is in the sensor only).  The best start (max, then
   RMS) is the incumbent: so the floor is at or below every causal controller by construction.
2. **Inverse-model learning** with a population of gains (the old oracle's update, now open-loop and
   everywhere): ``U + gamma Q(P^{-1} e_n)``, ``e_n`` the incumbent's true tracking error along the contour
   normal, ``P^{-1}`` the exact plant's linear inverse (:func:`vcnc_baselines.inverse_model.linear_inverse`),
   ``Q`` a zero-phase Butterworth low-pass; each candidate is scored on the exact plant and kept only if
   better (a learning step that drifts is never kept).
3. **Cross-entropy search** (Rubinstein 1999; de Boer et al. 2005) in windows around the incumbent's largest
   errors: per window and axis, Gaussian bumps of a position displacement ``delta x(t) = sum theta_b
   g_b(t)`` (mm) turned into an input through the same linear inverse, so that a bump moves the table
   locally instead of leaving an offset behind; a diagonal Gaussian over ``theta`` refit to the elite each
   generation, the windows re-chosen each round.

The objective is lexicographic (max, then RMS): a candidate replaces the incumbent when its max is lower, or
equal with a lower RMS.  Candidates that diverge or do not finish the part score infinity.
"""

from __future__ import annotations

import time
from types import SimpleNamespace
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.envs.task import ContouringBatch
from ..inverse_model import linear_inverse
from .open_loop import OpenLoopPolicy
from .rollout import Rollouts, figures, OUT_COMPLETED

__all__ = ["Solution", "solve", "warm_starts", "causal_names"]


@dataclass
class Solution:
    """An input sequence and its replayed figures.

    Attributes
    ----------
    start : str
        The best causal start's name (a registry name; ``ilc#3``, a learning controller's third trial).
    correction : ndarray, (L, 2) float32
        Normalised correction added to the start's command at each decision step (0 beyond L).
    table : ndarray or None, (L', 2)
        The start's recorded commands where it runs open-loop (no compiled form, or a learning controller's
        trial); None where the start runs closed-loop.
    max_um, rms_um : float
        Contour error of its replay on the exact plant, um.
    warm_starts : dict
        Name -> (max um, rms um) of every causal controller run as a start.
    history : ndarray, (H, 2)
        (evaluations, incumbent max um) after each generation: the convergence.
    solve_time_s : float
    evaluations : int
        Whole episodes simulated.
    """

    start: str
    correction: np.ndarray
    table: np.ndarray | None
    max_um: float
    rms_um: float
    warm_starts: dict = field(default_factory=dict)
    history: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    solve_time_s: float = float("nan")
    evaluations: int = 0


def causal_names(env) -> list[str]:
    """The causal controllers of :mod:`vcnc_baselines` (registry names and variants) that apply to ``env``: designed
    for its plant, given a reference where they need one, and the env takes two axis commands (so not those that set
    the feed override, ``mpcc``); not those that
    declare ``oracle_start = False`` (the normalised score's reference PD, ``pd-ref``: a deliberately plain loop
    that is never the best start, and which would otherwise make every stored solution be solved again); not the
    registry's ``EXTRA_VARIANTS`` (the predictive pair on the commissioned model, which the default table leaves out:
    measured far above the bare names, 105 against 10.7 um on the shop-floor heart, so never the best start; the
    floor is at or below them by measurement, not by construction)."""
    from ..registry import EXTRA_VARIANTS, names, policy_class

    u = env.unwrapped if hasattr(env, "unwrapped") else env
    if getattr(u.action_space, "shape", None) not in ((2,), (getattr(u, "num_envs", 0), 2)):
        return []
    plant = getattr(u, "plant", None)
    out = []
    for name in names():
        cls = policy_class(name)
        if getattr(cls, "causal", True) is False or plant is None or not cls.designed_for(plant):
            continue
        if getattr(cls, "oracle_start", True) is False or name in EXTRA_VARIANTS:  # never the best start
            continue
        if getattr(cls, "sets_feed_override", False):  # a third action (mpcc): not on an env of two axis commands
            continue
        if getattr(cls, "needs_reference", False) and not hasattr(getattr(u, "task", None), "reference_arrays"):
            continue
        out.append(name)
    return out


def _record(policy, task, parameters, noise_state, trials: int):
    """Episodes of ``policy`` (its Python ``predict``) on one machine of ``task`` with the exact plant: per trial
    the applied commands (L, 2) as the env received them."""
    batch = ContouringBatch(task, 1)
    b = batch.buffers
    runs = []
    for _ in range(trials):
        batch.reset_env(0, parameters)
        if noise_state is not None:
            batch.plant_arrays.rng[0] = noise_state
        batch.run()
        start = np.ones(1, dtype=bool)
        actions = []
        for _ in range(task.max_episode_steps):
            action, _ = policy.predict(b.obs[:1].copy(), episode_start=start, deterministic=True)
            start = np.zeros(1, dtype=bool)
            action = np.asarray(action).reshape(2)
            actions.append(action.copy())
            b.action[0] = action
            b.mode[0] = sk.MODE_STEP
            batch.run()
            if b.flags[0, sk.FLAG_TERMINATED] or b.flags[0, sk.FLAG_TRUNCATED]:
                break
        if hasattr(policy, "end_episodes"):
            policy.end_episodes(np.ones(1, dtype=bool))
        runs.append(np.array(actions))
    return runs


@dataclass
class Start:
    """A causal controller's run on the exact plant: ``policy`` (its compiled form runs in the floor's loop; an
    :class:`~vcnc_baselines.optimal.open_loop.OpenLoopPolicy` of its recorded commands where it has none or learns
    across trials), its replayed max and RMS contour error (mm) and whether the tool finished the part."""

    policy: object
    max: float
    rms: float
    completed: bool
    table: np.ndarray | None = None  # the recorded commands of an open-loop start


def warm_starts(env, rollouts: Rollouts, *, trials: int = 10, names=None, extra=None, log=None) -> dict:
    """Every causal controller of ``names`` (default :func:`causal_names`) closed-loop on the exact plant of
    ``rollouts``: name -> :class:`Start`.  A controller that learns across episodes runs ``trials`` trials,
    each a start (``ilc#3``: its third), replayed open-loop.  ``extra`` (label -> policy with SB3's ``predict``,
    e.g. a trained agent) adds causal policies from outside :mod:`vcnc_baselines`, replayed open-loop too."""
    from ..registry import make

    task = rollouts.task
    zero = np.zeros((1, 1, 2))
    out = {}
    todo = [(name, None) for name in (causal_names(env) if names is None else names)]
    todo += list((extra or {}).items())
    for name, given in todo:
        t0 = time.perf_counter()
        try:
            policy = make(name, env) if given is None else given
        except ValueError as exc:  # a design that does not exist for this env (the papers' limits): not a start
            if log:
                log(f"  warm start {name}: not built ({exc})")
            continue
        if given is None and hasattr(policy, "plan"):  # as the evaluation loops do after a reset: an @machine
            # design commissions the machine the floor is solved on (its identification run reads its observation)
            policy.plan(SimpleNamespace(task=task, parameters=rollouts.parameters))
        learns = getattr(policy, "learns_across_episodes", False)
        compiled = getattr(policy, "compiled", None)
        if not learns and given is None and compiled is not None and compiled(1) is not None:
            runs = [(name, policy, None)]
        else:
            recorded = _record(policy, task, rollouts.parameters, rollouts.noise_state, trials if learns else 1)
            runs = [
                (name if len(recorded) == 1 else f"{name}#{j + 1}", OpenLoopPolicy(_exact(a)), _exact(a))
                for j, a in enumerate(recorded)
            ]
        for label, p, table in runs:
            rollouts.set_controller(p)
            summary, _, _ = rollouts.run(zero)
            peak, rms = figures(summary)
            out[label] = Start(p, float(peak[0]), float(rms[0]), bool(summary[0, OUT_COMPLETED]), table)
        if log:
            best = min(out[lab].max for lab, _, _ in runs)
            log(f"  warm start {name}: {1e3 * best:.3f} um max ({time.perf_counter() - t0:.1f} s)")
    return out


def _better(peak, rms, best_peak, best_rms) -> bool:
    return peak < best_peak or (peak == best_peak and rms < best_rms)


def _exact(actions: np.ndarray) -> np.ndarray:
    """``actions`` as float32 if that loses nothing, else float64."""
    a32 = actions.astype(np.float32)
    return a32 if np.array_equal(a32.astype(np.float64), actions) else actions


def _peaks(errors: np.ndarray, count: int, separation: int) -> list[int]:
    """Indices of the ``count`` largest errors at least ``separation`` steps apart."""
    order = np.argsort(errors)[::-1]
    chosen: list[int] = []
    for k in order:
        if all(abs(int(k) - c) >= separation for c in chosen):
            chosen.append(int(k))
            if len(chosen) == count:
                break
    return chosen


def solve(
    env,
    parameters: np.ndarray,
    *,
    noise_state=None,
    population: int = 16,
    ilc_iterations: int = 8,
    rounds: int = 8,
    generations: int = 12,
    windows: int = 3,
    window_s: float | None = None,
    trials: int = 10,
    seed: int = 0,
    names=None,
    extra_starts=None,
    log=None,
) -> Solution:
    """The floor's input sequence for ``env``'s task on the plant ``parameters`` (2, P); see the module notes.

    Parameters
    ----------
    env : gymnasium.Env
        A vcnc_gym contouring env (its ``unwrapped.task``; the warm starts are built for it).
    parameters : ndarray, (2, P)
        The exact plant.
    noise_state : int, optional
        The plant's noise generator state after the env's reset (shop floor), for the closed-loop starts.
    population : int
        Candidates per generation (machines of the private batch), >= 4.
    ilc_iterations : int
        Generations of the inverse-model learning stage.
    rounds, generations : int
        Cross-entropy rounds (windows re-chosen each) and generations per round.
    windows : int
        Windows per round, around the incumbent's largest errors.
    window_s : float, optional
        Window length, s; default 400 decision periods (40 ms at 0.1 ms).
    trials : int
        Trials of a learning controller among the starts.
    names : list of str, optional
        The :mod:`vcnc_baselines` controllers run as starts; default :func:`causal_names`.
    extra_starts : dict, optional
        Label -> causal policy from outside :mod:`vcnc_baselines` (a trained agent), run as a start too.
    seed : int
        The search's own generator.
    log : callable, optional
        Called with a line of progress.
    """
    t0 = time.perf_counter()
    u = env.unwrapped
    task = u.task
    rollouts = Rollouts(task, parameters, population, noise_state)
    starts = warm_starts(env, rollouts, trials=trials, names=names, extra=extra_starts, log=log)
    if not starts:
        raise ValueError(f"no causal controller applies to {getattr(u.spec, 'id', task)}: no start for the floor")
    name = min(starts, key=lambda k: (starts[k].max, starts[k].rms))
    search = _Search(task, parameters, rollouts, starts[name], population, seed, log)
    search.learn_inverse(ilc_iterations)
    search.cross_entropy(rounds, generations, windows, window_s)
    final, peak, rms = search.replay()
    return Solution(
        start=name,
        correction=final,
        table=search.first.table,
        max_um=1e3 * peak,
        rms_um=1e3 * rms,
        warm_starts={k: (1e3 * v.max, 1e3 * v.rms) for k, v in starts.items()},
        history=np.array(search.history),
        solve_time_s=time.perf_counter() - t0,
        evaluations=rollouts.evaluations,
    )


class _Search:
    """The stages of :func:`solve` after the warm starts, about one incumbent (``best``, its peak and RMS,
    mm): the inverse-model learning, the cross-entropy rounds and the final replay."""

    def __init__(self, task, parameters, rollouts: Rollouts, first, population: int, seed: int, log):
        self.dt = task.dt * task.config.n_repeat
        self.rng = np.random.default_rng(seed)
        self.rollouts, self.first, self.population, self.log = rollouts, first, population, log
        rollouts.set_controller(first.policy)
        self.best = np.zeros((int(task.max_episode_steps), 2))
        self.best_peak, self.best_rms = first.max, first.rms
        self.require = first.completed  # the floor must finish the part if its start did
        self.history = [(0, 1e3 * self.best_peak)]
        self.inverse = task.plant.inverse(parameters)
        self.u_max = task.plant.input_limits(parameters)  # (2,)
        ref = task.reference_arrays.samples
        self.tangent = ref[:, sk.REF_TANGENT : sk.REF_TANGENT + 2]

    def score(self, summary):
        """Max and RMS per rollout; a rollout that does not finish counts inf if the start finished."""
        peak, rms = figures(summary)
        if not self.require:
            done = np.isfinite(summary[:, 0])
            peak, rms = np.where(done, summary[:, 0], np.inf), np.where(done, rms, np.inf)
        return peak, rms

    def normal_error(self, tracking):
        """The tracking error's component normal to the reference's tangent."""
        tangent = self.tangent
        n = min(len(tracking), len(tangent))
        e = np.zeros_like(tracking)
        nrm = np.column_stack([-tangent[:n, 1], tangent[:n, 0]])
        e[:n] = nrm * np.sum(tracking[:n] * nrm, axis=1, keepdims=True)
        return e

    def evaluate(self, candidates):
        """Run the candidates; the incumbent moves to the best of them if it is better."""
        summary, _, _ = self.rollouts.run(np.clip(candidates, -2.0, 2.0))
        peak, rms = self.score(summary)
        j = int(np.lexsort((rms, peak))[0])
        improved = _better(peak[j], rms[j], self.best_peak, self.best_rms)
        if improved:
            self.best, self.best_peak, self.best_rms = np.clip(candidates[j], -2.0, 2.0), float(peak[j]), float(rms[j])
        self.history.append((self.rollouts.evaluations, 1e3 * self.best_peak))
        return peak, rms, improved

    def learn_inverse(self, iterations: int) -> None:
        """2. inverse-model learning, a population of gains and Q cut-offs."""
        dt = self.dt
        nyquist = 0.5 / dt
        gains = np.array([0.1, 0.25, 0.5, 1.0])
        cutoffs = [min(0.02 / dt, 0.8 * nyquist), min(0.06 / dt, 0.8 * nyquist)]
        for it in range(iterations):
            best = self.best
            _, _, tracking = self.rollouts.run(best[None], traces=True)
            e = self.normal_error(tracking[0, : len(best)])
            cands = []
            for fc in cutoffs:
                b, a = signal.butter(2, fc, fs=1.0 / dt)
                step = signal.filtfilt(b, a, linear_inverse(self.inverse, e, dt), axis=0) / self.u_max
                cands += [best + g * step for g in gains]
            _, _, improved = self.evaluate(np.array(cands[: self.population]))
            if self.log:
                self.log(f"  learning {it + 1}: {1e3 * self.best_peak:.4f} um max, {1e3 * self.best_rms:.4f} um rms")
            if not improved and it >= 2:
                break

    def cross_entropy(self, rounds: int, generations: int, windows: int, window_s: float | None) -> None:
        """3. cross-entropy search in windows around the largest errors."""
        dt = self.dt
        width = max(4, int(round((window_s if window_s is not None else 400 * dt) / dt)))
        for rnd in range(rounds):
            _, errors, _ = self.rollouts.run(self.best[None], traces=True)
            centres = _peaks(errors[0, : len(self.best)], windows, width // 2)
            basis = self._basis(centres, width)
            if not basis:
                break
            self._generations(basis, generations)
            if self.log:
                self.log(
                    f"  search round {rnd + 1}: {1e3 * self.best_peak:.4f} um max, {1e3 * self.best_rms:.4f} "
                    f"um rms (windows at {[round(c * dt, 4) for c in centres]} s, {self.rollouts.evaluations} "
                    "evaluations)"
                )

    def _basis(self, centres, width: int) -> list:
        """Bumps: per window, centres from (peak - 0.8 width) to (peak + 0.2 width); per axis.  Each (start,
        stop, axis, input correction per unit theta (normalised))."""
        length, spacing = len(self.best), max(2, width // 10)
        basis = []
        for c in centres:
            lo, hi = max(0, c - int(0.8 * width)), min(length, c + int(0.2 * width))
            pad = 4 * spacing
            seg = np.arange(max(0, lo - pad), min(length, hi + pad))
            for m in np.arange(lo, hi, spacing):
                g = np.exp(-0.5 * ((seg - m) / (0.6 * spacing)) ** 2) * 1e-3  # 1 um of displacement per unit
                for axis in range(2):
                    x = np.zeros((len(seg), 2))
                    x[:, axis] = g
                    du = linear_inverse(self.inverse, x, self.dt)[:, axis] / self.u_max[axis]
                    basis.append((seg[0], seg[-1] + 1, axis, du))
        return basis

    def _generations(self, basis: list, generations: int) -> None:
        """One round's generations of the cross-entropy method over the bumps' amplitudes."""
        population, dim = self.population, len(basis)
        scale = 0.25 * 1e3 * self.best_peak if np.isfinite(self.best_peak) else 0.5
        # three quarters of the candidates at the distribution's scale, an eighth at a tenth, an eighth at a
        # hundredth of it (where the reference cannot be followed, the steps that help are small ones)
        spread = np.where(
            np.arange(population) < 3 * population // 4,
            1.0,
            np.where(np.arange(population) < 7 * population // 8, 0.1, 0.01),
        )
        mean, sigma = np.zeros(dim), np.full(dim, max(0.05, scale))  # um of displacement
        for _ in range(generations):
            theta = mean + sigma * self.rng.standard_normal((population, dim)) * spread[:, None]
            theta[0] = mean
            cands = np.repeat(self.best[None], population, axis=0)
            for d, (s0, s1, axis, du) in enumerate(basis):
                cands[:, s0:s1, axis] += theta[:, d, None] * du[None]
            peak, rms, improved = self.evaluate(cands)
            if improved:  # the incumbent moved: the distribution is now about it
                mean = mean - theta[int(np.lexsort((rms, peak))[0])]
            order = np.lexsort((rms, peak))
            elite = theta[order[: max(2, population // 4)]]
            if improved:
                elite = elite - theta[order[0]]
            mean = 0.7 * elite.mean(axis=0) + 0.3 * mean
            sigma = 0.7 * elite.std(axis=0) + 0.3 * sigma + 1e-3

    def replay(self) -> tuple[np.ndarray, float, float]:
        """The correction as the kernel adds it (float32), trimmed to one trailing zero, replayed once more: it,
        its max and RMS, mm."""
        final = self.best.astype(np.float32)
        nonzero = np.flatnonzero(np.any(final != 0, axis=1))
        final = final[: nonzero[-1] + 2] if len(nonzero) else final[:1]  # the last row (held) is 0
        summary, _, _ = self.rollouts.run(final[None])
        peak, rms = self.score(summary)
        if not (peak[0] <= self.first.max):  # cannot happen (the kernel reads the float32 values it was scored with)
            raise RuntimeError(f"the floor's replay {1e3 * peak[0]} um is above its start's {1e3 * self.first.max} um")
        self.history.append((self.rollouts.evaluations, 1e3 * float(peak[0])))
        return final, float(peak[0]), float(rms[0])
