"""VCNC-OmegaOverride-v1's arguments: numbers through vcnc_gym.validation, the time limit's ceiling."""

from __future__ import annotations

import time

import gymnasium as gym
import pytest

import vcnc_gym  # noqa: F401
from vcnc_gym.envs.feed_override_env import MAX_TIME_LIMIT

ID = "VCNC-OmegaOverride-v1"


@pytest.mark.parametrize(
    "name, value",
    [
        ("time_cost", "1"),
        ("time_cost", True),
        ("time_cost", -1.0),
        ("time_limit", True),
        ("time_limit", "3"),
        ("time_limit", 0.5),
        ("override_rate", False),
        ("override_rate", "10"),
        ("max_override", True),
        ("max_override", 0.9),
        ("max_override", 2.0),
        ("lookahead", (100.0,)),
        ("lookahead", "fast"),
        ("lookahead", (0.0, 1e3)),
        ("lookahead", (100.0, "1000")),
    ],
)
def test_an_override_argument_that_is_not_a_valid_number_is_refused_naming_it(name, value):
    with pytest.raises(ValueError, match=name):
        gym.make(ID, **{name: value})


@pytest.mark.parametrize("limit", [MAX_TIME_LIMIT * 1.01, 1e4, 1e9])
def test_a_time_limit_above_the_ceiling_is_refused_at_once(limit):
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"time_limit must be in \[1, 100\]"):
        gym.make(ID, time_limit=limit)
    assert time.perf_counter() - t0 < 1.0
