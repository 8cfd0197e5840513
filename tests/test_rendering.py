"""Rendering (vcnc_gym/envs/rendering.py): a frame's shape, the frame skip, the frame rate in simulated time, env 0 of
the native vector env, and a recorded video's length.  The frame's wall time is measured by
``python benchmarks/render_timing.py``."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs.rendering import PICTURES_PER_SECOND, default_render_every, render_fps

ZERO = np.zeros(2, dtype=np.float32)


def test_a_frame_is_an_rgb_picture_of_the_episode():
    env = gym.make("VCNC-Heart-v2", render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(20):
        env.step(ZERO)
    frame = env.render()
    assert frame.shape == (360, 800, 3) and frame.dtype == np.uint8 and frame.flags.c_contiguous
    assert frame.std() > 0
    env.close()


def test_render_every_draws_a_new_picture_every_so_many_decisions():
    env = gym.make("VCNC-Omega-v2", render_mode="rgb_array", render_every=3)
    env.reset(seed=0)
    frames = [env.render()]
    for _ in range(7):
        env.step(ZERO)
        frames.append(env.render())
    new = [i for i in range(1, len(frames)) if frames[i] is not frames[i - 1]]
    assert new == [3, 6]  # decisions 0 (the reset), 3 and 6 drawn; the others return the last picture
    env.reset(seed=0)  # a new episode draws at once
    assert env.render() is not frames[-1]
    with pytest.raises(ValueError, match="render_every"):
        gym.make("VCNC-Omega-v2", render_mode="rgb_array", render_every=0)


def test_the_last_decision_of_an_episode_is_drawn():
    env = gym.make("VCNC-Circle-v2", render_mode="rgb_array", render_every=10_000)
    env.reset(seed=0)
    first = env.render()
    done = False
    while not done:
        _, _, term, trunc, _ = env.step(ZERO)
        done = term or trunc
    last = env.render()
    assert last is not first and env.render() is last  # drawn once at the end, then kept


def test_the_frame_rate_is_one_frame_per_decision_in_simulated_time():
    heart = gym.make("VCNC-Heart-v2", render_mode="rgb_array").unwrapped
    assert heart.metadata["render_fps"] == 1000 == render_fps(heart.decision_period)
    assert heart.render_every == 33 == default_render_every(heart.decision_period)
    circle = gym.make("VCNC-Circle-v2").unwrapped
    assert circle.metadata["render_fps"] == 100 and circle.render_every == round(100 / PICTURES_PER_SECOND)
    assert gym.make("VCNC-Heart-v1").unwrapped.metadata["render_fps"] == 10_000
    # a whole heart of one frame per decision at render_fps lasts its simulated time, 3.2 s
    assert 3.0 <= heart.episode_steps / heart.metadata["render_fps"] <= 10.0


def test_a_pickled_env_keeps_its_episode_and_its_frame_skip():
    env = gym.make("VCNC-Omega-v2", render_mode="rgb_array", render_every=4).unwrapped
    env.reset(seed=0)
    for _ in range(5):
        env.step(ZERO)
    back = pickle.loads(pickle.dumps(env))
    assert back.render_every == 4 and len(back._history["t"]) == 6
    np.testing.assert_array_equal(back.render(), env.render())


def test_the_native_vector_env_renders_env_0():
    venv = gym.make_vec(
        "VCNC-Omega-v2", num_envs=3, vectorization_mode="vector_entry_point", render_mode="rgb_array", render_every=2
    )
    assert venv.metadata["render_fps"] == 1000 and venv.render_mode == "rgb_array"
    venv.reset(seed=0)
    (frame,) = venv.render()
    assert frame.shape == (360, 800, 3)
    for _ in range(2):
        venv.step(np.zeros((3, 2), dtype=np.float32))
    (again,) = venv.render()
    assert again is not frame and again.std() > 0
    venv.close()
    with pytest.raises(ValueError, match="env 0"):
        gym.make_vec("VCNC-Omega-v2", num_envs=2, vectorization_mode="vector_entry_point", render_mode="human")


def test_record_video_plays_an_episode_in_simulated_time(tmp_path):
    pytest.importorskip("moviepy")
    import re
    import subprocess

    import imageio_ffmpeg
    from gymnasium.wrappers import RecordVideo

    env = RecordVideo(gym.make("VCNC-Omega-v2", render_mode="rgb_array"), str(tmp_path), episode_trigger=lambda e: True)
    env.reset(seed=0)
    n, done = 0, False
    while not done:
        _, _, term, trunc, _ = env.step(ZERO)
        n, done = n + 1, term or trunc
    env.close()
    (video,) = tmp_path.glob("*.mp4")
    out = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-i", str(video)], capture_output=True, text=True).stderr
    seconds = float(re.search(r"Duration: 00:00:([\d.]+)", out).group(1))
    assert seconds == pytest.approx((n + 1) / 1000, abs=0.02)  # one frame per decision (and the reset) at 1000 fps
