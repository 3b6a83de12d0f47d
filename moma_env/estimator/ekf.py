"""EKF cooperative localisation: the classic baseline of MOMA's comparisons.

In the manner of Roumeliotis and Bekey's distributed EKF, and of Han et al.
(2018), where a stationary robot serves as a temporary landmark: one extended
Kalman filter over the poses of every robot, predicted with wheel odometry when
it is given and updated with the same detections as MOMA.

State
-----
Every robot has a pose ``T_w_b`` (4x4, W) and a 6-dof error block in one joint
covariance ``P``, in the convention of :mod:`moma_env.estimator.uncertainty`
(translation m first, then rotation rad, perturbed on the left in W). A
*planar* robot (``add_robot(planar=True)``, a UGV) keeps its height, roll and
pitch: those components have zero covariance and are never corrected, so its
state is (x, y, yaw). The observer (a UAV) has all six. A robot with an initial
pose starts with zero covariance (it defines W); one without (the observer) is
initialised from its first detection of a REFERENCE robot's board, with its
covariance and its cross-covariance to that robot propagated to first order.

Prediction
----------
* Odometry (:meth:`EkfLocaliser.odometry`, the
  :class:`moma_env.sim.OdometryConsumer` hook): ``T <- T @ exp(dx, dy, dyaw)``,
  its covariance in the body frame propagated by the composition Jacobians.
* A MOBILE robot that got no odometry since the last update (the observer, or
  every robot in an env without odometry) moves by a random walk of standard
  deviation ``unmodelled_speed_m_s * dt`` (m) and ``unmodelled_turn_rad_s * dt``
  (rad) per update of ``dt`` seconds; a robot estimated in 6-DoF (not planar)
  that got odometry walks so in height, roll and pitch, which wheel odometry
  does not measure. Static robots do not move.

Update
------
Each detection is the relative pose ``T_c_m = inv(T_w_o T_o_c) T_w_r T_r_m``
of a board on robot r in a camera on robot o, with the detection's 6x6
covariance (camera frame; with a ``persistent_covariance``, the covariance of
:func:`~moma_env.estimator.detection.frame_fusion_covariance` for the frame's
place in the run of frames its board stands still, ``Bookkeeper.still_frames``,
once odometry chains the frames of moving robots; before any odometry, in the
run of frames the robots its camera relates stand still together,
``Bookkeeper.still_together``) plus a floor of ``detection_floor_m`` /
``detection_floor_rad``. The residual ``pose_error(T_c_m measured, predicted)``
is gated by its normalised innovation squared (``gate_nis``, a chi-square
quantile of 6 dof), and every accepted detection of the frame is fused in one
update (Joseph form), relinearised ``iterations`` times (an iterated EKF). Statuses and phases follow
:mod:`moma_env.estimator.bookkeeping` (the MOMA semantics).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from moma_env.config import ConfigError, check_count, check_positive
from moma_env.estimator.bookkeeping import BookkeptLocaliser, Bookkeeper, RobotRecord
from moma_env.estimator.config import EstimatorConfig
from moma_env.estimator.detection import Detection, frame_fusion_covariance
from moma_env.estimator.results import Phase, Status
from moma_env.estimator.uncertainty import (
    apply_error,
    compose_jacobian_first,
    compose_jacobians,
    inverse_jacobian,
    pose_error,
    upright_projection_jacobian,
)
from moma_env.geometry import invert, se2_to_se3, upright_body_from_mount

__all__ = ["EkfConfig", "EkfLocaliser"]

#: Error components a planar robot has (x, y, yaw).
PLANAR = (0, 1, 5)


@dataclass(frozen=True)
class EkfConfig:
    """Settings of :class:`EkfLocaliser` beyond the shared :class:`EstimatorConfig`.

    Attributes:
        unmodelled_speed_m_s: random walk of a mobile robot without odometry
            (m per second of update interval).
        unmodelled_turn_rad_s: its rotation counterpart (rad per second).
        detection_floor_m, detection_floor_rad: standard deviations added to
            every detection's covariance (m, rad), so that exact detections
            keep the innovation covariance invertible.
        gate_nis: a detection whose normalised innovation squared exceeds
            this is left out (default: the 99.99 % quantile of the chi-square
            distribution of 6 dof, 27.856); ``math.inf`` keeps every detection.
        iterations: relinearisations of the update (an iterated EKF; 1 is the
            plain EKF). The observer moves between frames by a random walk, so
            its prior is centimetres off; iterating makes the update exact
            for exact detections.
    """

    unmodelled_speed_m_s: float = 0.5
    unmodelled_turn_rad_s: float = 0.5
    detection_floor_m: float = 1e-4
    detection_floor_rad: float = 1e-4
    gate_nis: float = 27.856341236
    iterations: int = 3

    def __post_init__(self) -> None:
        check_count("ekf.iterations", self.iterations)
        check_positive("ekf.unmodelled_speed_m_s", self.unmodelled_speed_m_s)
        check_positive("ekf.unmodelled_turn_rad_s", self.unmodelled_turn_rad_s)
        check_positive("ekf.detection_floor_m", self.detection_floor_m)
        check_positive("ekf.detection_floor_rad", self.detection_floor_rad)
        if isinstance(self.gate_nis, bool) or not isinstance(self.gate_nis, (int, float)) or not self.gate_nis > 0.0:
            raise ConfigError("ekf.gate_nis", f"must be a number > 0 (math.inf: no gate), got {self.gate_nis!r}")


class EkfLocaliser(BookkeptLocaliser):
    """EKF cooperative localisation behind the :class:`moma_env.sim.Localiser` protocol
    (and :class:`moma_env.sim.OdometryConsumer`); see the module docstring."""

    def __init__(self, config: EstimatorConfig | None = None, ekf: EkfConfig | None = None):
        self._book = Bookkeeper(EstimatorConfig() if config is None else config)
        if ekf is None:
            ekf = EkfConfig()
        if not isinstance(ekf, EkfConfig):
            raise TypeError(f"ekf must be an EkfConfig, got {type(ekf).__name__}")
        self.ekf = ekf
        self._slot: dict[str, int] = {}
        self._pose: dict[str, np.ndarray | None] = {}
        self._P = np.zeros((0, 0))
        self._odometry_seen: set[str] = set()
        self._last_update: float | None = None
        floor = [ekf.detection_floor_m**2] * 3 + [ekf.detection_floor_rad**2] * 3
        self._floor = np.diag(floor)
        self._gate = float(ekf.gate_nis)
        self._chained = False  # odometry received: it chains the frames of a moving robot
        self._groups: dict[str, list[Detection]] = {}  # the current update's detections by camera

    # ------------------------------------------------------------------ queries
    @property
    def covariance(self) -> np.ndarray:
        """The joint covariance (6 per robot, in :attr:`robots` order), a copy."""
        return self._P.copy()

    def estimate_of(self, name: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Robot ``name``'s pose and its block of the joint covariance."""
        i = self._slot[name]
        return self._pose[name], self._P[i : i + 6, i : i + 6]

    # ------------------------------------------------------------ declarations
    def add_robot(self, name: str, *, boards: Mapping[int, np.ndarray] | None = None,
                  cameras: Mapping[str, np.ndarray] | None = None, static: bool, initial_pose: np.ndarray | None = None,
                  time: float | None = None, planar: bool = False) -> None:
        """Declare a robot (the arguments of ``MomaEstimator.add_robot``)."""
        r = self._book.add_robot(name, boards=boards, cameras=cameras, static=static, initial_pose=initial_pose, time=time, planar=planar)
        n = self._P.shape[0]
        P = np.zeros((n + 6, n + 6))
        P[:n, :n] = self._P
        self._P = P
        self._slot[name] = n
        self._pose[name] = None if r.initial_pose is None else r.initial_pose.copy()

    def set_static(self, name: str, static: bool, time: float) -> None:
        """The owner's declaration (MOMA's semantics)."""
        self._book.set_static(name, static, time)

    def odometry(self, name: str, increment: tuple[float, float, float], covariance: np.ndarray, time: float) -> None:
        """Predict robot ``name`` by the planar ``increment`` (dx, dy, dyaw) in its body frame (m, rad),
        of 3x3 ``covariance``; a robot without a pose yet ignores it."""
        r = self._book.robot(name)
        try:
            dx, dy, dyaw = (float(v) for v in increment)
        except (TypeError, ValueError):
            raise ValueError(f"odometry of {name!r}: increment must be three numbers, got {increment!r}") from None
        Q3 = np.asarray(covariance, dtype=float)
        if Q3.shape != (3, 3) or not np.isfinite(Q3).all() or not all(map(math.isfinite, (dx, dy, dyaw))):
            raise ValueError(f"odometry of {name!r}: increment must be finite and covariance a finite 3x3 array")
        self._book.time = self._book.checked_time(time)
        self._odometry_seen.add(name)
        self._chained = True
        T = self._pose[name]
        if T is None:
            return
        delta = se2_to_se3(dx, dy, dyaw)
        J_A, J_B = compose_jacobians(T, delta)
        new = T @ delta
        if r.planar:
            new = upright_body_from_mount(new, np.eye(4), r.plane_z)
        self._pose[name] = new
        Q = np.zeros((6, 6))
        Q[np.ix_(PLANAR, PLANAR)] = Q3
        i = self._slot[name]
        P = self._P
        P[i : i + 6, :] = J_A @ P[i : i + 6, :]
        P[:, i : i + 6] = P[:, i : i + 6] @ J_A.T
        P[i : i + 6, i : i + 6] += J_B @ Q @ J_B.T

    # ------------------------------------------------------------------ update
    def update(self, time: float, detections: Iterable[Detection]) -> None:
        """One camera frame at ``time`` (s): predict the robots without odometry, initialise the
        robots seen for the first time, fuse the frame's detections, update the statuses."""
        book = self._book
        t, by_camera = book.begin_update(time, detections)
        dt = 0.0 if self._last_update is None else t - self._last_update
        self._last_update = t
        self._random_walk(dt)
        self._odometry_seen.clear()
        self._groups = by_camera

        references = {camera_id for camera_id, group in by_camera.items() if self._sees_reference(camera_id, group)}
        used: set[int] = set()
        for camera_id in references:
            own = book.camera_owner[camera_id]
            if self._pose[own.name] is None or (own.phase is Phase.MOBILE and own.status is Status.LOST):
                d = min(
                    (d for d in by_camera[camera_id] if self._is_reference_board(d, own)),
                    key=lambda d: float(np.trace(self._R(d))),
                )
                self._init_camera_owner(d, own)
                used.add(id(d))
        for camera_id, group in by_camera.items():
            own = book.camera_owner[camera_id]
            if self._pose[own.name] is None:
                continue
            for d in group:
                r = book.board_owner[d.board_id]
                if r is not own and (self._pose[r.name] is None or (r.phase is Phase.MOBILE and r.status is Status.LOST)):
                    if camera_id in references:
                        self._init_board_owner(d, own, r)
                        used.add(id(d))

        accepted = self._fuse([d for group in by_camera.values() for d in group if id(d) not in used])
        accepted |= used
        located = {cid for cid, group in by_camera.items() if self._sees_reference(cid, [d for d in group if id(d) in accepted])}
        measured = set()
        for camera_id in located:
            measured.add(book.camera_owner[camera_id].name)
            measured.update(book.board_owner[d.board_id].name for d in by_camera[camera_id] if id(d) in accepted)
        book.end_update(t, measured)

    # ---------------------------------------------------------------- helpers
    def _is_reference_board(self, d: Detection, own: RobotRecord) -> bool:
        r = self._book.board_owner[d.board_id]
        return r is not own and r.phase is Phase.REFERENCE and self._pose[r.name] is not None

    def _sees_reference(self, camera_id: str, group: list[Detection]) -> bool:
        own = self._book.camera_owner[camera_id]
        if own.phase is Phase.REFERENCE and self._pose[own.name] is not None and group:
            return True
        return any(self._is_reference_board(d, own) for d in group)

    def _R(self, d: Detection) -> np.ndarray:
        if d.persistent_covariance is None:
            cov = d.covariance
        elif self._chained:  # odometry chains the frames: every frame of a still board shares its error
            cov = frame_fusion_covariance(d, self._book.still_frames(d.board_id))
        else:
            cov = frame_fusion_covariance(d, self._book.still_together(d.camera_id, self._groups[d.camera_id]))
        return self._floor if cov is None else cov + self._floor

    def _random_walk(self, dt: float) -> None:
        if dt <= 0.0:
            return
        v = (self.ekf.unmodelled_speed_m_s * dt) ** 2
        w = (self.ekf.unmodelled_turn_rad_s * dt) ** 2
        for name, r in self._book.robots.items():
            if r.phase is not Phase.MOBILE or self._pose[name] is None or (r.planar and name in self._odometry_seen):
                continue
            i = self._slot[name]
            noise = np.array([v, v, v, w, w, w])
            if r.planar:
                noise[[2, 3, 4]] = 0.0
            elif name in self._odometry_seen:
                noise[[0, 1, 5]] = 0.0  # odometry moved it in the plane; height, roll and pitch walk
            self._P[i : i + 6, i : i + 6] += np.diag(noise)

    def _insert(self, name: str, pose: np.ndarray, source: str, G: np.ndarray, noise: np.ndarray) -> None:
        """Set robot ``name``'s pose and covariance: error ``G e_source + n`` (n of covariance ``noise``)."""
        i, s = self._slot[name], self._slot[source]
        P = self._P
        P[i : i + 6, :] = 0.0
        P[:, i : i + 6] = 0.0
        cross = G @ P[s : s + 6, :]
        P[i : i + 6, :] = cross
        P[:, i : i + 6] = cross.T
        own = G @ P[s : s + 6, s : s + 6] @ G.T + noise
        P[i : i + 6, i : i + 6] = 0.5 * (own + own.T)
        self._pose[name] = pose

    def _init_camera_owner(self, d: Detection, own: RobotRecord) -> None:
        """Robot ``own`` (carrying ``d``'s camera) from a REFERENCE board: ``T_w_r T_r_m inv(T_c_m) T_c_o``."""
        r = self._book.board_owner[d.board_id]
        T_w_r = self._pose[r.name]
        T_r_m = r.boards[d.board_id]
        T_w_m = T_w_r @ T_r_m
        T_m_c = invert(d.T_c_m)
        J_a, J_b = compose_jacobians(T_w_m, T_m_c)
        T_w_c = T_w_m @ T_m_c
        T_o_c = own.cameras[d.camera_id]
        if own.planar:
            pose, A = upright_body_from_mount(T_w_c, T_o_c, own.plane_z), upright_projection_jacobian(T_w_c, T_o_c)
        else:
            T_c_o = invert(T_o_c)
            pose, A = T_w_c @ T_c_o, compose_jacobian_first(T_w_c, T_c_o)
        G_n = A @ J_b @ inverse_jacobian(d.T_c_m)
        self._insert(own.name, pose, r.name, A @ J_a @ compose_jacobian_first(T_w_r, T_r_m), G_n @ self._R(d) @ G_n.T)

    def _init_board_owner(self, d: Detection, own: RobotRecord, r: RobotRecord) -> None:
        """Robot ``r`` (carrying ``d``'s board) from the camera on ``own``: ``T_w_o T_o_c T_c_m T_m_r``."""
        T_w_o = self._pose[own.name]
        T_o_c = own.cameras[d.camera_id]
        T_w_c = T_w_o @ T_o_c
        J_a, J_b = compose_jacobians(T_w_c, d.T_c_m)
        T_w_m = T_w_c @ d.T_c_m
        T_r_m = r.boards[d.board_id]
        if r.planar:
            pose, A = upright_body_from_mount(T_w_m, T_r_m, r.plane_z), upright_projection_jacobian(T_w_m, T_r_m)
        else:
            T_m_r = invert(T_r_m)
            pose, A = T_w_m @ T_m_r, compose_jacobian_first(T_w_m, T_m_r)
        G_n = A @ J_b
        self._insert(r.name, pose, own.name, A @ J_a @ compose_jacobian_first(T_w_o, T_o_c), G_n @ self._R(d) @ G_n.T)

    def _measurement(self, d: Detection) -> tuple[np.ndarray, np.ndarray] | None:
        """Residual (6) and Jacobian (6 x n) of a detection between two robots with poses, else None."""
        book = self._book
        own = book.camera_owner[d.camera_id]
        r = book.board_owner[d.board_id]
        T_w_o, T_w_r = self._pose[own.name], self._pose[r.name]
        if r is own or T_w_o is None or T_w_r is None:
            return None
        T_o_c = own.cameras[d.camera_id]
        T_r_m = r.boards[d.board_id]
        A = T_w_o @ T_o_c
        A_inv = invert(A)
        B = T_w_r @ T_r_m
        J1, J2 = compose_jacobians(A_inv, B)
        predicted = A_inv @ B
        H = np.zeros((6, self._P.shape[0]))
        i, j = self._slot[own.name], self._slot[r.name]
        H[:, i : i + 6] = J1 @ inverse_jacobian(A) @ compose_jacobian_first(T_w_o, T_o_c)
        H[:, j : j + 6] = J2 @ compose_jacobian_first(T_w_r, T_r_m)
        return pose_error(d.T_c_m, predicted), H

    def _fuse(self, detections: list[Detection]) -> set[int]:
        """One iterated EKF update with every detection that passes the gate; the ids of those."""
        P = self._P
        accepted: list[Detection] = []
        Rs = []
        for d in detections:
            m = self._measurement(d)
            if m is None:
                continue
            r, H = m
            R = self._R(d)
            if float(r @ np.linalg.solve(H @ P @ H.T + R, r)) > self._gate:
                continue
            accepted.append(d)
            Rs.append(R)
        if not accepted:
            return set()
        k = len(Rs)
        R = np.zeros((6 * k, 6 * k))
        for n, Rn in enumerate(Rs):
            R[6 * n : 6 * n + 6, 6 * n : 6 * n + 6] = Rn
        prior = dict(self._pose)
        robots = [(name, robot, self._slot[name]) for name, robot in self._book.robots.items() if prior[name] is not None]
        for _ in range(self.ekf.iterations):
            rows, Hs = [], []
            for d in accepted:
                r, H = self._measurement(d)  # type: ignore[misc]
                rows.append(r)
                Hs.append(H)
            H = np.vstack(Hs)
            offset = np.zeros(P.shape[0])  # current estimate (-) prior
            for name, _, i in robots:
                offset[i : i + 6] = pose_error(self._pose[name], prior[name])
            S = H @ P @ H.T + R
            K = np.linalg.solve(S, H @ P).T  # P H^T S^-1 (S, P symmetric)
            delta = K @ (np.concatenate(rows) + H @ offset)
            for name, robot, i in robots:
                step = delta[i : i + 6].copy()
                if robot.planar:
                    step[[2, 3, 4]] = 0.0
                self._pose[name] = apply_error(prior[name], step) if step.any() else prior[name]
        IKH = np.eye(P.shape[0]) - K @ H
        P_new = IKH @ P @ IKH.T + K @ R @ K.T
        P_new = 0.5 * (P_new + P_new.T)
        for _, robot, i in robots:
            if robot.planar:
                P_new[i + 2 : i + 5, :] = 0.0
                P_new[:, i + 2 : i + 5] = 0.0
        self._P = P_new
        return {id(d) for d in accepted}
