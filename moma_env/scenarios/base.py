"""The contract between a configuration and the environment: :class:`Scenario`.

A configuration (``top_observer``, ``caterpillar``, ...) is a typed, validated
dataclass with defaults from DESIGN.md; its ``scenario()`` method lays out one
episode as a :class:`Scenario`: the world (arena, robots with their boards and
cameras, observer, sleds), the camera model, the goals and the motion-rule
parameters. The environment builds everything it simulates and estimates from
a Scenario alone, so a new configuration needs no change in the environment.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from moma_env.camera import CameraConfig
from moma_env.config import ConfigError, check_finite, check_non_negative, check_positive
from moma_env.estimator import EstimatorConfig
from moma_env.world import WorldConfig

__all__ = ["Scenario"]

Pose2D = tuple[float, float, float]


@dataclass(frozen=True)
class Scenario:
    """One episode's layout.

    Attributes:
        name: configuration name, e.g. ``"top_observer"``.
        world: the physical world; its UGVs start static at their initial poses,
            which define the MOMA world frame (the estimator is told them).
        camera: intrinsics and noise shared by every camera of the world.
        goals: final goal ``(x, y, yaw)`` of each UGV that has one (m, rad, in W);
            the episode terminates when every goal is reached.
        estimator: MOMA estimator settings.
        leg_length: longest advance of one turn in ``switching`` mode (m).
        dwell_s: motion rule 3, time every switch keeps two devices static (s).
        goal_tolerance_m, goal_tolerance_rad: a goal counts as reached within these.
        max_cycles: default episode length in control steps.
        routes: via poses ``(x, y, yaw)`` (m, rad, in W) a UGV passes, in order,
            on its way to its goal in ``switching`` mode (none: straight to the
            goal); the yaw of each is the heading the robot drives with towards it.
    """

    name: str
    world: WorldConfig
    camera: CameraConfig = field(default_factory=CameraConfig)
    goals: Mapping[str, Pose2D] = field(default_factory=dict)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    leg_length: float = 0.5
    dwell_s: float = 1.0
    goal_tolerance_m: float = 0.05
    goal_tolerance_rad: float = 0.1
    max_cycles: int = 2000
    routes: Mapping[str, tuple[Pose2D, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError("scenario.name", f"must be a non-empty string, got {self.name!r}")
        if not isinstance(self.world, WorldConfig):
            raise ConfigError("scenario.world", f"must be a WorldConfig, got {type(self.world).__name__}")
        if not isinstance(self.camera, CameraConfig):
            raise ConfigError("scenario.camera", f"must be a CameraConfig, got {type(self.camera).__name__}")
        if not isinstance(self.estimator, EstimatorConfig):
            raise ConfigError("scenario.estimator", f"must be an EstimatorConfig, got {type(self.estimator).__name__}")
        known = set(self.world.ugv_names)
        goals = {}
        for name, goal in dict(self.goals).items():
            if name not in known:
                raise ConfigError(f"scenario.goals[{name!r}]", f"unknown UGV; known: {sorted(known)}")
            if len(tuple(goal)) != 3:
                raise ConfigError(f"scenario.goals[{name!r}]", f"must be (x, y, yaw), got {goal!r}")
            for v in goal:
                check_finite(f"scenario.goals[{name!r}]", v)
            goals[name] = tuple(float(v) for v in goal)
        object.__setattr__(self, "goals", goals)
        routes = {}
        for name, route in dict(self.routes).items():
            if name not in goals:
                raise ConfigError(f"scenario.routes[{name!r}]", f"names no UGV with a goal; with goals: {sorted(goals)}")
            poses = []
            for k, pose in enumerate(tuple(route)):
                if len(tuple(pose)) != 3:
                    raise ConfigError(f"scenario.routes[{name!r}][{k}]", f"must be (x, y, yaw), got {pose!r}")
                for v in pose:
                    check_finite(f"scenario.routes[{name!r}][{k}]", v)
                poses.append(tuple(float(v) for v in pose))
            if poses:
                routes[name] = tuple(poses)
        object.__setattr__(self, "routes", routes)
        check_positive("scenario.leg_length", self.leg_length)
        check_non_negative("scenario.dwell_s", self.dwell_s)
        check_positive("scenario.goal_tolerance_m", self.goal_tolerance_m)
        check_positive("scenario.goal_tolerance_rad", self.goal_tolerance_rad)
        if isinstance(self.max_cycles, bool) or not isinstance(self.max_cycles, int) or self.max_cycles < 1:
            raise ConfigError("scenario.max_cycles", f"must be an integer >= 1, got {self.max_cycles!r}")
