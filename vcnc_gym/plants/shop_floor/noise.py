"""The shop floor's noise generator: one splitmix64 state per machine, normal numbers by Box-Muller (numba)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["splitmix64", "normal_pair"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_ONE = np.uint64(1)


@njit(cache=True, _nrt=False)
def splitmix64(rng, k):
    """Next 64-bit output of machine ``k``'s splitmix64 generator (Steele, Lea & Flood 2014), state
    ``rng[k]`` advanced."""
    s = rng[k] + _GOLDEN
    rng[k] = s
    z = (s ^ (s >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@njit(cache=True, _nrt=False)
def normal_pair(rng, k):
    """Two independent standard normal numbers from machine ``k``'s generator (Box-Muller on two uniforms
    in (0, 1])."""
    u1 = float((splitmix64(rng, k) >> _S11) + _ONE) * 2.0**-53
    u2 = float((splitmix64(rng, k) >> _S11) + _ONE) * 2.0**-53
    r = math.sqrt(-2.0 * math.log(u1))
    t = 2.0 * math.pi * u2
    return r * math.cos(t), r * math.sin(t)
