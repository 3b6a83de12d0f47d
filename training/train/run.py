"""A training run from start to finish, or resumed from its last checkpoint.

``train(config, out)`` builds the vectorised envs of the route, the model, the
checkpoint and evaluation callbacks, learns ``config.steps`` timesteps and
writes the final checkpoint (:mod:`training.train.checkpoint`). With
``config.init_from`` it starts from another run's networks and statistics
(:mod:`training.train.init_from`), and with ``config.dagger_teacher`` too it first runs
DAgger rounds from that policy; with ``config.kl_to_start`` its PPO loss keeps it
near the policy it started from (:mod:`training.train.kl_to_start`). With
``resume=True`` it loads the checkpoint that ``out``'s manifest names: model
weights, optimiser state and step counter (the SB3 zip), ``VecNormalize``
statistics, the replay buffer of off-policy algorithms, the training wall time
and the earlier evaluations, and learns the remaining ``config.steps -
num_timesteps`` timesteps. The resumed envs are seeded with ``config.seed +
num_timesteps``: a resumed run is as reproducible as a fresh one, though not
identical to an uninterrupted one (its envs restart at new layouts).
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback, CallbackList

from moma_env.config import ConfigError
from moma_env.io import claim_run_folder, run_kind, write_json
from training.train.callbacks import EVALUATIONS, CheckpointCallback, EvaluationCallback, update_threads_callback
from training.train.checkpoint import checkpoint_files, read_manifest, remove_stale_temporaries, save_checkpoint, source_revision
from agents.learned import torch_threads
from training.train.config import ROLLOUT_UPDATES, TrainConfig, update_threads
from training.train.envs import make_vec_env, wrap_normalisation
from training.train.demonstrations import read_demonstrations
from training.train.init_from import INITIALISATION, read_initial_weights
from training.train import kl_to_start
from training.train.models import algorithm_class, build_model, training_logger

__all__ = ["train", "RESUMABLE_CHANGES", "PRETRAINING"]

#: The record of a run's behaviour cloning or DAgger (:func:`training.train.pretrain.pretrain_model`, ``dagger_model``), in its folder.
PRETRAINING = "pretrain.json"

#: Fields of the configuration that a resumed run may change; every other must match the run's.
RESUMABLE_CHANGES = frozenset(
    {"steps", "subproc", "workers", "checkpoint_every", "eval_every", "eval_episodes", "eval_seed", "eval_max_cycles", "eval_sample_actions", "eval_jobs",
     "progress_bar", "torch_threads", "update_threads"}
)


def _check_resumable(stored: TrainConfig, config: TrainConfig) -> None:
    old, new = stored.to_dict(), config.to_dict()
    for name in old:
        if name not in RESUMABLE_CHANGES and old[name] != new[name]:
            raise ConfigError(name, f"the run in this folder has {old[name]!r}, the command gives {new[name]!r}; resume with the run's own settings")


def _earlier_records(out: Path, up_to: int) -> list[dict]:
    path = out / EVALUATIONS
    if not path.is_file():
        return []
    records = json.loads(path.read_text(encoding="utf-8")).get("records", [])
    return [r for r in records if r.get("num_timesteps", 0) <= up_to]


def _print_progress(line: str) -> None:
    """A line of the pretraining's progress on stderr (stdout may carry ``--json``'s record)."""
    print(f"moma-env train: {line}", file=sys.stderr, flush=True)


def train(config: TrainConfig, out: str | Path, resume: bool = False, callbacks: Sequence[BaseCallback] = ()) -> dict[str, Any]:
    """Train (or resume) the run ``config`` in folder ``out``; return the final manifest.

    Args:
        config: the run.
        out: its folder (created, marked as a training run, :func:`moma_env.io.claim_run_folder`).
            A fresh run refuses a folder that already holds one, or anything else.
        resume: continue the run in ``out`` from its last checkpoint.
        callbacks: more SB3 callbacks (called after the checkpoint and evaluation ones).

    Raises:
        ConfigError: ``out`` holds a run and ``resume`` is False, or the
            configuration differs from the resumed run's (naming the field).
        moma_env.io.RunFolderError: ``out`` holds another kind of run (an evaluation,
            an experiment) or files that are not a moma-env run.
        agents.learned.TrainingDirError: ``resume`` without a loadable checkpoint in ``out``.
    """
    out = Path(out)
    with torch_threads(config.torch_threads):
        return _train(config, out, resume, callbacks)


def _train(config: TrainConfig, out: Path, resume: bool, callbacks: Sequence[BaseCallback]) -> dict[str, Any]:
    if resume:
        if out.is_dir() and run_kind(out) not in (None, "train"):
            claim_run_folder(out, "train")  # RunFolderError: another kind of run
        manifest = read_manifest(out)
        _check_resumable(TrainConfig.from_dict(manifest["config"]), config)
        remove_stale_temporaries(out)
        done = int(manifest["num_timesteps"])
        venv = make_vec_env(config, config.seed + done)
        stats = out / manifest["vecnormalize"] if manifest.get("vecnormalize") else None
        venv = wrap_normalisation(venv, config, stats)
        model = algorithm_class(config.algo).load(out / manifest["model"], env=venv, device="cpu")
        if manifest.get("replay_buffer"):
            model.load_replay_buffer(out / manifest["replay_buffer"])
        wall_before = float(manifest["wall_time_s"])
        records = _earlier_records(out, done)
        kept = None  # a resumed run's cloning is done
    else:
        if out.exists() and ((out / "manifest.json").exists() or checkpoint_files(out)):
            raise ConfigError("out", f"{str(out)!r} already holds a training run; pass --resume to continue it or choose another folder")
        source = read_initial_weights(config) if config.init_from is not None else None  # ConfigError before the folder is claimed
        kept = read_demonstrations(config) if config.demonstrations is not None else None
        claim_run_folder(out, "train")  # RunFolderError: another kind of run, or files that are not a run
        remove_stale_temporaries(out)  # a run killed before its first checkpoint
        venv = wrap_normalisation(make_vec_env(config, config.seed), config, source.statistics if source is not None else None)
        model = build_model(config, venv)
        if source is not None:
            write_json(out / INITIALISATION, source.load_into(model))
        wall_before = 0.0
        records = []
    provenance: dict[str, Any] = {"git": source_revision()}  # the code of this session (a resume records its own)
    if config.algo in ROLLOUT_UPDATES:
        provenance["update_threads"] = update_threads(config)  # what the updates run on here (a resumed run records its own)
    session_start = time.perf_counter()

    def wall_time() -> float:
        return wall_before + time.perf_counter() - session_start

    def save() -> dict[str, Any]:
        return save_checkpoint(out, model, config, wall_time(), provenance)

    evaluation = EvaluationCallback(config, out, records, wall_time)
    # The threads first: the others' rollout-start work (checkpoints, evaluations) runs on the rollouts' count.
    threads = update_threads_callback(config)
    first = [threads] if threads is not None else []
    chain = CallbackList([*first, CheckpointCallback(config.checkpoint_every, save), evaluation, *callbacks])
    logger = training_logger(out, model.num_timesteps)
    model.set_logger(logger)
    try:
        with evaluation:  # its worker pool, if it starts one, ends here
            if not resume and (config.pretrain is not None or config.dagger_teacher is not None):
                from training.train.pretrain import dagger_model, pretrain_model

                report = _print_progress if config.progress_bar else None
                if config.pretrain is not None:
                    record = pretrain_model(model, venv, config, report, kept, keep=out)
                else:  # DAgger from init_from's policy
                    record = dagger_model(model, venv, config, report, kept)
                write_json(out / PRETRAINING, record)
            if config.kl_to_start > 0:
                start = kl_to_start.start_policy_from(out, model) if resume else kl_to_start.write_start_policy(out, model)
                kl_to_start.install(model, start, config.kl_to_start, config.ent_coef)
            if (config.pretrain is not None or config.init_from is not None) and not resume and config.eval_every > 0:
                evaluation.init_callback(model)  # where the cloned or given policy starts the curves
                evaluation.evaluate_now()
            remaining = config.steps - model.num_timesteps
            if remaining > 0:
                model.learn(remaining, callback=chain, reset_num_timesteps=not resume, progress_bar=config.progress_bar)
                if config.eval_every > 0 and (not evaluation.records or evaluation.records[-1]["num_timesteps"] != model.num_timesteps):
                    evaluation.evaluate_now()
                    logger.record("time/total_timesteps", model.num_timesteps)
                    logger.dump(model.num_timesteps)  # learn has dumped its last row already
        manifest = save()
    finally:
        logger.close()
        venv.close()
    return manifest
