"""The shop floor's observations held to the bit against a recording (tests/data/shop_floor_episodes.npz).

The recording was made with the closed shop-floor kernel of before issue 34 item 5 (the effects as composable
terms); the composed kernel must give the same observations, rewards and infos, bit for bit (``np.array_equal``,
which counts 0.0 and -0.0 equal): ``VCNC-HeartShop-v1`` (nominal and randomised), ``VCNC-CircleShop-v1``, and
Jahanpour et al.'s drive on the heart with each effect alone.  Regenerate (only when a change of behaviour is
meant, with the env ids' versions bumped): ``python tests/test_shop_floor_fixture.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

FIXTURE = Path(__file__).resolve().parent / "data" / "shop_floor_episodes.npz"
STEPS = 200

#: Every effect off (written out here, not taken from the module under test).
_OFF = {
    "encoder_resolution": 0.0,
    "noise_std": 0.0,
    "command_delay": 0.0,
    "sensor_delay": 0.0,
    "mode_frequency": 0.0,
    "cutting_force": 0.0,
    "cutting_ripple": 0.0,
    "stribeck_force": 0.0,
}

#: name: (env id or None for ContouringEnv on the heart, keyword arguments)
CASES = {
    "heart_shop": ("VCNC-HeartShop-v1", {}),
    "heart_shop_randomised": ("VCNC-HeartShop-v1", {"randomize": True}),
    "circle_shop": ("VCNC-CircleShop-v1", {}),
    "encoder": (None, {"shop_floor": {**_OFF, "encoder_resolution": 1e-4}}),
    "noise": (None, {"shop_floor": {**_OFF, "noise_std": 5e-5}}),
    "command_delay": (None, {"shop_floor": {**_OFF, "command_delay": 2}}),
    "sensor_delay": (None, {"shop_floor": {**_OFF, "sensor_delay": 2}}),
    "mode": (None, {"shop_floor": {**_OFF, "mode_frequency": 150.0, "mode_damping": 0.05}}),
    "cutting": (None, {"shop_floor": {**_OFF, "cutting_force": 100.0, "cutting_ripple": 50.0}}),
    "stribeck": (None, {"shop_floor": {**_OFF, "stribeck_force": 30.0}}),
}
INFO_KEYS = ("contour_error", "position", "measured_position")


def record(name: str) -> dict[str, np.ndarray]:
    """``STEPS`` steps of case ``name`` under seed 0 and a fixed sequence of nonzero actions (an episode that ends
    is reset with the next seed): observations, rewards, flags and the infos' ``INFO_KEYS``."""
    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)
    from vcnc_gym.envs.contouring_env import ContouringEnv

    env_id, kwargs = CASES[name]
    env = gym.make(env_id, **kwargs).unwrapped if env_id else ContouringEnv(contour="heart", **kwargs)
    actions = np.random.default_rng(12).uniform(-0.4, 0.9, (STEPS, 2)).astype(np.float32)
    seed = 0
    obs, _ = env.reset(seed=seed)
    out = {"obs": [obs], "reward": [], "flags": [], **{key: [] for key in INFO_KEYS}}
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out["obs"].append(obs)
        out["reward"].append(reward)
        out["flags"].append((terminated, truncated))
        for key in INFO_KEYS:
            out[key].append(np.asarray(info[key], dtype=np.float64))
        if terminated or truncated:
            seed += 1
            obs, _ = env.reset(seed=seed)
            out["obs"].append(obs)
    return {key: np.array(value) for key, value in out.items()}


@pytest.fixture(scope="module")
def recorded():
    with np.load(FIXTURE) as data:
        return {key: data[key] for key in data.files}


@pytest.mark.parametrize("name", list(CASES))
def test_the_shop_floor_gives_the_recorded_episode_to_the_bit(name, recorded):
    now = record(name)
    for key, value in now.items():
        expected = recorded[f"{name}/{key}"]
        assert value.shape == expected.shape, (name, key)
        assert np.array_equal(value, expected), (name, key, np.max(np.abs(value - expected)))
    # the case shows its effect: not the plain plant's episode (every case but those on the nominal heart)
    assert now["obs"].std() > 0.0


def test_each_effect_alone_changes_the_episode(recorded):
    """The fixture is not blind: each effect alone gives observations other than every other case's."""
    alone = [name for name, (env_id, _) in CASES.items() if env_id is None]
    for i, a in enumerate(alone):
        for b in alone[i + 1 :]:
            x, y = recorded[f"{a}/obs"], recorded[f"{b}/obs"]
            assert x.shape != y.shape or not np.array_equal(x, y), (a, b)


if __name__ == "__main__":
    FIXTURE.parent.mkdir(exist_ok=True)
    arrays = {f"{name}/{key}": value for name in CASES for key, value in record(name).items()}
    np.savez_compressed(FIXTURE, **arrays)
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size} bytes, {len(arrays)} arrays)")
