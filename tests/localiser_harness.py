"""A synthetic leapfrog for any localiser (no simulator, no camera module).

Two UGVs (upright, boards on top) leapfrog along x under a downward camera on a
UAV that follows their midpoint and turns slowly. Every detection's ``T_c_m`` is
the truth perturbed by a Gaussian error of a fixed covariance (camera frame,
the convention of :class:`~moma_env.estimator.Detection`), which the detection
carries; ``exact=True`` leaves the poses exact (the covariance is still given
unless ``covariances=False``: a filter weighs its prior against it).
A mover drives ``step_m`` along x in ``frames_per_leg`` frames; a localiser
that takes odometry (:class:`moma_env.sim.OdometryConsumer`) gets each UGV's
planar increment per frame, with relative noise of ``ODOMETRY_STD``.
"""

from __future__ import annotations

import math

import numpy as np

from moma_env import geometry as g
from moma_env.estimator import Detection, EstimatorConfig
from moma_env.estimator.uncertainty import apply_error
from moma_env.sim import OdometryConsumer

BOARD_TOP = g.make_transform(g.R_BODY_BOARD_UP, [0.0, 0.0, 0.30])
CAM_DOWN = g.make_transform(g.R_BODY_CAM_DOWN, [0.0, 0.0, -0.05])
DT = 0.04
#: Standard deviations of a detection's error (m, m, m, rad, rad, rad) in the camera frame.
DETECTION_STD = (0.004, 0.004, 0.01, 0.01, 0.01, 0.004)
#: Relative standard deviations of an odometry increment (translation, rotation) and its floor (m, rad).
ODOMETRY_STD = (0.05, 0.05, 1e-4)
NAMES = ("ugv_0", "ugv_1")


class SyntheticLeapfrog:
    """Two UGVs leapfrogging under a camera; ``factory(EstimatorConfig)`` builds the localiser."""

    def __init__(self, factory, seed: int, *, exact: bool = False, config: EstimatorConfig | None = None,
                 step_m: float = 0.4, frames_per_leg: int = 10, odometry: bool = True, covariances: bool = True):
        self.rng = np.random.default_rng(seed)
        self.exact = exact
        self.step_m = step_m
        self.frames_per_leg = frames_per_leg
        self.truth = {"ugv_0": g.se2_to_se3(0.0, 0.0, 0.3), "ugv_1": g.se2_to_se3(0.0, 0.6, 0.3)}
        self.std = np.array(DETECTION_STD)
        self.covariance = np.diag(self.std**2) if covariances else None
        self.covariance_given = covariances
        self.localiser = factory(config if config is not None else EstimatorConfig(window=10, gate=None))
        self.odometry = odometry and isinstance(self.localiser, OdometryConsumer)
        for i, name in enumerate(NAMES):
            self.localiser.add_robot(name, boards={i: BOARD_TOP}, static=True, initial_pose=self.truth[name], planar=True)
        self.localiser.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
        self.time = 0.0
        self.uav_truth = self._uav_pose()

    def _uav_pose(self) -> np.ndarray:
        centre = 0.5 * (self.truth["ugv_0"][:3, 3] + self.truth["ugv_1"][:3, 3])
        return g.make_transform(g.rot_z(0.1 * self.time), [centre[0], centre[1], 2.0])

    def frame(self, moves: dict[str, float] | None = None) -> None:
        """One camera frame, after moving the named UGVs ``dx`` m forward (their x axis)."""
        self.time = round(self.time + DT, 10)
        for name, dx in (moves or {}).items():
            self.truth[name] = self.truth[name] @ g.se2_to_se3(dx, 0.0, 0.0)
        if self.odometry:
            for name in NAMES:
                dx = (moves or {}).get(name, 0.0)
                rel_t, rel_r, floor = ODOMETRY_STD
                std = np.array([rel_t * abs(dx) + floor, floor, rel_r * abs(dx) + floor])
                noise = np.zeros(3) if self.exact else self.rng.normal(0.0, std)
                if self.exact and not self.covariance_given:
                    std = np.full(3, 1e-6)
                self.localiser.odometry(name, (dx + noise[0], noise[1], noise[2]), np.diag(std**2), self.time)
        self.uav_truth = self._uav_pose()
        T_w_c = self.uav_truth @ CAM_DOWN
        detections = []
        for i, name in enumerate(NAMES):
            T_c_m = g.invert(T_w_c) @ self.truth[name] @ BOARD_TOP
            if not self.exact:
                T_c_m = apply_error(T_c_m, self.rng.normal(0.0, self.std))
            detections.append(Detection("down", i, T_c_m, np.empty((0, 2)), (), self.time, covariance=self.covariance))
        self.localiser.update(self.time, detections)

    def switch(self, k: int) -> str:
        """Switch ``k``: robot ``k % 2`` drives ``step_m`` and stops; returns its name once its window is ready."""
        mover, other = NAMES[k % 2], NAMES[(k + 1) % 2]
        while not self.localiser.window_ready(other):
            self.frame()
        self.localiser.set_static(mover, False, self.time)
        for _ in range(self.frames_per_leg):
            self.frame({mover: self.step_m / self.frames_per_leg})
        self.localiser.set_static(mover, True, self.time)
        while not self.localiser.window_ready(mover):
            self.frame()
        return mover


def planar_error(T_est: np.ndarray, T_true: np.ndarray) -> np.ndarray:
    """(dx, dy, dyaw) of an estimate against the truth (m, m, rad), in the covariance convention (W)."""
    dyaw = math.remainder(g.yaw_of(T_true) - g.yaw_of(T_est), 2.0 * math.pi)
    return np.array([T_true[0, 3] - T_est[0, 3], T_true[1, 3] - T_est[1, 3], dyaw])


def planar_nees(estimate, T_true: np.ndarray) -> tuple[float, float]:
    """Position (2 dof) and heading (1 dof) NEES of a RobotEstimate against the truth."""
    e = planar_error(estimate.T_w_b, T_true)
    P = estimate.covariance
    return float(e[:2] @ np.linalg.solve(P[:2, :2], e[:2])), float(e[2] ** 2 / P[5, 5])
