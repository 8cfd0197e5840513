"""What produced a bench's figures: the CPU, the libraries and numba's settings, for the JSON's ``settings``.

The same agent file gave a different max contour error on another CPU (``agents/trained/README.md``: the
shop-floor heart's nominal max 57.4 um on one host, 73.8 um on another): float32 network arithmetic and numba's
compiled kernels depend on the instruction set (FMA, AVX-512) LLVM targets and on the libraries' versions.  A
figure is therefore recorded with the CPU model and flags (``/proc/cpuinfo``; ``platform`` elsewhere), the versions
of numpy, numba, torch, Stable-Baselines3 and gymnasium, and numba's settings (the threading layer asked for and
the one in use, ``NUMBA_OPT``, the CPU name and features LLVM compiles for, fastmath off by the suite's rule), and
the environment variables that choose the libraries' code paths (:data:`CODE_PATH_VARIABLES`).

Another CPU's code paths can be taken on this host (:func:`code_paths_of`): numba compiles for the recorded CPU
name and features, OpenBLAS runs that CPU's kernels (``OPENBLAS_CORETYPE``) and torch, MKL and oneDNN stop at its
vector width.  ``python -m vcnc_bench.provenance --like RUN.json -- COMMAND ...`` runs a command so, to judge
whether a verdict holds on the CPU a stored run was made on.  Tested where the other CPU's figures are known: the
identification run shipped from a Zen 3 host is reproduced to the bit on a Zen 4 host
(``tests/test_commissioning.py``), and not without it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path

__all__ = [
    "LIBRARIES",
    "CODE_PATH_VARIABLES",
    "OPENBLAS_CORES",
    "cpu",
    "libraries",
    "numba_settings",
    "code_paths",
    "provenance",
    "code_paths_of",
]

#: The distributions whose versions are recorded (None where not installed).
LIBRARIES = ("numpy", "numba", "llvmlite", "torch", "stable-baselines3", "gymnasium", "scipy", "vcnc-gym")


def cpu(cpuinfo: str | Path = "/proc/cpuinfo") -> dict:
    """The CPU's model name, flags (sorted) and logical count: from ``cpuinfo`` (Linux) where readable, else
    :mod:`platform`'s processor string and no flags."""
    model, flags = None, []
    try:
        for line in Path(cpuinfo).read_text().splitlines():
            key, _, value = line.partition(":")
            key = key.strip()
            if key == "model name" and model is None:
                model = value.strip()
            elif key in ("flags", "Features") and not flags:
                flags = sorted(value.split())
    except OSError:
        pass
    return {
        "model": model or platform.processor() or platform.machine(),
        "flags": flags,
        "logical_cpus": os.cpu_count(),
        "machine": platform.machine(),
    }


def libraries() -> dict:
    """``{distribution: version or None}`` of :data:`LIBRARIES`, and Python's version."""
    out = {"python": sys.version.split()[0]}
    for name in LIBRARIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def numba_settings() -> dict:
    """numba's settings that change compiled code or its threads: the threading layer asked for
    (``NUMBA_THREADING_LAYER``) and the one in use (None before any parallel kernel ran), ``NUMBA_OPT``, the
    number of threads, the CPU name and features LLVM targets (``NUMBA_CPU_NAME``/``NUMBA_CPU_FEATURES`` or the
    host's), and ``NUMBA_DISABLE_JIT``."""
    import numba
    from numba.core import config

    try:
        in_use = numba.threading_layer()
    except ValueError:  # no parallel kernel has run in this process
        in_use = None
    try:
        import llvmlite.binding as llvm

        host_name, host_features = llvm.get_host_cpu_name(), llvm.get_host_cpu_features().flatten()
    except Exception:  # noqa: BLE001  (a llvmlite without these calls: recorded as unknown)
        host_name, host_features = None, None
    return {
        "threading_layer_requested": config.THREADING_LAYER,
        "threading_layer": in_use,
        "opt": config.OPT,
        "num_threads": config.NUMBA_NUM_THREADS,
        "cpu_name": config.CPU_NAME or host_name,
        "cpu_features": config.CPU_FEATURES or host_features,
        "disable_jit": bool(config.DISABLE_JIT),
    }


#: The environment variables that choose the code paths of the libraries the figures go through (numpy's, OpenBLAS's,
#: torch's, MKL's, oneDNN's); numba's are in :func:`numba_settings`.
CODE_PATH_VARIABLES = (
    "NPY_DISABLE_CPU_FEATURES",
    "OPENBLAS_CORETYPE",
    "ATEN_CPU_CAPABILITY",
    "MKL_ENABLE_INSTRUCTIONS",
    "ONEDNN_MAX_CPU_ISA",
)

#: OpenBLAS's kernels (``OPENBLAS_CORETYPE``) for the CPU names LLVM gives (numba's ``cpu_name``); a name not here
#: leaves OpenBLAS to choose by itself, which :func:`code_paths_of` says.
OPENBLAS_CORES = {
    "znver1": "Zen",
    "znver2": "Zen",
    "znver3": "Zen",
    "haswell": "Haswell",
    "broadwell": "Haswell",
    "skylake": "Haswell",
    "skylake-avx512": "SkylakeX",
    "cascadelake": "SkylakeX",
    "icelake-server": "SkylakeX",
    "cooperlake": "Cooperlake",
    "sapphirerapids": "SapphireRapids",
}


def code_paths() -> dict:
    """``{variable: value or None}`` of :data:`CODE_PATH_VARIABLES` in this process's environment."""
    return {k: os.environ.get(k) for k in CODE_PATH_VARIABLES}


def provenance() -> dict:
    """Everything above, JSON-ready: ``{"cpu", "libraries", "numba", "code_paths", "platform"}``."""
    return {
        "cpu": cpu(),
        "libraries": libraries(),
        "numba": numba_settings(),
        "code_paths": code_paths(),
        "platform": platform.platform(),
    }


def code_paths_of(recorded: dict) -> tuple[dict, list[str]]:
    """The environment variables that make this host take the code paths of the CPU in ``recorded`` (a JSON's
    ``settings["provenance"]``), and what they cannot set (a list of sentences: an OpenBLAS core type unknown for
    the CPU's name).  numba: the recorded CPU name and features; OpenBLAS: :data:`OPENBLAS_CORES`; torch, MKL and
    oneDNN: AVX-512 if the recorded flags have ``avx512f``, else AVX2 if they have ``avx2``, else their defaults.
    ValueError naming what ``recorded`` lacks."""
    numba, flags = recorded.get("numba") or {}, set((recorded.get("cpu") or {}).get("flags") or ())
    if not numba.get("cpu_name") or not numba.get("cpu_features"):
        raise ValueError("the run's provenance has no numba cpu_name and cpu_features: its CPU cannot be named")
    if not flags:
        raise ValueError("the run's provenance has no CPU flags: its vector width cannot be known")
    env = {"NUMBA_CPU_NAME": numba["cpu_name"], "NUMBA_CPU_FEATURES": numba["cpu_features"]}
    left = []
    core = OPENBLAS_CORES.get(numba["cpu_name"])
    if core is None:
        left.append(f"no OpenBLAS core type is known for {numba['cpu_name']!r}: OpenBLAS chooses this host's kernels")
    else:
        env["OPENBLAS_CORETYPE"] = core
    if "avx512f" in flags:
        env.update(ATEN_CPU_CAPABILITY="avx512", MKL_ENABLE_INSTRUCTIONS="AVX512", ONEDNN_MAX_CPU_ISA="AVX512_CORE")
    elif "avx2" in flags:
        env.update(ATEN_CPU_CAPABILITY="avx2", MKL_ENABLE_INSTRUCTIONS="AVX2", ONEDNN_MAX_CPU_ISA="AVX2")
    recorded_paths = recorded.get("code_paths") or {}
    if recorded_paths.get("NPY_DISABLE_CPU_FEATURES") is not None:
        env["NPY_DISABLE_CPU_FEATURES"] = recorded_paths["NPY_DISABLE_CPU_FEATURES"]
    return env, left


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m vcnc_bench.provenance",
        description="Run a command on the code paths of the CPU a stored run was made on (numba's target, OpenBLAS's "
        "kernels, torch's vector width), with a fresh numba cache of its own.",
    )
    p.add_argument(
        "--like",
        type=Path,
        required=True,
        metavar="RUN.json",
        help="a vcnc-bench --json file (its settings' provenance) or a provenance JSON",
    )
    p.add_argument(
        "--cache",
        type=Path,
        metavar="DIR",
        help="NUMBA_CACHE_DIR for the other CPU's kernels (default ~/.cache/vcnc-gym/numba-CPU_NAME)",
    )
    p.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND ARG ...")
    args = p.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        p.error("give the command after --")
    try:
        data = json.loads(args.like.read_text())
    except (OSError, ValueError) as exc:
        p.error(f"--like: {args.like}: {exc}")
    recorded = (data.get("settings") or {}).get("provenance") or data
    try:
        env, left = code_paths_of(recorded)
    except ValueError as exc:
        p.error(f"--like: {args.like}: {exc}")
    cache = args.cache or Path.home() / ".cache" / "vcnc-gym" / f"numba-{env['NUMBA_CPU_NAME']}"
    env["NUMBA_CACHE_DIR"] = str(cache)
    for sentence in left:
        print(f"vcnc_bench.provenance: warning: {sentence}", file=sys.stderr)
    print(
        "vcnc_bench.provenance: " + " ".join(f"{k}={v if len(v) < 40 else v[:37] + '...'}" for k, v in env.items()),
        file=sys.stderr,
        flush=True,
    )
    return subprocess.call(command, env={**os.environ, **env})


if __name__ == "__main__":
    raise SystemExit(main())
