"""Hand-checked cases that pin every convention of moma_env.geometry."""

import math
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env import geometry as g

angles = st.floats(min_value=-math.pi, max_value=math.pi, allow_nan=False)
coords = st.floats(min_value=-10, max_value=10, allow_nan=False)


def random_pose(rng: np.random.Generator) -> np.ndarray:
    rvec = rng.normal(size=3)
    return g.make_transform(g.rotvec_to_matrix(rvec), rng.normal(size=3))


def test_point_maps_from_b_to_a():
    # Frame b sits at (1, 2, 0) in a, rotated +90 deg about z: b's x axis is a's +y.
    T_a_b = g.se2_to_se3(1.0, 2.0, math.pi / 2)
    p_b = np.array([1.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(T_a_b @ p_b, [1.0, 3.0, 0.0, 1.0], atol=1e-12)


def test_chaining_and_inverse():
    rng = np.random.default_rng(0)
    T_a_b, T_b_c = random_pose(rng), random_pose(rng)
    T_a_c = T_a_b @ T_b_c
    p_c = np.array([0.3, -0.2, 0.7, 1.0])
    np.testing.assert_allclose(T_a_c @ p_c, T_a_b @ (T_b_c @ p_c), atol=1e-12)
    np.testing.assert_allclose(g.invert(T_a_b) @ T_a_b, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(g.invert(T_a_b), np.linalg.inv(T_a_b), atol=1e-12)


def test_rotations_are_right_handed():
    np.testing.assert_allclose(g.rot_z(math.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(g.rot_x(math.pi / 2) @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(g.rot_y(math.pi / 2) @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    # Positive pitch (about +y) tips the x axis down: nose-down for a quadcopter.
    assert (g.rot_y(0.1) @ [1, 0, 0])[2] < 0


@given(coords, coords, angles, coords)
def test_se2_round_trip(x, y, yaw, z):
    T = g.se2_to_se3(x, y, yaw, z)
    x2, y2, yaw2 = g.se3_to_se2(T)
    assert x2 == pytest.approx(x) and y2 == pytest.approx(y)
    assert abs(g.wrap_angle(yaw2 - yaw)) < 1e-9
    assert T[2, 3] == z


def test_wrap_angle():
    assert g.wrap_angle(math.pi + 0.1) == pytest.approx(-math.pi + 0.1)
    assert g.wrap_angle(-math.pi - 0.1) == pytest.approx(math.pi - 0.1)
    np.testing.assert_allclose(g.wrap_angle(np.array([0.0, 2 * math.pi, 3 * math.pi])), [0.0, 0.0, -math.pi], atol=1e-12)


def test_mount_rotations_are_proper_and_point_the_right_way():
    for R in (g.R_BODY_CAM_DOWN, g.R_BODY_CAM_FORWARD, g.R_BODY_BOARD_UP, g.R_BODY_BOARD_BACK, g.R_BODY_CAM_BACKWARD, g.R_BODY_BOARD_FRONT):
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
    # Column 2 of R_b_c is the optical axis in the body frame.
    np.testing.assert_allclose(g.R_BODY_CAM_DOWN[:, 2], [0, 0, -1])
    np.testing.assert_allclose(g.R_BODY_CAM_DOWN[:, 1], [-1, 0, 0])  # image down = backward: top of image looks forward
    np.testing.assert_allclose(g.R_BODY_CAM_FORWARD[:, 2], [1, 0, 0])
    np.testing.assert_allclose(g.R_BODY_CAM_FORWARD[:, 1], [0, 0, -1])  # image y points down in the world
    # Board on the back: printed face (z_M) looks backward, its y axis up.
    np.testing.assert_allclose(g.R_BODY_BOARD_BACK[:, 2], [-1, 0, 0])
    np.testing.assert_allclose(g.R_BODY_BOARD_BACK[:, 1], [0, 0, 1])
    np.testing.assert_allclose(g.R_BODY_CAM_BACKWARD[:, 2], [-1, 0, 0])
    np.testing.assert_allclose(g.R_BODY_CAM_BACKWARD[:, 1], [0, 0, -1])
    np.testing.assert_allclose(g.R_BODY_BOARD_FRONT[:, 2], [1, 0, 0])
    np.testing.assert_allclose(g.R_BODY_BOARD_FRONT[:, 1], [0, 0, 1])


def test_forward_camera_sees_back_board_face_on():
    # Follower at the origin, leader 0.6 m ahead; the camera looks at the printed face.
    T_w_cam = g.make_transform(g.R_BODY_CAM_FORWARD, [0.2, 0.0, 0.3])
    T_w_board = g.make_transform(g.R_BODY_BOARD_BACK, [0.6, 0.0, 0.3])
    T_c_m = g.invert(T_w_cam) @ T_w_board
    np.testing.assert_allclose(T_c_m[:3, 3], [0.0, 0.0, 0.4], atol=1e-12)
    # The board's z (out of the face) points back at the camera: -z_c.
    np.testing.assert_allclose(T_c_m[:3, 2], [0, 0, -1], atol=1e-12)


def test_quaternion_matches_hand_values():
    q = g.matrix_to_quaternion(g.rot_z(math.pi / 2))
    np.testing.assert_allclose(q, [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)], atol=1e-12)
    np.testing.assert_allclose(g.matrix_to_quaternion(np.eye(3)), [0, 0, 0, 1])
    # 180 deg about x: w = 0, any sign convention gives |qx| = 1.
    np.testing.assert_allclose(np.abs(g.matrix_to_quaternion(g.rot_x(math.pi))), [1, 0, 0, 0], atol=1e-12)


@settings(max_examples=50)
@given(st.lists(st.floats(-3, 3, allow_nan=False), min_size=3, max_size=3))
def test_rotvec_round_trip(v):
    R = g.rotvec_to_matrix(v)
    np.testing.assert_allclose(g.rotvec_to_matrix(g.matrix_to_rotvec(R)), R, atol=1e-9)
    assert g.rotation_angle(R) == pytest.approx(min(np.linalg.norm(v), 2 * math.pi - np.linalg.norm(v)) if np.linalg.norm(v) > math.pi else np.linalg.norm(v), abs=1e-7)


def test_mean_rotation_of_symmetric_spread_is_the_centre():
    centre = g.rot_z(0.7) @ g.rot_x(0.2)
    spread = [centre @ g.rotvec_to_matrix(s * np.array(a)) for a in ([0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05]) for s in (1, -1)]
    np.testing.assert_allclose(g.mean_rotation(spread), centre, atol=1e-12)


def test_mean_pose_averages_translation_and_rotation():
    rng = np.random.default_rng(3)
    truth = random_pose(rng)
    samples = []
    for _ in range(400):
        noise = g.make_transform(g.rotvec_to_matrix(rng.normal(scale=0.01, size=3)), rng.normal(scale=0.01, size=3))
        samples.append(truth @ noise)
    m = g.mean_pose(samples)
    assert np.linalg.norm(m[:3, 3] - truth[:3, 3]) < 0.003
    assert g.rotation_angle(m[:3, :3].T @ truth[:3, :3]) < 0.003
    single = samples[0]
    assert np.linalg.norm(single[:3, 3] - truth[:3, 3]) > np.linalg.norm(m[:3, 3] - truth[:3, 3])
    np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-12)


def test_mean_of_one_pose_is_that_pose():
    T = random_pose(np.random.default_rng(1))
    np.testing.assert_allclose(g.mean_pose([T]), T, atol=1e-12)


def test_mean_rejects_empty_input():
    with pytest.raises(ValueError, match="non-empty"):
        g.mean_pose([])


def test_projection_keeps_a_proper_rotation():
    M = np.diag([-3.0, -2.0, -1.0])  # det < 0: the smallest singular direction flips
    np.testing.assert_allclose(g.project_to_rotation(M), np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    np.testing.assert_allclose(g.mean_rotation([M]), np.diag([-1.0, -1.0, 1.0]), atol=1e-12)


def test_upright_body_from_mount_recovers_an_upright_body():
    T_b_m = g.make_transform(g.R_BODY_BOARD_BACK, [-0.23, 0.05, 0.3])
    T_w_b = g.se2_to_se3(1.0, -2.0, 2.5)
    np.testing.assert_allclose(g.upright_body_from_mount(T_w_b @ T_b_m, T_b_m), T_w_b, atol=1e-12)


def test_upright_projection_removes_the_lever_arm_of_a_tilt():
    # A board 0.4 m above the body, measured with a 0.1 rad tilt about its own centre.
    T_b_m = g.make_transform(None, [0.0, 0.0, 0.4])
    T_w_b = g.se2_to_se3(0.5, 0.5, 0.3)
    T_w_m = T_w_b @ T_b_m @ g.make_transform(g.rot_x(0.1))
    full = T_w_m @ g.invert(T_b_m)
    upright = g.upright_body_from_mount(T_w_m, T_b_m)
    assert np.linalg.norm(full[:2, 3] - T_w_b[:2, 3]) == pytest.approx(0.4 * math.sin(0.1))
    np.testing.assert_allclose(upright[:2, 3], T_w_b[:2, 3], atol=1e-12)
    assert g.yaw_of(upright) == pytest.approx(0.3)


def test_interpolate_pose_ends_and_midpoint() -> None:
    from moma_env.geometry import interpolate_pose, make_transform, rot_x, rot_z, rotation_angle

    T0 = make_transform(rot_z(0.2), [1.0, 2.0, 3.0])
    T1 = make_transform(rot_z(0.2) @ rot_x(0.6), [3.0, 2.0, 1.0])
    assert np.allclose(interpolate_pose(T0, T1, 0.0), T0)
    assert np.allclose(interpolate_pose(T0, T1, 1.0), T1)
    mid = interpolate_pose(T0, T1, 0.5)
    assert np.allclose(mid[:3, 3], [2.0, 2.0, 2.0])
    assert rotation_angle(T0[:3, :3].T @ mid[:3, :3]) == pytest.approx(0.3)
    assert rotation_angle(mid[:3, :3].T @ T1[:3, :3]) == pytest.approx(0.3)


def test_fit_rigid_2d_recovers_a_planar_pose_and_rejects_bad_input() -> None:
    from moma_env.geometry import fit_rigid_2d

    rng = np.random.default_rng(0)
    q = rng.uniform(-1.0, 1.0, (10, 2))
    x, y, yaw = 0.3, -0.7, 2.5
    c, s = math.cos(yaw), math.sin(yaw)
    p = q @ np.array([[c, -s], [s, c]]).T + (x, y)
    assert np.allclose(fit_rigid_2d(p, q), (x, y, yaw))
    with pytest.raises(ValueError, match="at least 2"):
        fit_rigid_2d(p[:1], q[:1])
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        fit_rigid_2d(p, q[:5])


def test_hypot_kernel_is_math_hypot_bit_for_bit():
    """The compiled hypot repeats Python's (not the C library's, which differs in the last
    bit now and then) at every scale of normal floats, zeros, infinities and NaN included;
    with a subnormal larger magnitude, within one unit of the last place."""
    rng = np.random.default_rng(0)
    pairs = [tuple(p) for scale in (1e-300, 1e-150, 1e-3, 1.0, 7.0, 1e150, 1e300) for p in rng.normal(0.0, scale, (20000, 2))]
    pairs += [(0.0, 0.0), (-0.0, 0.0), (0.0, -3.0), (3.0, 4.0), (1.0, 1e-17), (1e-300, 5e-324), (math.inf, math.nan), (math.nan, 1.0), (-math.inf, 2.0)]
    pairs = [(x, y) for x, y in pairs if max(abs(x), abs(y)) >= sys.float_info.min or max(abs(x), abs(y)) == 0.0]
    assert len(pairs) > 139000
    for x, y in pairs:
        got, want = g.hypot_kernel(x, y), math.hypot(x, y)
        assert got == want or (math.isnan(got) and math.isnan(want)), (x, y, got, want)
    for x, y in rng.normal(0.0, 1e-310, (2000, 2)):
        assert abs(g.hypot_kernel(x, y) - math.hypot(x, y)) <= math.ulp(math.hypot(x, y))
