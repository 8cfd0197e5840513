"""Closed-loop runs of Jahanpour et al.'s baselines on the registered contouring envs.

Every baseline must trace the "heart" and the "omega" (Jahanpour et al. (2014), section 3a)
without ``info["diverged"]``, on the nominal plant and on corners of the
uncertainty box, and must run under SB3's ``evaluate_policy``.

The contour-error bounds below are regression bounds, about twice what the
controllers reach today, not the paper's Table 4.  The heart is feasible for
the +-5 V drives (its reference needs at most ~3.4 V); the omega at 100 mm/s
is not: its corners ask for ~5e4 mm/s^2, about 15 times what 5 V gives, so
there only completion is checked, and the paper-level comparison is made at
20 mm/s, where the reference is within the drives' reach.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import vcnc_baselines

vcnc_gym = pytest.importorskip("vcnc_gym")
if "VCNC-Heart-v1" not in gym.envs.registry:  # pragma: no cover
    pytest.skip("vcnc_gym does not register VCNC-Heart-v1", allow_module_level=True)

from vcnc_gym.plants import vcnc_feed_drive as plant  # noqa: E402
from vcnc_gym.plants import get_plant  # noqa: E402

VERTICES = plant.uncertainty_vertices()
#: vertex 0: every parameter at its lower bound (slowest, least damped x/y gains);
#: vertex 63: every parameter at its upper bound.
PLANTS = {"nominal": None, "vertex0": VERTICES[0], "vertex63": VERTICES[63]}

#: Regression bounds on the max contour error, um (measured values in the docstrings of the tests).
HEART_BOUND_UM = {"qft": 400.0, "smc": 45.0, "fuzzy": 100.0}
OMEGA_SLOW_BOUND_UM = {"qft": 300.0, "smc": 30.0, "fuzzy": 90.0}


def rollout(name, env_id, parameters=None, **env_kwargs):
    """One episode; returns (max contour error in um, diverged, terminated, steps)."""
    kwargs = dict(env_kwargs)
    if parameters is not None:
        kwargs["parameters"] = parameters
    env = gym.make(env_id, **kwargs)
    policy = vcnc_baselines.make(name, env)
    obs, _ = env.reset(seed=0)
    start, worst, steps = True, 0.0, 0
    while True:
        action, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        worst = max(worst, info["contour_error"])
        assert not info["diverged"], f"{name} diverged on {env_id} after {steps} steps"
        if terminated or truncated:
            break
    env.close()
    return 1e3 * worst, bool(info["diverged"]), bool(terminated), steps


@pytest.mark.parametrize("plant_name", list(PLANTS))
@pytest.mark.parametrize("name", ["qft", "smc", "fuzzy"])
def test_heart_completes(name, plant_name, record_property):
    """Measured (um, nominal / vertex 0 / vertex 63): qft 203/203/203, smc 10/21/13, fuzzy 31/46/22."""
    err_um, diverged, terminated, _ = rollout(name, "VCNC-Heart-v1", PLANTS[plant_name])
    record_property("max_contour_error_um", err_um)
    print(f"heart {name} {plant_name}: max contour error {err_um:.1f} um")
    assert terminated and not diverged
    assert err_um < HEART_BOUND_UM[name]


@pytest.mark.parametrize("plant_name", list(PLANTS))
@pytest.mark.parametrize("name", ["qft", "smc", "fuzzy"])
def test_omega_completes(name, plant_name, record_property):
    """At 100 mm/s the omega's corners saturate every controller; it must still finish."""
    err_um, diverged, terminated, _ = rollout(name, "VCNC-Omega-v1", PLANTS[plant_name])
    record_property("max_contour_error_um", err_um)
    print(f"omega {name} {plant_name}: max contour error {err_um:.1f} um")
    assert terminated and not diverged


@pytest.mark.parametrize("name", ["qft", "smc", "fuzzy"])
def test_omega_at_a_feasible_feedrate(name, record_property):
    """Measured at 20 mm/s (um): qft 132, smc 11, fuzzy 26."""
    env_id = "VCNC-Omega-v1"
    steps = gym.make(env_id, feedrate=20.0).unwrapped.task.time_limit_steps
    err_um, diverged, terminated, _ = rollout(name, env_id, feedrate=20.0, max_episode_steps=steps)
    record_property("max_contour_error_um", err_um)
    print(f"omega 20 mm/s {name}: max contour error {err_um:.1f} um")
    assert terminated and not diverged
    assert err_um < OMEGA_SLOW_BOUND_UM[name]


@pytest.mark.parametrize("name", ["qft", "smc"])
def test_evaluate_policy_runs_and_resets_memory(name):
    """SB3's evaluate_policy, two episodes in a row on one env: equal returns need the memory reset."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    vec = make_vec_env("VCNC-Omega-v1", n_envs=1, seed=0)
    policy = vcnc_baselines.make(name, vec)
    rewards, lengths = evaluate_policy(policy, vec, n_eval_episodes=2, deterministic=True, return_episode_rewards=True)
    assert len(rewards) == 2 and lengths[0] == lengths[1]
    assert np.isfinite(rewards).all()
    assert rewards[0] == pytest.approx(rewards[1], rel=1e-12)
    # the same return as a hand-written rollout on a fresh env
    env = gym.make("VCNC-Omega-v1")
    pol = vcnc_baselines.make(name, env)
    obs, _ = env.reset(seed=0)
    total, start = 0.0, True
    while True:
        a, _ = pol.predict(obs, episode_start=start)
        start = False
        obs, r, term, trunc, _ = env.step(a)
        total += r
        if term or trunc:
            break
    assert rewards[0] == pytest.approx(total, rel=1e-6)


def test_evaluate_policy_batched_envs():
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    vec = make_vec_env("VCNC-Omega-v1", n_envs=3, seed=0)
    policy = vcnc_baselines.make("fuzzy", vec)
    rewards, _ = evaluate_policy(policy, vec, n_eval_episodes=3, return_episode_rewards=True)
    assert len(rewards) == 3 and np.ptp(rewards) <= 1e-9 * abs(np.mean(rewards))


#: The controllers of Jahanpour et al.'s plant (not the non-causal oracle, a floor planned offline:
#: tests/test_feedforward.py; not mpcc, which sets its own progress on a feed-override id: tests/test_mpcc.py).
JAHANPOUR_BASELINES = [
    n
    for n in vcnc_baselines.names()
    if vcnc_baselines.registry.policy_class(n).designed_for(get_plant("vcnc_feed_drive"))
    and getattr(vcnc_baselines.registry.policy_class(n), "causal", True)
    and not getattr(vcnc_baselines.registry.policy_class(n), "sets_feed_override", False)
]


def _omega_case(name):
    """A QP per env and period (mpc) and an identification of 64 machines (@machine) are slow; lq-preview at the
    nominal machine's commissioned bandwidth diverges on 8 vertices of the S-curve omega (a reference no drive of
    the box can follow), found when the commissioning replaced the hand table, and mpc on the same 8: an open
    defect, kept visible."""
    if name in ("mpc", "mpc@commissioned"):  # lq-preview's 8 vertices: its model and preview (found at 82c5693)
        return pytest.param(
            name,
            marks=[
                pytest.mark.slow,
                pytest.mark.xfail(strict=True, reason="diverges on the 8 vertices lq-preview diverges on (open)"),
            ],
        )
    if name == "pd-ref" or name.endswith("@machine"):  # pd-ref: the score's reference, tested elsewhere
        return pytest.param(name, marks=pytest.mark.slow)
    if name in ("lq-preview", "lq-preview@commissioned"):  # on either model (the identified one: slow to design)
        xfail = pytest.mark.xfail(
            strict=True, reason="diverges on 8 vertices of the S-curve omega at the commissioned bandwidth (open)"
        )
        return pytest.param(name, marks=[xfail] + ([pytest.mark.slow] if "@" in name else []))
    return name


@pytest.mark.parametrize("name", [_omega_case(n) for n in JAHANPOUR_BASELINES])
def test_omega_completes_on_every_vertex_of_the_uncertainty_box(name):
    """All 64 corners of Jahanpour et al.'s box, as one batch of the vector env, the policy's predict on the batch
    (the heart is run on vertices 0 and 63 above)."""
    from vcnc_bench.robust import make_batch, run_plants

    env = gym.make("VCNC-Omega-v1")
    runs = run_plants(
        vcnc_baselines.make(name, env),
        make_batch("VCNC-Omega-v1", len(VERTICES)),
        np.array(VERTICES),
        decision_period=env.unwrapped.decision_period,
    )
    assert not runs.diverged.any(), f"{name} diverged on vertices {np.flatnonzero(runs.diverged).tolist()}"
    assert np.all(runs.steps <= env.unwrapped.task.time_limit_steps)
