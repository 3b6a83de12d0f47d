"""What every benchmark of ``training`` shares: resident memory, timed calls, step rates, rounds, MPE2.

:mod:`training.bench` (``moma-env bench``), :mod:`training.bench_rendered`,
:mod:`training.bench_step` and :mod:`training.bench_memory` build their rows from
these; :mod:`training.bench` exports them too, where they have always been
importable. Measurements only: nothing here asserts a speed.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

__all__ = ["resident_mb", "in_fresh_process", "time_calls", "steps_per_second", "best_of_rounds", "mpe2_reference"]


def resident_mb() -> float:
    """Current resident set size of this process (MB), from /proc (Linux)."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1e6
    except (OSError, ValueError):
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3


def in_fresh_process(function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)`` in a new interpreter (spawned, so it inherits none of this one's
    memory: a resident size measured there is its own), and its result. ``function`` must be
    a module-level function and its arguments and result picklable."""
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(function, *args).result()


def time_calls(owner: object, method: str, totals: dict[str, float], key: str) -> None:
    """Replace ``owner.method`` by a wrapper that adds the wall time (s) of each call to
    ``totals[key]``. Only the instance ``owner`` is changed (nothing global is patched).
    An instance already wrapped keeps its one wrapper, which from now on adds to
    ``totals[key]`` (so a second measurement of the same objects is not lost in the first's
    totals, and calls are never timed twice)."""
    inner: Callable = getattr(owner, method)
    if getattr(inner, "_timed", False):
        inner._sink = (totals, key)  # type: ignore[attr-defined]
        return

    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            sink, name = wrapper._sink  # type: ignore[attr-defined]
            sink[name] += time.perf_counter() - start

    wrapper._timed = True  # type: ignore[attr-defined]
    wrapper._sink = (totals, key)  # type: ignore[attr-defined]
    setattr(owner, method, wrapper)


def steps_per_second(make_env: Callable[[], Any], steps: int, seed: int = 0, pool: int = 1000) -> float:
    """Joint steps per second of a PettingZoo parallel env under random actions.

    The random actions are drawn from the action spaces before the clock starts
    (``pool`` joint actions, used in turn), so the rate is that of ``env.step``
    and ``env.reset``, not of gymnasium's ``Space.sample`` (about 100 us per Box).
    """
    env = make_env()
    env.reset(seed=seed)
    agents = list(env.possible_agents)
    for agent in agents:
        env.action_space(agent).seed(seed)
    joint = [{a: env.action_space(a).sample() for a in agents} for _ in range(max(1, min(pool, steps)))]
    start = time.perf_counter()
    for i in range(steps):
        if not env.agents:
            env.reset()
        actions = joint[i % len(joint)]
        env.step({a: actions[a] for a in env.agents})
    elapsed = time.perf_counter() - start
    env.close()
    return steps / elapsed


def best_of_rounds(measures: Sequence[Callable[[], dict]], rounds: int) -> list[dict]:
    """Run every measure once per round, rounds interleaved; per measure, the row of
    its fastest run (largest ``steps_per_s``) with ``rounds_steps_per_s``, every run's rate."""
    runs: list[list[dict]] = [[] for _ in measures]
    for _ in range(rounds):
        for k, measure in enumerate(measures):
            runs[k].append(measure())
    rows = []
    for measured in runs:
        best = dict(max(measured, key=lambda row: row["steps_per_s"]))
        best["rounds_steps_per_s"] = [row["steps_per_s"] for row in measured]
        rows.append(best)
    return rows


def mpe2_reference() -> Callable[[], Any] | None:
    """The benchmarks' reference: a constructor of MPE2 ``simple_spread`` (N=3, the
    parallel API), or None if mpe2 is not installed."""
    try:
        from mpe2 import simple_spread_v3
    except ImportError:
        return None
    return lambda: simple_spread_v3.parallel_env(N=3)
