"""VecNormalize statistics as data: a ``.npz`` file read with ``allow_pickle=False``.

SB3 saves a ``VecNormalize`` with :mod:`pickle`, and unpickling a file runs
whatever code the file asks for.  An agent folder and a run's checkpoints hold
:class:`NormalizationStats` instead, plain numbers in an ``.npz``:

=============== =========== ===================================================
key             shape/type  meaning
=============== =========== ===================================================
format          int         file format version (1)
norm_obs        bool        observations are normalised
norm_reward     bool        rewards are normalised (training only)
obs_mean        (n,) f8     running mean of the observations
obs_var         (n,) f8     running variance of the observations
obs_count       f8          observations counted (VecNormalize's RunningMeanStd)
ret_mean        f8          running mean of the discounted return
ret_var         f8          running variance of the discounted return
ret_count       f8          returns counted
clip_obs        f8          normalised observations are clipped to +-clip_obs
clip_reward     f8          normalised rewards are clipped to +-clip_reward
epsilon         f8          added to the variances before the square root
gamma           f8          discount of the return statistics
=============== =========== ===================================================

``normalize_obs`` computes exactly what ``VecNormalize.normalize_obs`` does,
``clip((obs - mean) / sqrt(var + epsilon), -clip_obs, clip_obs)`` cast to
float32, so an agent loaded from the file acts bit for bit as in training.

Converting an old ``vecnormalize.pkl`` needs unpickling it, which is safe only
for a file you trust (one you wrote yourself)::

    python -m vcnc_agents.normalization --convert-trusted-pickle RUN/best/vecnormalize.pkl
"""

from __future__ import annotations

import io
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["NormalizationStats", "FORMAT_VERSION", "convert_trusted_pickle"]

FORMAT_VERSION = 1
_SCALARS = ("obs_count", "ret_mean", "ret_var", "ret_count", "clip_obs", "clip_reward", "epsilon", "gamma")
_KEYS = ("format", "norm_obs", "norm_reward", "obs_mean", "obs_var") + _SCALARS


@dataclass(frozen=True)
class NormalizationStats:
    """The statistics of an SB3 ``VecNormalize`` (flat Box observations), as plain data.

    Attributes are those of the module's table.
    """

    norm_obs: bool
    norm_reward: bool
    obs_mean: np.ndarray
    obs_var: np.ndarray
    obs_count: float
    ret_mean: float
    ret_var: float
    ret_count: float
    clip_obs: float
    clip_reward: float
    epsilon: float
    gamma: float

    def __post_init__(self):
        self.check()

    @property
    def observation_size(self) -> int:
        """Number of observation entries the statistics describe."""
        return int(self.obs_mean.shape[0])

    def check(self, where: str = "normalisation statistics") -> None:
        """ValueError naming ``where`` and the field for shapes or values VecNormalize never writes."""
        m, v = np.asarray(self.obs_mean), np.asarray(self.obs_var)
        if m.ndim != 1 or v.shape != m.shape or m.size == 0:
            raise ValueError(
                f"{where}: obs_mean and obs_var must be two equal non-empty vectors, got shapes {m.shape} and {v.shape}"
            )
        if not (np.all(np.isfinite(m)) and np.all(np.isfinite(v)) and np.all(v >= 0)):
            raise ValueError(f"{where}: obs_mean must be finite and obs_var finite and >= 0")
        for name in _SCALARS:
            x = getattr(self, name)
            if not math.isfinite(x):
                raise ValueError(f"{where}: {name} must be finite, got {x!r}")
        for name in ("obs_count", "ret_count", "clip_obs", "clip_reward", "epsilon"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{where}: {name} must be > 0, got {getattr(self, name)!r}")
        if self.ret_var < 0 or not 0 < self.gamma <= 1:
            raise ValueError(f"{where}: ret_var must be >= 0 and gamma in (0, 1], got {self.ret_var!r}, {self.gamma!r}")

    # -- use -----------------------------------------------------------------------------------
    def normalize_obs(self, obs: np.ndarray) -> np.ndarray:
        """Observations as the agent saw them in training (VecNormalize.normalize_obs), float32."""
        if not self.norm_obs:
            return np.array(obs, copy=True)
        return np.clip(
            (obs - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon), -self.clip_obs, self.clip_obs
        ).astype(np.float32)

    # -- VecNormalize ------------------------------------------------------------------------------
    @classmethod
    def from_vecnormalize(cls, vec_normalize) -> "NormalizationStats":
        """A copy of a live VecNormalize's statistics."""
        o, r = vec_normalize.obs_rms, vec_normalize.ret_rms
        return cls(
            norm_obs=bool(vec_normalize.norm_obs),
            norm_reward=bool(vec_normalize.norm_reward),
            obs_mean=np.array(o.mean, dtype=np.float64),
            obs_var=np.array(o.var, dtype=np.float64),
            obs_count=float(o.count),
            ret_mean=float(np.asarray(r.mean).reshape(())),
            ret_var=float(np.asarray(r.var).reshape(())),
            ret_count=float(r.count),
            clip_obs=float(vec_normalize.clip_obs),
            clip_reward=float(vec_normalize.clip_reward),
            epsilon=float(vec_normalize.epsilon),
            gamma=float(vec_normalize.gamma),
        )

    def vecnormalize(self, venv, training: bool = True):
        """A VecNormalize around ``venv`` holding these statistics (``returns`` start at zero, as after a reset)."""
        from stable_baselines3.common.vec_env import VecNormalize

        n = venv.observation_space.shape
        if n != (self.observation_size,):
            raise ValueError(
                f"the normalisation statistics describe {self.observation_size} observation entries, "
                f"the env gives shape {n}"
            )
        v = VecNormalize(
            venv,
            training=training,
            norm_obs=self.norm_obs,
            norm_reward=self.norm_reward,
            clip_obs=self.clip_obs,
            clip_reward=self.clip_reward,
            gamma=self.gamma,
            epsilon=self.epsilon,
        )
        v.obs_rms.mean, v.obs_rms.var, v.obs_rms.count = self.obs_mean.copy(), self.obs_var.copy(), self.obs_count
        v.ret_rms.mean, v.ret_rms.var, v.ret_rms.count = (
            np.float64(self.ret_mean),
            np.float64(self.ret_var),
            self.ret_count,
        )
        return v

    # -- the file -----------------------------------------------------------------------------------
    def save(self, path) -> None:
        """Write the ``.npz`` atomically (a temporary file renamed over ``path``)."""
        arrays = {
            "format": np.int64(FORMAT_VERSION),
            "norm_obs": np.bool_(self.norm_obs),
            "norm_reward": np.bool_(self.norm_reward),
            "obs_mean": self.obs_mean,
            "obs_var": self.obs_var,
        }
        arrays.update({k: np.float64(getattr(self, k)) for k in _SCALARS})
        buffer = io.BytesIO()
        np.savez(buffer, **arrays)
        atomic_write_bytes(Path(path), buffer.getvalue())

    @classmethod
    def load(cls, path) -> "NormalizationStats":
        """Read a ``.npz`` written by :meth:`save` (``allow_pickle=False``: no code runs).

        Raises FileNotFoundError for a missing file and ValueError naming the
        file for anything else (not an npz, object arrays, missing keys, bad values).
        """
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no normalisation statistics at {str(path)!r}")
        try:
            z = np.load(path, allow_pickle=False)
        except Exception as exc:  # ValueError (pickled or unknown content), EOFError (empty), BadZipFile...
            raise ValueError(f"{path} is not a data-only .npz file ({type(exc).__name__}: {exc})") from None
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise ValueError(f"{path} is a single .npy array, not the .npz of normalisation statistics")
        with z:
            missing = [k for k in _KEYS if k not in z.files]
            if missing:
                raise ValueError(f"{path} is not a normalisation file of vcnc-gym: it lacks {', '.join(missing)}")
            try:
                data = {k: z[k] for k in _KEYS}
            except Exception as exc:  # object arrays (pickles), damaged members
                raise ValueError(f"{path} is damaged or holds non-numeric data ({type(exc).__name__}: {exc})") from None
        if int(data["format"]) != FORMAT_VERSION:
            raise ValueError(f"{path} has format {int(data['format'])}, this code reads format {FORMAT_VERSION}")
        for k, a in data.items():
            if a.dtype.kind not in "biuf":
                raise ValueError(f"{path}: {k} must be numeric, got dtype {a.dtype}")
            if k not in ("obs_mean", "obs_var") and a.shape != ():
                raise ValueError(f"{path}: {k} must be a scalar, got shape {a.shape}")
        try:
            return cls(
                norm_obs=bool(data["norm_obs"]),
                norm_reward=bool(data["norm_reward"]),
                obs_mean=data["obs_mean"].astype(np.float64),
                obs_var=data["obs_var"].astype(np.float64),
                **{k: float(data[k]) for k in _SCALARS},
            )
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None


def atomic_write_bytes(path: Path, payload: bytes) -> None:
    """Write ``payload`` to ``path`` through a temporary file in the same folder, then rename it.

    A reader (or a process killed mid-write) sees the old file or the whole
    new one, never a truncated one.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            f.write(payload)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def convert_trusted_pickle(pkl_path, npz_path=None) -> Path:
    """Convert a VecNormalize ``.pkl`` (SB3's ``VecNormalize.save``) into the ``.npz`` of this module.

    This UNPICKLES ``pkl_path``, which runs any code the file holds: call it
    only on a file you trust (one your own training wrote).  Returns the
    written ``.npz`` path (default: next to the pickle, ``vecnormalize.npz``).
    """
    import pickle

    pkl_path = Path(pkl_path)
    npz_path = Path(npz_path) if npz_path is not None else pkl_path.with_suffix(".npz")
    with open(pkl_path, "rb") as f:
        vec_normalize = pickle.load(f)  # trusted by the caller, see the docstring
    NormalizationStats.from_vecnormalize(vec_normalize).save(npz_path)
    return npz_path


def main(argv: list[str] | None = None) -> int:
    """``python -m vcnc_agents.normalization --convert-trusted-pickle FILE.pkl [FILE.pkl ...]``"""
    import argparse

    p = argparse.ArgumentParser(
        prog="python -m vcnc_agents.normalization",
        description="Convert VecNormalize pickles you trust into data-only .npz files.",
    )
    p.add_argument(
        "--convert-trusted-pickle",
        nargs="+",
        metavar="PKL",
        required=True,
        type=Path,
        help="pickles to convert (each becomes a .npz next to it); unpickling runs the file's code",
    )
    args = p.parse_args(argv)
    for pkl in args.convert_trusted_pickle:
        print(f"{pkl} -> {convert_trusted_pickle(pkl)}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
