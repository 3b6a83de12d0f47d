"""Resident memory over many short episodes: does memory grow with resets?

``python -m training.bench_memory [--resets 20000] [--steps 20] [--targets world top_observer top_observer_random]``
runs ``--resets`` episodes of ``--steps`` steps of each target and samples the
resident set size (:func:`training.bench_common.resident_mb`) every ``--every``
resets:

* ``world``: the top_observer scenario's :class:`~moma_env.world.World` alone,
  ``World.reset()`` then ``--steps`` steps with every robot released and driven
  by commands drawn from a seeded generator before the clock starts (up to
  0.2 m/s and 0.2 rad/s), and the UAV flown a little;
* ``top_observer``: the environment (switching mode, geometric camera),
  ``env.reset()`` then ``--steps`` joint steps of random actions drawn from the
  action spaces beforehand (a pool used in turn, as in ``moma-env bench``);
* ``top_observer_random``: the same with ``random_scenarios=True``: a new layout,
  hence a new simulation and world, at every reset.

Each target runs in a fresh process (the resident memory of a process is all of
it: a target run after another would start with what the first left behind);
:func:`reset_memory` alone runs in the calling process.
Reported per target: the RSS after the first episode (``start``), at the end,
the peak, the growth per 1,000 resets over the whole run, and the steepest
growth between two samples after the first (a run whose memory grows until
Python's garbage collector happens to run a full collection and then drops
grows like a sawtooth: its end can be close to its start), and how many full
garbage collections ran (Python's own and those the world runs to reclaim its
replaced spaces; about 0.1 s each in such a process). Each pymunk space
the world replaces at a reset holds about 280 KiB outside Python's view until
the cyclic garbage collector frees it (see :mod:`moma_env.world.world`), which
is what this benchmark watches. A measurement, not an assertion.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import time
from collections.abc import Callable

from training.bench_common import in_fresh_process

__all__ = ["TARGETS", "reset_memory", "format_reset_memory"]

#: What can be measured: the world alone, the whole environment, or the environment
#: with a new random layout (a new simulation) at every reset.
TARGETS = ("world", "top_observer", "top_observer_random")


def _world_episode(steps: int, seed: int) -> Callable[[], None]:
    """One episode of the top_observer world alone: reset, release the robots, drive."""
    import numpy as np

    from moma_env.scenarios import CONFIGURATIONS
    from moma_env.world import World

    world = World(CONFIGURATIONS["top_observer"]().scenario().world)
    rng = np.random.default_rng(seed)
    names = world.ugv_names
    pool = 1000
    limits = np.array([0.2, 0.2, 0.2])
    ugv_commands = [{name: rng.uniform(-limits, limits) for name in names} for _ in range(pool)]
    uav_commands = [rng.uniform(-0.05, 0.05, 4) if world.has_uav else None for _ in range(pool)]
    turn = 0

    def episode() -> None:
        nonlocal turn
        world.reset()
        for name in names:
            world.set_static(name, False)
        for _ in range(steps):
            world.step(ugv_commands[turn % pool], uav_commands[turn % pool])
            turn += 1

    return episode


def _env_episode(configuration: str, steps: int, seed: int, random_scenarios: bool = False) -> Callable[[], None]:
    """One episode of the environment: reset, then ``steps`` joint steps of pre-drawn random actions."""
    from moma_env.env.factory import parallel_env

    env = parallel_env(configuration, random_scenarios=random_scenarios)
    env.reset(seed=seed)
    agents = list(env.possible_agents)
    for agent in agents:
        env.action_space(agent).seed(seed)
    joint = [{a: env.action_space(a).sample() for a in agents} for _ in range(1000)]
    turn = 0

    def episode() -> None:
        nonlocal turn
        env.reset()
        for _ in range(steps):
            if not env.agents:
                break
            actions = joint[turn % len(joint)]
            env.step({a: actions[a] for a in env.agents})
            turn += 1

    return episode


def reset_memory(target: str, resets: int, steps: int = 20, every: int = 1000, seed: int = 0) -> dict:
    """RSS (MB) of ``resets`` episodes of ``steps`` steps of ``target`` (one of :data:`TARGETS`).

    Runs in this process. Returns a row: ``target``, ``resets``, ``steps``,
    ``samples`` (pairs of resets done and RSS in MB, after the first episode,
    every ``every`` resets and at the end), ``start_mb`` (after the first
    episode), ``end_mb``, ``peak_mb``, ``per_1000_mb`` (growth per 1,000 resets
    from the first episode to the end), ``steepest_per_1000_mb`` (the largest
    growth per 1,000 resets between two consecutive samples after the first
    interval, which holds the warm-up), ``full_collections`` (full garbage
    collections during the episodes), ``seconds`` (wall time of the episodes).
    """
    from training.bench_common import resident_mb

    if target not in TARGETS:
        raise ValueError(f"unknown target {target!r}; known: {list(TARGETS)}")
    if resets < 2 or steps < 0 or every < 1:
        raise ValueError(f"need resets >= 2, steps >= 0 and every >= 1, got {resets}, {steps}, {every}")
    if target == "world":
        episode = _world_episode(steps, seed)
    else:
        episode = _env_episode("top_observer", steps, seed, random_scenarios=target == "top_observer_random")
    episode()
    samples = [(1, resident_mb())]
    collections = gc.get_stats()[-1]["collections"]
    start = time.perf_counter()
    for k in range(2, resets + 1):
        episode()
        if k % every == 0 or k == resets:
            samples.append((k, resident_mb()))
    seconds = time.perf_counter() - start
    collections = gc.get_stats()[-1]["collections"] - collections

    def per_1000(a: tuple[int, float], b: tuple[int, float]) -> float:
        return (b[1] - a[1]) / (b[0] - a[0]) * 1000.0

    later = [per_1000(a, b) for a, b in zip(samples[1:], samples[2:])]
    return {
        "target": target,
        "resets": resets,
        "steps": steps,
        "samples": samples,
        "start_mb": samples[0][1],
        "end_mb": samples[-1][1],
        "peak_mb": max(mb for _, mb in samples),
        "per_1000_mb": per_1000(samples[0], samples[-1]),
        "steepest_per_1000_mb": max(later) if later else float("nan"),
        "full_collections": collections,
        "seconds": seconds,
    }


def format_reset_memory(rows: list[dict]) -> str:
    """The table of :func:`reset_memory` rows."""
    lines = [
        f"{'target':<14}{'resets':>8}{'steps':>7}{'start MB':>10}{'end MB':>9}{'peak MB':>9}"
        f"{'MB/1000':>9}{'steepest MB/1000':>18}{'full GCs':>10}{'time s':>8}",
        "-" * 102,
    ]
    for r in rows:
        lines.append(
            f"{r['target']:<14}{r['resets']:>8}{r['steps']:>7}{r['start_mb']:>10.1f}{r['end_mb']:>9.1f}{r['peak_mb']:>9.1f}"
            f"{r['per_1000_mb']:>9.2f}{r['steepest_per_1000_mb']:>18.2f}{r['full_collections']:>10}{r['seconds']:>8.0f}"
        )
    lines.append(
        "(resident set size, each target in a fresh process; start: after the first episode; MB/1000: growth per "
        "1,000 resets over the run; steepest: between two samples after the first; full GCs: full garbage "
        f"collections during the run; {os.cpu_count()} cores)"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Resident memory over many resets of short episodes.")
    parser.add_argument("--resets", type=int, default=20_000, help="episodes per target (default 20000)")
    parser.add_argument("--steps", type=int, default=20, help="steps per episode (default 20)")
    parser.add_argument("--every", type=int, default=1000, help="resets between two RSS samples (default 1000)")
    parser.add_argument("--targets", nargs="+", choices=TARGETS, default=list(TARGETS), help="what to measure (default all)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args(argv)
    if args.resets < 2:
        parser.error("--resets must be >= 2")
    if args.steps < 0:
        parser.error("--steps must be >= 0")
    if args.every < 1:
        parser.error("--every must be >= 1")
    rows = [in_fresh_process(reset_memory, target, args.resets, args.steps, args.every) for target in args.targets]
    print(json.dumps(rows, indent=2) if args.json else format_reset_memory(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
