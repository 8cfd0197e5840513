"""What produced a bench's figures: the CPU, the libraries and numba's settings, for the JSON's ``settings``.

The same agent file gave a different max contour error on another CPU (``agents/trained/README.md``: the
shop-floor heart's nominal max 57.4 um on one host, 73.8 um on another): float32 network arithmetic and numba's
compiled kernels depend on the instruction set (FMA, AVX-512) LLVM targets and on the libraries' versions.  A
figure is therefore recorded with the CPU model and flags (``/proc/cpuinfo``; ``platform`` elsewhere), the versions
of numpy, numba, torch, Stable-Baselines3 and gymnasium, and numba's settings (the threading layer asked for and
the one in use, ``NUMBA_OPT``, the CPU name and features LLVM compiles for, fastmath off by the suite's rule).
"""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata
from pathlib import Path

__all__ = ["LIBRARIES", "cpu", "libraries", "numba_settings", "provenance"]

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
    return {"model": model or platform.processor() or platform.machine(), "flags": flags,
            "logical_cpus": os.cpu_count(), "machine": platform.machine()}


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
    return {"threading_layer_requested": config.THREADING_LAYER, "threading_layer": in_use,
            "opt": config.OPT, "num_threads": config.NUMBA_NUM_THREADS,
            "cpu_name": config.CPU_NAME or host_name, "cpu_features": config.CPU_FEATURES or host_features,
            "disable_jit": bool(config.DISABLE_JIT)}


def provenance() -> dict:
    """Everything above, JSON-ready: ``{"cpu", "libraries", "numba", "platform"}``."""
    return {"cpu": cpu(), "libraries": libraries(), "numba": numba_settings(), "platform": platform.platform()}
