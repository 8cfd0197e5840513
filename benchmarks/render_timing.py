"""What rendering a contouring env costs: a frame's wall time, and a whole episode recorded by Gymnasium's RecordVideo.

Run: ``python benchmarks/render_timing.py`` (``--env ID``, default ``VCNC-Heart-v2``; ``--frames N`` frames timed;
``--no-video`` to skip the recording; ``--out DIR`` for the video, default a temporary folder).

1. A frame: the env runs the drive's servo alone (the zero action) and draws a new picture (``render()`` with
   ``render_every=1``) every ``episode_steps / N`` decisions, so the pictures hold from a few to every decision's
   point of the path; it prints the first picture (the figure made and its background drawn) and the median and
   largest of the others, ms.
2. A video: ``gymnasium.wrappers.RecordVideo`` over ``gym.make(ID, render_mode="rgb_array")`` (the default
   ``render_every``) records one whole episode of the zero action; it prints the episode's wall time with the
   frames, the encoding's (moviepy, ffmpeg), the total, and the video's length as ffmpeg reads it from the file.

The wall times are of this host, with its load (printed: ``os.getloadavg``).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import gymnasium as gym

import vcnc_gym  # noqa: F401  (registers the ids)


def frame_times(env_id: str, frames: int) -> dict:
    """Wall times of ``frames`` pictures along one episode of the zero action, ms."""
    env = gym.make(env_id, render_mode="rgb_array", render_every=1)
    u = env.unwrapped
    env.reset(seed=0)
    every = max(1, u.episode_steps // frames)
    times, shape, n, done = [], None, 0, False
    while not done:
        _, _, term, trunc, _ = env.step(np.zeros(2, dtype=np.float32))
        n, done = n + 1, term or trunc
        if n % every == 0 or done:
            t0 = time.perf_counter()
            frame = env.render()
            times.append(1e3 * (time.perf_counter() - t0))
            shape = frame.shape
    env.close()
    rest = times[1:]
    return {
        "frames": len(times),
        "shape": shape,
        "first_ms": times[0],
        "median_ms": statistics.median(rest),
        "max_ms": max(rest),
        "decisions": n,
    }


def video_length_s(path: Path) -> float:
    """The video's duration as ffmpeg reads it from the file, s."""
    import imageio_ffmpeg

    out = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-i", str(path)], capture_output=True, text=True).stderr
    h, m, s = re.search(r"Duration: (\d+):(\d+):([\d.]+)", out).groups()
    return 3600 * int(h) + 60 * int(m) + float(s)


def record_video(env_id: str, folder: Path) -> dict:
    """One whole episode of the zero action recorded by RecordVideo: the wall times and the video's length."""
    from gymnasium.wrappers import RecordVideo

    t0 = time.perf_counter()
    env = RecordVideo(gym.make(env_id, render_mode="rgb_array"), str(folder), episode_trigger=lambda e: e == 0)
    u = env.unwrapped
    env.reset(seed=0)
    n, done = 0, False
    while not done:
        _, _, term, trunc, _ = env.step(np.zeros(2, dtype=np.float32))
        n, done = n + 1, term or trunc
    t1 = time.perf_counter()
    env.close()  # writes the video
    t2 = time.perf_counter()
    path = next(folder.glob("*.mp4"))
    return {
        "decisions": n,
        "render_every": u.render_every,
        "render_fps": u.metadata["render_fps"],
        "episode_s": t1 - t0,
        "encode_s": t2 - t1,
        "total_s": t2 - t0,
        "video_s": video_length_s(path),
        "simulated_s": n * u.decision_period,
        "path": path,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="VCNC-Heart-v2", help="env id (default VCNC-Heart-v2)")
    p.add_argument("--frames", type=int, default=40, help="frames timed along the episode (default 40)")
    p.add_argument("--no-video", action="store_true", help="time the frames only")
    p.add_argument("--out", type=Path, help="folder of the video (default: a temporary one)")
    args = p.parse_args(argv)
    print(f"# {args.env}; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    f = frame_times(args.env, args.frames)
    print(
        f"frame {f['shape']}: first {f['first_ms']:.0f} ms (figure and background), then median "
        f"{f['median_ms']:.1f} ms, max {f['max_ms']:.1f} ms over {f['frames'] - 1} frames "
        f"({f['decisions']} decisions)"
    )
    if args.no_video:
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        v = record_video(args.env, folder)
        print(
            f"RecordVideo of a whole episode ({v['decisions']} decisions, {v['simulated_s']:.3f} s simulated; "
            f"render_every {v['render_every']}, render_fps {v['render_fps']}): episode with frames "
            f"{v['episode_s']:.1f} s, encoding {v['encode_s']:.1f} s, total {v['total_s']:.1f} s wall; video "
            f"{v['video_s']:.2f} s long ({v['path'].name}, {v['path'].stat().st_size / 1e3:.0f} kB)"
        )
    print(f"# load average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
