"""Where a sweep's tasks run: a local process pool or Ray.

A task is a short list of cells (:func:`training.sweep.cells.run_cells`); both backends
hand every finished task's rows to ``on_done`` in the driver as they arrive, which
stores them (:class:`training.sweep.folder.SweepFolder`) and advances the progress bar.

* :class:`LocalBackend`: ``concurrent.futures.ProcessPoolExecutor`` with ``jobs``
  workers on this machine, started from a clean server process (forkserver, else
  spawn), not forked from the driver; no Ray needed.
* :class:`RayBackend`: every task is a Ray task (``num_cpus=1``), on a Ray started for
  the command (all cores of this machine; ``ray.init()``) or on an existing cluster
  (``address``, e.g. ``"auto"`` or ``"ray://head:10001"``); a Ray already initialised in
  this process (a test's fixture) is used as it is and left running. A task whose worker
  process dies (killed, out of memory, a node lost) is retried by Ray up to ``retries``
  times (``max_retries``); an exception raised by the task itself is not retried (it
  would raise again) and stops the sweep with the cells finished so far kept.

What is shipped to a worker: the cell list and the two episode options (a few hundred
bytes); what comes back: the rows (about 1 kB per cell). The code itself must be
importable on every node (the project installed there, or a shared checkout).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, wait
from dataclasses import dataclass
from typing import Any, Protocol

from moma_env.config import check_count
from moma_env.vector.parent_watch import worker_pool
from training.sweep.cells import run_cells
from training.sweep.spec import Cell

__all__ = ["Backend", "LocalBackend", "RayBackend", "TaskDone", "BACKENDS"]

#: Called in the driver with a finished task's cells and their rows.
TaskDone = Callable[[Sequence[Cell], list[dict[str, Any]]], None]

BACKENDS = ("ray", "local")


class Backend(Protocol):
    """Runs every task, calling ``on_done`` for each as it finishes."""

    def run(self, tasks: Sequence[Sequence[Cell]], options: Mapping[str, Any], on_done: TaskDone) -> None: ...


@dataclass(frozen=True)
class LocalBackend:
    """A process pool of ``jobs`` workers (1: in this process, no pool).

    The pool is :func:`~moma_env.vector.parent_watch.worker_pool`'s: its workers start from
    a clean server process (forked from a driver that has run torch with more than one
    thread, as loading a trained policy does, a worker would hang at its first parallel
    torch operation, waiting on OpenMP threads the fork did not copy) and end with this
    process, or at once on an error or Ctrl-C.
    """

    jobs: int = 1

    def __post_init__(self) -> None:
        check_count("jobs", self.jobs, 1)

    def run(self, tasks: Sequence[Sequence[Cell]], options: Mapping[str, Any], on_done: TaskDone) -> None:
        if self.jobs == 1:
            for cells in tasks:
                on_done(cells, run_cells(cells, options))
            return
        # An error or Ctrl-C here leaves the pool's block: its workers end at once and the
        # pending tasks are cancelled (WorkerPool).
        with worker_pool(min(self.jobs, max(1, len(tasks)))) as pool:
            pending = {pool.submit(run_cells, list(cells), dict(options)): cells for cells in tasks}
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    cells = pending.pop(future)
                    on_done(cells, future.result())


@dataclass(frozen=True)
class RayBackend:
    """Ray tasks on a local Ray (``address`` None) or on the cluster at ``address``.

    Attributes:
        address: a Ray cluster's address, or None to start Ray for the command.
        retries: how often a task whose worker died is run again (>= 0).
        max_in_flight: tasks submitted ahead of the finished ones (bounds the driver's
            memory and the object store on a long sweep); None: all at once.
    """

    address: str | None = None
    retries: int = 3
    max_in_flight: int | None = None

    def __post_init__(self) -> None:
        check_count("retries", self.retries, 0)
        if self.max_in_flight is not None:
            check_count("max_in_flight", self.max_in_flight, 1)

    def run(self, tasks: Sequence[Sequence[Cell]], options: Mapping[str, Any], on_done: TaskDone) -> None:
        try:
            import ray
        except ImportError as err:
            raise RuntimeError(f"the Ray backend needs the 'ray' extra (pip install -e '.[ray]'): {err}") from None
        started = False
        if not ray.is_initialized():
            if self.address is None:
                ray.init(include_dashboard=False, log_to_driver=False)
            else:  # a cluster's own settings apply (a ray:// client accepts few options)
                ray.init(address=self.address)
            started = True
        try:
            remote = ray.remote(num_cpus=1, max_retries=self.retries, retry_exceptions=False)(run_cells)
            options_ref = ray.put(dict(options))
            queue = deque(tasks)
            limit = self.max_in_flight or max(1, len(queue))
            pending: dict[Any, Sequence[Cell]] = {}
            try:
                while queue or pending:
                    while queue and len(pending) < limit:
                        cells = queue.popleft()
                        pending[remote.remote(list(cells), options_ref)] = cells
                    done, _ = ray.wait(list(pending), num_returns=1)
                    for ref in done:
                        cells = pending.pop(ref)
                        on_done(cells, ray.get(ref))
            except BaseException:
                for ref in pending:
                    ray.cancel(ref, force=True)
                raise
        finally:
            if started:
                ray.shutdown()
