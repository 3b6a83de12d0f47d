"""Repeated seeded runs of a leapfrog experiment, with a line of progress per run.

Run k uses seed ``seed + k``, so any run of a table can be re-run on its own.
Runs are independent, so they can go to several worker processes (``jobs``);
every run draws only from its own seeded generators, so the results are the
same bit for bit whatever the number of jobs, and come back in seed order.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

from moma_env.vector.parent_watch import worker_pool
from training.experiments.leapfrog_run import CameraFactory, LeapfrogConfig, LeapfrogRun, run_leapfrog, run_leapfrog_recorded

__all__ = ["run_many", "describe_run"]


def describe_run(run: LeapfrogRun) -> str:
    """One line: completion, simulated time and each method's final error (cm) or track loss."""
    parts = []
    for method in run.methods:
        final = run.metrics[method].final_error
        text = f"{method} E_f {100 * final:.2f} cm" if math.isfinite(final) else f"{method} E_f n/a"
        if run.lost_at[method] is not None:
            text += f" (lost track at {run.lost_at[method]:.1f} s)"
        parts.append(text)
    status = "done" if run.completed else "NOT COMPLETED"
    return f"seed {run.seed}: {status} in {run.duration_s:.1f} s sim, " + ", ".join(parts)


def run_many(
    config: LeapfrogConfig,
    n_runs: int,
    seed: int,
    log: Callable[[str], None] | None = None,
    jobs: int = 1,
    camera_factory: CameraFactory | None = None,
    detection_logs: list[str] | None = None,
) -> list[LeapfrogRun]:
    """``n_runs`` runs of ``config`` with seeds ``seed .. seed + n_runs - 1``, in seed order.

    Args:
        config: the experiment.
        n_runs: number of runs (>= 1).
        seed: seed of the first run.
        log: gets one line per finished run.
        jobs: worker processes (>= 1); 1 runs in this process. The workers
            (:func:`~moma_env.vector.parent_watch.worker_pool`) end with this process.
        camera_factory: the observer's camera (see :func:`run_leapfrog`); with
            ``jobs > 1`` it must be picklable (a module-level function).
        detection_logs: when given, each run's detection log (the file's text,
            :func:`run_leapfrog_recorded`) is appended to it, in seed order; the runs are
            the same.
    """
    if n_runs < 1:
        raise ValueError(f"n_runs must be >= 1, got {n_runs}")
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    seeds = [seed + k for k in range(n_runs)]
    runs = []

    recording = detection_logs is not None

    def done(result: LeapfrogRun | tuple[LeapfrogRun, str]) -> None:
        if recording:
            run, text = result
            detection_logs.append(text)
        else:
            run = result
        runs.append(run)
        if log is not None:
            log(f"run {len(runs)}/{n_runs} {describe_run(run)}")

    one_run = partial(run_leapfrog_recorded if recording else run_leapfrog, camera_factory=camera_factory)
    if jobs == 1 or n_runs == 1:
        for s in seeds:
            done(one_run(config, s))
    else:
        with worker_pool(min(jobs, n_runs)) as pool:
            for run in pool.map(one_run, [config] * n_runs, seeds):
                done(run)
    return runs
