"""Repeated seeded runs of a leapfrog experiment, with a line of progress per run.

Run k uses seed ``seed + k``, so any run of a table can be re-run on its own.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from training.experiments.leapfrog_run import LeapfrogConfig, LeapfrogRun, run_leapfrog

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


def run_many(config: LeapfrogConfig, n_runs: int, seed: int, log: Callable[[str], None] | None = None) -> list[LeapfrogRun]:
    """``n_runs`` runs of ``config`` with seeds ``seed .. seed + n_runs - 1``; ``log`` gets one line per run."""
    if n_runs < 1:
        raise ValueError(f"n_runs must be >= 1, got {n_runs}")
    runs = []
    for k in range(n_runs):
        run = run_leapfrog(config, seed + k)
        runs.append(run)
        if log is not None:
            log(f"run {k + 1}/{n_runs} {describe_run(run)}")
    return runs
