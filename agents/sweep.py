"""Hyperparameter sweeps of ``vcnc-train`` on Ray Tune: ``vcnc-train --sweep FILE``.

A sweep file (YAML) names an env, the hyperparameters every trial starts from
and a search space over the options of ``vcnc-train``::

    env: VCNC-Omega-v1            # a registered id (required)
    hyperparams: ../hyperparams/ppo.yml   # RL Zoo file, relative to this file (default: the shipped one)
    overrides: {n_steps: 512}     # hyperparameters of the entry changed in every trial
    search:                       # a value (fixed), a list (grid: every value) or one of
      seed: [0, 1, 2]             #   {choice: [...]}, {uniform: [lo, hi]}, {loguniform: [lo, hi]},
      learning_rate: {loguniform: [1.0e-4, 1.0e-3]}   #   {randint: [lo, hi]} (both ends included)
      action_mode: residual
      baseline: qft
      correction: {uniform: [0.3, 1.0]}
      action_repeat: [5, 10]
      n_envs: 2
      timesteps: 500000
    num_samples: 4                # draws of the random parameters per grid point (Tune's num_samples)
    search_seed: 0                # seed of those draws: the same file draws the same trials
    checkpoint_freq: 50000        # vcnc-train's options, the same for every trial (optional)
    eval_freq: 20000
    vec_env: native
    cpus_per_trial: 1             # CPUs Tune reserves per trial, and its torch / numba threads
    max_concurrent_trials: 2      # optional

The searchable parameters are :data:`SEARCH_KEYS`: the options of
``vcnc-train`` (``seed``, ``n_envs``, ``timesteps``, the action mode) and
``learning_rate``, which goes into the trial's hyperparameter file.  A
direct-mode trial ignores ``baseline`` and ``correction``.  Every value of a
list or choice and both bounds of a range are checked by the trainer's own
rules, and every combination of the action-mode values is set up once
(:func:`vcnc_agents.run_session.prepare_run`: env, baseline, policy) before Ray starts.

Each trial is one run of :func:`vcnc_agents.training.train` with the arguments of
one ``vcnc-train`` command line, in its own folder of the sweep's::

    SWEEP/
      sweep.yml               the sweep file, as given
      trials/<trial>/ppo.yml  the trial's hyperparameters (the entry, overrides, learning_rate)
      trials/<trial>/run/     its vcnc-train run folder (best/ and final/ agents, evaluations.csv, ...)
      tune/                   Ray Tune's experiment folder
      sweep_results.csv       one row per trial: settings, max / RMS contour error, score, wall time, command
      sweep_results.md        the trials sorted by score, the best one's figures and the command retraining it

The metric is vcnc-train's evaluation score (:func:`vcnc_agents.training.evaluation_score`):
sqrt(max x RMS) contour error, um, of the run's best deterministic evaluation
on the nominal plant, lower is better; a run whose every evaluation diverged
scores inf.  The retrain command is the trial's own command line with another
``--output``; it runs where the sweep ran (its paths are as the sweep was given them).

Ray is an optional extra (``pip install 'vcnc-gym[sweep]'``).  Without
``ray_address`` a local Ray instance sized to the machine runs the trials;
with one (``auto``, ``HOST:PORT``, ``ray://HOST:10001``) they run on that
cluster, whose nodes need vcnc-gym installed and the sweep folder on a
filesystem they share (each trial writes its run folder at the same path).
"""

from __future__ import annotations

import csv
import io
import itertools
import logging
import math
import os
import shlex
import shutil
import tempfile
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from .run_config import TRAINING_OPTIONS

__all__ = [
    "SweepSpec",
    "SweepResult",
    "load_sweep",
    "run_sweep",
    "trial_argv",
    "import_ray",
    "SEARCH_KEYS",
    "RESULT_FIELDS",
]

#: Parameters a sweep may search, and the kind of their values.
SEARCH_KEYS = {
    "seed": "int",
    "learning_rate": "float",
    "action_mode": "str",
    "baseline": "str",
    "correction": "float",
    "action_repeat": "int",
    "n_envs": "int",
    "timesteps": "int",
}
#: The vcnc-train option of each searchable parameter (learning_rate goes into the trial's hyperparameter file).
_FLAGS = {
    "seed": "--seed",
    "n_envs": "--n-envs",
    "timesteps": "--timesteps",
    "action_mode": "--action-mode",
    "baseline": "--baseline",
    "correction": "--correction",
    "action_repeat": "--action-repeat",
}
#: Search-space forms: which kinds of parameter each applies to.
_DOMAINS = {"choice": ("int", "float", "str"), "uniform": ("float",), "loguniform": ("float",), "randint": ("int",)}
#: Keys of a sweep file.
_FILE_KEYS = (
    "env",
    "hyperparams",
    "overrides",
    "search",
    "num_samples",
    "search_seed",
    *TRAINING_OPTIONS,
    "vec_env",
    "cpus_per_trial",
    "max_concurrent_trials",
)
#: Hyperparameter keys of the entry that a searched parameter sets (refused in overrides, set in two places).
_ENTRY_KEYS = {"learning_rate": "learning_rate", "n_envs": "n_envs", "timesteps": "n_timesteps"}
#: Columns of sweep_results.csv.
RESULT_FIELDS = (
    "trial",
    "status",
    *SEARCH_KEYS,
    "max_um",
    "rms_um",
    "score_um",
    "best_steps",
    "trained_steps",
    "wall_s",
    "train_wall_s",
    "run_dir",
    "command",
    "note",
)
#: The oldest Ray whose Tune has ``tune.report(metrics)`` and ``tune.get_context()`` in function trainables.
_RAY_MIN = (2, 41)
_INSTALL = "pip install 'vcnc-gym[sweep]'"


# -- the sweep file ------------------------------------------------------------------------------
@dataclass
class SweepSpec:
    """A checked sweep file (:func:`load_sweep`).

    ``search`` maps each searched parameter to ``(form, value)``: ``("value", v)``,
    ``("grid", [v, ...])``, ``("choice", [v, ...])``, ``("uniform" | "loguniform" | "randint", (lo, hi))``.
    ``options`` holds the file's training options (:data:`vcnc_agents.run_config.TRAINING_OPTIONS`), None where it
    sets none.
    """

    path: Path
    env_id: str
    hyperparams: Path
    overrides: dict
    search: dict
    num_samples: int = 1
    search_seed: int = 0
    options: dict = field(default_factory=dict)
    vec_env: str = "native"
    cpus_per_trial: int = 1
    max_concurrent_trials: int | None = None

    @property
    def name(self) -> str:
        """The sweep's name: its file's (runs/sweep_<name> by default)."""
        return self.path.stem

    @property
    def n_trials(self) -> int:
        """Trials the sweep runs: num_samples x the product of the grid sizes."""
        return self.num_samples * math.prod(len(v) for form, v in self.search.values() if form == "grid")

    def param_space(self) -> dict:
        """The search space in Ray Tune's terms."""
        from ray import tune

        make = {
            "value": lambda v: v,
            "grid": tune.grid_search,
            "choice": tune.choice,
            "uniform": lambda b: tune.uniform(*b),
            "loguniform": lambda b: tune.loguniform(*b),
            "randint": lambda b: tune.randint(b[0], b[1] + 1),
        }  # Tune's upper bound is excluded
        return {k: make[form](v) for k, (form, v) in self.search.items()}

    def entry(self, settings: dict) -> dict:
        """The hyperparameter entry of a trial: the file's entry, the overrides, the trial's learning rate."""
        from .config import load_hyperparameters

        h = load_hyperparameters(self.env_id, self.hyperparams)
        h.update(self.overrides)
        if "learning_rate" in settings:
            h["learning_rate"] = float(settings["learning_rate"])
        return h


def _error(path, message: str) -> ValueError:
    return ValueError(f"sweep file {path}: {message}")


def _value_rules():
    """Check of one value of each searchable parameter: the trainer's own rules."""
    import vcnc_baselines

    from .action_modes import ACTION_MODES, ActionMode
    from .config import count, ppo_arguments
    from .run_config import check_seed

    def one_of(name, allowed):
        def check(v):
            if v not in allowed:
                raise ValueError(f"{name} must be one of {sorted(allowed)}, got {v!r}")
            return v

        return check

    def learning_rate(v):
        ppo_arguments({"learning_rate": v})
        return v

    return {
        "seed": check_seed,
        "learning_rate": learning_rate,
        "action_mode": one_of("action_mode", ACTION_MODES),
        "baseline": one_of("baseline", vcnc_baselines.names()),
        "correction": lambda v: ActionMode("residual", baseline=vcnc_baselines.names()[0], correction=v).correction,
        "action_repeat": lambda v: count("action_repeat", v),
        "n_envs": lambda v: count("n_envs", v),
        "timesteps": lambda v: count("timesteps", v),
    }


def _typed(key: str, v):
    """A value of the parameter's kind (a YAML string "1e-4" read as a float); ValueError otherwise."""
    from .config import number

    kind = SEARCH_KEYS[key]
    if kind == "str":
        if not isinstance(v, str):
            raise ValueError(f"{key} must be a string, got {v!r}")
        return v
    if kind == "float":
        return number(key, v)
    if isinstance(v, float) and v.is_integer():
        v = int(v)
    if isinstance(v, bool) or not isinstance(v, int):
        raise ValueError(f"{key} must be an integer, got {v!r}")
    return v


def _parse_domain(key: str, raw) -> tuple[str, object]:
    """(form, value) of one search entry, every value checked; ValueError naming the parameter."""
    rules = _value_rules()
    check = lambda v: rules[key](_typed(key, v))  # noqa: E731
    try:
        if isinstance(raw, dict):
            if len(raw) != 1 or next(iter(raw)) not in _DOMAINS:
                raise ValueError(
                    f"a search form is one of {{{', '.join(f'{k}: [...]' for k in _DOMAINS)}}}, got {raw!r}"
                )
            ((form, args),) = raw.items()
            if SEARCH_KEYS[key] not in _DOMAINS[form]:
                applies = " and ".join(k for k, t in SEARCH_KEYS.items() if t in _DOMAINS[form])
                raise ValueError(f"{form} applies to {applies}, not to {key}")
            if form == "choice":
                if not isinstance(args, list) or not args:
                    raise ValueError(f"choice needs a non-empty list of values, got {args!r}")
                return form, [check(v) for v in args]
            if not isinstance(args, list) or len(args) != 2:
                raise ValueError(f"{form} needs [low, high], got {args!r}")
            lo, hi = (check(v) for v in args)
            if not lo < hi:
                raise ValueError(f"{form} needs low < high, got {args!r}")
            return form, (lo, hi)
        if isinstance(raw, list):
            values = [check(v) for v in raw]
            if not values or len(set(values)) != len(values):
                raise ValueError(f"a grid lists one or more values, each once, got {raw!r}")
            return "grid", values
        return "value", check(raw)
    except ValueError as exc:
        raise ValueError(f"search: {key}: {exc}") from None


def _values(form: str, v) -> list:
    """The values of a search entry that bound what a trial can get (a range: its two ends)."""
    return [v] if form == "value" else list(v)


def _direct(settings: dict) -> dict:
    """The settings a trial runs with: a direct-mode trial drops baseline and correction."""
    if settings.get("action_mode") == "direct":
        return {k: v for k, v in settings.items() if k not in ("baseline", "correction")}
    return dict(settings)


def load_sweep(path) -> SweepSpec:
    """Read and check a sweep file; ValueError (or FileNotFoundError) naming the file and the key.

    Checks, before anything runs: the keys (misspellings get a hint), the
    env id, the hyperparameter file and its entry with the overrides, every
    value of the search space against the trainer's rules, and one set-up of
    every combination of the action-mode values (:func:`vcnc_agents.run_session.prepare_run`,
    which builds the env, the residual's baseline and the policy; nothing is written).
    """
    from .config import DEFAULT_CONFIG, refuse_unknown, count, ppo_arguments, read_yaml
    from .run_config import check_env_id, check_training_options

    path = Path(path)
    data = read_yaml("sweep file", path)
    if not isinstance(data, dict):
        raise _error(path, f"must be a mapping of {', '.join(_FILE_KEYS)}, got {type(data).__name__}")
    try:
        refuse_unknown("the sweep file", data, _FILE_KEYS)
        if "env" not in data:
            raise ValueError("env (the env id) is required")
        env_id = check_env_id(data["env"])
        config = data.get("hyperparams")
        config = DEFAULT_CONFIG if config is None else path.parent / str(config)
        overrides = data.get("overrides") or {}
        if not isinstance(overrides, dict):
            raise ValueError(f"overrides must be a mapping of hyperparameters, got {overrides!r}")
        search = data.get("search")
        if not isinstance(search, dict) or not search:
            raise ValueError(f"search must be a mapping of some of {', '.join(SEARCH_KEYS)}, got {search!r}")
        refuse_unknown("search", search, SEARCH_KEYS)
        twice = [f"{k} (search: {s})" for s, k in _ENTRY_KEYS.items() if s in search and k in overrides]
        if twice:
            raise ValueError(f"overrides set {', '.join(twice)}, which the search sets: keep one")
        options = {k: data.get(k) for k in TRAINING_OPTIONS}
        vec_env = data.get("vec_env", "native")
        check_training_options(vec_env=vec_env, tensorboard=None, **options)
        spec = SweepSpec(
            path=path,
            env_id=env_id,
            hyperparams=config,
            overrides=dict(overrides),
            search={k: _parse_domain(k, v) for k, v in search.items()},
            num_samples=count("num_samples", data.get("num_samples", 1)),
            search_seed=count("search_seed", data.get("search_seed", 0), 0),
            options=options,
            vec_env=vec_env,
            cpus_per_trial=count("cpus_per_trial", data.get("cpus_per_trial", 1)),
            max_concurrent_trials=(
                None
                if data.get("max_concurrent_trials") is None
                else count("max_concurrent_trials", data["max_concurrent_trials"])
            ),
        )
        ppo_arguments(spec.entry({}))
    except (ValueError, FileNotFoundError) as exc:
        raise _error(path, str(exc)) from None
    _check_trials(spec)
    return spec


def _check_trials(spec: SweepSpec) -> None:
    """Set up (without writing) one trial per combination of the action-mode values; ValueError naming it.

    The other parameters take their first value (a range: its low end); their
    every value was checked on its own by :func:`load_sweep`.
    """
    from .run_session import prepare_run
    from .run_warning import RunWarning

    mode_keys = ("action_mode", "baseline", "action_repeat")
    axes = {k: _values(*spec.search[k]) for k in mode_keys if k in spec.search}
    rest = {k: _values(*v)[0] for k, v in spec.search.items() if k not in axes}
    combos = {
        tuple(sorted(_direct(dict(rest, **dict(zip(axes, c)))).items())) for c in itertools.product(*axes.values())
    }
    seen = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, combo in enumerate(sorted(combos, key=repr)):
            settings = dict(combo)
            config_file = Path(tmp) / f"ppo_{i}.yml"
            _write_entry(spec, settings, config_file)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", RunWarning)
                try:
                    prepare_run(**_train_kwargs(trial_argv(spec, settings, config_file, Path(tmp) / "run")))
                except (ValueError, FileNotFoundError) as exc:
                    raise _error(spec.path, f"a trial with {settings} cannot run: {exc}") from None
            for w in caught:
                message = str(w.message).replace(str(Path(tmp)), "<trial>")
                if issubclass(w.category, RunWarning) and message not in seen:
                    seen.append(message)
                    warnings.warn(f"sweep {spec.path}: {message}", RunWarning, stacklevel=2)


# -- one trial --------------------------------------------------------------------------------
def _format(key: str, v) -> str:
    kind = SEARCH_KEYS[key]
    return str(int(v)) if kind == "int" else repr(float(v)) if kind == "float" else str(v)


def trial_argv(spec: SweepSpec, settings: dict, config_file, output) -> list[str]:
    """The ``vcnc-train`` arguments of a trial: what the trial runs, and with another output, its retrain command
    (SB3's trainer, which the trials run, named: ``vcnc-train``'s default is the lean one)."""
    settings = _direct(settings)
    argv = ["--env", spec.env_id, "--trainer", "sb3", "--config", str(config_file)]
    for key, flag in _FLAGS.items():
        if key in settings:
            argv += [flag, _format(key, settings[key])]
    for key, value in spec.options.items():
        if value is not None:
            argv += [f"--{key.replace('_', '-')}", str(value)]
    if spec.vec_env != "native":
        argv += ["--vec-env", spec.vec_env]
    return argv + ["--threads", str(spec.cpus_per_trial), "--output", str(output)]


def _train_kwargs(argv: list[str]) -> dict:
    """The arguments of :func:`vcnc_agents.run_session.prepare_run` that ``vcnc-train ARGV`` runs with."""
    from .arguments import action_mode, parser

    args = parser().parse_args(argv)
    return {
        "env_id": args.env,
        "run_dir": args.output,
        "n_timesteps": args.timesteps,
        "seed": 0 if args.seed is None else args.seed,
        "n_envs": args.n_envs,
        "config_file": args.config,
        "action_mode": action_mode(args, args.config),
        **{name: getattr(args, name) for name in TRAINING_OPTIONS},
    }


def _write_entry(spec: SweepSpec, settings: dict, path: Path) -> None:
    text = yaml.safe_dump({spec.env_id: spec.entry(settings)}, sort_keys=False)
    path.write_text(
        f"# hyperparameters of a trial of the sweep {spec.path}: its entry, overrides and learning rate\n" + text
    )


def _trial(settings: dict, *, spec: SweepSpec, sweep_dir: str) -> None:
    """Ray Tune trainable: one vcnc-train run, its figures reported to Tune."""
    import numba
    import torch
    from ray import tune

    from .run_config import RunConfig
    from .run_warning import RunWarning
    from .training import train

    name = tune.get_context().get_trial_name()
    folder = Path(sweep_dir) / "trials" / name
    folder.mkdir(parents=True, exist_ok=True)
    _write_entry(spec, settings, folder / "ppo.yml")
    argv = trial_argv(spec, settings, folder / "ppo.yml", folder / "run")
    torch.set_num_threads(spec.cpus_per_trial)
    numba.set_num_threads(min(spec.cpus_per_trial, numba.config.NUMBA_NUM_THREADS))
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RunWarning)
        result = train(**_train_kwargs(argv), progress_bar=False, vec_env=spec.vec_env)
    wall = time.perf_counter() - t0
    run = RunConfig.read(folder / "run")
    mode = run.mode
    best = result.best or {}
    tune.report(
        {
            "trial": name,
            "seed": run.seed,
            "learning_rate": run.hyperparams.get("learning_rate"),
            "action_mode": mode.mode,
            "baseline": mode.baseline,
            "correction": mode.correction,
            "action_repeat": mode.action_repeat,
            "n_envs": run.n_envs,
            "timesteps": run.n_timesteps,
            "max_um": best.get("max_um", math.inf),
            "rms_um": best.get("rms_um", math.inf),
            "score_um": best.get("score_um", math.inf),
            "best_steps": best.get("steps"),
            "trained_steps": result.timesteps,
            "wall_s": wall,
            "train_wall_s": result.wall_s,
            "note": "; ".join(dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, RunWarning))),
        }
    )


# -- Ray -------------------------------------------------------------------------------------------
def import_ray():
    """``(ray, ray.tune)``; ImportError telling how to install them when Ray is missing or too old."""
    try:
        import ray
        from ray import tune
    except ImportError:
        raise ImportError(
            f"vcnc-train --sweep runs on Ray Tune, an optional extra that is not installed: {_INSTALL}"
        ) from None
    version = tuple(int(p) for p in ray.__version__.split(".")[:2] if p.isdigit())
    if version < _RAY_MIN:
        raise ImportError(
            f"vcnc-train --sweep needs Ray >= {'.'.join(map(str, _RAY_MIN))}, found "
            f"{ray.__version__}: pip install -U 'vcnc-gym[sweep]'"
        )
    return ray, tune


def _local_cpus() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _start_ray(ray, address: str | None, cpus_per_trial: int) -> tuple[bool, str]:
    """Start local Ray or connect to ``address``; (whether we started it, where the trials run)."""
    if ray.is_initialized():
        return False, "the Ray instance already running in this process"
    quiet = {"include_dashboard": False, "log_to_driver": False, "logging_level": logging.ERROR}
    if address is None:
        cpus = _local_cpus()
        if cpus_per_trial > cpus:
            raise ValueError(
                f"cpus_per_trial {cpus_per_trial} is more than this machine's {cpus} CPUs: no trial could start"
            )
        ray.init(num_cpus=cpus, **quiet)
        return True, f"local Ray, {cpus} CPUs"
    try:
        ray.init(address=address, log_to_driver=False, logging_level=logging.ERROR)
    except Exception as exc:  # Ray raises ConnectionError, RuntimeError, ValueError ... depending on the address
        cause = f" ({exc.__cause__})" if exc.__cause__ is not None else ""  # e.g. a missing auth token
        raise ConnectionError(f"cannot connect to the Ray cluster at {address!r}: {exc}{cause}") from None
    cpus = int(ray.cluster_resources().get("CPU", 0))
    return True, f"Ray cluster at {address}, {cpus} CPUs"


def _progress(tune, n_trials: int):
    """A Tune callback printing one line per finished or failed trial."""

    class Progress(tune.Callback):
        def _line(self, trials, trial, what: str) -> None:
            done = sum(t.status in ("TERMINATED", "ERROR") for t in trials) + 1
            print(f"vcnc-train: {trial} {what} ({min(done, n_trials)} of {n_trials} trials)", flush=True)

        def on_trial_complete(self, iteration, trials, trial, **info):
            m = trial.last_result or {}
            figures = (
                f"max {m['max_um']:.2f} um, RMS {m['rms_um']:.2f} um, score {m['score_um']:.2f} um"
                if "score_um" in m
                else "no figures"
            )
            self._line(trials, trial, f"finished: {figures}")

        def on_trial_error(self, iteration, trials, trial, **info):
            self._line(trials, trial, "failed (see sweep_results.md)")

    return Progress()


@contextmanager
def _no_tune_loggers():
    """Without Tune's own per-trial CSV, JSON and TensorBoard loggers (the sweep writes its table; an inf
    score would make the TensorBoard logger print a warning per trial)."""
    key = "TUNE_DISABLE_AUTO_CALLBACK_LOGGERS"
    before = os.environ.get(key)
    os.environ[key] = "1"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(key)
        else:
            os.environ[key] = before


def _default_output(spec: SweepSpec) -> Path:
    return Path("runs") / f"sweep_{spec.name}"


def check_output(output) -> Path:
    """``output`` if a sweep may write there (absent or empty); FileExistsError otherwise."""
    output = Path(output)
    if output.exists() and (not output.is_dir() or any(output.iterdir())):
        raise FileExistsError(f"{output} already exists and is not an empty folder: choose another --output")
    return output


# -- the sweep ------------------------------------------------------------------------------------
@dataclass
class SweepResult:
    """What :func:`run_sweep` did: the sweep folder, one row per trial (RESULT_FIELDS), the best row or None."""

    sweep_dir: Path
    rows: list
    best: dict | None
    wall_s: float
    where: str


def run_sweep(spec, output=None, *, ray_address: str | None = None, verbose: int = 0) -> SweepResult:
    """Run the sweep ``spec`` (a :class:`SweepSpec` or a sweep file) on Ray Tune and write its results table.

    ``output``: the sweep's folder (default ``runs/sweep_<file name>``),
    absent or empty.  ``ray_address``: an existing Ray cluster (default: a
    local Ray sized to the machine).  Raises ValueError / FileNotFoundError
    for a bad sweep file, FileExistsError for a used output folder,
    ImportError when Ray is missing, ConnectionError for an unreachable
    cluster, all before anything is written.
    """
    spec = spec if isinstance(spec, SweepSpec) else load_sweep(spec)
    output = check_output(output if output is not None else _default_output(spec))
    ray, tune = import_ray()
    from ray.tune.search import BasicVariantGenerator

    started, where = _start_ray(ray, ray_address, spec.cpus_per_trial)
    try:
        output.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(spec.path, output / "sweep.yml")
        t0 = time.perf_counter()
        trainable = tune.with_resources(
            tune.with_parameters(_trial, spec=spec, sweep_dir=str(output.resolve())), {"cpu": spec.cpus_per_trial}
        )
        tuner = tune.Tuner(
            trainable,
            param_space=spec.param_space(),
            tune_config=tune.TuneConfig(
                metric="score_um",
                mode="min",
                num_samples=spec.num_samples,
                search_alg=BasicVariantGenerator(random_state=spec.search_seed),
                max_concurrent_trials=spec.max_concurrent_trials,
                trial_name_creator=lambda t: f"trial_{t.trial_id.rsplit('_', 1)[-1]}",
                trial_dirname_creator=lambda t: str(t),
            ),
            run_config=tune.RunConfig(
                name="tune",
                storage_path=str(output.resolve()),
                verbose=1 if verbose else 0,
                failure_config=tune.FailureConfig(max_failures=0),
                callbacks=[_progress(tune, spec.n_trials)],
            ),
        )
        with _no_tune_loggers():
            grid = tuner.fit()
        wall = time.perf_counter() - t0
    finally:
        if started:
            ray.shutdown()
    rows = [_row(spec, output, r) for r in grid]
    rows.sort(key=lambda r: (r["status"] != "finished", _score(r), r["trial"]))
    best = rows[0] if rows and rows[0]["status"] == "finished" and math.isfinite(_score(rows[0])) else None
    result = SweepResult(output, rows, best, wall, where)
    _write_results(spec, result, ray.__version__)
    return result


def _score(row: dict) -> float:
    return row["score_um"] if isinstance(row["score_um"], float) else math.inf


def _row(spec: SweepSpec, output: Path, r) -> dict:
    """One row of the results table from a Tune result (a failed trial keeps the settings Tune drew)."""
    m = dict(r.metrics or {})
    name = m.get("trial") or Path(r.path).name
    settings = {k: m.get(k, r.config.get(k)) for k in SEARCH_KEYS}
    status = "error" if r.error is not None else "finished" if "score_um" in m else "stopped"
    note = m.get("note") or ""
    if status == "finished" and m.get("best_steps") is None:
        note = "; ".join(filter(None, ["every evaluation diverged", note]))
    if r.error is not None:
        note = str(r.error).strip().splitlines()[-1]
    folder = output / "trials" / name
    ppo = folder / "ppo.yml"
    command = "vcnc-train " + shlex.join(
        trial_argv(
            spec, {k: v for k, v in r.config.items() if k in SEARCH_KEYS}, ppo, Path("runs") / f"{output.name}-{name}"
        )
    )
    return {
        "trial": name,
        "status": status,
        **settings,
        **{
            k: m.get(k, "")
            for k in ("max_um", "rms_um", "score_um", "best_steps", "trained_steps", "wall_s", "train_wall_s")
        },
        "run_dir": str(folder / "run"),
        "command": command,
        "note": note,
    }


def _fmt(v, digits: int = 2) -> str:
    if v is None or v == "":
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}" if math.isfinite(v) and 1e-2 <= abs(v) < 1e6 or v == 0 else f"{v:.3g}"
    return str(v)


def _write_results(spec: SweepSpec, result: SweepResult, ray_version: str) -> None:
    """sweep_results.csv and sweep_results.md in the sweep folder."""
    from .normalization import atomic_write_bytes

    buffer = io.StringIO()
    w = csv.DictWriter(buffer, fieldnames=RESULT_FIELDS)
    w.writeheader()
    w.writerows(result.rows)
    atomic_write_bytes(result.sweep_dir / "sweep_results.csv", buffer.getvalue().encode())

    searched = [k for k in SEARCH_KEYS if k in spec.search]
    finished = sum(r["status"] == "finished" for r in result.rows)
    lines = [
        f"# Sweep `{spec.name}` on {spec.env_id}",
        "",
        f"Sweep file `{spec.path}` (copied to `sweep.yml`); {len(result.rows)} trials, {finished} finished, "
        f"in {result.wall_s / 60:.1f} min on {result.where} (Ray {ray_version}).",
        "",
        "Metric: vcnc-train's evaluation score, sqrt(max x RMS) contour error (um) of each run's best "
        "deterministic evaluation on the nominal plant; lower is better.",
        "",
    ]
    b = result.best
    if b is None:
        lines += ["No trial finished with a finite score.", ""]
    else:
        mode = (
            f"residual over {b['baseline']}, correction {_fmt(b['correction'], 3)}"
            if b["action_mode"] == "residual"
            else "direct"
        )
        lines += [
            f"## Best trial: {b['trial']}",
            "",
            f"- max contour error {_fmt(b['max_um'])} um, RMS {_fmt(b['rms_um'])} um, score "
            f"{_fmt(b['score_um'])} um (its best evaluation, at {b['best_steps']} of {b['trained_steps']} "
            f"agent steps); {_fmt(b['wall_s'], 0)} s",
            f"- seed {b['seed']}, learning rate {_fmt(b['learning_rate'], 6)}, {mode}, action repeat "
            f"{b['action_repeat']}, n_envs {b['n_envs']}, {b['timesteps']} agent steps",
            f"- agent: `{b['run_dir']}/best` (`vcnc-bench --env {spec.env_id} --policy ppo:{b['run_dir']}/best`)",
            "- retrain it (from the folder the sweep ran in):",
            "",
            "```bash",
            b["command"],
            "```",
            "",
        ]
    lines += [
        "## Trials, best first",
        "",
        "| rank | trial | " + " | ".join(searched) + " | max um | RMS um | score um | wall s | status |",
        "|" + "---|" * (len(searched) + 7),
    ]
    for i, r in enumerate(result.rows, 1):
        cells = [
            str(i),
            r["trial"],
            *(_fmt(r[k], 6 if k == "learning_rate" else 3) for k in searched),
            _fmt(r["max_um"]),
            _fmt(r["rms_um"]),
            _fmt(r["score_um"]),
            _fmt(r["wall_s"], 0),
            r["status"],
        ]
        lines.append("| " + " | ".join(cells) + " |")
    notes = [f"- {r['trial']}: {r['note']}" for r in result.rows if r["note"]]
    if notes:
        lines += ["", "Notes:", "", *notes]
    lines += ["", "Every trial's command line is in `sweep_results.csv` (column `command`)."]
    atomic_write_bytes(result.sweep_dir / "sweep_results.md", ("\n".join(lines) + "\n").encode())
