"""Accuracy metrics of estimated trajectories (paper section IV) and TUM export.

* :mod:`.trajectory`: :class:`Trajectory` (timestamped ``T_w_b`` poses, NaN for
  unknown samples) and :class:`TrajectoryRecorder`.
* :mod:`.errors`: per-sample errors E(t) and heading errors at the truth's
  timestamps, errors at keypoints, APE/RPE statistics, keypoint relative errors.
* :mod:`.summary`: :class:`RunMetrics` (ME, E_f, % of path, ...) and
  :class:`AggregateMetrics` over repeated runs (ME_f and its std, failures).
* :mod:`.tum`: TUM text format (``timestamp tx ty tz qx qy qz qw``) for evo.
* :mod:`.tum_covariance`: the pose covariances beside a TUM file (``.cov.txt``).
* :mod:`.consistency`: NEES of an estimate against its covariance, its average
  over runs and the chi-square bounds (is the estimator honest?).

This package is the computational core only; command-line tools live elsewhere.
"""

from moma_env.metrics.consistency import NeesAverage, average_nees, chi2_bounds, nees, pose_errors, trajectory_nees
from moma_env.metrics.errors import (
    DEFAULT_MAX_DT,
    ErrorStats,
    ape_translation,
    associate,
    error_stats,
    errors_at_times,
    heading_errors,
    matched_estimate,
    nearest_valid_indices,
    position_errors,
    relative_errors,
    rpe_translation,
)
from moma_env.metrics.summary import AggregateMetrics, RunMetrics, aggregate, run_metrics
from moma_env.metrics.trajectory import Trajectory, TrajectoryRecorder
from moma_env.metrics.tum import TUM_HEADER, format_tum, quaternions_to_matrices, read_tum, write_tum
from moma_env.metrics.tum_covariance import (
    COVARIANCE_HEADER,
    covariance_path_for,
    format_covariances,
    read_covariances,
    read_tum_with_covariances,
    write_covariances,
)

__all__ = [
    "DEFAULT_MAX_DT",
    "ErrorStats",
    "ape_translation",
    "associate",
    "error_stats",
    "errors_at_times",
    "heading_errors",
    "matched_estimate",
    "nearest_valid_indices",
    "position_errors",
    "relative_errors",
    "rpe_translation",
    "AggregateMetrics",
    "RunMetrics",
    "aggregate",
    "run_metrics",
    "Trajectory",
    "TrajectoryRecorder",
    "TUM_HEADER",
    "format_tum",
    "quaternions_to_matrices",
    "read_tum",
    "write_tum",
    "COVARIANCE_HEADER",
    "covariance_path_for",
    "format_covariances",
    "read_covariances",
    "read_tum_with_covariances",
    "write_covariances",
    "NeesAverage",
    "average_nees",
    "chi2_bounds",
    "nees",
    "pose_errors",
    "trajectory_nees",
]
