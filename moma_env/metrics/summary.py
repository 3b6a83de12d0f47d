"""Per-run and across-run metrics of the paper's section IV.

Per run (:func:`run_metrics`): the mean error ME over the trajectory, the final
error E_f, E_f as a percentage of the path length, heading errors, the errors
at the switch instants (keypoints). Across runs (:func:`aggregate`): ME_f, the
mean of E_f, with its standard deviation, the mean of ME, best and worst cases,
and the number of failed runs. Distances are in metres, angles of the summaries
in degrees, times in seconds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from moma_env.config import check_positive
from moma_env.metrics.errors import (
    DEFAULT_MAX_DT,
    heading_errors,
    nearest_valid_indices,
    position_errors,
)
from moma_env.metrics.trajectory import Trajectory

__all__ = ["RunMetrics", "run_metrics", "AggregateMetrics", "aggregate"]


@dataclass(frozen=True)
class RunMetrics:
    """Accuracy of one estimated trajectory against its ground truth.

    Errors are planar position errors E(t) (m) at the truth's timestamps (see
    :mod:`moma_env.metrics.errors` for the association). Statistics over the
    trajectory use the *evaluable* samples: valid truth and valid estimate.

    Attributes:
        mean_error: ME, mean of E over evaluable samples (m); NaN if none.
        final_error: E_f, E at the last valid truth sample (m); NaN if the
            estimate is unknown there (the run counts as failed).
        max_error: largest E (m).
        rmse: root mean square of E (m).
        path_length: path length (m) used for the percentage: the truth's
            planar path length unless given to :func:`run_metrics`.
        final_error_pct_path: ``100 * final_error / path_length`` (%); NaN if
            the path length is 0.
        mean_heading_error_deg: mean absolute wrapped yaw error (deg).
        final_heading_error_deg: yaw error at the last valid truth sample (deg).
        switch_times: the switch instants (s) evaluated.
        errors_at_switches: E (m) at the valid truth sample nearest each switch
            instant.
        valid_fraction: evaluable samples / valid truth samples, in [0, 1].
        n_samples: number of valid truth samples.
    """

    mean_error: float
    final_error: float
    max_error: float
    rmse: float
    path_length: float
    final_error_pct_path: float
    mean_heading_error_deg: float
    final_heading_error_deg: float
    switch_times: tuple[float, ...]
    errors_at_switches: tuple[float, ...]
    valid_fraction: float
    n_samples: int

    @property
    def failed(self) -> bool:
        """True when the final error is unknown (the estimate was lost at the end)."""
        return not math.isfinite(self.final_error)

    def to_dict(self) -> dict[str, object]:
        """Plain mapping for JSON (tuples become lists; NaN stays float NaN)."""
        d = asdict(self)
        d["switch_times"] = list(self.switch_times)
        d["errors_at_switches"] = list(self.errors_at_switches)
        d["failed"] = self.failed
        return d


def _mean_or_nan(values: np.ndarray) -> float:
    return float(values.mean()) if values.shape[0] else math.nan


def run_metrics(
    estimate: Trajectory,
    truth: Trajectory,
    switch_times: Sequence[float] | np.ndarray = (),
    path_length: float | None = None,
    max_dt: float = DEFAULT_MAX_DT,
) -> RunMetrics:
    """Metrics of one run: ``estimate`` against ``truth`` (both ``T_w_b`` trajectories).

    Args:
        estimate: the estimated trajectory (invalid samples allowed).
        truth: the ground truth; needs at least one valid sample.
        switch_times: instants (s) of the reference switches / keypoints; each
            must lie within the truth's valid time span.
        path_length: path length (m) for the percentage; defaults to the
            truth's planar path length (e.g. pass 4.0 for the paper's square).
        max_dt: association tolerance (s), see :mod:`moma_env.metrics.errors`.

    Raises:
        ValueError: the truth has no valid sample, a switch time outside the
            truth's span, or a non-positive ``path_length``
            (:class:`moma_env.config.ConfigError`, a ValueError).
    """
    valid_truth = truth.valid
    if not valid_truth.any():
        raise ValueError("run_metrics needs a truth trajectory with at least one valid sample")
    if path_length is None:
        length = truth.path_length()
    else:
        check_positive("path_length", path_length)
        length = float(path_length)
    switches = tuple(float(t) for t in np.asarray(switch_times, dtype=float).reshape(-1))
    errors = position_errors(estimate, truth, max_dt)
    yaw_errors_deg = np.degrees(heading_errors(estimate, truth, max_dt))
    last = int(np.flatnonzero(valid_truth)[-1])
    evaluable = np.isfinite(errors)
    e = errors[evaluable]
    final = float(errors[last])
    return RunMetrics(
        mean_error=_mean_or_nan(e),
        final_error=final,
        max_error=float(e.max()) if e.shape[0] else math.nan,
        rmse=math.sqrt(_mean_or_nan(e * e)),
        path_length=length,
        final_error_pct_path=100.0 * final / length if length > 0.0 else math.nan,
        mean_heading_error_deg=_mean_or_nan(yaw_errors_deg[evaluable]),
        final_heading_error_deg=float(yaw_errors_deg[last]),
        switch_times=switches,
        errors_at_switches=tuple(float(v) for v in errors[nearest_valid_indices(truth, switches)]),
        valid_fraction=float(evaluable.sum()) / float(valid_truth.sum()),
        n_samples=int(valid_truth.sum()),
    )


@dataclass(frozen=True)
class AggregateMetrics:
    """Statistics over repeated runs, as the paper reports them.

    As in the paper ("this only includes the cases where Viso2 didn't lose
    track"), every statistic is taken over the *successful* runs, those with a
    finite final error; the others are counted in ``n_failed``. Standard
    deviations use ``ddof`` (1: sample standard deviation, the default, since
    the runs are a sample of the possible runs; the paper does not say which it
    used); with fewer than ``ddof + 1`` successful runs they are NaN.

    Attributes:
        n_runs: number of runs.
        n_failed: runs whose final error is NaN.
        mean_final_error: ME_f, mean of E_f (m).
        std_final_error: standard deviation of E_f (m).
        mean_mean_error: mean of the runs' ME (m).
        std_mean_error: standard deviation of the runs' ME (m).
        mean_final_error_pct_path: mean of E_f as % of each run's path length.
        best_final_error, worst_final_error: smallest and largest E_f (m).
        best_final_error_pct_path, worst_final_error_pct_path: smallest and
            largest E_f in % of path length.
        ddof: delta degrees of freedom of the standard deviations.
    """

    n_runs: int
    n_failed: int
    mean_final_error: float
    std_final_error: float
    mean_mean_error: float
    std_mean_error: float
    mean_final_error_pct_path: float
    best_final_error: float
    worst_final_error: float
    best_final_error_pct_path: float
    worst_final_error_pct_path: float
    ddof: int

    @property
    def failure_fraction(self) -> float:
        """Fraction of runs that failed, in [0, 1]."""
        return self.n_failed / self.n_runs

    def to_dict(self) -> dict[str, object]:
        """Plain mapping for JSON (NaN stays float NaN)."""
        d = asdict(self)
        d["failure_fraction"] = self.failure_fraction
        return d


def _std(values: np.ndarray, ddof: int) -> float:
    return float(values.std(ddof=ddof)) if values.shape[0] > ddof else math.nan


def aggregate(runs: Sequence[RunMetrics], ddof: int = 1) -> AggregateMetrics:
    """Summarise repeated runs (see :class:`AggregateMetrics`).

    Raises:
        ValueError: no runs, or ``ddof`` not 0 or 1.
    """
    runs = list(runs)
    if not runs:
        raise ValueError("aggregate needs at least one run")
    if ddof not in (0, 1):
        raise ValueError(f"ddof must be 0 (population) or 1 (sample), got {ddof!r}")
    ok = [r for r in runs if not r.failed]
    final = np.array([r.final_error for r in ok], dtype=float)
    mean = np.array([r.mean_error for r in ok], dtype=float)
    pct = np.array([r.final_error_pct_path for r in ok], dtype=float)
    pct = pct[np.isfinite(pct)]
    return AggregateMetrics(
        n_runs=len(runs),
        n_failed=len(runs) - len(ok),
        mean_final_error=_mean_or_nan(final),
        std_final_error=_std(final, ddof),
        mean_mean_error=_mean_or_nan(mean),
        std_mean_error=_std(mean, ddof),
        mean_final_error_pct_path=_mean_or_nan(pct),
        best_final_error=float(final.min()) if final.shape[0] else math.nan,
        worst_final_error=float(final.max()) if final.shape[0] else math.nan,
        best_final_error_pct_path=float(pct.min()) if pct.shape[0] else math.nan,
        worst_final_error_pct_path=float(pct.max()) if pct.shape[0] else math.nan,
        ddof=ddof,
    )
