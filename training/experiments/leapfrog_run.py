"""Shared core of the paper's two-robot experiments (the square and the line).

Section IV of the paper: a main robot drives a list of waypoints (x, y, theta) in
legs; a second robot keeps it company ``separation`` metres to its left; the two
move in turns with a dwell at every switch, and an observer above them (a UAV or a
hand-held camera) tracks both boards with its controller from the detections
alone. Every robot is driven on its MOMA estimate; the truth is only recorded.
The main robot's MOMA trajectory is compared with the truth and with the odometry
baselines (wheel odometry always; visual odometry when the camera is rendered).

An experiment subclasses :class:`LeapfrogConfig` and says where the main robot
goes (:meth:`LeapfrogConfig.waypoints`, :meth:`LeapfrogConfig.start_pose`,
:attr:`LeapfrogConfig.path_length`); :func:`run_leapfrog` runs one seeded run of
any of them and :func:`summarise` the statistics over runs.

Frames and units: world W (x, y on the floor, z up), metres, radians, seconds;
poses ``T_w_b`` of the robots' body frames (see :mod:`moma_env.geometry`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from agents.leapfrog import LeapfrogSchedule, Leg
from moma_env.camera import (
    CAMERA_BACKENDS,
    CameraBackend,
    CameraConfig,
    FloorCamera,
    FloorConfig,
    FloorTexture,
    PinholeCamera,
    RenderConfig,
    make_camera,
)
from moma_env.config import ConfigError, check_bool, check_choice, check_non_negative, check_numbers, check_positive
from moma_env.control.tracking import BoardTrackingController, TrackingControllerConfig
from moma_env.control.waypoint import WaypointFollower, WaypointFollowerConfig
from moma_env.estimator import EstimatorConfig, Status
from moma_env.estimator.log import RecordingFactory
from moma_env.estimator.registry import check_estimator_name, localiser_factory
from moma_env.markers import BoardLayout, board_for_robot
from moma_env.metrics import RunMetrics, Trajectory, TrajectoryRecorder, aggregate, run_metrics
from moma_env.odometry import WheelOdometry, WheelOdometryConfig
from moma_env.odometry.visual import VisualOdometry, VisualOdometryConfig
from moma_env.scenarios import Scenario
from moma_env.sim import Frame, LocaliserFactory, OdometryConsumer, Simulation, measured
from moma_env.world import ArenaConfig, UAVConfig, UGVConfig, WorldConfig, checked_observer_kinds
from moma_env.world.mounts import board_on_top, camera_down
from training.experiments.odometry_feed import OdometryFeed

__all__ = [
    "MAIN",
    "BUDDY",
    "floor_texture",
    "FloorVOSetup",
    "LeapfrogConfig",
    "LeapfrogRun",
    "CameraFactory",
    "left_of",
    "leapfrog_legs",
    "experiment_scenario",
    "run_leapfrog",
    "summarise",
]

MAIN = "ugv_0"
BUDDY = "ugv_1"
#: Free floor around the robots' paths inside the arena walls (m).
_ARENA_MARGIN = 1.5
#: Default distance (m) between neighbouring observers when several watch the pair.
_OBSERVER_SPACING_M = 0.5

Waypoint = tuple[float, float, float]


def _vo_camera() -> CameraConfig:
    return CameraConfig(width=160, height=120, fx=120.0, dist=(), noise_px=0.0)


def _floor() -> FloorConfig:
    # Fine enough for the robot's floor camera (2.5 mm/px at 0.3 m): 2 cm blobs at 400 px/m.
    return FloorConfig(px_per_m=400.0, feature_size_m=0.02, contrast=0.5)


@dataclass(frozen=True)
class FloorVOSetup:
    """The visual odometry baseline: a camera on the main robot looking down at the floor.

    Attributes:
        camera: its intrinsics (default 160x120 px, f = 120 px: at 0.3 m it sees
            0.40 x 0.30 m of floor, 2.5 mm per pixel).
        height: height of its optical centre above the floor (m).
        offset: distance of its optical centre ahead of the body origin (m).
        render: its image formation (a digital robot camera: the rendered
            backend's defaults, not the observer's analogue link).
        tracking: the VO's feature tracking and motion settings.
    """

    camera: CameraConfig = field(default_factory=_vo_camera)
    height: float = 0.30
    offset: float = 0.20
    render: RenderConfig = field(default_factory=RenderConfig)
    tracking: VisualOdometryConfig = field(default_factory=VisualOdometryConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.camera, CameraConfig):
            raise ConfigError("vo.camera", f"must be a CameraConfig, got {type(self.camera).__name__}")
        check_positive("vo.height", self.height)
        check_non_negative("vo.offset", self.offset)
        if not isinstance(self.render, RenderConfig):
            raise ConfigError("vo.render", f"must be a RenderConfig, got {type(self.render).__name__}")
        if not isinstance(self.tracking, VisualOdometryConfig):
            raise ConfigError("vo.tracking", f"must be a VisualOdometryConfig, got {type(self.tracking).__name__}")

    @property
    def T_b_c(self) -> np.ndarray:
        """4x4 pose of the camera in the robot's body frame (looking down, image top forward)."""
        return camera_down(height=self.height, offset=self.offset)


@dataclass(frozen=True)
class LeapfrogConfig:
    """What every two-robot leapfrog experiment shares (defaults: the paper's set-up).

    Attributes:
        separation: distance of the second robot to the left of the main one (m).
        dwell_s: time both robots are static at a switch (s).
        start_after_s: time before the first leg, for the observer to settle (s).
        observer: ``"quadcopter"`` or ``"handheld"``; or a tuple of those kinds,
            one per observer, for several observers watching the pair at once
            (named ``uav_0``, ``uav_1``, ...; each flown by its own tracking
            controller and localised by the estimator like the one observer).
        observer_offsets: per observer, how far (m) to the world's +y of the
            pair's centre it hovers: its tracking controller keeps the boards'
            centroid that far to the other side of its optical axis. None: 0 for
            one observer; ``(k - (n - 1) / 2) * 0.5`` m for the k-th of n.
        control_hz: control and camera rate (Hz); the paper's camera ran at 25.
        max_time_s: a run that has not finished by then is stopped and flagged (s).
        planar_ugvs: tell the estimator that the UGVs move upright on the floor
            (see ``MomaEstimator.add_robot(planar=...)``); False estimates their
            full 6-DoF pose as the paper's system did.
        camera_backend: ``"geometric"`` (projected corners with pixel noise) or
            ``"rendered"`` (synthetic images through ``cv2.aruco``).
        altitude: fixed flying altitude of the observer's body (m); None lets the
            tracking controller choose it from the robots' spread.
        board: layout of the robots' boards (marker size, gap); robot k gets the
            ids 4k..4k+3.
        render: image formation of the observer's rendered camera (blur, noise, interlacing).
        vo: the visual odometry baseline on the main robot (rendered backend only).
        floor: texture of the floor as the rendered cameras see it (default:
            2 cm blobs at 400 px/m, for the robot's floor camera); its
            ``extent`` and ``textured`` regions are set per run from
            :meth:`textured_regions`.
        camera, estimator, odometry, follower, tracking: the parts' configurations.
        localiser: the estimator by name (:data:`moma_env.estimator.registry.ESTIMATORS`:
            ``"moma"``, the paper's, by default; ``"fused"``, ``"ekf"``, ``"graph"``),
            built from ``estimator``. Its trajectories are the runs' ``"moma"`` method.
    """

    #: Prefix of the field names in this experiment's configuration errors.
    experiment: ClassVar[str] = "leapfrog"

    separation: float = 0.6
    dwell_s: float = 1.5
    start_after_s: float = 1.0
    observer: str | tuple[str, ...] = "quadcopter"
    observer_offsets: tuple[float, ...] | None = None
    control_hz: float = 25.0
    max_time_s: float = 300.0
    planar_ugvs: bool = True
    camera_backend: str = "geometric"
    altitude: float | None = None
    board: BoardLayout = field(default_factory=BoardLayout)
    camera: CameraConfig = field(default_factory=CameraConfig)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    odometry: WheelOdometryConfig = field(default_factory=WheelOdometryConfig)
    follower: WaypointFollowerConfig = field(default_factory=WaypointFollowerConfig)
    tracking: TrackingControllerConfig = field(default_factory=TrackingControllerConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    floor: FloorConfig = field(default_factory=_floor)
    vo: FloorVOSetup = field(default_factory=FloorVOSetup)
    localiser: str = "moma"

    def __post_init__(self) -> None:
        name = self.experiment
        check_estimator_name(f"{name}.localiser", self.localiser)
        check_positive(f"{name}.separation", self.separation)
        if self.separation < 0.5:
            raise ConfigError(f"{name}.separation", f"robots of 0.45 m need >= 0.5 m between centres, got {self.separation}")
        check_non_negative(f"{name}.dwell_s", self.dwell_s)
        check_non_negative(f"{name}.start_after_s", self.start_after_s)
        self._check_observers()
        check_positive(f"{name}.control_hz", self.control_hz)
        check_positive(f"{name}.max_time_s", self.max_time_s)
        check_bool(f"{name}.planar_ugvs", self.planar_ugvs)
        check_choice(f"{name}.camera_backend", self.camera_backend, CAMERA_BACKENDS)
        if not isinstance(self.render, RenderConfig):
            raise ConfigError(f"{name}.render", f"must be a RenderConfig, got {type(self.render).__name__}")
        if not isinstance(self.floor, FloorConfig):
            raise ConfigError(f"{name}.floor", f"must be a FloorConfig, got {type(self.floor).__name__}")
        if not isinstance(self.vo, FloorVOSetup):
            raise ConfigError(f"{name}.vo", f"must be a FloorVOSetup, got {type(self.vo).__name__}")
        if not isinstance(self.board, BoardLayout):
            raise ConfigError(f"{name}.board", f"must be a BoardLayout, got {type(self.board).__name__}")
        if self.altitude is not None:
            check_positive(f"{name}.altitude", self.altitude)
            uav = self._uav_config()
            if not uav.min_altitude <= self.altitude <= uav.max_altitude:
                raise ConfigError(
                    f"{name}.altitude", f"must be within the observer's range [{uav.min_altitude}, {uav.max_altitude}] m, got {self.altitude}"
                )
            depth = self.altitude - _board_height()
            if depth <= 0.0:
                raise ConfigError(f"{name}.altitude", f"must be above the boards ({_board_height()} m), got {self.altitude}")
            # Centred over the pair (the tracking controller centres the boards on the
            # optical axis), the camera must hold both boards whole at every switch:
            # the narrowest side of the view from the principal point, lens included.
            half_view = depth * PinholeCamera(self.camera).axis_half_view_tan
            needed = self.max_spread() / 2.0 + math.hypot(self.board.width, self.board.height) / 2.0
            needed += max(abs(v) for v in self.resolved_observer_offsets)
            if half_view < needed:
                raise ConfigError(
                    f"{name}.altitude",
                    f"{self.altitude} m is too low to keep both boards in view (half view {half_view:.2f} m at the boards, "
                    f"needs {needed:.2f} m for robots up to {self.max_spread():.2f} m apart)",
                )

    # -- what an experiment defines -------------------------------------------------
    def waypoints(self) -> list[Waypoint]:
        """The main robot's waypoints (x, y, theta), in driving order (m, rad)."""
        raise NotImplementedError

    def start_pose(self) -> Waypoint:
        """The main robot's start pose (x, y, theta) (m, rad)."""
        raise NotImplementedError

    @property
    def path_length(self) -> float:
        """Nominal path of the main robot (m), the denominator of '% of path'."""
        raise NotImplementedError

    def textured_regions(self) -> tuple[tuple[float, float, float, float], ...]:
        """Rectangles ``(xmin, ymin, xmax, ymax)`` of textured floor in W (m); the rest is plain."""
        raise NotImplementedError

    # -- derived ----------------------------------------------------------------------
    def max_spread(self) -> float:
        """Largest distance between the two robots' centres over the run (m).

        The buddy waits beside the main robot's previous waypoint while the main
        robot drives to its next one, so the spread peaks at the main robot's
        arrivals.
        """
        main = [self.start_pose(), *self.waypoints()]
        buddy = [left_of(wp, self.separation) for wp in main]
        return max(self.separation, *(math.dist(main[k][:2], buddy[k - 1][:2]) for k in range(1, len(main))))

    def _check_observers(self) -> None:
        name = self.experiment
        object.__setattr__(self, "observer", checked_observer_kinds(f"{name}.observer", self.observer))
        if self.observer_offsets is not None:
            offsets = check_numbers(f"{name}.observer_offsets", self.observer_offsets, tuple(f"uav_{k}" for k in range(len(self.observer_kinds))))
            object.__setattr__(self, "observer_offsets", tuple(float(v) for v in offsets))

    @property
    def observer_kinds(self) -> tuple[str, ...]:
        """The observers' kinds, one per observer."""
        return (self.observer,) if isinstance(self.observer, str) else tuple(self.observer)

    @property
    def resolved_observer_offsets(self) -> tuple[float, ...]:
        """:attr:`observer_offsets` with its default filled in (m, one per observer)."""
        if self.observer_offsets is not None:
            return self.observer_offsets
        n = len(self.observer_kinds)
        return (0.0,) if n == 1 else tuple((k - (n - 1) / 2.0) * _OBSERVER_SPACING_M for k in range(n))

    def _uav_config(self) -> UAVConfig:
        """The first observer's configuration (its limits bound the fixed altitude)."""
        return UAVConfig.handheld() if self.observer_kinds[0] == "handheld" else UAVConfig()

    def uav_configs(self) -> tuple[UAVConfig, ...]:
        """Every observer's configuration before placement: one ``uav``, or ``uav_0``, ``uav_1``, ..."""
        kinds = self.observer_kinds
        out = []
        for k, kind in enumerate(kinds):
            names = {} if len(kinds) == 1 else {"name": f"uav_{k}", "camera_name": f"uav_{k}/camera"}
            out.append(UAVConfig.handheld(**names) if kind == "handheld" else UAVConfig(**names))
        return tuple(out)

    def tracking_config(self, offset_m: float = 0.0) -> TrackingControllerConfig:
        """The tracking controller's configuration of an observer hovering ``offset_m`` to the
        world's +y of the pair, with the depth pinned if the altitude is fixed."""
        tracking = self.tracking
        if offset_m != 0.0:
            # The UAVs keep the yaw they start with (0): body axes are the world's.
            tracking = dataclasses.replace(tracking, target_offset=(0.0, -offset_m))
        if self.altitude is None:
            return tracking
        depth = self.altitude - _board_height()
        return dataclasses.replace(tracking, min_depth=depth, max_depth=depth)


def _board_height() -> float:
    """Height of the boards above the floor (m): the default top mount of a UGV."""
    return float(board_on_top()[2, 3])


@dataclass(frozen=True)
class LeapfrogRun:
    """The record of one run.

    Attributes:
        seed: the run's seed.
        trajectories: ``{robot: {"truth" | method: Trajectory}}``; the main robot
            has every method of ``methods``.
        waypoints: the main robot's waypoints (x, y, theta).
        switch_times: times (s) at which the main robot was declared static
            (the keypoints of the line experiment).
        metrics: ``{method: RunMetrics}`` of the main robot.
        lost_at: ``{method: time (s) it first lost track, or None}``.
        completed: True if every leg was driven before ``max_time_s``.
        duration_s: simulated time (s).
        localised: ``{robot: (n,) bool}``, per sample of the robot's
            trajectories, True where MOMA's estimate was LOCALISED (fresh), not
            HOLDING or LOST: the samples where its covariance describes its pose.
            The MOMA trajectories carry their covariances
            (:attr:`Trajectory.covariances`).
    """

    seed: int
    trajectories: dict[str, dict[str, Trajectory]]
    waypoints: tuple[Waypoint, ...]
    switch_times: tuple[float, ...]
    metrics: dict[str, RunMetrics]
    lost_at: dict[str, float | None]
    completed: bool
    duration_s: float
    localised: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def methods(self) -> tuple[str, ...]:
        """The localisation methods compared in this run, in table order."""
        return tuple(self.metrics)


def methods_of(config: LeapfrogConfig) -> tuple[str, ...]:
    """The localisation methods a run of ``config`` compares: MOMA, wheel odometry, and VO when rendered."""
    return ("moma", "wheel", "vo") if config.camera_backend == "rendered" else ("moma", "wheel")


def left_of(waypoint: Waypoint, distance: float) -> Waypoint:
    """The pose ``distance`` m to the left of ``waypoint`` (its y axis), same heading."""
    x, y, yaw = waypoint
    return (x - distance * math.sin(yaw), y + distance * math.cos(yaw), yaw)


def leapfrog_legs(config: LeapfrogConfig) -> list[Leg]:
    """Alternating legs: the main robot to its next waypoint, then its buddy beside it."""
    legs = []
    for wp in config.waypoints():
        legs.append(Leg(MAIN, wp))
        legs.append(Leg(BUDDY, left_of(wp, config.separation)))
    return legs


def _arena(config: LeapfrogConfig) -> ArenaConfig:
    """Walls ``_ARENA_MARGIN`` m beyond every pose either robot is sent to."""
    poses = [config.start_pose(), left_of(config.start_pose(), config.separation)] + [leg.waypoint for leg in leapfrog_legs(config)]
    xy = np.array([(x, y) for x, y, _ in poses])
    low = xy.min(axis=0) - _ARENA_MARGIN
    high = xy.max(axis=0) + _ARENA_MARGIN
    return ArenaConfig(width=float(high[0] - low[0]), height=float(high[1] - low[1]), origin=(float(low[0]), float(low[1])))


def _world_config(config: LeapfrogConfig, rng: np.random.Generator) -> WorldConfig:
    start_main = config.start_pose()
    start_buddy = left_of(start_main, config.separation)
    uavs = []
    for uav, lateral in zip(config.uav_configs(), config.resolved_observer_offsets):
        # Each observer starts above the pair (beside it by its offset), with a small random offset.
        offset = rng.normal(scale=0.05, size=2)
        cx, cy = (start_main[0] + start_buddy[0]) / 2 + offset[0], (start_main[1] + start_buddy[1]) / 2 + offset[1]
        initial = (cx, cy if lateral == 0.0 else cy + lateral, 0.0)
        uavs.append(dataclasses.replace(uav, initial=initial, **({} if config.altitude is None else {"altitude": config.altitude})))
    layout = {"marker_size": config.board.marker_size, "gap": config.board.gap, "dictionary": config.board.dictionary}
    ugvs = (
        UGVConfig(name=MAIN, initial_pose=start_main, board=board_for_robot(0, **layout)),
        UGVConfig(name=BUDDY, initial_pose=start_buddy, board=board_for_robot(1, **layout)),
    )
    return WorldConfig(arena=_arena(config), ugvs=ugvs, uavs=tuple(uavs), control_hz=config.control_hz)


def experiment_scenario(config: LeapfrogConfig, rng: np.random.Generator) -> Scenario:
    """The run's layout as a :class:`Scenario`: the pair at its start, the observers above it
    (each with a small random offset drawn from ``rng``), the camera, estimator and dwell of ``config``."""
    return Scenario(
        name=config.experiment,
        world=_world_config(config, rng),
        camera=config.camera,
        estimator=config.estimator,
        dwell_s=config.dwell_s,
    )


def floor_texture(config: LeapfrogConfig) -> FloorTexture:
    """The floor of a run: ``config.floor`` textured in :meth:`LeapfrogConfig.textured_regions`, plain elsewhere.

    With a perfectly plain floor (``config.floor.grain`` None) the raster spans
    the textured regions only (the floor outside it is one gray level anyway),
    which keeps a fine raster small; with grain it spans the arena too (the
    textured regions and the walls' rectangle), where the grain is drawn.
    """
    regions = np.array(config.textured_regions(), dtype=float).reshape(-1, 4)
    if config.floor.grain is not None:
        arena = _arena(config)
        x0, y0 = arena.origin
        regions = np.vstack([regions, [x0, y0, x0 + arena.width, y0 + arena.height]])
    if regions.shape[0] == 0:
        return FloorTexture(dataclasses.replace(config.floor, textured=()))
    extent = (*regions[:, :2].min(axis=0), *regions[:, 2:].max(axis=0))
    return FloorTexture(dataclasses.replace(config.floor, extent=tuple(float(v) for v in extent), textured=config.textured_regions()))


def _observer_camera(config: LeapfrogConfig, camera_name: str, floor: FloorTexture | None) -> CameraBackend:
    if config.camera_backend == "geometric":
        return make_camera(camera_name, config.camera)
    return make_camera(camera_name, config.camera, backend="rendered", render=config.render, floor=floor)


#: ``camera_factory(config, camera_name, floor) -> CameraBackend``: builds the observer's camera of a run.
CameraFactory = Callable[[LeapfrogConfig, str, FloorTexture | None], CameraBackend]


def run_leapfrog(
    config: LeapfrogConfig,
    seed: int,
    progress: Callable[[float], None] | None = None,
    camera_factory: CameraFactory | None = None,
    localiser: LocaliserFactory | None = None,
) -> LeapfrogRun:
    """Run the experiment once with every random draw seeded by ``seed``.

    Args:
        config: the experiment (square, line, ...).
        seed: seed of the run's generators (world, camera, odometry).
        progress: called with the simulated time (s) after every step, if given.
        camera_factory: builds the observer's camera from the configuration,
            the camera's name and the floor texture (None unless the backend is
            rendered); default: ``config.camera_backend``'s camera. The camera
            draws from the run's camera generator, so a factory changes only
            what the camera does with it.
        localiser: builds the run's localiser from ``config.estimator``
            (default: the factory of ``config.localiser``); a wrapper that
            times the estimator, for instance.
    """
    root = np.random.default_rng(seed)
    # A child does not depend on how many are spawned: geometric runs are unchanged by the VO's,
    # and every run by the odometry feed's (child 5, drawn only for a localiser that takes odometry).
    rng_world, rng_camera, rng_odometry, rng_vo_frames, rng_vo, rng_feed = root.spawn(6)
    scenario = experiment_scenario(config, rng_world)
    uavs = scenario.world.uavs
    floor = floor_texture(config) if config.camera_backend == "rendered" else None
    cameras = {uav.camera_name: (camera_factory or _observer_camera)(config, uav.camera_name, floor) for uav in uavs}
    # The schedule is the authority on switches here (no motion rules), and the first
    # camera frame is the first step's.
    sim = Simulation(
        scenario,
        cameras,
        localiser=localiser_factory(config.localiser) if localiser is None else localiser,
        rules=False,
        planar_ugvs=config.planar_ugvs,
        measure_at_reset=False,
    )
    frame = sim.reset(rng_camera)
    world = sim.world
    image_size = (config.camera.width, config.camera.height)
    trackers = {
        uav.name: BoardTrackingController(uav.camera_mount[:3, :3], config.camera.fx, image_size, config.tracking_config(lateral))
        for uav, lateral in zip(uavs, config.resolved_observer_offsets)
    }

    wheel = WheelOdometry(config.odometry, initial_pose=world.ugv_pose(MAIN))
    feed = OdometryFeed(config.odometry, world, (MAIN, BUDDY), rng_feed) if isinstance(sim.localiser, OdometryConsumer) else None
    schedule = LeapfrogSchedule(
        leapfrog_legs(config), WaypointFollower(config.follower), config.dwell_s, [MAIN, BUDDY], start_after_s=config.start_after_s
    )
    methods = methods_of(config)
    vo = vo_camera = None
    if "vo" in methods:
        vo_camera = FloorCamera(config.vo.camera, config.vo.T_b_c, floor, config.vo.render)
        vo = VisualOdometry(config.vo.camera, config.vo.T_b_c, config.vo.tracking, initial_pose=world.ugv_pose(MAIN), rng=rng_vo)
        vo.update(vo_camera.frame(world.ugv_transform(MAIN), rng_vo_frames, time=world.time))
    # MOMA reports a covariance with its poses; the other methods do not.
    recorders = {
        name: {m: TrajectoryRecorder(covariances=m == "moma") for m in ("truth", *methods)} for name in (MAIN, BUDDY)
    }
    for uav in uavs:
        recorders[uav.name] = {m: TrajectoryRecorder(covariances=m == "moma") for m in ("truth", "moma")}
    uav_names = set(scenario.world.uav_names)
    localised: dict[str, list[bool]] = {name: [] for name in recorders}
    lost_at: dict[str, float | None] = {m: None for m in methods}
    switch_times: list[float] = []

    def record(frame: Frame) -> None:
        t = frame.time
        for name in (MAIN, BUDDY, *scenario.world.uav_names):
            truth = world.uav_transform(name) if name in uav_names else world.ugv_transform(name)
            recorders[name]["truth"].append(t, truth)
            est = frame.estimates[name]
            recorders[name]["moma"].append(t, est.T_w_b, est.covariance)
            localised[name].append(est.status is Status.LOCALISED)
        recorders[MAIN]["wheel"].append(t, wheel.pose)
        recorders[BUDDY]["wheel"].append(t, None)
        if vo is not None:
            recorders[MAIN]["vo"].append(t, vo.T_w_b)
            recorders[BUDDY]["vo"].append(t, None)
            if lost_at["vo"] is None and vo.lost:
                lost_at["vo"] = t
        if lost_at["moma"] is None and frame.estimates[MAIN].status is Status.LOST:
            lost_at["moma"] = t

    record(frame)
    uav_command = {uav.name: np.zeros(4) for uav in uavs}
    ugv_commands = {MAIN: np.zeros(3), BUDDY: np.zeros(3)}
    while not schedule.done and world.time < config.max_time_s:
        requests = sim.move(ugv_commands, uav_command)
        if feed is not None:
            feed.step(world, sim.localiser)
        frame = sim.localise(measured(requests))
        wheel.update(world.ugv_body_velocity(MAIN), world.dt, rng_odometry)
        if vo is not None:
            vo.update(vo_camera.frame(world.ugv_transform(MAIN), rng_vo_frames, time=world.time))
        record(frame)
        if progress is not None:
            progress(world.time)

        uav_command = {
            uav.name: trackers[uav.name].command([d.T_c_m[:3, 3] for d in frame.detections if d.camera_id == uav.camera_name])
            for uav in uavs
        }
        poses = {}
        for name in (MAIN, BUDDY):
            est = frame.estimates[name]
            poses[name] = frame.estimated[name] if est.status is Status.LOCALISED else None
        ugv_commands, changes = schedule.step(world.time, poses, sim.localiser.window_ready)
        for change in changes:
            sim.declare(change.robot, static=change.static)
            if change.robot == MAIN and change.static:
                switch_times.append(world.time)

    trajectories = {name: {m: r.to_trajectory() for m, r in recs.items()} for name, recs in recorders.items()}
    main = trajectories[MAIN]
    metrics = {
        method: run_metrics(main[method], main["truth"], switch_times=switch_times, path_length=config.path_length) for method in methods
    }
    return LeapfrogRun(
        seed=seed,
        trajectories=trajectories,
        waypoints=tuple(config.waypoints()),
        switch_times=tuple(switch_times),
        metrics=metrics,
        lost_at=lost_at,
        completed=schedule.done,
        duration_s=world.time,
        localised={name: np.array(flags, dtype=bool) for name, flags in localised.items()},
    )


def run_leapfrog_recorded(
    config: LeapfrogConfig,
    seed: int,
    progress: Callable[[float], None] | None = None,
    camera_factory: CameraFactory | None = None,
) -> tuple[LeapfrogRun, str]:
    """:func:`run_leapfrog` with its localiser recorded: the same run, and its detection log
    (:mod:`moma_env.estimator.log`, the file's text: every call the localiser took)."""
    recording = RecordingFactory(localiser_factory(config.localiser))
    run = run_leapfrog(config, seed, progress, camera_factory, localiser=recording)
    return run, recording.made[-1].text()


def summarise(runs: list[LeapfrogRun]) -> dict[str, dict]:
    """Per method: the aggregate over runs (ME_f, std, ME, % of path, ...) and its track loss.

    ``track_loss_rate`` is the fraction of runs in which the method lost track at
    least once (:attr:`LeapfrogRun.lost_at`), in [0, 1]. The aggregate covers
    every run with a known final error (a visual odometry holds its last pose
    while lost, so its error keeps counting); ``kept_track`` is the aggregate over
    the runs where the method never lost track, the paper's convention for Viso2
    ("this only includes the cases where Viso2 didn't lose track"), or None if
    there is no such run.
    """
    if not runs:
        raise ValueError("summarise needs at least one run")
    out = {}
    for method in runs[0].methods:
        summary = aggregate([run.metrics[method] for run in runs]).to_dict()
        kept = [run.metrics[method] for run in runs if run.lost_at[method] is None]
        summary["track_loss_rate"] = 1.0 - len(kept) / len(runs)
        summary["kept_track"] = aggregate(kept).to_dict() if kept else None
        out[method] = summary
    return out
