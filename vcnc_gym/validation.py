"""Argument checks shared by every layer: one rule per kind of value, one wording of the error.

Each returns the value converted (float, int, bool) or raises ``ValueError``
naming the argument and its unit.  Booleans, strings and complex numbers are
never accepted as numbers.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = [
    "real",
    "positive",
    "non_negative",
    "per_axis",
    "polynomial",
    "integer",
    "flag",
    "size",
    "available_memory",
    "MEMORY_FRACTION",
]

#: Share of the memory available when a size is checked that one request may
#: plan to fill (ours): the rest is left to the interpreter, the other
#: arrays of the run and the other processes of the machine.
MEMORY_FRACTION = 0.5


def _in(unit: str) -> str:
    return f" ({unit})" if unit else ""


def real(name: str, value, unit: str = "") -> float:
    """``value`` as a float; ValueError naming ``name`` and ``unit`` unless it is a finite real number."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number{_in(unit)}, got {value!r} of type {type(value).__name__}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite{_in(unit)}, got {value!r}")
    return v


def positive(name: str, value, unit: str = "") -> float:
    """``value`` as a float; ValueError naming ``name`` and ``unit`` unless it is a finite real > 0."""
    v = real(name, value, unit)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0{_in(unit)}, got {value!r}")
    return v


def non_negative(name: str, value, unit: str = "") -> float:
    """``value`` as a float; ValueError naming ``name`` and ``unit`` unless it is a finite real >= 0."""
    v = real(name, value, unit)
    if v < 0.0:
        raise ValueError(f"{name} must be >= 0{_in(unit)}, got {value!r}")
    return v


def per_axis(name: str, value, unit: str = "", *, rule=real) -> np.ndarray:
    """A scalar or a pair (x, y), each checked by ``rule`` (:func:`real`, :func:`positive`, :func:`non_negative`),
    as a (2,) float array: a controller gain given for both axes or per axis."""
    if isinstance(value, (str, bytes, bool)):
        raise ValueError(f"{name} must be a real number or a pair (x, y) of them{_in(unit)}, got {value!r}")
    if isinstance(value, numbers.Real) or (isinstance(value, np.ndarray) and value.ndim == 0):
        v = rule(name, value, unit)
        return np.array([v, v])
    try:
        items = list(value)
    except TypeError:
        raise ValueError(f"{name} must be a real number or a pair (x, y) of them{_in(unit)}, got {value!r}") from None
    if len(items) != 2:
        raise ValueError(f"{name} must be a scalar or have one value per axis (2), got {len(items)} values")
    return np.array([rule(f"{name}[{a}]", v, unit) for a, v in zip("xy", items)])


def polynomial(name: str, coeffs) -> np.ndarray:
    """Polynomial coefficients, highest power first: 1-D, finite, real, leading zeros dropped, not all zero."""
    if isinstance(coeffs, (str, bytes)):
        raise ValueError(f"{name} must be a sequence of real coefficients, got {coeffs!r}")
    if isinstance(coeffs, numbers.Real) and not isinstance(coeffs, bool):
        coeffs = [coeffs]
    try:
        c = np.asarray(coeffs)
    except Exception as exc:  # pragma: no cover - numpy rarely refuses
        raise ValueError(f"{name}: cannot read coefficients {coeffs!r}: {exc}") from None
    if c.dtype == bool or c.dtype.kind not in "iuf":
        raise ValueError(f"{name} must hold real numbers, got {coeffs!r}")
    c = np.atleast_1d(c.astype(float))
    if c.ndim != 1 or c.size == 0:
        raise ValueError(f"{name} must be a 1-D sequence of coefficients, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{name} must be finite, got {c}")
    c = np.trim_zeros(c, "f")
    if c.size == 0:
        raise ValueError(f"{name} is the zero polynomial")
    return c


def integer(name: str, value, minimum: int = 1, maximum: int | None = None) -> int:
    """``value`` as an int; ValueError unless it is an integer (not a bool) in [minimum, maximum]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer, got {value!r} of type {type(value).__name__}")
    v = int(value)
    if v < minimum or (maximum is not None and v > maximum):
        bound = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        raise ValueError(f"{name} must be an integer {bound}, got {value!r}")
    return v


def flag(name: str, value) -> bool:
    """``value`` as a bool; ValueError unless it is True or False (not "no", not 0)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r} of type {type(value).__name__}")
    return bool(value)


def available_memory() -> int:
    """Bytes of memory a new allocation can get now without swapping.

    ``MemAvailable`` of ``/proc/meminfo`` (Linux: free memory plus the page
    cache that can be dropped); elsewhere the free physical pages
    (``os.sysconf``); 2**63 - 1 if neither can be read.
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import os

        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return 2**63 - 1


def _bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000.0 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} TB"  # pragma: no cover


def size(
    name: str, value, *, bytes_each: float | None = None, ceiling: int | None = None, why: str = "", minimum: int = 1
) -> int:
    """``value`` as an int in [minimum, limit]: a size a user gives (envs, plants, trials, steps, samples).

    The limit is the smaller of ``ceiling`` (a documented bound; ``why`` says
    where it comes from) and, with ``bytes_each``, the count whose memory
    fits in :data:`MEMORY_FRACTION` of :func:`available_memory`.  Checked
    before anything of that size is built.

    Parameters
    ----------
    name : str
        The argument as the user wrote it (``"num_envs"``, ``"--plants"``).
    value : int
        The size asked for.
    bytes_each : float, optional
        Memory that one unit of the size costs, bytes (e.g. one env's rows of
        the batch arrays).
    ceiling : int, optional
        A fixed upper bound.
    why : str
        What the ceiling or ``bytes_each`` is, for the message ("each env
        holds 2.1 kB of batch arrays").
    minimum : int
        Smallest valid value.

    Raises
    ------
    ValueError
        Naming ``name``, the limit and why, if ``value`` is not an integer in
        [minimum, limit].
    """
    v = integer(name, value, minimum)
    limits = []
    if ceiling is not None:
        limits.append((int(ceiling), why or "a documented ceiling"))
    if bytes_each is not None and bytes_each > 0:
        free = available_memory()
        fit = int(MEMORY_FRACTION * free // bytes_each)
        reason = (
            f"{why + ': ' if why and ceiling is None else ''}{_bytes(bytes_each)} each, against "
            f"{MEMORY_FRACTION:.0%} of the {_bytes(free)} of memory this machine has available"
        )
        limits.append((max(fit, 0), reason))
    if not limits:
        return v
    limit, reason = min(limits, key=lambda item: item[0])
    if v > limit:
        raise ValueError(f"{name} must be at most {limit:,} ({reason}), got {v:,}")
    return v
