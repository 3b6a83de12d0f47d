"""What the RLlib and TorchRL training runs share: opening the run folder (fresh or resumed)
and recording a held-out evaluation.

A run folder holds one training run (``moma_env.io.claim_run_folder`` marks it): a fresh
run refuses a folder that already holds one; a resumed run reads its manifest through
the backend's reader, refuses settings other than :data:`RESUMABLE` ones that differ
from the run's (naming the field), and keeps the evaluations made up to its checkpoint.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.learned import MANIFEST
from moma_env.config import ConfigError
from moma_env.io import claim_run_folder, run_kind
from training.train.callbacks import write_evaluations
from training.train.curves import EVALUATIONS, write_curves

__all__ = ["RunStart", "RunProgress", "start_run", "check_resumable", "record_evaluation"]


@dataclass(frozen=True)
class RunStart:
    """Where a run starts: its manifest (None when fresh), env steps done, training wall
    time so far (s) and the held-out evaluations recorded up to its checkpoint."""

    manifest: dict[str, Any] | None
    steps: int
    wall_before: float
    records: list[dict[str, Any]]


def check_resumable(stored: Any, config: Any, resumable: Collection[str]) -> None:
    """Raise ConfigError naming the first field outside ``resumable`` where ``config`` differs from ``stored``."""
    old, new = stored.to_dict(), config.to_dict()
    for name in old:
        if name not in resumable and old[name] != new[name]:
            raise ConfigError(name, f"the run in this folder has {old[name]!r}, the command gives {new[name]!r}; resume with the run's own settings")


def start_run(out: Path, resume: bool, config: Any, read_manifest: Callable[[Path], dict[str, Any]],
              resumable: Collection[str], has_checkpoint: Callable[[Path], bool]) -> RunStart:
    """Claim ``out`` for a fresh run, or read the run to resume in it (see the module docstring).

    Args:
        out: the run folder.
        resume: continue the run in ``out``.
        config: the command's configuration (``to_dict`` and ``from_dict`` of its class).
        read_manifest: the backend's manifest reader (raises ``TrainingDirError``).
        resumable: the fields a resumed run may change.
        has_checkpoint: whether a folder holds a checkpoint of the backend.

    Raises:
        moma_env.io.RunFolderError: ``out`` holds another kind of run or files that are not a run.
        ConfigError: a fresh run in a folder that holds one; a resumed run with other settings.
        agents.learned.TrainingDirError: ``resume`` without a loadable run.
    """
    if resume:
        if out.is_dir() and run_kind(out) not in (None, "train"):
            claim_run_folder(out, "train")  # RunFolderError: another kind of run
        manifest = read_manifest(out)
        check_resumable(type(config).from_dict(manifest["config"]), config, resumable)
        steps = int(manifest["num_timesteps"])
        records = []
        if (out / EVALUATIONS).is_file():
            records = [r for r in json.loads((out / EVALUATIONS).read_text(encoding="utf-8")).get("records", [])
                       if r.get("num_timesteps", 0) <= steps]
        return RunStart(manifest, steps, float(manifest["wall_time_s"]), records)
    if out.exists() and ((out / MANIFEST).exists() or has_checkpoint(out)):
        raise ConfigError("out", f"{str(out)!r} already holds a training run; pass --resume to continue it or choose another folder")
    claim_run_folder(out, "train")  # RunFolderError: another kind of run, or files that are not a run
    return RunStart(None, 0, 0.0, [])


def record_evaluation(out: Path, config: Any, records: list[dict[str, Any]], steps: int, wall_time_s: float,
                      numbers: Mapping[str, Any], seconds: float, title: str) -> None:
    """Append one held-out evaluation (its headline ``numbers``, taking ``seconds``) at ``steps``
    (env steps: what the TorchRL and RLlib backends count) to ``records`` and rewrite
    ``evaluations.json`` and the curves (titled ``title``)."""
    records.append({"num_timesteps": steps, "env_steps": steps, "wall_time_s": wall_time_s, **numbers, "eval_seconds": seconds,
                    "sample_actions": config.eval_sample_actions})
    write_evaluations(out, config, records)
    write_curves(out, records, title)


class RunProgress:
    """A run's training wall time (s, the earlier sessions' included) and its evaluations.

    Args:
        out: the run folder.
        config: the run's configuration (``eval_sample_actions`` and what
            ``evaluations.json`` records).
        start: where the run started (:func:`start_run`).
        title: the curves' title.
    """

    def __init__(self, out: Path, config: Any, start: RunStart, title: str):
        self.out = out
        self.config = config
        self.records = start.records
        self.title = title
        self._wall_before = start.wall_before
        self._session_start = time.perf_counter()

    def wall(self) -> float:
        """Training wall time so far (s)."""
        return self._wall_before + time.perf_counter() - self._session_start

    def evaluate(self, steps: int, numbers: Callable[[], Mapping[str, Any]]) -> None:
        """Run the held-out evaluation ``numbers`` at ``steps`` and record it (:func:`record_evaluation`)."""
        began = time.perf_counter()
        result = numbers()
        record_evaluation(self.out, self.config, self.records, steps, self.wall(), result, time.perf_counter() - began, self.title)

    def evaluated_at(self, steps: int) -> bool:
        """Whether the last recorded evaluation is at ``steps``."""
        return bool(self.records) and self.records[-1]["num_timesteps"] == steps
