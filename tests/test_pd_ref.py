"""pd-ref, the normalised score's reference PD: its poles from the plant's own transfer function (python-control),
and a completed, stable episode on every contouring id's nominal plant (one cheap id here, the rest slow)."""

from __future__ import annotations

import control
import gymnasium as gym
import numpy as np
import pytest

import vcnc_baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_baselines.feedback.pd_ref import FRACTION
from vcnc_gym.envs import CONTOURING_IDS
from vcnc_gym.evaluation import run_episode

CHEAP = "VCNC-OmegaLookaheadShop-v1"  # about a second: the shop floor's mode, delays and noise


def test_poles_are_the_declared_double_pole_on_the_plants_transfer_function():
    """The loop kp + kd s around the nominal linear model of each axis (python-control's, from the plant module)
    has the double pole at -FRACTION * servo_bandwidth the design places, and no feedforward in its table."""
    env = gym.make("VCNC-Heart-v1")
    policy = vcnc_baselines.make("pd-ref", env)
    u = env.unwrapped
    w = FRACTION * u.plant.servo_bandwidth
    assert policy.bandwidth == pytest.approx(w)
    for axis in range(2):
        g = u.plant.linear_model(u.nominal_parameters, axis=axis)
        k = control.tf([policy.gains.kd[0, axis], policy.gains.kp[0, axis]], [1.0])
        poles = np.sort_complex(control.poles(control.feedback(k * g, 1)))
        slowest = poles[np.argsort(-poles.real)][:2]  # the two poles nearest the imaginary axis
        assert np.allclose(slowest, -w, rtol=1e-3, atol=1e-6 * w), (axis, poles)
    assert not np.any(policy.table[..., :6]), "pd-ref has no feedforward and no loop offsets"
    assert np.all(policy.gains.ki == 0)
    assert "pd-ref" not in vcnc_baselines.optimal.search.causal_names(env)  # never one of the floor's starts


def _episode(env_id):
    env = gym.make(env_id)
    result = run_episode(vcnc_baselines.make("pd-ref", env), env, seed=0)
    assert result.completed and not result.diverged, (env_id, result.max_contour_error_um)
    assert np.isfinite(result.max_contour_error_um)
    return result


def test_completes_on_a_shop_floor_id():
    _episode(CHEAP)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", [e for e in CONTOURING_IDS if e != CHEAP])
def test_completes_on_every_contouring_id(env_id):
    env = gym.make(env_id)
    if getattr(env.unwrapped, "retimes_reference", False):
        with pytest.raises(ValueError, match="re-times its reference"):
            vcnc_baselines.make("pd-ref", env)  # a table-based law: no score on the feed override (said so)
        return
    _episode(env_id)
