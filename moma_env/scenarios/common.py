"""What every configuration shares: surroundings, camera, estimator, episode settings.

A configuration is a frozen, keyword-only dataclass deriving from
:class:`ScenarioConfig`. It adds its own fields (number of robots, distances,
observer, ...), checks them in ``_check_fields`` and lays out its robots and
goals in ``_make_layout``; the base class then checks everything that depends
on the layout (the arena holds every start and goal, no obstacle covers one),
builds the :class:`~moma_env.world.WorldConfig` and the
:class:`~moma_env.scenarios.base.Scenario`. Construction fails with a
:class:`~moma_env.config.ConfigError` naming the field
(``"caterpillar.standoff"``, ``"top_observer.obstacles[2]"``); a configuration
that constructs always gives a valid scenario.

Units: metres, seconds, radians; poses ``(x, y, yaw)`` in the world frame W.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from moma_env.camera import CameraConfig
from moma_env.config import ConfigError, check_count, check_finite, check_numbers, check_non_negative, check_positive, from_mapping
from moma_env.estimator import EstimatorConfig
from moma_env.markers import ARUCO_DICTIONARIES, MARKERS_PER_BOARD, MAX_TEAM_BOARDS, TEAM_DICTIONARIES
from moma_env.scenarios.base import Scenario
from moma_env.scenarios.layout import Disk, Pose2D, convex_hull
from moma_env.world import ArenaConfig, BoxObstacle, SledConfig, UAVConfig, UGVConfig, WorldConfig
from moma_env.world.arena import disk_inside_rectangle, disk_overlaps_box

__all__ = [
    "ARENA_MARGIN_M",
    "MIN_ARENA_SIDE_M",
    "WALL_CLEARANCE_M",
    "Layout",
    "ScenarioConfig",
    "ugv_name",
    "camera_name",
    "default_ugv_radius",
    "field_default",
    "planar_pose",
    "check_team_boards",
]

#: Margin (m) between the start/goal footprints and the walls of a fitted arena (``arena=None``).
ARENA_MARGIN_M = 1.0
#: Smallest side (m) of a fitted arena.
MIN_ARENA_SIDE_M = 4.0
#: Smallest gap (m) allowed between a start or goal footprint and a wall.
WALL_CLEARANCE_M = 0.1
#: Episode time (s) granted on top of the turns when ``max_cycles`` is derived.
START_BUDGET_S = 10.0
#: Factor on the turns' nominal time when ``max_cycles`` is derived.
TIME_SLACK = 1.5


def ugv_name(index: int) -> str:
    """Name of ground robot ``index``: ``"ugv_<index>"``."""
    return f"ugv_{index}"


def camera_name(owner: str) -> str:
    """Name of the camera carried by ``owner``: ``"<owner>/camera"``."""
    return f"{owner}/camera"


def field_default(cls: type, name: str) -> Any:
    """Default value of field ``name`` of the dataclass ``cls`` (one with a plain default)."""
    return cls.__dataclass_fields__[name].default  # type: ignore[attr-defined]


def default_ugv_radius() -> float:
    """Footprint radius (m) of a UGV with the world's defaults (Festo Robotino)."""
    return float(field_default(UGVConfig, "radius"))


def planar_pose(field_name: str, value: object) -> Pose2D:
    """``value`` as a float ``(x, y, yaw)``; ConfigError naming ``field_name`` otherwise."""
    return check_numbers(field_name, value, ("x", "y", "yaw"))  # type: ignore[return-value]


def check_team_boards(field_name: str, n_ugvs: int, n_boards: int) -> None:
    """ConfigError naming ``field_name`` (the robot count) if a team of ``n_ugvs`` robots
    carrying ``n_boards`` boards of ``markers.board_for_robot`` needs more distinct
    marker ids than the largest team dictionary holds (``markers.MAX_TEAM_BOARDS`` boards)."""
    if n_boards > MAX_TEAM_BOARDS:
        largest = TEAM_DICTIONARIES[-1]
        raise ConfigError(
            field_name,
            f"must be at most {MAX_TEAM_BOARDS + n_ugvs - n_boards}: the team's {n_boards} boards need "
            f"{MARKERS_PER_BOARD * n_boards} distinct ArUco ids ({MARKERS_PER_BOARD} a board) and the largest "
            f"dictionary, {largest}, holds {ARUCO_DICTIONARIES[largest]}; got {n_ugvs}",
        )


@dataclass(frozen=True)
class Layout:
    """A configuration's devices at the start and their goals.

    Attributes:
        ugvs: ground robots, with their boards and cameras, at their start poses.
        goals: UGV name -> goal ``(x, y, yaw)``.
        disks: floor disks the devices cover at the start and at their goals
            (a sled: its circumscribed disk), labelled (``"ugv_0 start"``,
            ``"ugv_0 goal"``); the arena must hold them and no obstacle may cover them.
        movers: devices that take turns to move (for the derived ``max_cycles``).
        path_m: distance each mover travels to its goal (m).
        speed: speed of the slowest mover (m/s), for the derived ``max_cycles``;
            None means the slowest UGV's ``max_speed``.
        uavs: the observers (none, one or several).
        sleds: the towed sleds.
        routes: UGV name -> via poses it passes on its way to its goal
            (``Scenario.routes``); their footprints belong in ``disks``.
        obstacles: boxes the layout itself needs (a wall the team must go
            around), in addition to the configuration's ``obstacles``.
    """

    ugvs: tuple[UGVConfig, ...]
    goals: Mapping[str, Pose2D]
    disks: tuple[Disk, ...]
    movers: int
    path_m: float
    speed: float | None = None
    uavs: tuple[UAVConfig, ...] = ()
    sleds: tuple[SledConfig, ...] = ()
    routes: Mapping[str, tuple[Pose2D, ...]] = field(default_factory=dict)
    obstacles: tuple[BoxObstacle, ...] = ()


@dataclass(frozen=True, kw_only=True)
class ScenarioConfig(ABC):
    """Fields and checks shared by every configuration (keyword-only, abstract).

    Attributes:
        arena: interior ``(width, height)`` of the walled arena (m). None fits it
            to the start and goal footprints with ``ARENA_MARGIN_M`` on each side
            (at least ``MIN_ARENA_SIDE_M`` a side).
        arena_origin: world xy (m) of the arena's lower-left interior corner; None
            centres the arena on the start and goal footprints.
        obstacles: box obstacles (``BoxObstacle`` or mappings of its fields); none
            may cover a start or a goal.
        camera: intrinsics, distortion and noise of every camera.
        estimator: MOMA estimator settings.
        leg_length: longest advance of one turn in ``switching`` mode (m).
        dwell_s: motion rule 3's dwell time at every switch (s).
        goal_tolerance_m, goal_tolerance_rad: a goal is reached within these.
        max_cycles: episode length in control steps; None derives it from the
            turns the devices need: ``movers * ceil(path / leg_length)`` turns of
            ``2 * leg_length / speed + dwell_s + window / control_hz +
            settle_delay_s`` seconds each, times ``TIME_SLACK``, plus
            ``START_BUDGET_S``.
    """

    #: Configuration name (the scenario's name and the prefix of error fields).
    NAME: ClassVar[str] = "scenario"
    #: Fields that fix the team (the env's agents) or its task -> inclusive range
    #: ``(low, high)`` of the values ``random`` can keep them at (``random(rng,
    #: n_ugvs=5)``); integer bounds make an integer field, float bounds a real one.
    #: Random layouts of an env (``random_scenarios=True``) keep its configuration's
    #: values. Empty: the team is always the same.
    TEAM_FIELDS: ClassVar[Mapping[str, tuple[float, float]]] = MappingProxyType({})
    #: The rig's settings: fields that :meth:`random` never draws (it leaves them at
    #: their defaults). Random layouts of an env (``random_scenarios=True``) keep the
    #: values its configuration was given, so ``leg_length=1.5`` or an ``estimator``
    #: applies to every layout, not only the first.
    SETTING_FIELDS: ClassVar[tuple[str, ...]] = (
        "estimator",
        "leg_length",
        "dwell_s",
        "goal_tolerance_m",
        "goal_tolerance_rad",
        "max_cycles",
    )

    arena: tuple[float, float] | None = None
    arena_origin: tuple[float, float] | None = None
    obstacles: tuple[BoxObstacle, ...] = ()
    camera: CameraConfig = field(default_factory=CameraConfig)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    leg_length: float = 0.5
    dwell_s: float = 1.0
    goal_tolerance_m: float = 0.05
    goal_tolerance_rad: float = 0.1
    max_cycles: int | None = None

    # -- to implement -------------------------------------------------------------------

    @abstractmethod
    def _check_fields(self) -> None:
        """Check (and normalise, with ``object.__setattr__``) the subclass's own fields."""

    @abstractmethod
    def _make_layout(self) -> Layout:
        """Robots at their start poses, goals and footprints (fields already checked); called
        once, by the constructor, and kept as :attr:`layout` for every other reader."""

    @abstractmethod
    def required_views(self) -> Mapping[str, tuple[str, ...]]:
        """Camera name -> owners (robot or sled names) of the boards it must see whole at the start."""

    @classmethod
    @abstractmethod
    def random(cls, rng: np.random.Generator, **team: int) -> ScenarioConfig:
        """A random valid configuration; every draw comes from ``rng``.

        ``team`` keeps fields of :attr:`TEAM_FIELDS` at the given values (checked
        by :meth:`check_team`: ConfigError naming the field otherwise).
        """

    @classmethod
    def check_team(cls, team: Mapping[str, Any]) -> dict[str, int | float]:
        """``team`` as ints (floats for a real field) if :meth:`random` can keep every value;
        else ConfigError naming the field (``"top_observer.n_ugvs"``) and the range of
        :attr:`TEAM_FIELDS` it allows."""
        checked: dict[str, int | float] = {}
        for name, value in team.items():
            field_name = f"{cls.NAME}.{name}"
            if name not in cls.TEAM_FIELDS:
                kept = sorted(cls.TEAM_FIELDS) or "none"
                raise ConfigError(field_name, f"random layouts cannot keep this field; the fields they keep: {kept}")
            low, high = cls.TEAM_FIELDS[name]
            if isinstance(low, int):
                check_count(field_name, value, minimum=low)
            else:
                check_finite(field_name, value)
            if not low <= value <= high:
                raise ConfigError(
                    field_name, f"must be in [{low}, {high}] for random layouts (random_scenarios=True), got {value!r}"
                )
            checked[name] = int(value) if isinstance(low, int) else float(value)
        return checked

    # -- construction -------------------------------------------------------------------

    def _field(self, name: str) -> str:
        return f"{self.NAME}.{name}"

    def __post_init__(self) -> None:
        self._check_fields()
        self._check_common_fields()
        # Laid out and built once (both are functions of the fields alone): the layout serves
        # occupied_disks and required_views, the checked scenario the first scenario() call.
        # Private attributes, not fields: equality, hashing, repr and replace() ignore them.
        layout = self._make_layout()
        object.__setattr__(self, "_layout", layout)
        object.__setattr__(self, "_unclaimed", self._build(layout))

    def __getstate__(self) -> dict[str, Any]:
        # A copy or a pickle builds its own first scenario: the constructor's is handed out once.
        state = dict(self.__dict__)
        state["_unclaimed"] = None
        return state

    def _check_common_fields(self) -> None:
        if self.arena is not None:
            object.__setattr__(self, "arena", check_numbers(self._field("arena"), self.arena, ("width", "height"), positive=True))
        if self.arena_origin is not None:
            origin = check_numbers(self._field("arena_origin"), self.arena_origin, ("x", "y"))
            object.__setattr__(self, "arena_origin", origin)
        object.__setattr__(self, "obstacles", self._checked_obstacles())
        if not isinstance(self.camera, CameraConfig):
            raise ConfigError(self._field("camera"), f"must be a CameraConfig, got {type(self.camera).__name__}")
        if not isinstance(self.estimator, EstimatorConfig):
            raise ConfigError(
                self._field("estimator"), f"must be an EstimatorConfig, got {type(self.estimator).__name__}"
            )
        check_positive(self._field("leg_length"), self.leg_length)
        check_non_negative(self._field("dwell_s"), self.dwell_s)
        check_positive(self._field("goal_tolerance_m"), self.goal_tolerance_m)
        check_positive(self._field("goal_tolerance_rad"), self.goal_tolerance_rad)
        if self.max_cycles is not None:
            check_count(self._field("max_cycles"), self.max_cycles)

    def _checked_obstacles(self) -> tuple[BoxObstacle, ...]:
        if isinstance(self.obstacles, (str, bytes, Mapping)) or not isinstance(self.obstacles, Sequence):
            raise ConfigError(self._field("obstacles"), f"must be a sequence of boxes, got {self.obstacles!r}")
        obstacles = []
        for k, item in enumerate(self.obstacles):
            path = self._field(f"obstacles[{k}]")
            if isinstance(item, Mapping):
                try:
                    item = from_mapping(BoxObstacle, item)
                except ConfigError as error:
                    raise ConfigError(path, str(error)) from None
            if not isinstance(item, BoxObstacle):
                raise ConfigError(path, f"must be a BoxObstacle or a mapping of its fields, got {type(item).__name__}")
            obstacles.append(item)
        return tuple(obstacles)

    def _build(self, layout: Layout) -> Scenario:
        """The scenario of ``layout`` (this configuration's, from :meth:`_make_layout`), after
        the checks that depend on it."""
        arena = self._arena_config(layout.disks, self.obstacles + layout.obstacles)
        for k, obstacle in enumerate(self.obstacles):
            for label, x, y, radius in layout.disks:
                if disk_overlaps_box(x, y, radius, obstacle):
                    raise ConfigError(self._field(f"obstacles[{k}]"), f"covers the {label} at ({x:.3f}, {y:.3f})")
        for obstacle in layout.obstacles:
            for label, x, y, radius in layout.disks:
                if disk_overlaps_box(x, y, radius, obstacle):
                    raise ConfigError(self._field("layout"), f"its obstacle {obstacle} covers the {label} at ({x:.3f}, {y:.3f})")
        try:
            world = WorldConfig(arena=arena, ugvs=layout.ugvs, uavs=layout.uavs, sleds=layout.sleds)
        except ConfigError as error:
            message = str(error)[len(error.field) + 2 :]
            raise ConfigError(self._field(f"world.{error.field}"), message) from None
        return Scenario(
            name=self.NAME,
            world=world,
            camera=self.camera,
            goals=layout.goals,
            estimator=self.estimator,
            leg_length=self.leg_length,
            dwell_s=self.dwell_s,
            goal_tolerance_m=self.goal_tolerance_m,
            goal_tolerance_rad=self.goal_tolerance_rad,
            max_cycles=self._resolved_max_cycles(layout, world.control_hz),
            routes=layout.routes,
        )

    def _arena_config(self, disks: Sequence[Disk], obstacles: tuple[BoxObstacle, ...]) -> ArenaConfig:
        centres = np.array([(x, y) for _, x, y, _ in disks])
        radii = np.array([[r] for *_, r in disks])
        lo = (centres - radii).min(axis=0)
        hi = (centres + radii).max(axis=0)
        if self.arena is None:
            size = np.maximum(hi - lo + 2.0 * ARENA_MARGIN_M, MIN_ARENA_SIDE_M)
        else:
            size = np.array(self.arena)
        origin = 0.5 * (lo + hi) - 0.5 * size if self.arena_origin is None else np.array(self.arena_origin)
        arena = ArenaConfig(
            width=float(size[0]),
            height=float(size[1]),
            origin=(float(origin[0]), float(origin[1])),
            obstacles=obstacles,
        )
        for label, x, y, radius in disks:
            if not disk_inside_rectangle(x, y, radius + WALL_CLEARANCE_M, arena.bounds):
                raise ConfigError(
                    self._field("arena"),
                    f"the {label} at ({x:.3f}, {y:.3f}) is not inside the arena {arena.bounds} with "
                    f"{WALL_CLEARANCE_M} m to the walls; enlarge or move the arena (arena=None fits it)",
                )
        return arena

    def _resolved_max_cycles(self, layout: Layout, control_hz: float) -> int:
        if self.max_cycles is not None:
            return int(self.max_cycles)
        speed = min(ugv.max_speed for ugv in layout.ugvs) if layout.speed is None else layout.speed
        turns = layout.movers * max(1, math.ceil(layout.path_m / self.leg_length - 1e-9))
        turn_s = (
            2.0 * self.leg_length / speed
            + self.dwell_s
            + self.estimator.window / control_hz
            + self.estimator.settle_delay_s
        )
        return math.ceil((START_BUDGET_S + TIME_SLACK * turns * turn_s) * control_hz)

    # -- public -------------------------------------------------------------------------

    def scenario(self) -> Scenario:
        """The episode layout (a new :class:`Scenario` at every call; building it draws nothing random)."""
        built = self.__dict__.get("_unclaimed")
        if built is None:
            return self._build(self.layout)
        object.__setattr__(self, "_unclaimed", None)  # the one built by the constructor, handed out once
        return built

    @property
    def layout(self) -> Layout:
        """The devices at the start, their goals and footprints (:class:`Layout`, made once)."""
        layout = self.__dict__.get("_layout")
        if layout is None:  # a configuration unpickled from a version that did not keep it
            layout = self._make_layout()
            object.__setattr__(self, "_layout", layout)
        return layout

    @property
    def occupied_disks(self) -> tuple[Disk, ...]:
        """Labelled floor disks ``(label, x, y, radius)`` the devices cover at the start and at their goals (m)."""
        return self.layout.disks

    def corridor(self) -> np.ndarray:
        """Convex hull (k, 2) of the centres of :attr:`occupied_disks`, counter-clockwise (m).

        The devices travel inside it (inflated by their radius) on their straight
        way to the goals.
        """
        return convex_hull([(x, y) for _, x, y, _ in self.occupied_disks])
