"""Is an estimator honest about its uncertainty? NEES, its average over runs, chi-square bounds.

Errors follow the covariance convention of :mod:`moma_env.estimator.uncertainty`
(a ROS ``PoseWithCovariance``): the error of an estimate ``T_w_b = [R, t]`` is
``e = (dt, dtheta)`` with ``T_true = [exp([dtheta]x) R, t + dt]``: translation
(m) additive in the world frame W, rotation (rad) perturbed on the left, about
W's axes; the estimate's covariance is that of ``e`` (6x6, translation first).

* Position: ``dt[:2]`` (2 dof, robots constrained upright on the floor, whose
  z variance is zero) or ``dt`` (3 dof, full 6-DoF estimates), against the
  matching block of the covariance.
* Heading: ``dtheta[2]``, the rotation about W's z axis (1 dof), against the
  covariance's ``[5, 5]``; for an upright robot it is the wrapped yaw error.

The normalised estimation error squared of one sample is
``NEES = e^T P^-1 e`` over the chosen ``d`` components; for a consistent
estimator with Gaussian errors it is chi-square with ``d`` dof (mean ``d``). A
sample whose covariance block is singular (smallest eigenvalue not above
``1e-12`` times the largest, e.g. the zero covariance of a pose that defines W)
has no NEES (NaN) and is counted as skipped.

Averaging (:func:`average_nees`): at each time step ``k`` the NEES of the
``N_k`` runs that have one is averaged and divided by ``d``:
``ANEES_k = sum_i NEES_ik / (N_k d)``, mean 1 when consistent. Since
``N_k d ANEES_k`` is chi-square with ``N_k d`` dof, the two-sided
``confidence`` interval of ``ANEES_k`` is ``[chi2.ppf(a, N_k d), chi2.ppf(1 - a,
N_k d)] / (N_k d)`` with ``a = (1 - confidence) / 2``
(:func:`chi2_bounds`). The summary is the mean of ``ANEES_k`` over the time
steps that have one, and the fraction of those steps whose ``ANEES_k`` lies
inside its bounds (about ``confidence`` for a consistent estimator; lower
means under- or over-confident: see ``fraction_above`` and ``fraction_below``).
Samples at different steps of one run are correlated, so the mean over time
has no simple chi-square bound; only the per-step bounds are tested.

This module is the computational core; the experiment and its command line
live in :mod:`training.experiments.consistency`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.geometry import matrix_to_rotvec
from moma_env.metrics.errors import DEFAULT_MAX_DT, associate
from moma_env.metrics.trajectory import Trajectory

__all__ = [
    "SINGULAR_RTOL",
    "POSITION_PLANAR",
    "POSITION_3D",
    "HEADING",
    "pose_errors",
    "matched_covariances",
    "nees",
    "trajectory_nees",
    "chi2_bounds",
    "NeesAverage",
    "average_nees",
]

#: A covariance block is singular if its smallest eigenvalue is not above this times its largest.
SINGULAR_RTOL = 1e-12
#: Error components (indices into ``e = (dx, dy, dz, rx, ry, rz)``) of each NEES.
POSITION_PLANAR = (0, 1)
POSITION_3D = (0, 1, 2)
HEADING = (5,)
#: Below this rotation angle (rad) the log map uses its series (angle / sin(angle) ~ 1).
_SMALL_ANGLE = 1e-6
#: Above this rotation angle (rad) the batched log map is ill-conditioned; the geometry module's is used.
_LARGE_ANGLE = 3.0


def _rotation_logs(R: np.ndarray) -> np.ndarray:
    """``(n, 3)`` rotation vectors (rad) of ``(n, 3, 3)`` rotation matrices (NaN rows stay NaN)."""
    cos = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos)
    v = 0.5 * np.stack((R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(angle < _SMALL_ANGLE, 1.0 + angle * angle / 6.0, angle / np.sin(angle))
    out = v * scale[:, None]
    for k in np.flatnonzero(angle > _LARGE_ANGLE):
        out[k] = matrix_to_rotvec(R[k])
    return out


def pose_errors(estimate: Trajectory, truth: Trajectory, max_dt: float = DEFAULT_MAX_DT) -> np.ndarray:
    """``(n_truth, 6)`` errors ``e = (dt, dtheta)`` of the estimate at the truth's timestamps.

    ``T_true = [exp([dtheta]x) R_est, t_est + dt]``: ``dt`` in m (world frame
    W), ``dtheta`` in rad (about W's axes). Association as in
    :mod:`moma_env.metrics.errors` (the estimate sample nearest each truth time
    within ``max_dt`` s); NaN rows where unmatched or either pose is invalid.
    """
    index = associate(truth.times, estimate.times, max_dt)
    est = np.full((len(truth), 4, 4), np.nan)
    matched = index >= 0
    est[matched] = estimate.poses[index[matched]]
    errors = np.full((len(truth), 6), np.nan)
    known = np.isfinite(est).all(axis=(1, 2)) & truth.valid
    if known.any():
        T_true, T_est = truth.poses[known], est[known]
        errors[known, :3] = T_true[:, :3, 3] - T_est[:, :3, 3]
        errors[known, 3:] = _rotation_logs(T_true[:, :3, :3] @ T_est[:, :3, :3].transpose(0, 2, 1))
    return errors


def matched_covariances(estimate: Trajectory, truth: Trajectory, max_dt: float = DEFAULT_MAX_DT) -> np.ndarray:
    """``(n_truth, 6, 6)`` covariances of the estimate at the truth's timestamps; NaN where unknown.

    Raises:
        ValueError: the estimate carries no covariances.
    """
    if estimate.covariances is None:
        raise ValueError("the estimate carries no covariances (Trajectory.covariances is None)")
    index = associate(truth.times, estimate.times, max_dt)
    out = np.full((len(truth), 6, 6), np.nan)
    matched = index >= 0
    out[matched] = estimate.covariances[index[matched]]
    return out


def _components(components: Sequence[int]) -> np.ndarray:
    idx = np.asarray(components, dtype=int).reshape(-1)
    if idx.shape[0] == 0 or len(set(idx.tolist())) != idx.shape[0] or idx.min() < 0 or idx.max() > 5:
        raise ValueError(f"components must be distinct indices in 0..5, got {list(components)!r}")
    return idx


def nees(errors: np.ndarray, covariances: np.ndarray, components: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """NEES of the ``components`` of ``(n, 6)`` errors against ``(n, 6, 6)`` covariances.

    Returns:
        ``(values, singular)``: ``(n,)`` NEES (dimensionless; NaN where the
        error or the covariance is unknown or the covariance block is
        singular), and an ``(n,)`` bool mask of the samples skipped because
        their (known) covariance block is singular (see :data:`SINGULAR_RTOL`).

    Raises:
        ValueError: shapes that do not match, or bad ``components``.
    """
    idx = _components(components)
    e = np.asarray(errors, dtype=float)
    P = np.asarray(covariances, dtype=float)
    if e.ndim != 2 or e.shape[1] != 6:
        raise ValueError(f"errors must have shape (n, 6), got {e.shape}")
    if P.shape != (e.shape[0], 6, 6):
        raise ValueError(f"covariances must have shape ({e.shape[0]}, 6, 6) to match errors, got {P.shape}")
    e = e[:, idx]
    P = P[:, idx[:, None], idx[None, :]]
    values = np.full(e.shape[0], np.nan)
    known = np.isfinite(e).all(axis=1) & np.isfinite(P).all(axis=(1, 2))
    singular = np.zeros(e.shape[0], dtype=bool)
    if known.any():
        eig = np.linalg.eigvalsh(P[known])
        ok = eig[:, 0] > SINGULAR_RTOL * np.maximum(eig[:, -1], 0.0)
        ok &= eig[:, -1] > 0.0
        rows = np.flatnonzero(known)
        singular[rows[~ok]] = True
        good = rows[ok]
        if good.shape[0]:
            sol = np.linalg.solve(P[good], e[good][:, :, None])[:, :, 0]
            values[good] = np.einsum("ni,ni->n", e[good], sol)
    return values, singular


def trajectory_nees(
    estimate: Trajectory,
    truth: Trajectory,
    components: Sequence[int],
    usable: np.ndarray | None = None,
    max_dt: float = DEFAULT_MAX_DT,
) -> tuple[np.ndarray, np.ndarray]:
    """NEES of ``estimate`` against ``truth`` at the truth's timestamps, for the error ``components``.

    Args:
        estimate: an estimate carrying covariances.
        truth: the ground truth.
        components: indices into ``e = (dx, dy, dz, rx, ry, rz)``, e.g.
            :data:`POSITION_PLANAR`, :data:`POSITION_3D`, :data:`HEADING`.
        usable: optional ``(n_truth,)`` bool mask of the samples to evaluate
            (e.g. those where the estimator said LOCALISED); the others are NaN
            and not counted as singular.
        max_dt: association tolerance (s).

    Returns:
        ``(values, singular)`` as :func:`nees`.

    Raises:
        ValueError: the estimate has no covariances, or ``usable`` has the wrong shape.
    """
    errors = pose_errors(estimate, truth, max_dt)
    covariances = matched_covariances(estimate, truth, max_dt)
    if usable is not None:
        mask = np.asarray(usable, dtype=bool)
        if mask.shape != (len(truth),):
            raise ValueError(f"usable must have shape ({len(truth)},) to match the truth, got {mask.shape}")
        errors = errors.copy()
        errors[~mask] = np.nan
    return nees(errors, covariances, components)


def chi2_bounds(n: int | np.ndarray, dof: int, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided ``confidence`` bounds of the average of ``n`` independent NEES of ``dof`` dof, divided by ``dof``.

    ``(chi2.ppf(a, n dof), chi2.ppf(1 - a, n dof)) / (n dof)`` with
    ``a = (1 - confidence) / 2`` (exact quantiles, from scipy). ``n`` may be an
    array (one bound per entry); entries with ``n < 1`` give NaN.

    Raises:
        ValueError: ``dof`` < 1 or ``confidence`` outside (0, 1).
    """
    from scipy.stats import chi2  # imported here: scipy is slow to import and only this needs it

    if int(dof) != dof or dof < 1:
        raise ValueError(f"dof must be an integer >= 1, got {dof!r}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    k = np.asarray(n, dtype=float) * dof
    a = (1.0 - confidence) / 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        lower = np.where(k >= dof, chi2.ppf(a, np.maximum(k, 1.0)) / k, np.nan)
        upper = np.where(k >= dof, chi2.ppf(1.0 - a, np.maximum(k, 1.0)) / k, np.nan)
    return lower, upper


@dataclass(frozen=True, eq=False)
class NeesAverage:
    """The NEES of ``n_runs`` runs averaged over runs per time step (see the module docstring).

    Attributes:
        dof: degrees of freedom ``d`` of one NEES.
        n_runs: runs averaged.
        confidence: of the bounds (e.g. 0.95).
        times: ``(K,)`` time of each step (s), from the longest run.
        counts: ``(K,)`` runs ``N_k`` with a NEES at each step.
        anees: ``(K,)`` ``ANEES_k`` = mean NEES over those runs / ``d`` (NaN where ``N_k = 0``).
        lower, upper: ``(K,)`` bounds of ``ANEES_k`` (NaN where ``N_k = 0``).
        n_singular: samples (over runs and steps) skipped for a singular covariance.
    """

    dof: int
    n_runs: int
    confidence: float
    times: np.ndarray
    counts: np.ndarray
    anees: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    n_singular: int

    @property
    def steps(self) -> np.ndarray:
        """``(K,)`` mask of the time steps with at least one NEES."""
        return self.counts > 0

    @property
    def n_steps(self) -> int:
        """Time steps with at least one NEES."""
        return int(self.steps.sum())

    @property
    def n_samples(self) -> int:
        """NEES values averaged, over runs and steps."""
        return int(self.counts.sum())

    @property
    def mean_anees(self) -> float:
        """Mean of ``ANEES_k`` over the steps that have one (1 when consistent); NaN if none."""
        return float(self.anees[self.steps].mean()) if self.n_steps else float("nan")

    @property
    def fraction_inside(self) -> float:
        """Fraction of the steps whose ``ANEES_k`` is inside its bounds; NaN if none."""
        s = self.steps
        return float(((self.anees[s] >= self.lower[s]) & (self.anees[s] <= self.upper[s])).mean()) if s.any() else float("nan")

    @property
    def fraction_above(self) -> float:
        """Fraction of the steps above the upper bound (the estimator is over-confident there); NaN if none."""
        s = self.steps
        return float((self.anees[s] > self.upper[s]).mean()) if s.any() else float("nan")

    @property
    def fraction_below(self) -> float:
        """Fraction of the steps below the lower bound (the estimator is too cautious there); NaN if none."""
        s = self.steps
        return float((self.anees[s] < self.lower[s]).mean()) if s.any() else float("nan")

    @property
    def nominal_bounds(self) -> tuple[float, float]:
        """The bounds of ``ANEES_k`` when every run has a NEES at step k (``N_k = n_runs``)."""
        lo, hi = chi2_bounds(self.n_runs, self.dof, self.confidence)
        return float(lo), float(hi)

    def to_dict(self) -> dict[str, object]:
        """The scalar summary, as plain JSON data (the per-step arrays are left out)."""
        lo, hi = self.nominal_bounds
        return {
            "dof": self.dof,
            "n_runs": self.n_runs,
            "confidence": self.confidence,
            "mean_anees": self.mean_anees,
            "nominal_lower": lo,
            "nominal_upper": hi,
            "fraction_inside": self.fraction_inside,
            "fraction_above": self.fraction_above,
            "fraction_below": self.fraction_below,
            "n_steps": self.n_steps,
            "n_samples": self.n_samples,
            "n_singular_skipped": self.n_singular,
        }


def average_nees(
    times: Sequence[np.ndarray],
    values: Sequence[np.ndarray],
    dof: int,
    singular: Sequence[np.ndarray] | None = None,
    confidence: float = 0.95,
    time_tolerance: float = 1e-6,
) -> NeesAverage:
    """Average per-run NEES over runs at each time step (see the module docstring).

    Args:
        times: per run, ``(n_i,)`` sample times (s); the runs must share one
            time base (same step period and start: step k at the same time in
            every run that has it, within ``time_tolerance`` s); runs may
            differ in length.
        values: per run, ``(n_i,)`` NEES (NaN where none).
        dof: degrees of freedom of one NEES.
        singular: per run, ``(n_i,)`` masks of the samples skipped for a
            singular covariance (only counted).
        confidence: of the bounds.
        time_tolerance: largest difference between the runs' times of a step (s).

    Raises:
        ValueError: no run, mismatched lengths, or runs on different time bases.
    """
    if len(times) == 0 or len(times) != len(values):
        raise ValueError(f"times and values must hold the same, non-zero number of runs, got {len(times)} and {len(values)}")
    if singular is not None and len(singular) != len(times):
        raise ValueError(f"singular must hold one mask per run ({len(times)}), got {len(singular)}")
    t_list = [np.asarray(t, dtype=float).reshape(-1) for t in times]
    v_list = [np.asarray(v, dtype=float).reshape(-1) for v in values]
    for i, (t, v) in enumerate(zip(t_list, v_list)):
        if t.shape != v.shape:
            raise ValueError(f"run {i}: times {t.shape} and values {v.shape} must have the same length")
    longest = max(range(len(t_list)), key=lambda i: t_list[i].shape[0])
    base = t_list[longest]
    for i, t in enumerate(t_list):
        gap = np.abs(t - base[: t.shape[0]])
        if gap.shape[0] and gap.max() > time_tolerance:
            k = int(np.argmax(gap > time_tolerance))
            raise ValueError(f"run {i} is on another time base: its step {k} is at {t[k]!r} s, run {longest}'s at {base[k]!r} s")
    K = base.shape[0]
    sums = np.zeros(K)
    counts = np.zeros(K, dtype=int)
    for v in v_list:
        ok = np.isfinite(v)
        sums[: v.shape[0]] += np.where(ok, v, 0.0)
        counts[: v.shape[0]] += ok
    with np.errstate(invalid="ignore", divide="ignore"):
        anees = np.where(counts > 0, sums / (np.maximum(counts, 1) * dof), np.nan)
    lower, upper = chi2_bounds(counts, dof, confidence)
    n_singular = 0 if singular is None else int(sum(int(np.asarray(s, dtype=bool).sum()) for s in singular))
    return NeesAverage(
        dof=int(dof), n_runs=len(t_list), confidence=float(confidence), times=base.copy(), counts=counts,
        anees=anees, lower=lower, upper=upper, n_singular=n_singular,
    )
