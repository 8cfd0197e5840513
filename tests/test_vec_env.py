"""agents' VcncVecEnv: the residual mode with the baseline compiled into the step, the same as calling its predict.

The compiled path (``ContouringVectorEnv.step_controlled``: a decision of N envs in one numba call) must give,
to the bit, what the per-period Python path gives (the baseline's batched ``predict`` every control period), and
that what N single envs wrapped in ``ResidualAction`` give: observations, rewards, episode ends and infos, over
episodes that end (by divergence: large random corrections, a 50 um bound) and restart, with randomised plants.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import vcnc_baselines
from vcnc_agents.action_modes import ActionMode, ResidualAction
from vcnc_agents.vec_env import VcncVecEnv
from vcnc_gym.envs import controller_contract

ENV_ID = "VCNC-Omega-v1"
N = 3
SEED = 7
KEYS = ("contour_error", "contour_error_max", "position", "command", "time", "diverged")


def _mode(baseline, correction):
    return ActionMode(mode="residual", baseline=baseline, correction=correction, action_repeat=10)


def _actions(decisions):
    """Random corrections held for 15 decisions (so that some drive the table off the contour), some beyond
    [-1, 1]."""
    held = np.random.default_rng(0).uniform(-1.5, 1.5, (decisions // 15 + 1, N, 2))
    return np.repeat(held, 15, axis=0)[:decisions].astype(np.float32)


def _run_vec(compiled, actions, baseline, correction, env_kwargs):
    venv = VcncVecEnv(ENV_ID, N, _mode(baseline, correction), env_kwargs, seed=SEED, compiled=compiled)
    assert (venv.controller is not None) == compiled
    rows = [(venv.reset(), None, None, None)]
    for a in actions:
        venv.step_async(a)
        obs, rewards, dones, infos = venv.step_wait()
        rows.append(
            (
                obs,
                rewards,
                dones,
                [{k: np.asarray(inf[k]) for k in KEYS + ("terminal_observation",) if k in inf} for inf in infos],
            )
        )
    return rows


def _run_single(actions, baseline, correction, env_kwargs):
    """N single envs in ResidualAction, reset as SB3 does (at once, the generator continuing)."""
    envs = [
        ResidualAction(
            gym.make(ENV_ID, action_repeat=1, **env_kwargs), baseline=baseline, correction=correction, action_repeat=10
        )
        for _ in range(N)
    ]
    obs = np.stack([e.reset(seed=SEED + i)[0] for i, e in enumerate(envs)])
    rows = [(obs, None, None, None)]
    for a in actions:
        out = [e.step(a[i]) for i, e in enumerate(envs)]
        dones = np.array([o[2] or o[3] for o in out])
        infos = [{k: np.asarray(o[4][k]) for k in KEYS} for o in out]
        obs = np.stack([o[0] for o in out])
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = obs[i].copy()
            obs[i] = envs[i].reset()[0]
        rows.append((obs, np.array([o[1] for o in out], dtype=np.float32), dones, infos))
    return rows


def _assert_same(a, b):
    for k, (x, y) in enumerate(zip(a, b)):
        np.testing.assert_array_equal(x[0], y[0], err_msg=f"observations of decision {k}")
        if k:
            np.testing.assert_array_equal(x[1], y[1], err_msg=f"rewards of decision {k}")
            np.testing.assert_array_equal(x[2], y[2], err_msg=f"dones of decision {k}")
            for i, (p, q) in enumerate(zip(x[3], y[3])):
                assert p.keys() == q.keys(), f"info keys of env {i}, decision {k}"
                for key in p:
                    np.testing.assert_array_equal(p[key], q[key], err_msg=f"info[{key!r}] of env {i}, decision {k}")


@pytest.mark.parametrize(
    "baseline, randomize", [("smc", False), ("smc", True), ("qft", True), ("ff-ccc", True), ("ff-pid-online", True)]
)
def test_compiled_baseline_gives_the_python_path_and_single_envs_to_the_bit(baseline, randomize):
    actions = _actions(120)
    kwargs = {"divergence_bound": 0.05, "randomize": randomize}  # 50 um: corrections of 2 u_max end episodes
    compiled = _run_vec(True, actions, baseline, 2.0, kwargs)
    assert sum(int(r[2].sum()) for r in compiled[1:]) >= 2, "no episode ended: the test would not cover resets"
    _assert_same(compiled, _run_vec(False, actions, baseline, 2.0, kwargs))
    _assert_same(compiled, _run_single(actions, baseline, 2.0, kwargs))


@pytest.mark.parametrize("name", ["smc", "qft", "ff-ccc", "zpetc", "ff-pid-online"])
def test_compiled_law_is_the_numpy_law_to_the_bit(name):
    """predict runs the compiled law on float32 observations and the NumPy statement of it (``_command``) on
    float64 ones: the same commands and memory, on random observations (1e-3 to 1e2) and a random memory."""
    env = gym.make(ENV_ID)
    layout = env.unwrapped.layout
    policy = vcnc_baselines.make(name, env)
    rng = np.random.default_rng(1)
    n = 500
    obs = rng.normal(size=(n, layout.size)) * rng.choice([1e-3, 1.0, 100.0], size=(n, layout.size))
    obs = obs.astype(np.float32)
    controller = policy.compiled(n)
    memory = rng.uniform(-0.3, 0.3, policy.controller_state.shape)
    policy.controller_state[:] = memory  # the compiled form's memory is the policy's
    out = np.zeros((n, 2))
    controller_contract.commands(controller, obs, layout.offsets(), out)
    compiled_memory = policy.controller_state.copy()
    assert not np.array_equal(compiled_memory, memory)
    policy.controller_state[:] = memory
    numpy_action, _ = policy.predict(obs.astype(np.float64))
    np.testing.assert_array_equal(out.astype(np.float32), numpy_action)
    np.testing.assert_array_equal(compiled_memory, policy.controller_state)
    policy.controller_state[:] = memory
    action, _ = policy.predict(obs)
    np.testing.assert_array_equal(action, numpy_action)


def test_step_controlled_refuses_bad_arguments():
    venv = gym.make_vec(
        ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode=AutoresetMode.DISABLED
    )
    controller = vcnc_baselines.make("smc", venv).compiled(2)
    with pytest.raises(RuntimeError, match="before reset"):
        venv.unwrapped.step_controlled(controller, np.zeros((2, 2)), 0.2, 10)
    venv.reset(seed=0)
    for args, message in [
        ((np.zeros((3, 2)), 0.2, 10), "shape"),
        ((np.full((2, 2), np.nan), 0.2, 10), "finite"),
        ((np.zeros((2, 2)), 0.0, 10), "correction"),
        ((np.zeros((2, 2)), 0.2, 0), "repeat"),
    ]:
        with pytest.raises(ValueError, match=message):
            venv.unwrapped.step_controlled(controller, *args)
    for wrong, message in [
        (None, "compiled controller"),
        ((np.zeros((2, 2)),), "compiled controller"),
        (vcnc_baselines.make("smc", venv).compiled(3), "must have 2 rows"),
    ]:
        with pytest.raises(ValueError, match=message):
            venv.unwrapped.step_controlled(wrong, np.zeros((2, 2)), 0.2, 10)
    other = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point")
    other.reset(seed=0)
    with pytest.raises(ValueError, match="AutoresetMode.DISABLED"):
        other.unwrapped.step_controlled(controller, np.zeros((2, 2)), 0.2, 10)
