"""The geometric camera backend: exact poses without noise, noise statistics, determinism."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.camera import BoardView, CameraBackend, CameraConfig, GeometricCamera
from moma_env.estimator.detection import Detection
from moma_env.geometry import (
    R_BODY_BOARD_BACK,
    R_BODY_BOARD_UP,
    R_BODY_CAM_DOWN,
    R_BODY_CAM_FORWARD,
    invert,
    make_transform,
    rot_x,
    rot_y,
    rotation_angle,
    se2_to_se3,
)
from moma_env.markers import BoardLayout, board_for_robot

BOARD_HEIGHT = 0.4  # m, board on top of a Robotino


def uav_camera(x, y, yaw, altitude, roll=0.0, pitch=0.0):
    """World pose of a UAV's downward camera; the body tilts by roll/pitch."""
    T_w_b = se2_to_se3(x, y, yaw, altitude) @ make_transform(rot_x(roll) @ rot_y(pitch))
    return T_w_b @ make_transform(R_BODY_CAM_DOWN)


def floor_board(board_id, x, y, yaw):
    """A board face-up on top of robot ``board_id`` at planar pose (x, y, yaw)."""
    T_w_m = se2_to_se3(x, y, yaw, BOARD_HEIGHT) @ make_transform(R_BODY_BOARD_UP)
    return BoardView(board_id, board_for_robot(board_id), T_w_m)


def assert_pose_exact(det, T_w_c, boards, atol_m=1e-6, atol_rad=1e-6):
    truth = invert(T_w_c) @ boards[det.board_id].T_w_m
    np.testing.assert_allclose(det.T_c_m[:3, 3], truth[:3, 3], rtol=0, atol=atol_m)
    assert rotation_angle(det.T_c_m[:3, :3].T @ truth[:3, :3]) <= atol_rad
    np.testing.assert_array_equal(det.T_c_m[3], [0, 0, 0, 1])


def true_corners_px(cam, T_w_c, board, marker_ids):
    """Noise-free pixels of the given markers of ``board``, in detection order."""
    T_c_m = invert(T_w_c) @ board.T_w_m
    sel = [board.layout.marker_ids.index(i) for i in marker_ids]
    pts = board.layout.marker_corners[sel].reshape(-1, 3)
    return cam.camera.project(pts @ T_c_m[:3, :3].T + T_c_m[:3, 3])


def test_geometric_camera_implements_the_backend_interface():
    cam = GeometricCamera("uav", CameraConfig())
    assert isinstance(cam, CameraBackend)
    assert cam.camera.config is cam.config


# ---------------------------------------------------------------- zero noise: exact poses


@settings(max_examples=150, deadline=None)
@given(
    x=st.floats(-2.0, 2.0),
    y=st.floats(-2.0, 2.0),
    yaw=st.floats(-math.pi, math.pi),
    altitude=st.floats(1.2, 3.0),
    roll=st.floats(-0.15, 0.15),
    pitch=st.floats(-0.15, 0.15),
    offsets=st.lists(
        st.tuples(st.floats(-1.2, 1.2), st.floats(-1.2, 1.2), st.floats(-math.pi, math.pi)), min_size=1, max_size=3
    ),
)
def test_zero_noise_uav_recovers_floor_boards_exactly(x, y, yaw, altitude, roll, pitch, offsets):
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.0))
    T_w_c = uav_camera(x, y, yaw, altitude, roll, pitch)
    # Board 0 right under the camera (always seen), the others anywhere around.
    boards = [floor_board(0, x + 0.1 * offsets[0][0], y + 0.1 * offsets[0][1], offsets[0][2])]
    boards += [floor_board(i, x + dx, y + dy, th) for i, (dx, dy, th) in enumerate(offsets[1:], start=1)]
    dets = cam.measure(T_w_c, boards, 2.5, np.random.default_rng(0))
    assert dets and dets[0].board_id == 0
    assert [d.board_id for d in dets] == sorted(d.board_id for d in dets)
    for det in dets:
        assert_pose_exact(det, T_w_c, boards)
        assert det.camera_id == "uav" and det.time == 2.5
        np.testing.assert_allclose(
            det.corners_px, true_corners_px(cam, T_w_c, boards[det.board_id], det.marker_ids), rtol=0, atol=1e-9
        )
        assert det.reprojection_error_px < 1e-6


@settings(max_examples=100, deadline=None)
@given(
    distance=st.floats(0.45, 2.5),
    lateral=st.floats(-0.2, 0.2),
    leader_yaw=st.floats(-0.4, 0.4),
    board_height=st.floats(0.25, 0.4),
)
def test_zero_noise_forward_camera_recovers_a_vertical_board_exactly(distance, lateral, leader_yaw, board_height):
    cam = GeometricCamera("follower", CameraConfig(noise_px=0.0))
    T_w_c = se2_to_se3(0.0, 0.0, 0.0, 0.3) @ make_transform(R_BODY_CAM_FORWARD)
    # The leader drives ahead; its board is on its back, facing backwards.
    T_w_m = se2_to_se3(distance + 0.2, lateral, leader_yaw, board_height) @ make_transform(
        R_BODY_BOARD_BACK, [-0.2, 0.0, 0.0]
    )
    boards = [BoardView(0, board_for_robot(0), T_w_m)]
    dets = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(0))
    assert len(dets) == 1
    assert_pose_exact(dets[0], T_w_c, boards)


@pytest.mark.parametrize("method", ["IPPE", "ITERATIVE", "SQPNP"])
def test_every_pnp_method_is_exact_without_noise(method):
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.0, pnp_method=method))
    rng = np.random.default_rng(4)
    for _ in range(20):
        T_w_c = uav_camera(0.0, 0.0, rng.uniform(-3, 3), rng.uniform(1.2, 2.5), *rng.uniform(-0.15, 0.15, 2))
        boards = [floor_board(0, *rng.uniform(-0.3, 0.3, 2), rng.uniform(-3, 3))]
        (det,) = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(0))
        assert_pose_exact(det, T_w_c, boards)


@pytest.mark.parametrize("method", ["IPPE", "ITERATIVE", "SQPNP"])
def test_face_on_boards_are_exact_in_every_in_plane_rotation(method):
    # Face-on views are singular for OpenCV's IPPE (180 degree rotation in M, NaN
    # when the board normal is along the ray to its centre): a hovering UAV right
    # above a robot is the most common view of the simulation.
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.0, pnp_method=method))
    angles = np.arange(8) * math.pi / 4
    for cam_yaw in angles:
        for board_yaw in angles:
            for tilt in (0.0, 0.08):
                T_w_c = uav_camera(0.0, 0.0, cam_yaw, 1.6, roll=tilt)
                boards = [floor_board(0, 0.0, 0.0, board_yaw)]
                (det,) = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(0))
                assert_pose_exact(det, T_w_c, boards)
    # A forward camera squarely facing a vertical board.
    T_w_c = se2_to_se3(0.0, 0.0, 0.0, 0.3) @ make_transform(R_BODY_CAM_FORWARD)
    T_w_m = se2_to_se3(1.0, 0.0, 0.0, 0.3) @ make_transform(R_BODY_BOARD_BACK)
    (det,) = cam.measure(T_w_c, [BoardView(0, BoardLayout(), T_w_m)], 0.0, np.random.default_rng(0))
    assert_pose_exact(det, T_w_c, [BoardView(0, BoardLayout(), T_w_m)])


def test_single_visible_marker_is_enough():
    cam = GeometricCamera("fwd", CameraConfig(noise_px=0.0))
    T_c_m = make_transform(np.diag([1.0, -1.0, -1.0]), [0.0, 0.0, 1.0])  # board facing the camera
    # Move the board right and down so that only its top-left marker (id 0) stays in view.
    x_edge = cam.camera.undistort(np.array([[714.5, 570.5]]))[0]
    T_c_m[:3, 3] = [x_edge[0], x_edge[1], 1.0]
    boards = [BoardView(3, BoardLayout(), T_c_m)]
    (det,) = cam.measure(np.eye(4), boards, 0.0, np.random.default_rng(0))
    assert det.marker_ids == (0,) and det.n_markers == 1
    assert det.corners_px.shape == (4, 2)
    assert_pose_exact(det, np.eye(4), {3: boards[0]})


# ---------------------------------------------------------------- visibility through measure


def test_board_half_outside_the_image_is_detected_from_its_visible_markers():
    cam = GeometricCamera("fwd", CameraConfig(noise_px=0.0))
    cfg = cam.config
    x_edge = cam.camera.undistort(np.array([[cfg.width - 0.5 - cfg.margin_px, cfg.cy]]))[0, 0]
    boards = [BoardView(7, board_for_robot(1), make_transform(np.diag([1.0, -1.0, -1.0]), [x_edge, 0.0, 1.0]))]
    (det,) = cam.measure(np.eye(4), boards, 0.0, np.random.default_rng(0))
    assert det.board_id == 7
    assert det.marker_ids == (4, 6)  # the left column of robot 1's board
    assert det.corners_px.shape == (8, 2)
    assert_pose_exact(det, np.eye(4), {7: boards[0]})


def test_invisible_boards_are_dropped_and_order_is_kept():
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.5))
    T_w_c = uav_camera(0.0, 0.0, 0.0, 2.0)
    boards = [
        floor_board(2, 0.3, 0.1, 0.0),
        floor_board(0, 5.0, 5.0, 0.0),  # far outside the view
        floor_board(1, -0.3, -0.1, 1.0),
    ]
    dets = cam.measure(T_w_c, boards, 1.0, np.random.default_rng(0))
    assert [d.board_id for d in dets] == [2, 1]
    assert all(isinstance(d, Detection) for d in dets)
    assert cam.measure(T_w_c, [], 1.0, np.random.default_rng(0)) == []
    assert cam.measure(T_w_c, boards[1:2], 1.0, np.random.default_rng(0)) == []


def test_occluded_markers_are_left_out():
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.0))
    T_w_c = uav_camera(0.0, 0.0, 0.0, 2.0)
    boards = [floor_board(0, 0.0, 0.0, 0.0), floor_board(1, 0.6, 0.0, 0.0)]

    def wall_at_x_0_3(p_from, p_to):  # blocks lines of sight ending beyond x = 0.3
        return bool(p_to[0] > 0.3)

    dets = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(0), occluded=wall_at_x_0_3)
    assert [d.board_id for d in dets] == [0]
    assert dets[0].marker_ids == (0, 1, 2, 3)


# ---------------------------------------------------------------- noise


def noisy_scene(noise_px, method="IPPE"):
    cam = GeometricCamera("uav", CameraConfig(noise_px=noise_px, pnp_method=method))
    T_w_c = uav_camera(0.2, -0.1, 0.5, 1.8, roll=0.05, pitch=-0.03)
    boards = [floor_board(0, 0.35, -0.2, 0.3), floor_board(1, -0.2, 0.15, 2.0)]
    return cam, T_w_c, boards


def test_same_seed_gives_identical_detections():
    cam, T_w_c, boards = noisy_scene(0.7)
    a = cam.measure(T_w_c, boards, 3.0, np.random.default_rng(123))
    b = cam.measure(T_w_c, boards, 3.0, np.random.default_rng(123))
    c = cam.measure(T_w_c, boards, 3.0, np.random.default_rng(124))
    assert len(a) == len(b) == 2
    for da, db in zip(a, b):
        np.testing.assert_array_equal(da.T_c_m, db.T_c_m)
        np.testing.assert_array_equal(da.corners_px, db.corners_px)
        assert da.marker_ids == db.marker_ids and da.reprojection_error_px == db.reprojection_error_px
    assert not np.array_equal(a[0].corners_px, c[0].corners_px)


def test_zero_noise_draws_nothing_from_the_generator():
    cam, T_w_c, boards = noisy_scene(0.0)
    rng = np.random.default_rng(9)
    before = rng.bit_generator.state
    assert len(cam.measure(T_w_c, boards, 0.0, rng)) == 2
    assert rng.bit_generator.state == before


def test_corner_noise_has_the_configured_std():
    noise = 0.8
    cam, T_w_c, boards = noisy_scene(noise)
    rng = np.random.default_rng(2024)
    residuals = []
    for _ in range(400):
        for det in cam.measure(T_w_c, boards, 0.0, rng):
            residuals.append(det.corners_px - true_corners_px(cam, T_w_c, boards[det.board_id], det.marker_ids))
    r = np.concatenate(residuals)
    assert r.shape == (400 * 32, 2)
    # 25600 samples: the std of the sample std is ~0.4 %; allow 3 %.
    assert np.std(r) == pytest.approx(noise, rel=0.03)
    assert np.std(r[:, 0]) == pytest.approx(noise, rel=0.04) and np.std(r[:, 1]) == pytest.approx(noise, rel=0.04)
    assert abs(r.mean()) < 0.02


@pytest.mark.parametrize("method", ["IPPE", "ITERATIVE"])
def test_pose_error_grows_with_noise(method):
    def mean_errors(noise_px):
        cam, T_w_c, boards = noisy_scene(noise_px, method)
        rng = np.random.default_rng(77)
        t_err, r_err, reproj = [], [], []
        for _ in range(150):
            for det in cam.measure(T_w_c, boards, 0.0, rng):
                truth = invert(T_w_c) @ boards[det.board_id].T_w_m
                t_err.append(np.linalg.norm(det.T_c_m[:3, 3] - truth[:3, 3]))
                r_err.append(rotation_angle(det.T_c_m[:3, :3].T @ truth[:3, :3]))
                reproj.append(det.reprojection_error_px)
        return np.mean(t_err), np.mean(r_err), np.mean(reproj)

    t_small, r_small, e_small = mean_errors(0.25)
    t_large, r_large, e_large = mean_errors(2.0)
    assert 0.0 < t_small and 0.0 < r_small
    assert t_large > 3.0 * t_small and r_large > 3.0 * r_small
    # The RMS corner distance after the fit follows the pixel noise: about
    # sigma * sqrt(2) (two coordinates), a bit less as the pose absorbs some.
    for e, sigma in ((e_small, 0.25), (e_large, 2.0)):
        assert 0.8 * math.sqrt(2) * sigma < e < math.sqrt(2) * sigma
    # Half a pixel of noise at 1.4 m: millimetres, not centimetres.
    assert t_small < 0.01


# ---------------------------------------------------------------- bad input


def test_bad_inputs_raise_clear_errors():
    cam, T_w_c, boards = noisy_scene(0.5)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="T_w_c"):
        cam.measure(np.eye(3), boards, 0.0, rng)
    with pytest.raises(ValueError, match="T_w_c"):
        cam.measure(np.full((4, 4), np.nan), boards, 0.0, rng)
    with pytest.raises(ValueError, match="time"):
        cam.measure(T_w_c, boards, math.nan, rng)
    with pytest.raises(TypeError, match="Generator"):
        cam.measure(T_w_c, boards, 0.0, np.random.RandomState(0))
    with pytest.raises(ValueError, match="camera_id"):
        GeometricCamera("", CameraConfig())
    with pytest.raises(ValueError, match="T_w_m"):
        BoardView(0, BoardLayout(), np.eye(3))
    with pytest.raises(TypeError, match="board_id"):
        BoardView(1.5, BoardLayout(), np.eye(4))
    with pytest.raises(TypeError, match="layout"):
        BoardView(0, "board", np.eye(4))
    assert BoardView(np.int64(3), BoardLayout(), np.eye(4)).board_id == 3
