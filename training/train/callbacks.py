"""Callbacks of a training run: periodic checkpoints, periodic held-out evaluations, and
torch's thread count for the updates.

The first two act at the start of a rollout, that is after the model has been updated
with every step counted so far (for PPO, after ``train()`` of the previous
rollout), so a checkpoint at ``S`` timesteps holds the weights trained on those
``S`` steps and a resumed run neither repeats nor skips an update.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

from moma_env.io import write_json
from moma_env.vector.parent_watch import WorkerPool, worker_pool
from training.train.config import ROLLOUT_UPDATES, TrainConfig, eval_jobs, update_threads
from training.train.curves import EVALUATIONS, write_curves
from training.train.evaluation import evaluate_model, headline

__all__ = ["CheckpointCallback", "EvaluationCallback", "EVALUATIONS", "UpdateThreadsCallback", "update_threads_callback", "slots_per_copy"]


class UpdateThreadsCallback(BaseCallback):
    """torch's intra-op threads: ``update`` for the gradient updates that follow each rollout,
    ``rollout`` while the rollout is collected.

    An on-policy algorithm (PPO, MaskablePPO, A2C) updates after each rollout, while every
    env copy, in this process or in a worker, waits for the new policy: its updates can take
    the cores the copies use while collecting, where a second thread only contends with
    them. The count is set at the end of each rollout (SB3 then calls ``train()``) and back
    at the start of the next. A run is deterministic for its seed and both thread counts; on
    the default networks and minibatches one or two update threads give the same weights
    (``tests/test_train_threads.py``).
    """

    def __init__(self, update: int, rollout: int):
        super().__init__()
        self.update = update
        self.rollout = rollout

    def _on_rollout_start(self) -> None:
        import torch

        torch.set_num_threads(self.rollout)

    def _on_rollout_end(self) -> None:
        import torch

        torch.set_num_threads(self.update)

    def _on_step(self) -> bool:
        return True


def update_threads_callback(config: TrainConfig) -> UpdateThreadsCallback | None:
    """The :class:`UpdateThreadsCallback` of ``config`` (:func:`~training.train.config.update_threads`
    threads for the updates, ``config.torch_threads`` for the rollouts), or None where the
    algorithm does not update between rollouts or both counts are the same."""
    if config.algo not in ROLLOUT_UPDATES:
        return None
    threads = update_threads(config)
    return UpdateThreadsCallback(threads, config.torch_threads) if threads != config.torch_threads else None


class CheckpointCallback(BaseCallback):
    """Calls ``save()`` at the first rollout start ``every`` timesteps after the last save.

    Args:
        every: timesteps between checkpoints.
        save: writes a checkpoint of the model (see :func:`training.train.checkpoint.save_checkpoint`).
    """

    def __init__(self, every: int, save: Callable[[], Any]):
        super().__init__()
        self.every = every
        self._save = save
        self.last_saved: int | None = None
        self.saved_at: list[int] = []

    def _on_training_start(self) -> None:
        self.last_saved = self.num_timesteps

    def _on_rollout_start(self) -> None:
        if self.num_timesteps - self.last_saved >= self.every:
            self._save()
            self.last_saved = self.num_timesteps
            self.saved_at.append(self.num_timesteps)

    def _on_step(self) -> bool:
        return True


class EvaluationCallback(BaseCallback):
    """Runs the evaluation harness on held-out random scenarios every ``config.eval_every`` timesteps.

    Every evaluation appends a record (timesteps, training wall time in s, the
    :func:`~training.train.evaluation.headline` numbers, whether the actions
    were sampled) and rewrites
    ``<out>/evaluations.json``, ``<out>/curves.csv`` and ``<out>/curves.png``
    (:mod:`training.train.curves`), each whole; the numbers also go to the SB3
    logger (``eval/...``, in TensorBoard when it is installed).

    With :func:`~training.train.config.eval_jobs` above 1 the episodes are split over a
    process pool started at the first evaluation and kept until the callback's ``with``
    block ends (the run's), so that the workers start, and import torch, once a run.

    Args:
        config: the run (``eval_every``, ``eval_episodes``, ``eval_seed``, ...).
        out: the run's folder.
        records: the records of earlier sessions of the run (resume).
        wall_time: returns the run's training wall time so far (s).
    """

    def __init__(self, config: TrainConfig, out: Path, records: list[dict], wall_time: Callable[[], float]):
        super().__init__()
        self.config = config
        self.out = Path(out)
        self.records = list(records)
        self._wall_time = wall_time
        self._last: int | None = None
        self._jobs = eval_jobs(config)
        self._pool: WorkerPool | None = None

    def __enter__(self) -> "EvaluationCallback":
        return self

    def __exit__(self, exc_type, exc_value, traceback) -> bool:
        """End the evaluations' worker pool: after its tasks, or at once on an error."""
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.__exit__(exc_type, exc_value, traceback)
        return False

    def _on_training_start(self) -> None:
        self._last = self.num_timesteps

    def _on_rollout_start(self) -> None:
        if self.config.eval_every > 0 and self.num_timesteps - self._last >= self.config.eval_every:
            self.evaluate_now()
            self._last = self.num_timesteps

    def evaluate_now(self) -> dict:
        """Evaluate the current model, log and write the records; return the new record."""
        start = time.perf_counter()
        if self._jobs > 1 and self._pool is None:
            self._pool = worker_pool(self._jobs)
        result = evaluate_model(self.model, self.config, jobs=self._jobs, executor=self._pool)
        timesteps = int(self.model.num_timesteps)
        record = {"num_timesteps": timesteps, "env_steps": timesteps // slots_per_copy(self.model.get_env()),
                  "wall_time_s": self._wall_time(), **headline(result.summary),
                  "eval_seconds": time.perf_counter() - start, "sample_actions": self.config.eval_sample_actions}
        self.records.append(record)
        for key in ("success_rate", "time_to_goal_s", "n_switches", "me_m", "e_f_m"):
            self.logger.record(f"eval/{key}", record[key])
        write_evaluations(self.out, self.config, self.records)
        write_curves(self.out, self.records, f"{self.config.scenario}: {self.config.algo}, {self.config.route}, seed {self.config.seed}")
        return record

    def _on_step(self) -> bool:
        return True


def slots_per_copy(venv: Any) -> int:
    """SB3 timesteps per env step of the training env ``venv`` (under its wrappers): the UGV
    slots of one copy on the shared route, 1 on the centralised one (the adapters' ``per_copy``)."""
    return int(venv.unwrapped.per_copy)


def write_evaluations(out: Path, config: TrainConfig, records: list[dict]) -> None:
    """``<out>/evaluations.json``, whole or not at all."""
    write_json(Path(out) / EVALUATIONS, {
        "scenario": config.scenario,
        "episodes": config.eval_episodes,
        "first_seed": config.eval_seed,
        "action_mode": config.action_mode,
        "records": records,
    })
