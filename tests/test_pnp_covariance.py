"""The PnP covariance every detection carries (moma_env.camera.kernels.solve_boards).

Monte Carlo: many noise draws of one fixed board view; the errors of the
detected pose in the Detection convention (camera frame C, translation first,
``T_true = [exp([dtheta]x) R, t + dt]``) must have the predicted covariance:
the normalised estimation error squared (NEES) has mean 6 within its
chi-square bounds.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import chi2

from moma_env.camera import BoardView, CameraConfig, GeometricCamera, RenderedCamera
from moma_env.camera.kernels import camera_parameters, pixel_weights
from moma_env.camera.distortion import distort
from moma_env.geometry import invert, make_transform, matrix_to_rotvec, rot_x, rot_y, rotvec_to_matrix
from moma_env.markers import board_for_robot

#: Monte Carlo draws per case.
_DRAWS = 1500
#: Two-sided probability of a false alarm of each NEES bound.
_ALPHA = 1e-4

UP_M = np.array([0.0, 0.0, 1.0])


def view(tilt_deg: float, distance: float) -> np.ndarray:
    """``T_c_m``: the robot board ``distance`` m ahead (slightly off-axis), its normal tilted by ``tilt_deg``."""
    R = rot_y(math.radians(tilt_deg))[:3, :3] @ rot_x(math.pi)[:3, :3]  # z_M towards the camera, then tilted
    return make_transform(R, (0.1, -0.05, distance))


def pose_error(T_true: np.ndarray, T_est: np.ndarray) -> np.ndarray:
    """``(dt, dtheta)`` with ``T_true = [exp([dtheta]x) R_est, t_est + dt]``."""
    dt = T_true[:3, 3] - T_est[:3, 3]
    dtheta = matrix_to_rotvec(T_true[:3, :3] @ T_est[:3, :3].T)
    return np.concatenate([dt, dtheta])


def nees_of(camera: GeometricCamera, T_c_m: np.ndarray, draws: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """NEES of every draw and the sample covariance of the errors.

    The board's declared up direction is the true one turned by a random rotation
    of ``upright_prior_deg`` per axis (a new draw each time), so that the upright
    prior's assumed error is really there.
    """
    prior_rad = math.radians(camera.config.upright_prior_deg)
    layout = board_for_robot(0)
    T_w_m = np.eye(4)
    T_w_c = T_w_m @ invert(T_c_m)
    rng = np.random.default_rng(seed)
    nees, errors = [], []
    for _ in range(draws):
        up_m = rotvec_to_matrix(rng.normal(0.0, prior_rad, 3)) @ UP_M
        (d,) = camera.measure(T_w_c, [BoardView(0, layout, T_w_m, up_m=up_m)], 0.0, rng)
        assert d.covariance is not None and d.covariance.shape == (6, 6)
        e = pose_error(T_c_m, d.T_c_m)
        errors.append(e)
        nees.append(float(e @ np.linalg.solve(d.covariance, e)))
    return np.array(nees), np.cov(np.array(errors).T)


def assert_nees_consistent(nees: np.ndarray) -> None:
    n = len(nees)
    low, high = chi2.ppf([_ALPHA / 2, 1 - _ALPHA / 2], 6 * n) / n
    assert low <= nees.mean() <= high, f"mean NEES {nees.mean():.3f} outside [{low:.3f}, {high:.3f}]"


CASES = {
    # name: (camera overrides, tilt deg, distance m)
    "face-on, square pixels": ({}, 0.0, 1.0),
    "oblique, square pixels": ({}, 40.0, 1.0),
    "face-on, non-square pixels": ({"fy": 300.0}, 0.0, 1.0),
    "oblique, non-square pixels, strong distortion": ({"fy": 520.0, "dist": (-0.2, 0.05, 0.002, -0.001, 0.0)}, 40.0, 1.0),
}


@pytest.mark.parametrize("rule", ["upright", "min_cost"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_covariance_matches_monte_carlo_errors(case, rule):
    overrides, tilt, distance = CASES[case]
    camera = GeometricCamera("uav", CameraConfig(noise_px=0.5, pose_disambiguation=rule, **overrides))
    nees, sample = nees_of(camera, view(tilt, distance), _DRAWS, seed=7)
    assert_nees_consistent(nees)
    # At most 2.5 times the expected share beyond the 99 % quantile (no heavy tail of flips).
    assert np.mean(nees > chi2.ppf(0.99, 6)) < 0.025


def test_upright_prior_shrinks_the_rotation_covariance_only_about_horizontal_axes():
    """With the prior, the covariance is the posterior: smaller in tilt, equal in yaw about up."""
    T_c_m = view(0.0, 3.0)
    T_w_c = invert(T_c_m)
    layout = board_for_robot(0)
    covs = {}
    for rule in ("upright", "min_cost"):
        camera = GeometricCamera("uav", CameraConfig(noise_px=1.0, pose_disambiguation=rule))
        (d,) = camera.measure(T_w_c, [BoardView(0, layout, np.eye(4), up_m=UP_M)], 0.0, np.random.default_rng(3))
        covs[rule] = d.covariance
    up_c = T_w_c[2, :3]
    tilt_axis = np.cross(up_c, [1.0, 0.0, 0.0])
    tilt_axis /= np.linalg.norm(tilt_axis)
    var = {rule: (float(tilt_axis @ c[3:, 3:] @ tilt_axis), float(up_c @ c[3:, 3:] @ up_c)) for rule, c in covs.items()}
    assert var["upright"][0] < 0.5 * var["min_cost"][0]
    assert var["upright"][1] == pytest.approx(var["min_cost"][1], rel=0.2)


def test_zero_noise_gives_a_zero_covariance():
    camera = GeometricCamera("uav", CameraConfig(noise_px=0.0))
    T_c_m = view(20.0, 2.0)
    (d,) = camera.measure(invert(T_c_m), [BoardView(0, board_for_robot(0), np.eye(4), up_m=UP_M)], 0.0, np.random.default_rng(0))
    np.testing.assert_array_equal(d.covariance, np.zeros((6, 6)))


@pytest.mark.parametrize("method", ["IPPE", "ITERATIVE", "SQPNP"])
def test_opencv_methods_carry_a_consistent_covariance(method):
    camera = GeometricCamera("uav", CameraConfig(noise_px=0.5, pnp_method=method, pose_disambiguation="min_cost"))
    nees, _ = nees_of(camera, view(40.0, 1.5), 600, seed=11)
    # IPPE's closed form is not the least-squares pose: its errors are a little larger than the bound.
    assert 6.0 * 0.85 <= nees.mean() <= 6.0 * (1.3 if method == "IPPE" else 1.15)


def test_pixel_weights_are_the_jacobian_of_the_projection():
    cfg = CameraConfig(fx=400.0, fy=460.0, dist=(-0.2, 0.05, 0.002, -0.001, 0.01))
    p = camera_parameters(GeometricCamera("c", cfg).camera)
    xy = np.array([[0.3, -0.2], [-0.5, 0.4], [0.0, 0.0]])
    W = np.empty((3, 4))
    pixel_weights(xy, p, W)

    def pixel(q: np.ndarray) -> np.ndarray:
        xd, yd, _ = distort(q[:, 0], q[:, 1], cfg.dist)
        return np.column_stack([cfg.fx * xd, cfg.fy * yd])

    h = 1e-6
    for axis in range(2):
        step = np.zeros(2)
        step[axis] = h
        numeric = (pixel(xy + step) - pixel(xy - step)) / (2 * h)
        np.testing.assert_allclose(W[:, [axis, 2 + axis]], numeric, rtol=1e-6, atol=1e-6)


def test_rendered_camera_estimates_sigma_from_residuals():
    """A rendered detection carries a covariance; with the floor as the only sigma it scales as floor^2."""
    cfg = CameraConfig(pnp_sigma_floor_px=0.0)
    camera = RenderedCamera("uav", cfg)
    T_c_m = view(10.0, 1.2)
    board = BoardView(0, board_for_robot(0), np.eye(4), up_m=UP_M)
    (d,) = camera.measure(invert(T_c_m), [board], 0.0, np.random.default_rng(0))
    assert d.covariance is not None and np.all(np.linalg.eigvalsh(d.covariance) > 0.0)
    floored = RenderedCamera("uav", dataclasses.replace(cfg, pnp_sigma_floor_px=50.0))
    (big,) = floored.measure(invert(T_c_m), [board], 0.0, np.random.default_rng(0))
    # A 50 px floor dominates any residual: the covariance is 50^2 times the unit one, far above the estimate.
    assert np.trace(big.covariance) > 100.0 * np.trace(d.covariance)
