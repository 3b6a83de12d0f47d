"""Board and camera poses of ground robots, and the mount helpers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_BOARD_BACK, R_BODY_CAM_FORWARD, invert
from moma_env.markers import board_for_robot
from moma_env.world import (
    CameraMount,
    UAVConfig,
    UGVConfig,
    World,
    WorldConfig,
    board_on_back,
    board_on_top,
    camera_down,
    camera_forward,
)


def test_board_on_top_of_a_robot_facing_world_y():
    world = World(WorldConfig(ugvs=(UGVConfig("a", (1.0, 2.0, math.pi / 2)),)))
    T_w_m = world.board_transform("a")
    np.testing.assert_allclose(T_w_m[:3, 3], [1.0, 2.0, 0.40], atol=1e-15)
    np.testing.assert_allclose(T_w_m[:3, 0], [0.0, 1.0, 0.0], atol=1e-15)  # x_M along world +y
    np.testing.assert_allclose(T_w_m[:3, 2], [0.0, 0.0, 1.0], atol=1e-15)  # printed face up
    np.testing.assert_allclose(world.ugv_transform("a") @ board_on_top(0.40), T_w_m, atol=1e-15)


def test_robot_without_a_board_has_no_board_transform():
    world = World(WorldConfig(ugvs=(UGVConfig("a", board=None),)))
    assert world.board_transform("a") is None


def test_caterpillar_forward_camera_sees_the_back_board_of_the_leader():
    leader = UGVConfig("leader", (1.0, 0.0, 0.0), board=board_for_robot(0), board_mount=board_on_back(0.3, 0.23))
    follower = UGVConfig(
        "follower",
        (0.0, 0.0, 0.0),
        board=board_for_robot(1),
        cameras=(CameraMount("follower/front", camera_forward(0.3, 0.23)),),
    )
    world = World(WorldConfig(ugvs=(leader, follower)))
    assert world.camera_names == ("follower/front",)
    T_c_m = invert(world.camera_transform("follower/front")) @ world.board_transform("leader")
    # The board is straight ahead on the optical axis, 1 - 0.23 - 0.23 m away, facing the camera.
    np.testing.assert_allclose(T_c_m[:3, 3], [0.0, 0.0, 0.54], atol=1e-12)
    np.testing.assert_allclose(T_c_m[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)
    # Board y (up on the printed face) is image up (-y_C).
    np.testing.assert_allclose(T_c_m[:3, 1], [0.0, -1.0, 0.0], atol=1e-12)


def test_robot_camera_follows_the_robot():
    mount = CameraMount("a/front", camera_forward(0.3, 0.2))
    world = World(WorldConfig(ugvs=(UGVConfig("a", (0.5, 0.5, 0.0), cameras=(mount,), static=False),)))
    for _ in range(30):
        world.step({"a": (0.2, 0.0, 0.8)})
    x, y, yaw = world.ugv_pose("a")
    T_w_c = world.camera_transform("a/front")
    np.testing.assert_allclose(T_w_c[:3, 2], [math.cos(yaw), math.sin(yaw), 0.0], atol=1e-12)
    np.testing.assert_allclose(T_w_c[:3, 3], [x + 0.2 * math.cos(yaw), y + 0.2 * math.sin(yaw), 0.3], atol=1e-12)


def test_camera_names_list_robot_cameras_then_the_uav_camera():
    config = WorldConfig(
        ugvs=(UGVConfig("a", cameras=(CameraMount("a/front", camera_forward()),)),),
        uavs=(UAVConfig(camera_name="drone"),),
    )
    assert World(config).camera_names == ("a/front", "drone")


def test_mount_helpers_build_the_documented_transforms():
    T = board_on_back(0.3, 0.25)
    np.testing.assert_array_equal(T[:3, :3], R_BODY_BOARD_BACK)
    np.testing.assert_array_equal(T[:3, 3], [-0.25, 0.0, 0.3])
    np.testing.assert_array_equal(T[:3, 2], [-1.0, 0.0, 0.0])  # printed face looks backward
    T = camera_forward(0.3, 0.2)
    np.testing.assert_array_equal(T[:3, :3], R_BODY_CAM_FORWARD)
    np.testing.assert_array_equal(T[:3, 3], [0.2, 0.0, 0.3])
    np.testing.assert_array_equal(camera_down()[:3, 3], [0.0, 0.0, -0.05])
    np.testing.assert_array_equal(camera_down()[:3, 2], [0.0, 0.0, -1.0])
    np.testing.assert_array_equal(UAVConfig().camera_mount, camera_down())
    with pytest.raises(ConfigError, match="board_on_top.height"):
        board_on_top(-0.1)
    with pytest.raises(ConfigError, match="board_on_back.offset"):
        board_on_back(0.3, float("nan"))
