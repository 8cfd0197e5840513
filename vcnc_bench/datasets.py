"""``vcnc-datasets``: Minari datasets of the suite's controllers, one per id and behaviour policy.

Offline RL reads a control benchmark through datasets (D4RL: Fu et al., 2020; Minari, its successor at the
Farama Foundation; NeoRL-2 with PID-like behaviour policies).  This command writes, per env id and behaviour
policy, one local Minari dataset (:func:`minari.create_dataset_from_buffers`, HDF5 by default)::

    vcnc-datasets --env VCNC-Heart-v1 --plants 20 --out ~/vcnc-datasets
    vcnc-datasets --env VCNC-HeartShop-v1 --policy pd-ref --policy strongest --plants 20
    vcnc-datasets --env VCNC-Heart-v2 --policy servo --policy random --plants 20

The behaviour policies (default all four; on a learnable id, ``servo`` and ``random``)
--------------------------------------------------------------------------------------
- ``pd-ref``: the normalised score's reference PD (:mod:`vcnc_bench.score`, the score's 0);
- ``strongest``: the strongest causal controller of the id, chosen **by running** every classical controller of
  the bench's default table for the id (``baseline`` kind's defaults, the non-causal floor left out) for one
  episode on the nominal plant, the least max contour error winning (ties: the least RMS), the rule of
  :func:`vcnc_bench.headroom.headroom`; ``--strongest NAME`` names it instead;
- ``smc``: a paper's feedback controller (Jahanpour et al. (2014)'s sliding mode);
- ``oracle``: the non-causal floor (:mod:`vcnc_baselines.optimal`, the score's 1): it reads the exact plant and plans
  the whole episode ahead, so it is **no controller**, and its dataset says so (``algorithm_name`` and
  ``description`` carry "non-causal").  A floor on a plant other than the nominal one costs a search (minutes
  per plant), so its dataset holds the nominal plant only unless ``--oracle-on-samples``.

Any other bench spec (``ff-pid``, ``zpetc@machine``, ``ppo``, ``zoo:FOLDER``) is accepted too.

On a learnable id (``VCNC-Heart-v2``, ...: :data:`vcnc_gym.envs.registry.LEARNABLE_IDS`) the action is a
correction of the drive servo's set-point, which a classical controller's command is not; its behaviour policies
are ``servo`` (the zero action: the drive's servo alone, :data:`SERVO`), ``random`` (uniform actions in [-1, 1],
drawn from ``--seed``: D4RL's random dataset, :data:`RANDOM`) and agents of the id (``ppo:``, ``zoo:``, ``bc:``).
The classical controllers' datasets of the same task are those of its v1 id.

The plants: the nominal plant and ``--plants N`` plants drawn uniformly from the box with
``--plant-seed`` (:func:`vcnc_bench.robust.plant_set`, the draws of ``vcnc-bench --plants N``, without the
vertices), one episode each, all in one batch of the env's native vector env (reset seed ``--seed``: env ``i``
gets ``seed + i``, as in the bench).  Episode ``i`` of the dataset is plant ``i`` (0 = nominal); its reset seed and
plant parameters are ``metadata["vcnc"]["reset_seeds"][i]`` and ``["plant_parameters"][i]`` (2 x P, the plant's
parameter order ``["plant_parameter_names"]``; also the episode's HDF5 attributes ``seed`` and
``options/parameters``), so ``env.reset(seed=s, options={"parameters": p})`` replays it.  A progress bar per
dataset (and a line per reference episode) goes to stderr unless ``--no-progress``.

Ids and metadata
----------------
Dataset ids are Minari's ``namespace/name-vVERSION``: ``vcnc/<env without "VCNC-">/<policy>-v0``
(``vcnc/Heart-v1/pd-ref-v0``; a character Minari's names do not allow, e.g. ``@``, becomes ``_``).  The
metadata carry the env spec (``recover_environment()`` makes the env once ``vcnc_gym`` is imported: it registers
the ids), ``ref_min_score`` and ``ref_max_score``, and under the key ``vcnc`` the generating command, the code
version (vcnc-gym's version, the git commit when run from a checkout, :func:`vcnc_bench.provenance.provenance`),
the policy, and every episode's figures (max and RMS contour error, um; cycle time, s; diverged, completed).

**The score.**  ``ref_min_score`` and ``ref_max_score`` are returns, sums of the env's own rewards over an episode
on the nominal plant (reset seed ``--seed``): those of ``pd-ref`` and of the floor (:func:`reference_scores`), so
``minari.get_normalized_score(dataset, returns)`` is 0 for pd-ref's return and 1 for the floor's.  On a learnable
id both run on its v1 id, the same task, and their control periods are scored with the learnable id's reward
(:func:`learnable_return`: what ``gym.make(ID, base="pd-ref")`` returns with a zero correction, to rounding).  The
suite's own score of the max contour error (:func:`vcnc_bench.score.normalised_score`) has its ends in
``metadata["vcnc"]["score"]`` too (``reference_max_um``, ``floor_max_um``).

Nothing is uploaded or downloaded: datasets go to ``--out DIR`` (default ``MINARI_DATASETS_PATH``, else Minari's
``~/.minari/datasets``), and an existing dataset of the same id is an error unless ``--overwrite``.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vcnc_gym.extras import require_extra
from vcnc_gym.validation import integer

from .provenance import provenance
from .robust import make_batch, plant_set

__all__ = [
    "DEFAULT_POLICIES",
    "LEARNABLE_POLICIES",
    "STRONGEST",
    "FLOOR",
    "SERVO",
    "RANDOM",
    "DatasetReport",
    "Episodes",
    "dataset_id",
    "strongest_causal",
    "behaviour_policy",
    "collect",
    "learnable_return",
    "reference_scores",
    "write_dataset",
    "code_version",
    "main",
]

#: The behaviour policies written by default.
DEFAULT_POLICIES = ("pd-ref", "strongest", "smc", "oracle")
#: The behaviour policies written by default on a learnable id (its action a set-point correction).
LEARNABLE_POLICIES = ("servo", "random")
#: On a learnable id: the zero action, the drive's servo alone.
SERVO = "servo"
#: On a learnable id: uniform actions in [-1, 1], drawn from the reset seed.
RANDOM = "random"
#: The alias of the id's strongest causal controller.
STRONGEST = "strongest"
#: The non-causal floor's name (the score's 1).
FLOOR = "oracle"
#: The dataset version every id gets (``-v0``).
VERSION = 0

_NAME_CHARS = re.compile(r"[^-\w]")


def dataset_id(env_id: str, policy: str, version: int = VERSION) -> str:
    """Minari's id of the dataset of ``policy`` on ``env_id``: ``vcnc/<env without "VCNC-">/<policy>-v<version>``,
    every character Minari's names do not allow (``@``, ``:``, ``/``, ``.``) as ``_``."""
    if not isinstance(env_id, str) or not env_id:
        raise ValueError(f"env_id must be a non-empty id string, got {env_id!r}")
    if not isinstance(policy, str) or not policy:
        raise ValueError(f"policy must be a non-empty spec string, got {policy!r}")
    version = integer("version", version, 0)
    env = _NAME_CHARS.sub("_", env_id.removeprefix("VCNC-"))
    return f"vcnc/{env}/{_NAME_CHARS.sub('_', policy)}-v{version}"


def code_version() -> dict:
    """vcnc-gym's version and, when the package runs from a git checkout, its commit and whether the tree had
    changes (``dirty``); the libraries and the CPU (:func:`vcnc_bench.provenance.provenance`)."""
    import vcnc_gym

    out = {"vcnc_gym": vcnc_gym.__version__, "commit": None, "dirty": None}
    root = Path(vcnc_gym.__file__).resolve().parent.parent
    if not (root / ".git").exists():  # an installed wheel (site-packages): no commit of ours to name
        out["provenance"] = provenance()
        return out
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10)
        if head.returncode == 0:
            out["commit"] = head.stdout.strip()
            status = subprocess.run(
                ["git", "status", "--porcelain", "--untracked-files=no"],
                cwd=root,
                capture_output=True,
                text=True,
                timeout=10,
            )
            out["dirty"] = bool(status.stdout.strip()) if status.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):  # no git: the version alone
        pass
    out["provenance"] = provenance()
    return out


# -- the behaviour policies of a learnable id -------------------------------------------------------------------
class _ConstantAction:
    """The zero action of every env: on a learnable id, the drive's servo alone."""

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation)
        return np.zeros(obs.shape[:-1] + (2,), dtype=np.float32), state


class _RandomAction:
    """Uniform actions in [-1, 1] from a seeded generator (D4RL's random dataset)."""

    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation)
        return self.rng.uniform(-1.0, 1.0, obs.shape[:-1] + (2,)).astype(np.float32), state


def learnable(env) -> bool:
    """True for a learnable id's env (``action="setpoint"`` or ``"correction"``: the drive's servo or a classical
    controller inside the step)."""
    return bool(getattr(getattr(env.unwrapped, "task", None), "controlled", False))


def _refusal(spec: str, env) -> str | None:
    """Why ``spec`` cannot drive ``env`` (None: it can): servo and random need a learnable id, which a classical
    controller's amplifier command does not fit."""
    from .policies import split_spec

    env_id = env.spec.id if env.spec is not None else "this env"
    if spec in (SERVO, RANDOM) and not learnable(env):
        return f"{spec!r} is a behaviour policy of the learnable ids (a set-point action), not of {env_id}"
    if learnable(env) and (spec == STRONGEST or split_spec(spec)[0] == "baseline"):
        return (
            f"{spec!r} commands the amplifier; on the learnable id {env_id} the action is a set-point correction: "
            f"use {SERVO}, {RANDOM} or an agent of the id (ppo:, zoo:, bc:); the classical controllers' datasets of "
            f"this task are those of {env_id.replace('-v2', '-v1')}"
        )
    return None


def behaviour_policy(spec: str, env, seed: int = 0):
    """The behaviour policy of ``spec`` for ``env``: :data:`SERVO` and :data:`RANDOM` (a learnable id's), or a bench
    spec (:func:`vcnc_bench.policies.resolve_policy`).  ValueError for a classical controller on a learnable id,
    or for servo and random on another."""
    from .policies import resolve_policy

    why = _refusal(spec, env)
    if why is not None:
        raise ValueError(why)
    if spec == SERVO:
        return _ConstantAction()
    if spec == RANDOM:
        return _RandomAction(seed)
    return resolve_policy(spec, env)


# -- collecting the episodes -------------------------------------------------------------------------------------
@dataclass
class Episodes:
    """One episode per env of a batch, as Minari stores them.

    Attributes
    ----------
    observations : list of ndarray, (T_i + 1, D)
        The reset observation and every step's.
    actions : list of ndarray, (T_i, A)
        What the policy returned (the env clips it to its box).
    rewards : list of ndarray, (T_i,)
    terminations, truncations : list of ndarray of bool, (T_i,)
    max_um, rms_um : ndarray, (M,)
        Max and RMS of ``info["contour_error"]`` over each episode's steps, um (as
        :func:`vcnc_gym.evaluation.run_episode`).
    cycle_time_s : ndarray, (M,)
        ``info["cycle_time"]`` at the end, s (NaN: the tool did not arrive).
    diverged, completed : ndarray of bool, (M,)
    wall_s : float
        Wall time of the batch's episodes, s.
    """

    observations: list
    actions: list
    rewards: list
    terminations: list
    truncations: list
    max_um: np.ndarray
    rms_um: np.ndarray
    cycle_time_s: np.ndarray
    diverged: np.ndarray
    completed: np.ndarray
    wall_s: float

    @property
    def steps(self) -> int:
        """Decision steps over every episode."""
        return int(sum(len(r) for r in self.rewards))


def collect(policy, batch, parameters: np.ndarray, *, seed: int = 0, progress=None) -> Episodes:
    """Run ``policy`` for one episode on every plant of ``parameters`` in ``batch`` and record every step.

    Parameters
    ----------
    policy : object
        SB3's ``predict(observations (M, D), episode_start=(M,) bool, deterministic=True)``.
    batch : ContouringVectorEnv or SingleEnvBatch
        M envs, autoreset disabled (:func:`vcnc_bench.robust.make_batch`).
    parameters : ndarray, (M, 2, P)
        One plant per env.
    seed : int
        ``batch.reset(seed=...)``: env i gets ``seed + i``.
    progress : callable, optional
        Called with the decisions each step made (the envs still running), e.g. ``tqdm.update``.

    On a learnable id the max and RMS contour error are its episode summary's, over every control period
    (``info["episode_summary"]``); elsewhere over the decision steps' ``info["contour_error"]``.
    """
    m = parameters.shape[0]
    wall0 = time.perf_counter()
    obs, _ = batch.reset(seed=seed, options={"parameters": parameters})
    if hasattr(policy, "plan"):  # the non-causal floor plans with the plants it now runs on
        policy.plan(batch)
    obs_tr, act_tr, rew_tr, term_tr, trunc_tr = [obs.copy()], [], [], [], []
    active = np.ones(m, dtype=bool)
    length = np.zeros(m, dtype=np.int64)
    peak, square_sum = np.zeros(m), np.zeros(m)
    diverged, completed = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
    cycle = np.full(m, np.nan)
    start, not_start = np.ones(m, dtype=bool), np.zeros(m, dtype=bool)
    while active.any():
        action, _ = policy.predict(obs, episode_start=start, deterministic=True)
        start = not_start
        action = np.array(action, dtype=np.float32).reshape(m, -1)
        obs, reward, terminated, truncated, info = batch.step(action)
        obs_tr.append(obs.copy())
        act_tr.append(action)
        rew_tr.append(np.asarray(reward, dtype=np.float64).copy())
        term_tr.append(np.asarray(terminated, dtype=bool).copy())
        trunc_tr.append(np.asarray(truncated, dtype=bool).copy())
        e = info["contour_error"][active]
        peak[active] = np.maximum(peak[active], e)
        square_sum[active] += e * e
        length[active] += 1
        if progress is not None:
            progress(int(active.sum()))
        ended = active & (terminated | truncated)
        if ended.any():
            diverged[ended] = info["diverged"][ended]
            completed[ended] = info["completed"][ended] if "completed" in info else terminated[ended] & ~diverged[ended]
            if "cycle_time" in info:
                cycle[ended] = info["cycle_time"][ended]
            if "step_contour_error_max" in info:  # a learnable id: the summary's figures, over the control periods
                summary = info["episode_summary"]
                peak[ended] = summary["contour_error_max"][ended]
                square_sum[ended] = summary["contour_error_rms"][ended] ** 2 * length[ended]
            active &= ~ended
    obs_a, act_a = np.stack(obs_tr, axis=1), np.stack(act_tr, axis=1)
    rew_a, term_a, trunc_a = (np.stack(x, axis=1) for x in (rew_tr, term_tr, trunc_tr))
    n = [int(k) for k in length]
    return Episodes(
        observations=[obs_a[i, : k + 1] for i, k in enumerate(n)],
        actions=[act_a[i, :k] for i, k in enumerate(n)],
        rewards=[rew_a[i, :k] for i, k in enumerate(n)],
        terminations=[term_a[i, :k] for i, k in enumerate(n)],
        truncations=[trunc_a[i, :k] for i, k in enumerate(n)],
        max_um=1e3 * peak,
        rms_um=1e3 * np.sqrt(square_sum / np.maximum(length, 1)),
        cycle_time_s=cycle,
        diverged=diverged,
        completed=completed,
        wall_s=time.perf_counter() - wall0,
    )


def _run_nominal(env_id: str, spec: str, env_kwargs: dict, seed: int) -> Episodes:
    """``spec``'s episode on the nominal plant of ``env_id`` (a batch of one)."""
    import gymnasium as gym

    from .policies import resolve_policy

    env = gym.make(env_id, **env_kwargs)
    try:
        u = env.unwrapped
        policy = resolve_policy(spec, env)
        batch = make_batch(env_id, 1, **env_kwargs)
        try:
            return collect(policy, batch, u.nominal_parameters[None], seed=seed)
        finally:
            batch.close()
    finally:
        env.close()


def strongest_causal(env_id: str, env_kwargs: dict | None = None, seed: int = 0) -> tuple[str, dict]:
    """The strongest causal classical controller of ``env_id`` on its nominal plant, by running them.

    Every spec of the ``baseline`` kind's defaults for the env (the bench's default table) that is causal runs
    one episode on the nominal plant (reset seed ``seed``); the least max contour error wins, ties broken by the
    least RMS (:func:`vcnc_bench.headroom.headroom`'s rule).  Returns ``(spec, {spec: (max_um, rms_um)})``.
    """
    import gymnasium as gym

    from vcnc_baselines.registry import policy_class

    from .policies import policy_kinds

    env_kwargs = dict(env_kwargs or {})
    env = gym.make(env_id, **env_kwargs)
    try:
        specs = [
            s
            for s in policy_kinds()["baseline"].defaults(env)
            if getattr(policy_class(s.partition("@")[0]), "causal", True) is not False
        ]
    finally:
        env.close()
    if not specs:
        raise ValueError(f"env_id {env_id!r} has no causal classical controller in the bench's default table")
    figures = {}
    for spec in specs:
        ep = _run_nominal(env_id, spec, env_kwargs, seed)
        figures[spec] = (float(np.inf if ep.diverged[0] else ep.max_um[0]), float(ep.rms_um[0]))
    best = min(figures, key=lambda s: (figures[s][0], figures[s][1] if math.isfinite(figures[s][1]) else math.inf))
    return best, figures


#: The arguments of the learnable interface, left out when a learnable id's task runs on its v1 id.
_LEARNABLE_ARGUMENTS = (
    "action",
    "setpoint_range",
    "servo_gains",
    "base",
    "correction",
    "error_clip",
    "observation_scale",
    "reward_scale",
    "action_repeat",
    "effort_weight",
)


def learnable_return(env_id: str, spec: str, env_kwargs: dict | None = None, seed: int = 0) -> dict:
    """The classical controller (or floor) ``spec`` on the nominal plant of a learnable id's task, scored with the
    learnable id's reward: ``{"return", "max_um"}``.

    ``spec`` runs on the id's v1 (the same machine, contour, reference and episode end; the amplifier command every
    control period), and each control period is scored as the learnable id's kernel scores it:
    ``-min(e, error_clip) / reward_scale`` (and the effort term), the divergence penalty of ``error_clip /
    reward_scale`` per control period left to the natural end, the untraversed contour over ``reward_scale``; a
    decision's reward being the mean of its periods', the return is their sum over ``action_repeat``.  This is what
    ``gym.make(env_id, base=spec)`` returns with a zero correction (tests/test_datasets.py), for the floor too,
    which has no compiled form to run inside the step.
    """
    import gymnasium as gym

    from .policies import resolve_policy

    env_kwargs = dict(env_kwargs or {})
    task = gym.make(env_id, **env_kwargs).unwrapped.task
    env = gym.make(
        env_id.replace("-v2", "-v1"), **{k: v for k, v in env_kwargs.items() if k not in _LEARNABLE_ARGUMENTS}
    )
    u = env.unwrapped
    policy = resolve_policy(spec, env)
    obs, _ = env.reset(seed=seed)
    if hasattr(policy, "plan"):  # the non-causal floor plans with the plant it now runs on
        policy.plan(env)
    clip, scale, limit = task.error_clip, task.reward_scale, u.plant.input_limits(u.parameters)
    total, peak, start = 0.0, 0.0, np.array([True])
    while True:
        action, _ = policy.predict(obs, episode_start=start, deterministic=True)
        start = np.array([False])
        obs, _, terminated, truncated, info = env.step(action)
        e = info["contour_error"]
        peak = max(peak, e)
        a = np.clip(info["command"] / limit, -1.0, 1.0)
        total -= (e if e < clip else clip) / scale + task.effort_weight * 0.5 * float(a @ a)
        if info["diverged"]:
            k = round(info["time"] / task.dt)
            total -= max(0, task.config.episode_steps - k) * clip / scale
        total += info["reward_incomplete"] * u.task.reward_scale / scale  # v1's -(untraversed) / its own scale
        if terminated or truncated:
            break
    env.close()
    return {"return": total / task.action_repeat, "max_um": 1e3 * peak}


def _nominal_figures(env_id: str, spec: str, env_kwargs: dict, seed: int) -> dict:
    """``spec``'s return and max contour error (um) on the nominal plant of ``env_id``, by the env's own reward
    (a learnable id: :func:`learnable_return`)."""
    import gymnasium as gym

    env = gym.make(env_id, **env_kwargs)
    controlled = learnable(env)
    env.close()
    if controlled:
        return learnable_return(env_id, spec, env_kwargs, seed)
    ep = _run_nominal(env_id, spec, env_kwargs, seed)
    return {"return": float(np.sum(ep.rewards[0])), "max_um": float(ep.max_um[0])}


def reference_scores(
    env_id: str, env_kwargs: dict | None = None, seed: int = 0, known: dict | None = None, report=None
) -> dict:
    """The normalised scores' ends on the nominal plant: ``{"pd-ref": {"return", "max_um"}, "oracle": {...}}``,
    the return of the env's reward and the max contour error (um) of each, from ``known`` (figures already measured
    with the same seed) or from one episode.  ``report``, if given, is called with a line per episode run."""
    from .score import REFERENCE

    known = dict(known or {})
    out = {}
    for spec in (REFERENCE, FLOOR):
        if spec in known:
            out[spec] = dict(known[spec])
            continue
        t0 = time.perf_counter()
        out[spec] = _nominal_figures(env_id, spec, dict(env_kwargs or {}), seed)
        if report is not None:
            report(
                f"# {env_id}: {spec} on the nominal plant: return {out[spec]['return']:.6g}, max "
                f"{out[spec]['max_um']:.4g} um ({time.perf_counter() - t0:.1f} s)"
            )
    return out


# -- writing -----------------------------------------------------------------------------------------------------
@dataclass
class DatasetReport:
    """What :func:`write_dataset` wrote.

    Attributes
    ----------
    dataset_id : str
    path : Path
        The dataset's folder.
    policy : str
        The bench spec of the behaviour policy.
    episodes, steps : int
    bytes : int
        Size on disk of the dataset's folder.
    collect_s, write_s : float
        Wall time of the episodes and of Minari's writing, s.
    max_um : list of float
        Each episode's max contour error, um.
    """

    dataset_id: str
    path: Path
    policy: str
    episodes: int
    steps: int
    bytes: int
    collect_s: float
    write_s: float
    max_um: list


def _folder_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in Path(path).rglob("*") if f.is_file())


def _finite(x) -> list:
    return [float(v) if math.isfinite(v) else None for v in np.asarray(x, dtype=np.float64)]


def _description(env_id: str, spec: str, label: str, non_causal: bool, kinds: list[str], scores: dict) -> str:
    if non_causal:
        who = (
            f"the NON-CAUSAL floor '{spec}' (it reads the exact plant and plans the episode ahead: a bound, never a "
            f"controller; baselines/optimal)"
        )
    elif spec == SERVO:
        who = "the drive's servo alone (the zero set-point correction)"
    elif spec == RANDOM:
        who = "uniform random set-point corrections in [-1, 1]"
    else:
        who = f"the causal controller '{spec}'" + (
            " (the strongest causal controller of the id on its nominal plant)" if label == STRONGEST else ""
        )
    return (
        f"{env_id} driven by {who}: {kinds.count('nominal')} nominal and {kinds.count('sample')} plants drawn "
        f"from the id's uncertainty box, one deterministic episode each (vcnc-gym, vcnc_bench/datasets.py). "
        f"ref_min_score/ref_max_score are the returns (sums of the env's rewards) on the nominal plant of pd-ref "
        f"({scores['pd-ref']['return']:.6g}) and of the non-causal floor ({scores[FLOOR]['return']:.6g})."
    )


def write_dataset(
    env_id: str,
    spec: str,
    *,
    parameters: np.ndarray,
    kinds: list[str],
    scores: dict,
    command: str,
    label: str | None = None,
    seed: int = 0,
    env_kwargs: dict | None = None,
    data_format: str = "hdf5",
    overwrite: bool = False,
    policy=None,
    episodes: Episodes | None = None,
    progress: bool = False,
) -> DatasetReport:
    """Collect ``spec``'s episodes on ``parameters`` and write them as one Minari dataset.

    Parameters
    ----------
    env_id : str
        A registered id (``import vcnc_gym``).
    spec : str
        The bench spec of the behaviour policy (``pd-ref``, ``ff-pid-online``, ``oracle``).
    parameters : ndarray, (M, 2, P)
        The plants, one episode each; ``kinds`` says which is nominal and which a sample.
    scores : dict
        :func:`reference_scores`: the return (and the max contour error, um) of pd-ref and of the floor on the
        nominal plant.
    command : str
        The generating command, stored in the metadata.
    label : str, optional
        The dataset's policy name (default ``spec``; ``strongest`` for the strongest causal controller).
    seed : int
        Reset seed of the batch (env i: ``seed + i``).
    data_format : str
        Minari's storage, "hdf5" or "arrow".
    overwrite : bool
        Replace a dataset of the same id in the dataset folder (``MINARI_DATASETS_PATH``).
    policy : object, optional
        The policy already built for ``env_id``'s env (default: built from ``spec``).
    episodes : Episodes, optional
        Already collected episodes of this policy on ``parameters`` (then nothing is run).
    progress : bool
        A progress bar of the episodes' decisions on stderr.
    """
    require_extra("datasets", "vcnc-datasets")
    import gymnasium as gym
    import minari
    from minari.data_collector.episode_buffer import EpisodeBuffer
    from minari.storage.datasets_root_dir import get_dataset_path

    if data_format not in ("hdf5", "arrow"):
        raise ValueError(f"data_format must be 'hdf5' or 'arrow', got {data_format!r}")
    env_kwargs = dict(env_kwargs or {})
    label = label or spec
    name = dataset_id(env_id, label)
    path = get_dataset_path(name)
    if path.exists():
        if not overwrite:
            raise ValueError(f"dataset {name} already exists in {path.parent}; pass overwrite=True (--overwrite)")
        shutil.rmtree(path)
    env = gym.make(env_id, **env_kwargs)
    try:
        if episodes is None:
            policy = policy if policy is not None else behaviour_policy(spec, env, seed)
            batch = make_batch(env_id, parameters.shape[0], **env_kwargs)
            try:
                steps = int(getattr(env.unwrapped, "episode_steps", 0))
                episodes = _collect_with_progress(policy, batch, parameters, seed, name, steps, progress)
            finally:
                batch.close()
        non_causal = getattr(policy, "causal", True) is False or spec.partition(":")[0] == FLOOR
        buffers = [
            EpisodeBuffer(
                id=i,
                seed=seed + i,
                options={"parameters": np.asarray(parameters[i])},
                observations=episodes.observations[i],
                actions=episodes.actions[i],
                rewards=episodes.rewards[i],
                terminations=episodes.terminations[i],
                truncations=episodes.truncations[i],
            )
            for i in range(parameters.shape[0])
        ]
        t0 = time.perf_counter()
        dataset = minari.create_dataset_from_buffers(
            dataset_id=name,
            buffer=buffers,
            env=env.spec,
            eval_env=env.spec,
            algorithm_name=f"{spec} (non-causal floor)" if non_causal else spec,
            author="vcnc-gym",
            author_email="vcnc-gym (no contact address: see the project's README)",
            code_permalink=f"vcnc_bench/datasets.py of vcnc-gym {code_version()['vcnc_gym']}",
            ref_min_score=float(scores["pd-ref"]["return"]),
            ref_max_score=float(scores[FLOOR]["return"]),
            description=_description(env_id, spec, label, non_causal, list(kinds), scores),
            data_format=data_format,
            requirements=_requirements(),
        )
        dataset.storage.update_metadata(
            {
                "vcnc": {
                    "env_id": env_id,
                    "env_kwargs": env_kwargs,
                    "policy": label,
                    "spec": spec,
                    "non_causal": non_causal,
                    "command": command,
                    "code_version": code_version(),
                    "score": {
                        "quantity": "return: the sum of the env's rewards over an episode (nominal plant)",
                        "reference": "pd-ref",
                        "floor": FLOOR,
                        "reference_return": float(scores["pd-ref"]["return"]),
                        "floor_return": float(scores[FLOOR]["return"]),
                        "reference_max_um": float(scores["pd-ref"]["max_um"]),
                        "floor_max_um": float(scores[FLOOR]["max_um"]),
                    },
                    "reset_seeds": [int(seed) + i for i in range(parameters.shape[0])],
                    "plant_kinds": list(kinds),
                    "plant_parameters": np.asarray(parameters, dtype=np.float64).tolist(),
                    "plant_parameter_names": list(env.unwrapped.plant.parameter_names),
                    "episodes": {
                        "max_um": _finite(episodes.max_um),
                        "rms_um": _finite(episodes.rms_um),
                        "cycle_time_s": _finite(episodes.cycle_time_s),
                        "diverged": [bool(v) for v in episodes.diverged],
                        "completed": [bool(v) for v in episodes.completed],
                    },
                }
            }
        )
        write_s = time.perf_counter() - t0
    finally:
        env.close()
    return DatasetReport(
        dataset_id=name,
        path=path,
        policy=label,
        episodes=parameters.shape[0],
        steps=episodes.steps,
        bytes=_folder_bytes(path),
        collect_s=episodes.wall_s,
        write_s=write_s,
        max_um=_finite(episodes.max_um),
    )


def _collect_with_progress(policy, batch, parameters, seed: int, name: str, steps: int, progress: bool) -> Episodes:
    """:func:`collect`, with a progress bar of the decisions (``steps`` per episode, its natural length) on stderr
    when ``progress``."""
    if not progress:
        return collect(policy, batch, parameters, seed=seed)
    from tqdm import tqdm

    total = parameters.shape[0] * steps
    with tqdm(total=total, desc=name, unit="decision", file=sys.stderr, mininterval=1.0, leave=False) as bar:
        return collect(policy, batch, parameters, seed=seed, progress=bar.update)


def _requirements() -> list[str]:
    """The pip requirement of the env (vcnc-gym at this version) for ``recover_environment``'s check."""
    import vcnc_gym

    return [f"vcnc-gym=={vcnc_gym.__version__}"]


# -- the command -------------------------------------------------------------------------------------------------
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vcnc-datasets", description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--env", action="append", required=True, metavar="ID", help="env id (repeatable)")
    p.add_argument(
        "--policy",
        action="append",
        metavar="SPEC",
        help=f"behaviour policy (repeatable): a bench spec or '{STRONGEST}'; default {' '.join(DEFAULT_POLICIES)}; "
        f"on a learnable id (VCNC-...-v2) '{SERVO}', '{RANDOM}' or an agent, default {' '.join(LEARNABLE_POLICIES)}",
    )
    p.add_argument(
        "--strongest",
        metavar="SPEC",
        help="the strongest causal controller (default: run the "
        "default table's on the nominal plant and take the best)",
    )
    p.add_argument(
        "--plants",
        type=int,
        default=20,
        metavar="N",
        help="plants drawn from the box besides the nominal one (default 20; 0: the nominal only)",
    )
    p.add_argument("--plant-seed", type=int, default=0, help="seed of the draws (default 0, as vcnc-bench)")
    p.add_argument("--seed", type=int, default=0, help="reset seed: env i gets SEED + i (default 0)")
    p.add_argument(
        "--oracle-on-samples",
        action="store_true",
        help="run the floor on the drawn plants too (a search per plant, minutes each)",
    )
    p.add_argument("--out", metavar="DIR", help="dataset folder (default MINARI_DATASETS_PATH or ~/.minari/datasets)")
    p.add_argument("--format", dest="data_format", choices=("hdf5", "arrow"), default="hdf5")
    p.add_argument("--overwrite", action="store_true", help="replace datasets of the same id")
    p.add_argument(
        "--no-progress", action="store_true", help="no progress bars nor reference lines on stderr (the table stays)"
    )
    return p


def _plants(env, n: int, plant_seed: int) -> tuple[np.ndarray, list[str]]:
    u = env.unwrapped
    if n == 0:
        return u.nominal_parameters[None].copy(), ["nominal"]
    ps = plant_set(u.plant, n, plant_seed, max_vertices=0, nominal=u.nominal_parameters)
    return ps.parameters, ps.kinds


def _policies_of(env_id: str, args) -> list[str]:
    """The behaviour policies written for ``env_id``: ``--policy``'s, else the defaults of its kind of id."""
    from vcnc_gym.envs.registry import LEARNABLE_IDS

    return list(args.policy or (LEARNABLE_POLICIES if env_id in LEARNABLE_IDS else DEFAULT_POLICIES))


def _check(args) -> None:
    """ValueError (or Gymnasium's error) naming a bad policy or id, before anything runs."""
    import gymnasium as gym

    from .policies import check_policy_spec

    for env_id in args.env:
        gym.spec(env_id)
        env = gym.make(env_id)
        try:
            for spec in _policies_of(env_id, args):
                if spec not in (SERVO, RANDOM, STRONGEST):
                    check_policy_spec(spec)
                why = _refusal(spec, env)
                if why is not None:
                    raise ValueError(why)
        finally:
            env.close()
    if args.strongest:
        check_policy_spec(args.strongest)


def _write_env(env_id: str, args, command: str, log) -> None:
    """Every dataset of ``env_id``: its plants, its references' returns, one dataset per behaviour policy."""
    import gymnasium as gym

    env = gym.make(env_id)
    parameters, kinds = _plants(env, args.plants, args.plant_seed)
    env.close()
    policies = _policies_of(env_id, args)
    strongest = args.strongest
    if STRONGEST in policies and strongest is None:
        t0 = time.perf_counter()
        strongest, figures = strongest_causal(env_id, seed=args.seed)
        log(
            f"# {env_id}: strongest causal controller on the nominal plant: {strongest} "
            f"({figures[strongest][0]:.4g} um max; of {len(figures)} run in {time.perf_counter() - t0:.1f} s)"
        )
    scores = reference_scores(env_id, seed=args.seed, report=log)
    for label in policies:
        spec = strongest if label == STRONGEST else label
        use, use_kinds = parameters, kinds
        if spec == FLOOR and not args.oracle_on_samples:
            use, use_kinds = parameters[:1], kinds[:1]
        rep = write_dataset(
            env_id,
            spec,
            parameters=use,
            kinds=use_kinds,
            scores=scores,
            command=command,
            label=label,
            seed=args.seed,
            data_format=args.data_format,
            overwrite=args.overwrite,
            progress=not args.no_progress,
        )
        first = rep.max_um[0] if rep.max_um[0] is not None else math.inf
        print(
            f"{rep.dataset_id:<40} {spec:<16} {rep.episodes:>8} {rep.steps:>9} {rep.bytes / 1e6:>8.2f} "
            f"{rep.collect_s:>7.1f} {rep.write_s:>7.1f} {first:>14.4g}",
            flush=True,
        )


def main(argv: list[str] | None = None) -> int:
    """The console script ``vcnc-datasets``; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    try:
        require_extra("datasets", "vcnc-datasets")
        integer("--plants", args.plants, 0)
        integer("--plant-seed", args.plant_seed, 0)
        integer("--seed", args.seed, 0)
    except (ValueError, ModuleNotFoundError) as exc:
        print(f"vcnc-datasets: {exc}", file=sys.stderr)
        return 2
    if args.out:
        os.environ["MINARI_DATASETS_PATH"] = str(Path(args.out).expanduser().resolve())
    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)

    try:
        _check(args)
    except (ValueError, gym.error.Error) as exc:
        print(f"vcnc-datasets: {exc}", file=sys.stderr)
        return 2
    command = " ".join(["vcnc-datasets"] + argv)

    def log(line: str) -> None:
        if not args.no_progress:
            print(line, file=sys.stderr, flush=True)

    print(
        f"{'dataset id':<40} {'policy':<16} {'episodes':>8} {'steps':>9} {'MB':>8} {'run s':>7} {'write s':>7} "
        f"{'nominal max um':>14}"
    )
    for env_id in args.env:
        _write_env(env_id, args, command, log)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
