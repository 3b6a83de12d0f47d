"""The physics world: arena, omnidirectional ground robots and towed sleds (pymunk), and the UAV.

Ground truth of the simulator. The camera and the estimator are applied on top
by the caller and are not imported here.
"""

from moma_env.world.arena import WALL_NAME, obstacle_name
from moma_env.world.config import (
    UAV_KINDS,
    checked_observer_kinds,
    ArenaConfig,
    BoxObstacle,
    CameraMount,
    SledConfig,
    UAVConfig,
    UGVConfig,
    WorldConfig,
    world_config_from_mapping,
)
from moma_env.world.mounts import (
    board_on_back,
    board_on_front,
    board_on_top,
    camera_backward,
    camera_down,
    camera_forward,
)
from moma_env.world.sled import ROPE_ERROR_BIAS, friction_lever
from moma_env.world.uav import GRAVITY, UAVState, uav_body_transform
from moma_env.world.world import COLLISION_SLOP, World

__all__ = [
    "ArenaConfig",
    "BoxObstacle",
    "CameraMount",
    "UGVConfig",
    "SledConfig",
    "UAVConfig",
    "UAV_KINDS",
    "checked_observer_kinds",
    "WorldConfig",
    "world_config_from_mapping",
    "board_on_top",
    "board_on_back",
    "board_on_front",
    "camera_forward",
    "camera_backward",
    "camera_down",
    "World",
    "UAVState",
    "uav_body_transform",
    "GRAVITY",
    "COLLISION_SLOP",
    "WALL_NAME",
    "obstacle_name",
    "friction_lever",
    "ROPE_ERROR_BIAS",
]
