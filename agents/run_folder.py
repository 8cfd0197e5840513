"""The run folder of ``vcnc-train``: its layout, checkpoints, logs, summary, lock and resume.

Everything of one run lives in one folder::

    RUN/
      config.yml          env id, env kwargs and signature, seed, n_envs, n_timesteps,
                          checkpoint and evaluation periods, action mode, hyperparameters
      checkpoints/        rl_model_<steps>_steps.zip + rl_model_vecnormalize_<steps>_steps.npz
      best/               model.zip, vecnormalize.npz, config.yml: best deterministic evaluation
      final/              the same three at the end of training
      evaluations.csv     steps, max / mean / RMS contour error (um) of each evaluation (inf when
                          it diverged), score, diverged
      monitor/            SB3 Monitor files of the training envs, one row per episode: return r,
                          length l (agent steps), t (s since the session's start) and
                          steps (the run's agent-step count at the episode's end)
      tb/                 TensorBoard logs (when tensorboard is installed)
      summary.json        wall time, steps per second and status of each training session

``best/`` and ``final/`` are agents: ``vcnc-bench --policy ppo:RUN/best``.
Evaluation runs the agent deterministically on the nominal plant through the
same :func:`vcnc_gym.evaluation.run_episode` as the benchmark and keeps the
model with the lowest ``sqrt(max * RMS)`` contour error, so both figures of
the benchmark count.

What the run folder guarantees
------------------------------
- Nothing is written before every option is checked (:func:`vcnc_agents.run_session.prepare_run`):
  a bad option leaves no folder behind.  A new run that fails before its
  first checkpoint removes what it created; after one, it can be resumed.
- Checkpoints are written between PPO updates, each file atomically (a
  temporary file renamed), the model last.  Every evaluation is taken on a
  checkpoint, so ``best/`` can always be rebuilt from ``checkpoints/``.
- ``--resume`` goes on from the newest *intact* checkpoint (a damaged newer
  one is renamed ``*.damaged`` with a warning), first rolling the logs back
  to it: rows of evaluations.csv and monitor/ past the checkpoint belong to
  training that was lost and are dropped, so every step of the model's history
  is logged exactly once.  Monitor files are appended to, never overwritten.
- SIGINT or SIGTERM stops at the next environment step, saves a checkpoint
  of the model as of its last update and summary.json, and says how to resume.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import yaml

from .model_file import check_model_data, check_tensor_files, read_model_data, recorded_shape
from .normalization import NormalizationStats, atomic_write_bytes
from .run_warning import note

__all__ = [
    "MODEL_FILE",
    "NORMALIZATION_FILE",
    "CONFIG_FILE",
    "CHECKPOINT_PREFIX",
    "RUN_ENTRIES",
    "EVAL_FIELDS",
    "agent_files",
    "read_agent_config",
    "evaluation_score",
    "evaluation_row",
    "checkpoint_files",
    "check_checkpoint",
    "scan_checkpoints",
    "latest_checkpoint",
    "write_yaml",
    "write_config",
    "save_model",
    "save_agent",
    "read_evaluations",
    "write_evaluations",
    "best_of",
    "roll_back",
    "read_summary",
    "record_session",
    "session_rates",
    "run_lock",
    "RunLocked",
    "check_output_folder",
    "stale_run",
    "read_run_config",
    "clear_new_run",
    "set_aside",
]

#: The files of an agent folder (a run's ``best/`` and ``final/``, a shipped agent): what
#: :func:`vcnc_agents.load_agent` reads.
MODEL_FILE = "model.zip"
NORMALIZATION_FILE = "vecnormalize.npz"
CONFIG_FILE = "config.yml"

CHECKPOINT_PREFIX = "rl_model"
CHECKPOINT_NAME = re.compile(rf"^{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
#: Entries a run folder may hold; a folder holding others is not ours to clear.
RUN_ENTRIES = {CONFIG_FILE, "checkpoints", "best", "final", "evaluations.csv", "monitor", "tb", "summary.json", ".lock"}
LOCK_FILE = ".lock"
EVAL_FIELDS = ("steps", "max_um", "mean_um", "rms_um", "score_um", "diverged")


# -- an agent folder ----------------------------------------------------------------------
_PICKLED_NORMALIZATION = "vecnormalize.pkl"


def agent_files(path) -> tuple[Path, Path, Path]:
    """(model, normalisation, config) paths of an agent folder, or of its ``model.zip``.

    Raises FileNotFoundError naming what is missing.
    """
    if path is None or str(path) == "":
        raise ValueError("the agent path is empty: give an agent folder (e.g. RUN/best) or its model.zip")
    p = Path(path)
    folder = p.parent if p.suffix == ".zip" else p
    if not folder.is_dir():
        raise FileNotFoundError(f"no agent at {str(path)!r}: not a folder or a model.zip in one")
    files = (p if p.suffix == ".zip" else folder / MODEL_FILE, folder / NORMALIZATION_FILE, folder / CONFIG_FILE)
    missing = [f.name for f in files if not f.is_file()]
    if NORMALIZATION_FILE in missing and (folder / _PICKLED_NORMALIZATION).is_file():
        raise ValueError(
            f"agent folder {str(folder)!r} holds its normalisation as {_PICKLED_NORMALIZATION} (a pickle, which runs "
            f"code when loaded) instead of {NORMALIZATION_FILE}; if you trust the folder, convert it once with "
            f"python -m vcnc_agents.normalization --convert-trusted-pickle {folder / _PICKLED_NORMALIZATION}"
        )
    if missing:
        raise FileNotFoundError(f"agent folder {str(folder)!r} lacks {', '.join(missing)}")
    return files


def read_agent_config(config_file: Path) -> dict:
    """The mapping of an agent folder's config.yml (:func:`agent_files`' third path); ValueError for a file that is
    not valid YAML or not an agent's config (a mapping whose ``action_mode``, if any, is a mapping)."""
    try:
        data = yaml.safe_load(Path(config_file).read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"{config_file} is not valid YAML: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get("action_mode", {}), dict):
        raise ValueError(f"{config_file} is not an agent's config.yml (a mapping with env_id and action_mode)")
    return data


# -- evaluations ---------------------------------------------------------------------------
def evaluation_score(max_um: float, rms_um: float) -> float:
    """Selection score of an evaluation, um: the geometric mean of max and RMS contour error
    (inf if either is not finite; a diverged episode is scored inf by the caller)."""
    return math.sqrt(max_um * rms_um) if math.isfinite(max_um) and math.isfinite(rms_um) else math.inf


def evaluation_row(steps: int, result) -> dict:
    """The evaluations.csv row of an evaluation episode (``vcnc_gym.evaluation.run_episode``'s result), as both
    trainers write it.

    A diverged episode's errors cover only the part before it left the bounds (a table that never moved has
    0.0 um there): its figures are written as inf, the bench's figure for a diverged plant, never as perfect.
    An episode cut by the completion time limit covers part of the contour only: its score is inf (no
    candidate for best/).
    """
    diverged = bool(result.diverged)
    completed = bool(result.completed)
    figures = (
        (math.inf,) * 3
        if diverged
        else (result.max_contour_error_um, result.mean_contour_error_um, result.rms_contour_error_um)
    )
    score = math.inf if diverged or not completed else evaluation_score(figures[0], figures[2])
    return {
        "steps": int(steps),
        "max_um": float(figures[0]),
        "mean_um": float(figures[1]),
        "rms_um": float(figures[2]),
        "score_um": float(score),
        "diverged": diverged,
    }


# -- checkpoints ------------------------------------------------------------------------
def checkpoint_files(folder: Path, steps: int) -> tuple[Path, Path]:
    return (
        folder / f"{CHECKPOINT_PREFIX}_{steps}_steps.zip",
        folder / f"{CHECKPOINT_PREFIX}_vecnormalize_{steps}_steps.npz",
    )


def check_checkpoint(steps: int, model_zip: Path, norm: Path, n_envs: int | None = None) -> None:
    """ValueError saying what is wrong with a checkpoint pair (nothing is unpickled)."""
    if not norm.is_file():
        raise ValueError(f"{norm.name} is missing")
    data = read_model_data(model_zip)
    check_model_data(data, model_zip.name)
    if data.get("num_timesteps") != steps:
        raise ValueError(f"{model_zip.name} records {data.get('num_timesteps')!r} steps, its name {steps}")
    if n_envs is not None and data.get("n_envs") != n_envs:
        raise ValueError(f"{model_zip.name} was trained with n_envs {data.get('n_envs')!r}, the run has {n_envs}")
    shape = recorded_shape(data, "observation_space", model_zip)
    stats = NormalizationStats.load(norm)
    if (stats.observation_size,) != shape:
        raise ValueError(f"{norm.name} normalises {stats.observation_size} entries, the model observes {shape}")


def scan_checkpoints(run_dir, n_envs: int | None = None) -> tuple[list, list]:
    """(intact, damaged) checkpoints of a run, newest first.

    ``intact``: (steps, model zip, normalisation npz); ``damaged``: (steps,
    model zip, reason) for a pair that is missing its statistics, is
    truncated, empty, garbage or inconsistent.
    """
    folder = Path(run_dir) / "checkpoints"
    found = []
    for p in folder.iterdir() if folder.is_dir() else []:
        m = CHECKPOINT_NAME.match(p.name)
        if m:
            found.append((int(m.group(1)), p))
    intact, damaged = [], []
    for steps, model_zip in sorted(found, reverse=True):
        norm = checkpoint_files(folder, steps)[1]
        try:
            check_checkpoint(steps, model_zip, norm, n_envs)
        except ValueError as exc:
            damaged.append((steps, model_zip, str(exc)))
        else:
            intact.append((steps, model_zip, norm))
    return intact, damaged


def latest_checkpoint(run_dir, n_envs: int | None = None) -> tuple[int, Path, Path] | None:
    """(steps, model zip, normalisation npz) of the newest intact checkpoint of a run, or None.

    A damaged checkpoint newer than it is skipped with a :class:`RunWarning`; so is one whose tensor files
    (``policy.pth``, ...) do not read with torch's weights-only reader (a pickled object), the newest being
    read before it is resumed from.
    """
    intact, damaged = scan_checkpoints(run_dir, n_envs)
    newest = None
    for steps, model_zip, norm in intact:
        try:
            check_tensor_files(model_zip)
        except ValueError as exc:
            damaged.append((steps, model_zip, str(exc)))
            continue
        newest = (steps, model_zip, norm)
        break
    for steps, model_zip, reason in damaged:
        if newest is None or steps > newest[0]:
            fallback = f"falling back to the one at {newest[0]} steps" if newest else "no intact checkpoint is left"
            note(f"checkpoint {model_zip} is damaged ({reason}); {fallback}")
    return newest


# -- files ---------------------------------------------------------------------------------
def write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def write_yaml(path: Path, data: dict) -> None:
    write_text(path, yaml.safe_dump(data, sort_keys=False))


def write_config(folder: Path, config, **extra) -> None:
    """Write ``folder/config.yml``: the run's configuration (:class:`vcnc_agents.run_config.RunConfig`, or any record
    whose ``to_dict()`` is config.yml's mapping), then ``extra`` (an agent folder's ``agent`` block)."""
    write_yaml(folder / CONFIG_FILE, {**config.to_dict(), **extra})


def save_model(model, path: Path) -> None:
    buffer = io.BytesIO()
    model.save(buffer)
    atomic_write_bytes(path, buffer.getvalue())


def save_agent(folder: Path, model, stats: NormalizationStats, config, steps: int, evaluation=None) -> None:
    """Write an agent folder (model, statistics, the run's ``config`` with the agent's step count) as a whole.

    The files are written into a temporary folder that then replaces ``folder``.
    """
    tmp = folder.with_name(f".{folder.name}.tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    save_model(model, tmp / MODEL_FILE)
    stats.save(tmp / NORMALIZATION_FILE)
    write_config(tmp, config, agent={"timesteps": int(steps), "evaluation": evaluation})
    replace_dir(tmp, folder)


def replace_dir(new: Path, folder: Path) -> None:
    old = folder.with_name(f".{folder.name}.old")
    if old.exists():
        shutil.rmtree(old)
    if folder.exists():
        folder.rename(old)
    new.rename(folder)
    if old.exists():
        shutil.rmtree(old)


def read_evaluations(csv_path: Path) -> list[dict]:
    """The complete rows of an evaluations.csv, typed (a torn last line is left out)."""
    if not csv_path.is_file():
        return []
    rows = []
    with open(csv_path, newline="") as f:
        for r in csv.DictReader(f):
            try:
                rows.append(
                    {
                        "steps": int(r["steps"]),
                        **{k: float(r[k]) for k in ("max_um", "mean_um", "rms_um", "score_um")},
                        "diverged": {"True": True, "False": False}[r["diverged"]],
                    }
                )
            except (KeyError, TypeError, ValueError):
                continue
    return rows


def write_evaluations(csv_path: Path, rows: list[dict]) -> None:
    buffer = io.StringIO()
    w = csv.DictWriter(buffer, fieldnames=EVAL_FIELDS)
    w.writeheader()
    w.writerows(rows)
    write_text(csv_path, buffer.getvalue())


def best_of(rows: list[dict]) -> dict | None:
    """The best finite-score row, or None."""
    rows = [r for r in rows if math.isfinite(r["score_um"]) and not r["diverged"]]
    return min(rows, key=lambda r: r["score_um"]) if rows else None


def roll_back_monitor(path: Path, steps: int) -> int:
    """Drop the episodes of a Monitor file that ended after ``steps``; the number dropped.

    A file without the ``steps`` column (an older vcnc-train) is kept as it
    is under ``<name>.before_resume`` and a new one is started.
    """
    lines = path.read_text().splitlines()
    if len(lines) < 2 or not lines[0].startswith("#"):
        path.rename(path.with_name(path.name + ".before_resume"))
        return 0
    header = next(csv.reader([lines[1]]))
    if "steps" not in header:
        path.rename(path.with_name(path.name + ".before_resume"))
        return 0
    kept, dropped = lines[:2], 0
    for row in csv.reader(lines[2:]):
        try:
            ok = len(row) == len(header) and int(float(row[header.index("steps")])) <= steps
        except ValueError:
            ok = False
        if ok:
            buffer = io.StringIO()
            csv.writer(buffer, lineterminator="").writerow(row)
            kept.append(buffer.getvalue())
        else:
            dropped += 1
    write_text(path, "\n".join(kept) + "\n")
    return dropped


def set_aside(model_zips, above: int = -1) -> list[Path]:
    """Rename the checkpoint pairs of ``model_zips`` (their model zip and statistics) past ``above`` steps to
    ``*.damaged``: kept for a look, never resumed from; the renamed files."""
    renamed = []
    for model_zip in model_zips:
        steps = int(CHECKPOINT_NAME.match(Path(model_zip).name).group(1))
        if steps > above:
            for p in checkpoint_files(Path(model_zip).parent, steps):
                if p.exists():
                    renamed.append(p.rename(p.with_name(p.name + ".damaged")))
    return renamed


def roll_back(run_dir: Path, config, steps: int, damaged: list) -> dict:
    """Bring the run's logs and best/ back to the checkpoint at ``steps`` (see the module docstring)."""
    csv_path = run_dir / "evaluations.csv"
    rows = read_evaluations(csv_path)
    kept = [r for r in rows if r["steps"] <= steps]
    if csv_path.exists():
        write_evaluations(csv_path, kept)
    episodes = sum(roll_back_monitor(p, steps) for p in sorted((run_dir / "monitor").glob("*.monitor.csv")))
    set_aside([model_zip for _, model_zip, _ in damaged], above=steps)
    rebuild_best(run_dir, config, kept, steps)
    summary = read_summary(run_dir)
    for s in summary["sessions"]:
        if s.get("status") == "running":
            s["status"] = "killed"
    summary["best"] = best_of(kept)
    write_summary(run_dir, summary)
    return {"evaluations": len(rows) - len(kept), "episodes": episodes}


def rebuild_best(run_dir: Path, config, rows: list[dict], steps: int) -> None:
    """Make best/ the checkpoint of the best of ``rows`` if it holds a model of lost training (past
    ``steps``) or not that best one, or is missing; a best/ of unknown origin (older runs) is left alone.

    Every evaluated model is a checkpoint, so best/ is copied from ``checkpoints/``.
    """
    best = best_of(rows)
    folder = run_dir / "best"
    have = None
    if (folder / CONFIG_FILE).is_file():
        try:
            have = (yaml.safe_load((folder / CONFIG_FILE).read_text()).get("agent") or {}).get("timesteps")
        except (yaml.YAMLError, AttributeError):
            have = None
        if have is None:
            return
    if folder.exists() and have is not None and have <= steps and best is not None and have == best["steps"]:
        return
    if not folder.exists() and best is None:
        return
    if best is None:
        if have is not None and have > steps:
            shutil.rmtree(folder)
        return
    model_zip, norm = checkpoint_files(run_dir / "checkpoints", best["steps"])
    try:
        check_checkpoint(best["steps"], model_zip, norm)
    except ValueError as exc:
        note(f"best/ cannot be rebuilt from the checkpoint at {best['steps']} steps ({exc}); removed")
        if folder.exists():
            shutil.rmtree(folder)
        return
    tmp = folder.with_name(".best.tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    shutil.copyfile(model_zip, tmp / MODEL_FILE)
    shutil.copyfile(norm, tmp / NORMALIZATION_FILE)
    write_config(tmp, config, agent={"timesteps": best["steps"], "evaluation": best})
    replace_dir(tmp, folder)


def read_summary(run_dir: Path) -> dict:
    path = run_dir / "summary.json"
    try:
        summary = json.loads(path.read_text()) if path.is_file() else {}
    except json.JSONDecodeError:
        summary = {}
    summary.setdefault("sessions", [])
    return summary


def record_session(run_dir: Path, session: dict, best: dict | None) -> None:
    """Write ``session`` (replacing its earlier record) and the best evaluation into summary.json."""
    summary = read_summary(run_dir)
    summary["sessions"] = [s for s in summary["sessions"] if s.get("id") != session["id"]] + [dict(session)]
    summary["best"] = best
    write_summary(run_dir, summary)


def write_summary(run_dir: Path, summary: dict) -> None:
    sessions = summary["sessions"]
    summary["timesteps"] = sessions[-1]["end_timesteps"] if sessions else 0
    summary["wall_s"] = sum(s.get("wall_s", 0.0) for s in sessions)
    write_text(run_dir / "summary.json", json.dumps(summary, indent=2) + "\n")


def session_rates(start: int, end: int, wall: float, repeat: int) -> dict:
    steps = end - start
    wall = max(wall, 1e-9)
    return {"wall_s": wall, "steps_per_s": steps / wall, "control_periods_per_s": steps * repeat / wall}


class RunLocked(ValueError):
    """Another process trains the run folder (it holds its lock): this session wrote nothing there."""


@contextmanager
def run_lock(run_dir: Path, *, probe: bool = False):
    """Hold an exclusive lock on ``run_dir/.lock`` (released by the OS even on SIGKILL).

    :class:`RunLocked` (a ValueError) if another process holds it: two sessions must never write one
    run folder.  ``probe`` only checks (the folder must exist).
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    path = run_dir / LOCK_FILE
    if probe and not path.exists():
        yield
        return
    with open(path, "a+") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            owner = f.read().strip() or "?"
            raise RunLocked(
                f"{run_dir} is being trained by another process (pid {owner}); wait for it to end or stop it first"
            ) from None
        if not probe:
            f.seek(0)
            f.truncate()
            f.write(f"{os.getpid()}\n")
            f.flush()
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def check_writable(run_dir: Path) -> None:
    """ValueError unless the run folder and its sub-folders can be written (a resumed run writes its lock,
    checkpoints and logs there): checked before anything is written."""
    folders = [run_dir] + [
        run_dir / name for name in ("checkpoints", "monitor", "best", "final") if (run_dir / name).is_dir()
    ]
    for folder in folders:
        if not os.access(folder, os.W_OK | os.X_OK):
            raise ValueError(
                f"{folder} is not writable: a resumed run writes its checkpoints and logs there "
                "(check its permissions, or copy the run folder somewhere writable)"
            )


def check_output_folder(run_dir: Path) -> None:
    """ValueError naming ``run_dir`` unless a folder can be made there: a probe folder is made and removed in
    its nearest existing ancestor (``--output /proc/run``: procfs takes no new folder)."""
    run_dir = Path(run_dir)
    ancestor = run_dir if run_dir.is_dir() else next((p for p in run_dir.absolute().parents if p.exists()), None)
    if ancestor is None or not ancestor.is_dir():
        raise ValueError(f"cannot make the run folder {run_dir}: {ancestor} is not a folder")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".vcnc-train-probe-", dir=ancestor))
    except OSError as exc:
        raise ValueError(
            f"cannot make the run folder {run_dir}: no folder can be made in {ancestor} "
            f"({exc.strerror or type(exc).__name__}); choose another --output"
        ) from None


def stale_run(run_dir: Path) -> bool:
    """True for a folder holding a run of ours that never reached an intact checkpoint (safe to start over)."""
    names = {p.name for p in run_dir.iterdir()}
    return (run_dir / CONFIG_FILE).is_file() and names <= RUN_ENTRIES and not scan_checkpoints(run_dir)[0]


def read_run_config(run_dir: Path) -> dict:
    """The mapping of a run folder's config.yml, for :meth:`vcnc_agents.run_config.RunConfig.read` to type; ValueError
    or FileNotFoundError saying why it cannot be resumed."""
    path = run_dir / CONFIG_FILE
    if not path.is_file():
        raise FileNotFoundError(f"cannot resume: {run_dir} has no {CONFIG_FILE}; is it a vcnc-train run folder?")
    try:
        config = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot resume: {path} is not valid YAML: {exc}") from None
    if not isinstance(config, dict) or not {"env_id", "n_envs", "seed", "action_mode", "hyperparams"} <= set(config):
        raise ValueError(f"cannot resume: {path} is not the config.yml of a vcnc-train run")
    return config


def clear_new_run(run_dir: Path, created: bool) -> None:
    """Remove what a new run wrote (the folder itself if it created it)."""
    if not run_dir.exists():
        return
    if created:
        shutil.rmtree(run_dir)
        return
    for p in run_dir.iterdir():
        if (p.name in RUN_ENTRIES or p.name.startswith(".")) and p.name != LOCK_FILE:
            shutil.rmtree(p) if p.is_dir() else p.unlink()
