"""Validated configuration of the physics world: arena, UGVs, sleds, UAV.

Every configuration is a frozen dataclass that checks itself in ``__post_init__``
and raises :class:`moma_env.config.ConfigError` naming the offending field
("ugv.radius", "arena.obstacles[2]", "ugvs[1].initial_pose", ...).
:func:`world_config_from_mapping` builds a whole :class:`WorldConfig` from plain
mappings (JSON, YAML) and reports errors with their full path ("ugvs[1].radius").

Units: metres, seconds, radians (``max_tilt_deg`` in degrees), kilograms.
Poses ``(x, y, yaw)`` are planar poses of the body frame B in the world frame W
(for a sled: its frame S, origin at the centre of its footprint, x towards the
front where the rope is tied).
Mount transforms (``board_mount`` = T_b_m, camera ``T_b_c``) are 4x4 rigid
transforms in the body frame, stored as read-only arrays; configurations compare
and hash by value.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from moma_env.config import (
    check_numbers,
    ConfigError,
    check_choice,
    check_finite,
    check_non_negative,
    check_positive,
    check_range,
    from_mapping,
)
from moma_env.markers import BoardLayout, board_for_robot
from moma_env.world.footprints import (
    box_inside_rectangle,
    boxes_overlap,
    disk_inside_rectangle,
    disk_overlaps_box,
)
from moma_env.world.mounts import board_on_front, board_on_top, camera_down, rigid_transform

__all__ = [
    "BoxObstacle",
    "ArenaConfig",
    "CameraMount",
    "UGVConfig",
    "UAVConfig",
    "UAV_KINDS",
    "checked_observer_kinds",
    "SledConfig",
    "WorldConfig",
    "world_config_from_mapping",
    "unknown_name",
    "WALL_NAME",
    "obstacle_name",
]

#: Name reported for the walls in collision pairs (reserved: no robot or sled may take it).
WALL_NAME = "wall"
#: Start of the names reported for the obstacles in collision pairs (reserved, see :func:`obstacle_name`).
_OBSTACLE_PREFIX = "obstacle["

#: Kinds of observer the UAV state models.
UAV_KINDS = ("quadcopter", "handheld")

def checked_observer_kinds(field_name: str, value: object, max_observers: int | None = None) -> str | tuple[str, ...]:
    """``value``, one observer kind (:data:`UAV_KINDS`) or a sequence of them, as one kind or a
    tuple of two or more (a one-element sequence becomes its kind); ConfigError naming
    ``field_name`` (or ``field_name[k]``) otherwise, or beyond ``max_observers``."""
    if isinstance(value, str):
        check_choice(field_name, value, UAV_KINDS)
        return value
    try:
        kinds = tuple(value)  # type: ignore[arg-type]
    except TypeError:
        raise ConfigError(field_name, f"must be an observer kind or a tuple of them, got {value!r}") from None
    if not kinds:
        raise ConfigError(field_name, "must name at least one observer")
    if max_observers is not None and len(kinds) > max_observers:
        raise ConfigError(field_name, f"must name 1 to {max_observers} observers, got {len(kinds)}")
    for k, kind in enumerate(kinds):
        check_choice(f"{field_name}[{k}]", kind, UAV_KINDS)
    return kinds[0] if len(kinds) == 1 else kinds


#: Defaults that :meth:`UAVConfig.handheld` applies for a hand-held camera:
#: slower, smoother velocity response and much less tilt than a quadcopter.
_HANDHELD_DEFAULTS: Mapping[str, Any] = MappingProxyType(
    {
        "kind": "handheld",
        "response_time": 0.8,
        "max_accel": 0.5,
        "tilt_gain": 0.2,
        "tilt_time_constant": 0.5,
    }
)


def obstacle_name(index: int) -> str:
    """Name reported for obstacle ``index`` (its position in ``ArenaConfig.obstacles``) in collision pairs."""
    return f"{_OBSTACLE_PREFIX}{index}]"


def _reserved(name: str) -> bool:
    """Whether ``name`` is one of the names of the static shapes (walls, obstacles)."""
    return name == WALL_NAME or name.startswith(_OBSTACLE_PREFIX)


def unknown_name(kind: str, name: object, known: Sequence[str]) -> KeyError:
    """A KeyError for a name lookup that failed, listing the known names."""
    return KeyError(f"unknown {kind} {name!r}; known {kind}s are {list(known)}")


def _check_name(field_name: str, value: object) -> None:
    if not isinstance(value, str) or not value:
        raise ConfigError(field_name, f"must be a non-empty string, got {value!r}")


def _planar_pose(field_name: str, value: object) -> tuple[float, float, float]:
    return check_numbers(field_name, value, ("x", "y", "yaw"))  # type: ignore[return-value]


def _planar_point(field_name: str, value: object) -> tuple[float, float]:
    return check_numbers(field_name, value, ("x", "y"))  # type: ignore[return-value]


def _matrix_key(T: np.ndarray) -> tuple[float, ...]:
    return tuple(float(v) for v in T.ravel())


@dataclass(frozen=True)
class BoxObstacle:
    """A static rectangular obstacle.

    Attributes:
        x, y: centre in the world frame (m).
        width: extent along the box's own x axis (m).
        height: extent along the box's own y axis (m).
        yaw: rotation of the box about +z (rad).
    """

    x: float
    y: float
    width: float
    height: float
    yaw: float = 0.0

    def __post_init__(self) -> None:
        check_finite("obstacle.x", self.x)
        check_finite("obstacle.y", self.y)
        check_positive("obstacle.width", self.width)
        check_positive("obstacle.height", self.height)
        check_finite("obstacle.yaw", self.yaw)


@dataclass(frozen=True)
class ArenaConfig:
    """A walled rectangular floor with box obstacles.

    Attributes:
        width, height: interior size along world x and y (m).
        origin: world xy (m) of the interior's lower-left corner.
        wall_thickness: thickness of the walls, which lie outside the interior (m).
        obstacles: static box obstacles.
    """

    width: float = 6.0
    height: float = 6.0
    origin: tuple[float, float] = (-1.5, -1.5)
    wall_thickness: float = 0.1
    obstacles: tuple[BoxObstacle, ...] = ()

    def __post_init__(self) -> None:
        check_positive("arena.width", self.width)
        check_positive("arena.height", self.height)
        try:
            origin = tuple(self.origin)
        except TypeError:
            raise ConfigError("arena.origin", f"must be (x, y), got {self.origin!r}") from None
        if len(origin) != 2:
            raise ConfigError("arena.origin", f"must be (x, y), got {len(origin)} values")
        check_finite("arena.origin.x", origin[0])
        check_finite("arena.origin.y", origin[1])
        object.__setattr__(self, "origin", (float(origin[0]), float(origin[1])))
        check_positive("arena.wall_thickness", self.wall_thickness)
        obstacles = tuple(self.obstacles)
        for i, obstacle in enumerate(obstacles):
            if not isinstance(obstacle, BoxObstacle):
                raise ConfigError(f"arena.obstacles[{i}]", f"must be a BoxObstacle, got {type(obstacle).__name__}")
        object.__setattr__(self, "obstacles", obstacles)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """Interior ``(xmin, ymin, xmax, ymax)`` in the world frame (m)."""
        x0, y0 = self.origin
        return (x0, y0, x0 + self.width, y0 + self.height)


@dataclass(frozen=True)
class CameraMount:
    """A camera rigidly mounted on a body.

    Attributes:
        name: camera name, unique in the world (the Detection's ``camera_id``).
        T_b_c: 4x4 pose of the OpenCV camera frame C in the body frame B.
    """

    name: str
    T_b_c: np.ndarray = field(compare=False)
    _T_b_c_key: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        _check_name("camera.name", self.name)
        T = rigid_transform("camera.T_b_c", self.T_b_c)
        object.__setattr__(self, "T_b_c", T)
        object.__setattr__(self, "_T_b_c_key", _matrix_key(T))


@dataclass(frozen=True)
class UGVConfig:
    """An omnidirectional ground robot (Festo Robotino-like).

    Attributes:
        name: unique robot name (not "wall" nor "obstacle[...]", which name static shapes).
        initial_pose: (x, y, yaw) of B in W at reset (m, m, rad).
        radius: radius of the robot's circular footprint (m).
        mass: mass (kg); the moment of inertia is that of a uniform disk.
        max_speed: limit on the norm of the commanded planar velocity (m/s).
        max_yaw_rate: limit on the commanded yaw rate (rad/s).
        max_accel: traction limit: largest acceleration the wheels can give (m/s^2).
        max_yaw_accel: largest angular acceleration the wheels can give (rad/s^2).
        board: the ArUco board the robot carries, or None. The default has ids
            0..3; give every robot its own ids (``markers.board_for_robot(i)``).
        board_mount: 4x4 T_b_m of the board (default face-up, 0.40 m above the floor).
        cameras: cameras carried by the robot (e.g. a forward camera for caterpillar).
        static: whether the robot starts locked in place (a static marker).
    """

    name: str
    initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.225
    mass: float = 20.0
    max_speed: float = 0.5
    max_yaw_rate: float = 1.5
    max_accel: float = 1.0
    max_yaw_accel: float = 3.0
    board: BoardLayout | None = field(default_factory=BoardLayout)
    board_mount: np.ndarray = field(default_factory=board_on_top, compare=False)
    cameras: tuple[CameraMount, ...] = ()
    static: bool = True
    _board_mount_key: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        _check_name("ugv.name", self.name)
        if _reserved(self.name):
            raise ConfigError("ugv.name", f"{self.name!r} is reserved for static shapes")
        object.__setattr__(self, "initial_pose", _planar_pose("ugv.initial_pose", self.initial_pose))
        for name in ("radius", "mass", "max_speed", "max_yaw_rate", "max_accel", "max_yaw_accel"):
            check_positive(f"ugv.{name}", getattr(self, name))
        if self.board is not None and not isinstance(self.board, BoardLayout):
            raise ConfigError("ugv.board", f"must be a BoardLayout or None, got {type(self.board).__name__}")
        T = rigid_transform("ugv.board_mount", self.board_mount)
        object.__setattr__(self, "board_mount", T)
        object.__setattr__(self, "_board_mount_key", _matrix_key(T))
        cameras = tuple(self.cameras)
        for i, camera in enumerate(cameras):
            if not isinstance(camera, CameraMount):
                raise ConfigError(f"ugv.cameras[{i}]", f"must be a CameraMount, got {type(camera).__name__}")
        object.__setattr__(self, "cameras", cameras)
        if not isinstance(self.static, bool):
            raise ConfigError("ugv.static", f"must be a bool, got {self.static!r}")

    @property
    def board_height(self) -> float:
        """Height of the board frame's origin above the floor (m)."""
        return float(self.board_mount[2, 3])

    @property
    def moment(self) -> float:
        """Moment of inertia about the vertical axis (kg m^2), uniform disk."""
        return 0.5 * self.mass * self.radius**2


@dataclass(frozen=True)
class UAVConfig:
    """The observer: a quadcopter with a downward camera, or a hand-held camera.

    The UAV is not a collider; its 2.5D state is (x, y, altitude z, yaw) plus the
    roll and pitch it takes while accelerating (see ``moma_env.world.uav``).

    Attributes:
        name: observer name.
        kind: "quadcopter" or "handheld" (use :meth:`handheld` for its defaults).
        initial: (x, y, yaw) at reset (m, m, rad).
        altitude: altitude z of the body origin at reset (m).
        min_altitude, max_altitude: altitude limits (m); z is clipped to them.
        max_speed: limit on the norm of the horizontal velocity command (m/s).
        max_climb: limit on the climb-rate command (m/s).
        max_yaw_rate: limit on the yaw-rate command (rad/s).
        response_time: time constant of the first-order velocity response (s).
        max_accel: limit on the horizontal and the vertical acceleration (m/s^2).
        tilt_gain: tilt = tilt_gain * atan(acceleration / g).
        tilt_time_constant: low-pass time constant of the tilt (s).
        max_tilt_deg: limit on |roll| and |pitch| (degrees).
        camera_mount: 4x4 T_b_c of the camera (default: looking down, 5 cm below B).
        camera_name: camera name, unique in the world.
    """

    name: str = "uav"
    kind: str = "quadcopter"
    initial: tuple[float, float, float] = (0.0, 0.0, 0.0)
    altitude: float = 1.6
    min_altitude: float = 0.6
    max_altitude: float = 4.0
    max_speed: float = 1.0
    max_climb: float = 0.5
    max_yaw_rate: float = 1.0
    response_time: float = 0.35
    max_accel: float = 2.0
    tilt_gain: float = 1.0
    tilt_time_constant: float = 0.15
    max_tilt_deg: float = 20.0
    camera_mount: np.ndarray = field(default_factory=camera_down, compare=False)
    camera_name: str = "uav/camera"
    _camera_mount_key: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        _check_name("uav.name", self.name)
        check_choice("uav.kind", self.kind, UAV_KINDS)
        object.__setattr__(self, "initial", _planar_pose("uav.initial", self.initial))
        check_positive("uav.min_altitude", self.min_altitude)
        check_positive("uav.max_altitude", self.max_altitude)
        if self.max_altitude <= self.min_altitude:
            raise ConfigError("uav.max_altitude", f"must be > min_altitude={self.min_altitude}, got {self.max_altitude}")
        check_range("uav.altitude", self.altitude, self.min_altitude, self.max_altitude)
        for name in ("max_speed", "max_climb", "max_yaw_rate", "max_accel"):
            check_positive(f"uav.{name}", getattr(self, name))
        check_non_negative("uav.response_time", self.response_time)
        check_non_negative("uav.tilt_gain", self.tilt_gain)
        check_non_negative("uav.tilt_time_constant", self.tilt_time_constant)
        check_finite("uav.max_tilt_deg", self.max_tilt_deg)
        if not 0.0 < self.max_tilt_deg < 90.0:
            raise ConfigError("uav.max_tilt_deg", f"must be in (0, 90), got {self.max_tilt_deg}")
        T = rigid_transform("uav.camera_mount", self.camera_mount)
        object.__setattr__(self, "camera_mount", T)
        object.__setattr__(self, "_camera_mount_key", _matrix_key(T))
        _check_name("uav.camera_name", self.camera_name)

    @classmethod
    def handheld(cls, **overrides: Any) -> UAVConfig:
        """A hand-held camera: response_time 0.8 s, max_accel 0.5 m/s^2, tilt_gain 0.2,
        tilt_time_constant 0.5 s; ``overrides`` replace any field."""
        return cls(**{**_HANDHELD_DEFAULTS, **overrides})

    @property
    def max_tilt(self) -> float:
        """Limit on |roll| and |pitch| (rad)."""
        return math.radians(self.max_tilt_deg)


def _default_sled_board() -> BoardLayout:
    return board_for_robot(1)


@dataclass(frozen=True)
class SledConfig:
    """A sled towed by a ground robot through a rope on a pulley (single-robot caterpillar).

    The sled is a box on the floor with a vertical board on its front. A rope
    joins ``robot_anchor`` on the robot to ``sled_anchor`` on the sled: slack
    below its current length, taut at it. While the sled is *static* (a static
    marker) the world holds it still and the rope pays out freely as the robot
    drives away, up to ``max_rope`` (a leash). While it is *mobile*, the robot
    reels the rope in or lets it out (``World.set_reel``) and a taut rope drags
    the sled, against ground friction.

    Sled frame S: origin at the centre of the footprint, x towards the front
    (where the rope and the board are), y left, z up.

    Attributes:
        name: unique sled name (not "wall" nor "obstacle[...]").
        robot: name of the UGV that tows it (one sled per robot).
        initial_pose: (x, y, yaw) of S in W at reset (m, m, rad).
        size: footprint (length along x_S, width along y_S) (m).
        mass: mass (kg); the moment of inertia is that of a uniform box.
        friction_accel: ground friction as the largest deceleration it gives the
            sled (m/s^2); the friction force is ``mass * friction_accel`` (N).
        board: the ArUco board on the sled's front (default ids 4..7,
            ``markers.board_for_robot(1)``, next to a robot with ids 0..3).
        board_mount: 4x4 T_s_m of the board; None (default) means
            ``board_on_front(height=0.25, offset=size[0]/2)``.
        rope_length: rope length at reset, anchor to anchor (m). If the sled
            starts farther from the robot than that, the world starts with the
            rope taut at the anchors' distance instead (``World.rope_length``).
        min_rope, max_rope: limits of the rope length (m), 0 < min < max.
        reel_speed: rope speed at a reel rate of +-1 (m/s).
        max_tension: largest rope tension (N): how hard the leash holds the
            robot and the winch pulls. The default stops a 20 kg robot at
            0.5 m/s within one 10 ms substep; contacts always win against it.
        robot_anchor: (x, y) of the rope's end in the robot's body frame B (m);
            None (default) means the robot's back, ``(-radius, 0)``, filled in
            by :class:`WorldConfig`.
        sled_anchor: (x, y) of the rope's end in S (m); None (default) means the
            middle of the front edge, ``(size[0]/2, 0)``.
        static: whether the sled starts static (held still by the world).
    """

    name: str = "sled"
    robot: str = ""
    initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    size: tuple[float, float] = (0.30, 0.30)
    mass: float = 3.0
    friction_accel: float = 2.0
    board: BoardLayout = field(default_factory=_default_sled_board)
    board_mount: np.ndarray | None = field(default=None, compare=False)
    rope_length: float = 0.6
    min_rope: float = 0.35
    max_rope: float = 1.5
    reel_speed: float = 0.15
    max_tension: float = 2000.0
    robot_anchor: tuple[float, float] | None = None
    sled_anchor: tuple[float, float] | None = None
    static: bool = True
    _board_mount_key: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        _check_name("sled.name", self.name)
        if _reserved(self.name):
            raise ConfigError("sled.name", f"{self.name!r} is reserved for static shapes")
        _check_name("sled.robot", self.robot)
        object.__setattr__(self, "initial_pose", _planar_pose("sled.initial_pose", self.initial_pose))
        size = _planar_point("sled.size", self.size)
        check_positive("sled.size.x", size[0])
        check_positive("sled.size.y", size[1])
        object.__setattr__(self, "size", size)
        check_positive("sled.mass", self.mass)
        check_non_negative("sled.friction_accel", self.friction_accel)
        if not isinstance(self.board, BoardLayout):
            raise ConfigError("sled.board", f"must be a BoardLayout, got {type(self.board).__name__}")
        mount = board_on_front(0.25, size[0] / 2.0) if self.board_mount is None else self.board_mount
        T = rigid_transform("sled.board_mount", mount)
        object.__setattr__(self, "board_mount", T)
        object.__setattr__(self, "_board_mount_key", _matrix_key(T))
        check_positive("sled.min_rope", self.min_rope)
        check_positive("sled.max_rope", self.max_rope)
        if self.max_rope <= self.min_rope:
            raise ConfigError("sled.max_rope", f"must be > min_rope={self.min_rope}, got {self.max_rope}")
        check_range("sled.rope_length", self.rope_length, self.min_rope, self.max_rope)
        check_positive("sled.reel_speed", self.reel_speed)
        check_positive("sled.max_tension", self.max_tension)
        if self.robot_anchor is not None:
            object.__setattr__(self, "robot_anchor", _planar_point("sled.robot_anchor", self.robot_anchor))
        anchor = (size[0] / 2.0, 0.0) if self.sled_anchor is None else self.sled_anchor
        object.__setattr__(self, "sled_anchor", _planar_point("sled.sled_anchor", anchor))
        if not isinstance(self.static, bool):
            raise ConfigError("sled.static", f"must be a bool, got {self.static!r}")

    @property
    def board_height(self) -> float:
        """Height of the board frame's origin above the floor (m)."""
        return float(self.board_mount[2, 3])

    @property
    def moment(self) -> float:
        """Moment of inertia about the vertical axis (kg m^2), uniform box."""
        length, width = self.size
        return self.mass * (length**2 + width**2) / 12.0

    def footprint(self, pose: Sequence[float] | None = None) -> BoxObstacle:
        """The sled's footprint at planar ``pose`` (default: its initial pose), as a box."""
        x, y, yaw = self.initial_pose if pose is None else pose
        return BoxObstacle(float(x), float(y), self.size[0], self.size[1], float(yaw))

    def anchor_distance(self, robot_pose: Sequence[float], sled_pose: Sequence[float] | None = None) -> float:
        """Distance (m) between the rope's anchors with the robot and the sled at planar poses.

        ``sled_pose`` defaults to the initial pose. Needs a resolved
        ``robot_anchor`` (every sled of a :class:`WorldConfig` has one).
        """
        if self.robot_anchor is None:
            raise ValueError(f"sled {self.name!r} has no robot_anchor yet; WorldConfig resolves it")
        rx, ry, ryaw = robot_pose
        sx, sy, syaw = self.initial_pose if sled_pose is None else sled_pose
        (ax, ay), (bx, by) = self.robot_anchor, self.sled_anchor
        c, s = math.cos(ryaw), math.sin(ryaw)
        px, py = rx + c * ax - s * ay, ry + s * ax + c * ay
        c, s = math.cos(syaw), math.sin(syaw)
        qx, qy = sx + c * bx - s * by, sy + s * bx + c * by
        return math.hypot(qx - px, qy - py)


@dataclass(frozen=True)
class WorldConfig:
    """The whole world: arena, ground robots, sleds, the observers (UAVs), and the step rate.

    Attributes:
        arena: walls and obstacles.
        ugvs: ground robots, in the order the world reports them.
        uavs: the flying (or hand-held) observers, none, one or several; each
            flies on its own and carries its own camera (:attr:`uav` is the only
            one of a world with at most one).
        control_hz: control steps per second (Hz); one ``World.step`` is 1/control_hz s.
        substeps: physics substeps per control step.
        sleds: sleds towed by the robots (at most one per robot). Stored with
            their ``robot_anchor`` resolved (None becomes the robot's back).

    Checked here: robot, sled and UAV names are unique (a sled's name is not a
    camera's name either) and camera names are unique; every sled's robot
    exists; no two boards share a marker id of the same dictionary; every robot
    and sled starts inside the arena, clear of the obstacles and of every other
    robot and sled (touching is allowed); every sled starts within ``max_rope``
    of its robot's anchor.
    """

    arena: ArenaConfig = field(default_factory=ArenaConfig)
    ugvs: tuple[UGVConfig, ...] = ()
    uavs: tuple[UAVConfig, ...] = ()
    control_hz: float = 25.0
    substeps: int = 4
    sleds: tuple[SledConfig, ...] = ()
    _ugv_index: dict[str, int] = field(init=False, repr=False, compare=False)
    _sled_index: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.arena, ArenaConfig):
            raise ConfigError("arena", f"must be an ArenaConfig, got {type(self.arena).__name__}")
        ugvs = _tuple_of("ugvs", self.ugvs, UGVConfig)
        object.__setattr__(self, "ugvs", ugvs)
        object.__setattr__(self, "uavs", _tuple_of("uavs", self.uavs, UAVConfig))
        check_positive("control_hz", self.control_hz)
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, int) or self.substeps < 1:
            raise ConfigError("substeps", f"must be an int >= 1, got {self.substeps!r}")
        object.__setattr__(self, "_ugv_index", {ugv.name: i for i, ugv in enumerate(ugvs)})
        self._resolve_sleds()
        self._check_names()
        self._check_marker_ids()
        self._check_placement()
        self._check_sled_placement()
        object.__setattr__(self, "_sled_index", {sled.name: k for k, sled in enumerate(self.sleds)})

    def _resolve_sleds(self) -> None:
        """Type-check the sleds, check their robots, and fill in default robot anchors."""
        try:
            sleds = tuple(self.sleds)
        except TypeError:
            raise ConfigError("sleds", f"must be a sequence of SledConfig, got {type(self.sleds).__name__}") from None
        towed_by: dict[str, int] = {}
        resolved = []
        for k, sled in enumerate(sleds):
            if not isinstance(sled, SledConfig):
                raise ConfigError(f"sleds[{k}]", f"must be a SledConfig, got {type(sled).__name__}")
            if sled.robot not in self._ugv_index:
                raise ConfigError(
                    f"sleds[{k}].robot", f"unknown robot {sled.robot!r}; known robots are {list(self.ugv_names)}"
                )
            if sled.robot in towed_by:
                raise ConfigError(
                    f"sleds[{k}].robot", f"robot {sled.robot!r} already tows sleds[{towed_by[sled.robot]}]"
                )
            towed_by[sled.robot] = k
            if sled.robot_anchor is None:
                radius = self.ugvs[self._ugv_index[sled.robot]].radius
                sled = dataclasses.replace(sled, robot_anchor=(-radius, 0.0))
            resolved.append(sled)
        object.__setattr__(self, "sleds", tuple(resolved))

    def _check_names(self) -> None:
        owner: dict[str, str] = {}
        for i, ugv in enumerate(self.ugvs):
            if ugv.name in owner:
                raise ConfigError(f"ugvs[{i}].name", f"duplicate name {ugv.name!r} (also {owner[ugv.name]})")
            owner[ugv.name] = f"ugvs[{i}]"
        for k, sled in enumerate(self.sleds):
            if sled.name in owner:
                raise ConfigError(f"sleds[{k}].name", f"duplicate name {sled.name!r} (also {owner[sled.name]})")
            owner[sled.name] = f"sleds[{k}]"
        for k, uav in enumerate(self.uavs):
            if uav.name in owner:
                raise ConfigError(f"uavs[{k}].name", f"duplicate name {uav.name!r} (also {owner[uav.name]})")
            owner[uav.name] = f"uavs[{k}]"
        camera_owner: dict[str, str] = {}
        for i, ugv in enumerate(self.ugvs):
            for j, camera in enumerate(ugv.cameras):
                path = f"ugvs[{i}].cameras[{j}]"
                if camera.name in camera_owner:
                    raise ConfigError(
                        f"{path}.name", f"duplicate camera name {camera.name!r} (also {camera_owner[camera.name]})"
                    )
                camera_owner[camera.name] = path
        for k, uav in enumerate(self.uavs):
            name = uav.camera_name
            if name in camera_owner:
                raise ConfigError(f"uavs[{k}].camera_name", f"duplicate camera name {name!r} (also {camera_owner[name]})")
            camera_owner[name] = f"uavs[{k}].camera_name"
        for k, sled in enumerate(self.sleds):
            if sled.name in camera_owner:
                raise ConfigError(
                    f"sleds[{k}].name", f"{sled.name!r} is also the name of a camera ({camera_owner[sled.name]})"
                )

    def _check_marker_ids(self) -> None:
        boards = [(f"ugvs[{i}]", ugv.name, ugv.board) for i, ugv in enumerate(self.ugvs) if ugv.board is not None]
        boards += [(f"sleds[{k}]", sled.name, sled.board) for k, sled in enumerate(self.sleds)]
        owner: dict[tuple[str, int], tuple[str, str]] = {}
        for path, name, board in boards:
            for marker_id in board.marker_ids:
                key = (board.dictionary, marker_id)
                if key in owner:
                    other_path, other_name = owner[key]
                    raise ConfigError(
                        f"{path}.board.marker_ids",
                        f"marker id {marker_id} ({board.dictionary}) is also on {other_path} ({other_name!r}); "
                        "give each board its own ids, e.g. markers.board_for_robot(i) for the i-th board",
                    )
                owner[key] = (path, name)

    def _check_placement(self) -> None:
        bounds = self.arena.bounds
        for i, ugv in enumerate(self.ugvs):
            x, y, _ = ugv.initial_pose
            field_name = f"ugvs[{i}].initial_pose"
            if not disk_inside_rectangle(x, y, ugv.radius, bounds):
                raise ConfigError(
                    field_name, f"robot {ugv.name!r} (radius {ugv.radius}) at ({x}, {y}) is not inside the arena {bounds}"
                )
            for k, obstacle in enumerate(self.arena.obstacles):
                if disk_overlaps_box(x, y, ugv.radius, obstacle):
                    raise ConfigError(field_name, f"robot {ugv.name!r} at ({x}, {y}) overlaps arena.obstacles[{k}]")
            for j in range(i):
                other = self.ugvs[j]
                gap = math.hypot(x - other.initial_pose[0], y - other.initial_pose[1]) - ugv.radius - other.radius
                if gap < -1e-9:
                    raise ConfigError(
                        field_name, f"robot {ugv.name!r} overlaps ugvs[{j}] ({other.name!r}) by {-gap:.4g} m"
                    )

    def _check_sled_placement(self) -> None:
        bounds = self.arena.bounds
        footprints = [sled.footprint() for sled in self.sleds]
        for k, (sled, box) in enumerate(zip(self.sleds, footprints)):
            field_name = f"sleds[{k}].initial_pose"
            where = f"sled {sled.name!r} (size {sled.size}) at {sled.initial_pose}"
            if not box_inside_rectangle(box, bounds):
                raise ConfigError(field_name, f"{where} is not inside the arena {bounds}")
            for j, obstacle in enumerate(self.arena.obstacles):
                if boxes_overlap(box, obstacle):
                    raise ConfigError(field_name, f"{where} overlaps arena.obstacles[{j}]")
            for i, ugv in enumerate(self.ugvs):
                x, y, _ = ugv.initial_pose
                if disk_overlaps_box(x, y, ugv.radius, box):
                    raise ConfigError(field_name, f"{where} overlaps ugvs[{i}] ({ugv.name!r})")
            for j in range(k):
                if boxes_overlap(box, footprints[j]):
                    raise ConfigError(field_name, f"{where} overlaps sleds[{j}] ({self.sleds[j].name!r})")
            distance = sled.anchor_distance(self.ugv(sled.robot).initial_pose)
            if distance > sled.max_rope + 1e-9:
                raise ConfigError(
                    field_name,
                    f"{where} starts {distance:.4g} m from its robot's anchor, beyond max_rope={sled.max_rope}",
                )

    @property
    def dt(self) -> float:
        """Duration of one control step (s)."""
        return 1.0 / self.control_hz

    @property
    def uav(self) -> UAVConfig | None:
        """The observer of a world with at most one (None without): ValueError naming
        ``uavs`` in a world of several, whose readers must take :attr:`uavs`."""
        if len(self.uavs) > 1:
            names = ", ".join(u.name for u in self.uavs)
            raise ValueError(f"uavs: this world has {len(self.uavs)} observers ({names}); read WorldConfig.uavs")
        return self.uavs[0] if self.uavs else None

    @property
    def uav_names(self) -> tuple[str, ...]:
        """The observers' names, in configuration order."""
        return tuple(u.name for u in self.uavs)

    @property
    def ugv_names(self) -> tuple[str, ...]:
        """Names of the ground robots, in order."""
        return tuple(ugv.name for ugv in self.ugvs)

    def ugv_index(self, name: str) -> int:
        """Index of the robot called ``name``; KeyError listing known names otherwise."""
        try:
            return self._ugv_index[name]
        except (KeyError, TypeError):
            raise unknown_name("ugv", name, self.ugv_names) from None

    def ugv(self, name: str) -> UGVConfig:
        """Configuration of the robot called ``name``; KeyError listing known names otherwise."""
        return self.ugvs[self.ugv_index(name)]

    @property
    def sled_names(self) -> tuple[str, ...]:
        """Names of the sleds, in order."""
        return tuple(sled.name for sled in self.sleds)

    def sled(self, name: str) -> SledConfig:
        """Configuration of the sled called ``name``; KeyError listing known names otherwise."""
        try:
            return self.sleds[self._sled_index[name]]
        except (KeyError, TypeError):
            raise unknown_name("sled", name, self.sled_names) from None


# -- building from plain mappings -------------------------------------------------------


def _rebased(error: ConfigError, own_prefix: str, path: str) -> ConfigError:
    """Re-raise-able copy of ``error`` with its field placed under ``path``."""
    message = str(error)[len(error.field) + 2 :]
    name = error.field
    if name == own_prefix or name.startswith(own_prefix + "."):
        name = path + name[len(own_prefix) :]
    else:
        name = f"{path}.{name}"
    return ConfigError(name, message)


def _tuple_of(field_name: str, values: object, cls: type) -> tuple:
    """``values`` (a tuple or list of ``cls``) as a tuple; ConfigError naming the field or the bad entry."""
    if not isinstance(values, (tuple, list)):
        raise ConfigError(field_name, f"must be a sequence of {cls.__name__}, got {type(values).__name__}")
    for k, value in enumerate(values):
        if not isinstance(value, cls):
            raise ConfigError(f"{field_name}[{k}]", f"must be a {cls.__name__}, got {type(value).__name__}")
    return tuple(values)


def _build(cls: type, mapping: object, own_prefix: str, path: str) -> Any:
    if isinstance(mapping, cls):
        return mapping
    if not isinstance(mapping, Mapping):
        raise ConfigError(path, f"expected a mapping, got {type(mapping).__name__}")
    try:
        return from_mapping(cls, mapping)
    except ConfigError as error:
        raise _rebased(error, own_prefix, path) from None


def _build_list(value: object, path: str) -> list[object]:
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence):
        raise ConfigError(path, f"expected a list, got {type(value).__name__}")
    return list(value)


def world_config_from_mapping(mapping: Mapping[str, Any]) -> WorldConfig:
    """Build a :class:`WorldConfig` from nested plain mappings and lists.

    ``arena.obstacles`` and ``ugvs`` are lists of mappings, ``ugvs[i].cameras`` a
    list of ``{name, T_b_c}``, ``ugvs[i].board`` a BoardLayout mapping or None,
    ``uav`` a mapping or None (one observer; ``kind: handheld`` starts from the
    hand-held defaults) or ``uavs`` a list of such mappings, ``sleds`` a list of mappings (``board`` a BoardLayout mapping).
    Errors name the full path, e.g. ``ugvs[1].radius``.
    """
    if not isinstance(mapping, Mapping):
        raise ConfigError("world", f"expected a mapping, got {type(mapping).__name__}")
    known = {f.name for f in dataclasses.fields(WorldConfig) if f.init} | {"uav"}
    unknown = sorted(set(mapping) - known)
    if unknown:
        raise ConfigError(unknown[0], f"unknown field; known fields are {sorted(known)}")
    kwargs: dict[str, Any] = dict(mapping)
    if "arena" in kwargs:
        arena = kwargs["arena"]
        if isinstance(arena, Mapping) and "obstacles" in arena:
            obstacles = [
                _build(BoxObstacle, item, "obstacle", f"arena.obstacles[{k}]")
                for k, item in enumerate(_build_list(arena["obstacles"], "arena.obstacles"))
            ]
            arena = {**arena, "obstacles": tuple(obstacles)}
        kwargs["arena"] = _build(ArenaConfig, arena, "arena", "arena")
    if "ugvs" in kwargs:
        ugvs = []
        for i, item in enumerate(_build_list(kwargs["ugvs"], "ugvs")):
            path = f"ugvs[{i}]"
            if isinstance(item, Mapping):
                item = dict(item)
                if isinstance(item.get("board"), Mapping):
                    item["board"] = _build(BoardLayout, item["board"], "board", f"{path}.board")
                if "cameras" in item:
                    item["cameras"] = tuple(
                        _build(CameraMount, camera, "camera", f"{path}.cameras[{j}]")
                        for j, camera in enumerate(_build_list(item["cameras"], f"{path}.cameras"))
                    )
            ugvs.append(_build(UGVConfig, item, "ugv", path))
        kwargs["ugvs"] = tuple(ugvs)
    if "sleds" in kwargs:
        sleds = []
        for k, item in enumerate(_build_list(kwargs["sleds"], "sleds")):
            path = f"sleds[{k}]"
            if isinstance(item, Mapping) and isinstance(item.get("board"), Mapping):
                item = {**item, "board": _build(BoardLayout, item["board"], "board", f"{path}.board")}
            sleds.append(_build(SledConfig, item, "sled", path))
        kwargs["sleds"] = tuple(sleds)
    if "uav" in kwargs:
        if "uavs" in kwargs:
            raise ConfigError("uav", "give either uav (one observer) or uavs (a list), not both")
        uav = kwargs.pop("uav")
        kwargs["uavs"] = () if uav is None else (_uav_from(uav, "uav"),)
    elif "uavs" in kwargs:
        kwargs["uavs"] = tuple(_uav_from(item, f"uavs[{k}]") for k, item in enumerate(_build_list(kwargs["uavs"], "uavs")))
    return WorldConfig(**kwargs)


def _uav_from(item: object, path: str) -> UAVConfig:
    """A UAV's mapping built into a :class:`UAVConfig` (``kind: handheld`` starts from its defaults)."""
    if isinstance(item, Mapping) and item.get("kind") == "handheld":
        item = {**_HANDHELD_DEFAULTS, **item}
    return _build(UAVConfig, item, "uav", path)
