"""Trajectory container and recorder."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.geometry import make_transform, rot_x, rot_z, se2_to_se3
from moma_env.metrics import Trajectory, TrajectoryRecorder


def square_path(points_per_side: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Corners (0,0) -> (1,0) -> (1,1) -> (0,1) -> (0,0), sampled along each side."""
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])
    s = np.linspace(0.0, 1.0, points_per_side, endpoint=False)
    xy = np.concatenate([a + s[:, None] * (b - a) for a, b in zip(corners[:-1], corners[1:])] + [corners[-1:]])
    return np.arange(xy.shape[0]) * 0.1, xy


def test_square_path_length_is_4m() -> None:
    t, xy = square_path()
    traj = Trajectory.from_planar(t, xy[:, 0], xy[:, 1], np.zeros(len(t)))
    assert traj.path_length() == pytest.approx(4.0, abs=1e-12)
    assert len(traj) == 41


def test_path_length_bridges_invalid_samples() -> None:
    t = np.arange(4.0)
    x = np.array([0.0, np.nan, 3.0, 3.0])
    y = np.array([0.0, 0.0, 4.0, 5.0])
    traj = Trajectory.from_planar(t, x, y, np.zeros(4))
    assert traj.valid.tolist() == [True, False, True, True]
    assert traj.path_length() == pytest.approx(5.0 + 1.0)


def test_planar_properties_and_height() -> None:
    traj = Trajectory.from_planar([0.0, 1.0], [1.0, 2.0], [3.0, 4.0], [0.5, -3.0], z=[0.2, 0.3])
    np.testing.assert_allclose(traj.positions, [[1.0, 3.0, 0.2], [2.0, 4.0, 0.3]])
    np.testing.assert_allclose(traj.xy, [[1.0, 3.0], [2.0, 4.0]])
    np.testing.assert_allclose(traj.yaw, [0.5, -3.0])
    np.testing.assert_allclose(traj.poses[1], se2_to_se3(2.0, 4.0, -3.0, 0.3))
    assert traj.duration == 1.0


def test_from_poses_matches_from_planar() -> None:
    t = [0.0, 0.5, 2.0]
    poses = [se2_to_se3(0.1 * i, -0.2 * i, 0.7 * i, 0.25) for i in range(3)]
    a = Trajectory.from_poses(t, poses)
    b = Trajectory.from_planar(t, [0.0, 0.1, 0.2], [0.0, -0.2, -0.4], [0.0, 0.7, 1.4], z=0.25)
    np.testing.assert_allclose(a.poses, b.poses, atol=1e-15)
    np.testing.assert_array_equal(a.times, b.times)


def test_nan_pose_marks_sample_invalid_and_whole_pose_nan() -> None:
    poses = np.stack([np.eye(4)] * 3)
    poses[1, 0, 3] = np.nan
    traj = Trajectory.from_poses([0.0, 1.0, 2.0], poses)
    assert traj.valid.tolist() == [True, False, True]
    assert np.isnan(traj.poses[1]).all()
    assert np.isnan(traj.positions[1]).all() and math.isnan(traj.yaw[1])


def test_trajectory_is_immutable_and_copies_its_input() -> None:
    times = np.array([0.0, 1.0])
    poses = np.stack([np.eye(4)] * 2)
    traj = Trajectory(times, poses)
    times[0] = -5.0
    poses[0, 0, 3] = 9.0
    assert traj.times[0] == 0.0 and traj.poses[0, 0, 3] == 0.0
    with pytest.raises(ValueError):
        traj.times[0] = 3.0
    with pytest.raises(ValueError):
        traj.positions[0, 0] = 3.0
    with pytest.raises(AttributeError):
        traj.times = np.zeros(2)  # type: ignore[misc]


@pytest.mark.parametrize(
    ("times", "poses", "message"),
    [
        (np.zeros((2, 1)), np.stack([np.eye(4)] * 2), "1-D"),
        (np.array([0.0, 1.0]), np.stack([np.eye(4)] * 3), r"shape \(2, 4, 4\)"),
        (np.array([0.0, 1.0, 1.0]), np.stack([np.eye(4)] * 3), r"strictly increasing; times\[1\]"),
        (np.array([0.0, 2.0, 1.0]), np.stack([np.eye(4)] * 3), r"strictly increasing; times\[1\]"),
        (np.array([0.0, np.nan]), np.stack([np.eye(4)] * 2), r"finite; times\[1\]"),
        (np.array([0.0, np.inf]), np.stack([np.eye(4)] * 2), r"finite; times\[1\]"),
    ],
)
def test_bad_times_and_shapes_are_named(times: np.ndarray, poses: np.ndarray, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Trajectory(times, poses)


def test_non_rigid_and_infinite_poses_are_rejected() -> None:
    poses = np.stack([np.eye(4)] * 3)
    poses[2, 0, 0] = 2.0
    with pytest.raises(ValueError, match=r"poses\[2\] is not a rigid transform: rotation"):
        Trajectory(np.arange(3.0), poses)
    poses = np.stack([np.eye(4)] * 3)
    poses[1, 3, 0] = 1.0
    with pytest.raises(ValueError, match=r"poses\[1\].*bottom row"):
        Trajectory(np.arange(3.0), poses)
    poses = np.stack([np.eye(4)] * 3)
    poses[1, :3, :3] = -np.eye(3)  # reflection, det -1
    with pytest.raises(ValueError, match=r"poses\[1\]"):
        Trajectory(np.arange(3.0), poses)
    poses = np.stack([np.eye(4)] * 3)
    poses[0, 1, 3] = np.inf
    with pytest.raises(ValueError, match=r"poses\[0\] contains inf"):
        Trajectory(np.arange(3.0), poses)


def test_from_planar_checks_lengths() -> None:
    with pytest.raises(ValueError, match="yaw must have shape"):
        Trajectory.from_planar([0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.0])
    with pytest.raises(ValueError, match="z must be"):
        Trajectory.from_planar([0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.0, 0.0], z=[1.0, 2.0, 3.0])


def test_window_is_closed_interval() -> None:
    t = np.arange(10) * 0.5
    traj = Trajectory.from_planar(t, t, t, t)
    w = traj.window(1.0, 2.5)
    np.testing.assert_array_equal(w.times, [1.0, 1.5, 2.0, 2.5])
    np.testing.assert_array_equal(w.xy[:, 0], [1.0, 1.5, 2.0, 2.5])
    assert len(traj.window(10.0, 20.0)) == 0
    assert len(traj.window(-math.inf, math.inf)) == 10
    with pytest.raises(ValueError, match="after stop"):
        traj.window(2.0, 1.0)


def test_valid_only_and_empty() -> None:
    traj = Trajectory.from_planar([0.0, 1.0, 2.0], [0.0, np.nan, 2.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    v = traj.valid_only()
    np.testing.assert_array_equal(v.times, [0.0, 2.0])
    assert v.valid.all()
    e = Trajectory.empty()
    assert len(e) == 0 and e.path_length() == 0.0 and e.duration == 0.0


def test_recorder_accepts_matrix_planar_and_none_and_grows() -> None:
    rec = TrajectoryRecorder(planar_z=0.4, capacity=2)
    T = make_transform(rot_z(0.3) @ rot_x(0.1), [1.0, 2.0, 3.0])
    rec.append(0.0, T)
    rec.append(0.1, (0.5, -0.5, 1.0))
    rec.append(0.2, None)
    rec.append(0.3, np.array([1.0, 1.0, -2.0]))
    for k in range(4, 40):
        rec.append(0.1 * k, (float(k), 0.0, 0.0))
    traj = rec.to_trajectory()
    assert len(rec) == len(traj) == 40
    np.testing.assert_array_equal(traj.poses[0], T)
    np.testing.assert_allclose(traj.poses[1], se2_to_se3(0.5, -0.5, 1.0, 0.4), atol=1e-15)
    assert traj.valid[:4].tolist() == [True, True, False, True]
    np.testing.assert_allclose(traj.poses[3], se2_to_se3(1.0, 1.0, -2.0, 0.4), atol=1e-15)
    np.testing.assert_array_equal(traj.xy[4:, 0], np.arange(4.0, 40.0))
    # the trajectory is independent of later appends
    rec.append(10.0, None)
    assert len(traj) == 40 and len(rec) == 41


def test_recorder_rejects_bad_input() -> None:
    rec = TrajectoryRecorder()
    rec.append(1.0, None)
    with pytest.raises(ValueError, match="after the previous"):
        rec.append(1.0, None)
    with pytest.raises(ValueError, match="after the previous"):
        rec.append(float("nan"), None)
    with pytest.raises(ValueError, match="4x4"):
        rec.append(2.0, np.eye(3))
    with pytest.raises(ValueError, match="capacity"):
        TrajectoryRecorder(capacity=0)
    assert len(rec) == 1


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(-50, 50),
            st.floats(-50, 50),
            st.floats(-10, 10),
            st.booleans(),
        ),
        min_size=1,
        max_size=30,
    )
)
def test_recorder_equals_from_planar(samples: list[tuple[float, float, float, bool]]) -> None:
    t = np.arange(len(samples)) * 0.04
    rec = TrajectoryRecorder(planar_z=0.1, capacity=3)
    for ti, (x, y, yaw, ok) in zip(t, samples):
        rec.append(ti, (x, y, yaw) if ok else None)
    got = rec.to_trajectory()
    x = np.array([s[0] if s[3] else np.nan for s in samples])
    y = np.array([s[1] for s in samples])
    yaw = np.array([s[2] for s in samples])
    want = Trajectory.from_planar(t, x, y, yaw, z=0.1)
    np.testing.assert_array_equal(got.valid, want.valid)
    np.testing.assert_array_equal(got.poses, want.poses)
    assert got.path_length() == pytest.approx(want.path_length())
