"""NEES, its average over runs and the chi-square bounds, on synthetic errors of known covariance."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.metrics import Trajectory, average_nees, chi2_bounds, nees, pose_errors, trajectory_nees
from moma_env.metrics.consistency import HEADING, POSITION_3D, POSITION_PLANAR


def perturb(T: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``[exp([dtheta]x) R, t + dt]``: the estimator's error convention."""
    out = T.copy()
    out[:3, :3] = g.rotvec_to_matrix(e[3:]) @ T[:3, :3]
    out[:3, 3] = T[:3, 3] + e[:3]
    return out


def spd(rng: np.random.Generator, d: int) -> np.ndarray:
    A = rng.normal(size=(d, d)) * rng.uniform(0.5, 2.0, d)[:, None]
    return A @ A.T + 0.1 * np.eye(d)


def test_bounds_match_chi_square_tables():
    lo, hi = chi2_bounds(1, 2)
    assert float(lo) == pytest.approx(0.0506356 / 2, rel=1e-5) and float(hi) == pytest.approx(7.377759 / 2, rel=1e-6)
    lo, hi = chi2_bounds(10, 2)  # 20 dof
    assert float(lo) == pytest.approx(9.590777 / 20, rel=1e-6) and float(hi) == pytest.approx(34.169607 / 20, rel=1e-6)
    lo, hi = chi2_bounds(np.array([0, 50]), 1, confidence=0.99)
    assert np.isnan(lo[0]) and np.isnan(hi[0])
    assert float(lo[1]) == pytest.approx(27.990749 / 50, rel=1e-6) and float(hi[1]) == pytest.approx(79.489978 / 50, rel=1e-6)
    with pytest.raises(ValueError, match="dof"):
        chi2_bounds(3, 0)
    with pytest.raises(ValueError, match="confidence"):
        chi2_bounds(3, 2, confidence=1.0)


def test_pose_errors_recover_a_planted_perturbation():
    rng = np.random.default_rng(0)
    n = 30
    est = np.stack([g.make_transform(g.rotvec_to_matrix(rng.normal(size=3)), rng.normal(size=3)) for _ in range(n)])
    e = rng.normal(scale=[0.01, 0.01, 0.01, 0.02, 0.02, 0.02], size=(n, 6))
    e[0, 3:] = 0.0  # no rotation error
    e[1, 3:] = [0.0, 0.0, 3.1]  # close to pi: the fallback log
    truth = np.stack([perturb(T, ek) for T, ek in zip(est, e)])
    times = 0.04 * np.arange(n)
    estimate = Trajectory(times, est)
    estimate_poses = estimate.poses.copy()
    estimate_poses[4] = np.nan
    got = pose_errors(Trajectory(times, estimate_poses), Trajectory(times, truth))
    assert np.isnan(got[4]).all()
    keep = np.arange(n) != 4
    np.testing.assert_allclose(got[keep], e[keep], atol=1e-9)


def test_heading_error_of_upright_poses_is_the_wrapped_yaw_difference():
    times = np.arange(3.0)
    est = Trajectory.from_planar(times, [0.0, 1.0, 2.0], [0.0] * 3, [3.1, -0.2, 0.0])
    truth = Trajectory.from_planar(times, [0.0, 1.0, 2.5], [0.0] * 3, [-3.1, -0.1, 0.0])
    e = pose_errors(est, truth)
    np.testing.assert_allclose(e[:, 5], [2 * np.pi - 6.2, 0.1, 0.0], atol=1e-12)
    np.testing.assert_allclose(e[:, 0], [0.0, 0.0, 0.5])


def test_nees_of_a_known_error_and_the_skipped_samples():
    errors = np.zeros((4, 6))
    errors[:, :2] = [[0.2, 0.0], [0.0, 0.3], [0.1, 0.1], [np.nan, 0.0]]
    covs = np.stack([np.diag([0.01, 0.04, 1, 1, 1, 1.0])] * 4)
    covs[2] = 0.0  # the zero covariance of a pose defining the world frame
    values, singular = nees(errors, covs, POSITION_PLANAR)
    np.testing.assert_allclose(values[:2], [4.0, 0.09 / 0.04])
    assert np.isnan(values[2:]).all()
    assert singular.tolist() == [False, False, True, False]  # unknown error: not counted as singular
    with pytest.raises(ValueError, match="components"):
        nees(errors, covs, (0, 0))
    with pytest.raises(ValueError, match="components"):
        nees(errors, covs, (6,))
    with pytest.raises(ValueError, match=r"covariances must have shape \(4, 6, 6\)"):
        nees(errors, covs[:3], HEADING)


def _synthetic_runs(rng, n_runs, n_steps, components, scale):
    """Per run: truth and an estimate whose error is ``scale`` x a draw of its covariance."""
    d = len(components)
    idx = np.array(components)
    times, values, singular = [], [], []
    for _ in range(n_runs):
        n = n_steps - int(rng.integers(0, 5))  # runs of slightly different lengths
        t = 0.04 * np.arange(n)
        covs = np.zeros((n, 6, 6))
        truth = np.stack([g.se2_to_se3(*rng.normal(size=2), rng.uniform(-3, 3))] * n)
        est = truth.copy()
        for k in range(n):
            full = np.eye(6) * 1e-4
            full[np.ix_(idx, idx)] = spd(rng, d) * 1e-4
            covs[k] = full
            e = np.zeros(6)
            e[idx] = scale * np.linalg.cholesky(full[np.ix_(idx, idx)]) @ rng.standard_normal(d)
            # the estimate with truth = perturb(estimate, e)
            est[k] = g.make_transform(g.rotvec_to_matrix(-e[3:]) @ truth[k][:3, :3], truth[k][:3, 3] - e[:3])
        v, s = trajectory_nees(Trajectory(t, est, covs), Trajectory(t, truth), components)
        times.append(t)
        values.append(v)
        singular.append(s)
    return times, values, singular


@pytest.mark.parametrize("components", [POSITION_PLANAR, POSITION_3D, HEADING])
def test_anees_of_gaussian_errors_is_inside_the_bounds_and_of_inflated_errors_outside(components):
    rng = np.random.default_rng(len(components))
    d = len(components)
    consistent = average_nees(*_synthetic_runs(rng, 30, 120, components, 1.0)[:2], dof=d)
    assert consistent.mean_anees == pytest.approx(1.0, abs=0.06)
    assert 0.9 <= consistent.fraction_inside <= 0.99
    assert consistent.n_runs == 30 and consistent.counts.max() == 30 and consistent.n_singular == 0
    over = average_nees(*_synthetic_runs(rng, 30, 120, components, 2.0)[:2], dof=d)  # errors twice the stated std
    assert over.mean_anees == pytest.approx(4.0, rel=0.1)
    assert over.fraction_inside < 0.05 and over.fraction_above > 0.95
    under = average_nees(*_synthetic_runs(rng, 30, 120, components, 0.4)[:2], dof=d)  # a too cautious covariance
    assert under.fraction_inside < 0.1 and under.fraction_below > 0.9


def test_average_over_runs_per_step_with_missing_samples():
    t = 0.1 * np.arange(4)
    runs_t = [t, t[:3]]
    values = [np.array([2.0, np.nan, 4.0, 6.0]), np.array([4.0, 1.0, np.nan])]
    singular = [np.array([False, True, False, False]), np.zeros(3, dtype=bool)]
    avg = average_nees(runs_t, values, dof=2, singular=singular)
    np.testing.assert_array_equal(avg.counts, [2, 1, 1, 1])
    np.testing.assert_allclose(avg.anees, [1.5, 0.5, 2.0, 3.0])
    lo1, hi1 = chi2_bounds(1, 2)
    assert avg.upper[1] == pytest.approx(float(hi1)) and avg.lower[0] == pytest.approx(float(chi2_bounds(2, 2)[0]))
    assert avg.n_singular == 1 and avg.n_samples == 5 and avg.n_steps == 4
    assert avg.mean_anees == pytest.approx(np.mean([1.5, 0.5, 2.0, 3.0]))
    assert avg.fraction_inside == pytest.approx(1.0)
    d = avg.to_dict()
    assert d["n_singular_skipped"] == 1 and d["dof"] == 2 and d["n_runs"] == 2
    empty = average_nees([t], [np.full(4, np.nan)], dof=1)
    assert empty.n_steps == 0 and np.isnan(empty.mean_anees) and np.isnan(empty.fraction_inside)


def test_average_rejects_runs_on_other_time_bases():
    t = 0.04 * np.arange(5)
    with pytest.raises(ValueError, match="run 1 is on another time base"):
        average_nees([t, t + 0.02], [np.ones(5), np.ones(5)], dof=1)
    with pytest.raises(ValueError, match="same, non-zero number of runs"):
        average_nees([], [], dof=1)
    with pytest.raises(ValueError, match="run 0: times"):
        average_nees([t], [np.ones(4)], dof=1)


def test_trajectory_nees_needs_covariances_and_a_matching_mask():
    t = np.arange(3.0)
    truth = Trajectory.from_planar(t, [0.0] * 3, [0.0] * 3, [0.0] * 3)
    with pytest.raises(ValueError, match="carries no covariances"):
        trajectory_nees(truth, truth, HEADING)
    est = truth.with_covariances(np.stack([np.eye(6)] * 3))
    with pytest.raises(ValueError, match=r"usable must have shape \(3,\)"):
        trajectory_nees(est, truth, HEADING, usable=np.ones(2, dtype=bool))
    values, _ = trajectory_nees(est, truth, HEADING, usable=np.array([True, False, True]))
    assert values[0] == 0.0 and np.isnan(values[1])
