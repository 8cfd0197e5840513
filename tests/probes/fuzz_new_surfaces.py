"""Fuzz the new surfaces with a check that can fail: G-code programs, shop-floor settings, override actions,
random-contour specs.

Run: ``python tests/probes/fuzz_new_surfaces.py [--n 200] [--seed 0]``.  Every input must give either a clear
error (a ValueError naming what it refuses: a GCodeError with its line for a program, the setting's name for a
shop-floor setting, ``spec`` for a spec) or a result that holds (a toolpath with a finite contour; observations
finite and inside the space).  Anything else (another exception, an error that names nothing, a non-finite
value) is counted as a failure, printed, and makes the exit status 1.  ``--kill-resume`` adds a SIGKILL and
resume of each trainer (``tests/probes/kill_and_resume.py``: no row lost or duplicated, the rows reach the end).
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings

import numpy as np


def _mutate(text: str, rng) -> str:
    """A random program made unusual as CAM systems, old controls or typos make them."""
    lines = text.splitlines()
    for _ in range(int(rng.integers(0, 4))):
        k = int(rng.integers(0, len(lines)))
        kind = int(rng.integers(0, 8))
        if kind == 0:
            lines[k] = "/" + lines[k]
        elif kind == 1:
            lines[k] = lines[k] + " (note\fform feed)"
        elif kind == 2:
            lines[k] = lines[k] + " (Fr\u00e4ser)"
        elif kind == 3:
            lines[k] = lines[k].replace("X", "X9" + "9" * int(rng.integers(1, 400)), 1)
        elif kind == 4:
            lines[k] = lines[k] + " R" + str(10.0 ** float(rng.uniform(-3, 12)))
        elif kind == 5:
            lines.insert(k, lines[k])  # a move to its own end
        elif kind == 6:
            lines[k] = lines[k][: int(rng.integers(0, max(1, len(lines[k]))))]
        else:
            lines[k] = "N10 /" + lines[k]
    return "\n".join(lines) + "\n"


def fuzz_programs(n: int, rng, failures: list) -> dict:
    from vcnc_gym.gcode import GCodeError, read_program
    from vcnc_gym.gcode.random_contour import RandomContourSpec, random_program

    counts = {"read": 0, "clear error": 0}
    for i in range(n):
        text = _mutate(random_program(rng, RandomContourSpec()), rng)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                path = read_program(text, float(rng.choice([0.001, 0.01, 0.1])))
            pts = (
                path.curve.evaluate(np.linspace(*path.curve.u_range, 50))
                if hasattr(path.curve, "evaluate")
                else path.curve.control_points
            )
            if not np.all(np.isfinite(pts)):
                failures.append(("program", i, "non-finite contour"))
            counts["read"] += 1
        except GCodeError as exc:
            counts["clear error"] += 1
            if exc.line is None and "path" not in str(exc) and "program" not in str(exc):
                failures.append(("program", i, f"GCodeError naming no line: {exc}"))
        except Exception as exc:  # noqa: BLE001 - anything else is the failure this counts
            failures.append(("program", i, f"{type(exc).__name__}: {exc}"))
    return counts


def fuzz_shop_floor(n: int, rng, failures: list) -> dict:
    from vcnc_gym.plants.shop_floor import EFFECT_NAMES, shop_floor

    values = [
        True,
        False,
        None,
        "abc",
        "1",
        1.5,
        2,
        -1.0,
        0.0,
        float("nan"),
        float("inf"),
        1e-4,
        (1, 2),
        (1.0,),
        [3, 4, 5],
        1j,
        100.0,
    ]
    counts = {"built": 0, "clear error": 0}
    for i in range(n):
        name = EFFECT_NAMES[int(rng.integers(0, len(EFFECT_NAMES)))]
        value = values[int(rng.integers(0, len(values)))]
        try:
            shop_floor("vcnc_feed_drive", {name: value})
            counts["built"] += 1
            if isinstance(value, (bool, str)) or value is None:
                failures.append(("shop floor", i, f"{name}={value!r} accepted"))
        except ValueError as exc:
            counts["clear error"] += 1
            if name not in str(exc):
                failures.append(("shop floor", i, f"{name}={value!r}: the message does not name it: {exc}"))
        except Exception as exc:  # noqa: BLE001
            failures.append(("shop floor", i, f"{name}={value!r}: {type(exc).__name__}: {exc}"))
    return counts


def fuzz_override(episodes: int, rng, failures: list) -> dict:
    import gymnasium as gym

    import vcnc_gym  # noqa: F401

    env = gym.make("VCNC-OmegaOverride-v1")
    steps = 0
    for e in range(episodes):
        obs, _ = env.reset(seed=int(rng.integers(0, 2**31)))
        done = False
        while not done:
            action = rng.uniform(-1.5, 1.5, size=3).astype(np.float32)  # beyond the box too: clipped
            obs, reward, terminated, truncated, info = env.step(action)
            steps += 1
            done = terminated or truncated
            if not (np.all(np.isfinite(obs)) and math.isfinite(reward) and env.observation_space.contains(obs)):
                failures.append(("override", e, f"step {steps}: non-finite or out of space"))
                break
    env.close()
    return {"episodes": episodes, "steps": steps}


def fuzz_specs(n: int, rng, failures: list) -> dict:
    from vcnc_gym.gcode.random_contour import RandomContourSpec

    fields = list(RandomContourSpec.__dataclass_fields__)
    values = [True, "5", None, 2.5, 0, -1, 10**9, 1e6, float("nan"), 3, 10.0, 179.0, 0.5]
    counts = {"built": 0, "clear error": 0}
    for i in range(n):
        spec = {f: values[int(rng.integers(0, len(values)))] for f in rng.choice(fields, size=2, replace=False)}
        try:
            s = RandomContourSpec(**spec)
            counts["built"] += 1
            if s.moves_max * max(s.line_max, 2 * s.radius_max) > 900.0:
                failures.append(("spec", i, f"{spec}: beyond MAX_EXTENT accepted"))
        except ValueError as exc:
            counts["clear error"] += 1
            if "spec" not in str(exc):
                failures.append(("spec", i, f"{spec}: message names no spec field: {exc}"))
        except Exception as exc:  # noqa: BLE001
            failures.append(("spec", i, f"{spec}: {type(exc).__name__}: {exc}"))
    return counts


def fuzz_kill_resume(failures: list) -> dict:
    import tempfile
    from pathlib import Path

    from kill_and_resume import kill_and_resume

    out = {}
    for trainer in ("lean", "sb3"):
        with tempfile.TemporaryDirectory() as tmp:
            r = kill_and_resume(Path(tmp), trainer=trainer)
        a = r["audit"]
        ok = (
            r["pre_checkpoint_rows_unchanged"]
            and a["evaluations"]["increasing"]
            and not a["evaluations"]["duplicates"]
            and all(
                m["chain_breaks"] == 0 and m["duplicates"] == 0 and not m["tail_lost"] for m in a["monitor"].values()
            )
        )
        rows = sum(m["rows"] for m in a["monitor"].values())
        out[trainer] = (
            f"resumed from {r['resumed_from']}: {rows} monitor rows, {a['evaluations']['rows']} evaluations, "
            f"{'ok' if ok else 'LOST OR DUPLICATED ROWS'}"
        )
        if not ok:
            failures.append(("kill/resume", trainer, str(a)))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=200, help="inputs per surface (default 200)")
    p.add_argument("--episodes", type=int, default=2, help="override episodes (default 2)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--kill-resume", action="store_true", help="also kill and resume a run of each trainer")
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    failures: list = []
    for name, run in (
        ("G-code programs", lambda: fuzz_programs(args.n, rng, failures)),
        ("shop-floor settings", lambda: fuzz_shop_floor(args.n, rng, failures)),
        ("random-contour specs", lambda: fuzz_specs(args.n, rng, failures)),
        ("override actions", lambda: fuzz_override(args.episodes, rng, failures)),
    ):
        print(f"{name}: {run()}", flush=True)
    if args.kill_resume:
        print(f"kill and resume: {fuzz_kill_resume(failures)}", flush=True)
    for f in failures[:30]:
        print("FAIL", *f)
    print(f"failures: {len(failures)}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
