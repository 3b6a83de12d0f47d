"""A process pool's worker ends with the process that started it (moma_env.vector.parent_watch)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from moma_env.vector.parent_watch import exit_with_parent

_MAIN = textwrap.dedent(
    """
    import multiprocessing as mp
    import os
    import sys
    import time
    from concurrent.futures import ProcessPoolExecutor

    from moma_env.vector.parent_watch import worker_pool
    from moma_env.vector.sharded import default_start_method

    if __name__ == "__main__":
        if sys.argv[1] == "watched":
            pool = worker_pool(1)  # the pool of the demonstrations and of the local sweeps
        else:
            pool = ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context(default_start_method()))
        print(pool.submit(os.getpid).result(), flush=True)
        pool.submit(time.sleep, 120)  # a long task, as a teacher's demonstrations are
        time.sleep(120)
    """
)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def _orphan_worker(tmp_path, mode: str) -> int:
    """Start a main process with a pool busy in a long task, kill the main process
    (SIGKILL: no clean-up of any kind), and return its worker's pid."""
    script = tmp_path / "main.py"
    script.write_text(_MAIN)
    main = subprocess.Popen([sys.executable, str(script), mode], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(main.stdout.readline())
    finally:
        main.kill()
        main.wait()
        main.stdout.close()
    return worker


def _gone_within(pid: int, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not _alive(pid):
            return True
        time.sleep(0.1)
    return not _alive(pid)


def test_a_watched_worker_ends_when_its_main_process_is_killed(tmp_path):
    worker = _orphan_worker(tmp_path, "watched")
    try:
        assert _gone_within(worker, 10.0), f"worker {worker} still runs 10 s after its main process was killed"
    finally:
        if _alive(worker):
            os.kill(worker, signal.SIGKILL)


def test_an_unwatched_worker_outlives_its_main_process(tmp_path):
    """The control: without the watch the worker goes on with its task."""
    worker = _orphan_worker(tmp_path, "unwatched")
    try:
        assert not _gone_within(worker, 5.0)
    finally:
        if _alive(worker):
            os.kill(worker, signal.SIGKILL)


def test_a_process_not_started_by_multiprocessing_is_refused():
    with pytest.raises(RuntimeError, match="started by multiprocessing"):
        exit_with_parent()


def test_a_raising_pool_block_ends_its_workers_at_once():
    """An error (or Ctrl-C) in the main process's share of the work is raised without
    waiting for the workers' running tasks, and the workers are gone."""
    from moma_env.vector.parent_watch import worker_pool

    start = time.monotonic()
    with pytest.raises(KeyError, match="the main process's own work"):
        with worker_pool(2) as pool:
            pids = {pool.submit(os.getpid).result() for _ in range(4)}
            running = [pool.submit(time.sleep, 60) for _ in range(2)]  # long tasks, as a teacher's demonstrations are
            time.sleep(0.5)
            raise KeyError("the main process's own work failed")
    assert time.monotonic() - start < 30.0
    assert all(_gone_within(pid, 5.0) for pid in pids)
    assert all(future.done() and future.exception() is not None for future in running)


def test_a_pool_block_that_ends_normally_waits_for_its_tasks():
    from moma_env.vector.parent_watch import worker_pool

    with worker_pool(1) as pool:
        future = pool.submit(_slow_square, 12)
    assert future.result(timeout=0) == 144


def _slow_square(x: int) -> int:
    time.sleep(1.0)
    return x * x
