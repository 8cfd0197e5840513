"""Arguments and inputs of the envs: what is accepted as something else gets a clear error instead.

Each case of the reliability review (issue 9, "Unit slips and arguments
accepted as something else", "Episodes cut short without a word") that the
env layer owns is one test here.
"""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym
from vcnc_gym.geometry import NurbsCurve

OMEGA = "VCNC-Omega-v1"


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"randomize": "no"}, "randomize must be True or False"),
        ({"randomize": 1}, "randomize must be True or False"),
        ({"preview_steps": (2.7,)}, "preview_steps"),
        ({"preview_steps": 10}, "preview_steps"),
        ({"preview_steps": (True,)}, "preview_steps"),  # () is no preview field (the ablations)
        ({"preview_steps": (0, 5)}, "preview_steps"),
        ({"dt": 0.1}, r"dt=0.1 s is outside"),
        ({"dt": 1e-9}, r"outside"),
        ({"dt": "1e-4"}, "dt must be a real number"),
        ({"dt": 1e-4 + 0j}, "dt must be a real number"),
        ({"action_repeat": 10**9}, "longer than the whole episode"),
        ({"action_repeat": 0}, "action_repeat must be an integer >= 1"),
        ({"action_repeat": 2.0}, "action_repeat must be an integer"),
        ({"action_repeat": True}, "action_repeat must be an integer"),
        ({"reward_scale": float("nan")}, "reward_scale must be finite"),
        ({"divergence_bound": -1.0}, "divergence_bound must be > 0"),
        ({"plant": "nope"}, "unknown plant 'nope'"),
        ({"plant_options": {"substeps": 3}}, r"unknown option\(s\) \['substeps'\]"),
        ({"plant_options": {"substep": 0.0}}, "substep must be > 0"),
        ({"max_episode_steps": 0}, "max_episode_steps must be an integer >= 1"),
        ({"contour": "circle-ish"}, "contour must be one of"),
    ],
)
def test_bad_arguments_raise_naming_the_argument(kwargs, message):
    with pytest.raises(ValueError, match=message):
        vcnc_gym.ContouringEnv(**{"contour": "omega", **kwargs})


def test_parameters_and_randomize_together_are_refused():
    p = gym.make(OMEGA).unwrapped.plant.nominal()
    with pytest.raises(ValueError, match="not both"):
        gym.make(OMEGA, parameters=p, randomize=True)


def test_an_infinite_input_limit_is_refused():
    plant = gym.make(OMEGA).unwrapped.plant
    p = plant.nominal()
    p[:, plant.index("u_max")] = np.inf
    with pytest.raises(ValueError, match="finite"):
        gym.make(OMEGA, parameters=p)
    env = gym.make(OMEGA)
    with pytest.raises(ValueError, match="finite"):
        env.reset(options={"parameters": p})


@pytest.mark.parametrize(
    "action, message",
    [
        (np.array([0.1, 0.2, 0.3]), "shape"),
        (np.array([[0.1, 0.2]]), "shape"),
        (np.array([np.nan, 0.0]), "finite"),
        (np.array([np.inf, 0.0]), "finite"),
        (np.array([0.1 + 1j, 0.0]), "real"),
        (np.array(["0.1", "0.2"]), "real"),
        (["a", "b"], "real"),
        (np.array([True, False]), "real"),
    ],
)
def test_bad_actions_raise(action, message):
    env = gym.make(OMEGA)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.unwrapped.step(action)


def test_a_misspelt_reset_option_raises():
    env = gym.make(OMEGA)
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['paramters'\]"):
        env.reset(options={"paramters": None})


def test_a_large_divergence_bound_costs_no_memory():
    t0 = time.perf_counter()
    env = gym.make(OMEGA, divergence_bound=1e4, tracking_bound=1e4)
    env.reset(seed=0)
    env.step(np.zeros(2))
    assert time.perf_counter() - t0 < 30.0
    assert env.unwrapped.projector.arrays[-2].size < 2_000_000  # cell_start: the grid's cell count


def test_far_contours_are_observed_without_clipping():
    """A contour at x = 1500 mm: the position bound follows the contour instead of clipping at 1000 mm."""
    curve = NurbsCurve(
        np.array([[1500.0, 0.0], [1510.0, 5.0], [1520.0, 0.0]]), np.ones(3), np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]), 2
    )
    env = vcnc_gym.ContouringEnv(contour=curve, feedrate=20.0, ramp_time=0.05)
    obs, _ = env.reset(seed=0)
    assert env.layout.reference_position(obs)[0] == pytest.approx(1500.0)
    assert env.observation_space.contains(obs)
    _, _, _, _, info = env.step(np.zeros(2))
    assert info["observation_clipped"] == 0


def test_the_natural_length_follows_the_configuration_and_is_never_cut_silently():
    """feedrate=10 through gym.make: the episode runs to the end of the contour (no fixed TimeLimit)."""
    env = gym.make("VCNC-Heart-v1", feedrate=10.0)
    u = env.unwrapped
    assert env.spec.max_episode_steps is None
    assert u.episode_steps > 34_000 * 5  # ten times slower than the default 100 mm/s
    assert u.task.max_episode_steps == u.task.time_limit_steps >= u.episode_steps


def test_a_shorter_limit_of_the_env_warns():
    with pytest.warns(UserWarning, match="truncated before the end of the contour"):
        env = vcnc_gym.ContouringEnv(contour="omega", max_episode_steps=100)
        env.reset(seed=0)


def test_an_episode_cut_by_a_time_limit_is_reported_incomplete():
    """gym.make(max_episode_steps=...) adds Gymnasium's TimeLimit, which the env cannot see: the one
    evaluation loop reports the episode as not reaching the end of the contour."""
    from vcnc_gym.evaluation import run_episode

    class Zero:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.zeros(2, dtype=np.float32), state

    res = run_episode(Zero(), gym.make(OMEGA, max_episode_steps=50))
    assert res.truncated and not res.completed and res.episode_steps == 50


def test_profile_accepts_a_profile_object():
    """profile= takes any object with plan(length): the interpolator reads only the plan."""
    from vcnc_gym.motion import ConstantFeedrate

    own = gym.make("VCNC-Heart-v1", profile=ConstantFeedrate(80.0)).unwrapped.reference
    named = gym.make("VCNC-Heart-v1", profile="constant", feedrate=80.0).unwrapped.reference
    np.testing.assert_array_equal(own.position, named.position)
    with pytest.raises(ValueError, match="profile must be one of"):
        gym.make("VCNC-Heart-v1", profile=3)
    with pytest.raises(ValueError, match="ramp_time"):
        gym.make("VCNC-Heart-v1", profile=ConstantFeedrate(80.0), ramp_time=0.1)
