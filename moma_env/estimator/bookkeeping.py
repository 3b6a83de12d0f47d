"""What every estimator behind the localiser protocol shares besides its mathematics.

The robots and their mounts, the owners' declarations (phases), the statuses
and switch events, time checks and the checks of a frame's detections, with
the semantics of :class:`~moma_env.estimator.MomaEstimator`:

* phases: a robot declared static is SETTLING until it has been measured
  ``window`` times since its declaration (or, when another robot is declared
  mobile, ``min_window`` times), then it is a REFERENCE; a robot with an
  initial pose that starts static is a REFERENCE from the start; a robot
  declared mobile is MOBILE (:meth:`Bookkeeper.set_static`);
* statuses: LOCALISED when measured this update, or a REFERENCE, or a SETTLING
  robot measured since its declaration; HOLDING otherwise; LOST when not fresh
  for longer than ``lost_after_s`` or never localised
  (:meth:`Bookkeeper.end_update`);
* a robot is *measured* when a located camera sees one of its boards, or when
  it carries a located camera; a camera is *located* when it sees a board of a
  REFERENCE robot other than its own (so a team's error grows at switches, as
  in MOMA, whatever the estimator does with the measurements).

An estimator (:mod:`moma_env.estimator.ekf`, :mod:`moma_env.estimator.graph`)
keeps one :class:`Bookkeeper` and does its own estimation. Units: metres,
radians, seconds; mounts ``T_b_m`` / ``T_b_c`` (4x4) in the body frame B.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from moma_env.config import ConfigError, check_rigid_transform
from moma_env.estimator.checks import checked_time, is_covariance, mapping_field
from moma_env.estimator.config import EstimatorConfig
from moma_env.estimator.detection import Detection
from moma_env.estimator.errors import UnknownBoardError, UnknownCameraError, UnknownRobotError
from moma_env.estimator.results import Phase, RobotEstimate, Status, SwitchEvent

__all__ = ["RobotRecord", "Bookkeeper", "check_detection"]


class RobotRecord:
    """One robot as declared, and its phase and status (mutable; owned by a :class:`Bookkeeper`).

    Attributes:
        name: the robot.
        boards: board id -> ``T_b_m`` (4x4).
        cameras: camera id -> ``T_b_c`` (4x4).
        planar: moves upright on the floor at height ``plane_z`` (m).
        phase, status: as reported.
        last_fresh_time: last time (s) the pose was fresh, None if never.
        n_static: times measured since the last static declaration.
        initial_pose: ``T_w_b`` given at ``add_robot``, or None.
    """

    def __init__(self, name: str, boards: dict[int, np.ndarray], cameras: dict[str, np.ndarray], planar: bool,
                 initial_pose: np.ndarray | None):
        self.name = name
        self.boards = boards
        self.cameras = cameras
        self.planar = planar
        self.plane_z = 0.0 if initial_pose is None else float(initial_pose[2, 3])
        self.initial_pose = initial_pose
        self.phase = Phase.MOBILE
        self.status = Status.LOST
        self.last_fresh_time: float | None = None
        self.lost_logged = False
        self.n_static = 0


def check_detection(d: object, i: int, board_owner: Mapping[int, object], camera_owner: Mapping[str, object]) -> Detection:
    """``d`` if it is a :class:`Detection` of known ids with a finite rigid ``T_c_m`` and, if any,
    a finite symmetric 6x6 covariance and persistent covariance; TypeError / UnknownCameraError / UnknownBoardError /
    ValueError naming ``detections[i]`` otherwise."""
    if not isinstance(d, Detection):
        raise TypeError(f"detections[{i}] must be a Detection, got {type(d).__name__}")
    if d.camera_id not in camera_owner:
        raise UnknownCameraError(d.camera_id, camera_owner)
    if d.board_id not in board_owner:
        raise UnknownBoardError(d.board_id, board_owner)
    try:
        check_rigid_transform(f"detections[{i}].T_c_m", d.T_c_m)
    except ConfigError as err:
        raise ValueError(str(err)) from None
    cov = d.covariance
    if cov is not None and not is_covariance(cov):
        raise ValueError(f"detections[{i}].covariance must be a finite symmetric 6x6 array with a non-negative diagonal")
    P = d.persistent_covariance
    if P is not None:
        if cov is None:
            raise ValueError(f"detections[{i}].persistent_covariance needs a covariance (it is a part of it)")
        if not is_covariance(P):
            raise ValueError(
                f"detections[{i}].persistent_covariance must be a finite symmetric 6x6 array with a non-negative diagonal"
            )
    return d


class Bookkeeper:
    """Robots, declarations, phases, statuses and events of one estimator (see the module docstring)."""

    def __init__(self, config: EstimatorConfig):
        if not isinstance(config, EstimatorConfig):
            raise TypeError(f"config must be an EstimatorConfig, got {type(config).__name__}")
        self.config = config
        self.robots: dict[str, RobotRecord] = {}
        self.board_owner: dict[int, RobotRecord] = {}
        self.camera_owner: dict[str, RobotRecord] = {}
        self.events: list[SwitchEvent] = []
        self.time: float | None = None

    # ------------------------------------------------------------ declarations
    def add_robot(self, name: str, *, boards: Mapping[int, np.ndarray] | None, cameras: Mapping[str, np.ndarray] | None,
                  static: bool, initial_pose: np.ndarray | None, time: float | None, planar: bool) -> RobotRecord:
        """Validate and record a robot (the arguments of ``Localiser.add_robot``); ConfigError names a bad field."""
        if not isinstance(name, str) or not name:
            raise ConfigError("name", f"robot name must be a non-empty string, got {name!r}")
        if name in self.robots:
            raise ConfigError("name", f"duplicate robot name {name!r}")
        for what, value in (("static", static), ("planar", planar)):
            if not isinstance(value, bool):
                raise ConfigError(f"robots[{name!r}].{what}", f"must be a bool, got {value!r}")
        t = self.checked_time(0.0 if time is None and self.time is None else self.time if time is None else time)
        board_mounts: dict[int, np.ndarray] = {}
        for board_id, mount in mapping_field(f"robots[{name!r}].boards", boards).items():
            if isinstance(board_id, bool) or not isinstance(board_id, (int, np.integer)):
                raise ConfigError(f"robots[{name!r}].boards", f"board ids must be integers, got {board_id!r}")
            if int(board_id) in self.board_owner:
                raise ConfigError(f"robots[{name!r}].boards", f"duplicate board id {int(board_id)}")
            board_mounts[int(board_id)] = check_rigid_transform(f"robots[{name!r}].boards[{board_id}]", mount)
        camera_mounts: dict[str, np.ndarray] = {}
        for camera_id, mount in mapping_field(f"robots[{name!r}].cameras", cameras).items():
            if not isinstance(camera_id, str) or not camera_id:
                raise ConfigError(f"robots[{name!r}].cameras", f"camera ids must be non-empty strings, got {camera_id!r}")
            if camera_id in self.camera_owner:
                raise ConfigError(f"robots[{name!r}].cameras", f"duplicate camera id {camera_id!r}")
            camera_mounts[camera_id] = check_rigid_transform(f"robots[{name!r}].cameras[{camera_id!r}]", mount)
        pose = None if initial_pose is None else check_rigid_transform(f"robots[{name!r}].initial_pose", initial_pose)
        r = RobotRecord(name, board_mounts, camera_mounts, planar, pose)
        if pose is not None:
            r.last_fresh_time = t
            r.status = Status.LOCALISED
        if static:
            r.phase = Phase.REFERENCE if pose is not None else Phase.SETTLING
        self.time = t
        self.robots[name] = r
        for board_id in board_mounts:
            self.board_owner[board_id] = r
        for camera_id in camera_mounts:
            self.camera_owner[camera_id] = r
        return r

    def set_static(self, name: str, static: bool, time: float) -> RobotRecord:
        """The owner's declaration (the semantics of ``MomaEstimator.set_static``); the robot's record."""
        r = self.robot(name)
        if not isinstance(static, bool):
            raise ValueError(f"static must be a bool, got {static!r}")
        t = self.checked_time(time)
        self.time = t
        if static:
            if r.phase is Phase.MOBILE:
                r.phase = Phase.SETTLING
                r.n_static = 0
                self.events.append(SwitchEvent(t, name, "static", 0))
            return r
        if r.phase is Phase.MOBILE:
            return r
        for other in self.robots.values():
            if other is not r and other.phase is Phase.SETTLING and other.n_static >= self.config.min_window:
                self._make_reference(other, t)
        was_fresh = r.phase is Phase.REFERENCE or r.n_static > 0
        r.phase = Phase.MOBILE
        r.n_static = 0
        if was_fresh:
            self.mark_fresh(r, t)
        self.events.append(SwitchEvent(t, name, "mobile", 0))
        return r

    def _make_reference(self, r: RobotRecord, t: float) -> None:
        r.phase = Phase.REFERENCE
        self.mark_fresh(r, t)
        self.events.append(SwitchEvent(t, r.name, "frozen", r.n_static))

    # ------------------------------------------------------------------ update
    def begin_update(self, time: float, detections: Iterable[Detection]) -> tuple[float, dict[str, list[Detection]]]:
        """Check a frame: its time and its detections grouped by camera (one board once per camera)."""
        t = self.checked_time(time)
        if detections is None or isinstance(detections, (str, bytes, Detection)) or not isinstance(detections, Iterable):
            raise TypeError(f"detections must be an iterable of Detection, got {type(detections).__name__}")
        by_camera: dict[str, list[Detection]] = {}
        for i, d in enumerate(detections):
            check_detection(d, i, self.board_owner, self.camera_owner)
            group = by_camera.setdefault(d.camera_id, [])
            if any(other.board_id == d.board_id for other in group):
                raise ValueError(f"detections[{i}]: board {d.board_id} is detected twice in one frame by camera {d.camera_id!r}")
            group.append(d)
        self.time = t
        return t, by_camera

    def located_cameras(self, by_camera: Mapping[str, list[Detection]]) -> set[str]:
        """The cameras of the frame that see a board of a REFERENCE robot other than their own, and
        the cameras carried by REFERENCE robots that see anything."""
        located = set()
        for camera_id, group in by_camera.items():
            own = self.camera_owner[camera_id]
            if own.phase is Phase.REFERENCE or any(
                self.board_owner[d.board_id] is not own and self.board_owner[d.board_id].phase is Phase.REFERENCE for d in group
            ):
                located.add(camera_id)
        return located

    def still_frames(self, board_id: int) -> int:
        """Which frame (1, 2, ...) of its still run a detection of ``board_id`` in this update is.

        A board stands still while its owner is not MOBILE: this is ``1 +
        n_static`` of the owner (the frames it was measured in since its static
        declaration, this update's not yet counted), and 1 for a mobile owner
        (every frame of a moving board is a new scene). The index of
        :func:`~moma_env.estimator.detection.frame_fusion_covariance`.
        """
        r = self.board_owner[board_id]
        return 1 if r.phase is Phase.MOBILE else 1 + r.n_static

    def still_together(self, camera_id: str, group: list[Detection]) -> int:
        """Which frame (1, 2, ...) of a run in which the robots ``camera_id`` relates stand still together this is.

        The static robots of the frame are the owners of the boards in
        ``group`` (the camera's detections) that are not MOBILE, and the
        camera's owner if it is not MOBILE. With two or more, ``1 +
        min(n_static)`` over them (the frames since the latest of their static
        declarations); otherwise 1. Without odometry the only frames an
        estimator combines are those relating robots that stand still
        together, so this, not :meth:`still_frames`, is the index of
        :func:`~moma_env.estimator.detection.frame_fusion_covariance` there.
        """
        own = self.camera_owner[camera_id]
        static = {id(r): r for r in (self.board_owner[d.board_id] for d in group) if r is not own and r.phase is not Phase.MOBILE}
        if own.phase is not Phase.MOBILE:
            static[id(own)] = own
        if len(static) < 2:
            return 1
        return 1 + min(r.n_static for r in static.values())

    def measured_robots(self, by_camera: Mapping[str, list[Detection]], located: set[str]) -> set[str]:
        """The robots measured in the frame: boards seen by a located camera, carriers of a located camera."""
        measured = set()
        for camera_id in located:
            own = self.camera_owner[camera_id]
            measured.add(own.name)
            for d in by_camera[camera_id]:
                measured.add(self.board_owner[d.board_id].name)
        return measured

    def end_update(self, t: float, measured: set[str]) -> None:
        """Phases and statuses after an update at ``t`` in which the ``measured`` robots were measured."""
        cfg = self.config
        for r in self.robots.values():
            if r.name in measured and r.phase is not Phase.MOBILE:
                r.n_static += 1
                if r.phase is Phase.SETTLING and r.n_static >= cfg.window:
                    self._make_reference(r, t)
            if r.name in measured or r.phase is Phase.REFERENCE or (r.phase is Phase.SETTLING and r.n_static > 0):
                self.mark_fresh(r, t)
            elif r.last_fresh_time is None or t - r.last_fresh_time > cfg.lost_after_s:
                r.status = Status.LOST
                if r.last_fresh_time is not None and not r.lost_logged:
                    r.lost_logged = True
                    self.events.append(SwitchEvent(t, r.name, "lost", 0))
            else:
                r.status = Status.HOLDING

    def mark_fresh(self, r: RobotRecord, t: float) -> None:
        """The robot's pose is fresh at ``t`` (logs a relocalisation after a loss)."""
        r.last_fresh_time = t
        r.status = Status.LOCALISED
        if r.lost_logged:
            r.lost_logged = False
            self.events.append(SwitchEvent(t, r.name, "relocalised", 0))

    # ------------------------------------------------------------------ queries
    def robot(self, name: str) -> RobotRecord:
        """The record of ``name`` (UnknownRobotError otherwise)."""
        r = self.robots.get(name)
        if r is None:
            raise UnknownRobotError(name, self.robots)
        return r

    def window_ready(self, name: str) -> bool:
        """A REFERENCE, or a SETTLING robot measured at least ``min_window`` times since its declaration."""
        r = self.robot(name)
        return r.phase is Phase.REFERENCE or (r.phase is Phase.SETTLING and r.n_static >= self.config.min_window)

    def snapshot(self, r: RobotRecord, pose: np.ndarray | None, covariance: np.ndarray | None) -> RobotEstimate:
        """The :class:`RobotEstimate` of ``r`` with this pose and covariance (copied)."""
        n_window = 0 if r.phase is Phase.MOBILE else r.n_static
        if pose is None:
            return RobotEstimate(r.name, None, r.status, r.phase, r.last_fresh_time, n_window, None)
        return RobotEstimate(r.name, np.array(pose), r.status, r.phase, r.last_fresh_time, n_window,
                             None if covariance is None else np.array(covariance))

    # ------------------------------------------------------------------ checks
    def checked_time(self, time: float) -> float:
        """``time`` as a float if a finite real number not before the last time, else ValueError."""
        return checked_time(time, self.time)


class BookkeptLocaliser:
    """What a localiser built on a :class:`Bookkeeper` answers alike: its settings, robots,
    events, estimates and window readiness. A subclass sets ``self._book`` and gives
    :meth:`estimate_of` (its own pose and covariance of a robot)."""

    _book: Bookkeeper

    @property
    def config(self) -> EstimatorConfig:
        """The shared estimator settings (window, lost_after_s)."""
        return self._book.config

    @property
    def robots(self) -> tuple[str, ...]:
        """Names of the robots, in the order they were added."""
        return tuple(self._book.robots)

    @property
    def events(self) -> tuple[SwitchEvent, ...]:
        """Every switch event so far."""
        return tuple(self._book.events)

    def estimate_of(self, name: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Robot ``name``'s pose ``T_w_b`` and 6x6 covariance in W (None where unknown)."""
        raise NotImplementedError

    def estimate(self, name: str) -> RobotEstimate:
        """Snapshot of robot ``name``'s estimate."""
        r = self._book.robot(name)
        return self._book.snapshot(r, *self.estimate_of(name))

    def estimates(self) -> dict[str, RobotEstimate]:
        """Snapshots of every robot, by name."""
        return {name: self.estimate(name) for name in self._book.robots}

    def window_ready(self, name: str) -> bool:
        """See :meth:`Bookkeeper.window_ready`."""
        return self._book.window_ready(name)
