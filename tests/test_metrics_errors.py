"""Per-sample errors, association, keypoint errors, APE/RPE."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.geometry import make_transform, rot_z, se2_to_se3
from moma_env.metrics import (
    Trajectory,
    ape_translation,
    associate,
    error_stats,
    errors_at_times,
    heading_errors,
    nearest_valid_indices,
    position_errors,
    relative_errors,
    rpe_translation,
)


def line(t: np.ndarray, dy: float = 0.0, yaw: float = 0.0) -> Trajectory:
    return Trajectory.from_planar(t, t.copy(), np.full(len(t), dy), np.full(len(t), yaw))


def test_constant_offset_gives_constant_error() -> None:
    t = np.linspace(0.0, 4.0, 41)
    e = position_errors(line(t, dy=0.03), line(t))
    np.testing.assert_allclose(e, 0.03, rtol=0, atol=1e-15)


def test_position_error_is_planar_only() -> None:
    t = np.arange(3.0)
    truth = Trajectory.from_planar(t, [0.0, 1.0, 2.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], z=0.0)
    est = Trajectory.from_planar(t, [0.3, 1.0, 2.0], [0.4, 0.0, 0.0], [0.0, 0.0, 0.0], z=0.5)
    np.testing.assert_allclose(position_errors(est, truth), [0.5, 0.0, 0.0], atol=1e-15)
    assert ape_translation(est, truth, planar=True).max == pytest.approx(0.5)
    full = ape_translation(est, truth, planar=False)
    assert full.min == pytest.approx(0.5) and full.max == pytest.approx(math.sqrt(0.5**2 + 0.5**2))


def test_heading_error_wraps_across_pi() -> None:
    t = np.arange(2.0)
    truth = Trajectory.from_planar(t, [0.0, 0.0], [0.0, 0.0], [math.pi - 0.01, -math.pi + 0.02])
    est = Trajectory.from_planar(t, [0.0, 0.0], [0.0, 0.0], [-math.pi + 0.01, math.pi - 0.03])
    np.testing.assert_allclose(heading_errors(est, truth), [0.02, 0.05], atol=1e-12)


def test_invalid_estimate_samples_give_nan() -> None:
    t = np.arange(4.0)
    est = Trajectory.from_planar(t, [0.0, np.nan, 2.0, 3.0], [0.1] * 4, [0.0] * 4)
    e = position_errors(est, line(t))
    assert np.isnan(e[1])
    np.testing.assert_allclose(e[[0, 2, 3]], 0.1, atol=1e-15)
    assert np.isnan(heading_errors(est, line(t))[1])


def test_association_by_nearest_time_within_tolerance() -> None:
    truth_t = np.array([0.0, 0.08, 0.2, 0.28, 0.4])
    est_t = np.array([0.0, 0.19, 0.41])
    np.testing.assert_array_equal(associate(truth_t, est_t, max_dt=0.015), [0, -1, 1, -1, 2])
    np.testing.assert_array_equal(associate(truth_t, est_t, max_dt=math.inf), [0, 0, 1, 1, 2])
    np.testing.assert_array_equal(associate(truth_t, est_t, max_dt=0.1), [0, 0, 1, 1, 2])
    np.testing.assert_array_equal(associate(truth_t, est_t, max_dt=0.085), [0, 0, 1, -1, 2])
    # exact tie between 0.0 and 0.2 goes to the earlier sample
    np.testing.assert_array_equal(associate(np.array([0.1]), np.array([0.0, 0.2]), max_dt=1.0), [0])
    assert associate(truth_t, np.empty(0)).tolist() == [-1] * 5
    with pytest.raises(ValueError, match="max_dt"):
        associate(truth_t, est_t, max_dt=-1.0)


def test_errors_use_association_tolerance() -> None:
    truth = line(np.array([0.0, 0.1, 0.2, 0.3, 0.4]))
    est_t = np.array([0.0, 0.19, 0.41])
    est = Trajectory.from_planar(est_t, [0.0, 0.2, 0.4], [0.05, 0.05, 0.05], [0.0, 0.0, 0.0])
    e = position_errors(est, truth, max_dt=0.015)
    np.testing.assert_allclose(e[[0, 2, 4]], 0.05, atol=1e-12)
    assert np.isnan(e[[1, 3]]).all()
    # default tolerance: equal timestamps up to round-off only
    shifted = Trajectory.from_planar(truth.times + 1e-9, truth.xy[:, 0], truth.xy[:, 1], truth.yaw)
    np.testing.assert_allclose(position_errors(shifted, truth), 0.0, atol=0)


def test_time_base_mismatch_raises() -> None:
    truth = line(np.arange(5) * 0.1)
    est = line(np.arange(5) + 100.0)
    with pytest.raises(ValueError, match="no estimate sample lies within"):
        position_errors(est, truth)


def test_empty_estimate_gives_all_nan() -> None:
    assert np.isnan(position_errors(Trajectory.empty(), line(np.arange(3.0)))).all()


def test_errors_at_times_pick_nearest_valid_truth_sample() -> None:
    t = np.arange(6.0)
    truth = line(t)
    # error grows by 1 cm per sample: E(k) = 0.01 k
    est = Trajectory.from_planar(t, t, 0.01 * t, np.zeros(6))
    np.testing.assert_allclose(errors_at_times(est, truth, [1.2, 3.6, 2.5, 0.0, 5.0]), [0.01, 0.04, 0.02, 0.0, 0.05])
    # invalid truth samples are skipped: with truth only at 0, 3, 5 the nearest of 1.2 is 0
    sparse = Trajectory.from_planar(t, [0.0, np.nan, np.nan, 3.0, np.nan, 5.0], np.zeros(6), np.zeros(6))
    np.testing.assert_array_equal(nearest_valid_indices(sparse, [1.2, 1.6, 4.2]), [0, 3, 5])
    with pytest.raises(ValueError, match=r"outside the truth's valid time span"):
        errors_at_times(est, truth, [6.5])
    with pytest.raises(ValueError, match="entry 1"):
        nearest_valid_indices(truth, [1.0, float("nan")])


def test_relative_errors_between_keypoints() -> None:
    t = np.arange(3.0)
    truth = Trajectory.from_planar(t, [0.0, 1.0, 3.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    est = Trajectory.from_planar(t, [0.0, 1.1, 2.9], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(relative_errors(est, truth, [0.0, 1.0, 2.0]), [0.1, 0.2], atol=1e-12)
    assert relative_errors(est, truth, [1.0]).shape == (0,)
    with pytest.raises(ValueError, match="strictly increasing"):
        relative_errors(est, truth, [1.0, 0.0])


def test_rpe_is_blind_to_a_global_rigid_offset_but_ape_is_not() -> None:
    t = np.arange(20) * 0.1
    truth = Trajectory.from_planar(t, np.cos(t), np.sin(2 * t), t)
    offset = make_transform(rot_z(0.2), [0.5, -0.3, 0.0])
    est = Trajectory.from_poses(t, offset @ truth.poses)
    assert rpe_translation(est, truth, delta=3).max < 1e-12
    assert rpe_translation(est, truth, delta=1, planar=False).max < 1e-12
    assert ape_translation(est, truth).min > 0.1
    with pytest.raises(ValueError, match="delta"):
        rpe_translation(est, truth, delta=0)


def test_rpe_of_a_single_step_jump() -> None:
    t = np.arange(5.0)
    truth = line(t)
    x = t.copy()
    x[3:] += 0.07  # the estimate jumps 7 cm between samples 2 and 3
    est = Trajectory.from_planar(t, x, np.zeros(5), np.zeros(5))
    stats = rpe_translation(est, truth, delta=1)
    assert stats.n == 4
    assert stats.max == pytest.approx(0.07) and stats.median == pytest.approx(0.0, abs=1e-12)


def test_error_stats_hand_values_and_empty() -> None:
    s = error_stats([3.0, np.nan, 4.0])
    assert (s.n, s.mean, s.min, s.max, s.median) == (2, 3.5, 3.0, 4.0, 3.5)
    assert s.rmse == pytest.approx(math.sqrt(12.5)) and s.std == pytest.approx(0.5)
    empty = error_stats([np.nan])
    assert empty.n == 0 and math.isnan(empty.mean)
    assert set(s.to_dict()) == {"n", "rmse", "mean", "median", "std", "min", "max"}


planar_samples = st.lists(
    st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-math.pi, math.pi)),
    min_size=1,
    max_size=25,
)


def trajectory_from(samples: list[tuple[float, float, float]]) -> Trajectory:
    a = np.array(samples, dtype=float)
    return Trajectory.from_planar(np.arange(len(a)) * 0.04, a[:, 0], a[:, 1], a[:, 2])


@settings(max_examples=60, deadline=None)
@given(planar_samples)
def test_truth_against_itself_has_zero_error(samples: list[tuple[float, float, float]]) -> None:
    truth = trajectory_from(samples)
    assert (position_errors(truth, truth) == 0.0).all()
    assert (heading_errors(truth, truth) == 0.0).all()
    rpe = rpe_translation(truth, truth)
    assert rpe.n == len(truth) - 1
    if rpe.n:
        assert rpe.max == 0.0


@settings(max_examples=60, deadline=None)
@given(
    planar_samples,
    st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-3, 3)), min_size=25, max_size=25),
    st.tuples(st.floats(-10, 10), st.floats(-10, 10), st.floats(-math.pi, math.pi)),
)
def test_errors_invariant_under_common_rigid_motion(
    samples: list[tuple[float, float, float]],
    noise: list[tuple[float, float, float]],
    motion: tuple[float, float, float],
) -> None:
    truth = trajectory_from(samples)
    n = len(truth)
    noisy = np.array(samples) + np.array(noise[:n])
    est = Trajectory.from_planar(truth.times, noisy[:, 0], noisy[:, 1], noisy[:, 2])
    G = se2_to_se3(*motion)
    moved_truth = Trajectory.from_poses(truth.times, G @ truth.poses)
    moved_est = Trajectory.from_poses(est.times, G @ est.poses)
    np.testing.assert_allclose(position_errors(moved_est, moved_truth), position_errors(est, truth), atol=1e-9)
    h = heading_errors(est, truth)
    np.testing.assert_allclose(heading_errors(moved_est, moved_truth), h, atol=1e-9)
    assert ((h >= 0.0) & (h <= math.pi)).all()
    # symmetric in its two arguments when the timestamps are equal
    np.testing.assert_array_equal(position_errors(truth, est), position_errors(est, truth))
