"""What every backend of ``moma-env train`` does alike on the command line: read ``--reward``
and ``--workers``, and report the finished run (imported by :mod:`training.train.command` and the backends'
command modules, importing none of them).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from moma_env.tasks import TASKS
from training.train.config import auto_workers, reward_overrides, usable_cores

if TYPE_CHECKING:
    from moma_env.env.config import RewardConfig

__all__ = ["AUTO", "scenario_rewards", "resolved_workers", "report_training"]

#: ``--workers``'s default: as many processes as pay on this machine (:func:`resolved_workers`).
AUTO = "auto"


def scenario_rewards(scenario: str, pairs: list[str]) -> RewardConfig | None:
    """None without ``--reward`` (the scenario's own weights), else those pairs over a
    task's weights (:data:`moma_env.tasks.TASKS`) or the defaults."""
    if not pairs:
        return None
    task = TASKS.get(scenario)
    return reward_overrides(pairs, None if task is None else task.options.get("rewards"))


def resolved_workers(option: int | str, envs: int, splits: bool) -> int | None:
    """The worker count of ``--workers option`` for a run of ``envs`` copies: a count as given;
    ``auto``, where the run ``splits`` its batched env over processes (SB3 without
    ``--subproc``, the TorchRL backend), :func:`~training.train.config.auto_workers`
    on this process's cores, else None (every copy in this process)."""
    if option != AUTO:
        return option  # type: ignore[return-value]
    return auto_workers(envs, usable_cores()) if splits else None


def report_training(args: argparse.Namespace, run: Callable[[], dict], summary: Callable[[dict], str]) -> int:
    """Run a backend's training (``run`` returns its final manifest) and report it: the manifest
    as JSON with ``--json``, else ``summary(manifest)``; exit status 0, or 2 with one line
    when the run folder cannot be trained in or resumed (``TrainingDirError``)."""
    from agents.learned import TrainingDirError

    try:
        manifest = run()
    except TrainingDirError as err:
        print(f"moma-env train: {err}", file=sys.stderr)
        return 2
    print(json.dumps(manifest, indent=2, sort_keys=True) if args.json else summary(manifest))
    return 0
