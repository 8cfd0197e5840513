"""Time to refuse the largest inputs of the new surfaces (issue 35): each must be refused within 1 s, before the
work starts.

Run: ``python tests/probes/refusal_times.py [--bomb-gb 4]``.  Prints one line per case: what was given, the time
to the error, and the error's first words; exit status 1 if a case is not refused or takes 1 s or more.  The
8 GiB program file is sparse (no disk space used); the model.zip bomb is a real deflated member of
``--bomb-gb`` GB of zeros (about 4 MB on disk per GB; writing it takes a while, reading it must not).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import zipfile
from pathlib import Path


def _timed(label: str, call) -> bool:
    t0 = time.perf_counter()
    try:
        call()
    except (ValueError, FileNotFoundError) as exc:
        dt = time.perf_counter() - t0
        print(f"{label:<58} refused in {dt * 1e3:8.1f} ms: {str(exc)[:90]}")
        return dt < 1.0
    print(f"{label:<58} NOT refused ({time.perf_counter() - t0:.1f} s)")
    return False


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bomb-gb", type=float, default=4.0, help="size the model.zip's data member inflates to, GB")
    args = p.parse_args(argv)
    import gymnasium as gym

    import vcnc_gym  # noqa: F401
    from vcnc_agents.model_file import read_model_data
    from vcnc_gym.gcode import read_program_text

    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        big = tmp / "huge.nc"
        with open(big, "wb") as f:
            f.truncate(8 * 1024**3)
        ok &= _timed("VCNC-GCode-v1 program= an 8 GiB file", lambda: gym.make("VCNC-GCode-v1", program=str(big)))
        text = "G01 X1 F600\n" + "G01 X2\nG01 X1\n" * 50_000
        ok &= _timed("a 1e5-line program text (0.7 MB)", lambda: read_program_text(text))
        text = "G01 X1 F600\n" + "G01 X2\nG01 X1\n" * 500_000
        ok &= _timed("a 1e6-line program text", lambda: read_program_text(text))
        ok &= _timed("a 10 MB line", lambda: read_program_text("G01 X" + "1" * 10_000_000 + "\n"))
        ok &= _timed(
            "VCNC-RandomContour-v1 spec moves_max=10**9",
            lambda: gym.make("VCNC-RandomContour-v1", spec={"moves_max": 10**9}),
        )
        ok &= _timed("VCNC-OmegaOverride-v1 time_limit=1e9", lambda: gym.make("VCNC-OmegaOverride-v1", time_limit=1e9))
        bomb = tmp / "model.zip"
        t0 = time.perf_counter()
        with zipfile.ZipFile(bomb, "w", compression=zipfile.ZIP_DEFLATED) as z:
            info = zipfile.ZipInfo("data")
            info.compress_type = zipfile.ZIP_DEFLATED
            with z.open(info, "w", force_zip64=True) as f:
                chunk = b"\0" * (1 << 24)
                for _ in range(int(args.bomb_gb * 1e9) // len(chunk)):
                    f.write(chunk)
            z.writestr("policy.pth", b"")
        print(
            f"(model.zip bomb: {bomb.stat().st_size / 1e6:.1f} MB on disk, data member "
            f"{zipfile.ZipFile(bomb).getinfo('data').file_size / 1e9:.2f} GB, written in "
            f"{time.perf_counter() - t0:.0f} s)"
        )
        ok &= _timed(f"a model.zip whose data inflates to {args.bomb_gb:g} GB", lambda: read_model_data(bomb))
    print("OK: every case refused within 1 s" if ok else "FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
