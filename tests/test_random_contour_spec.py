"""VCNC-RandomContour-v1's spec and tolerance: checked through vcnc_gym.validation at construction, within the
documented ceilings, so that no reset fails later in a run."""

from __future__ import annotations

import time

import gymnasium as gym
import pytest

import vcnc_gym  # noqa: F401
from vcnc_gym.gcode.random_contour import MAX_MOVES, RandomContourSpec

ID = "VCNC-RandomContour-v1"


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("moves_min", 2.5, "moves_min must be an integer"),
        ("moves_max", True, "moves_max must be an integer"),
        ("line_min", "5", "line_min must be a real number"),
        ("feed_max", None, "feed_max must be a real number"),
        ("radius_min", 0.0, "radius_min must be > 0"),
        ("line_probability", "0.5", "line_probability"),
        ("line_min", 40.0, "line_min must be at most line_max"),
        ("turn_max", 180.0, "U-turn"),
        ("turn_min", 20.2, None),
        ("line_probability", 1.5, r"line_probability must be in \[0, 1\]"),
    ],
)
def test_a_bad_spec_field_is_refused_naming_it(field, value, message):
    kwargs = {field: value}
    if field == "turn_min":  # 20.2..20.8 holds no whole degree
        kwargs["turn_max"], message = 20.8, "no whole degree"
    with pytest.raises(ValueError, match=message):
        RandomContourSpec(**kwargs)


@pytest.mark.parametrize("spec", [{"moves_max": 10**9}, {"moves_max": MAX_MOVES}, {"line_max": 1e6, "line_min": 1}])
def test_a_spec_beyond_the_ceilings_is_refused_at_once(spec):
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="moves_max"):
        gym.make(ID, spec=spec)
    assert time.perf_counter() - t0 < 1.0


def test_a_tolerance_whose_blends_cannot_fit_the_spec_s_lines_is_refused_at_construction():
    with pytest.raises(ValueError, match="tolerance = 1 mm is too large"):
        gym.make(ID, tolerance=1.0)
    for bad in (True, "0.01", -0.01):
        with pytest.raises(ValueError, match="tolerance"):
            gym.make(ID, tolerance=bad)


@pytest.mark.slow  # 12 resets, ~10 s
def test_every_reset_succeeds_at_the_largest_tolerance_accepted():
    from vcnc_gym.envs.random_contour_env import check_blends_fit
    from vcnc_gym.gcode import path_limits

    spec = RandomContourSpec()
    a, j = path_limits("vcnc_feed_drive")
    tolerance = 0.16  # just below the refusal (2 l_s at 20 degrees = line_min = 5 mm near 0.15 mm)
    while True:
        try:
            check_blends_fit(spec, tolerance, a, j)
            break
        except ValueError:
            tolerance *= 0.95
    env = gym.make(ID, tolerance=tolerance)
    for seed in range(12):  # the flattest corners on the shortest lines: each reset builds its blends
        env.reset(seed=seed)


@pytest.mark.parametrize("name, value", [("acceleration", "1000"), ("jerk", True), ("acceleration", -1.0)])
def test_the_path_limits_go_through_validation(name, value):
    with pytest.raises(ValueError, match=name):
        gym.make(ID, **{name: value})
