"""What runs during training besides PPO: checkpoints, evaluations and the stop on a signal.

As SB3's ``common/callbacks.py``: :func:`make_run_callback` is the SB3 callback of a run (checkpoint and
evaluate between PPO updates, stop on SIGINT/SIGTERM); :func:`evaluation_score` ranks evaluations;
:class:`StopSignal` and :func:`stop_on_signals` turn a signal into a request to stop at the next step.
"""

from __future__ import annotations

import csv
import math
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from .action_modes import ActionMode
from .env_factory import make_eval_env
from .normalization import NormalizationStats
from .policy import AgentPolicy
from .run_folder import (EVAL_FIELDS, best_of, checkpoint_files, read_evaluations, record_session, save_agent,
                         save_model, session_rates)

__all__ = ["evaluation_score", "evaluation_row", "make_run_callback", "StopSignal", "stop_on_signals"]


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
    figures = ((math.inf,) * 3 if diverged else
               (result.max_contour_error_um, result.mean_contour_error_um, result.rms_contour_error_um))
    score = math.inf if diverged or not completed else evaluation_score(figures[0], figures[2])
    return {"steps": int(steps), "max_um": float(figures[0]), "mean_um": float(figures[1]),
            "rms_um": float(figures[2]), "score_um": float(score), "diverged": diverged}


def make_run_callback(config: dict, run_dir: Path, session: dict, stop, verbose: int):
    """The callback that checkpoints and evaluates, both between PPO updates, and stops on a signal.

    SB3 calls ``_on_rollout_start`` after each policy update, so a checkpoint
    or an evaluation there holds the model trained on every step counted in
    ``num_timesteps``; ``_on_training_end`` comes after the last update, or
    after a stop in the middle of a rollout, where the model is still the one
    of the rollout's start: that is what the stop's checkpoint saves.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class RunCallback(_RunCallbackSteps, BaseCallback):
        pass

    return RunCallback(config, run_dir, session, stop, verbose)


class _RunCallbackSteps:
    """The methods of :func:`make_run_callback`'s callback (mixed into SB3's ``BaseCallback`` there, imported
    only when a run is made)."""

    def __init__(self, config: dict, run_dir: Path, session: dict, stop, verbose: int):
        super().__init__(verbose)
        self._config, self._run_dir, self._session, self._stop = config, run_dir, session, stop
        self._checkpoint_freq = config["checkpoint_freq"]
        self._eval_freq = config["eval_freq"]  # 0: only at the end
        self.env = make_eval_env(self._config)
        self.mode = ActionMode(**self._config["action_mode"])
        self.csv = self._run_dir / "evaluations.csv"
        rows = read_evaluations(self.csv)
        self.best = best_of(rows)
        self.last_eval_row = max((r["steps"] for r in rows), default=None)
        self.stopped_early = False
        self.t0 = time.perf_counter()

    def stats(self) -> NormalizationStats:
        return NormalizationStats.from_vecnormalize(self.model.get_vec_normalize_env())

    def _on_training_start(self) -> None:
        self.last_checkpoint = self.rollout_start = self.num_timesteps
        self.last_eval = self.last_eval_row if self.last_eval_row is not None else 0
        self.rollout_stats = self.stats()

    def _on_rollout_start(self) -> None:
        n = self.rollout_start = self.num_timesteps
        self.rollout_stats = self.stats()
        # on grids of multiples of the periods (at the first update past each), whatever else was saved
        due_eval = self._eval_freq > 0 and n // self._eval_freq > self.last_eval // self._eval_freq
        if due_eval or n // self._checkpoint_freq > self.last_checkpoint // self._checkpoint_freq:
            self.checkpoint(n, self.rollout_stats)
        if due_eval:
            self.evaluate(n, self.rollout_stats)

    def _on_step(self) -> bool:
        if self._stop.signum is not None:
            self.stopped_early = True
            return False
        return True

    def _on_training_end(self) -> None:
        if self.stopped_early:  # the model is the one of the rollout's start
            self.model.num_timesteps = self.rollout_start
            self.checkpoint(self.rollout_start, self.rollout_stats)
            return
        n = self.num_timesteps
        stats = self.stats()
        self.checkpoint(n, stats)
        if n != self.last_eval:
            self.evaluate(n, stats)

    def checkpoint(self, n: int, stats: NormalizationStats) -> None:
        model_zip, norm = checkpoint_files(self._run_dir / "checkpoints", n)
        if n == self.last_checkpoint and model_zip.is_file():
            return
        model_zip.parent.mkdir(parents=True, exist_ok=True)
        stats.save(norm)
        save_model(self.model, model_zip)  # last: the zip completes the pair
        self.last_checkpoint = n
        rates = session_rates(self._session["start_timesteps"], n, time.perf_counter() - self.t0,
                              self._config["action_mode"]["action_repeat"])
        self._session.update(end_timesteps=n, **rates)
        record_session(self._run_dir, self._session, self.best)

    def evaluate(self, n: int, stats: NormalizationStats) -> None:
        from vcnc_gym.evaluation import run_episode

        self.last_eval = n
        if n == self.last_eval_row:
            return  # this checkpoint was evaluated before the run was resumed
        policy = AgentPolicy(self.model, stats, self.mode, self.env)
        r = run_episode(policy, self.env, seed=0)
        row = evaluation_row(n, r)
        score = row["score_um"]
        new = not self.csv.exists()
        with open(self.csv, "a", newline="") as f:
            w = csv.DictWriter(f, fieldnames=EVAL_FIELDS)
            if new:
                w.writeheader()
            w.writerow(row)
        self.last_eval_row = n
        for key in ("max_um", "rms_um", "score_um"):
            self.logger.record(f"eval/contour_{key}", row[key])
        if math.isfinite(score) and (self.best is None or score < self.best["score_um"]):
            self.best = row
            save_agent(self._run_dir / "best", self.model, stats, self._config, n, row)
        if self.verbose:
            best = f"{self.best['score_um']:.2f}" if self.best else "-"
            print(f"eval at {n} steps: " + ("diverged" if r.diverged else
                                              f"max {r.max_contour_error_um:.2f} um, "
                                              f"RMS {r.rms_contour_error_um:.2f} um") + f" (best score {best})")


class StopSignal:
    """The signal that asked the run to stop, if any."""

    signum: int | None = None


@contextmanager
def stop_on_signals(stop: StopSignal):
    """Turn SIGINT and SIGTERM into ``stop.signum`` (main thread only); a second one acts as usual."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}

    def handler(signum, frame):
        stop.signum = signum
        signal.signal(signum, previous[signum])
        print(f"\nvcnc-train: {signal.Signals(signum).name} received: saving a checkpoint at the last PPO update "
              "(send it again to quit at once)", file=sys.stderr, flush=True)

    for s in (signal.SIGINT, signal.SIGTERM):
        previous[s] = signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
