"""Covariance through MOMA's chain: Jacobians against finite differences, and the
estimator's covariances against Monte Carlo errors (consistency)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator, Status
from moma_env.estimator.uncertainty import (
    LinearError,
    compose_jacobians,
    inverse_jacobian,
    upright_projection_jacobian,
)

DT = 0.04
BOARD_TOP = g.make_transform(g.R_BODY_BOARD_UP, [0.0, 0.0, 0.30])
CAM_DOWN = g.make_transform(g.R_BODY_CAM_DOWN, [0.0, 0.0, -0.05])
NO_CORNERS = np.empty((0, 2))


def perturb(T: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``T`` with the error ``e = (dt, dtheta)``: ``[exp([dtheta]x) R, t + dt]``."""
    out = T.copy()
    out[:3, :3] = g.rotvec_to_matrix(e[3:]) @ T[:3, :3]
    out[:3, 3] = T[:3, 3] + e[:3]
    return out


def error_of(T: np.ndarray, T_ref: np.ndarray) -> np.ndarray:
    """The error ``e`` with ``T = perturb(T_ref, e)``."""
    return np.concatenate([T[:3, 3] - T_ref[:3, 3], g.matrix_to_rotvec(T[:3, :3] @ T_ref[:3, :3].T)])


def random_pose(rng: np.random.Generator) -> np.ndarray:
    return g.make_transform(g.rotvec_to_matrix(rng.uniform(-2, 2, 3)), rng.uniform(-2, 2, 3))


def numeric_jacobian(f, T: np.ndarray, h: float = 1e-6) -> np.ndarray:
    J = np.empty((6, 6))
    base = f(T)
    for k in range(6):
        e = np.zeros(6)
        e[k] = h
        J[:, k] = (error_of(f(perturb(T, e)), base) - error_of(f(perturb(T, -e)), base)) / (2 * h)
    return J


@pytest.mark.parametrize("seed", range(5))
def test_compose_and_inverse_jacobians_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    A, B = random_pose(rng), random_pose(rng)
    J_A, J_B = compose_jacobians(A, B)
    np.testing.assert_allclose(J_A, numeric_jacobian(lambda X: X @ B, A), atol=1e-6)
    np.testing.assert_allclose(J_B, numeric_jacobian(lambda X: A @ X, B), atol=1e-6)
    np.testing.assert_allclose(inverse_jacobian(A), numeric_jacobian(g.invert, A), atol=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_upright_projection_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    T_b_x = g.make_transform(g.R_BODY_BOARD_UP @ g.rot_z(rng.uniform(-1, 1)), rng.uniform(-0.3, 0.3, 3))
    T_w_b = g.se2_to_se3(*rng.uniform(-2, 2, 2), rng.uniform(-3, 3), z=0.0)
    tilt = g.make_transform(g.rotvec_to_matrix(rng.normal(0, 0.05, 3)))
    T_w_x = tilt @ T_w_b @ T_b_x
    J = upright_projection_jacobian(T_w_x, T_b_x)
    numeric = numeric_jacobian(lambda X: g.upright_body_from_mount(X, T_b_x, 0.0), T_w_x)
    np.testing.assert_allclose(J, numeric, atol=1e-6)
    assert not J[2:5].any()


def test_linear_error_mean_keeps_the_shared_reference_and_averages_fresh_noise():
    Q = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    errors = [LinearError({0: np.eye(6)}, Q) for _ in range(4)]
    mean = LinearError.mean(errors)
    P = {(0, 0): 2.0 * np.eye(6)}
    np.testing.assert_allclose(mean.covariance(P), 2.0 * np.eye(6) + Q / 4)
    np.testing.assert_allclose(mean.cross(P, 0), 2.0 * np.eye(6))


# --------------------------------------------------------------------------- the estimator
class NoisyLeapfrog:
    """Two UGVs leapfrogging under a moving camera; each detection's ``T_c_m`` has
    Gaussian error of a known covariance, which the detection carries."""

    def __init__(self, seed: int, *, travel: bool, planar: bool, window: int = 10):
        self.rng = np.random.default_rng(seed)
        self.travel = travel
        self.planar = planar
        self.names = ("ugv_0", "ugv_1")
        self.truth = {"ugv_0": g.se2_to_se3(0.0, 0.0, 0.3), "ugv_1": g.se2_to_se3(0.0, 0.6, 0.3)}
        sd = np.array([0.004, 0.004, 0.01, 0.01, 0.01, 0.004])  # m and rad, in the camera frame
        self.cov = np.diag(sd**2)
        self.sd = sd
        self.est = MomaEstimator(EstimatorConfig(window=window, gate=None))
        for i, name in enumerate(self.names):
            self.est.add_robot(name, boards={i: BOARD_TOP}, static=True, initial_pose=self.truth[name], planar=planar)
        self.est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
        self.t = 0.0

    def frame(self) -> None:
        self.t = round(self.t + DT, 10)
        centre = 0.5 * (self.truth["ugv_0"][:3, 3] + self.truth["ugv_1"][:3, 3])
        T_w_c = g.make_transform(g.rot_z(0.1 * self.t), [centre[0], centre[1], 2.0]) @ CAM_DOWN
        dets = []
        for i, name in enumerate(self.names):
            T_c_m = g.invert(T_w_c) @ self.truth[name] @ BOARD_TOP
            noisy = perturb(T_c_m, self.rng.normal(0.0, self.sd))
            dets.append(Detection("down", i, noisy, NO_CORNERS, (), self.t, covariance=self.cov))
        self.est.update(self.t, dets)

    def switch(self, k: int) -> None:
        mover = self.names[k % 2]
        while not self.est.window_ready(self.names[(k + 1) % 2]):
            self.frame()
        self.est.set_static(mover, False, self.t)
        if self.travel:
            x, y, yaw = g.se3_to_se2(self.truth[mover])
            self.truth[mover] = g.se2_to_se3(x + 0.5, y, yaw)
        self.frame()
        self.est.set_static(mover, True, self.t)
        self.frame()

    def nees(self, name: str) -> tuple[float, float, int]:
        """Position NEES, heading NEES and position dimension of ``name``'s current estimate."""
        e = self.est.estimate(name)
        err = error_of(e.T_w_b, self.truth[name])
        d = 2 if self.planar else 3
        P = e.covariance
        pos = float(err[:d] @ np.linalg.solve(P[:d, :d], err[:d]))
        heading = float(err[5] ** 2 / P[5, 5])
        return pos, heading, d


@pytest.mark.parametrize("planar", [False, True])
def test_covariance_is_consistent_over_monte_carlo_runs(planar):
    """ANEES of position and heading of a robot after 6 switches, over 150 runs, inside 99 % chi-square bounds."""
    runs = 150
    pos, head = [], []
    for seed in range(runs):
        sim = NoisyLeapfrog(seed, travel=True, planar=planar)
        for k in range(6):
            sim.switch(k)
        while not sim.est.window_ready("ugv_1"):
            sim.frame()
        assert sim.est.estimate("ugv_1").status is Status.LOCALISED
        p, h, d = sim.nees("ugv_1")
        pos.append(p)
        head.append(h)
    for values, dof in ((pos, d), (head, 1)):
        anees = float(np.mean(values)) / dof
        # chi2(runs * dof) / (runs * dof): mean 1, sd sqrt(2 / (runs dof)); 99 % ~ 2.6 sd.
        half_width = 2.6 * math.sqrt(2.0 / (runs * dof))
        assert abs(anees - 1.0) < half_width, (anees, dof)


def test_covariance_grows_faster_for_a_travelling_team_than_for_one_that_stays():
    """Heading error becomes lateral error as the team travels: the predicted position
    variance grows super-linearly in the number of switches when travelling, linearly when not."""
    growth = {}
    for travel in (True, False):
        sim = NoisyLeapfrog(0, travel=travel, planar=True)
        var = []
        for k in range(24):
            sim.switch(k)
            while not sim.est.window_ready(sim.names[k % 2]):
                sim.frame()
            cov = sim.est.estimate(sim.names[k % 2]).covariance
            var.append(cov[0, 0] + cov[1, 1])
        n = np.arange(1, 25)
        slope = np.polyfit(np.log(n[4:]), np.log(np.array(var)[4:]), 1)[0]
        growth[travel] = slope
    # Position standard deviation ~ n^(slope / 2): about n^0.5 in place, well above it when travelling.
    assert 0.8 < growth[False] < 1.2, growth
    assert growth[True] > 1.6, growth


def test_initial_references_have_zero_covariance_and_mobile_robots_positive():
    sim = NoisyLeapfrog(1, travel=True, planar=False)
    assert not sim.est.estimate("ugv_0").covariance.any()
    sim.switch(0)
    sim.frame()
    cov = sim.est.estimate("uav").covariance
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    e = sim.est.estimate("ugv_1")
    assert e.position_std_m == pytest.approx(math.sqrt(np.trace(e.covariance[:3, :3])))
    assert e.heading_std_rad == pytest.approx(math.sqrt(e.covariance[5, 5]))
