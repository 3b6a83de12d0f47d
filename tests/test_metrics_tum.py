"""TUM trajectory files: format, exact round trip, clear errors."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from moma_env.geometry import make_transform, matrix_to_quaternion, rotvec_to_matrix, se2_to_se3
from moma_env.metrics import TUM_HEADER, Trajectory, quaternions_to_matrices, read_tum, write_tum


def test_written_lines_have_tum_layout(tmp_path: Path) -> None:
    traj = Trajectory.from_planar([0.5, 1.25], [1.0, 2.0], [0.0, -1.5], [0.0, math.pi / 2], z=0.3)
    path = tmp_path / "est.tum"
    write_tum(path, traj)
    lines = path.read_text().splitlines()
    assert lines[0] == TUM_HEADER == "# timestamp tx ty tz qx qy qz qw"
    assert lines[1] == "0.5 1.0 0.0 0.3 0.0 0.0 0.0 1.0"
    fields = [float(v) for v in lines[2].split()]
    assert fields[:4] == [1.25, 2.0, -1.5, 0.3]
    np.testing.assert_allclose(fields[4:], [0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)], atol=1e-15)
    assert len(lines) == 3


def test_invalid_samples_are_skipped(tmp_path: Path) -> None:
    traj = Trajectory.from_planar([0.0, 1.0, 2.0], [0.0, np.nan, 2.0], [0.0] * 3, [0.0] * 3)
    path = tmp_path / "est.tum"
    write_tum(path, traj, header=False)
    back = read_tum(path)
    np.testing.assert_array_equal(back.times, [0.0, 2.0])
    assert len(path.read_text().splitlines()) == 2


def test_all_invalid_trajectory_reads_back_empty(tmp_path: Path) -> None:
    traj = Trajectory.from_planar([0.0, 1.0], [np.nan] * 2, [0.0] * 2, [0.0] * 2)
    write_tum(tmp_path / "lost.tum", traj)
    assert (tmp_path / "lost.tum").read_text() == TUM_HEADER + "\n"
    assert len(read_tum(tmp_path / "lost.tum")) == 0


def test_reader_accepts_comments_blanks_tabs_and_commas(tmp_path: Path) -> None:
    path = tmp_path / "in.txt"
    path.write_text("# a comment\n\n1.0\t2.0 3.0 4.0 0 0 0 2\n  \n2.0,2.5,3.0,4.0,0,0,0,1\n# end\n")
    traj = read_tum(path)
    np.testing.assert_array_equal(traj.times, [1.0, 2.0])
    np.testing.assert_array_equal(traj.positions, [[2.0, 3.0, 4.0], [2.5, 3.0, 4.0]])
    np.testing.assert_allclose(traj.poses[0][:3, :3], np.eye(3))  # quaternion normalised


@pytest.mark.parametrize(
    ("body", "line_number", "message"),
    [
        ("# h\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n", 3, "expected 8 values"),
        ("0 0 0 0 0 0 0 1\n\n1 0 x 0 0 0 0 1\n", 3, "not a number"),
        ("0 0 0 0 0 0 0 1\n1 0 nan 0 0 0 0 1\n", 2, "non-finite"),
        ("0 0 0 0 0 0 0 0\n", 1, "zero quaternion"),
        ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", 3, "timestamp 1.0 is not after the previous one 1.0"),
    ],
)
def test_malformed_line_is_named(tmp_path: Path, body: str, line_number: int, message: str) -> None:
    path = tmp_path / "bad.tum"
    path.write_text(body)
    with pytest.raises(ValueError, match=rf"bad\.tum:{line_number}: {message}"):
        read_tum(path)


def test_quaternion_conversion_inverts_geometry() -> None:
    rng = np.random.default_rng(3)
    R = np.stack([rotvec_to_matrix(v) for v in rng.normal(size=(20, 3)) * 2.0])
    q = np.stack([matrix_to_quaternion(r) for r in R])
    np.testing.assert_allclose(quaternions_to_matrices(q), R, atol=1e-12)
    np.testing.assert_allclose(quaternions_to_matrices(-3.0 * q), R, atol=1e-12)


def test_rewrite_is_atomic_and_leaves_no_temp(tmp_path: Path) -> None:
    path = tmp_path / "a.tum"
    write_tum(path, Trajectory.from_planar([0.0], [1.0], [2.0], [0.0]))
    write_tum(path, Trajectory.from_planar([0.0], [3.0], [4.0], [0.0]))
    assert [p.name for p in tmp_path.iterdir()] == ["a.tum"]
    np.testing.assert_array_equal(read_tum(path).xy, [[3.0, 4.0]])


finite = st.floats(-1e4, 1e4, allow_nan=False, allow_subnormal=False)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(1e-6, 10.0), min_size=1, max_size=15),
    st.floats(-1e6, 1e6),
    st.lists(
        st.tuples(finite, finite, finite, st.floats(-4, 4), st.floats(-4, 4), st.floats(-4, 4)),
        min_size=15,
        max_size=15,
    ),
)
def test_round_trip_is_exact_to_printed_precision(
    steps: list[float], start: float, samples: list[tuple[float, ...]]
) -> None:
    times = start + np.cumsum(steps)
    assume((np.diff(times) > 0).all())  # no step lost to round-off at large |start|
    poses = np.stack(
        [make_transform(rotvec_to_matrix(s[3:]), s[:3]) for s in samples[: len(times)]]
    )
    traj = Trajectory.from_poses(times, poses)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rt.tum"
        write_tum(path, traj)
        back = read_tum(path)
        write_tum(path, back)
        again = read_tum(path)
    np.testing.assert_array_equal(back.times, traj.times)  # repr round-trips exactly
    np.testing.assert_array_equal(back.positions, traj.positions)
    np.testing.assert_allclose(back.poses[:, :3, :3], traj.poses[:, :3, :3], rtol=0, atol=1e-14)
    np.testing.assert_array_equal(again.times, back.times)
    np.testing.assert_allclose(again.poses, back.poses, rtol=0, atol=1e-15)


def test_planar_round_trip_keeps_yaw() -> None:
    t = np.arange(50) * 0.04
    traj = Trajectory.from_planar(t, np.cos(t), np.sin(t), np.linspace(-math.pi, math.pi, 50))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "p.tum"
        write_tum(path, traj)
        back = read_tum(path)
    yaw_diff = np.angle(np.exp(1j * (back.yaw - traj.yaw)))
    assert np.abs(yaw_diff).max() < 1e-14
    np.testing.assert_allclose(back.poses[3], se2_to_se3(traj.xy[3, 0], traj.xy[3, 1], traj.yaw[3]), atol=1e-15)
