"""The ``zoo`` policy kind of vcnc-bench: an agent trained by RL Baselines3 Zoo (rl_zoo3), read from its output.

``vcnc-bench --env VCNC-Circle-v2 --policy zoo:FOLDER`` runs the agent of a run of::

    python -m rl_zoo3.train --algo ppo --env VCNC-Circle-v2 --gym-packages vcnc_gym -f logs

which writes (``rl_zoo3.exp_manager.ExperimentManager``) the run folder ``logs/ppo/VCNC-Circle-v2_1`` holding

- ``VCNC-Circle-v2.zip``: the final model (SB3's ``model.save``); ``best_model.zip`` with ``--eval-freq``,
  ``rl_model_N_steps.zip`` with ``--save-freq``;
- ``VCNC-Circle-v2/vecnormalize.pkl``: the ``VecNormalize`` statistics, when the hyperparameters normalise;
- ``VCNC-Circle-v2/config.yml``: the hyperparameters, ``VCNC-Circle-v2/args.yml``: the command's arguments
  (``algo``, ``env``, ``env_kwargs``).

FOLDER is that run folder, a model ``.zip`` in it (``.../best_model.zip``), or ``logs/ALGO`` or ``logs``: the env's
latest run there, as rl_zoo3's own ``enjoy`` picks it.  The agent runs on the env it was trained on (``args.yml``'s
``env`` and ``env_kwargs``; a run whose hyperparameters wrap the env, ``env_wrapper`` or ``frame_stack``, is
refused): its observation normalised with the run's statistics, the model's deterministic action.

Loading runs no code from the folder, as the ``ppo`` kind's: the YAML files are read with a safe loader that knows
the one Python tag rl_zoo3 writes (an ``OrderedDict``), ``vecnormalize.pkl`` with an unpickler that builds numpy
arrays and records every other object it names from a fixed list as plain data (anything else is refused), and the
model with every pickled entry of its ``data`` replaced (:mod:`vcnc_agents.model_file`): spaces from the env,
the policy class from its name, ``policy_kwargs`` from the JSON or from the hyperparameters' text parsed as
``vcnc-train`` parses it (:func:`vcnc_agents.config.parse_policy_kwargs`), the training-only entries left out.
"""

from __future__ import annotations

import io
import pickle
import re
from pathlib import Path

import numpy as np

import vcnc_agents  # noqa: F401  (an install without the agents extra, torch and SB3, skips this kind)

from ..policies import PolicyKind

__all__ = ["KIND", "ZooAgent", "ZooRun", "find_run", "load_zoo_agent", "read_vecnormalize"]

#: rl_zoo3's algorithm names and the classes that load their models.
ALGORITHMS = {
    "ppo": "stable_baselines3.PPO",
    "a2c": "stable_baselines3.A2C",
    "sac": "stable_baselines3.SAC",
    "td3": "stable_baselines3.TD3",
    "ddpg": "stable_baselines3.DDPG",
    "ppo_lstm": "sb3_contrib.RecurrentPPO",
    "tqc": "sb3_contrib.TQC",
    "trpo": "sb3_contrib.TRPO",
    "crossq": "sb3_contrib.CrossQ",
}

#: The pickled entries of a model's ``data`` replaced by a value that needs nothing of the file (training state,
#: unused by ``predict``; schedules as constants): the others are the spaces, the policy class and its kwargs.
_CONSTANTS = {
    "learning_rate": 0.0,
    "lr_schedule": 0.0,
    "clip_range": 0.2,
    "clip_range_vf": None,
    "train_freq": (1, "step"),
}

#: What ``vecnormalize.pkl`` may name besides numpy's arrays: recorded as plain data (:class:`_Record`), never built.
_RECORDED = {
    ("stable_baselines3.common.vec_env.vec_normalize", "VecNormalize"),
    ("stable_baselines3.common.running_mean_std", "RunningMeanStd"),
    ("gymnasium.spaces.box", "Box"),
    ("gymnasium.spaces.discrete", "Discrete"),
    ("numpy.random._pickle", "__generator_ctor"),
    ("numpy.random._pickle", "__bit_generator_ctor"),
    ("numpy.random._pickle", "__randomstate_ctor"),
    ("numpy.random._pcg64", "PCG64"),
    ("numpy.random._mt19937", "MT19937"),
    ("numpy.random.bit_generator", "SeedSequence"),
    ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
    ("collections", "OrderedDict"),
}
#: numpy's own reconstruction of arrays, dtypes and scalars: built.
_NUMPY = {
    ("numpy", "dtype"),
    ("numpy", "ndarray"),
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy._core.multiarray", "scalar"),
}


class _Record:
    """An object of ``vecnormalize.pkl`` kept as plain data: its constructor's arguments and its state."""

    def __init__(self, *args, **kwargs):
        self.args, self.state = args, None

    def __setstate__(self, state):
        self.state = state

    def __call__(self, *args, **kwargs):  # a class recorded as a function's result
        return _Record(*args)


class _RecordingUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if (module, name) in _NUMPY:
            return super().find_class(module, name)
        if (module, name) in _RECORDED:
            return _Record
        raise pickle.UnpicklingError(f"it names {module}.{name}, which a VecNormalize file does not hold")


def read_vecnormalize(path) -> dict:
    """The observation normalisation of rl_zoo3's ``vecnormalize.pkl`` (SB3's ``VecNormalize.save``), nothing of
    it run: ``{"norm_obs", "mean", "var", "epsilon", "clip_obs"}``; ValueError for anything else."""
    path = Path(path)
    try:
        record = _RecordingUnpickler(io.BytesIO(path.read_bytes())).load()
        state = record.state
        rms = state["obs_rms"].state
        out = {
            "norm_obs": bool(state["norm_obs"]),
            "mean": np.asarray(rms["mean"], dtype=np.float64),
            "var": np.asarray(rms["var"], dtype=np.float64),
            "epsilon": float(state["epsilon"]),
            "clip_obs": float(state["clip_obs"]),
        }
    except (pickle.UnpicklingError, AttributeError, KeyError, TypeError, ValueError, EOFError) as exc:
        raise ValueError(f"{path} is not a VecNormalize file this loader reads ({type(exc).__name__}: {exc})") from None
    if out["mean"].shape != out["var"].shape or out["mean"].ndim != 1:
        raise ValueError(f"{path}: observation statistics of shapes {out['mean'].shape} and {out['var'].shape}")
    return out


# -- the run folder ------------------------------------------------------------------------------------------------
def _yaml_loader():
    """A safe YAML loader that reads rl_zoo3's ``!!python/object/apply:collections.OrderedDict`` as a dict."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def ordered(loader, node):
        return dict(loader.construct_sequence(node, deep=True)[0] if node.value else [])

    Loader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", ordered)
    return Loader


def _read_yaml(path: Path) -> dict:
    import yaml

    try:
        data = yaml.load(path.read_text(), Loader=_yaml_loader())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path} does not read as rl_zoo3's YAML ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} must hold a mapping, got {type(data).__name__}")
    return data


class ZooRun:
    """One rl_zoo3 run folder: its model file, its statistics, its hyperparameters and arguments."""

    def __init__(self, folder: Path, model: Path | None = None):
        self.folder = folder
        params = [d for d in folder.iterdir() if d.is_dir() and (d / "args.yml").is_file()]
        if len(params) != 1:
            raise ValueError(f"{folder} is not an rl_zoo3 run folder: it needs one ENV/args.yml, found {len(params)}")
        self.params = params[0]
        self.args = _read_yaml(self.params / "args.yml")
        self.hyperparams = _read_yaml(self.params / "config.yml") if (self.params / "config.yml").is_file() else {}
        self.env_id = str(self.args.get("env", self.params.name))
        self.algo = str(self.args.get("algo", "")).lower()
        self.model = model or folder / f"{self.params.name}.zip"
        if not self.model.is_file():
            raise FileNotFoundError(f"{folder}: no model {self.model.name} (the run did not finish?)")
        stats = self.params / "vecnormalize.pkl"
        self.normalization = stats if stats.is_file() else None

    def env_kwargs(self) -> dict:
        kwargs = self.args.get("env_kwargs") or {}
        if not isinstance(kwargs, dict):
            raise ValueError(f"{self.params / 'args.yml'}: env_kwargs must be a mapping, got {kwargs!r}")
        return kwargs


def _latest_runs(folder: Path, env_id: str) -> list[Path]:
    """The env's runs ``ENV_N`` under ``folder`` (``logs/ALGO``) or under each algorithm folder of ``folder``
    (``logs``): the latest of each algorithm."""
    pattern = re.compile(re.escape(env_id) + r"_(\d+)$")
    found = []
    for algo in [folder] + [d for d in folder.iterdir() if d.is_dir()]:
        runs = [(int(m.group(1)), d) for d in algo.iterdir() if d.is_dir() and (m := pattern.match(d.name))]
        if runs:
            found.append(max(runs)[1])
    return found


def find_run(path: str, env_id: str | None) -> ZooRun:
    """The run of ``zoo:PATH``: a run folder, a model ``.zip`` in one, or a log folder (``logs``, ``logs/ALGO``)
    holding runs of ``env_id`` (its latest); FileNotFoundError or ValueError naming what is missing."""
    p = Path(path).expanduser()
    if not p.exists():
        raise FileNotFoundError(f"zoo:{path}: no such file or folder")
    if p.is_file():
        if p.suffix != ".zip":
            raise ValueError(f"zoo:{path}: give a run folder or a model .zip of one")
        return ZooRun(p.parent, p)
    if any((d / "args.yml").is_file() for d in p.iterdir() if d.is_dir()):
        return ZooRun(p)
    runs = _latest_runs(p, env_id) if env_id else []
    if len(runs) != 1:
        what = "no run of " + str(env_id) if not runs else "runs of several algorithms: " + ", ".join(map(str, runs))
        raise ValueError(f"zoo:{path}: {what}; give the run folder (logs/ALGO/ENV_N)")
    return ZooRun(runs[0])


# -- the model -----------------------------------------------------------------------------------------------------
#: The algorithms whose policy_kwargs text this kind parses (:func:`vcnc_agents.config.parse_policy_kwargs`, with the
#: policy's class); another algorithm's model must hold its policy_kwargs as JSON.
_PARSED = {"ppo": ("MlpPolicy",), "ppo_lstm": ("MlpLstmPolicy",)}


def policy_kwargs_of(text, algo: str = "ppo", policy: str = "MlpPolicy") -> dict:
    """rl_zoo3's ``policy_kwargs`` hyperparameter (a dict, or its text ``"dict(net_arch=[64, 64])"``) as a dict,
    parsed without evaluating it (:func:`vcnc_agents.config.parse_policy_kwargs`: literals, ``dict(...)``, the
    activation functions and optimisers it names); ValueError for anything else."""
    from vcnc_agents.config import parse_policy_kwargs

    if policy not in _PARSED.get(algo, ()):
        raise ValueError(
            f"policy_kwargs of a {algo} {policy} are read from its model's JSON only; this model pickled them"
        )
    return parse_policy_kwargs(text, policy)


def _algorithm(name: str):
    import importlib

    if name not in ALGORITHMS:
        raise ValueError(f"the run's algorithm {name!r} is not one this kind loads ({', '.join(ALGORITHMS)})")
    module, cls = ALGORITHMS[name].rsplit(".", 1)
    return getattr(importlib.import_module(module), cls)


def _load_model(run: ZooRun, env):
    """The run's model, every pickled entry of its ``data`` replaced (nothing of the file unpickled)."""
    from vcnc_agents.model_file import check_torch, read_model_data, recorded_shape

    cls = _algorithm(run.algo)
    check_torch()
    data = read_model_data(run.model)
    for key in ("observation_space", "action_space"):
        shape, own = recorded_shape(data, key, run.model), tuple(getattr(env, key).shape)
        if shape != own:
            raise ValueError(f"{run.model}: the model's {key} has shape {shape}, the env's {own}")
    policy = run.hyperparams.get("policy", "MlpPolicy")
    if not isinstance(policy, str) or policy not in cls.policy_aliases:
        raise ValueError(f"{run.params / 'config.yml'}: policy {policy!r} is not one of {sorted(cls.policy_aliases)}")
    kwargs = data.get("policy_kwargs", {})
    serialized = isinstance(kwargs, dict) and ":serialized:" in kwargs
    replace = {
        "policy_class": cls.policy_aliases[policy],
        "observation_space": env.observation_space,
        "action_space": env.action_space,
        "policy_kwargs": policy_kwargs_of(run.hyperparams.get("policy_kwargs"), run.algo, policy)
        if serialized
        else kwargs,
    }
    for key, value in data.items():
        if key not in replace and isinstance(value, dict) and ":serialized:" in value:
            replace[key] = _CONSTANTS.get(key)
    try:
        return cls.load(run.model, device="cpu", custom_objects=replace)
    except pickle.UnpicklingError as exc:
        raise ValueError(f"{run.model}: its tensor files hold more than tensors ({exc})") from None
    except (RuntimeError, KeyError, ValueError, AssertionError, TypeError) as exc:
        raise ValueError(f"{run.model} does not load as a {run.algo} model ({type(exc).__name__}: {exc})") from None


class ZooAgent:
    """An rl_zoo3 run's agent as a policy with SB3's ``predict``: the observation normalised with the run's
    statistics (``VecNormalize.normalize_obs``), the model's action."""

    def __init__(self, model, normalization: dict | None, run: ZooRun):
        self.model, self.normalization, self.run = model, normalization, run

    def normalize(self, observation: np.ndarray) -> np.ndarray:
        n = self.normalization
        obs = np.asarray(observation, dtype=np.float32)
        if n is None or not n["norm_obs"]:
            return obs
        scaled = (obs - n["mean"]) / np.sqrt(n["var"] + n["epsilon"])
        return np.clip(scaled, -n["clip_obs"], n["clip_obs"]).astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return self.model.predict(self.normalize(observation), state, episode_start, deterministic)

    def __repr__(self) -> str:
        return f"ZooAgent({self.run.algo} on {self.run.env_id}, {self.run.model})"


def _check_env(run: ZooRun, env) -> None:
    """ValueError unless ``env`` is the env the run trained on, unwrapped by the run's hyperparameters."""
    spec = env.unwrapped.spec
    env_id = spec.id if spec is not None else None
    if env_id != run.env_id:
        raise ValueError(
            f"{run.folder} trained on {run.env_id}, not {env_id}: run it with vcnc-bench --env {run.env_id}"
        )
    for key, value in run.env_kwargs().items():
        if spec.kwargs.get(key) != value:
            raise ValueError(f"{run.folder} trained with {key}={value!r}; this env has {key}={spec.kwargs.get(key)!r}")
    for key in ("env_wrapper", "frame_stack"):
        if run.hyperparams.get(key):
            raise ValueError(
                f"{run.folder}: its hyperparameters set {key} ({run.hyperparams[key]!r}); the zoo kind runs agents "
                "on the registered env itself (the learnable ids, VCNC-...-v2, need no wrapper)"
            )


def load_zoo_agent(path: str, env) -> ZooAgent:
    """The agent of ``zoo:PATH`` (:func:`find_run`) for ``env``, checked to be the env it trained on."""
    spec = env.unwrapped.spec
    run = find_run(path, spec.id if spec is not None else None)
    _check_env(run, env)
    normalization = read_vecnormalize(run.normalization) if run.normalization is not None else None
    if normalization is not None and normalization["mean"].shape != env.observation_space.shape:
        raise ValueError(
            f"{run.normalization}: statistics of shape {normalization['mean'].shape}, the env's "
            f"observation {env.observation_space.shape}"
        )
    return ZooAgent(_load_model(run, env.unwrapped), normalization, run)


KIND = PolicyKind(
    name="zoo",
    make=load_zoo_agent,
    description="an agent trained by RL Baselines3 Zoo: zoo:FOLDER, its run folder (logs/ALGO/ENV_N), a model "
    ".zip in it, or logs/ALGO (the env's latest run)",
)
