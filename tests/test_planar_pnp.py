"""The compiled planar PnP solver (moma_env.camera.planar_pnp)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from moma_env.camera.planar_pnp import solve_planar_pnp
from moma_env.geometry import rot_x, rot_y, rot_z
from moma_env.markers import board_for_robot


def board_xy() -> np.ndarray:
    """(16, 2) corners of a robot's 2x2 board in its plane (m)."""
    return board_for_robot(0).marker_corners.reshape(-1, 3)[:, :2].copy()


def random_pose(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A board 2-4 m in front of the camera, turned towards it within ~0.3 rad."""
    R = rot_z(rng.uniform(-3, 3))[:3, :3] @ rot_x(np.pi + rng.normal(0, 0.3))[:3, :3] @ rot_y(rng.normal(0, 0.3))[:3, :3]
    t = np.array([rng.uniform(-1, 1), rng.uniform(-0.8, 0.8), rng.uniform(2, 4)])
    return R, t


def image_of(obj_xy: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    p = np.column_stack([obj_xy, np.zeros(len(obj_xy))]) @ R.T + t
    return p[:, :2] / p[:, 2:]


@pytest.mark.parametrize("seed", range(5))
def test_exact_without_noise(seed):
    rng = np.random.default_rng(seed)
    obj = board_xy()
    R, t = random_pose(rng)
    T = solve_planar_pnp(obj, image_of(obj, R, t))
    assert T is not None
    np.testing.assert_allclose(T[:3, :3], R, atol=1e-9)
    np.testing.assert_allclose(T[:3, 3], t, atol=1e-9)
    np.testing.assert_array_equal(T[3], [0.0, 0.0, 0.0, 1.0])


def test_face_on_board_is_exact():
    # A board seen face-on is a 180 degree rotation in its own frame, where
    # rotation-vector solvers are singular.
    obj = board_xy()
    R, t = rot_x(np.pi)[:3, :3], np.array([0.1, -0.2, 3.0])
    T = solve_planar_pnp(obj, image_of(obj, R, t))
    np.testing.assert_allclose(T[:3, :3], R, atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], t, atol=1e-12)


def test_one_marker_is_enough():
    obj = board_xy()[:4]
    R, t = random_pose(np.random.default_rng(7))
    T = solve_planar_pnp(obj, image_of(obj, R, t))
    np.testing.assert_allclose(T[:3, 3], t, atol=1e-9)


def test_noisy_corners_at_least_as_accurate_as_sqpnp():
    # The maximum-likelihood pose: over many noisy views its mean position
    # error is no worse than OpenCV's SQPNP, and it never lands on a far-off pose.
    rng = np.random.default_rng(0)
    obj = board_xy()
    obj3 = np.column_stack([obj, np.zeros(len(obj))]).reshape(-1, 1, 3)
    ours, sqpnp = [], []
    for _ in range(200):
        R, t = random_pose(rng)
        xy = image_of(obj, R, t) + rng.normal(0.0, 0.5 / 420.0, (len(obj), 2))
        T = solve_planar_pnp(obj, xy)
        ours.append(np.linalg.norm(T[:3, 3] - t))
        _, _, tvec = cv2.solvePnP(obj3, xy.reshape(-1, 1, 2), np.eye(3), None, flags=cv2.SOLVEPNP_SQPNP)
        sqpnp.append(np.linalg.norm(tvec.ravel() - t))
    assert np.mean(ours) <= np.mean(sqpnp)
    assert max(ours) < 0.25  # metres, at 2-4 m with a 0.2 m board


def test_the_lower_cost_pose_of_the_ambiguity_is_returned():
    # Its reprojection error is never above SQPNP's (global optimum) by more than rounding.
    rng = np.random.default_rng(1)
    obj = board_xy()
    obj3 = np.column_stack([obj, np.zeros(len(obj))]).reshape(-1, 1, 3)

    def cost(R, t, xy):
        return float(((image_of(obj, R, t) - xy) ** 2).sum())

    for _ in range(100):
        R, t = random_pose(rng)
        xy = image_of(obj, R, t) + rng.normal(0.0, 1.0 / 420.0, (len(obj), 2))
        T = solve_planar_pnp(obj, xy)
        _, rvec, tvec = cv2.solvePnP(obj3, xy.reshape(-1, 1, 2), np.eye(3), None, flags=cv2.SOLVEPNP_SQPNP)
        assert cost(T[:3, :3], T[:3, 3], xy) <= cost(cv2.Rodrigues(rvec)[0], tvec.ravel(), xy) * (1 + 1e-6)


def test_degenerate_input_is_not_solved():
    collinear = np.column_stack([np.linspace(-0.1, 0.1, 6), np.zeros(6)])
    assert solve_planar_pnp(collinear, collinear * 0.3 + 0.05) is None
    assert solve_planar_pnp(board_xy()[:3], board_xy()[:3]) is None
    assert solve_planar_pnp(board_xy(), np.full((16, 2), np.nan)) is None


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="object_xy and image_xy"):
        solve_planar_pnp(np.zeros((5, 3)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="object_xy and image_xy"):
        solve_planar_pnp(np.zeros((5, 2)), np.zeros((4, 2)))
