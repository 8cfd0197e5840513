"""The agent's feed override dial at a limited rate (``dial_rate``, :class:`vcnc_agents.action_modes.DialSlew`).

Checked against the ramp computed here by hand, and between the two places an agent acts: the training wrapper
(:class:`ResidualAction`) and the bench's policy (:class:`vcnc_agents.policy.AgentPolicy`) send the env the same
commands to the bit.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym  # noqa: F401
from vcnc_agents.action_modes import ActionMode, DialSlew, ResidualAction
from vcnc_agents.config import action_mode_of, with_action_mode

OMEGA = "VCNC-OmegaTolerance-v2"
RATE = 3.0  # 1/s


class Recorder(gym.Wrapper):
    """Keeps every command the env is given."""

    def __init__(self, env):
        super().__init__(env)
        self.commands = []

    def step(self, action):
        self.commands.append(np.array(action, dtype=np.float32))
        return self.env.step(action)


def test_the_dial_ramps_at_its_rate_and_starts_each_episode_at_0():
    dt = 1e-3
    slew = DialSlew(RATE, dt, 2)
    target = np.array([[0.5, -0.5, 1.0], [0.0, 0.0, -0.2]], dtype=np.float32)
    dials = np.array([slew(target)[:, 2] for _ in range(400)])
    k = np.arange(1, 401)
    # by hand: a ramp of RATE per second toward each target, held there
    np.testing.assert_allclose(dials[:, 0], np.minimum(1.0, RATE * dt * k), atol=1e-5)
    np.testing.assert_allclose(dials[:, 1], np.maximum(-0.2, -RATE * dt * k), atol=1e-5)
    assert dials[-1, 0] == np.float32(1.0) and dials[-1, 1] == np.float32(-0.2)
    np.testing.assert_array_equal(slew(target)[:, :2], target[:, :2])  # the axes' corrections pass
    slew.restart(np.array([True, False]))
    assert slew.dial[0] == 0.0 and slew.dial[1] == np.float32(-0.2)
    single = DialSlew(RATE, dt, 1)
    assert single(np.array([0.0, 0.0, 7.0]))[2] == np.float32(RATE * dt)  # clipped to the dial's 1 first


def test_the_wrapper_turns_the_dial_at_its_rate():
    env = Recorder(gym.make(OMEGA, action_repeat=1))
    wrapped = ResidualAction(env, baseline="ff-pid-online", correction=0.1, action_repeat=20, dial_rate=RATE)
    wrapped.reset(seed=0)
    for _ in range(5):
        wrapped.step(np.array([0.0, 0.0, 1.0]))
    dial = np.array([c[2] for c in env.commands])
    dt = env.unwrapped.dt
    np.testing.assert_allclose(dial, np.minimum(1.0, RATE * dt * np.arange(1, 101)), atol=1e-5)
    wrapped.reset(seed=0)
    env.commands.clear()
    wrapped.step(np.array([0.0, 0.0, -1.0]))
    assert env.commands[0][2] == np.float32(-RATE * dt)  # from 0 again
    wrapped.close()


def test_the_bench_s_policy_turns_the_dial_the_wrapper_turned():
    from stable_baselines3 import PPO

    from vcnc_agents.lean_ppo import _spaces_only
    from vcnc_agents.policy import AgentPolicy

    mode = ActionMode("residual", 20, "ff-pid-online", 0.1, dial_rate=RATE)
    plain = Recorder(gym.make(OMEGA, action_repeat=1))
    model = PPO(
        "MlpPolicy",
        _spaces_only(plain.observation_space, plain.action_space, 1),
        n_steps=8,
        batch_size=8,
        seed=0,
        policy_kwargs={"log_std_init": 0.0},
    )
    with np.errstate(all="ignore"):
        for p in model.policy.action_net.parameters():  # a dial that swings: the rate binds
            p.data.mul_(50.0)
    policy = AgentPolicy(model, None, mode, plain)
    obs, _ = plain.reset(seed=1)
    policy.plan(plain)
    for k in range(200):
        action, _ = policy.predict(obs, episode_start=np.array([k == 0]))
        obs, *_ = plain.step(action)

    trained = Recorder(gym.make(OMEGA, action_repeat=1))
    wrapped = mode.wrap(trained)
    obs, _ = wrapped.reset(seed=1)
    for _ in range(10):
        obs, *_ = wrapped.step(policy._actor(obs[None])[0])
    np.testing.assert_array_equal(np.array(trained.commands), np.array(plain.commands))
    dial = np.array(plain.commands)[:, 2]
    assert np.abs(np.diff(dial)).max() <= RATE * plain.unwrapped.dt * (1 + 1e-5)
    assert np.ptp(dial) > 0.05  # the dial moved, 0.3e-3 a period at most
    plain.close()
    wrapped.close()


def test_a_bad_or_misplaced_dial_rate_is_refused_by_name():
    with pytest.raises(ValueError, match="dial_rate must be a number >= 0"):
        ActionMode("residual", 20, "ff-pid-online", 0.1, dial_rate=-1.0)
    with pytest.raises(ValueError, match="dial_rate apply to the residual mode only"):
        ActionMode("direct", 20, dial_rate=3.0)
    with pytest.raises(ValueError, match="dial_rate limits a feed override dial"):
        ResidualAction(gym.make("VCNC-Heart-v1", action_repeat=1), baseline="ff-pid", dial_rate=3.0)
    from vcnc_agents.vec_env import native_batch

    with pytest.raises(ValueError, match="dial_rate limits a feed override dial"):
        native_batch("VCNC-Heart-v1", 2, ActionMode("residual", 10, "ff-pid", 0.2, dial_rate=3.0))


def test_dial_rate_round_trips_through_a_config_entry_and_the_command_line():
    from pathlib import Path

    from vcnc_agents.arguments import action_mode, parser

    mode = ActionMode("residual", 20, "ff-pid-online", 0.1, dial_rate=RATE)
    assert mode.to_dict()["dial_rate"] == RATE
    assert "dial_rate" not in ActionMode("residual", 20, "ff-pid", 0.1).to_dict()
    assert ActionMode(**mode.to_dict()) == mode
    assert action_mode_of(with_action_mode({"n_envs": 4}, mode)) == mode
    root = Path(__file__).resolve().parents[1]
    config = root / "experiments" / "tolerance" / "recipes" / "tolerance_violation30.yml"
    args = parser().parse_args(["--env", "VCNC-OmegaToleranceShop-v2", "--config", str(config), "--dial-rate", "3"])
    assert action_mode(args, config) == ActionMode("residual", 20, "ff-pid-online@machine", 0.1, dial_rate=3.0)
    args = parser().parse_args(["--env", "VCNC-Heart-v1", "--action-mode", "direct", "--dial-rate", "3"])
    with pytest.raises(ValueError, match="--dial-rate apply to --action-mode residual"):
        action_mode(args, root / "agents" / "hyperparams" / "ppo.yml")
