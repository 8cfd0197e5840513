"""``vcnc-bench --plants N``: every policy on many plants of the env's uncertainty box.

Which plants (:func:`plant_set`)
--------------------------------
- the **nominal** plant, the reference row (the ordinary bench's figure);
- **N samples** drawn uniformly from the box, ``PlantModel.sample`` with
  ``numpy.random.default_rng(plant_seed)`` (every env draws from the same
  seed, so the heart and the omega meet the same machines);
- the box's **vertices** (``PlantModel.vertices``) when there are at most
  :data:`MAX_VERTICES` of them, i.e. at most 6 uncertain coordinates
  (Jahanpour et al.'s feed drive: 6 -> 64 vertices, Yadav et al.'s and Purtojo et al.'s
  tables: 4 -> 16; Simba et al.'s drive has 8 -> 256, none).

How they run (:func:`run_plants`)
---------------------------------
All plants of an env are one batch: the env's native vector env
(``gym.make_vec(..., vectorization_mode="vector_entry_point",
autoreset_mode="Disabled")``, one compiled call per decision step for every
plant, on one thread unless ``parallel``: see :func:`evaluate`) and one
``predict(observations, episode_start, deterministic=True)`` per step on
the whole batch.  An env without a vector env (the positioning
env ``VCNC-Step-*``) runs as a batch of single envs, stepped in turn
(:class:`SingleEnvBatch`); the policy sees the same batches.  A plant that
has ended is no longer stepped; the policy is still called with its last
observation until every plant has ended (its action is ignored).

A policy that learns across episodes (``learns_across_episodes``: ILC)
runs ``trials`` episodes in a row on the same batch, each plant its own
sequence of trials, and is scored on the last; by default one (the first
trial, the plain feedback).  A plant whose trial ended before the batch's
last keeps being called with its last observation; the policy's
``end_episodes(mask)`` is told when, so that it does not record those calls
as part of the trial.

Per plant, over the decision steps of the (last) episode: max and RMS of
``info["contour_error"]`` (um; on the positioning env the distance to the
set-point), as :func:`vcnc_gym.evaluation.run_episode` computes them, so
the nominal row is the ordinary bench's figure (a trained agent's may differ:
its network asked for a batch rounds in another order than for one
observation, and a part whose feed the agent sets can grow that last bit
into microns; ``experiments/tolerance/README.md``, "The sixth try"); ``info["diverged"]``;
``info["completed"]`` (where the env gives none: terminated and not
diverged); the cycle time ``info["cycle_time"]`` (s, NaN if the tool did
not reach the end; where the env gives none: steps x decision period on a
contouring env, none on a positioning env).

Sensor-noise seeds (``noise_seeds``)
------------------------------------
On an id whose plant draws sensor noise (a shop-floor plant: its ``seed_machine``), ``noise_seeds = K`` runs
every plant K times in the same batch, copy ``k`` of plant ``m`` as env ``k M + m``: the batch's
``reset(seed=s)`` seeds env ``i`` with ``s + i``, so each (plant, noise seed) pair meets its own noise
realisation, and every policy meets the same ones (the verdicts' pairing, :mod:`vcnc_bench.verdicts`).  The
record's figures above stay copy 0's (reset seed ``s + m``, the run without ``noise_seeds``); ``per_noise``
holds every copy's, (K, M), and ``noise`` their distribution (:func:`noise_summary`).  On a plant without
noise the copies would be identical: it runs once.

The figures (:func:`summarize`)
-------------------------------
Median and 95th percentile over the N samples (a uniform draw over the box;
the vertices would weigh its corners), worst over samples and vertices.  A
plant that diverged counts as an infinite error, one that never reached
the end as an infinite cycle time; ``diverged`` and ``incomplete`` (not
diverged, not complete) count them.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import gymnasium as gym
import numpy as np

from vcnc_gym.envs import suite_env
from vcnc_gym.validation import integer, size

__all__ = [
    "MAX_VERTICES",
    "PlantSet",
    "PlantRuns",
    "SingleEnvBatch",
    "plant_set",
    "make_batch",
    "run_plants",
    "summarize",
    "evaluate",
    "ROBUST_COLUMNS",
    "plot_robust",
    "noisy",
    "noise_summary",
    "split_noise",
]

#: The vertices of the box join the plants when there are at most this many (2^6: at most 6 uncertain coordinates).
MAX_VERTICES = 64

#: Memory of one plant of a batch of single envs (an env without a vector
#: env: the positioning env), bytes: 32 kB measured with tracemalloc for
#: VCNC-Step-v0 (its env, wrappers and arrays), rounded up.
SINGLE_ENV_BYTES = 40_000


def bytes_per_plant(env) -> int:
    """Memory one plant of ``--plants`` costs in ``env``'s batch, bytes: its env's rows of the vector env's
    arrays (:meth:`~vcnc_gym.envs.task.ContouringBatch.bytes_per_env`) or a whole single env
    (:data:`SINGLE_ENV_BYTES`), plus its parameters drawn and kept, its observation and action in ``predict``
    and its figures (12 floats)."""
    u = env.unwrapped
    task = getattr(u, "task", None)
    if task is not None and suite_env(u.spec.id).vector_entry_point is not None:
        from vcnc_gym.envs.task import ContouringBatch

        rows = ContouringBatch.bytes_per_env(task)
    else:
        rows = SINGLE_ENV_BYTES
    p = u.plant.n_parameters
    d = int(np.prod(env.observation_space.shape))
    return rows + 3 * 2 * p * 8 + 2 * (4 * d + 16) + 12 * 8


def check_plants(n_plants: int, env, argument: str = "--plants") -> int:
    """``n_plants`` if the plants of ``env`` fit in memory (:func:`vcnc_gym.validation.size`), else a
    ValueError naming ``argument``, the limit and why."""
    return size(
        argument,
        n_plants,
        bytes_each=bytes_per_plant(env),
        why=f"each plant of {env.unwrapped.spec.id} is one env of its batch and its figures",
    )


@dataclass
class PlantSet:
    """The plants of a robust evaluation, each (2, P) in the plant's parameter order.

    Attributes
    ----------
    nominal : ndarray, (2, P)
    samples : ndarray, (N, 2, P)
        Uniform draws from the box.
    vertices : ndarray, (V, 2, P)
        The box's corners, V = 0 when there are more than ``max_vertices``.
    seed : int
        The seed of the draws.
    """

    nominal: np.ndarray
    samples: np.ndarray
    vertices: np.ndarray
    seed: int

    @property
    def parameters(self) -> np.ndarray:
        """Every plant, (1 + N + V, 2, P): nominal first, then the samples, then the vertices."""
        return np.concatenate([self.nominal[None], self.samples, self.vertices])

    @property
    def kinds(self) -> list[str]:
        """ "nominal", "sample" or "vertex" for each plant of :attr:`parameters`."""
        return ["nominal"] + ["sample"] * len(self.samples) + ["vertex"] * len(self.vertices)


def plant_set(plant, n: int, seed: int = 0, max_vertices: int = MAX_VERTICES, nominal=None) -> PlantSet:
    """The nominal plant (``nominal``, (2, P), default the plant's), ``n`` draws from the box of ``plant``
    (a PlantModel) seeded by ``seed``, and the box's vertices when there are at most ``max_vertices``."""
    n = integer("n (plants)", n, 1)
    seed = integer("seed", seed, 0)
    max_vertices = integer("max_vertices", max_vertices, 0)
    rng = np.random.default_rng(seed)
    samples = np.stack([plant.sample(rng) for _ in range(n)])
    d = plant.box()[0].size
    vertices = plant.vertices() if 2**d <= max_vertices else np.empty((0,) + samples.shape[1:])
    nominal = plant.nominal() if nominal is None else plant.validate(nominal, 1)[0]
    return PlantSet(nominal, samples, vertices, seed)


class SingleEnvBatch:
    """M single envs of an id without a native vector env, stepped in turn, shaped like the vector env with
    autoreset disabled: ``reset(seed=s, options={"parameters": (M, 2, P)})`` and ``step(actions (M, 2))``
    returning (M,) arrays; an env whose episode has ended is not stepped (its row keeps its last values)."""

    #: The info keys collected per env (those an env gives), with the value of an env that has not given it.
    KEYS = {"contour_error": np.nan, "diverged": False, "completed": False, "cycle_time": np.nan}

    def __init__(self, env_id: str, num_envs: int, **kwargs):
        self.envs = [gym.make(env_id, **kwargs) for _ in range(num_envs)]
        self.num_envs = num_envs
        self._obs = None
        self._done = np.zeros(num_envs, dtype=bool)
        self._info: dict = {}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        params = options["parameters"]
        self._obs = np.stack(
            [
                env.reset(seed=None if seed is None else seed + i, options={"parameters": p})[0]
                for i, (env, p) in enumerate(zip(self.envs, params))
            ]
        )
        self._done[:] = False
        self._info = {}
        return self._obs.copy(), {}

    @property
    def parameters(self) -> np.ndarray:
        """The plants the envs hold now, (M, 2, P): what a controller commissioned per machine identifies."""
        return np.stack([env.unwrapped.parameters for env in self.envs])

    @property
    def task(self):
        """The first env's task (every env of the batch is one id, built with the same arguments)."""
        return self.envs[0].unwrapped.task

    def step(self, actions):
        m = self.num_envs
        terminated, truncated = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
        for i in np.flatnonzero(~self._done):
            self._obs[i], _, terminated[i], truncated[i], info = self.envs[i].step(actions[i])
            for key, empty in self.KEYS.items():
                if key in info:
                    self._info.setdefault(key, np.full(m, empty))[i] = info[key]
        self._done |= terminated | truncated
        return self._obs.copy(), np.zeros(m), terminated, truncated, {k: v.copy() for k, v in self._info.items()}

    def close(self):
        for env in self.envs:
            env.close()


def make_batch(env_id: str, num_envs: int, parallel: bool = False, **kwargs):
    """``num_envs`` envs of ``env_id`` in one batch: its native vector env (autoreset disabled; the kernel
    spread over numba's threads if ``parallel``) where the suite registers one, else a
    :class:`SingleEnvBatch`.  ``kwargs`` go to the env (e.g. ``feedrate``)."""
    if suite_env(env_id).vector_entry_point is None:
        return SingleEnvBatch(env_id, num_envs, **kwargs)
    return gym.make_vec(
        env_id,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode="Disabled",
        parallel=parallel,
        **kwargs,
    )


@dataclass
class PlantRuns:
    """One policy's (last) episode on every plant of a :class:`PlantSet`, in its order.

    Attributes
    ----------
    max_um, rms_um : ndarray, (M,)
        Max and RMS of the contour error over the episode's decision steps, um (``inf`` where the state
        became non-finite).
    cycle_time_s : ndarray, (M,)
        s; NaN where the tool did not reach the end (or the env has no cycle time).
    has_cycle_time : bool
        False for an env with no cycle time (a positioning env whose info gives none).
    diverged, completed : ndarray of bool, (M,)
    steps : ndarray of int, (M,)
        Decision steps of each plant's episode.
    trials : int
        Episodes run per plant (the figures are the last one's).
    wall_s : float
        Wall time of every trial, s.
    """

    max_um: np.ndarray
    rms_um: np.ndarray
    cycle_time_s: np.ndarray
    has_cycle_time: bool
    diverged: np.ndarray
    completed: np.ndarray
    steps: np.ndarray
    trials: int
    wall_s: float


def run_plants(
    policy,
    batch,
    parameters: np.ndarray,
    *,
    decision_period: float,
    contouring: bool = True,
    seed: int | None = 0,
    trials: int = 1,
    progress: Callable[[int, int], object] | None = None,
    progress_every: int = 1000,
    planning: Callable[[int, int], object] | None = None,
) -> PlantRuns:
    """Run ``policy`` (SB3's ``predict`` on batches) on every plant of ``parameters`` at once.

    Parameters
    ----------
    policy : object
        ``predict(observations (M, D), episode_start=(M,) bool, deterministic=True) -> (actions (M, 2), state)``.
    batch : ContouringVectorEnv or SingleEnvBatch
        M envs of one configuration, autoreset disabled (:func:`make_batch`).
    parameters : ndarray, (M, 2, P)
        One plant per env.
    decision_period : float
        s, for the cycle time of an env whose info has none.
    contouring : bool
        False for a positioning env: no cycle time unless its info gives one.
    seed : int or None
        ``batch.reset(seed=...)``: env i gets ``seed + i``.
    trials : int
        Episodes in a row per plant (a policy that learns across episodes); the last is scored.
    progress : callable (trial, steps), optional
        Called every ``progress_every`` steps.
    planning : callable (plants done, plants), optional
        Passed to the ``plan`` of a policy that plans each plant apart (``plans_per_plant``: the floor, minutes a
        plant), called as its plants are planned.
    """
    trials = integer("trials", trials, 1)
    m = parameters.shape[0]
    has_cycle_time = contouring
    wall0 = time.perf_counter()
    for trial in range(1, trials + 1):
        obs, _ = batch.reset(seed=seed, options={"parameters": parameters})
        if hasattr(policy, "plan"):  # a non-causal floor (baselines' oracle) plans with the plants it now runs on
            if planning is not None and getattr(policy, "plans_per_plant", False):
                policy.plan(batch, progress=planning)
            else:
                policy.plan(batch)
        active = np.ones(m, dtype=bool)
        start, not_start = np.ones(m, dtype=bool), np.zeros(m, dtype=bool)
        steps = np.zeros(m, dtype=np.int64)
        peak, square_sum = np.zeros(m), np.zeros(m)
        diverged, completed = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
        cycle = np.full(m, np.nan)
        k = 0
        while active.any():
            action, _ = policy.predict(obs, episode_start=start, deterministic=True)
            start = not_start
            obs, _, terminated, truncated, info = batch.step(action)
            e = info["contour_error"][active]
            peak[active] = np.maximum(peak[active], e)
            square_sum[active] += e * e
            steps[active] += 1
            ended = active & (terminated | truncated)
            if ended.any():
                if hasattr(policy, "end_episodes"):  # a learning policy: the calls that follow are not its trial
                    policy.end_episodes(ended)
                diverged[ended] = info["diverged"][ended]
                completed[ended] = (
                    info["completed"][ended] if "completed" in info else terminated[ended] & ~diverged[ended]
                )
                if "cycle_time" in info:
                    cycle[ended] = info["cycle_time"][ended]
                    has_cycle_time = True
                elif contouring:
                    cycle[ended] = steps[ended] * decision_period
                active &= ~ended
            k += 1
            if progress is not None and k % progress_every == 0:
                progress(trial, k)
    with np.errstate(invalid="ignore"):
        rms = 1e3 * np.sqrt(square_sum / np.maximum(steps, 1))
    return PlantRuns(
        max_um=1e3 * peak,
        rms_um=rms,
        cycle_time_s=cycle,
        has_cycle_time=has_cycle_time,
        diverged=diverged,
        completed=completed,
        steps=steps,
        trials=trials,
        wall_s=time.perf_counter() - wall0,
    )


# -- the figures ---------------------------------------------------------------------------------
def _quantile(x: np.ndarray, q: float) -> float:
    """The q-quantile (linear interpolation, numpy's default) of ``x``, ``inf`` when it reaches an infinite
    value (numpy's interpolation would give NaN there)."""
    s = np.sort(x)
    if not s.size:
        return math.nan
    h = (s.size - 1) * q
    lo, hi = math.floor(h), math.ceil(h)
    return float(s[lo] if lo == hi else s[hi] if math.isinf(s[hi]) else s[lo] + (h - lo) * (s[hi] - s[lo]))


def summarize(runs: PlantRuns, plants: PlantSet, plant_model=None) -> dict:
    """The record of one policy on one env: nominal, median, p95 and worst of max and RMS contour error (um),
    nominal, median and worst cycle time (s), counts, and the per-plant figures (JSON-ready lists).

    Median and p95 over the samples, worst over samples and vertices; a diverged plant's errors and a
    cycle time that was never reached count as infinite.  ``plant_model`` (optional) names the worst
    plant's parameters."""
    kinds = np.array(plants.kinds)
    bad = runs.diverged
    err = {"max": np.where(bad, np.inf, runs.max_um), "rms": np.where(bad, np.inf, runs.rms_um)}
    cycle = np.where(np.isnan(runs.cycle_time_s), np.inf, runs.cycle_time_s)
    has_cycle = runs.has_cycle_time
    sampled, boxed = kinds == "sample", kinds != "nominal"
    rec: dict = {
        "n_plants": int(boxed.sum()),
        "n_samples": int(sampled.sum()),
        "n_vertices": int((kinds == "vertex").sum()),
    }
    for name, x in err.items():
        rec[f"nominal_{name}_um"] = float(x[0])
        rec[f"median_{name}_um"] = _quantile(x[sampled], 0.5)
        rec[f"p95_{name}_um"] = _quantile(x[sampled], 0.95)
        rec[f"worst_{name}_um"] = float(np.max(x[boxed]))
    rec["nominal_cycle_time_s"] = float(cycle[0]) if has_cycle else None
    rec["median_cycle_time_s"] = _quantile(cycle[sampled], 0.5) if has_cycle else None
    rec["worst_cycle_time_s"] = float(np.max(cycle[boxed])) if has_cycle else None
    rec["n_diverged"] = int(runs.diverged[boxed].sum())
    rec["n_incomplete"] = int((~runs.completed & ~runs.diverged)[boxed].sum())
    rec["nominal_diverged"] = bool(runs.diverged[0])
    rec["nominal_completed"] = bool(runs.completed[0])
    worst = int(np.flatnonzero(boxed)[np.argmax(err["max"][boxed])])
    first = int(np.flatnonzero(kinds == kinds[worst])[0])
    rec["worst_max_plant"] = {"kind": str(kinds[worst]), "index": worst - first}  # index among its kind
    if plant_model is not None:
        rec["worst_max_plant"]["parameters"] = plant_model.to_dict(plants.parameters[worst])
    rec["trials"] = runs.trials
    rec["wall_s"] = runs.wall_s
    rec["per_plant"] = {
        "kind": kinds.tolist(),
        "max_um": _finite_or_none(runs.max_um),
        "rms_um": _finite_or_none(runs.rms_um),
        "cycle_time_s": _finite_or_none(runs.cycle_time_s),
        "diverged": runs.diverged.tolist(),
        "completed": runs.completed.tolist(),
        "steps": runs.steps.tolist(),
    }
    return rec


def noisy(plant) -> bool:
    """True if ``plant`` (a PlantModel) draws sensor noise per machine at reset (its ``seed_machine``)."""
    return getattr(plant, "seed_machine", None) is not None


def split_noise(runs: PlantRuns, k: int) -> tuple[PlantRuns, dict]:
    """``runs`` of K copies of M plants (env ``k M + m``) as copy 0's :class:`PlantRuns` (M) and every copy's
    figures, ``{"max_um", "rms_um", "diverged", "completed"}`` each (K, M)."""
    m = runs.max_um.size // k
    shaped = {
        name: getattr(runs, name).reshape(k, m)
        for name in ("max_um", "rms_um", "cycle_time_s", "diverged", "completed", "steps")
    }
    first = PlantRuns(
        shaped["max_um"][0],
        shaped["rms_um"][0],
        shaped["cycle_time_s"][0],
        runs.has_cycle_time,
        shaped["diverged"][0],
        shaped["completed"][0],
        shaped["steps"][0],
        runs.trials,
        runs.wall_s,
    )
    return first, {name: shaped[name] for name in ("max_um", "rms_um", "diverged", "completed")}


def noise_summary(per_noise: dict, plants: PlantSet) -> dict:
    """The distribution over the noise seeds: per figure (max, RMS; um, a diverged run infinite) the nominal
    plant's min, median and max over the K seeds, and over the sampled plants the median of each plant's spread
    (max - min over its seeds) and the IQM over every (sampled plant, seed) run."""
    from .verdicts import iqm

    kinds = np.array(plants.kinds)
    sampled = kinds == "sample"
    out: dict = {"noise_seeds": int(per_noise["max_um"].shape[0])}
    for name in ("max", "rms"):
        x = np.where(per_noise["diverged"], np.inf, per_noise[f"{name}_um"])  # (K, M)
        nominal = x[:, 0]
        with np.errstate(invalid="ignore"):
            spread = x[:, sampled].max(axis=0) - x[:, sampled].min(axis=0)
        out[name] = {
            "nominal_min_um": float(nominal.min()),
            "nominal_median_um": float(np.median(nominal)),
            "nominal_max_um": float(nominal.max()),
            "median_spread_um": _quantile(np.where(np.isnan(spread), np.inf, spread), 0.5),
            "iqm_um": iqm(x[:, sampled]) if sampled.any() else math.nan,
        }
    return out


def _finite_or_none(x: np.ndarray) -> list:
    return [float(v) if math.isfinite(v) else None for v in x]


#: The robust table's columns: header, width, record key, format (:func:`vcnc_bench.output.format_table`).
ROBUST_COLUMNS = [
    ("env", 14, "env", "{}"),
    ("policy", 10, "policy", "{}"),
    ("plants", 6, "n_plants", "{:d}"),
    ("max_nom", 9, "nominal_max_um", "{:.4g}"),
    ("max_med", 9, "median_max_um", "{:.4g}"),
    ("max_p95", 9, "p95_max_um", "{:.4g}"),
    ("max_worst", 9, "worst_max_um", "{:.4g}"),
    ("rms_nom", 9, "nominal_rms_um", "{:.4g}"),
    ("rms_med", 9, "median_rms_um", "{:.4g}"),
    ("rms_p95", 9, "p95_rms_um", "{:.4g}"),
    ("rms_worst", 9, "worst_rms_um", "{:.4g}"),
    ("cyc_nom_s", 9, "nominal_cycle_time_s", "{:.4f}"),
    ("cyc_med_s", 9, "median_cycle_time_s", "{:.4f}"),
    ("cyc_worst", 9, "worst_cycle_time_s", "{:.4f}"),
    ("diverged", 8, "n_diverged", "{:d}"),
    ("incompl", 7, "n_incomplete", "{:d}"),
    ("wall_s", 7, "wall_s", "{:.1f}"),
]


# -- the plot --------------------------------------------------------------------------------------
def plot_robust(records: list[dict], path, *, title: str | None = None):
    """Box plots of max and RMS contour error (um, log scale) per policy over the sampled plants of one env,
    the vertices as grey crosses, the nominal plant as a red diamond, the count of diverged plants under
    each box.

    Parameters
    ----------
    records : list of dict
        :func:`summarize` records (with ``env`` and ``policy``) of one env.
    path : str or path-like
        Where to write the figure (PNG by extension).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    labels = [r["policy"] for r in records]
    error = "contour error" if suite_env(records[0]["env"]).contouring else "distance to the set-point"
    fig, axes = plt.subplots(1, 2, figsize=(max(8.0, 1.6 * len(records) + 4.0), 4.8), dpi=110, squeeze=False)
    rng = np.random.default_rng(0)  # jitter of the vertex crosses only
    for ax, (name, what) in zip(axes[0], (("max_um", "max"), ("rms_um", "RMS"))):
        for j, rec in enumerate(records, start=1):
            per = rec["per_plant"]
            kinds = np.array(per["kind"])
            values = np.array([np.nan if v is None else v for v in per[name]])
            ok = np.isfinite(values) & (values > 0.0) & ~np.array(per["diverged"])
            sample = values[(kinds == "sample") & ok]
            if sample.size:
                ax.boxplot(sample, positions=[j], widths=0.5, whis=(0, 100), showfliers=False)
            vertex = values[(kinds == "vertex") & ok]
            if vertex.size:
                ax.plot(
                    j + rng.uniform(-0.18, 0.18, vertex.size),
                    vertex,
                    "x",
                    color="0.5",
                    ms=4,
                    label="vertices" if j == 1 else None,
                )
            if ok[0]:
                ax.plot([j], [values[0]], "D", color="C3", ms=6, label="nominal" if j == 1 else None, zorder=3)
            if rec["n_diverged"]:
                ax.annotate(
                    f"{rec['n_diverged']} diverged",
                    (j, 0),
                    xycoords=("data", "axes fraction"),
                    xytext=(0, 3),
                    textcoords="offset points",
                    ha="center",
                    fontsize=7,
                    color="C3",
                )
        ax.set_xticks(range(1, len(records) + 1))
        ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=8)
        ax.set_xlim(0.4, len(records) + 0.6)
        ax.set_yscale("log")
        ax.set_ylabel(f"{what} {error} (µm)")
        ax.grid(True, which="both", axis="y", lw=0.3)
        ax.set_title(f"{what} {error}", fontsize=9)
        handles, _ = ax.get_legend_handles_labels()
        if handles:
            ax.legend(fontsize=8, loc="best")
    n = records[0]
    fig.suptitle(
        title
        or f"{n['env']}: {error} over the uncertainty box, {n['n_samples']} sampled plants "
        f"(box: quartiles, whiskers: min to max)"
        + (f", {n['n_vertices']} vertices" if n["n_vertices"] else ""),
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# -- the bench's robust mode ------------------------------------------------------------------------
def evaluate(
    runs,
    envs: dict,
    n_plants: int,
    *,
    plant_seed: int = 0,
    seed: int = 0,
    trials: int = 1,
    env_kwargs: dict | None = None,
    parallel: bool = False,
    bar=None,
    noise_seeds: int = 1,
) -> tuple[list[dict], dict]:
    """Every (env id, label, policy) of ``runs`` on the plants of its env: the records, env by env.

    Parameters
    ----------
    runs : list of (str, str, policy)
        Env id, policy label, policy (built for ``envs[env_id]``), grouped by env in the order given.
    envs : dict
        Env id -> the single env the policies were built for (its plant, decision period).
    n_plants, plant_seed : int
        :func:`plant_set`'s ``n`` and ``seed``.
    seed : int
        ``reset(seed=...)`` of the batch.
    trials : int
        Episodes per plant of a policy that learns across episodes (the last is scored); 1 for the others.
    env_kwargs : dict, optional
        Arguments of every batch's envs (``feedrate``).
    parallel : bool
        Spread each vector env's step over numba's threads.  Off by default: on 2 cores that other
        processes also use, a parallel step waits for both threads to be scheduled: 5.3 ms against
        0.42 ms on one thread for 165 omega envs, measured beside two trainings (0.23 ms with
        ``OMP_WAIT_POLICY=PASSIVE``).
    bar : tqdm, optional
        Advanced by one per run; its postfix names the run and its step.
    noise_seeds : int
        Sensor-noise seeds per plant on an env whose plant is :func:`noisy` (see the module docstring); 1:
        one.

    Returns
    -------
    records : list of dict
        :func:`summarize` records with ``env`` and ``policy``.
    plant_sets : dict
        Env id -> its :class:`PlantSet`.
    """
    records, plant_sets = [], {}
    for env_id in dict.fromkeys(e for e, _, _ in runs):
        u = envs[env_id].unwrapped
        plants = plant_sets[env_id] = plant_set(u.plant, n_plants, plant_seed, nominal=u.nominal_parameters)
        copies = integer("noise_seeds", noise_seeds, 1) if noisy(u.plant) else 1
        parameters = np.tile(plants.parameters, (copies, 1, 1))
        batch = make_batch(env_id, parameters.shape[0], parallel=parallel, **(env_kwargs or {}))
        try:
            for _, label, policy in (r for r in runs if r[0] == env_id):
                learns = getattr(policy, "learns_across_episodes", False)
                k = trials if learns else 1
                name = f"{label} (trial {k})" if learns else label

                def progress(trial, step, name=name):
                    if bar is not None:
                        bar.set_postfix_str(
                            f"{env_id} {name}" + (f" trial {trial}/{k}" if k > 1 else "") + f" step {step}"
                        )

                def planning(done, total, name=name):
                    if bar is not None:
                        bar.set_postfix_str(f"{env_id} {name}: plant {done} of {total} planned")

                progress(1, 0)
                result = run_plants(
                    policy,
                    batch,
                    parameters,
                    decision_period=u.decision_period,
                    contouring=suite_env(env_id).contouring,
                    seed=seed,
                    trials=k,
                    progress=progress,
                    planning=planning,
                )
                first, per_noise = split_noise(result, copies)
                rec = {"env": env_id, "policy": name, **summarize(first, plants, u.plant)}
                if copies > 1:
                    rec["noise"] = noise_summary(per_noise, plants)
                    rec["per_noise"] = {
                        k: (_finite_or_none(v.reshape(-1)) if v.dtype.kind == "f" else v.reshape(-1).tolist())
                        for k, v in per_noise.items()
                    }
                    rec["per_noise"]["shape"] = list(per_noise["max_um"].shape)
                records.append(rec)
                if bar is not None:
                    bar.update(1)
        finally:
            batch.close()
    return records, plant_sets
