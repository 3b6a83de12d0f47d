"""Single-robot caterpillar: a robot and the sled it tows on a pulley.

The paper's single-robot caterpillar: ``ugv_0`` carries a backward camera
(``mounts.camera_backward``, named ``"ugv_0/camera"``) and tows ``"sled"``, a
box with a vertical board on its front (ids of ``board_for_robot(1)``), through
a rope it can reel in or let out. The robot moves while the sled stays behind
as the static reference, then stops and reels the sled in, measuring it: MOMA
odometry with one robot. No observer; the robot carries no board.

Start (m, in the frame of ``start``, the robot's pose): the sled straight
behind the robot, its front anchor ``rope_length`` m behind the robot's back
anchor (the rope just taut). The camera sits ``CAMERA_OFFSET_M`` behind the
robot's centre at the height of the sled's board, so it looks at the board's
centre. The robot's goal is its start advanced by ``goal_distance`` along its
heading (the sled has no goal).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from moma_env.config import ConfigError, check_positive
from moma_env.geometry import wrap_angle
from moma_env.markers import board_for_robot
from moma_env.scenarios.common import Layout, ScenarioConfig, camera_name, default_ugv_radius, planar_pose, ugv_name
from moma_env.scenarios.layout import Pose2D, advanced
from moma_env.scenarios.sampling import (
    draw_until_valid,
    random_camera,
    random_goal_distance,
    random_heading,
    random_surroundings,
)
from moma_env.scenarios.spec import ScenarioSpec
from moma_env.world import CameraMount, SledConfig, UGVConfig, WorldConfig, camera_backward

__all__ = ["CaterpillarSledConfig", "SLED_NAME", "CAMERA_OFFSET_M", "RANDOM_ROPE_RANGE_M", "sled_views", "SPEC"]

#: Name of the sled.
SLED_NAME = "sled"
#: Distance (m) of the robot's camera behind its centre (just behind its back edge).
CAMERA_OFFSET_M = 0.23
#: Range of the initial rope length (m) of a random configuration.
RANDOM_ROPE_RANGE_M = (0.45, 1.0)


def sled_views(world: WorldConfig) -> dict[str, tuple[str, ...]]:
    """The camera of every sled's towing robot -> that sled's board (its robot keeps it in
    view while either moves)."""
    return {camera_name(sled.robot): (sled.name,) for sled in world.sleds}


@dataclass(frozen=True, kw_only=True)
class CaterpillarSledConfig(ScenarioConfig):
    """A robot with a backward camera towing a sled with a front board (fields in
    addition to :class:`ScenarioConfig`'s).

    Attributes:
        rope_length: rope length at the start, anchor to anchor (m), in
            ``[min_rope, max_rope]``; the sled starts that far behind the robot.
        min_rope, max_rope: limits of the rope length (m), 0 < min < max.
        reel_speed: rope speed at full reel rate (m/s).
        goal_distance: advance of the robot to its goal along its heading (m).
        start: the robot's ``(x, y, yaw)``.
    """

    NAME: ClassVar[str] = "caterpillar_sled"

    rope_length: float = 0.6
    min_rope: float = 0.35
    max_rope: float = 1.5
    reel_speed: float = 0.15
    goal_distance: float = 2.0
    start: Pose2D = (0.0, 0.0, 0.0)

    def _check_fields(self) -> None:
        object.__setattr__(self, "start", planar_pose(self._field("start"), self.start))
        check_positive(self._field("goal_distance"), self.goal_distance)
        self._sled(self.start)  # checks the rope fields

    def _sled(self, pose: Pose2D) -> SledConfig:
        """The sled at ``pose``; its rope errors are reported under this configuration's fields."""
        try:
            return SledConfig(
                name=SLED_NAME,
                robot=ugv_name(0),
                initial_pose=pose,
                board=board_for_robot(1),
                rope_length=self.rope_length,
                min_rope=self.min_rope,
                max_rope=self.max_rope,
                reel_speed=self.reel_speed,
            )
        except ConfigError as error:
            name = error.field.removeprefix("sled.")
            raise ConfigError(self._field(name), str(error)[len(error.field) + 2 :]) from None

    def _make_layout(self) -> Layout:
        radius = default_ugv_radius()
        robot_start = (self.start[0], self.start[1], float(wrap_angle(self.start[2])))
        robot_goal = advanced(robot_start, self.goal_distance)
        probe = self._sled(robot_start)
        behind = radius + self.rope_length + probe.size[0] / 2.0  # robot centre to sled centre
        sled_start = advanced(robot_start, -behind)
        sled_at_goal = advanced(robot_goal, -behind)
        sled = self._sled(sled_start)
        camera = CameraMount(camera_name(ugv_name(0)), camera_backward(sled.board_height, CAMERA_OFFSET_M))
        robot = UGVConfig(name=ugv_name(0), initial_pose=robot_start, board=None, cameras=(camera,))
        sled_radius = 0.5 * float(np.hypot(*sled.size))
        return Layout(
            ugvs=(robot,),
            goals={robot.name: robot_goal},
            disks=(
                (f"{robot.name} start", robot_start[0], robot_start[1], radius),
                (f"{robot.name} goal", robot_goal[0], robot_goal[1], radius),
                (f"{SLED_NAME} start", sled_start[0], sled_start[1], sled_radius),
                (f"{SLED_NAME} behind the goal", sled_at_goal[0], sled_at_goal[1], sled_radius),
            ),
            movers=2,
            path_m=self.goal_distance,
            speed=min(robot.max_speed, self.reel_speed),
            sleds=(sled,),
        )

    def required_views(self) -> Mapping[str, tuple[str, ...]]:
        """The robot's backward camera sees the sled's board."""
        return {camera_name(ugv_name(0)): (SLED_NAME,)}

    @classmethod
    def random(cls, rng: np.random.Generator, **team: int) -> CaterpillarSledConfig:
        """Random heading, goal distance (1-3 m), initial rope length (0.45-1.0 m),
        camera, arena and obstacles; every draw from ``rng``.

        ``team`` must be empty (the team is always the same; ConfigError otherwise).
        """
        cls.check_team(team)

        def draw(rng: np.random.Generator) -> CaterpillarSledConfig:
            config = cls(
                start=(0.0, 0.0, random_heading(rng)),
                goal_distance=random_goal_distance(rng),
                rope_length=float(rng.uniform(*RANDOM_ROPE_RANGE_M)),
                camera=random_camera(rng),
            )
            return replace(config, **random_surroundings(rng, config.occupied_disks))

        return draw_until_valid(cls, rng, draw)


#: The single-robot caterpillar's place in the registry.
SPEC = ScenarioSpec(
    config_type=CaterpillarSledConfig,
    gymnasium_id="moma_env/CaterpillarSled-v0",
    pettingzoo_module="caterpillar_sled_v0",
    schedule="moma_env.planning.planner:sled_schedule",
    scripted_policy="agents.policies.caterpillar_sled:CaterpillarSled",
    motion_views=sled_views,
)
