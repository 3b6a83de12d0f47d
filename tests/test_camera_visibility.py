"""Marker visibility: front, image, lens fold, size, incidence, range, occlusion.

Most scenes put the camera at the world origin (T_w_c = I), so world = camera
frame C (x right, y down, z forward). Each negative case comes with a control that
changes only the quantity under test and is visible.
"""

import math

import numpy as np
import pytest

from moma_env.camera import CameraConfig, PinholeCamera, marker_visibility, visible_markers
from moma_env.geometry import (
    R_BODY_BOARD_UP,
    R_BODY_CAM_DOWN,
    invert,
    make_transform,
    rot_x,
    rot_y,
    se2_to_se3,
)
from moma_env.markers import BoardLayout

I4 = np.eye(4)
#: Board facing a camera that looks along +z: x_M = x_C, y_M = -y_C, z_M = -z_C.
R_FACING = np.diag([1.0, -1.0, -1.0])
BOARD = BoardLayout()


def facing(x: float, y: float, z: float, tilt: float = 0.0) -> np.ndarray:
    """Pose in C of a board at (x, y, z) facing the camera, tilted by ``tilt`` rad about x_M."""
    return make_transform(R_FACING @ rot_x(tilt), [x, y, z])


def test_board_straight_ahead_is_fully_visible():
    cam = PinholeCamera(CameraConfig())
    assert visible_markers(cam, I4, facing(0.0, 0.0, 1.5), BOARD).tolist() == [True] * 4


def test_board_under_a_downward_camera_is_visible():
    cam = PinholeCamera(CameraConfig())
    T_w_c = se2_to_se3(0.0, 0.0, 0.4, 2.0) @ make_transform(R_BODY_CAM_DOWN)
    T_w_m = se2_to_se3(0.1, -0.1, 1.0, 0.4) @ make_transform(R_BODY_BOARD_UP)
    assert visible_markers(cam, T_w_c, T_w_m, BOARD).all()


def test_board_behind_the_camera_is_not_visible():
    cam = PinholeCamera(CameraConfig())
    # Behind the camera and turned towards it: only the "in front" check fails.
    T_c_m = make_transform(rot_y(math.pi) @ R_FACING, [0.0, 0.0, -1.5])
    assert not visible_markers(cam, I4, T_c_m, BOARD).any()


def test_board_outside_the_image_is_not_visible():
    cam = PinholeCamera(CameraConfig(max_incidence_deg=90.0))
    assert not visible_markers(cam, I4, facing(2.5, 0.0, 1.5), BOARD).any()
    assert not visible_markers(cam, I4, facing(0.0, -2.0, 1.5), BOARD).any()
    assert visible_markers(cam, I4, facing(0.6, 0.0, 1.5), BOARD).all()


def test_board_too_far_is_not_visible():
    big = BoardLayout(marker_size=1.0, gap=0.1)  # large enough in pixels at 9 m
    cam = PinholeCamera(CameraConfig(max_range_m=8.0))
    assert visible_markers(cam, I4, facing(0.0, 0.0, 7.5), big).all()
    assert not visible_markers(cam, I4, facing(0.0, 0.0, 8.5), big).any()
    assert visible_markers(PinholeCamera(CameraConfig(max_range_m=9.0)), I4, facing(0.0, 0.0, 8.5), big).all()


def test_board_too_small_in_the_image_is_not_visible():
    cam = PinholeCamera(CameraConfig(min_marker_px=12.0))
    # A 16 cm marker is about 420 * 0.16 / d px wide: 13.4 px at 5 m, 11.2 px at 6 m.
    assert visible_markers(cam, I4, facing(0.0, 0.0, 5.0), BOARD).all()
    assert not visible_markers(cam, I4, facing(0.0, 0.0, 6.0), BOARD).any()
    assert visible_markers(PinholeCamera(CameraConfig(min_marker_px=10.0)), I4, facing(0.0, 0.0, 6.0), BOARD).all()


def test_board_seen_at_grazing_incidence_is_not_visible():
    cam = PinholeCamera(CameraConfig(max_incidence_deg=70.0))
    assert visible_markers(cam, I4, facing(0.0, 0.0, 0.8, tilt=math.radians(65.0)), BOARD).all()
    assert not visible_markers(cam, I4, facing(0.0, 0.0, 0.8, tilt=math.radians(75.0)), BOARD).any()
    wide = PinholeCamera(CameraConfig(max_incidence_deg=80.0))
    assert visible_markers(wide, I4, facing(0.0, 0.0, 0.8, tilt=math.radians(75.0)), BOARD).all()


def test_back_of_a_board_is_not_visible():
    cam = PinholeCamera(CameraConfig(max_incidence_deg=90.0))
    back = make_transform(rot_y(math.pi) @ R_FACING, [0.0, 0.0, 1.5])
    assert not visible_markers(cam, I4, back, BOARD).any()


def test_board_half_outside_the_image_keeps_the_inner_markers():
    cfg = CameraConfig()
    cam = PinholeCamera(cfg)
    # Put the gap between the board's columns on the ray through the right image
    # edge (margin included), 1 m away: the left column (ids 0, 2) is inside.
    x_edge = cam.undistort(np.array([[cfg.width - 0.5 - cfg.margin_px, cfg.cy]]))[0, 0]
    T_c_m = facing(x_edge, 0.0, 1.0)
    mask = visible_markers(cam, I4, T_c_m, BOARD)
    assert mask.tolist() == [True, False, True, False]
    # Consistent with the projected corners.
    corners_c = BOARD.marker_corners @ T_c_m[:3, :3].T + T_c_m[:3, 3]
    np.testing.assert_array_equal(cam.in_image(cam.project(corners_c)).all(axis=1), mask)


def test_lens_fold_does_not_bring_far_off_axis_markers_into_view():
    cfg = CameraConfig(dist=(-0.1,), min_marker_px=0.0, max_incidence_deg=90.0)
    cam = PinholeCamera(cfg)
    assert math.isfinite(cam.fold_r2)
    # A board 72 degrees off axis (normalised radius 3, beyond the fold), turned to
    # face the camera: the distortion polynomial maps it back into the image.
    centre = np.array([3.0, 0.0, 1.0])
    z_m = -centre / np.linalg.norm(centre)
    x_m = np.array([1.0, 0.0, 0.0]) - z_m[0] * z_m
    x_m /= np.linalg.norm(x_m)
    T_c_m = make_transform(np.column_stack([x_m, np.cross(z_m, x_m), z_m]), centre)
    small = BoardLayout(marker_ids=(0,), rows=1, cols=1, marker_size=0.02)
    corners_c = small.marker_corners @ T_c_m[:3, :3].T + T_c_m[:3, 3]
    assert cam.in_image(cam.project(corners_c)).all()
    assert not visible_markers(cam, I4, T_c_m, small).any()
    # Every other check passes (in front, in the image, in range, size and incidence
    # limits off); the corners lie beyond the fold radius, which is what rejects it.
    assert (np.sum((corners_c[..., :2] / corners_c[..., 2:]) ** 2, axis=-1) > cam.fold_r2).all()


def test_occlusion_query_gets_world_points_and_hides_markers():
    cam = PinholeCamera(CameraConfig())
    T_w_c = se2_to_se3(0.5, 0.2, 0.3, 2.0) @ make_transform(R_BODY_CAM_DOWN)
    T_w_m = se2_to_se3(0.45, 0.25, -0.2, 0.4)
    centres_w = BOARD.marker_corners.mean(axis=1) @ T_w_m[:3, :3].T + T_w_m[:3, 3]
    calls = []

    def block_marker_1(p_from, p_to):
        calls.append((p_from.copy(), p_to.copy()))
        return bool(np.allclose(p_to, centres_w[1]))

    mask = visible_markers(cam, T_w_c, T_w_m, BOARD, occluded=block_marker_1)
    assert mask.tolist() == [True, False, True, True]
    assert len(calls) == 4
    for (p_from, p_to), centre in zip(calls, centres_w):
        np.testing.assert_allclose(p_from, T_w_c[:3, 3], atol=1e-12)
        np.testing.assert_allclose(p_to, centre, atol=1e-12)
    assert not visible_markers(cam, T_w_c, T_w_m, BOARD, occluded=lambda a, b: True).any()


def test_occlusion_is_not_asked_for_geometrically_hidden_markers():
    cam = PinholeCamera(CameraConfig())
    calls = []
    visible_markers(cam, I4, facing(0.0, 0.0, -1.0), BOARD, occluded=lambda a, b: calls.append(1) or False)
    assert calls == []


def test_marker_visibility_batches_several_boards():
    cam = PinholeCamera(CameraConfig())
    poses = [facing(0.0, 0.0, 1.5), facing(0.0, 0.0, 6.0), facing(0.0, 0.0, -1.0)]
    corners = np.concatenate([BOARD.marker_corners @ T[:3, :3].T + T[:3, 3] for T in poses])
    normals = np.repeat([T[:3, 2] for T in poses], 4, axis=0)
    visible, px = marker_visibility(cam, corners, normals)
    assert visible.tolist() == [True] * 4 + [False] * 8
    assert px.shape == (12, 4, 2)
    np.testing.assert_allclose(px[:4], cam.project(corners[:4]), atol=0)
    assert np.isnan(px[8:]).all()


def test_visible_markers_rejects_bad_poses():
    cam = PinholeCamera(CameraConfig())
    with pytest.raises(ValueError, match="T_w_c"):
        visible_markers(cam, np.eye(3), I4, BOARD)
    with pytest.raises(ValueError, match="T_w_m"):
        visible_markers(cam, I4, np.full((4, 4), np.nan), BOARD)


def test_world_and_camera_frame_scenes_agree():
    cam = PinholeCamera(CameraConfig())
    T_w_c = se2_to_se3(1.0, -2.0, 2.5, 1.7) @ make_transform(rot_x(0.12) @ R_BODY_CAM_DOWN)
    rng = np.random.default_rng(11)
    for _ in range(50):
        T_w_m = se2_to_se3(1.0 + rng.uniform(-1.5, 1.5), -2.0 + rng.uniform(-1.5, 1.5), rng.uniform(-3, 3), 0.4)
        np.testing.assert_array_equal(
            visible_markers(cam, T_w_c, T_w_m, BOARD), visible_markers(cam, I4, invert(T_w_c) @ T_w_m, BOARD)
        )
