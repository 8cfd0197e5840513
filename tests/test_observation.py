"""Every observation field holds what its name says, for every env id, whatever the field order."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym
from vcnc_gym.envs import layout as layout_module

IDS = list(vcnc_gym.envs.CONTOURING_IDS)


def _check_fields(env, n_steps=400):
    """Step a PD loop and compare each field with info, the reference and the plant."""
    u = env.unwrapped
    lay = u.layout
    ref = u.task.reference_arrays.samples
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    prev_pos = None
    prev_measured = None
    shop = getattr(u.plant, "inner", None) is not None  # on the shop floor (vcnc_gym.plants.shop_floor)
    sensor_error = 0.5e-3  # Purtojo et al.'s 1 um encoder; a shop-floor sensor's half count plus 6 sigma of noise
    if shop:
        p = u.plant.nominal()[0]
        sensor_error = 0.5 * p[u.plant.index("encoder_resolution")] + 6.0 * p[u.plant.index("noise_std")]
    for t in range(n_steps):
        e = lay.tracking_error(obs)
        a = np.clip((300 * e + (lay.reference_velocity(obs) - lay.velocity(obs))) / 5.0, -1, 1)
        a = a + 0.05 * rng.standard_normal(2)
        obs, _, term, trunc, info = env.step(a)
        k = min(int(round(info["time"] / u.dt)), ref.shape[0] - 1)
        f32 = lambda x: np.asarray(x, dtype=np.float32)  # noqa: E731
        np.testing.assert_array_equal(lay.reference_position(obs), f32(ref[k, 0:2]))
        np.testing.assert_array_equal(lay.reference_position(obs), f32(info["reference_position"]))
        np.testing.assert_array_equal(lay.reference_velocity(obs), f32(ref[k, 2:4]))
        np.testing.assert_array_equal(lay.reference_acceleration(obs), f32(ref[k, 4:6]))
        # the observation sees the sensor (quantised on Purtojo et al.'s table); info's tracking error is the truth
        measured_error = info["reference_position"] - info["measured_position"]
        np.testing.assert_array_equal(lay.tracking_error(obs), f32(measured_error))
        assert np.all(np.abs(info["measured_position"] - info["position"]) <= sensor_error + 1e-12)
        np.testing.assert_array_equal(lay.contour_error(obs)[0], np.float32(info["contour_error"]))
        tangent = ref[k, 6:8]
        ex, ey = measured_error
        np.testing.assert_allclose(lay.get(obs, "tangential_error")[0], tangent @ [ex, ey], atol=1e-7)
        np.testing.assert_allclose(lay.get(obs, "normal_error")[0], -tangent[1] * ex + tangent[0] * ey, atol=1e-7)
        np.testing.assert_array_equal(lay.previous_action(obs), f32(np.clip(a, -1, 1)))
        for j, s in enumerate(lay.preview_steps):
            kp = min(k + s, ref.shape[0] - 1)
            np.testing.assert_allclose(lay.preview(obs)[j], ref[kp, 0:2] - info["measured_position"], atol=1e-5)
        if shop and prev_measured is not None:  # a shop-floor sensor: the readings' difference (no sensor delay)
            np.testing.assert_allclose(
                lay.velocity(obs), (info["measured_position"] - prev_measured) / u.dt, rtol=1e-6, atol=1e-3
            )
        prev_measured = info["measured_position"].copy()
        # the velocity field is the table's: it matches the position's finite difference on average
        if prev_pos is not None and t > 50 and not shop:
            fd = (info["position"] - prev_pos) / u.decision_period
            assert np.all(np.abs(lay.velocity(obs) - fd) <= 0.05 * np.abs(fd) + 2.0)
        prev_pos = info["position"].copy()
        assert info["observation_clipped"] == 0
        if term or trunc:
            break


@pytest.mark.parametrize("env_id", IDS)
def test_every_field_matches_info_and_reference(env_id):
    _check_fields(gym.make(env_id))


def test_a_reordered_layout_still_names_the_right_fields(monkeypatch):
    """The kernel writes by name: reversing the field order moves the fields, not their meaning."""
    reversed_names = tuple(reversed(layout_module.FIELD_NAMES))
    monkeypatch.setattr(layout_module, "FIELD_NAMES", reversed_names)
    env = gym.make("VCNC-Omega-v1")
    lay = env.unwrapped.layout
    assert [f.name for f in lay.fields] == list(reversed_names)
    assert lay.offset("previous_action") == 0
    _check_fields(env, n_steps=200)


def test_clipping_is_counted_in_info():
    env = gym.make("VCNC-Omega-v1", tracking_bound=50.0, divergence_bound=50.0)
    env.reset(seed=0)
    clipped = 0
    for _ in range(3000):  # full command one way: the tracking error leaves its 10 mm bound
        _, _, term, trunc, info = env.step(np.array([1.0, 1.0]))
        clipped = max(clipped, info["observation_clipped"])
        if term or trunc:
            break
    assert clipped > 0


@pytest.mark.parametrize("steps, ahead", [((), ()), ((50,), (1.0, 4.0)), ((100, 10), ())])
def test_a_smaller_preview_is_picked_out_of_the_full_observation(steps, ahead):
    """An env with a smaller preview (an ablation's agent: ``preview_steps=()`` and ``contour_ahead=()`` remove
    the fields) observes exactly the entries ``vcnc_agents.signature.observation_pick`` picks out of the full env's
    observation, step for step under the same commands; the env itself is the independent computation."""
    from vcnc_agents.signature import env_signature, observation_pick

    full = gym.make("VCNC-OmegaLookahead-v1")
    small = gym.make("VCNC-OmegaLookahead-v1", preview_steps=steps, contour_ahead=ahead)
    pick = observation_pick(env_signature(small), full)
    assert pick is not None and len(pick) == small.observation_space.shape[0]
    assert small.observation_space.shape[0] == 15 + 2 * len(steps) + 3 * len(ahead)
    a, _ = full.reset(seed=3)
    b, _ = small.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(40):
        np.testing.assert_array_equal(a[pick], b)
        u = rng.uniform(-0.2, 0.2, 2).astype(np.float32)
        a = full.step(u)[0]
        b = small.step(u)[0]
    assert observation_pick(env_signature(full), full) is None


def test_a_preview_the_env_does_not_give_is_refused_by_name():
    from vcnc_agents.signature import env_signature, observation_pick

    more = gym.make("VCNC-OmegaLookahead-v1", preview_steps=(10, 20))
    with pytest.raises(ValueError, match="preview step 20"):
        observation_pick(env_signature(more), gym.make("VCNC-OmegaLookahead-v1"))
    with pytest.raises(ValueError, match="contouring-fb.*preview_steps is empty"):
        from vcnc_bench.policies import resolve_policy

        resolve_policy("contouring-fb", gym.make("VCNC-Corners-v1", preview_steps=()))
