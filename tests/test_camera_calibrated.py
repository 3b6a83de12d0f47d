"""The authors' calibrated observer camera (tud_momana ardrone_ext_cam.yaml) through the whole camera model.

Non-square pixels (fx = 492.9, fy = 526.0 px), a principal point off the image
centre and a strong barrel distortion (k1 = -0.419, k2 = 0.152, small p1, p2):
projection, undistortion, visibility, the rendered floor and a board imaged in
a corner of the image, where the distortion is strongest.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from moma_env.camera import BoardView, CameraConfig, GeometricCamera, PinholeCamera, RenderConfig, RenderedCamera, visible_markers
from moma_env.camera.kernels import camera_parameters, undistort_points
from moma_env.camera.rays import PixelRays
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_CAM_DOWN, invert, make_transform, rotation_angle
from moma_env.markers import board_for_robot
from training.experiments.presets import PAPER, PAPER_CAMERA

CAMERA = PinholeCamera(PAPER_CAMERA)
LAYOUT = board_for_robot(0, marker_size=0.16, gap=0.02)


def test_the_preset_holds_the_published_calibration():
    cfg = PAPER.camera
    assert (cfg.width, cfg.height) == (720, 576)
    assert (cfg.fx, cfg.fy, cfg.cx, cfg.cy) == (492.856172, 526.006429, 338.263513, 257.626108)
    assert cfg.dist == (-0.419143, 0.152472, 0.000282, -0.001497, 0.0)
    np.testing.assert_array_equal(CAMERA.K, [[492.856172, 0.0, 338.263513], [0.0, 526.006429, 257.626108], [0.0, 0.0, 1.0]])


def test_the_lens_does_not_fold_but_its_k1_alone_would():
    # 9 k1^2 < 20 k2: the radial mapping increases everywhere.
    assert CAMERA.fold_r2 == math.inf
    r = np.linspace(0.0, 3.0, 3001)
    k1, k2 = PAPER_CAMERA.dist[:2]
    assert np.all(np.diff(r * (1 + k1 * r**2 + k2 * r**4)) > 0.0)
    # Without k2 the same k1 folds at r = 0.89, inside the image (corner radius 0.98): rejected.
    with pytest.raises(ConfigError, match="camera.dist.*folds"):
        CameraConfig(width=720, height=576, fx=492.856172, fy=526.006429, cx=338.263513, cy=257.626108, dist=(-0.419143,))


def test_field_of_view_is_wide_and_asymmetric():
    h_fov, v_fov = CAMERA.field_of_view_deg
    assert 88.0 < h_fov < 91.0 and 64.0 < v_fov < 67.0
    # The principal point sits 30 px above the image centre: the narrowest half view is upward.
    up = -CAMERA.undistort(np.array([[PAPER_CAMERA.cx, PAPER_CAMERA.margin_px - 0.5]]))[0, 1]
    assert CAMERA.axis_half_view_tan == pytest.approx(up)
    assert CAMERA.axis_half_view_tan < (PAPER_CAMERA.height / 2) / PAPER_CAMERA.fy


def _whole_image_grid(step: float = 3.0) -> np.ndarray:
    u, v = np.meshgrid(np.arange(-0.5, 720.0, step), np.arange(-0.5, 576.0, step))
    grid = np.column_stack([u.ravel(), v.ravel()])
    return np.vstack([grid, CAMERA.sensor_corners_px])


def test_undistort_then_project_round_trips_over_the_whole_image():
    px = _whole_image_grid()
    xy = CAMERA.undistort(px)
    back = CAMERA.project(np.column_stack([xy, np.ones(len(xy))]))
    assert np.abs(back - px).max() < 1e-9
    # The compiled kernel's undistortion (used by PnP) agrees with OpenCV's.
    kernel_xy = np.empty_like(xy)
    undistort_points(px, camera_parameters(CAMERA), kernel_xy)
    assert np.abs(kernel_xy - xy).max() < 1e-12


def test_projection_matches_cv2_over_the_whole_field_of_view():
    xy = CAMERA.undistort(_whole_image_grid(9.0))
    rng = np.random.default_rng(0)
    points = np.column_stack([xy, np.ones(len(xy))]) * rng.uniform(0.5, 4.0, size=(len(xy), 1))
    expected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), CAMERA.K, CAMERA.dist)
    np.testing.assert_allclose(CAMERA.project(points), expected.reshape(-1, 2), atol=1e-9)


def test_pixel_rays_are_the_undistorted_pixel_centres():
    rays = PixelRays(CAMERA)
    for u, v in ((0, 0), (719, 0), (719, 575), (0, 575), (338, 257)):
        ray = rays.xy[v, u].astype(float)
        np.testing.assert_allclose(CAMERA.project(np.array([*ray, 1.0])), (u, v), atol=2e-4)  # float32 rays


def _board_at_pixel(u: float, v: float, depth: float, T_w_c: np.ndarray) -> np.ndarray:
    """World pose of a floor-parallel board whose centre images at pixel (u, v), ``depth`` m below the camera."""
    x, y = CAMERA.undistort(np.array([[u, v]]))[0]
    centre_w = T_w_c[:3, :3] @ (depth * np.array([x, y, 1.0])) + T_w_c[:3, 3]
    return make_transform(np.eye(3), centre_w)


@pytest.mark.parametrize("corner", [(0, 0), (1, 0), (1, 1), (0, 1)])
def test_a_board_in_an_image_corner_is_visible_detected_and_solved(corner):
    """A board imaged near each corner of the image, where the lens bends and shrinks it most.

    The geometric camera sees all four markers and its noise-free PnP is exact (the
    lens model's projection and undistortion agree there). The rendered camera (clean
    image) detects all four markers with every corner within 2 px of its true
    projection (a lens model off by fy/fx or by the distortion would be tens of px
    off here) and its pose within 5 cm and 2 degrees of the truth, 2.1 m below:
    ArUco's corner refinement is off by up to ~1.5 px at the 3 px gaps between the
    markers (2 cm, compressed by the lens), which at this range is 2-3.5 cm along
    the line of sight (1.1 cm for the same board at the image centre).
    """
    T_w_c = make_transform(R_BODY_CAM_DOWN, [0.0, 0.0, 2.5])
    depth = 2.1
    # The markers' outermost corner 20-35 px inside the image's edges.
    u = 60.0 if corner[0] == 0 else 660.0
    v = 55.0 if corner[1] == 0 else 521.0
    T_w_m = _board_at_pixel(u, v, depth, T_w_c)
    T_true = invert(T_w_c) @ T_w_m
    corners_px = CAMERA.project(LAYOUT.marker_corners @ T_true[:3, :3].T + T_true[:3, 3])
    assert CAMERA.in_image(corners_px).all()
    image_corner = CAMERA.sensor_corners_px[[0, 1, 3, 2][2 * corner[1] + corner[0]]]
    assert np.min(np.hypot(*(corners_px.reshape(-1, 2) - image_corner).T)) < 60.0
    assert visible_markers(CAMERA, T_w_c, T_w_m, LAYOUT).all()
    [exact] = GeometricCamera("uav", dataclasses.replace(PAPER_CAMERA, noise_px=0.0)).measure(
        T_w_c, [BoardView(0, LAYOUT, T_w_m)], 0.0, np.random.default_rng(0)
    )
    assert len(exact.marker_ids) == 4 and np.abs(exact.T_c_m - T_true).max() < 1e-6
    # Rendered, clean image (no noise): ArUco finds every marker and PnP recovers the pose.
    rendered = RenderedCamera("uav", PAPER_CAMERA, RenderConfig(noise_std=0.0))
    [found] = rendered.measure(T_w_c, [BoardView(0, LAYOUT, T_w_m)], 0.0, np.random.default_rng(1))
    assert len(found.marker_ids) == 4
    order = [list(LAYOUT.marker_ids).index(i) for i in found.marker_ids]
    assert np.abs(found.corners_px - corners_px[order].reshape(-1, 2)).max() < 2.0
    assert np.linalg.norm(found.T_c_m[:3, 3] - T_true[:3, 3]) < 0.05
    assert rotation_angle(found.T_c_m[:3, :3].T @ T_true[:3, :3]) < math.radians(2.0)


def test_a_board_beyond_the_image_corner_is_neither_visible_nor_detected():
    T_w_c = make_transform(R_BODY_CAM_DOWN, [0.0, 0.0, 2.5])
    # Centre imaged 10 px outside the top-left corner: part of the board is outside the image.
    T_w_m = _board_at_pixel(-10.0, -10.0, 2.1, T_w_c)
    assert not visible_markers(CAMERA, T_w_c, T_w_m, LAYOUT).all()
    geometric = GeometricCamera("uav", PAPER_CAMERA)
    seen = geometric.measure(T_w_c, [BoardView(0, LAYOUT, T_w_m)], 0.0, np.random.default_rng(0))
    rendered = RenderedCamera("uav", PAPER_CAMERA, RenderConfig())
    detected = rendered.measure(T_w_c, [BoardView(0, LAYOUT, T_w_m)], 0.0, np.random.default_rng(0))
    for found in (seen, detected):
        assert all(len(d.marker_ids) < 4 for d in found)


def test_floor_seen_through_the_lens_matches_the_exact_per_pixel_map():
    """The observer's floor view (sampling map interpolated from a 4 px grid) against the
    exact map of every pixel's ray: within 0.05 raster px for this lens (the generic lens:
    0.01), i.e. 0.2 mm on a floor 2.1 m below; the rendered floor then differs by at most
    a couple of gray levels on a grainy floor."""
    from moma_env.camera import FloorConfig, FloorGrainConfig, FloorTexture
    from moma_env.geometry import rot_x

    rays = PixelRays(CAMERA)
    floor = FloorTexture(FloorConfig(extent=(-3.0, -3.0, 4.0, 4.0), px_per_m=250.0, textured=(), grain=FloorGrainConfig()))
    for tilt in (0.0, 0.3):
        T_w_c = make_transform(R_BODY_CAM_DOWN @ rot_x(tilt), [0.5, 0.3, 2.1])
        H = floor.homography(T_w_c)
        assert np.abs(rays.smooth_map(H) - rays.sample_map(H)).max() < 0.05
        exact = cv2.remap(floor.raster, rays.sample_map(H), None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=140)
        image = floor.render(rays, T_w_c)
        assert np.abs(image.astype(int) - exact).max() <= 3
