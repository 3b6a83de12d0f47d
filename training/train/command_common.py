"""What every backend of ``moma-env train`` does alike on the command line: read ``--reward``
and report the finished run (imported by :mod:`training.train.command` and the backends'
command modules, importing none of them).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from moma_env.tasks import TASKS
from training.train.config import reward_overrides

if TYPE_CHECKING:
    from moma_env.env.config import RewardConfig

__all__ = ["scenario_rewards", "report_training"]


def scenario_rewards(scenario: str, pairs: list[str]) -> RewardConfig | None:
    """None without ``--reward`` (the scenario's own weights), else those pairs over a
    task's weights (:data:`moma_env.tasks.TASKS`) or the defaults."""
    if not pairs:
        return None
    task = TASKS.get(scenario)
    return reward_overrides(pairs, None if task is None else task.options.get("rewards"))


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
