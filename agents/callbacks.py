"""What runs during SB3's training besides PPO: checkpoints, evaluations and the stop on a signal.

As SB3's ``common/callbacks.py``: :func:`make_run_callback` is the SB3 callback of a run (checkpoint and
evaluate between PPO updates, stop when :class:`vcnc_agents.run_session.StopSignal` says so).  The rows it writes
and ranks are :mod:`vcnc_agents.run_folder`'s (:func:`vcnc_agents.run_folder.evaluation_row`), the session it records
:class:`vcnc_agents.run_session.Session`'s, handed in by the trainer.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from .env_factory import make_eval_env
from .normalization import NormalizationStats
from .policy import evaluate_model
from .run_folder import EVAL_FIELDS, best_of, checkpoint_files, read_evaluations, save_agent, save_model

__all__ = ["make_run_callback"]


def make_run_callback(config, run_dir: Path, session, stop, verbose: int):
    """The callback that checkpoints and evaluates, both between PPO updates, and stops on a signal.

    ``config`` is the run's :class:`vcnc_agents.run_config.RunConfig`, ``session`` its
    :class:`vcnc_agents.run_session.Session` (recorded at every checkpoint), ``stop`` its
    :class:`vcnc_agents.run_session.StopSignal`.

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

    def __init__(self, config, run_dir: Path, session, stop, verbose: int):
        super().__init__(verbose)
        self._config, self._run_dir, self._session, self._stop = config, run_dir, session, stop
        self._checkpoint_freq = config.checkpoint_freq
        self._eval_freq = config.eval_freq  # 0: only at the end
        self.env = make_eval_env(config)
        self.csv = self._run_dir / "evaluations.csv"
        rows = read_evaluations(self.csv)
        self.best = best_of(rows)
        self.last_eval_row = max((r["steps"] for r in rows), default=None)
        self.stopped_early = False

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
        self._session.checkpointed(n, self.best)

    def evaluate(self, n: int, stats: NormalizationStats) -> None:
        self.last_eval = n
        if n == self.last_eval_row:
            return  # this checkpoint was evaluated before the run was resumed
        row = evaluate_model(self.model, stats, self._config, self.env, n)
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
            print(
                f"eval at {n} steps: "
                + ("diverged" if row["diverged"] else f"max {row['max_um']:.2f} um, RMS {row['rms_um']:.2f} um")
                + f" (best score {best})"
            )
