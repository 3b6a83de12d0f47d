"""The ``moma-env sweep`` subcommand: :func:`add_sweep_parser` and its handler.

Building the parser imports nothing of the envs (``moma-env --help`` stays light);
the handler imports the sweep when it runs.

``moma-env sweep --scenarios top_observer,caterpillar --policies scripted,random
--seeds 0:100 --out runs/sweep`` runs every cell as a Ray task on a Ray started for
the command (all cores of this machine), ``--address ADDR`` on an existing cluster,
``--backend local`` on a process pool without Ray (the same table, byte for byte).
``--resume`` continues a killed sweep. Bad input exits with status 2 and one line.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path

from training.cli_args import SET_HELP, field_assignment, field_assignments, int_at_least

__all__ = ["add_sweep_parser", "run_sweep_command", "BACKENDS"]

#: ``--backend`` of ``moma-env sweep`` (:class:`training.sweep.backends.RayBackend`, :class:`~training.sweep.backends.LocalBackend`).
BACKENDS = ("ray", "local")


def add_sweep_parser(subparsers, add_subcommand: Callable[..., argparse.ArgumentParser] | None = None) -> argparse.ArgumentParser:
    """Add ``sweep`` to ``moma-env``'s subparsers; return its parser. ``add_subcommand(sub, name,
    help)`` makes the parser the CLI's way (its epilog of exit statuses), if given."""
    help_text = "evaluate every scenario x policy x seed cell, on Ray or a local process pool (docs/scaling.md)"
    if add_subcommand is not None:
        sw = add_subcommand(subparsers, "sweep", help_text)
    else:
        sw = subparsers.add_parser("sweep", help=help_text)
    sw.add_argument("--scenarios", required=True, help="comma-separated configurations or tasks, e.g. top_observer,caterpillar")
    sw.add_argument("--policies", required=True, help="comma-separated policy specs of moma-env evaluate --policy, e.g. scripted,random")
    sw.add_argument("--seeds", required=True, help="reset seeds: START:STOP (half-open, e.g. 0:100) or a comma-separated list")
    sw.add_argument("--out", type=Path, required=True, help="output folder (one sweep per folder)")
    sw.add_argument("--backend", choices=BACKENDS, default="ray", help="ray (default: Ray tasks) or local (a process pool, no Ray)")
    sw.add_argument("--address", default=None, help="with --backend ray: an existing Ray cluster's address (default: start Ray here on all cores)")
    sw.add_argument("--jobs", type=int_at_least(1, "job count"), default=None, help="with --backend local: worker processes (default: every core)")
    sw.add_argument("--cells-per-task", type=int_at_least(1, "cell count"), default=2, help="episodes per task (default 2)")
    sw.add_argument("--retries", type=int_at_least(0, "retry count"), default=3, help="with --backend ray: reruns of a task whose worker died (default 3)")
    sw.add_argument("--resume", action="store_true", help="continue the sweep in --out: run only the cells without a result")
    sw.add_argument("--fixed", dest="random_scenarios", action="store_false", help="the configuration's default layout for every seed (default: a random layout per seed)")
    sw.add_argument("--max-cycles", type=int_at_least(1, "step count"), default=None, help="episode length limit in steps (default: the scenario's)")
    sw.add_argument("--set", dest="overrides", action="append", type=field_assignment, metavar="FIELD=VALUE", default=None,
                    help=SET_HELP)
    sw.add_argument("--sample-actions", action="store_true",
                    help="trained policies sample their actions (seeded by the episode's seed); built-in policies are unchanged")
    sw.add_argument("--no-progress", dest="progress_bar", action="store_false", help="no progress bar (default: shown)")
    sw.add_argument("--json", action="store_true", help="print the report as JSON")
    sw.set_defaults(handler=run_sweep_command)
    return sw


class _Bar:
    """The sweep's progress bar (:class:`training.evaluation.progress.EpisodeProgress`)."""

    def __init__(self) -> None:
        self.bar = None

    def __call__(self, total: int) -> Callable[[int], None]:
        from training.evaluation.progress import EpisodeProgress

        self.bar = EpisodeProgress(total, "sweep")
        return self.update

    def update(self, n: int) -> None:
        for _ in range(n):
            self.bar.update()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_sweep_command(args: argparse.Namespace) -> int:
    """Handler of ``moma-env sweep``: exit status 0, or 2 with a one-line message on bad input."""
    from moma_env.config import ConfigError
    from moma_env.io import RunFolderError
    from training.evaluation.policies import PolicyLoadError
    from training.sweep.backends import LocalBackend, RayBackend
    from training.sweep.run import sweep
    from training.sweep.spec import SweepSpec, parse_names, parse_seeds

    try:
        spec = SweepSpec(
            scenarios=parse_names("scenarios", args.scenarios),
            policies=parse_names("policies", args.policies),
            seeds=parse_seeds(args.seeds),
            random_scenarios=args.random_scenarios,
            max_cycles=args.max_cycles,
            sample_actions=args.sample_actions,
            overrides=field_assignments(args.overrides),
        )
        if args.backend == "local":
            if args.address is not None:
                raise ConfigError("address", "--address needs --backend ray")
            backend = LocalBackend(args.jobs if args.jobs is not None else (os.cpu_count() or 1))
        else:
            if args.jobs is not None:
                raise ConfigError("jobs", "--jobs is for --backend local; Ray uses every CPU of its cluster")
            backend = RayBackend(address=args.address, retries=args.retries)
    except ConfigError as err:
        print(f"moma-env sweep: {err}", file=sys.stderr)
        return 2
    bar = _Bar() if args.progress_bar else None
    try:
        report = sweep(spec, args.out, backend, resume=args.resume, cells_per_task=args.cells_per_task, progress=bar)
    except (ConfigError, PolicyLoadError, RunFolderError) as err:
        print(f"moma-env sweep: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # a task's own error, re-raised by Ray or the pool
        cause = str(err).strip().splitlines()
        print(f"moma-env sweep: a task failed ({type(err).__name__}: {cause[-1] if cause else ''}); "
              "finished cells are kept, fix the cause and pass --resume", file=sys.stderr)
        return 1
    finally:
        if bar is not None:
            bar.close()
    if args.json:
        print(json.dumps({"n_cells": report.n_cells, "n_run": report.n_run, "wall_time_s": report.wall_time_s,
                          "episodes_per_s": report.episodes_per_s, "files": {k: str(v) for k, v in report.files.items()}}, indent=2))
    else:
        print(f"sweep: {report.n_cells} cells, {report.n_run} run now in {report.wall_time_s:.1f} s "
              f"({report.episodes_per_s:.2f} episodes/s)\n" + "\n".join(f"{kind}: {path}" for kind, path in report.files.items()))
    return 0
