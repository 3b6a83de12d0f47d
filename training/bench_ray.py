"""Throughput on one machine with 1 and 2 workers, in one run (``python -m training.bench_ray``).

Rows:

* **sweep, local**: ``moma-env sweep --backend local --jobs J`` (episodes/s), J = 1, 2;
* **sweep, ray**: the same cells as Ray tasks on a local Ray of ``num_cpus = J`` (episodes/s;
  Ray's start-up is reported apart, not counted);
* **sweep driver**: what a task ships (pickled arguments, bytes), what it returns
  (pickled rows, bytes per cell of a 2- and a 6-UGV team) and the driver's cost of
  storing one finished task of 8 cells (ms, median of 25, an ``fsync`` each);
* **rllib sampling**: env steps/s of RLlib's remote env runners sampling with the PPO
  module (``num_env_runners = J``, ``envs`` copies each), for both routes (``pettingzoo``:
  RLlib's PettingZoo wrapper, copies stepped one by one; ``vector``: the batched env).

Every row times only its work after a warm-up (the first task of each worker compiles
nothing: numba caches to disk, but it imports the project). Numbers depend on the
machine and on what else runs on it: say which.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["sweep_rows", "rllib_rows", "driver_row", "run", "format_rows", "main"]


def _spec(episodes: int, max_cycles: int | None):
    from training.sweep.spec import SweepSpec

    return SweepSpec(scenarios=("top_observer",), policies=("scripted",), seeds=tuple(range(episodes)), max_cycles=max_cycles)


def sweep_rows(episodes: int, workers: Sequence[int], max_cycles: int | None = None) -> list[dict[str, Any]]:
    """Episodes/s of the same sweep on the local pool and on Ray, per worker count."""
    import ray

    from training.sweep.backends import LocalBackend, RayBackend
    from training.sweep.run import sweep

    rows = []
    spec = _spec(episodes, max_cycles)
    with tempfile.TemporaryDirectory() as tmp:
        warm = _spec(2, max_cycles)
        sweep(warm, Path(tmp) / "warm", LocalBackend(1))  # imports and numba caches
        for jobs in workers:
            report = sweep(spec, Path(tmp) / f"local_{jobs}", LocalBackend(jobs), cells_per_task=2)
            rows.append({"row": "sweep", "backend": "local", "workers": jobs, "episodes": report.n_run,
                         "wall_s": report.wall_time_s, "episodes_per_s": report.episodes_per_s})
        for jobs in workers:
            start = time.perf_counter()
            ray.init(num_cpus=jobs, include_dashboard=False, log_to_driver=False)
            startup = time.perf_counter() - start
            try:
                sweep(warm, Path(tmp) / f"warm_ray_{jobs}", RayBackend(), cells_per_task=1)  # start the workers
                report = sweep(spec, Path(tmp) / f"ray_{jobs}", RayBackend(), cells_per_task=2)
            finally:
                ray.shutdown()
            rows.append({"row": "sweep", "backend": "ray", "workers": jobs, "episodes": report.n_run, "wall_s": report.wall_time_s,
                         "episodes_per_s": report.episodes_per_s, "ray_startup_s": startup})
    return rows


def driver_row(cells_per_task: int = 8, tasks: int = 25) -> dict[str, Any]:
    """Bytes shipped to and from a sweep task, and the driver's time to store one task's rows."""
    import pickle
    import statistics

    from training.sweep.cells import run_cell
    from training.sweep.folder import SweepFolder
    from training.sweep.spec import SweepSpec

    spec = SweepSpec(scenarios=("top_observer", "top_observer_team6"), policies=("scripted",), seeds=(0,), max_cycles=50)
    cells = spec.cells()
    rows = [run_cell(cell, spec.options) for cell in cells]
    big = SweepSpec(scenarios=("top_observer",), policies=("scripted",), seeds=tuple(range(cells_per_task * tasks)))
    times = []
    with tempfile.TemporaryDirectory() as tmp, SweepFolder(Path(tmp) / "s", big) as folder:
        every = big.cells()
        for k in range(0, len(every), cells_per_task):
            task = every[k:k + cells_per_task]
            task_rows = [dict(rows[0], seed=cell.seed) for cell in task]
            start = time.perf_counter()
            folder.write_rows(task, task_rows)
            times.append(time.perf_counter() - start)
    return {"row": "sweep_driver", "task_args_bytes": len(pickle.dumps((cells[:2], spec.options))),
            "row_bytes_2_ugvs": len(pickle.dumps(rows[0])), "row_bytes_6_ugvs": len(pickle.dumps(rows[1])),
            "cells_per_task": cells_per_task, "store_task_ms": 1e3 * statistics.median(times)}


def _sample(runner: Any, steps: int) -> int:
    episodes = runner.sample(num_timesteps=steps, random_actions=False)
    return int(sum(e.env_steps() for e in episodes))


def rllib_rows(steps: int, workers: Sequence[int], envs: int, routes: Sequence[str], max_cycles: int = 200) -> list[dict[str, Any]]:
    """Env steps/s of RLlib's remote env runners (PPO module, switching mode, masks), per route and runner count."""
    import ray

    from moma_env.integrations.rllib import ppo_config

    rows = []
    options = {"max_cycles": max_cycles, "observer_agent": False, "random_scenarios": True}
    for route in routes:
        for n in workers:
            ray.init(num_cpus=n + 1, include_dashboard=False, log_to_driver=False)
            try:
                algo = ppo_config("top_observer", options, route=route, num_env_runners=n, num_envs_per_env_runner=envs,
                                  rollout_fragment_length=64, train_batch_size=64 * envs * n, minibatch_size=64).build_algo()
                try:
                    group = algo.env_runner_group
                    group.foreach_env_runner(lambda r: _sample(r, 64 * envs), local_env_runner=False)  # warm-up
                    start = time.perf_counter()
                    counts = group.foreach_env_runner(lambda r: _sample(r, steps), local_env_runner=False)
                    wall = time.perf_counter() - start
                finally:
                    algo.stop()
            finally:
                ray.shutdown()
            total = int(sum(counts))
            rows.append({"row": "rllib_sampling", "route": route, "workers": n, "envs_per_runner": envs, "env_steps": total,
                         "wall_s": wall, "env_steps_per_s": total / wall})
    return rows


def run(episodes: int, steps: int, workers: Sequence[int] = (1, 2), envs: int = 4, routes: Sequence[str] = ("pettingzoo", "vector"),
        max_cycles: int | None = None) -> dict[str, Any]:
    """Every row, with the machine's description."""
    import platform

    import ray

    rows = sweep_rows(episodes, workers, max_cycles) + [driver_row()] + rllib_rows(steps, workers, envs, routes)
    return {"cpus": os.cpu_count(), "python": platform.python_version(), "ray": ray.__version__, "rows": rows}


def format_rows(result: dict[str, Any]) -> str:
    """The rows as a Markdown table."""
    lines = [f"{result['cpus']} CPUs, Python {result['python']}, Ray {result['ray']}", "",
             "| row | backend / route | workers | work | wall s | throughput |", "|---|---|---|---|---|---|"]
    for r in result["rows"]:
        if r["row"] == "sweep_driver":
            lines.append(f"| sweep driver | - | - | a task ships {r['task_args_bytes']} B (2 cells), returns {r['row_bytes_2_ugvs']} B "
                         f"(2 UGVs) / {r['row_bytes_6_ugvs']} B (6 UGVs) per cell | - | storing a task of {r['cells_per_task']} cells: "
                         f"{r['store_task_ms']:.1f} ms |")
        elif r["row"] == "sweep":
            extra = f" (Ray start {r['ray_startup_s']:.1f} s, not counted)" if "ray_startup_s" in r else ""
            lines.append(f"| sweep | {r['backend']} | {r['workers']} | {r['episodes']} episodes | {r['wall_s']:.2f} | "
                         f"{r['episodes_per_s']:.2f} episodes/s{extra} |")
        else:
            lines.append(f"| RLlib sampling | {r['route']} | {r['workers']} x {r['envs_per_runner']} envs | {r['env_steps']} env steps | "
                         f"{r['wall_s']:.2f} | {r['env_steps_per_s']:.0f} env steps/s |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m training.bench_ray", description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=16, help="sweep cells per row (top_observer, scripted; default 16)")
    parser.add_argument("--steps", type=int, default=2000, help="env steps each env runner samples per row (default 2000)")
    parser.add_argument("--envs", type=int, default=4, help="env copies per env runner (default 4)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.steps < 1 or args.envs < 1:
        print("python -m training.bench_ray: --episodes, --steps and --envs must be >= 1", file=sys.stderr)
        return 2
    result = run(args.episodes, args.steps, envs=args.envs)
    print(json.dumps(result, indent=2) if args.json else format_rows(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
