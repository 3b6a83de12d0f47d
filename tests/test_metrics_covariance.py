"""Pose covariances: carried by Trajectory and its recorder, written beside the TUM file and read back exactly."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from moma_env.geometry import make_transform, rotvec_to_matrix
from moma_env.metrics import (
    COVARIANCE_HEADER,
    Trajectory,
    TrajectoryRecorder,
    covariance_path_for,
    format_tum,
    read_covariances,
    read_tum,
    read_tum_with_covariances,
    write_covariances,
    write_tum,
)


def random_covariance(rng: np.random.Generator) -> np.ndarray:
    """A random symmetric positive definite 6x6 matrix with entries of varied magnitude."""
    A = rng.normal(size=(6, 6)) * np.array([1e-3, 1e-3, 1e-2, 1e-2, 1e-2, 3e-3])[:, None]
    return A @ A.T + 1e-9 * np.eye(6)


def trajectory_with_covariances(n: int = 12, seed: int = 0) -> Trajectory:
    """``n`` random poses at 25 Hz, sample 3 invalid, sample 5 valid without a covariance."""
    rng = np.random.default_rng(seed)
    times = 0.04 * np.arange(n) + 1.0 / 3.0
    poses = np.stack([make_transform(rotvec_to_matrix(rng.normal(size=3)), rng.normal(size=3)) for _ in range(n)])
    poses[3] = np.nan
    covs = np.stack([random_covariance(rng) for _ in range(n)])
    covs[5] = np.nan
    return Trajectory(times, poses, covs)


def test_trajectory_keeps_covariances_and_blanks_those_of_invalid_samples() -> None:
    traj = trajectory_with_covariances()
    assert traj.has_covariances and traj.covariances.shape == (12, 6, 6)
    assert np.isnan(traj.covariances[3]).all()  # invalid pose -> no covariance
    assert np.isnan(traj.covariances[5]).all()
    assert np.isfinite(traj.covariances[[0, 1, 2, 4, 6]]).all()
    assert not traj.covariances.flags.writeable
    # subsets keep the covariances of their samples
    sub = traj.window(traj.times[2], traj.times[6])
    np.testing.assert_array_equal(sub.covariances, traj.covariances[2:7])
    valid = traj.valid_only()
    assert len(valid) == 11
    np.testing.assert_array_equal(valid.covariances, traj.covariances[traj.valid])
    assert not Trajectory(traj.times, traj.poses).has_covariances


def test_a_partly_nan_covariance_becomes_all_nan() -> None:
    covs = np.zeros((2, 6, 6))
    covs[1, 2, 2] = np.nan
    traj = Trajectory(np.arange(2.0), np.stack([np.eye(4)] * 2), covs)
    assert np.isnan(traj.covariances[1]).all() and not np.isnan(traj.covariances[0]).any()


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda c: c.__setitem__((1, 0, 0), -1e-6), r"covariances\[1\] has a negative diagonal entry"),
        (lambda c: c.__setitem__((2, 0, 4), 1e-3), r"covariances\[2\] is not symmetric"),
        (lambda c: c.__setitem__((0, 1, 1), np.inf), r"covariances\[0\] contains inf"),
    ],
)
def test_bad_covariances_are_named(edit, message) -> None:
    covs = np.stack([np.eye(6) * 1e-4] * 3)
    edit(covs)
    with pytest.raises(ValueError, match=message):
        Trajectory(np.arange(3.0), np.stack([np.eye(4)] * 3), covs)
    with pytest.raises(ValueError, match=r"covariances must have shape \(3, 6, 6\)"):
        Trajectory(np.arange(3.0), np.stack([np.eye(4)] * 3), np.zeros((3, 3, 3)))


def test_recorder_records_covariances_and_nan_for_none() -> None:
    rng = np.random.default_rng(1)
    rec = TrajectoryRecorder(capacity=2, covariances=True)
    covs = [random_covariance(rng) for _ in range(5)]
    rec.append(0.0, (0.0, 0.0, 0.0), covs[0])
    rec.append(0.1, (1.0, 0.0, 0.5), None)  # valid pose, no covariance
    rec.append(0.2, None, covs[2])  # no pose: the covariance is dropped
    rec.append(0.3, np.eye(4), covs[3])  # grows past the capacity
    rec.append(0.4, (2.0, 1.0, 0.0), covs[4])
    traj = rec.to_trajectory()
    np.testing.assert_array_equal(traj.covariances[[0, 3, 4]], np.stack([covs[0], covs[3], covs[4]]))
    assert np.isnan(traj.covariances[1]).all() and np.isnan(traj.covariances[2]).all()
    assert traj.valid.tolist() == [True, True, False, True, True]


def test_recorder_without_covariances_is_unchanged_and_refuses_one() -> None:
    rec = TrajectoryRecorder()
    rec.append(0.0, np.eye(4))
    assert rec.to_trajectory().covariances is None
    with pytest.raises(ValueError, match="covariances=True"):
        rec.append(1.0, np.eye(4), np.eye(6))
    with_cov = TrajectoryRecorder(covariances=True)
    with pytest.raises(ValueError, match=r"covariance must be a 6x6 array or None, got shape \(3, 3\)"):
        with_cov.append(0.0, np.eye(4), np.eye(3))


def test_covariance_file_round_trips_exactly_line_for_line_with_the_tum_file(tmp_path: Path) -> None:
    traj = trajectory_with_covariances()
    tum = tmp_path / "ugv_0_moma.tum"
    write_tum(tum, traj)
    cov_path = Path(covariance_path_for(tum))
    assert cov_path.name == "ugv_0_moma.cov.txt"
    write_covariances(cov_path, traj)
    lines = cov_path.read_text().splitlines()
    assert "\n".join(lines[:3]) == COVARIANCE_HEADER
    data_lines = [line for line in lines if not line.startswith("#")]
    tum_lines = [line for line in tum.read_text().splitlines() if not line.startswith("#")]
    assert len(data_lines) == len(tum_lines) == 11  # the valid samples only
    assert [line.split()[0] for line in data_lines] == [line.split()[0] for line in tum_lines]
    assert len(data_lines[0].split()) == 37
    # row-major: entry (0, 1) is the 3rd field
    assert float(data_lines[0].split()[2]) == traj.covariances[0, 0, 1]

    times, covs = read_covariances(cov_path)
    np.testing.assert_array_equal(times, traj.times[traj.valid])  # bit for bit
    valid = traj.covariances[traj.valid]
    known = ~np.isnan(valid).any(axis=(1, 2))
    np.testing.assert_array_equal(covs[known], valid[known])
    assert np.isnan(covs[~known]).all() and (~known).sum() == 1

    back = read_tum_with_covariances(tum)
    np.testing.assert_array_equal(back.times, traj.times[traj.valid])
    np.testing.assert_array_equal(back.covariances[known], valid[known])


def test_tum_text_is_unchanged_by_covariances() -> None:
    traj = trajectory_with_covariances()
    assert format_tum(traj) == format_tum(Trajectory(traj.times, traj.poses))


def test_writing_needs_covariances(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="carries no covariances"):
        write_covariances(tmp_path / "x.cov.txt", Trajectory(np.arange(2.0), np.stack([np.eye(4)] * 2)))
    assert not (tmp_path / "x.cov.txt").exists()


def _row(t: float, cov: np.ndarray) -> str:
    return " ".join([repr(t)] + [repr(float(v)) for v in cov.reshape(-1)])


@pytest.mark.parametrize(
    ("lines", "line_number", "message"),
    [
        (["0.0 1 2 3"], 1, "expected 37 values"),
        ([_row(0.0, np.eye(6)).replace(" 0.0", " x", 1)], 1, "not a number"),
        (["# h", _row(0.0, np.eye(6)), _row(0.0, np.eye(6))], 3, "timestamp 0.0 is not after the previous one 0.0"),
        ([_row(0.0, np.eye(6)).replace("1.0", "inf", 1)], 1, "infinite value"),
        ([_row(0.0, np.eye(6)).replace("1.0", "nan", 1)], 1, "a covariance is either all nan"),
        ([_row(0.0, -np.eye(6))], 1, "negative variance"),
        ([_row(0.0, np.eye(6) + np.triu(np.ones((6, 6)), 1))], 1, "the covariance is not symmetric"),
        (["nan " + " ".join(["nan"] * 36)], 1, "the timestamp must be finite"),
    ],
)
def test_malformed_covariance_line_is_named(tmp_path: Path, lines: list[str], line_number: int, message: str) -> None:
    path = tmp_path / "bad.cov.txt"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=rf"bad\.cov\.txt:{line_number}: {message}"):
        read_covariances(path)


def test_tum_and_covariance_files_must_share_timestamps(tmp_path: Path) -> None:
    traj = trajectory_with_covariances()
    tum = tmp_path / "a.tum"
    write_tum(tum, traj)
    write_covariances(tmp_path / "a.cov.txt", traj.window(0.0, traj.times[6]))
    with pytest.raises(ValueError, match=r"a\.cov\.txt has 6 samples but .*a\.tum has 11"):
        read_tum_with_covariances(tum)
    shifted = Trajectory(traj.times + 1e-3, traj.poses, traj.covariances)
    write_covariances(tmp_path / "a.cov.txt", shifted)
    with pytest.raises(ValueError, match=r"sample 0 has timestamp"):
        read_tum_with_covariances(tum)
    assert len(read_tum(tum)) == 11
    assert math.isfinite(read_covariances(tmp_path / "a.cov.txt")[0][0])
