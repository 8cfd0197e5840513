"""The floor's solutions, cached: the bench replays a stored solution instead of solving again.

A solution (:class:`~vcnc_baselines.optimal.search.Solution`) is keyed by :func:`signature`: the env's id and keyword
arguments (``env.spec``), a hash of its packed reference, its control and decision periods, the plant's name and
exact parameters, and, on a plant with a random state (the shop floor's sensor noise), that state right after the
env's reset (a function of the reset's seed: the closed-loop starts, and so the floor, see that noise); a plant
without one is keyed without the seed, its replay being the same for every seed.  Each is one compressed
``.npz`` in :data:`DIRECTORY` (shipped with the package: the nominal plant of every contouring id,
``python benchmarks/oracle_convergence.py --store``) or in ``$VCNC_ORACLE_SOLUTIONS``: the start's name, the
correction (float32: the step kernel adds it as float32, so the stored values are the replayed ones), the
start's recorded commands where it runs open-loop, the replayed figures, the starts' figures and the
convergence.  A floor solved on this machine is stored in :func:`user_cache` (or ``$VCNC_ORACLE_SOLUTIONS``),
never in the package.  A key may hold several solutions, ``KEY.npz`` and ``KEY~CPU.npz``: the same floor solved on
other CPUs' code paths, where the first does not replay to the bit; the oracle tries them in turn
(:func:`load_all`).  ``VCNC_ORACLE_RECOMPUTE=1`` ignores stored solutions (and overwrites them where writable).
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np

from vcnc_gym.schema import BadFile, checked, count, mapping, number, sequence

from .search import Solution

__all__ = [
    "DIRECTORY",
    "SOLVER_VERSION",
    "signature",
    "user_cache",
    "directory",
    "folders",
    "paths",
    "load",
    "load_all",
    "store",
    "recompute_requested",
]

#: The shipped solutions.
DIRECTORY = Path(__file__).with_name("solutions")

#: Bumped when the search or the replay changes what a stored solution means.
SOLVER_VERSION = 1


def user_cache() -> Path:
    """Where the floors solved on this machine are kept: ``$XDG_CACHE_HOME/vcnc-gym/oracle`` (default
    ``~/.cache``), never the package (an installed package is not a scratch folder, and a test run must not leave
    files in the source tree)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "vcnc-gym" / "oracle"


def directory() -> Path:
    """Where :func:`store` writes: ``$VCNC_ORACLE_SOLUTIONS`` if set, else :func:`user_cache`."""
    return Path(os.environ.get("VCNC_ORACLE_SOLUTIONS") or user_cache())


def folders() -> list[Path]:
    """Where :func:`load` looks, in order: ``$VCNC_ORACLE_SOLUTIONS`` alone if set, else the shipped
    :data:`DIRECTORY` and :func:`user_cache`."""
    env = os.environ.get("VCNC_ORACLE_SOLUTIONS")
    return [Path(env)] if env else [DIRECTORY, user_cache()]


def recompute_requested() -> bool:
    """True if ``$VCNC_ORACLE_RECOMPUTE`` is set to something other than ``""`` or ``"0"``."""
    return os.environ.get("VCNC_ORACLE_RECOMPUTE", "") not in ("", "0")


#: A vector env's own arguments in its spec: how the envs are batched, not what they simulate; not in a key, so
#: that the floor of a plant stored from a single env is found from a vector env (the bench's ``--plants``) too.
VECTOR_KWARGS = ("autoreset_mode", "parallel", "vectorization_mode", "num_envs")


def signature(env, parameters: np.ndarray, noise_state=None) -> str:
    """The key of the floor for ``env`` (after its reset; a single env or a vector env) on the plant ``parameters``
    (2, P): a file name ``ID-HASH`` (see the module notes)."""
    u = env.unwrapped
    task = u.task
    spec = getattr(u, "spec", None) or getattr(env, "spec", None)
    name = spec.id if spec is not None else task.plant.name
    kwargs = None if spec is None else {k: v for k, v in spec.kwargs.items() if k not in VECTOR_KWARGS}
    h = hashlib.sha256()
    h.update(
        json.dumps(
            {
                "version": SOLVER_VERSION,
                "id": name,
                "kwargs": kwargs,
                "dt": task.dt,
                "n_repeat": int(task.config.n_repeat),
                "plant": task.plant.name,
                "options": task.plant_options,
            },
            sort_keys=True,
            default=repr,
        ).encode()
    )
    h.update(np.ascontiguousarray(task.reference_arrays.samples).tobytes())
    h.update(np.ascontiguousarray(parameters, dtype=np.float64).tobytes())
    if noise_state is not None:
        h.update(np.asarray(noise_state, dtype=np.uint64).tobytes())
    return f"{name}-{h.hexdigest()[:20]}"


def paths(key: str) -> list[Path]:
    """The files of the solutions stored under ``key``, in the order :func:`load_all` reads them: per folder of
    :func:`folders`, ``KEY.npz`` then ``KEY~CPU.npz`` (the same floor solved on another CPU's code paths, where the
    first does not replay to the bit: a floor's replay is exact only on the code paths it was solved on)."""
    out = []
    for folder in folders():
        first = folder / f"{key}.npz"
        out += [first] if first.is_file() else []
        out += sorted(folder.glob(f"{key}~*.npz"))
    return out


def load_all(key: str) -> list[Solution]:
    """Every solution stored under ``key`` (:func:`paths`), the first to try first; a damaged file (truncated,
    empty, not one :func:`store` writes) is passed over with a warning naming it."""
    out = []
    for p in paths(key):
        try:
            out.append(_read(p))
        except BadFile as exc:
            warnings.warn(f"the stored floor {exc}: the next stored solution, else solving again", stacklevel=2)
    return out


def load(key: str) -> Solution | None:
    """The first solution stored under ``key``, or None; :class:`vcnc_gym.schema.BadFile` naming a damaged file."""
    found = paths(key)
    return _read(found[0]) if found else None


#: The arrays of a stored solution (:func:`store`): name -> (dimensions, dtype kind) ("f" real, "i" integer, "U"
#: text).
_ARRAYS = {
    "start": (0, "U"),
    "correction": (2, "f"),
    "table": (2, "f"),
    "max_um": (0, "f"),
    "rms_um": (0, "f"),
    "warm_starts": (0, "U"),
    "history": (2, "f"),
    "solve_time_s": (0, "f"),
    "evaluations": (0, "i"),
}


def _arrays(path: Path) -> dict:
    """The arrays of the ``.npz`` ``path``; BadFile if it is not one (truncated, empty, pickled objects)."""
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise BadFile(path, "is a single .npy array, not a stored floor's .npz")
        with z:
            return {k: z[k] for k in z.files}
    except BadFile:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise BadFile(
            path, f"is not a stored floor's .npz (damaged or truncated?): {type(exc).__name__}: {exc}"
        ) from None


def _check(path: Path, z: dict) -> None:
    """The arrays checked as :func:`store` writes them: every one present with its shape and kind, the correction
    and the table (L, 2) and finite, the figures finite and >= 0."""
    missing = [k for k in _ARRAYS if k not in z]
    if missing:
        raise BadFile(path, f"is not a stored floor: it has no array {missing[0]!r}")
    for name, (ndim, dtype) in _ARRAYS.items():
        a = z[name]
        if a.ndim != ndim or a.dtype.kind != dtype or (ndim == 2 and a.shape[1] != 2):
            shape = "a scalar" if ndim == 0 else "(L, 2)"
            raise BadFile(path, f"{name} must be {shape} of kind {dtype!r}, got {a.dtype} of shape {a.shape}")
    with checked(path):
        for name in ("correction", "table"):
            if not np.all(np.isfinite(z[name])):
                raise ValueError(f"{name} holds a value that is not finite")
        number("max_um", float(z["max_um"]), "um", minimum=0.0)
        number("rms_um", float(z["rms_um"]), "um", minimum=0.0)
        count("evaluations", int(z["evaluations"]))
        try:
            starts = json.loads(str(z["warm_starts"]))
        except (ValueError, RecursionError):
            raise ValueError("warm_starts is not the JSON of the starts' figures") from None
        for k, v in mapping("warm_starts", starts).items():
            sequence(f"warm_starts[{k!r}]", v, 2)


def _read(path: Path) -> Solution:
    """The solution stored in ``path``, checked (:func:`_check`); BadFile naming the file otherwise."""
    z = _arrays(path)
    _check(path, z)
    table = z["table"] if z["table"].size else None
    return Solution(
        start=str(z["start"]),
        correction=z["correction"],
        table=table,
        max_um=float(z["max_um"]),
        rms_um=float(z["rms_um"]),
        warm_starts={k: tuple(v) for k, v in json.loads(str(z["warm_starts"])).items()},
        history=z["history"],
        solve_time_s=float(z["solve_time_s"]),
        evaluations=int(z["evaluations"]),
    )


def store(key: str, solution: Solution, folder: Path | None = None) -> Path | None:
    """Write ``solution`` under ``key`` into ``folder`` (default :func:`directory`); the path, or None where the
    folder is not writable."""
    folder = directory() if folder is None else Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{key}.npz"
        np.savez_compressed(
            path,
            start=solution.start,
            correction=np.asarray(solution.correction, dtype=np.float32),
            table=np.zeros((0, 2), dtype=np.float32) if solution.table is None else solution.table,
            max_um=solution.max_um,
            rms_um=solution.rms_um,
            warm_starts=json.dumps(solution.warm_starts),
            history=solution.history,
            solve_time_s=solution.solve_time_s,
            evaluations=solution.evaluations,
        )
        return path
    except OSError:
        return None
