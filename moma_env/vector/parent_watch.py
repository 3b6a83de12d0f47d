"""Worker processes that end with the process that started them: :func:`exit_with_parent`,
and :func:`worker_pool`, the process pool the project's long tasks run in.

A :class:`concurrent.futures.ProcessPoolExecutor` worker busy with a long task (a
teacher's demonstrations, a sweep's cells) does not notice that the main process was
killed: it runs its task to the end, possibly for many minutes, and only then finds
nobody to give the result to. Passed as the pool's ``initializer``,
:func:`exit_with_parent` starts a daemon thread in the worker that waits on the
parent's sentinel (:func:`multiprocessing.parent_process`: the process that made the
pool, with the ``forkserver`` start method as with ``spawn``) and ends the worker as
soon as it becomes ready, that is when the parent is gone.

The parent process's ``os.getppid()`` would not do with ``forkserver``: a worker's OS
parent is the fork server, which lives on as long as any of its children does.

Nor does the executor's own ``with`` block end its workers when the block raises (an
error in the main process's share of the work, or Ctrl-C): leaving it waits for the
running tasks to finish. :class:`WorkerPool` ends them at once instead: each worker also
watches a pipe whose only writing end the pool holds, and the pool closes it.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import multiprocessing.context
import os
import threading
from concurrent.futures import ProcessPoolExecutor

from moma_env.vector.sharded import default_start_method

__all__ = ["ORPHAN_EXIT_CODE", "WorkerPool", "exit_with_parent", "worker_pool"]

ORPHAN_EXIT_CODE = 3
"""The exit status of a worker ended by :func:`exit_with_parent`: its parent died first."""


def exit_with_parent(
    abandoned: multiprocessing.connection.Connection | None = None,
    abandon_end: multiprocessing.connection.Connection | None = None,
) -> None:
    """Start, in this worker process, a daemon thread that ends it (``os._exit``) as soon
    as the process that started it is gone, or ``abandoned`` (the reading end of a pipe)
    reads end of file: the pipe's writing end closed where it was last open. Meant as a
    process pool's ``initializer``.

    Args:
        abandoned: the reading end, or None (the parent alone).
        abandon_end: the pipe's writing end as this worker received it, closed here
            (a forked worker inherits it), or None.

    Raises:
        RuntimeError: this process was not started by :mod:`multiprocessing`.
    """
    parent = multiprocessing.parent_process()
    if parent is None:
        raise RuntimeError("exit_with_parent runs in a worker started by multiprocessing (a process pool's initializer)")
    if abandon_end is not None:
        abandon_end.close()
    watched = [parent.sentinel] if abandoned is None else [parent.sentinel, abandoned]

    def watch() -> None:
        multiprocessing.connection.wait(watched)
        os._exit(ORPHAN_EXIT_CODE)  # no clean-up: the task's result has nobody to go to

    threading.Thread(target=watch, name="moma-parent-watch", daemon=True).start()


class WorkerPool(ProcessPoolExecutor):
    """A :class:`~concurrent.futures.ProcessPoolExecutor` whose workers end with the
    process that made it (:func:`exit_with_parent`) and, when its ``with`` block raises
    (Ctrl-C included), at once (:meth:`abandon`), instead of after their running tasks.

    Args:
        max_workers: worker processes.
        context: the :mod:`multiprocessing` context they start with.
    """

    def __init__(self, max_workers: int, context: multiprocessing.context.BaseContext) -> None:
        abandoned, self._abandon_end = context.Pipe(duplex=False)
        super().__init__(
            max_workers=max_workers, mp_context=context, initializer=exit_with_parent, initargs=(abandoned, self._abandon_end)
        )
        self._abandoned = abandoned

    def abandon(self) -> None:
        """End every worker now, its running task unfinished (its future fails with
        ``BrokenProcessPool``), cancel the pending tasks, and shut the pool down."""
        self._abandon_end.close()
        self.shutdown(wait=True, cancel_futures=True)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """The executor's shutdown; with ``wait`` (the workers are gone) the pipe's ends are closed too."""
        super().shutdown(wait=wait, cancel_futures=cancel_futures)
        if wait:
            self._abandon_end.close()
            self._abandoned.close()

    def __exit__(self, exc_type, exc_value, traceback) -> bool:
        if exc_type is not None:
            self.abandon()
            return False
        return super().__exit__(exc_type, exc_value, traceback)


def worker_pool(max_workers: int) -> WorkerPool:
    """A process pool of ``max_workers`` workers that start from a clean server process
    (:func:`~moma_env.vector.sharded.default_start_method`: forked from a driver that ran
    torch with several threads, a worker would hang at its first parallel torch
    operation) and end with this process, or at once when the pool's ``with`` block
    raises (:class:`WorkerPool`)."""
    return WorkerPool(max_workers, multiprocessing.get_context(default_start_method()))
