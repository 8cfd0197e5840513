"""A recurrent residual (sb3-contrib's RecurrentPPO, ``policy: MlpLstmPolicy``; issue 37): trained by SB3's trainer,
loaded without unpickling, and run by the bench's :class:`vcnc_agents.policy.AgentPolicy` with its LSTM state
carried from decision to decision exactly as sb3-contrib's own loop carries it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from sb3_contrib import RecurrentPPO

import vcnc_gym  # noqa: F401
from vcnc_agents.action_modes import ActionMode
from vcnc_agents.policy import AgentPolicy

HEART = "VCNC-Heart-v1"

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _model(env, seed=0):
    from vcnc_agents.lean_ppo import _spaces_only

    stub = _spaces_only(env.observation_space, env.action_space, 1)
    return RecurrentPPO(
        "MlpLstmPolicy",
        stub,
        n_steps=8,
        batch_size=8,
        seed=seed,
        policy_kwargs=dict(lstm_hidden_size=8, net_arch=dict(pi=[16], vf=[16])),
    )


def test_the_bench_carries_the_lstm_state_as_sb3_contrib_does():
    """Over 40 decisions of the heart, the correction AgentPolicy holds at each decision (one call per control
    period on the plain env) equals RecurrentPPO.predict's on the residual wrapper's env (one call per decision,
    its state passed back, ``episode_start`` on the first), to float32 rounding; the LSTM's memory matters (a
    policy restarted at every decision acts otherwise)."""
    mode = ActionMode("residual", 10, "ff-pid", 0.2)
    plain = gym.make(HEART)
    model = _model(plain)
    policy = AgentPolicy(model, None, mode, plain)
    assert policy.recurrent and policy._actor is None
    wrapped = mode.wrap(gym.make(HEART, action_repeat=1))
    obs_w, _ = wrapped.reset(seed=0)
    obs_p, _ = plain.reset(seed=0)
    state, start = None, np.array([True])
    forgetful = []
    for k in range(40):
        a_ref, state = model.predict(obs_w[None], state=state, episode_start=start, deterministic=True)
        forgetful.append(
            model.predict(obs_w[None], state=None, episode_start=np.array([True]), deterministic=True)[0][0]
        )
        start = np.array([False])
        for j in range(10):
            u, _ = policy.predict(obs_p, episode_start=np.array([k == 0 and j == 0]))
            if j == 0:
                np.testing.assert_allclose(policy._held[0], a_ref[0], rtol=1e-5, atol=1e-6)
            obs_p, *_ = plain.step(u)
        obs_w, *_ = wrapped.step(a_ref[0])
        np.testing.assert_allclose(obs_p, obs_w, rtol=1e-6, atol=1e-9)
    assert not np.allclose(forgetful[-1], policy._held[0], atol=1e-6)  # the state it carries changes what it does
    # a new episode starts its LSTM from zeros again
    obs_p, _ = plain.reset(seed=0)
    policy.predict(obs_p, episode_start=np.array([True]))
    first, _ = model.predict(obs_p[None], state=None, episode_start=np.array([True]), deterministic=True)
    np.testing.assert_allclose(policy._held[0], first[0], rtol=1e-5, atol=1e-6)


def test_an_unknown_policy_name_is_refused_by_name():
    from vcnc_agents.config import ppo_arguments

    with pytest.raises(ValueError, match="policy must be one of"):
        ppo_arguments({"policy": "CnnPolicy"})
    assert ppo_arguments({"policy": "MlpLstmPolicy"})[0] == "MlpLstmPolicy"


@pytest.mark.slow  # a training run and a bench run
def test_a_recurrent_agent_trains_loads_and_scores_its_evaluation_in_the_bench(tmp_path, short_run_in_the_bench):
    """``policy: MlpLstmPolicy``: vcnc-train picks SB3's trainer (the lean one runs MlpPolicy) and RecurrentPPO; the
    agent loads with nothing unpickled, and vcnc-bench scores what the run's evaluation scored."""
    import math

    from vcnc_agents import load_agent

    def change(entry):
        entry.update(
            n_envs=2,
            n_steps=16,
            batch_size=32,
            n_epochs=1,
            policy="MlpLstmPolicy",
            policy_kwargs="dict(lstm_hidden_size=16, net_arch=dict(pi=[32], vf=[32]))",
        )

    run, recorded, record = short_run_in_the_bench(tmp_path, HEART, change, 64)
    assert recorded.get("trainer") is None  # SB3's
    policy = load_agent(run / "best", gym.make(HEART))
    assert isinstance(policy.model, RecurrentPPO) and policy.recurrent
    assert math.isfinite(record["max_contour_error_um"])
    assert record["max_contour_error_um"] == pytest.approx(recorded["agent"]["evaluation"]["max_um"], rel=1e-9)
