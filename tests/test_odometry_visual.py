"""Visual odometry on rendered floor frames: tracks on texture, drifts, loses track on a plain floor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env.camera import CameraConfig, FloorCamera, FloorConfig, FloorTexture
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_CAM_DOWN, make_transform, se2_to_se3, wrap_angle
from moma_env.odometry.visual import VisualOdometry, VisualOdometryConfig

#: Stated tolerance of the VO on a textured floor: after 0.45 m and 0.12 rad in
#: 30 frames, within 1 cm and 0.01 rad of the truth.
POSITION_TOL_M = 0.01
YAW_TOL_RAD = 0.01

CAMERA = CameraConfig(width=160, height=120, fx=120.0)
T_B_C = make_transform(R_BODY_CAM_DOWN, [0.2, 0.0, 0.3])  # looking down, 20 cm ahead, 30 cm up


@pytest.fixture(scope="module")
def floor() -> FloorTexture:
    """Textured for x < 1 m, plain beyond."""
    config = FloorConfig(
        extent=(-0.5, -1.0, 3.0, 1.0), textured=((-0.5, -1.0, 1.0, 1.0),), px_per_m=400.0, feature_size_m=0.02, contrast=0.5
    )
    return FloorTexture(config)


def drive(floor: FloorTexture, poses: list[tuple[float, float, float]], seed: int = 0) -> VisualOdometry:
    camera = FloorCamera(CAMERA, T_B_C, floor)
    rng = np.random.default_rng(seed)
    vo = VisualOdometry(CAMERA, T_B_C, initial_pose=poses[0], rng=np.random.default_rng(seed + 1))
    for pose in poses:
        vo.update(camera.frame(se2_to_se3(*pose), rng))
    return vo


def test_vo_tracks_a_known_motion_on_a_textured_floor(floor: FloorTexture) -> None:
    poses = [(0.015 * k, 0.002 * k, 0.004 * k) for k in range(31)]
    vo = drive(floor, poses)
    x, y, yaw = vo.pose
    assert math.hypot(x - poses[-1][0], y - poses[-1][1]) < POSITION_TOL_M
    assert abs(wrap_angle(yaw - poses[-1][2])) < YAW_TOL_RAD
    assert vo.frames == 31 and vo.lost_frames == 0 and vo.track_losses == 0 and not vo.lost
    assert vo.n_inliers >= vo.config.min_inliers
    # It is not the truth: frame-to-frame errors accumulate.
    assert vo.pose != pytest.approx(poses[-1], abs=1e-6)


def test_vo_reports_track_loss_on_a_plain_floor_and_holds_its_pose(floor: FloorTexture) -> None:
    poses = [(2.0 + 0.015 * k, 0.0, 0.0) for k in range(8)]
    vo = drive(floor, poses)
    assert vo.lost and vo.lost_frames == 7 and vo.track_losses == 1
    assert vo.pose == pytest.approx(poses[0])  # held where tracking was lost (here: the start)


def test_vo_loses_track_when_leaving_the_texture_and_resumes_when_back(floor: FloorTexture) -> None:
    # Out onto the plain floor in one long jump (a frame with no overlap), then back.
    poses = [(0.2 + 0.01 * k, 0.0, 0.0) for k in range(4)] + [(2.2, 0.0, 0.0), (2.21, 0.0, 0.0)]
    poses += [(0.5 + 0.01 * k, 0.0, 0.0) for k in range(5)]
    vo = drive(floor, poses)
    assert vo.track_losses >= 1 and vo.lost_frames >= 2 and not vo.lost
    # The jumps were missed: the estimate is off by what was driven while lost.
    assert vo.pose[0] == pytest.approx(0.23 + 0.04, abs=0.01)


def test_vo_same_seed_same_estimate(floor: FloorTexture) -> None:
    poses = [(0.01 * k, 0.0, 0.003 * k) for k in range(6)]
    assert drive(floor, poses, seed=4).pose == drive(floor, poses, seed=4).pose


def test_vo_rejects_bad_input() -> None:
    with pytest.raises(ConfigError, match="vo.T_b_c"):
        VisualOdometry(CAMERA, make_transform(R_BODY_CAM_DOWN, [0.0, 0.0, -0.1]))
    with pytest.raises(ConfigError, match="vo.min_features"):
        VisualOdometryConfig(max_features=10, min_features=20)
    vo = VisualOdometry(CAMERA, T_B_C)
    with pytest.raises(ValueError, match="uint8"):
        vo.update(np.zeros((120, 160), dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        vo.update(np.zeros((100, 160), dtype=np.uint8))


def test_corner_response_threshold_separates_noise_from_texture(floor: FloorTexture) -> None:
    """The default min_corner_response (20) lies between a plain floor with noise and the texture's features."""
    import cv2

    from moma_env.odometry.visual import _RESPONSE_SCALE

    camera = FloorCamera(CAMERA, T_B_C, floor)
    rng = np.random.default_rng(0)
    cfg = VisualOdometryConfig()

    def responses(image: np.ndarray) -> np.ndarray:
        corners = cv2.goodFeaturesToTrack(image, cfg.max_features, cfg.quality_level, cfg.min_distance_px, blockSize=cfg.block_size)
        uv = np.rint(corners.reshape(-1, 2)).astype(int)
        return cv2.cornerMinEigenVal(image, cfg.block_size)[uv[:, 1], uv[:, 0]] * _RESPONSE_SCALE

    plain = responses(camera.frame(se2_to_se3(2.0, 0.0, 0.0), rng))  # sensor noise of std 3 only
    textured = responses(camera.frame(se2_to_se3(0.3, 0.0, 0.0), rng))
    assert plain.max() < 5.0 < cfg.min_corner_response
    assert np.median(textured) > 30.0 > cfg.min_corner_response
