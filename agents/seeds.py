"""``vcnc-train --seeds K``: the same training run with K seeds, one run folder each.

A verdict on a learned controller rests on several training seeds (Henderson et al. (2018); Agarwal et al.
(2021)): ``vcnc-train --env ID --seeds 5 [--seed S] [options]`` runs seeds ``S, S+1, ..., S+K-1`` (``S`` default
0) with every other option unchanged.  Each seed is one ``vcnc-train`` process with ``--seed s`` and its own run
folder: ``OUTPUT/seed<s>`` with ``--output OUTPUT``, else ``runs/<ID>_seed<s>`` as a single run's.  They run on
``--jobs`` local processes at a time (default: every core but what other processes keep busy, at least 1;
each trains on one torch thread unless ``--threads`` says otherwise), or, with ``--ray-address ADDR``, as Ray tasks on that cluster (one CPU each;
the run folders must be on a file system the nodes share).  A seed's output goes to ``<run folder>.log``; its
last line is printed when it ends, and a summary table of every seed's best evaluation at the end
(``seeds.json`` beside the folders).  The bench evaluates the K agents (``vcnc-bench --policy ppo:FOLDER``).
A later command with the same options and ``--output`` and other seeds (``--seed 3 --seeds 2``: seeds 3 and 4)
adds its runs to that ``seeds.json``: a long family trains over several sessions.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from vcnc_gym import schema
from vcnc_gym.validation import integer, size

from .run_config import SEED_MAX, check_seed

__all__ = ["SeedRun", "MAX_SEEDS", "seed_folders", "seed_argv", "run_seeds", "read_summary"]

#: Most seeds of one ``--seeds`` command (ours): each is a whole training run (minutes to hours) with its own run
#: folder and log; a verdict rests on 5 to 20 (Agarwal et al. (2021)), a family is grown over several commands.
MAX_SEEDS = 1000

#: Options of the parent command that each seed's command sets itself (value-taking).
_OWN = ("--seeds", "--seed", "--output", "--jobs", "--ray-address")


@dataclass
class SeedRun:
    """One seed's run: its seed, folder, exit code, wall time (s) and best evaluation (um; None without one)."""

    seed: int
    folder: str
    code: int
    wall_s: float
    best_max_um: float | None = None
    best_rms_um: float | None = None


def seed_folders(env_id: str, seeds: list[int], output: Path | None) -> list[Path]:
    """The run folder of each seed: ``output/seed<s>``, or ``runs/<env_id>_seed<s>``."""
    return [output / f"seed{s}" if output is not None else Path("runs") / f"{env_id}_seed{s}" for s in seeds]


def _options(argv: list[str]) -> list[str]:
    """``argv`` without :data:`_OWN` (and their values) and ``--no-progress``: the options every seed shares."""
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        name = a.split("=", 1)[0]
        if name in _OWN:
            skip = "=" not in a
            continue
        if a != "--no-progress":
            out.append(a)
    return out


def seed_argv(argv: list[str], seed: int, folder: Path) -> list[str]:
    """``argv`` (the parent's options) without :data:`_OWN`, plus ``--seed``, ``--output`` and ``--no-progress``."""
    return _options(argv) + ["--seed", str(seed), "--output", str(folder), "--no-progress"]


def _check_run(name: str, r) -> dict:
    """One seed's row of ``seeds.json`` (a :class:`SeedRun`) checked; ValueError naming the field."""
    schema.mapping(name, r, ("seed", "folder", "code"), known=[f.name for f in fields(SeedRun)])
    integer(f"{name}.seed", r["seed"], 0, SEED_MAX)
    folder = schema.text(f"{name}.folder", r["folder"])
    if Path(folder).name in ("", ".", ".."):
        raise ValueError(f"{name}.folder must name a run folder, got {folder!r}")
    integer(f"{name}.code", r["code"], -(2**31), 2**31 - 1)
    schema.number(f"{name}.wall_s", r.get("wall_s", 0.0), "s", minimum=0.0)
    for k in ("best_max_um", "best_rms_um"):
        schema.maybe(schema.number, f"{name}.{k}", r.get(k), "um", minimum=0.0)
    return r


def read_summary(summary) -> dict:
    """The ``seeds.json`` ``summary`` written by :func:`run_seeds` (``{"env", "argv", "runs"}``), every field checked
    as :func:`run_seeds` writes it (the seeds distinct); a :class:`vcnc_gym.schema.BadFile` naming the file and the
    field otherwise."""
    with schema.checked(summary):
        data = schema.mapping("the file", schema.read_json(summary, "a vcnc-train --seeds summary"), ("runs",))
        schema.text("env", data.get("env", "?"))
        for i, a in enumerate(schema.sequence("argv", data.get("argv", []))):
            schema.text(f"argv[{i}]", a, empty=True)
        runs = [_check_run(f"runs[{i}]", r) for i, r in enumerate(schema.sequence("runs", data["runs"], minimum=1))]
        seeds = [r["seed"] for r in runs]
        if len(set(seeds)) != len(seeds):
            raise ValueError(f"runs holds seed {next(s for s in seeds if seeds.count(s) > 1)} twice")
    return data


def _earlier(summary: Path, env_id: str, argv: list[str], seeds: list[int]) -> list[dict]:
    """The runs an earlier ``--seeds`` command of the same env and options recorded in ``summary`` (other seeds
    than ``seeds``), which the new summary keeps; ValueError, before anything trains, where that command differed."""
    if not summary.is_file():
        return []
    try:
        data = read_summary(summary)
    except schema.BadFile as exc:
        raise ValueError(f"{exc}: not a seeds.json; choose another --output") from None
    runs = [dict(r) for r in data["runs"]]
    if data.get("env") != env_id or _options(data.get("argv") or []) != _options(argv):
        raise ValueError(
            f"{summary} holds the seeds of another run (env {data.get('env')!r}, options "
            f"{' '.join(_options(data.get('argv') or []))!r}); choose another --output"
        )
    return [r for r in runs if r.get("seed") not in seeds]


def _idle_cores() -> int:
    cores = os.cpu_count() or 1
    try:
        busy = os.getloadavg()[0]
    except OSError:
        busy = 0.0
    return max(1, min(cores, round(cores - busy)))


def _run_one(argv: list[str], folder: str) -> tuple[int, float, str]:
    """One seed's ``vcnc-train`` in a fresh process (one torch thread); (exit code, wall s, its last line)."""
    t0 = time.perf_counter()
    log = Path(f"{folder}.log")
    log.parent.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    with log.open("w") as f:
        threads = [] if any(a.split("=", 1)[0] == "--threads" for a in argv) else ["--threads", "1"]
        code = subprocess.run(
            [sys.executable, "-m", "vcnc_agents.cli", *argv, *threads], stdout=f, stderr=subprocess.STDOUT, env=env
        ).returncode
    lines = [ln for ln in log.read_text().splitlines() if ln.strip()]
    return code, time.perf_counter() - t0, lines[-1] if lines else ""


def _best(folder: Path) -> tuple[float | None, float | None]:
    """The best evaluation's max and RMS contour error (um) recorded in a run folder's summary, if any."""
    try:
        best = json.loads((folder / "summary.json").read_text()).get("best") or {}
    except (OSError, ValueError):
        return None, None
    return best.get("max_um"), best.get("rms_um")


def _local(tasks: list[tuple[list[str], str]], jobs: int, report) -> list[tuple[int, float, str]]:
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(jobs) as pool:
        futures = [pool.submit(_run_one, argv, folder) for argv, folder in tasks]
        results = []
        for (_, folder), f in zip(tasks, futures):
            results.append(f.result())
            report(folder, results[-1])
    return results


def _ray(tasks: list[tuple[list[str], str]], address: str, report) -> list[tuple[int, float, str]]:
    try:
        import ray
    except ImportError:
        raise ImportError(
            "vcnc-train --seeds --ray-address runs on Ray, an optional extra that is not installed: "
            "pip install 'vcnc-gym[sweep]'"
        ) from None
    ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(num_cpus=1)(_run_one)
    refs = [remote.remote(argv, folder) for argv, folder in tasks]
    results = []
    for (_, folder), ref in zip(tasks, refs):
        results.append(ray.get(ref))
        report(folder, results[-1])
    return results


def run_seeds(
    argv: list[str],
    env_id: str,
    first: int,
    count: int,
    output: Path | None,
    *,
    jobs: int | None = None,
    ray_address: str | None = None,
) -> list[SeedRun]:
    """Train seeds ``first .. first + count - 1`` with the options ``argv`` (see the module docstring); the runs,
    in seed order, written to ``seeds.json`` in the folders' parent.  ValueError for a bad seed range or a run
    folder that exists."""
    size(
        "--seeds",
        count,
        ceiling=MAX_SEEDS,
        why="each seed is a whole training run, minutes to hours, with a run folder of its own; a verdict rests on "
        "5 to 20 (Agarwal et al. (2021))",
    )
    seeds = [check_seed(s) for s in (first, first + count - 1)]
    seeds = list(range(seeds[0], seeds[1] + 1))
    folders = seed_folders(env_id, seeds, output)
    taken = [str(f) for f in folders if f.exists()]
    if taken:
        raise ValueError(f"run folder(s) already exist: {', '.join(taken)}; choose another --output or --seed")
    summary = folders[0].parent / "seeds.json"
    earlier = _earlier(summary, env_id, argv, seeds) if output is not None else []
    tasks = [(seed_argv(argv, s, f), str(f)) for s, f in zip(seeds, folders)]
    jobs = jobs or _idle_cores()
    where = f"the Ray cluster at {ray_address}" if ray_address else f"{min(jobs, count)} local process(es)"
    print(
        f"vcnc-train: {count} seeds ({seeds[0]}..{seeds[-1]}) of {env_id} on {where}; each seed's output in "
        f"its folder's .log",
        flush=True,
    )

    def report(folder, result):
        code, wall, last = result
        print(f"  {folder}: {'done' if code == 0 else f'exit {code}'} in {wall:.0f} s: {last}", flush=True)

    results = _ray(tasks, ray_address, report) if ray_address else _local(tasks, jobs, report)
    runs = [SeedRun(s, str(f), code, wall, *_best(f)) for s, f, (code, wall, _) in zip(seeds, folders, results)]
    rows = sorted(earlier + [asdict(r) for r in runs], key=lambda r: r["seed"])
    summary.write_text(json.dumps({"env": env_id, "argv": argv, "runs": rows}, indent=1) + "\n")
    _print_table([SeedRun(**r) for r in rows], summary)
    return runs


def _print_table(runs: list[SeedRun], summary: Path) -> None:
    print("seed  exit  wall_s  best max um  best RMS um  folder")
    for r in runs:
        cells = [f"{v:11.4g}" if v is not None else f"{'-':>11}" for v in (r.best_max_um, r.best_rms_um)]
        print(f"{r.seed:4d}  {r.code:4d}  {r.wall_s:6.0f}  {cells[0]}  {cells[1]}  {r.folder}")
    print(f"summary: {summary} (the agents' verdicts: vcnc-bench --env ID --policy ppo:FOLDER --plants N)")
