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
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import os
import threading
from concurrent.futures import ProcessPoolExecutor

from moma_env.vector.sharded import default_start_method

__all__ = ["ORPHAN_EXIT_CODE", "exit_with_parent", "worker_pool"]

ORPHAN_EXIT_CODE = 3
"""The exit status of a worker ended by :func:`exit_with_parent`: its parent died first."""


def exit_with_parent() -> None:
    """Start, in this worker process, a daemon thread that ends it (``os._exit``) as soon
    as the process that started it is gone. Meant as a process pool's ``initializer``.

    Raises:
        RuntimeError: this process was not started by :mod:`multiprocessing`.
    """
    parent = multiprocessing.parent_process()
    if parent is None:
        raise RuntimeError("exit_with_parent runs in a worker started by multiprocessing (a process pool's initializer)")

    def watch() -> None:
        multiprocessing.connection.wait([parent.sentinel])
        os._exit(ORPHAN_EXIT_CODE)  # no clean-up: the task's result has nobody to go to

    threading.Thread(target=watch, name="moma-parent-watch", daemon=True).start()


def worker_pool(max_workers: int) -> ProcessPoolExecutor:
    """A process pool of ``max_workers`` workers that start from a clean server process
    (:func:`~moma_env.vector.sharded.default_start_method`: forked from a driver that ran
    torch with several threads, a worker would hang at its first parallel torch
    operation) and end with this process (:func:`exit_with_parent`)."""
    context = multiprocessing.get_context(default_start_method())
    return ProcessPoolExecutor(max_workers=max_workers, mp_context=context, initializer=exit_with_parent)
