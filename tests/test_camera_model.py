"""CameraConfig validation and the pinhole model (projection, undistortion, FOV, footprint)."""

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.camera import CameraConfig, PinholeCamera
from moma_env.camera.distortion import distorted_radius, fold_radius_sq
from moma_env.config import ConfigError, from_mapping
from moma_env.geometry import R_BODY_CAM_DOWN, R_BODY_CAM_FORWARD, invert, make_transform, rot_x, se2_to_se3

# ---------------------------------------------------------------- configuration


def test_defaults_model_the_pal_camera():
    cfg = CameraConfig()
    assert (cfg.width, cfg.height) == (720, 576)
    assert cfg.fx == cfg.fy == 420.0
    assert (cfg.cx, cfg.cy) == (359.5, 287.5)
    assert len(cfg.dist) == 5 and cfg.dist[0] < 0.0  # mild barrel
    assert cfg.pnp_method == "PLANAR_LM"


def test_fy_and_principal_point_follow_fx_and_size():
    cfg = CameraConfig(width=640, height=480, fx=500.0)
    assert cfg.fy == 500.0
    assert (cfg.cx, cfg.cy) == (319.5, 239.5)
    assert CameraConfig(fx=500.0, fy=510.0).fy == 510.0


def test_integer_like_sizes_are_accepted_as_int():
    cfg = CameraConfig(width=np.int64(640), height=np.int32(480))
    assert (cfg.width, cfg.height) == (640, 480) and type(cfg.width) is int


def test_short_distortion_is_padded_with_zeros():
    assert CameraConfig(dist=(-0.1, 0.02)).dist == (-0.1, 0.02, 0.0, 0.0, 0.0)
    assert CameraConfig(dist=()).dist == (0.0,) * 5


def test_config_from_mapping():
    cfg = from_mapping(CameraConfig, {"fx": 450, "dist": [-0.02, 0.0, 0.0, 0.0]}, name="camera")
    assert cfg.fx == 450.0 and cfg.fy == 450.0
    assert cfg.dist == (-0.02, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ConfigError) as err:
        from_mapping(CameraConfig, {"focal": 450}, name="camera")
    assert err.value.field == "camera.focal"


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"fx": 0.0}, "camera.fx"),
        ({"fx": -420.0}, "camera.fx"),
        ({"fx": math.inf}, "camera.fx"),
        ({"fy": 0.0}, "camera.fy"),
        ({"width": 0}, "camera.width"),
        ({"width": 720.5}, "camera.width"),
        ({"height": -576}, "camera.height"),
        ({"cx": 1000.0}, "camera.cx"),
        ({"cy": math.nan}, "camera.cy"),
        ({"dist": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)}, "camera.dist"),
        ({"dist": (math.nan,)}, "camera.dist"),
        ({"dist": "barrel"}, "camera.dist"),
        ({"dist": (-0.3, 0.0)}, "camera.dist"),  # folds over inside the image
        ({"noise_px": -0.1}, "camera.noise_px"),
        ({"noise_px": math.nan}, "camera.noise_px"),
        ({"margin_px": 300.0}, "camera.margin_px"),
        ({"min_marker_px": -1.0}, "camera.min_marker_px"),
        ({"max_incidence_deg": 0.0}, "camera.max_incidence_deg"),
        ({"max_incidence_deg": 95.0}, "camera.max_incidence_deg"),
        ({"min_range_m": 0.0}, "camera.min_range_m"),
        ({"max_range_m": 0.05}, "camera.max_range_m"),
        ({"pnp_method": "EPNP"}, "camera.pnp_method"),
    ],
)
def test_bad_config_raises_naming_the_field(kwargs, field):
    with pytest.raises(ConfigError) as err:
        CameraConfig(**kwargs)
    assert err.value.field == field
    assert field in str(err.value)


def test_config_is_frozen_and_hashable():
    cfg = CameraConfig()
    with pytest.raises(AttributeError):
        cfg.fx = 1.0  # type: ignore[misc]
    assert hash(cfg) == hash(CameraConfig())


# ---------------------------------------------------------------- projection

@settings(max_examples=60, deadline=None)
@given(
    k1=st.floats(-0.1, 0.15),  # (strong negative k1 folds inside the image: rejected by the config)
    k2=st.floats(0.0, 0.02),
    p1=st.floats(-0.005, 0.005),
    p2=st.floats(-0.005, 0.005),
    k3=st.floats(0.0, 0.005),
    seed=st.integers(0, 2**32 - 1),
)
def test_projection_matches_cv2_project_points(k1, k2, p1, p2, k3, seed):
    cfg = CameraConfig(fx=430.0, fy=415.0, cx=352.0, cy=290.0, dist=(k1, k2, p1, p2, k3))
    cam = PinholeCamera(cfg)
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(-1.0, 1.0, (50, 2)), np.ones(50)]) * rng.uniform(0.2, 9.0, (50, 1))
    expected = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), cam.K, cam.dist)[0].reshape(-1, 2)
    np.testing.assert_allclose(cam.project(pts), expected, rtol=0, atol=1e-9)
    # Batch shape is kept.
    assert cam.project(pts.reshape(5, 10, 3)).shape == (5, 10, 2)


def test_default_projection_matches_cv2():
    cam = PinholeCamera(CameraConfig())
    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(-2.0, 2.0, (200, 2)), rng.uniform(0.3, 6.0, 200)])
    expected = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), cam.K, cam.dist)[0].reshape(-1, 2)
    np.testing.assert_allclose(cam.project(pts), expected, rtol=0, atol=1e-9)


def test_opencv_pixel_convention():
    cam = PinholeCamera(CameraConfig())
    cx, cy = cam.config.cx, cam.config.cy
    # The optical axis hits the principal point, whatever the depth.
    np.testing.assert_array_equal(cam.project(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 7.0]])), [[cx, cy], [cx, cy]])
    u_right, v_right = cam.project(np.array([0.2, 0.0, 1.0]))
    u_down, v_down = cam.project(np.array([0.0, 0.2, 1.0]))
    assert u_right > cx and v_right == pytest.approx(cy)  # +x_C goes right
    assert v_down > cy and u_down == pytest.approx(cx)  # +y_C goes down


def test_points_behind_the_camera_project_to_nan():
    cam = PinholeCamera(CameraConfig())
    px = cam.project(np.array([[0.1, 0.1, -1.0], [0.1, 0.1, 0.0], [0.1, 0.1, 1.0]]))
    assert np.isnan(px[:2]).all() and np.isfinite(px[2]).all()
    assert not cam.in_image(px[:2]).any()


def test_project_rejects_bad_shape():
    with pytest.raises(ValueError):
        PinholeCamera(CameraConfig()).project(np.zeros((4, 2)))


def test_undistort_inverts_project():
    cam = PinholeCamera(CameraConfig(dist=(-0.08, 0.015, 0.001, -0.001, 0.002)))
    rng = np.random.default_rng(5)
    xy = rng.uniform(-0.8, 0.8, (100, 2)) * [1.0, 0.65]
    px = cam.project(np.column_stack([xy, np.ones(100)]))
    assert cam.in_image(px, margin=0).all()
    np.testing.assert_allclose(cam.undistort(px), xy, rtol=0, atol=1e-11)


def test_in_image_uses_the_sensor_extent_and_margin():
    cam = PinholeCamera(CameraConfig(margin_px=5.0))
    px = np.array([[4.5, 100.0], [4.4, 100.0], [714.5, 100.0], [714.6, 100.0], [100.0, 570.5], [100.0, 570.6]])
    np.testing.assert_array_equal(cam.in_image(px), [True, False, True, False, True, False])
    np.testing.assert_array_equal(cam.in_image(np.array([[-0.5, -0.5], [719.5, 575.5], [-0.6, 0.0]]), margin=0),
                                  [True, True, False])


def test_intrinsics_are_read_only():
    cam = PinholeCamera(CameraConfig())
    with pytest.raises(ValueError):
        cam.K[0, 0] = 1.0
    with pytest.raises(ValueError):
        cam.dist[0] = 1.0


# ---------------------------------------------------------------- lens fold


def test_fold_radius_closed_forms():
    assert fold_radius_sq((-0.1, 0.0, 0.0, 0.0, 0.0)) == pytest.approx(1.0 / 0.3)
    assert fold_radius_sq((0.0, -0.01, 0.0, 0.0, 0.0)) == pytest.approx(math.sqrt(1.0 / 0.05))
    assert fold_radius_sq((-0.0625, 0.0, 0.0, 0.0, 1e-300)) == pytest.approx(1.0 / 0.1875)
    assert fold_radius_sq((0.1, 0.0, 0.0, 0.0, 0.0)) == math.inf
    assert fold_radius_sq((0.0,) * 5) == math.inf
    assert fold_radius_sq((-0.05, 0.01, 0.0, 0.0, 0.0)) == math.inf  # the default lens never folds


@settings(max_examples=100, deadline=None)
@given(k1=st.floats(-0.5, 0.5), k2=st.floats(-0.2, 0.2), k3=st.floats(-0.05, 0.05))
def test_distorted_radius_increases_exactly_up_to_the_fold(k1, k2, k3):
    dist = (k1, k2, 0.0, 0.0, k3)
    s_fold = fold_radius_sq(dist)
    s = np.linspace(0.0, min(0.999 * s_fold, 100.0), 3000)
    rd = [distorted_radius(v, dist) for v in s]
    assert np.all(np.diff(rd) > 0.0)
    if math.isfinite(s_fold) and s_fold < 100.0:
        assert distorted_radius(1.01 * s_fold, dist) < distorted_radius(s_fold, dist)


# ---------------------------------------------------------------- field of view and footprint


def test_field_of_view_without_distortion():
    cam = PinholeCamera(CameraConfig(dist=()))
    h, v = cam.field_of_view_deg
    assert h == pytest.approx(2 * math.degrees(math.atan(360.0 / 420.0)), abs=1e-9)
    assert v == pytest.approx(2 * math.degrees(math.atan(288.0 / 420.0)), abs=1e-9)


def test_barrel_distortion_widens_the_field_of_view():
    h0, v0 = PinholeCamera(CameraConfig(dist=())).field_of_view_deg
    h1, v1 = PinholeCamera(CameraConfig()).field_of_view_deg
    assert h1 > h0 + 1.0 and v1 > v0 + 0.5


def test_ground_footprint_of_a_level_downward_camera():
    cam = PinholeCamera(CameraConfig(dist=()))
    T_w_c = se2_to_se3(1.0, 2.0, 0.0, 3.0) @ make_transform(R_BODY_CAM_DOWN)
    fp = cam.ground_footprint(T_w_c, z=0.5)
    half_across = 2.5 * 360.0 / 420.0  # image x = -y_B
    half_along = 2.5 * 288.0 / 420.0  # image y = -x_B, top of the image looks forward
    # Top-left, top-right, bottom-right, bottom-left of the image.
    expected = [
        [1.0 + half_along, 2.0 + half_across],
        [1.0 + half_along, 2.0 - half_across],
        [1.0 - half_along, 2.0 - half_across],
        [1.0 - half_along, 2.0 + half_across],
    ]
    np.testing.assert_allclose(fp, expected, atol=1e-9)


def test_ground_footprint_reprojects_to_the_sensor_corners():
    cam = PinholeCamera(CameraConfig())
    T_w_c = se2_to_se3(0.3, -0.2, 0.7, 2.2) @ make_transform(rot_x(0.1)) @ make_transform(R_BODY_CAM_DOWN)
    fp = cam.ground_footprint(T_w_c)
    p_w = np.column_stack([fp, np.zeros(4), np.ones(4)])
    p_c = (invert(T_w_c) @ p_w.T).T[:, :3]
    np.testing.assert_allclose(cam.project(p_c), cam.sensor_corners_px, atol=1e-6)


def test_ground_footprint_above_the_horizon_is_nan():
    cam = PinholeCamera(CameraConfig())
    T_w_c = se2_to_se3(0.0, 0.0, 0.0, 0.3) @ make_transform(R_BODY_CAM_FORWARD)
    fp = cam.ground_footprint(T_w_c)
    assert np.isnan(fp[:2]).all()  # top corners look above the horizon
    assert np.isfinite(fp[2:]).all() and (fp[2:, 0] > 0).all()  # bottom corners hit the floor ahead


def test_view_wedge_of_a_level_forward_camera_spans_its_horizontal_field_of_view():
    cam = PinholeCamera(CameraConfig())
    yaw = 0.4
    T_w_c = se2_to_se3(1.0, -2.0, yaw, 0.3) @ make_transform(R_BODY_CAM_FORWARD)
    wedge = cam.view_wedge(T_w_c, 2.5)
    assert wedge.shape == (10, 2) and np.isfinite(wedge).all()
    np.testing.assert_allclose(wedge[0], [1.0, -2.0])
    arc = wedge[1:] - wedge[0]
    np.testing.assert_allclose(np.hypot(arc[:, 0], arc[:, 1]), 2.5)
    bearings = np.unwrap(np.arctan2(arc[:, 1], arc[:, 0])) - yaw
    # Left edge of the image first (image x = -y_B: the left of the robot), the optical axis in the middle.
    assert np.all(np.diff(bearings) < 0.0)
    assert bearings[4] == pytest.approx(0.0, abs=1e-12)
    assert math.degrees(bearings[0] - bearings[-1]) == pytest.approx(cam.field_of_view_deg[0], rel=1e-9)


def test_view_wedge_rows_without_a_horizontal_direction_are_nan_and_bad_range_raises():
    cam = PinholeCamera(CameraConfig())
    T_w_c = se2_to_se3(0.0, 0.0, 0.0, 2.0) @ make_transform(R_BODY_CAM_DOWN)
    wedge = cam.view_wedge(T_w_c, 1.0)
    assert np.isnan(wedge[5]).all()  # the principal point's ray points straight down
    assert np.isfinite(np.delete(wedge, 5, axis=0)).all()
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="range_m"):
            cam.view_wedge(T_w_c, bad)
    with pytest.raises(ValueError, match="4x4"):
        cam.view_wedge(np.eye(3), 1.0)
