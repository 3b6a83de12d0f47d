"""Per-sample errors of an estimated trajectory against the ground truth.

The paper (section IV) defines the error ``E(t)`` as the Euclidean distance
between the estimated and the true position; the simulator is planar, so here
``E`` is measured in the floor plane (x, y of the world frame W), in metres.

Association (used by every function here): errors are evaluated **at the
truth's timestamps**. For each truth sample the estimate sample nearest in time
is used if it lies within ``max_dt`` seconds (ties go to the earlier sample);
otherwise, or if that estimate sample is invalid, the error is NaN. The default
``max_dt`` (1 microsecond) amounts to requiring equal timestamps while
tolerating float round-off (e.g. a TUM round trip); pass half the estimator's
sample period to compare trajectories sampled at different rates. A NaN
error also results where the truth itself is invalid. No alignment is applied:
MOMA and the odometry baselines start from the known initial pose, as in the
paper.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from moma_env.geometry import wrap_angle
from moma_env.metrics.trajectory import Trajectory

__all__ = [
    "DEFAULT_MAX_DT",
    "ErrorStats",
    "associate",
    "matched_estimate",
    "position_errors",
    "heading_errors",
    "nearest_valid_indices",
    "errors_at_times",
    "error_stats",
    "ape_translation",
    "rpe_translation",
    "relative_errors",
]

#: Default association tolerance (s): equal timestamps up to float round-off.
DEFAULT_MAX_DT = 1e-6


def _check_max_dt(max_dt: float) -> float:
    max_dt = float(max_dt)
    if not max_dt >= 0.0:
        raise ValueError(f"max_dt must be >= 0 (s), got {max_dt!r}")
    return max_dt


def associate(reference_times: np.ndarray, query_times: np.ndarray, max_dt: float = DEFAULT_MAX_DT) -> np.ndarray:
    """Index into ``query_times`` of the sample nearest each reference time.

    Both arrays are sorted increasing (s). Returns an ``(n_reference,)`` int
    array; ``-1`` where no query time lies within ``max_dt`` (s). Ties go to
    the earlier query sample. A query sample may be matched to several
    reference samples when ``max_dt`` exceeds half the reference period.
    """
    max_dt = _check_max_dt(max_dt)
    ref = np.asarray(reference_times, dtype=float)
    query = np.asarray(query_times, dtype=float)
    if query.shape[0] == 0:
        return np.full(ref.shape[0], -1, dtype=np.intp)
    right = np.searchsorted(query, ref, side="left").clip(0, query.shape[0] - 1)
    left = (right - 1).clip(0, None)
    take_left = np.abs(ref - query[left]) <= np.abs(query[right] - ref)
    nearest = np.where(take_left, left, right)
    nearest[np.abs(query[nearest] - ref) > max_dt] = -1
    return nearest


def matched_estimate(estimate: Trajectory, truth: Trajectory, max_dt: float = DEFAULT_MAX_DT) -> np.ndarray:
    """``(n_truth, 4, 4)`` estimate poses at the truth's timestamps; NaN where unmatched or invalid.

    Raises:
        ValueError: both trajectories have samples but no truth time has an
            estimate sample within ``max_dt`` (a time-base mismatch, e.g. steps
            against seconds, rather than a failed estimator, which reports
            invalid samples at matching times).
    """
    index = associate(truth.times, estimate.times, max_dt)
    matched = index >= 0
    if len(estimate) and len(truth) and not matched.any():
        raise ValueError(
            f"no estimate sample lies within max_dt={max_dt} s of any truth sample "
            f"(estimate spans [{estimate.times[0]}, {estimate.times[-1]}] s, "
            f"truth spans [{truth.times[0]}, {truth.times[-1]}] s)"
        )
    poses = np.full((len(truth), 4, 4), np.nan)
    poses[matched] = estimate.poses[index[matched]]
    return poses


def position_errors(estimate: Trajectory, truth: Trajectory, max_dt: float = DEFAULT_MAX_DT) -> np.ndarray:
    """``(n_truth,)`` planar position errors E(t) (m) at the truth's timestamps; NaN if unknown."""
    est = matched_estimate(estimate, truth, max_dt)
    return np.hypot(est[:, 0, 3] - truth.poses[:, 0, 3], est[:, 1, 3] - truth.poses[:, 1, 3])


def heading_errors(estimate: Trajectory, truth: Trajectory, max_dt: float = DEFAULT_MAX_DT) -> np.ndarray:
    """``(n_truth,)`` absolute wrapped yaw errors (rad, in [0, pi]) at the truth's timestamps; NaN if unknown."""
    est = matched_estimate(estimate, truth, max_dt)
    est_yaw = np.arctan2(est[:, 1, 0], est[:, 0, 0])
    return np.abs(wrap_angle(est_yaw - truth.yaw))


def nearest_valid_indices(truth: Trajectory, times: Sequence[float] | np.ndarray) -> np.ndarray:
    """Index of the valid truth sample nearest each of ``times`` (s); ties go to the earlier one.

    Raises:
        ValueError: a time is not finite or lies outside the time span of the
            truth's valid samples (likely a unit or time-base mistake), or the
            truth has no valid sample.
    """
    t = np.asarray(times, dtype=float).reshape(-1)
    if t.shape[0] == 0:
        return np.empty(0, dtype=np.intp)
    valid_index = np.flatnonzero(truth.valid)
    if valid_index.shape[0] == 0:
        raise ValueError("the truth has no valid sample to evaluate errors at")
    valid_times = truth.times[valid_index]
    bad = ~np.isfinite(t) | (t < valid_times[0]) | (t > valid_times[-1])
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(
            f"time {t[k]!r} s (entry {k}) is outside the truth's valid time span "
            f"[{valid_times[0]!r}, {valid_times[-1]!r}] s"
        )
    return valid_index[associate(t, valid_times, max_dt=math.inf)]


def errors_at_times(
    estimate: Trajectory,
    truth: Trajectory,
    times: Sequence[float] | np.ndarray,
    max_dt: float = DEFAULT_MAX_DT,
) -> np.ndarray:
    """Planar position error E (m) at the valid truth sample nearest each of ``times`` (s).

    Used for the errors at switch instants / keypoints. NaN where the estimate
    is unknown at that sample. See :func:`nearest_valid_indices` for errors.
    """
    index = nearest_valid_indices(truth, times)
    return position_errors(estimate, truth, max_dt)[index]


@dataclass(frozen=True)
class ErrorStats:
    """Summary of a set of errors over its finite values (units of the errors).

    ``n`` counts the finite values; the statistics are NaN when ``n == 0``.
    ``std`` is the population standard deviation (as evo reports it).
    """

    n: int
    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float

    def to_dict(self) -> dict[str, float | int]:
        """Plain mapping for JSON."""
        return asdict(self)


def error_stats(errors: Sequence[float] | np.ndarray) -> ErrorStats:
    """:class:`ErrorStats` of the finite entries of ``errors``."""
    e = np.asarray(errors, dtype=float).reshape(-1)
    e = e[np.isfinite(e)]
    if e.shape[0] == 0:
        nan = math.nan
        return ErrorStats(0, nan, nan, nan, nan, nan, nan)
    return ErrorStats(
        n=int(e.shape[0]),
        rmse=float(np.sqrt(np.mean(e * e))),
        mean=float(e.mean()),
        median=float(np.median(e)),
        std=float(e.std()),
        min=float(e.min()),
        max=float(e.max()),
    )


def ape_translation(
    estimate: Trajectory, truth: Trajectory, planar: bool = True, max_dt: float = DEFAULT_MAX_DT
) -> ErrorStats:
    """Absolute position error statistics (m), without alignment.

    ``planar=True`` uses the x-y error E(t) of the paper; ``planar=False`` the
    full 3D translation error (as evo's APE, translation part, without
    alignment).
    """
    if planar:
        return error_stats(position_errors(estimate, truth, max_dt))
    est = matched_estimate(estimate, truth, max_dt)
    return error_stats(np.linalg.norm(est[:, :3, 3] - truth.positions, axis=1))


def _planarised(poses: np.ndarray) -> np.ndarray:
    """Project a stack of poses onto SE(2) (x, y, yaw), as 4x4 poses at z = 0."""
    yaw = np.arctan2(poses[:, 1, 0], poses[:, 0, 0])
    out = np.zeros_like(poses)
    c, s = np.cos(yaw), np.sin(yaw)
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s, s, c
    out[:, 2, 2] = 1.0
    out[:, 3, 3] = 1.0
    out[:, :2, 3] = poses[:, :2, 3]
    return out


def _relative(poses: np.ndarray, delta: int) -> np.ndarray:
    """``inv(T_i) @ T_{i+delta}`` for every i, for a stack of rigid poses."""
    a, b = poses[:-delta], poses[delta:]
    Ra_t = np.transpose(a[:, :3, :3], (0, 2, 1))
    rel = np.zeros_like(a)
    rel[:, :3, :3] = Ra_t @ b[:, :3, :3]
    rel[:, :3, 3] = np.einsum("nij,nj->ni", Ra_t, b[:, :3, 3] - a[:, :3, 3])
    rel[:, 3, 3] = 1.0
    return rel


def rpe_translation(
    estimate: Trajectory,
    truth: Trajectory,
    delta: int = 1,
    planar: bool = True,
    max_dt: float = DEFAULT_MAX_DT,
) -> ErrorStats:
    """Relative pose error statistics, translation part (m), over ``delta`` truth samples.

    For each pair of truth samples ``(i, i + delta)`` where both truth and
    matched estimate are valid, the error is the translation norm of
    ``inv(inv(G_i) G_j) @ inv(P_i) P_j`` (truth poses G, estimated poses P), as
    in evo's RPE. ``planar=True`` first projects both onto SE(2).
    """
    if int(delta) != delta or delta < 1:
        raise ValueError(f"delta must be a positive number of samples, got {delta!r}")
    delta = int(delta)
    est = matched_estimate(estimate, truth, max_dt)
    gt = np.asarray(truth.poses)
    if gt.shape[0] <= delta:
        return error_stats(())
    if planar:
        est, gt = _planarised(est), _planarised(gt)
    rel_gt = _relative(gt, delta)
    rel_est = _relative(est, delta)
    # inv(rel_gt) @ rel_est, translation only: R_gt^T (t_est - t_gt)
    diff = np.einsum("nji,nj->ni", rel_gt[:, :3, :3], rel_est[:, :3, 3] - rel_gt[:, :3, 3])
    return error_stats(np.linalg.norm(diff, axis=1))


def relative_errors(
    estimate: Trajectory,
    truth: Trajectory,
    keypoint_times: Sequence[float] | np.ndarray,
    max_dt: float = DEFAULT_MAX_DT,
) -> np.ndarray:
    """Errors (m) in the distance travelled between consecutive keypoints.

    The paper's line experiment ("the error in estimating the distance between
    keypoints"): for keypoints k and k+1 (taken at the valid truth sample
    nearest each keypoint time), ``| |p_est(k+1) - p_est(k)| - |p_true(k+1) -
    p_true(k)| |`` with planar distances. Returns ``(n_keypoints - 1,)``
    values; NaN where the estimate is unknown at either keypoint.

    Raises:
        ValueError: keypoint times not strictly increasing, or see
            :func:`nearest_valid_indices`.
    """
    t = np.asarray(keypoint_times, dtype=float).reshape(-1)
    if t.shape[0] > 1 and not (np.diff(t) > 0.0).all():
        raise ValueError("keypoint_times must be strictly increasing")
    if t.shape[0] < 2:
        return np.empty(0)
    index = nearest_valid_indices(truth, t)
    est_xy = matched_estimate(estimate, truth, max_dt)[index, :2, 3]
    true_xy = truth.xy[index]
    d_est = np.hypot(*np.diff(est_xy, axis=0).T)
    d_true = np.hypot(*np.diff(true_xy, axis=0).T)
    return np.abs(d_est - d_true)
