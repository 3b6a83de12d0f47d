"""Configuration of the world: validation errors name the field; lookups list names."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.config import ConfigError
from moma_env.geometry import make_transform, rot_z
from moma_env.markers import BoardLayout, board_for_robot
from moma_env.world import (
    ArenaConfig,
    BoxObstacle,
    CameraMount,
    UAVConfig,
    UGVConfig,
    World,
    WorldConfig,
    board_on_top,
    camera_forward,
    world_config_from_mapping,
)


def two_robots(**second) -> WorldConfig:
    kwargs = {"name": "b", "initial_pose": (1.0, 0.0, 0.0), "board": board_for_robot(1)}
    kwargs.update(second)
    return WorldConfig(ugvs=(UGVConfig("a"), UGVConfig(**kwargs)))


def field_of(excinfo: pytest.ExceptionInfo[ConfigError]) -> str:
    return excinfo.value.field


def test_defaults_are_valid_and_follow_the_paper():
    ugv = UGVConfig("a")
    assert ugv.radius == 0.225 and ugv.static
    assert ugv.board == BoardLayout(marker_ids=(0, 1, 2, 3))
    np.testing.assert_array_equal(ugv.board_mount, board_on_top(0.40))
    assert ugv.board_height == 0.40
    uav = UAVConfig()
    assert uav.kind == "quadcopter" and uav.altitude == 1.6
    config = WorldConfig(ugvs=(ugv,), uavs=(uav,))
    assert config.dt == pytest.approx(0.04)
    assert config.arena.bounds == (-1.5, -1.5, 4.5, 4.5)


def test_negative_radius_names_the_field():
    with pytest.raises(ConfigError) as excinfo:
        UGVConfig("a", radius=-0.1)
    assert field_of(excinfo) == "ugv.radius"


def test_mapping_errors_carry_the_full_path():
    mapping = {"ugvs": [{"name": "a"}, {"name": "b", "initial_pose": [1.0, 0.0, 0.0], "radius": -0.2}]}
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping(mapping)
    assert field_of(excinfo) == "ugvs[1].radius"
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({"ugvs": [{"name": "a", "wheels": 3}]})
    assert field_of(excinfo) == "ugvs[0].wheels"
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({"arena": {"obstacles": [{"x": 0, "y": 0, "width": 1, "height": 0}]}})
    assert field_of(excinfo) == "arena.obstacles[0].height"
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({"ugvs": [{"name": "a", "board": {"marker_ids": [0, 1, 2, 2]}}]})
    assert field_of(excinfo) == "ugvs[0].board.marker_ids"


def test_mapping_builds_the_same_config_as_python():
    mapping = {
        "arena": {"width": 4.0, "obstacles": [{"x": 2.0, "y": 2.0, "width": 0.5, "height": 0.5}]},
        "ugvs": [
            {"name": "a", "static": False},
            {"name": "b", "initial_pose": [1.0, 0.0, 0.0], "board": {"marker_ids": [4, 5, 6, 7]},
             "cameras": [{"name": "b/front", "T_b_c": camera_forward().tolist()}]},
        ],
        "uav": {"kind": "handheld", "altitude": 1.2},
        "control_hz": 30.0,
    }
    expected = WorldConfig(
        arena=ArenaConfig(width=4.0, obstacles=(BoxObstacle(2.0, 2.0, 0.5, 0.5),)),
        ugvs=(
            UGVConfig("a", static=False),
            UGVConfig("b", (1.0, 0.0, 0.0), board=board_for_robot(1), cameras=(CameraMount("b/front", camera_forward()),)),
        ),
        uavs=(UAVConfig.handheld(altitude=1.2),),
        control_hz=30.0,
    )
    assert world_config_from_mapping(mapping) == expected


def test_configs_compare_and_hash_by_value():
    a = UGVConfig("a", board_mount=board_on_top(0.5))
    b = UGVConfig("a", board_mount=board_on_top(0.5).tolist())
    c = UGVConfig("a", board_mount=board_on_top(0.6))
    assert a == b and hash(a) == hash(b)
    assert a != c
    assert not a.board_mount.flags.writeable


def test_robots_overlapping_at_start_are_rejected():
    with pytest.raises(ConfigError, match="overlaps ugvs\\[0\\]") as excinfo:
        two_robots(initial_pose=(0.3, 0.0, 0.0))
    assert field_of(excinfo) == "ugvs[1].initial_pose"
    # Touching is allowed.
    two_robots(initial_pose=(0.45, 0.0, 0.0))


def test_robot_in_a_wall_or_an_obstacle_is_rejected():
    with pytest.raises(ConfigError, match="not inside the arena") as excinfo:
        WorldConfig(ugvs=(UGVConfig("a", (4.4, 0.0, 0.0)),))
    assert field_of(excinfo) == "ugvs[0].initial_pose"
    arena = ArenaConfig(obstacles=(BoxObstacle(1.0, 0.0, 0.4, 0.4, yaw=math.pi / 4),))
    with pytest.raises(ConfigError, match="obstacles\\[0\\]") as excinfo:
        WorldConfig(arena=arena, ugvs=(UGVConfig("a", (0.6, 0.0, 0.0)),))
    assert field_of(excinfo) == "ugvs[0].initial_pose"
    # Clear of the rotated box (its corner reaches x = 1 - 0.2*sqrt(2) = 0.717).
    WorldConfig(arena=arena, ugvs=(UGVConfig("a", (0.717 - 0.226, 0.0, 0.0)),))


def test_duplicate_names_are_rejected():
    with pytest.raises(ConfigError, match="duplicate name 'a'") as excinfo:
        two_robots(name="a")
    assert field_of(excinfo) == "ugvs[1].name"
    with pytest.raises(ConfigError) as excinfo:
        WorldConfig(ugvs=(UGVConfig("uav"),), uavs=(UAVConfig(),))
    assert field_of(excinfo) == "uavs[0].name"
    cam = CameraMount("cam", camera_forward())
    with pytest.raises(ConfigError) as excinfo:
        WorldConfig(
            ugvs=(UGVConfig("a", cameras=(cam,)), UGVConfig("b", (1.0, 0.0, 0.0), board=board_for_robot(1), cameras=(cam,)))
        )
    assert field_of(excinfo) == "ugvs[1].cameras[0].name"
    with pytest.raises(ConfigError) as excinfo:
        WorldConfig(ugvs=(UGVConfig("a", cameras=(CameraMount("uav/camera", camera_forward()),)),), uavs=(UAVConfig(),))
    assert field_of(excinfo) == "uavs[0].camera_name"


def test_colliding_marker_ids_are_rejected():
    with pytest.raises(ConfigError, match="marker id 0") as excinfo:
        WorldConfig(ugvs=(UGVConfig("a"), UGVConfig("b", (1.0, 0.0, 0.0))))
    assert field_of(excinfo) == "ugvs[1].board.marker_ids"
    with pytest.raises(ConfigError, match="marker id 3") as excinfo:
        two_robots(board=BoardLayout(marker_ids=(3, 4, 5, 6)))
    assert field_of(excinfo) == "ugvs[1].board.marker_ids"
    # The same id in another dictionary is a different marker; no board is fine too.
    two_robots(board=BoardLayout(dictionary="DICT_5X5_100"))
    two_robots(board=None)


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: UGVConfig("a", initial_pose=(float("nan"), 0.0, 0.0)), "ugv.initial_pose.x"),
        (lambda: UGVConfig("a", initial_pose=(0.0, 0.0)), "ugv.initial_pose"),
        (lambda: UGVConfig("a", max_speed=float("inf")), "ugv.max_speed"),
        (lambda: UGVConfig("a", mass=0.0), "ugv.mass"),
        (lambda: UGVConfig(""), "ugv.name"),
        (lambda: UGVConfig("wall"), "ugv.name"),
        (lambda: UGVConfig("a", static=1), "ugv.static"),
        (lambda: UGVConfig("a", board_mount=np.eye(3)), "ugv.board_mount"),
        (lambda: UGVConfig("a", board_mount=make_transform(2.0 * rot_z(0.3))), "ugv.board_mount"),
        (lambda: UGVConfig("a", board_mount=make_transform(np.diag([1.0, 1.0, -1.0]))), "ugv.board_mount"),
        (lambda: UGVConfig("a", cameras=(np.eye(4),)), "ugv.cameras[0]"),
        (lambda: ArenaConfig(width=-1.0), "arena.width"),
        (lambda: ArenaConfig(origin=(0.0, float("inf"))), "arena.origin.y"),
        (lambda: ArenaConfig(wall_thickness=0.0), "arena.wall_thickness"),
        (lambda: ArenaConfig(obstacles=((1, 1, 1, 1),)), "arena.obstacles[0]"),
        (lambda: BoxObstacle(0.0, 0.0, -1.0, 1.0), "obstacle.width"),
        (lambda: UAVConfig(altitude=5.0), "uav.altitude"),
        (lambda: UAVConfig(min_altitude=2.0, max_altitude=1.0, altitude=1.5), "uav.max_altitude"),
        (lambda: UAVConfig(kind="blimp"), "uav.kind"),
        (lambda: UAVConfig(max_tilt_deg=90.0), "uav.max_tilt_deg"),
        (lambda: UAVConfig(response_time=-0.1), "uav.response_time"),
        (lambda: WorldConfig(control_hz=0.0), "control_hz"),
        (lambda: WorldConfig(substeps=0), "substeps"),
        (lambda: WorldConfig(substeps=2.0), "substeps"),
        (lambda: WorldConfig(ugvs=("a",)), "ugvs[0]"),
    ],
)
def test_bad_values_name_their_field(make, field):
    with pytest.raises(ConfigError) as excinfo:
        make()
    assert field_of(excinfo) == field


def test_handheld_defaults_and_overrides():
    hand = UAVConfig.handheld()
    assert hand.kind == "handheld"
    assert (hand.response_time, hand.max_accel, hand.tilt_gain, hand.tilt_time_constant) == (0.8, 0.5, 0.2, 0.5)
    assert UAVConfig.handheld(max_accel=0.7).max_accel == 0.7
    assert UAVConfig().max_tilt == pytest.approx(math.radians(20.0))


def test_unknown_names_raise_key_errors_listing_known_names():
    config = two_robots()
    assert config.ugv("b").name == "b" and config.ugv_index("b") == 1
    with pytest.raises(KeyError, match="'a', 'b'"):
        config.ugv("c")
    world = World(config)
    for query in (world.ugv_pose, world.ugv_transform, world.board_transform, world.is_static, world.ugv_body_velocity):
        with pytest.raises(KeyError, match="known ugvs are \\['a', 'b'\\]"):
            query("c")
    with pytest.raises(KeyError, match="known cameras are \\[\\]"):
        world.camera_transform("c")
    with pytest.raises(KeyError, match="unknown ugv 'c'"):
        world.step({"c": (0.0, 0.0, 0.0)})


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(-1.0, 2.0),
    y=st.floats(-1.0, 2.0),
    r=st.floats(0.05, 0.4),
)
def test_overlap_check_matches_the_distance_between_robots(x, y, r):
    gap = math.hypot(x, y) - 0.225 - r
    ugvs = (UGVConfig("a"), UGVConfig("b", (x, y, 0.0), radius=r, board=board_for_robot(1)))
    if gap < -1e-6:
        with pytest.raises(ConfigError):
            WorldConfig(ugvs=ugvs)
    elif gap > 1e-6:
        WorldConfig(ugvs=ugvs)
