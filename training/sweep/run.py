"""A sweep from its spec to the written table: :func:`sweep`.

The cells without a stored result are grouped into tasks of ``cells_per_task``
consecutive cells and run on the backend; every finished task's rows are stored at
once, one file per task (:class:`training.sweep.folder.SweepFolder`), so a sweep killed at
any instant loses at most the tasks in flight, and ``resume=True`` redoes only the cells that have
no result. When every cell has one, the rows are read back from their files in table
order and the table, the summary and the figure are written (:mod:`training.sweep.table`):
the same cells give the same bytes whatever backend ran them, in what order, in how
many sessions.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from training.evaluation.policies import load_policy
from training.sweep.backends import Backend
from training.sweep.folder import SweepFolder
from training.sweep.spec import Cell, SweepSpec, chunks
from training.sweep.table import write_outputs

__all__ = ["sweep", "check_policies", "SweepReport"]


@dataclass(frozen=True)
class SweepReport:
    """What a call of :func:`sweep` did.

    Attributes:
        n_cells: cells of the spec.
        n_run: cells run by this call (the others had results already).
        wall_time_s: wall time of this call (s).
        files: the written outputs by kind.
    """

    n_cells: int
    n_run: int
    wall_time_s: float
    files: dict[str, Path]

    @property
    def episodes_per_s(self) -> float:
        """Cells run by this call per second of its wall time."""
        return self.n_run / self.wall_time_s if self.wall_time_s > 0 else float("nan")


def check_policies(spec: SweepSpec) -> None:
    """Load every policy for every scenario once in the driver, before anything is written,
    so a misspelt policy or a policy that does not fit a scenario fails at once.

    Raises:
        PolicyLoadError: naming the policy.
    """
    for scenario in spec.scenarios:
        for policy in spec.policies:
            load_policy(policy, scenario, spec.seeds[0])


def sweep(
    spec: SweepSpec,
    out: str | Path,
    backend: Backend,
    *,
    resume: bool = False,
    cells_per_task: int = 1,
    progress: Callable[[int], Callable[[int], None]] | None = None,
) -> SweepReport:
    """Run every cell of ``spec`` that has no result in ``out``, then write the outputs.

    Args:
        spec: the sweep.
        out: its folder (see :mod:`training.sweep.folder`).
        backend: :class:`~training.sweep.backends.LocalBackend` or
            :class:`~training.sweep.backends.RayBackend`.
        resume: continue the sweep in ``out``.
        cells_per_task: cells per task (one episode each; >= 1).
        progress: called once with the number of cells to run; it returns the callback
            called with the number of cells of every finished task (a progress bar).

    Raises:
        ConfigError: see :class:`~training.sweep.folder.SweepFolder`; a bad ``cells_per_task``.
        PolicyLoadError: a policy that cannot be loaded for a scenario (:func:`check_policies`,
            before the folder is touched).
    """
    start = time.perf_counter()
    check_policies(spec)
    with SweepFolder(out, spec, resume=resume) as folder:
        finished = folder.finished()
        todo = [cell for cell in spec.cells() if cell not in finished]
        tasks = chunks(todo, cells_per_task) if todo else []
        advance = progress(len(todo)) if progress is not None else None

        def on_done(cells: Sequence[Cell], rows: list[dict[str, Any]]) -> None:
            folder.write_rows(cells, rows)
            if advance is not None:
                advance(len(cells))

        if tasks:
            backend.run(tasks, spec.options, on_done)
        stored = folder.stored()
        missing = [cell.key for cell in spec.cells() if cell not in stored]
        if missing:  # pragma: no cover - every task has reported or raised
            raise RuntimeError(f"cells without a result after the sweep: {missing[:5]}")
        rows = [stored[cell] for cell in spec.cells()]
        files = write_outputs(folder.out, rows, {"spec": spec.to_dict(), "n_cells": len(rows)})
    return SweepReport(n_cells=len(rows), n_run=len(todo), wall_time_s=time.perf_counter() - start, files=files)
