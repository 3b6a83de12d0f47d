"""The board-shift error model of the rendered camera, its configuration, and the geometric defaults."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env.camera import BoardView, CameraConfig, GeometricCamera, RenderConfig, RenderedCamera, make_camera
from moma_env.camera.board_shift import RENDERED_SHIFT_PERSISTENCE, RENDERED_SHIFT_PX, BoardShift, board_shift_for
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_CAM_DOWN, make_transform, se2_to_se3
from moma_env.markers import board_for_robot

T_W_C = make_transform(R_BODY_CAM_DOWN, [0.5, 0.3, 1.6])
BOARDS = [BoardView(0, board_for_robot(0), se2_to_se3(0.4, 0.2, 0.3, 0.3)), BoardView(1, board_for_robot(1), se2_to_se3(0.7, 0.5, -0.8, 0.3))]


@pytest.mark.parametrize(
    "field, value",
    [
        ("board_shift_px", -0.1),
        ("board_shift_px", math.nan),
        ("board_shift_px", "0.4"),
        ("board_shift_persistence", 1.5),
        ("board_shift_persistence", -0.01),
        ("board_shift_persistence", math.inf),
    ],
)
def test_bad_board_shift_names_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=f"camera.{field}"):
        CameraConfig(**{field: value})


def test_geometric_defaults_are_untouched() -> None:
    config = CameraConfig()
    assert config.board_shift_px is None and config.board_shift_persistence is None
    assert not board_shift_for(config, "geometric").active
    detections = GeometricCamera("uav", config).measure(T_W_C, BOARDS, 0.0, np.random.default_rng(0))
    assert len(detections) == 2
    assert all(d.covariance is not None and d.persistent_covariance is None for d in detections)
    # an explicit zero is the same camera
    again = GeometricCamera("uav", CameraConfig(board_shift_px=0.0)).measure(T_W_C, BOARDS, 0.0, np.random.default_rng(0))
    for a, b in zip(detections, again):
        assert np.array_equal(a.T_c_m, b.T_c_m) and np.array_equal(a.covariance, b.covariance)


def test_geometric_backend_refuses_a_board_shift() -> None:
    with pytest.raises(ConfigError, match="camera.board_shift_px"):
        make_camera("uav", CameraConfig(board_shift_px=0.3))


def test_rendered_defaults_are_the_measured_model() -> None:
    shift = board_shift_for(CameraConfig(), "rendered")
    assert (shift.sigma_px, shift.persistence) == (RENDERED_SHIFT_PX, RENDERED_SHIFT_PERSISTENCE)
    shift = board_shift_for(CameraConfig(board_shift_px=0.2, board_shift_persistence=0.5), "rendered")
    assert (shift.sigma_px, shift.persistence) == (0.2, 0.5)


def test_shift_covariance_is_the_lateral_translation_of_an_image_shift() -> None:
    shift = BoardShift(0.5, 0.6)
    T = make_transform(np.eye(3), [0.1, -0.2, 2.0])
    C = np.diag([1e-6, 2e-6, 3e-6, 1e-4, 1e-4, 1e-5])
    cov, persistent = shift.apply(T, C, fx=500.0, fy=400.0)
    S = np.zeros((6, 6))
    S[0, 0] = (2.0 * 0.5 / 500.0) ** 2  # a 0.5 px shift at 2 m, f = 500 px: 2 mm
    S[1, 1] = (2.0 * 0.5 / 400.0) ** 2
    np.testing.assert_allclose(cov, C + S, rtol=1e-15)
    np.testing.assert_allclose(persistent, 0.6 * S, rtol=1e-15)
    assert BoardShift().apply(T, C, 500.0, 400.0) == (C, None)
    assert shift.apply(T, None, 500.0, 400.0) == (None, None)


def test_rendered_detections_carry_the_board_shift() -> None:
    render = RenderConfig(noise_std=2.0)
    shift = 0.4
    on = RenderedCamera("uav", CameraConfig(board_shift_px=shift, board_shift_persistence=0.7), render)
    off = RenderedCamera("uav", CameraConfig(board_shift_px=0.0), render)
    with_shift = on.measure(T_W_C, BOARDS, 0.0, np.random.default_rng(1))
    without = off.measure(T_W_C, BOARDS, 0.0, np.random.default_rng(1))
    assert len(with_shift) == len(without) == 2
    for a, b in zip(with_shift, without):
        assert np.array_equal(a.T_c_m, b.T_c_m)  # the model changes the covariance only
        assert b.persistent_covariance is None
        z = a.T_c_m[2, 3]
        added = a.covariance - b.covariance
        np.testing.assert_allclose(np.diag(added)[:2], [(z * shift / on.config.fx) ** 2, (z * shift / on.config.fy) ** 2], rtol=1e-9)
        np.testing.assert_allclose(a.persistent_covariance, 0.7 * added, rtol=1e-9, atol=1e-18)
