"""The paper's waypoint experiment: two UGVs leapfrog around a 1 m square.

Section IV of the paper: the main robot drives a square of side 1 m through the
waypoints (x, y, theta) with pure rotations at (0, 1), (1, 1) and (1, 0), a 4 m
path; a second robot keeps it company about 0.6 m to its left (outside the
square); the two move in turns with a dwell at every switch, and a UAV above them
tracks both boards with its controller. Every robot is driven on its MOMA
estimate; the truth is only recorded. The main robot's MOMA trajectory is compared
with the truth and with wheel odometry (dead reckoning with slip).

This module is the experiment's core: :func:`run_square` runs one seeded run and
:func:`summarise` the statistics over runs. Printing, files and figures live in
:mod:`training.experiments.square_report`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from agents.leapfrog import LeapfrogSchedule, Leg
from moma_env.control.tracking import BoardTrackingController, TrackingControllerConfig
from moma_env.control.waypoint import WaypointFollower, WaypointFollowerConfig
from moma_env.camera import BoardView, CameraConfig, GeometricCamera
from moma_env.config import ConfigError, check_choice, check_non_negative, check_positive
from moma_env.estimator import EstimatorConfig, MomaEstimator, Status
from moma_env.geometry import se3_to_se2
from moma_env.markers import board_for_robot
from moma_env.metrics import RunMetrics, Trajectory, TrajectoryRecorder, aggregate, run_metrics
from moma_env.odometry import WheelOdometry, WheelOdometryConfig
from moma_env.world import ArenaConfig, UAVConfig, UGVConfig, World, WorldConfig

__all__ = ["SquareConfig", "SquareRun", "square_waypoints", "square_legs", "run_square", "summarise", "METHODS"]

MAIN = "ugv_0"
BUDDY = "ugv_1"
#: The localisation methods compared, in table order.
METHODS = ("moma", "wheel")


@dataclass(frozen=True)
class SquareConfig:
    """Everything that defines one square run (defaults: the paper's set-up).

    Attributes:
        side: side of the square (m); the main robot's path is ``4 * side``.
        leg: length of one leg of the main robot between switches (m).
        separation: distance of the second robot from the main one (m).
        dwell_s: time both robots are static at a switch (s).
        start_after_s: time before the first leg, for the observer to settle (s).
        observer: ``"quadcopter"`` or ``"handheld"``.
        control_hz: control and camera rate (Hz); the paper's camera ran at 25.
        max_time_s: a run that has not finished by then is stopped and flagged (s).
        planar_ugvs: tell the estimator that the UGVs move upright on the floor
            (see ``MomaEstimator.add_robot(planar=...)``); False estimates their
            full 6-DoF pose as the paper's system did.
    """

    side: float = 1.0
    leg: float = 0.5
    separation: float = 0.6
    dwell_s: float = 1.5
    start_after_s: float = 1.0
    observer: str = "quadcopter"
    control_hz: float = 25.0
    max_time_s: float = 300.0
    planar_ugvs: bool = True
    camera: CameraConfig = field(default_factory=CameraConfig)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    odometry: WheelOdometryConfig = field(default_factory=WheelOdometryConfig)
    follower: WaypointFollowerConfig = field(default_factory=WaypointFollowerConfig)
    tracking: TrackingControllerConfig = field(default_factory=TrackingControllerConfig)

    def __post_init__(self) -> None:
        check_positive("square.side", self.side)
        check_positive("square.leg", self.leg)
        check_positive("square.separation", self.separation)
        check_non_negative("square.dwell_s", self.dwell_s)
        check_non_negative("square.start_after_s", self.start_after_s)
        check_choice("square.observer", self.observer, ("quadcopter", "handheld"))
        check_positive("square.control_hz", self.control_hz)
        check_positive("square.max_time_s", self.max_time_s)
        if self.leg > self.side:
            raise ConfigError("square.leg", f"must be <= side ({self.side}), got {self.leg}")
        if self.separation < 0.5:
            raise ConfigError("square.separation", f"robots of 0.45 m need >= 0.5 m between centres, got {self.separation}")

    @property
    def path_length(self) -> float:
        """Nominal path of the main robot (m): the paper's 400 cm for a 1 m side."""
        return 4.0 * self.side


@dataclass(frozen=True)
class SquareRun:
    """The record of one run.

    Attributes:
        seed: the run's seed.
        trajectories: ``{robot: {"truth" | "moma" | "wheel": Trajectory}}``.
        waypoints: the main robot's waypoints (x, y, theta).
        switch_times: times (s) at which the main robot was declared static.
        metrics: ``{method: RunMetrics}`` of the main robot.
        completed: True if every leg was driven before ``max_time_s``.
        duration_s: simulated time (s).
    """

    seed: int
    trajectories: dict[str, dict[str, Trajectory]]
    waypoints: tuple[tuple[float, float, float], ...]
    switch_times: tuple[float, ...]
    metrics: dict[str, RunMetrics]
    completed: bool
    duration_s: float


def square_waypoints(side: float, leg: float) -> list[tuple[float, float, float]]:
    """Main robot waypoints: start (0, 0) heading +y, clockwise, turning at the corners.

    Each side is split into legs of at most ``leg`` metres; at a corner the robot
    turns in place to the next side's heading (the paper's pure rotations).
    """
    corners = [(0.0, 0.0), (0.0, side), (side, side), (side, 0.0), (0.0, 0.0)]
    headings = [math.pi / 2, 0.0, -math.pi / 2, math.pi]
    n = max(1, math.ceil(side / leg - 1e-9))
    waypoints: list[tuple[float, float, float]] = []
    for k in range(4):
        (x0, y0), (x1, y1) = corners[k], corners[k + 1]
        for i in range(1, n + 1):
            f = i / n
            heading = headings[k]
            if i == n and k < 3:
                heading = headings[k + 1]
            waypoints.append((x0 + f * (x1 - x0), y0 + f * (y1 - y0), heading))
    return waypoints


def _left_of(waypoint: tuple[float, float, float], distance: float) -> tuple[float, float, float]:
    x, y, yaw = waypoint
    return (x - distance * math.sin(yaw), y + distance * math.cos(yaw), yaw)


def square_legs(config: SquareConfig) -> list[Leg]:
    """Alternating legs: the main robot to its next waypoint, then its buddy beside it."""
    legs = []
    for wp in square_waypoints(config.side, config.leg):
        legs.append(Leg(MAIN, wp))
        legs.append(Leg(BUDDY, _left_of(wp, config.separation)))
    return legs


def _world_config(config: SquareConfig, rng: np.random.Generator) -> WorldConfig:
    start_main = (0.0, 0.0, math.pi / 2)
    start_buddy = _left_of(start_main, config.separation)
    uav = UAVConfig.handheld() if config.observer == "handheld" else UAVConfig()
    # The observer starts above the pair, with a small random offset.
    offset = rng.normal(scale=0.05, size=2)
    uav = dataclasses.replace(uav, initial=((start_main[0] + start_buddy[0]) / 2 + offset[0], (start_main[1] + start_buddy[1]) / 2 + offset[1], 0.0))
    margin = 1.5
    arena = ArenaConfig(
        width=config.side + config.separation + 2 * margin,
        height=config.side + config.separation + 2 * margin,
        origin=(-config.separation - margin, -margin),
    )
    ugvs = (
        UGVConfig(name=MAIN, initial_pose=start_main, board=board_for_robot(0)),
        UGVConfig(name=BUDDY, initial_pose=start_buddy, board=board_for_robot(1)),
    )
    return WorldConfig(arena=arena, ugvs=ugvs, uav=uav, control_hz=config.control_hz)


def run_square(config: SquareConfig, seed: int) -> SquareRun:
    """Run the square once with every random draw seeded by ``seed``."""
    root = np.random.default_rng(seed)
    rng_world, rng_camera, rng_odometry = root.spawn(3)
    world = World(_world_config(config, rng_world))
    world.reset(rng_world)
    uav_cfg = world.config.uav
    camera = GeometricCamera(uav_cfg.camera_name, config.camera)
    tracker = BoardTrackingController(uav_cfg.camera_mount[:3, :3], config.camera.fx, (config.camera.width, config.camera.height), config.tracking)

    estimator = MomaEstimator(config.estimator)
    boards = {}
    for index, ugv in enumerate(world.config.ugvs):
        estimator.add_robot(
            ugv.name,
            boards={index: ugv.board_mount},
            static=True,
            initial_pose=world.ugv_transform(ugv.name),
            time=world.time,
            planar=config.planar_ugvs,
        )
        boards[ugv.name] = (index, ugv.board)
    estimator.add_robot(uav_cfg.name, cameras={uav_cfg.camera_name: uav_cfg.camera_mount}, static=False, time=world.time)

    wheel = WheelOdometry(config.odometry, initial_pose=world.ugv_pose(MAIN))
    schedule = LeapfrogSchedule(
        square_legs(config), WaypointFollower(config.follower), config.dwell_s, [MAIN, BUDDY], start_after_s=config.start_after_s
    )
    recorders = {name: {m: TrajectoryRecorder() for m in ("truth", "moma", "wheel")} for name in (MAIN, BUDDY)}
    recorders[uav_cfg.name] = {m: TrajectoryRecorder() for m in ("truth", "moma")}
    switch_times: list[float] = []

    def record() -> None:
        t = world.time
        for name in (MAIN, BUDDY):
            recorders[name]["truth"].append(t, world.ugv_transform(name))
            recorders[name]["moma"].append(t, estimator.estimate(name).T_w_b)
        recorders[MAIN]["wheel"].append(t, wheel.pose)
        recorders[BUDDY]["wheel"].append(t, None)
        recorders[uav_cfg.name]["truth"].append(t, world.uav_transform())
        recorders[uav_cfg.name]["moma"].append(t, estimator.estimate(uav_cfg.name).T_w_b)

    record()
    uav_command = np.zeros(4)
    ugv_commands = {MAIN: np.zeros(3), BUDDY: np.zeros(3)}
    while not schedule.done and world.time < config.max_time_s:
        world.step(ugv_commands, uav_command)
        wheel.update(world.ugv_body_velocity(MAIN), world.dt, rng_odometry)
        views = [BoardView(board_id, layout, world.board_transform(name)) for name, (board_id, layout) in boards.items()]
        detections = camera.measure(world.camera_transform(uav_cfg.camera_name), views, world.time, rng_camera)
        estimator.update(world.time, detections)
        record()

        uav_command = tracker.command([d.T_c_m[:3, 3] for d in detections])
        poses = {}
        for name in (MAIN, BUDDY):
            est = estimator.estimate(name)
            poses[name] = se3_to_se2(est.T_w_b) if est.status is Status.LOCALISED and est.T_w_b is not None else None
        ugv_commands, changes = schedule.step(world.time, poses)
        for change in changes:
            world.set_static(change.robot, change.static)
            estimator.set_static(change.robot, change.static, world.time)
            if change.robot == MAIN and change.static:
                switch_times.append(world.time)

    trajectories = {name: {m: r.to_trajectory() for m, r in recs.items()} for name, recs in recorders.items()}
    main = trajectories[MAIN]
    metrics = {
        method: run_metrics(main[method], main["truth"], switch_times=switch_times, path_length=config.path_length)
        for method in METHODS
    }
    return SquareRun(
        seed=seed,
        trajectories=trajectories,
        waypoints=tuple(square_waypoints(config.side, config.leg)),
        switch_times=tuple(switch_times),
        metrics=metrics,
        completed=schedule.done,
        duration_s=world.time,
    )


def summarise(runs: list[SquareRun]) -> dict[str, dict]:
    """Per method: the aggregate over runs (ME_f, std, ME, % of path, ...) as a dict."""
    return {method: aggregate([run.metrics[method] for run in runs]).to_dict() for method in METHODS}
