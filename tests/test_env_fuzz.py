"""A short run of tests/probes/fuzz_envs.py: random valid curves and settings give clean episodes.

The full run (1 000 episodes) is ``python tests/probes/fuzz_envs.py``; here 30
episodes, and a check that the fuzz does see a NaN when one is there.
"""

from __future__ import annotations

import numpy as np
import pytest
from benchmark_script import probe_script

import vcnc_gym

fuzz_envs = probe_script("fuzz_envs")


@pytest.mark.slow  # > 10 s on 2 cores (pytest --durations, 2026-11-24)
def test_random_curves_and_settings_give_clean_episodes():
    out = fuzz_envs.fuzz(episodes=30, steps=80, seed=1, progress=False)
    c = out["counts"]
    assert c["episodes"] >= 15 and c["steps"] > 500
    assert {k: c[k] for k in fuzz_envs.FAILURE_KEYS} == {k: 0 for k in fuzz_envs.FAILURE_KEYS}, out["failures"][:1]


def test_the_fuzz_sees_a_nan(monkeypatch):
    """The check can fail: an env whose observations hold a NaN is counted."""
    step = vcnc_gym.ContouringEnv.step

    def poisoned(self, action):
        obs, r, te, tr, info = step(self, action)
        obs = obs.copy()
        obs[0] = np.nan
        return obs, r, te, tr, info

    monkeypatch.setattr(vcnc_gym.ContouringEnv, "step", poisoned)
    out = fuzz_envs.fuzz(episodes=3, steps=5, seed=2, progress=False)
    assert out["counts"]["non-finite observation"] > 0 and out["counts"]["observation outside the space"] > 0
