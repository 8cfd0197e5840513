"""Argument checks shared by every layer: one rule per kind of value, one wording of the error.

Each returns the value converted (float, int, bool) or raises ``ValueError``
naming the argument and its unit.  Booleans, strings and complex numbers are
never accepted as numbers.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["real", "positive", "non_negative", "integer", "flag"]


def real(name: str, value, unit: str) -> float:
    """``value`` as a float; ValueError naming ``name`` and ``unit`` unless it is a finite real number."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number ({unit}), got {value!r} of type {type(value).__name__}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite ({unit}), got {value!r}")
    return v


def positive(name: str, value, unit: str) -> float:
    """``value`` as a float; ValueError naming ``name`` and ``unit`` unless it is a finite real > 0."""
    v = real(name, value, unit)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0 ({unit}), got {value!r}")
    return v


def non_negative(name: str, value, unit: str) -> float:
    """``value`` as a float; ValueError naming ``name`` and ``unit`` unless it is a finite real >= 0."""
    v = real(name, value, unit)
    if v < 0.0:
        raise ValueError(f"{name} must be >= 0 ({unit}), got {value!r}")
    return v


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


