"""The MOMA estimator: robots localise each other through boards and cameras.

See the package docstring (:mod:`moma_env.estimator`) for the frames, the
mapping of the paper's G notation, and the update rules.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numba
import numpy as np

from moma_env.config import ConfigError, all_finite, check_rigid_transform
from moma_env.estimator.checks import checked_time, is_covariance, mapping_field
from moma_env.estimator.config import EstimatorConfig
from moma_env.estimator.detection import Detection
from moma_env.estimator.errors import (
    UnknownBoardError,
    UnknownCameraError,
    UnknownRobotError,
)
from moma_env.estimator.fusion import information_fusion
from moma_env.estimator.gate import OutlierGate
from moma_env.estimator.results import Phase, RobotEstimate, Status, SwitchEvent
from moma_env.estimator.kernels import (
    packed_camera_from_reference_board,
    packed_sample_from_board_seen,
    packed_sample_from_mounted_frame,
)
from moma_env.estimator.uncertainty import (
    NO_MATRIX,
    LinearError,
    compose_jacobian_first,
    covariance_of_operands,
    matrix6_array,
    noise_operands,
    packed_operands,
)
from moma_env.estimator.window import SettlingWindow
from moma_env.geometry import invert, mean_pose, pose_array

__all__ = ["MomaEstimator"]

_MOBILE = Phase.MOBILE
_SETTLING = Phase.SETTLING
_REFERENCE = Phase.REFERENCE

#: Largest deviation of a detection's rotation block from orthonormality (and of its last row).
_ROTATION_TOLERANCE = 1e-6
_EYE3 = np.eye(3)
#: The fast checks below pass a rotation block only this far inside the tolerance;
#: closer to it (and for anything unusual) the exact numpy checks decide.
_CLEAR_ROTATION_TOLERANCE = _ROTATION_TOLERANCE * (1.0 - 1e-6)


def _what(d: Detection) -> str:
    return f"detection of board {d.board_id} by camera {d.camera_id!r}"


def _clearly_rigid(T: object) -> bool:
    """Whether ``T`` is a float64 4x4 array that :func:`_check_pose` passes, decided in plain floats.

    True only when every entry is finite, the rotation block is orthonormal
    within :data:`_CLEAR_ROTATION_TOLERANCE` (far more than the rounding of
    ``R^T R``), its determinant is above 0.5 (it is 1 within 3e-6 once
    orthonormal) and the last row is ``(0, 0, 0, 1)`` within the tolerance
    (the same arithmetic as numpy). False sends ``T`` to the exact checks.
    """
    if type(T) is not np.ndarray or T.shape != (4, 4) or T.dtype.char != "d":
        return False
    return _clearly_rigid_kernel(T, _CLEAR_ROTATION_TOLERANCE, _ROTATION_TOLERANCE)


@numba.njit(cache=True)
def _clearly_rigid_kernel(T: np.ndarray, tol: float, last_row_tol: float) -> bool:
    """:func:`_clearly_rigid` of a float64 4x4 array, compiled."""
    total = 0.0
    for r in range(4):
        for c in range(4):
            total += T[r, c]
    if not math.isfinite(total):
        return False
    a, b, c = T[0, 0], T[0, 1], T[0, 2]
    e, f, g = T[1, 0], T[1, 1], T[1, 2]
    i, j, k = T[2, 0], T[2, 1], T[2, 2]
    return (
        abs(a * a + e * e + i * i - 1.0) <= tol
        and abs(b * b + f * f + j * j - 1.0) <= tol
        and abs(c * c + g * g + k * k - 1.0) <= tol
        and abs(a * b + e * f + i * j) <= tol
        and abs(a * c + e * g + i * k) <= tol
        and abs(b * c + f * g + j * k) <= tol
        and a * (f * k - g * j) - b * (e * k - g * i) + c * (e * j - f * i) > 0.5
        and abs(T[3, 0]) <= last_row_tol
        and abs(T[3, 1]) <= last_row_tol
        and abs(T[3, 2]) <= last_row_tol
        and abs(T[3, 3] - 1.0) <= last_row_tol
    )


def _check_pose(d: Detection) -> None:
    """ValueError unless ``d.T_c_m`` is a finite 4x4 rigid transform (the exact checks)."""
    T_c_m = d.T_c_m
    if not isinstance(T_c_m, np.ndarray) or T_c_m.shape != (4, 4) or not all_finite(T_c_m):
        raise ValueError(f"{_what(d)}: T_c_m must be a finite 4x4 array")
    R = T_c_m[:3, :3]
    if (
        np.abs(R.T @ R - _EYE3).max() > _ROTATION_TOLERANCE
        or np.linalg.det(R) <= 0.0
        or np.abs(T_c_m[3] - (0.0, 0.0, 0.0, 1.0)).max() > _ROTATION_TOLERANCE
    ):
        raise ValueError(
            f"{_what(d)}: T_c_m must be a rigid transform (rotation block orthonormal within "
            f"{_ROTATION_TOLERANCE:g}, determinant +1, last row (0, 0, 0, 1)); "
            f"got determinant {np.linalg.det(R):.6g}"
        )


def _clearly_valid_covariance(cov: object) -> bool:
    """Whether ``cov`` is a float64 6x6 array that :func:`_check_covariance` passes, in plain floats.

    For finite entries this is the same arithmetic as the exact check; anything
    else (another type, shape or dtype, a non-finite entry) goes to it.
    """
    if type(cov) is not np.ndarray or cov.shape != (6, 6) or cov.dtype.char != "d":
        return False
    return _clearly_valid_covariance_kernel(cov)


@numba.njit(cache=True)
def _clearly_valid_covariance_kernel(cov: np.ndarray) -> bool:
    """:func:`_clearly_valid_covariance` of a float64 6x6 array, compiled."""
    total = 0.0
    largest = 0.0
    for r in range(6):
        for c in range(6):
            total += cov[r, c]
            largest = max(largest, abs(cov[r, c]))
    if not math.isfinite(total):
        return False
    for d in range(6):
        if cov[d, d] < 0.0:
            return False
    limit = 1e-9 * max(1.0, largest)
    for r in range(6):
        for c in range(r + 1, 6):
            if abs(cov[r, c] - cov[c, r]) > limit:
                return False
    return True


@numba.njit(cache=True)
def _failed_fast_checks_kernel(T: np.ndarray, cov: np.ndarray, tol: float, last_row_tol: float) -> int:
    """Both fast checks of a detection in one compiled call: bit 1 set when ``T`` (float64 4x4)
    fails :func:`_clearly_rigid_kernel`, bit 2 when ``cov`` (float64 6x6) fails
    :func:`_clearly_valid_covariance_kernel`; 0 when both pass."""
    failed = 0 if _clearly_rigid_kernel(T, tol, last_row_tol) else 1
    if not _clearly_valid_covariance_kernel(cov):
        failed += 2
    return failed


def _check_covariance(d: Detection) -> None:
    """ValueError unless ``d.covariance`` is a finite symmetric 6x6 array with a non-negative diagonal."""
    if not is_covariance(d.covariance):
        raise ValueError(f"{_what(d)}: covariance must be a finite symmetric 6x6 array with a non-negative diagonal")


def _check_persistent(d: Detection) -> None:
    """ValueError unless ``d.persistent_covariance`` is a finite symmetric 6x6 array with a
    non-negative diagonal, given with a ``covariance`` (it is a part of it)."""
    P = d.persistent_covariance
    if d.covariance is None:
        raise ValueError(f"{_what(d)}: persistent_covariance needs a covariance (it is a part of it)")
    if not _clearly_valid_covariance(P) and not is_covariance(P):
        raise ValueError(
            f"{_what(d)}: persistent_covariance must be a finite symmetric 6x6 array with a non-negative diagonal"
        )


class _Robot:
    """Mutable per-robot state of the estimator (private)."""

    __slots__ = (
        "name",
        "board_mounts",
        "board_inverses",
        "camera_mounts",
        "camera_inverses",
        "phase",
        "pose",
        "status",
        "last_fresh_time",
        "lost_logged",
        "window",
        "n_frozen",
        "static_since",
        "gate",
        "board_world",
        "board_world_J",
        "camera_world",
        "plane_z",
        "covariance",
        "ref_key",
    )

    def __init__(
        self,
        name: str,
        board_mounts: dict[int, np.ndarray],
        camera_mounts: dict[str, np.ndarray],
        window: SettlingWindow,
        gate: OutlierGate | None,
        plane_z: float | None,
    ):
        self.name = name
        self.plane_z = plane_z  # body height if the robot moves on the floor (upright), else None
        self.board_mounts = board_mounts  # board_id -> T_b_m
        self.board_inverses = {k: invert(T) for k, T in board_mounts.items()}  # T_m_b
        self.camera_mounts = camera_mounts  # camera_id -> T_b_c
        self.camera_inverses = {k: invert(T) for k, T in camera_mounts.items()}  # T_c_b
        self.phase = _MOBILE
        self.pose: np.ndarray | None = None  # reported T_w_b
        self.status = Status.LOST
        self.last_fresh_time: float | None = None
        self.lost_logged = False
        self.window = window  # samples with their errors
        self.n_frozen = 0
        self.static_since = 0.0
        self.gate = gate
        self.board_world: dict[int, np.ndarray] = {}  # board_id -> T_w_m, REFERENCE only
        self.board_world_J: dict[int, np.ndarray] = {}  # board_id -> d e(T_w_m) / d e(T_w_b), REFERENCE only
        self.camera_world: dict[str, tuple[np.ndarray, LinearError]] = {}  # camera_id -> T_w_c and its error
        self.covariance: np.ndarray | None = None  # 6x6 of the reported pose (uncertainty module's convention)
        self.ref_key: int | None = None  # key of the frozen pose's error in the joint covariance, REFERENCE only


class MomaEstimator:
    """Tracks the pose ``T_w_b`` of every robot from board detections (MOMA).

    Usage::

        est = MomaEstimator(EstimatorConfig())
        est.add_robot("ugv_0", boards={0: T_b_m}, static=True, initial_pose=T_w_b0)
        est.add_robot("uav", cameras={"down": T_b_c}, static=False)
        est.update(t, detections)         # once per camera frame (all cameras)
        est.set_static("ugv_0", False, t) # the owner's declarations
        est.estimate("ugv_0").T_w_b

    Times (s) must not go backwards across ``add_robot``, ``update`` and
    ``set_static``. The ``time`` of :meth:`update` is authoritative; the
    detections' own ``time`` fields are not used.
    """

    def __init__(self, config: EstimatorConfig | None = None):
        if config is None:
            config = EstimatorConfig()
        if not isinstance(config, EstimatorConfig):
            raise TypeError(f"config must be an EstimatorConfig, got {type(config).__name__}")
        self._config = config
        self._information_fusion = config.fusion == "information"
        self._robots: dict[str, _Robot] = {}
        self._board_owner: dict[int, _Robot] = {}
        self._camera_owner: dict[str, _Robot] = {}
        # T_w_c and its error, of cameras on REFERENCE robots / located in the last update.
        self._reference_cameras: dict[str, tuple[np.ndarray, LinearError]] = {}
        self._camera_poses: dict[str, tuple[np.ndarray, LinearError]] = {}
        # Joint covariance of the errors of the frozen poses still in use, by pair of keys.
        self._joint: dict[tuple[int, int], np.ndarray] = {}
        self._next_key = 0
        self._events: list[SwitchEvent] = []
        self._time: float | None = None

    # ------------------------------------------------------------------ queries
    @property
    def config(self) -> EstimatorConfig:
        """The configuration."""
        return self._config

    @property
    def time(self) -> float | None:
        """Time (s) of the last call that took a time, None before any."""
        return self._time

    @property
    def robots(self) -> tuple[str, ...]:
        """Names of the robots, in the order they were added."""
        return tuple(self._robots)

    @property
    def events(self) -> tuple[SwitchEvent, ...]:
        """Every switch event so far, in order."""
        return tuple(self._events)

    def estimate(self, name: str) -> RobotEstimate:
        """Snapshot of robot ``name``'s estimate (the pose is a copy)."""
        return self._snapshot(self._robot(name))

    def estimates(self) -> dict[str, RobotEstimate]:
        """Snapshots of every robot, by name."""
        snapshot = self._snapshot
        return {name: snapshot(r) for name, r in self._robots.items()}

    @staticmethod
    def _snapshot(r: _Robot) -> RobotEstimate:
        phase = r.phase
        if phase is _SETTLING:
            n_window = len(r.window)
        elif phase is _REFERENCE:
            n_window = r.n_frozen
        else:
            n_window = 0
        pose = r.pose
        if pose is None:
            return RobotEstimate(r.name, None, r.status, phase, r.last_fresh_time, n_window, None)
        cov = r.covariance
        return RobotEstimate(r.name, pose.copy(), r.status, phase, r.last_fresh_time, n_window, None if cov is None else cov.copy())

    def camera_pose(self, camera_id: str) -> np.ndarray | None:
        """``T_w_c`` (4x4 copy) of a camera located in the last update, else None."""
        if camera_id not in self._camera_owner:
            raise UnknownCameraError(camera_id, self._camera_owner)
        located = self._camera_poses.get(camera_id)
        return None if located is None else located[0].copy()

    def camera_covariance(self, camera_id: str) -> np.ndarray | None:
        """6x6 covariance of :meth:`camera_pose` (world frame, the convention of
        :mod:`moma_env.estimator.uncertainty`), None if the camera was not located."""
        if camera_id not in self._camera_owner:
            raise UnknownCameraError(camera_id, self._camera_owner)
        located = self._camera_poses.get(camera_id)
        return None if located is None else located[1].covariance(self._joint)

    def window_ready(self, name: str) -> bool:
        """Whether robot ``name`` holds a pose another robot may rely on after a switch.

        True for a REFERENCE, and for a SETTLING robot whose window holds at
        least ``min_window`` inlier samples (it is frozen when another robot is
        declared mobile); False otherwise (a MOBILE robot, or one still
        collecting its window: declaring another robot mobile now leaves it
        settling, not a reference).
        """
        r = self._robot(name)
        if r.phase is _REFERENCE:
            return True
        return r.phase is _SETTLING and self._window_full_enough(r)

    def _window_full_enough(self, r: _Robot) -> bool:
        return len(r.window) >= self._config.min_window and len(r.window.inliers()) >= self._config.min_window

    # ------------------------------------------------------------ declarations
    def add_robot(
        self,
        name: str,
        *,
        boards: Mapping[int, np.ndarray] | None = None,
        cameras: Mapping[str, np.ndarray] | None = None,
        static: bool,
        initial_pose: np.ndarray | None = None,
        time: float | None = None,
        planar: bool = False,
    ) -> None:
        """Declare a robot.

        Args:
            name: unique robot name.
            boards: board_id -> ``T_b_m``, the board frame M in the body frame B (m).
            cameras: camera_id -> ``T_b_c``, the camera frame C in the body frame B (m).
            static: the owner's declaration. A static robot with an initial pose
                is a frozen reference from the start (it defines the world frame
                W); a static robot without one settles once it is measured.
            initial_pose: ``T_w_b`` at ``time``, or None if unknown.
            time: time of the declaration (s); None means the estimator's last
                time (0.0 before any).
            planar: the robot moves on the floor, upright (a UGV): roll and pitch
                are zero and its height is that of ``initial_pose`` (0 without
                one). Each measured mount pose is then projected on the plane at
                the mount (:func:`moma_env.geometry.upright_body_from_mount`).

        Raises:
            ConfigError: bad or duplicate name, board id or camera id,
                or a mount / pose that is not a finite rigid transform.
            ValueError: ``time`` is not finite or goes backwards.
        """
        if not isinstance(name, str) or not name:
            raise ConfigError("name", f"robot name must be a non-empty string, got {name!r}")
        if name in self._robots:
            raise ConfigError("name", f"duplicate robot name {name!r}")
        if not isinstance(static, bool):
            raise ConfigError(f"robots[{name!r}].static", f"must be a bool, got {static!r}")
        if not isinstance(planar, bool):
            raise ConfigError(f"robots[{name!r}].planar", f"must be a bool, got {planar!r}")
        if time is None:
            time = 0.0 if self._time is None else self._time
        t = self._checked_time(time)

        board_mounts: dict[int, np.ndarray] = {}
        for board_id, mount in mapping_field(f"robots[{name!r}].boards", boards).items():
            if isinstance(board_id, bool) or not isinstance(board_id, (int, np.integer)):
                raise ConfigError(f"robots[{name!r}].boards", f"board ids must be integers, got {board_id!r}")
            board_id = int(board_id)
            owner = self._board_owner.get(board_id)
            if owner is not None:
                raise ConfigError(
                    f"robots[{name!r}].boards", f"duplicate board id {board_id} (already on robot {owner.name!r})"
                )
            board_mounts[board_id] = check_rigid_transform(f"robots[{name!r}].boards[{board_id}]", mount)

        camera_mounts: dict[str, np.ndarray] = {}
        for camera_id, mount in mapping_field(f"robots[{name!r}].cameras", cameras).items():
            if not isinstance(camera_id, str) or not camera_id:
                raise ConfigError(
                    f"robots[{name!r}].cameras", f"camera ids must be non-empty strings, got {camera_id!r}"
                )
            owner = self._camera_owner.get(camera_id)
            if owner is not None:
                raise ConfigError(
                    f"robots[{name!r}].cameras", f"duplicate camera id {camera_id!r} (already on robot {owner.name!r})"
                )
            camera_mounts[camera_id] = check_rigid_transform(f"robots[{name!r}].cameras[{camera_id!r}]", mount)

        pose = None if initial_pose is None else check_rigid_transform(f"robots[{name!r}].initial_pose", initial_pose)

        cfg = self._config
        gate = OutlierGate(cfg.gate) if cfg.gate is not None and cfg.gate.enabled else None
        plane_z = (0.0 if pose is None else float(pose[2, 3])) if planar else None
        window = SettlingWindow(cfg.window, cfg.window_outlier_k, cfg.window_floor_m, cfg.window_floor_rad, self._joint)
        r = _Robot(name, board_mounts, camera_mounts, window, gate, plane_z)
        r.pose = pose
        if pose is not None:
            r.covariance = np.zeros((6, 6))
            r.last_fresh_time = t
            r.status = Status.LOCALISED
            if gate is not None:
                gate.reset(seed=pose, time=t)
        if static:
            r.phase = _SETTLING
            r.static_since = t
            if pose is not None:
                self._freeze(r, t, LinearError(), 0, log=False)

        self._time = t
        self._robots[name] = r
        for board_id in board_mounts:
            self._board_owner[board_id] = r
        for camera_id in camera_mounts:
            self._camera_owner[camera_id] = r

    def set_static(self, name: str, static: bool, time: float) -> None:
        """The owner declares robot ``name`` static (True) or mobile (False) at ``time`` (s).

        Static: a MOBILE robot starts SETTLING with an empty window; its last
        fresh pose stays its reported pose (and its status ages as usual: a
        LOST robot stays LOST) until a window sample arrives.
        Mobile: first every other SETTLING robot whose window is ready
        (:meth:`window_ready`) is frozen from its window; one that is not stays
        SETTLING and is no reference until its window fills, so a pose that is
        not fresh never becomes a reference. Then the robot leaves REFERENCE /
        SETTLING and is tracked at every update. Repeating the current
        declaration does nothing.
        """
        r = self._robot(name)
        if not isinstance(static, bool):
            raise ValueError(f"static must be a bool, got {static!r}")
        t = self._checked_time(time)
        self._time = t
        if static:
            if r.phase is _MOBILE:
                r.phase = _SETTLING
                r.window.clear()
                r.static_since = t
                self._events.append(SwitchEvent(t, name, "static", 0))
            return
        if r.phase is _MOBILE:
            return
        for other in self._robots.values():
            if other is not r and other.phase is _SETTLING and self._window_full_enough(other):
                self._freeze_window(other, t)
        pose_valid_now = r.phase is _REFERENCE or len(r.window) > 0
        if r.phase is _REFERENCE:
            for camera_id in r.camera_world:
                del self._reference_cameras[camera_id]
            r.board_world = {}
            r.board_world_J = {}
            r.camera_world = {}
            r.ref_key = None
            if r.gate is not None:
                r.gate.reset(seed=r.pose, time=t)
        r.phase = _MOBILE
        r.window.clear()
        r.n_frozen = 0
        self._forget_unused_keys()
        if pose_valid_now:
            r.last_fresh_time = t
            r.status = Status.LOCALISED
        self._events.append(SwitchEvent(t, name, "mobile", 0))

    # ------------------------------------------------------------------ update
    def update(self, time: float, detections: Iterable[Detection]) -> None:
        """Process one camera frame (the detections of every camera) taken at ``time`` (s).

        Raises (before changing any state):
            TypeError: ``detections`` is not an iterable of :class:`Detection`.
            UnknownCameraError / UnknownBoardError: an id no robot carries.
            ValueError: a ``T_c_m`` that is not a finite rigid transform (4x4,
                rotation block orthonormal with determinant +1, last row
                ``(0, 0, 0, 1)``), a ``covariance`` that is not a finite
                symmetric 6x6 array with a non-negative diagonal, one board
                detected twice by one camera in the frame (a detector reports a
                board once per image), or ``time`` not a finite number or going
                backwards.
        """
        t = self._checked_time(time)
        by_camera = self._checked_detections(detections)
        camera_owner = self._camera_owner
        joint = self._joint
        self._time = t

        # 1. Cameras: on a reference robot from its frozen pose, else from the
        #    reference boards they see (never through a non-reference board).
        camera_poses = dict(self._reference_cameras)
        for camera_id, group in by_camera.items():
            if camera_id in camera_poses:
                continue
            own = camera_owner[camera_id]
            located: list[np.ndarray] = []
            errors: list[LinearError] = []
            for board_id, ref, T_c_m, cov, has_cov, persistent, has_persistent in group:
                if ref.phase is _REFERENCE and ref is not own:
                    # LinearError(J).plus_noise(J_meas @ inverse_jacobian(T_c_m), covariance), without
                    # the zero Q: Q + 0.0 is the 0 + Q it gave (-0.0 entries turn +0.0 alike).
                    T_w_c, packed = packed_camera_from_reference_board(
                        ref.board_world[board_id], ref.board_world_J[board_id], T_c_m, cov, has_cov, persistent, has_persistent
                    )
                    errors.append(LinearError.of_packed((ref.ref_key,), packed, has_persistent))
                    located.append(T_w_c)
            if located:
                if len(located) == 1:
                    camera_poses[camera_id] = (located[0], errors[0])
                elif self._information_fusion:
                    camera_poses[camera_id] = information_fusion(located, errors, joint)
                else:
                    camera_poses[camera_id] = (mean_pose(located), LinearError.mean(errors))

        # 2. Samples of the non-reference robots: boards seen by located cameras,
        #    and robots carrying a located camera. A located camera's error operands
        #    are taken once, for both kinds of samples.
        # Each sample: (pose, its error's reference keys, the error packed, whether it has a
        # persistent part): LinearError.of_packed's arguments, an error made only to be fused.
        samples: dict[_Robot, list[tuple[np.ndarray, list, np.ndarray, bool]]] = {}
        camera_operands: dict[str, list] = {}
        for camera_id, group in by_camera.items():
            located_camera = camera_poses.get(camera_id)
            if located_camera is None:
                continue
            T_w_c = located_camera[0]
            own = camera_owner[camera_id]
            operands = None
            for board_id, r, T_c_m, cov, has_cov, persistent, has_persistent in group:
                if r.phase is not _REFERENCE and r is not own:
                    if operands is None:
                        operands = camera_operands[camera_id] = located_camera[1].operands()
                    keys, Js, Q, P, has_P = operands
                    plane_z = r.plane_z
                    sample, packed, has_P_out = packed_sample_from_board_seen(
                        T_w_c, T_c_m, r.board_mounts[board_id], r.board_inverses[board_id],
                        plane_z is not None, 0.0 if plane_z is None else plane_z,
                        Js, Q, P, has_P, cov, has_cov, persistent, has_persistent,
                    )
                    samples.setdefault(r, []).append((sample, keys, packed, has_P_out))
        for camera_id, (T_w_c, camera_error) in camera_poses.items():
            r = camera_owner[camera_id]
            if r.phase is not _REFERENCE:
                operands = camera_operands.get(camera_id)
                if operands is None:
                    operands = camera_error.operands()
                keys, Js, Q, P, has_P = operands
                plane_z = r.plane_z
                sample, packed, has_P_out = packed_sample_from_mounted_frame(
                    T_w_c, r.camera_mounts[camera_id], r.camera_inverses[camera_id],
                    plane_z is not None, 0.0 if plane_z is None else plane_z, Js, Q, P, has_P,
                )
                samples.setdefault(r, []).append((sample, keys, packed, has_P_out))

        measured: list[_Robot] = []
        settle_delay = self._config.settle_delay_s
        for r, parts in samples.items():
            if len(parts) == 1:  # the sample's error used as its compiled call packed it
                T, keys, packed, has_P = parts[0]
                operands = packed_operands(keys, packed, has_P)
            else:
                poses = [part[0] for part in parts]
                errors = [LinearError.of_packed(keys, packed, has_P) for _, keys, packed, has_P in parts]
                if self._information_fusion:
                    T, error = information_fusion(poses, errors, joint)
                else:
                    T = mean_pose(poses)
                    error = LinearError.mean(errors)
                operands = error.operands()
            gate = r.gate
            if gate is not None and not gate.accept(T, t):
                continue
            phase = r.phase
            if phase is _MOBILE:
                r.pose = T
                r.covariance = covariance_of_operands(operands[0], operands[1], operands[2], joint)
                measured.append(r)
            elif t - r.static_since >= settle_delay:  # SETTLING
                window = r.window
                r.pose, r.covariance = window.add_operands(T, *operands)
                if window.full:
                    self._freeze_window(r, t)

        # 3. Status.
        lost_after = self._config.lost_after_s
        for r in self._robots.values():
            phase = r.phase
            if phase is _REFERENCE or (phase is _SETTLING and len(r.window) > 0) or r in measured:
                self._mark_fresh(r, t)
            elif r.last_fresh_time is None:
                r.status = Status.LOST
            elif t - r.last_fresh_time > lost_after:
                r.status = Status.LOST
                if not r.lost_logged:
                    r.lost_logged = True
                    self._events.append(SwitchEvent(t, r.name, "lost", 0))
            else:
                r.status = Status.HOLDING
        self._camera_poses = camera_poses

    # ---------------------------------------------------------------- helpers
    def _checked_detections(self, detections: Iterable[Detection]) -> dict[str, list[tuple]]:
        """The detections grouped by camera, after every check of :meth:`update`.

        Each detection comes as what the compiled steps take of it: ``(board_id, the
        board's robot, T_c_m, covariance, has covariance, persistent covariance, has
        persistent covariance)``, the arrays C-ordered float64 (:func:`pose_array`,
        :func:`noise_operands`: zero stand-ins where absent).
        """
        if type(detections) is not list and (
            detections is None or isinstance(detections, (str, bytes, Detection)) or not isinstance(detections, Iterable)
        ):
            raise TypeError(f"detections must be an iterable of Detection, got {type(detections).__name__}")
        camera_owner = self._camera_owner
        board_owner = self._board_owner
        by_camera: dict[str, list[tuple]] = {}
        for i, d in enumerate(detections):
            if type(d) is not Detection and not isinstance(d, Detection):
                raise TypeError(f"detections[{i}] must be a Detection, got {type(d).__name__}")
            camera_id = d.camera_id
            if camera_id not in camera_owner:
                raise UnknownCameraError(camera_id, camera_owner)
            board_id = d.board_id
            r = board_owner.get(board_id)
            if r is None:
                raise UnknownBoardError(board_id, board_owner)
            T_c_m = d.T_c_m
            cov = d.covariance
            persistent = d.persistent_covariance
            if (
                type(T_c_m) is np.ndarray and T_c_m.shape == (4, 4) and T_c_m.dtype.char == "d"
                and type(cov) is np.ndarray and cov.shape == (6, 6) and cov.dtype.char == "d"
            ):
                # The usual detection: both fast checks in one compiled call, the exact
                # checks (pose first) for what they do not clearly pass.
                failed = _failed_fast_checks_kernel(T_c_m, cov, _CLEAR_ROTATION_TOLERANCE, _ROTATION_TOLERANCE)
                if failed & 1:
                    _check_pose(d)
                if failed & 2:
                    _check_covariance(d)
                # Without a persistent part, C-ordered: what pose_array and noise_operands give.
                fast = persistent is None and T_c_m.flags.c_contiguous and cov.flags.c_contiguous
            else:
                if not _clearly_rigid(T_c_m):
                    _check_pose(d)
                if cov is not None and not _clearly_valid_covariance(cov):
                    _check_covariance(d)
                fast = False
            if fast:
                entry = (board_id, r, T_c_m, cov, True, NO_MATRIX, False)
            else:
                if persistent is not None:
                    _check_persistent(d)
                entry = (board_id, r, pose_array(T_c_m, "T_c_m"), *noise_operands(cov, persistent))
            group = by_camera.get(camera_id)
            if group is None:
                by_camera[camera_id] = [entry]
            else:
                for other in group:
                    if other[0] == board_id:
                        raise ValueError(
                            f"{_what(d)}: the board is detected twice in one frame by the same camera"
                        )
                group.append(entry)
        return by_camera

    def _robot(self, name: str) -> _Robot:
        r = self._robots.get(name)
        if r is None:
            raise UnknownRobotError(name, self._robots)
        return r

    def _checked_time(self, time: float) -> float:
        """``time`` as a float if a finite real number not before the last time, else ValueError."""
        return checked_time(time, self._time)

    def _mark_fresh(self, r: _Robot, t: float) -> None:
        r.last_fresh_time = t
        r.status = Status.LOCALISED
        if r.lost_logged:
            r.lost_logged = False
            self._events.append(SwitchEvent(t, r.name, "relocalised", 0))

    def _freeze_window(self, r: _Robot, t: float) -> None:
        """Freeze a SETTLING robot at the mean of its window's inliers."""
        window = r.window
        index = window.inliers()
        r.pose = window.mean()
        self._freeze(r, t, window.mean_error(), len(index))

    def _freeze(self, r: _Robot, t: float, error: LinearError, n_samples: int, *, log: bool = True) -> None:
        """Make a robot a reference at its current pose, whose error is ``error``.

        The frozen pose's error gets a new key in the joint covariance, with its
        cross-covariances to every frozen pose still in use.
        """
        pose = r.pose
        assert pose is not None
        joint = self._joint
        key = self._next_key
        self._next_key += 1
        others = {a for a, _ in joint}
        own = error.covariance(joint)
        for other in others:
            C = error.cross(joint, other)
            joint[(key, other)] = C
            joint[(other, key)] = C.T
        joint[(key, key)] = own
        r.phase = _REFERENCE
        r.ref_key = key
        r.covariance = own
        r.n_frozen = n_samples
        r.window.clear()
        r.board_world = {}
        r.board_world_J = {}
        for board_id, T_b_m in r.board_mounts.items():
            r.board_world[board_id] = pose @ T_b_m
            r.board_world_J[board_id] = compose_jacobian_first(pose, T_b_m)
        r.camera_world = {
            camera_id: (pose @ T_b_c, LinearError({key: compose_jacobian_first(pose, T_b_c)}))
            for camera_id, T_b_c in r.camera_mounts.items()
        }
        self._reference_cameras.update(r.camera_world)
        self._mark_fresh(r, t)
        self._forget_unused_keys(keep=key)
        if log:
            self._events.append(SwitchEvent(t, r.name, "frozen", n_samples))

    def _forget_unused_keys(self, keep: int | None = None) -> None:
        """Drop from the joint covariance the frozen poses that no reference, window
        sample or located camera depends on (``keep``: a key to keep regardless)."""
        used: set[int] = {keep} if keep is not None else set()
        for r in self._robots.values():
            if r.phase is _REFERENCE:
                used.add(r.ref_key)  # type: ignore[arg-type]
            elif r.phase is _SETTLING:
                used.update(r.window.references())
        for _, error in self._camera_poses.values():
            used.update(error.references())
        joint = self._joint
        for pair in [pair for pair in joint if pair[0] not in used or pair[1] not in used]:
            del joint[pair]
