"""Caterpillar: a follower's forward camera on the board on its leader's back.

The paper's two-robot caterpillar (section III): ``ugv_0``, the leader, carries a
vertical board on its back (``mounts.board_on_back``, ids of
``board_for_robot(0)``); ``ugv_1``, the follower, a forward camera
(``mounts.camera_forward``, named ``"ugv_1/camera"``). No observer. They start
static in a file along the heading of ``start`` (the leader's pose), ``distance``
apart centre to centre, and each one's goal is its start advanced by
``goal_distance`` along that heading.

Mounts: camera and board sit ``(distance - standoff) / 2`` m from their robot's
centre (ahead of the follower, behind the leader) at ``MOUNT_HEIGHT_M``, so that
at the start the follower's camera is exactly ``standoff`` m from the leader's
board and looks at its centre (the authors' follower servoed to 0.539 m). With
the defaults the mounts lie inside the robots' footprints (0.13 m from the
centre, radius 0.225 m): a line-of-sight query between them must ignore both
robots.

:class:`RobotFileConfig` (fields and checks) and :func:`file_layout` serve any
number of robots; :mod:`moma_env.scenarios.caterpillar_multi` uses them for
longer files.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from moma_env.config import ConfigError, check_positive
from moma_env.geometry import wrap_angle
from moma_env.markers import board_for_robot, team_dictionary
from moma_env.scenarios.common import (
    Layout,
    ScenarioConfig,
    camera_name,
    default_ugv_radius,
    planar_pose,
    ugv_name,
)
from moma_env.scenarios.layout import Pose2D, advanced
from moma_env.scenarios.sampling import (
    draw_until_valid,
    random_camera,
    random_goal_distance,
    random_heading,
    random_surroundings,
)
from moma_env.scenarios.spec import ScenarioSpec
from moma_env.world import CameraMount, UGVConfig, WorldConfig, board_on_back, camera_forward

__all__ = [
    "CaterpillarConfig",
    "RobotFileConfig",
    "MOUNT_HEIGHT_M",
    "file_layout",
    "file_views",
    "file_motion_views",
    "SPEC",
]

#: Height (m) of the followers' cameras and of the boards on the robots' backs.
MOUNT_HEIGHT_M = 0.30


def file_layout(start: Pose2D, n_ugvs: int, distance: float, standoff: float, goal_distance: float) -> Layout:
    """``n_ugvs`` robots in a file behind the leader at ``start``; goals ``goal_distance`` m ahead.

    ``ugv_0`` carries a back board only; ``ugv_k`` (k >= 1) a forward camera on
    ``ugv_{k-1}``'s board and, unless it is the last, a back board of its own
    (ids of ``board_for_robot(k)``, all of ``team_dictionary(n_ugvs - 1)``).
    """
    radius = default_ugv_radius()
    dictionary = team_dictionary(max(n_ugvs - 1, 0))
    mount_offset = 0.5 * (distance - standoff)
    leader = (start[0], start[1], float(wrap_angle(start[2])))
    ugvs, goals, disks = [], {}, []
    for k in range(n_ugvs):
        name = ugv_name(k)
        pose = advanced(leader, -k * distance)
        goal = advanced(pose, goal_distance)
        has_board = k < n_ugvs - 1
        cameras = (CameraMount(camera_name(name), camera_forward(MOUNT_HEIGHT_M, mount_offset)),) if k > 0 else ()
        ugvs.append(
            UGVConfig(
                name=name,
                initial_pose=pose,
                board=board_for_robot(k, dictionary=dictionary) if has_board else None,
                board_mount=board_on_back(MOUNT_HEIGHT_M, mount_offset),
                cameras=cameras,
            )
        )
        goals[name] = goal
        disks += [(f"{name} start", pose[0], pose[1], radius), (f"{name} goal", goal[0], goal[1], radius)]
    return Layout(ugvs=tuple(ugvs), goals=goals, disks=tuple(disks), movers=n_ugvs, path_m=goal_distance)


def file_views(n_ugvs: int) -> dict[str, tuple[str, ...]]:
    """Camera of ``ugv_k`` -> the board of ``ugv_{k-1}``, for k >= 1."""
    return {camera_name(ugv_name(k)): (ugv_name(k - 1),) for k in range(1, n_ugvs)}


def file_motion_views(world: WorldConfig) -> dict[str, tuple[str, ...]]:
    """:func:`file_views` of the file of ``world``'s UGVs: every follower keeps the
    board ahead in view while it or the robot ahead moves."""
    return file_views(len(world.ugvs))


@dataclass(frozen=True, kw_only=True)
class RobotFileConfig(ScenarioConfig):
    """Fields of a file of robots (in addition to :class:`ScenarioConfig`'s).

    Attributes:
        distance: distance between neighbours in the file, centre to centre (m),
            at least the robots' diameter.
        standoff: distance from a follower's camera to the board in front of it
            at the start (m), less than ``distance``; the authors' 0.539 m.
        goal_distance: advance of every robot to its goal along the heading (m).
        start: the leader's ``(x, y, yaw)``; the others stand behind it.
    """

    distance: float = 0.8
    standoff: float = 0.539
    goal_distance: float = 2.0
    start: Pose2D = (0.0, 0.0, 0.0)

    @property
    @abstractmethod
    def file_length(self) -> int:
        """Number of robots in the file."""

    def _check_fields(self) -> None:
        object.__setattr__(self, "start", planar_pose(self._field("start"), self.start))
        check_positive(self._field("distance"), self.distance)
        diameter = 2.0 * default_ugv_radius()
        if self.distance < diameter:
            raise ConfigError(
                self._field("distance"), f"must be at least the robots' diameter {diameter} m, got {self.distance}"
            )
        check_positive(self._field("standoff"), self.standoff)
        if self.standoff >= self.distance:
            raise ConfigError(
                self._field("standoff"),
                f"must be less than distance={self.distance} (camera and board sit between the robots' centres), "
                f"got {self.standoff}",
            )
        check_positive(self._field("goal_distance"), self.goal_distance)

    def _make_layout(self) -> Layout:
        return file_layout(self.start, self.file_length, self.distance, self.standoff, self.goal_distance)

    def required_views(self) -> Mapping[str, tuple[str, ...]]:
        """Every follower's camera sees the board of the robot in front of it."""
        return file_views(self.file_length)


@dataclass(frozen=True, kw_only=True)
class CaterpillarConfig(RobotFileConfig):
    """Leader ``ugv_0`` with a back board, follower ``ugv_1`` with a forward camera
    (fields of :class:`RobotFileConfig`)."""

    NAME: ClassVar[str] = "caterpillar"

    @property
    def file_length(self) -> int:
        """Two robots."""
        return 2

    @classmethod
    def random(cls, rng: np.random.Generator, **team: int) -> CaterpillarConfig:
        """Random heading, goal distance (1-3 m), camera, arena and obstacles; every draw from ``rng``.

        ``team`` must be empty (the team is always the same; ConfigError otherwise).
        """
        cls.check_team(team)

        def draw(rng: np.random.Generator) -> CaterpillarConfig:
            config = cls(
                start=(0.0, 0.0, random_heading(rng)),
                goal_distance=random_goal_distance(rng),
                camera=random_camera(rng),
            )
            return replace(config, **random_surroundings(rng, config.occupied_disks))

        return draw_until_valid(cls, rng, draw)


#: The two-robot caterpillar's place in the registry.
SPEC = ScenarioSpec(
    config_type=CaterpillarConfig,
    gymnasium_id="moma_env/Caterpillar-v0",
    pettingzoo_module="caterpillar_v0",
    schedule="moma_env.planning.planner:robot_file_schedule",
    scripted_policy="agents.policies.caterpillar_multi:CaterpillarTwo",
    motion_views=file_motion_views,
)
