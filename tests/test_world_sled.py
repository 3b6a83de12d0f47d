"""The single-robot caterpillar's sled: configuration, rope and pulley, board, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_BOARD_FRONT, R_BODY_CAM_BACKWARD, invert
from moma_env.markers import BoardLayout, board_for_robot
from moma_env.world import (
    COLLISION_SLOP,
    ArenaConfig,
    BoxObstacle,
    CameraMount,
    SledConfig,
    UAVConfig,
    UGVConfig,
    World,
    WorldConfig,
    board_on_front,
    camera_backward,
    friction_lever,
    world_config_from_mapping,
)
from moma_env.world.arena import box_inside_rectangle, boxes_overlap

RADIUS = 0.225  # default robot radius
HALF = 0.15  # half the default sled length
#: Room behind a robot at the origin for a sled at the end of the longest rope.
ARENA = ArenaConfig(width=8.0, height=6.0, origin=(-3.5, -3.0))


def sled_x(rope: float) -> float:
    """Sled centre x that puts the anchors (robot back, sled front) ``rope`` m apart, robot at the origin."""
    return -(RADIUS + rope + HALF)


def towing_config(robot_static: bool = False, sled_static: bool = True, rope: float = 0.6, **sled) -> WorldConfig:
    """Robot "a" at the origin facing +x with a backward camera; sled "sled" behind it, rope taut."""
    sled.setdefault("initial_pose", (sled_x(rope), 0.0, 0.0))
    sled.setdefault("rope_length", rope)
    robot = UGVConfig(
        "a",
        (0.0, 0.0, 0.0),
        static=robot_static,
        board=board_for_robot(0),
        cameras=(CameraMount("a/back", camera_backward(0.30, 0.23)),),
    )
    return WorldConfig(arena=ARENA, ugvs=(robot,), sleds=(SledConfig("sled", "a", static=sled_static, **sled),))


def anchor_distance(world: World) -> float:
    sled = world.config.sled("sled")
    return sled.anchor_distance(world.ugv_pose("a"), world.sled_pose("sled"))


#: How far a rope snapping taut may overshoot: one 10 ms substep of the robot anchor's
#: fastest travel (max_speed + max_yaw_rate * radius), as a robot may sink into a wall.
SNAP = (0.5 + 1.5 * RADIUS) * 0.01


def field_of(excinfo: pytest.ExceptionInfo[ConfigError]) -> str:
    return excinfo.value.field


# -- static sled: the rope pays out, up to a leash ----------------------------------------


def test_static_sled_holds_still_while_the_rope_pays_out_up_to_the_leash():
    world = World(towing_config())
    pose, transform = world.sled_pose("sled"), world.sled_transform("sled")
    assert world.is_static("sled") and not world.is_static("a")
    assert world.rope_length("sled") == 0.6
    lengths = []
    for _ in range(150):  # 6 s at 0.3 m/s: the robot would go 1.8 m without the leash
        world.step({"a": (0.3, 0.0, 0.0)})
        assert world.sled_pose("sled") == pose
        lengths.append(world.rope_length("sled"))
        if lengths[-1] < 1.5:
            assert lengths[-1] == pytest.approx(anchor_distance(world), abs=1e-12)
    np.testing.assert_array_equal(world.sled_transform("sled"), transform)
    assert np.all(np.diff(lengths) >= 0.0) and lengths[40] > 0.9  # paid out as the robot drove
    assert world.rope_length("sled") == 1.5
    x, y, yaw = world.ugv_pose("a")
    # Held at max_rope: centres at most max_rope + both anchor offsets apart.
    assert math.hypot(x - pose[0], y - pose[1]) <= 1.5 + RADIUS + HALF + COLLISION_SLOP
    assert x == pytest.approx(1.5 - 0.6, abs=COLLISION_SLOP)
    assert world.ugv_body_velocity("a")[0] == pytest.approx(0.0, abs=1e-6)
    # Driving back does not shorten the rope (it lies slack on the floor).
    for _ in range(25):
        world.step({"a": (-0.3, 0.0, 0.0)})
    assert world.rope_length("sled") == 1.5 and anchor_distance(world) < 1.3
    assert world.sled_pose("sled") == pose


@settings(max_examples=15, deadline=None)
@given(
    vx=st.floats(-0.5, 0.5),
    vy=st.floats(-0.5, 0.5),
    omega=st.floats(-1.5, 1.5),
)
def test_the_leash_holds_whatever_the_robot_does(vx, vy, omega):
    world = World(towing_config(rope=1.2))
    for _ in range(100):
        world.step({"a": (vx, vy, omega)})
        assert anchor_distance(world) <= 1.5 + SNAP
        assert world.rope_length("sled") <= 1.5
    for _ in range(25):
        world.step({"a": (0.0, 0.0, 0.0)})  # braking: the rope settles
    assert anchor_distance(world) <= 1.5 + COLLISION_SLOP
    assert world.sled_pose("sled") == world.config.sled("sled").initial_pose


# -- mobile sled: reel in, let out, hold --------------------------------------------------


def test_reel_in_with_the_robot_static_pulls_the_sled_to_min_rope():
    world = World(towing_config(robot_static=True, sled_static=False, rope=1.5))
    robot = world.ugv_pose("a")
    world.set_reel("sled", 1.0)
    assert world.reel_rate("sled") == 1.0
    per_step = 0.15 * world.dt  # reel_speed * dt
    xs = [world.sled_pose("sled")[0]]
    for k in range(1, 192):  # (1.5 - 0.35) / 0.006 = 191.7 steps
        world.step()
        assert world.rope_length("sled") == pytest.approx(1.5 - k * per_step, abs=1e-12)
        assert world.ugv_pose("a") == robot
        xs.append(world.sled_pose("sled")[0])
        # The taut rope drags the sled along: it lags the rope's end by one substep of reel.
        assert anchor_distance(world) - world.rope_length("sled") == pytest.approx(per_step / 4, abs=1e-6)
    assert np.all(np.diff(xs) > 0.0)  # towards the robot, every step
    for _ in range(50):
        world.step()
    assert world.rope_length("sled") == 0.35
    assert world.ugv_pose("a") == robot and world.is_static("a")
    # The sled slid a few millimetres past min_rope (friction stops it), rope slack.
    assert 0.35 - 0.01 < anchor_distance(world) <= 0.35 + 1e-9
    x, y, yaw = world.sled_pose("sled")
    assert x == pytest.approx(sled_x(0.35), abs=0.01) and y == pytest.approx(0.0, abs=1e-9)
    assert yaw == pytest.approx(0.0, abs=1e-9)
    stopped = world.sled_pose("sled")
    world.step()
    assert world.sled_pose("sled") == pytest.approx(stopped, abs=1e-12)


def test_reel_in_off_axis_ends_min_rope_behind_the_anchor_trailing_the_rope():
    start = (-1.2, 0.8, 0.3)
    world = World(towing_config(robot_static=True, sled_static=False, rope=1.5, initial_pose=start))
    robot_anchor = np.array([-RADIUS, 0.0])

    def rope_direction() -> np.ndarray:
        x, y, yaw = world.sled_pose("sled")
        d = np.array([x + HALF * math.cos(yaw), y + HALF * math.sin(yaw)]) - robot_anchor
        return d / np.linalg.norm(d)

    first = rope_direction()
    world.set_reel("sled", 1.0)
    for _ in range(400):
        world.step()
    assert world.rope_length("sled") == 0.35
    assert 0.35 - 0.01 < anchor_distance(world) <= 0.35 + 1e-9
    last = rope_direction()
    # The sled swung round to trail the rope, front first, as it was pulled in.
    yaw = world.sled_pose("sled")[2]
    assert abs(math.remainder(yaw - math.atan2(-last[1], -last[0]), 2 * math.pi)) < 1e-3
    assert abs(yaw - start[2]) > 0.5
    assert math.acos(float(first @ last)) < 0.25  # roughly where the rope first lay


def test_rate_zero_holds_the_length_and_letting_out_leaves_the_sled_in_place():
    world = World(towing_config(robot_static=True, sled_static=False, rope=0.6))
    pose = world.sled_pose("sled")
    for _ in range(20):
        world.step()
        assert world.rope_length("sled") == 0.6
    world.set_reel("sled", -0.5)
    for k in range(1, 21):
        world.step()
        assert world.rope_length("sled") == pytest.approx(0.6 + k * 0.5 * 0.15 * world.dt, abs=1e-12)
    assert world.sled_pose("sled") == pose  # slack rope: nothing pulls the sled
    world.set_reel("sled", -1.0)
    for _ in range(300):
        world.step()
    assert world.rope_length("sled") == 1.5  # capped at max_rope
    world.set_reel("sled", 0.0)
    world.step()
    assert world.rope_length("sled") == 1.5 and world.sled_pose("sled") == pose


def test_a_taut_rope_drags_a_mobile_sled_and_friction_stops_it():
    world = World(towing_config(sled_static=False))
    for _ in range(50):
        world.step({"a": (0.3, 0.0, 0.0)})
    x, y, yaw = world.sled_pose("sled")
    assert world.rope_length("sled") == 0.6
    assert anchor_distance(world) == pytest.approx(0.6, abs=COLLISION_SLOP)
    assert x - sled_x(0.6) == pytest.approx(world.ugv_pose("a")[0], abs=COLLISION_SLOP)
    assert x - sled_x(0.6) > 0.5
    for _ in range(25):
        world.step({"a": (0.0, 0.0, 0.0)})
    stopped = world.sled_pose("sled")
    world.step()
    assert world.sled_pose("sled") == pytest.approx(stopped, abs=1e-12)
    # It slid on by at most v^2 / (2 friction_accel) after the robot braked.
    assert anchor_distance(world) > 0.6 - 0.3**2 / (2 * 2.0) - 1e-3


def test_a_static_sled_ignores_the_reel_until_released():
    world = World(towing_config(robot_static=True, rope=1.0))
    pose = world.sled_pose("sled")
    world.set_reel("sled", 1.0)
    for _ in range(10):
        world.step()
    assert world.rope_length("sled") == 1.0 and world.sled_pose("sled") == pose
    world.set_static("sled", False)  # the command persists across the switch
    world.step()
    assert world.rope_length("sled") == pytest.approx(1.0 - 0.15 * world.dt, abs=1e-12)
    assert world.sled_pose("sled")[0] > pose[0]


@pytest.mark.parametrize("rate", [float("nan"), float("inf"), -float("inf"), 1.01, -1.5, "in", None, True, [0.5]])
def test_invalid_reel_rates_raise_value_errors_naming_the_sled(rate):
    world = World(towing_config(sled_static=False))
    with pytest.raises(ValueError, match="sled 'sled'"):
        world.set_reel("sled", rate)
    assert world.reel_rate("sled") == 0.0


def test_reel_rates_at_the_limits_and_numpy_numbers_are_accepted():
    world = World(towing_config(sled_static=False))
    for rate in (1, -1, np.float32(0.25), np.int64(0)):
        world.set_reel("sled", rate)
        assert world.reel_rate("sled") == float(rate)
    with pytest.raises(KeyError, match="known sleds are \\['sled'\\]"):
        world.set_reel("a", 0.5)


# -- static switches of the robot and the sled --------------------------------------------


def test_robot_and_sled_both_static_then_released_stay_finite_and_leashed():
    world = World(towing_config(robot_static=True, sled_static=True))
    robot, sled = world.ugv_pose("a"), world.sled_pose("sled")
    for _ in range(10):
        world.step({"a": (0.3, 0.0, 0.0)})
    assert world.ugv_pose("a") == robot and world.sled_pose("sled") == sled
    assert np.isfinite(world.state_array()).all()
    world.set_static("a", False)
    for _ in range(150):
        world.step({"a": (0.4, 0.0, 0.0)})
    assert np.isfinite(world.state_array()).all()
    assert world.rope_length("sled") == 1.5 and anchor_distance(world) <= 1.5 + COLLISION_SLOP
    world.set_static("a", True)
    world.set_static("sled", False)
    world.set_static("sled", True)
    world.set_static("a", False)
    world.step({"a": (-0.3, 0.0, 0.0)})
    assert np.isfinite(world.state_array()).all() and world.sled_pose("sled") == sled


# -- collisions -----------------------------------------------------------------------------


def test_the_sled_collides_with_other_robots_but_not_with_its_own():
    b = UGVConfig("b", (sled_x(0.6) - 0.1, -1.0, math.pi / 2), static=False, board=board_for_robot(2))
    base = towing_config()
    world = World(WorldConfig(arena=ARENA, ugvs=base.ugvs + (b,), sleds=base.sleds))
    pose = world.sled_pose("sled")
    front = pose[0] + HALF
    own, other = False, False
    for _ in range(100):
        # Robot a backs over its own sled (stopping clear of b); b drives into the sled's side.
        back = -0.3 if world.ugv_pose("a")[0] > front + 0.05 else 0.0
        world.step({"a": (back, 0.0, 0.0), "b": (0.3, 0.0, 0.0)})
        own |= frozenset({"a", "sled"}) in world.collisions_since_last_step
        other |= frozenset({"b", "sled"}) in world.collisions_since_last_step
    assert other and not own
    assert world.ugv_pose("a")[0] - RADIUS < front - 0.1  # its disk lies over the sled
    assert world.ugv_pose("b")[1] == pytest.approx(-HALF - RADIUS, abs=2 * COLLISION_SLOP)  # stopped by the sled
    assert world.sled_pose("sled") == pose  # static: pushed, not moved


@pytest.mark.parametrize("robot_static", [True, False])
def test_the_rope_never_pulls_a_sled_through_an_obstacle(robot_static):
    base = towing_config(robot_static=robot_static, sled_static=False, rope=0.6)
    arena = ArenaConfig(width=8.0, height=6.0, origin=(-3.5, -3.0), obstacles=(BoxObstacle(-0.6, 0.0, 0.1, 0.6),))
    world = World(WorldConfig(arena=arena, ugvs=base.ugvs, sleds=base.sleds))
    world.set_reel("sled", 1.0)
    hit = False
    for _ in range(100):
        world.step()
        hit |= frozenset({"sled", "obstacle[0]"}) in world.collisions_since_last_step
        # At the impact the front sinks in by a few mm (a few substeps of travel) ...
        assert world.sled_pose("sled")[0] + HALF <= -0.65 + 0.01
    assert hit
    # ... then it rests against the box's face.
    assert world.sled_pose("sled")[0] + HALF == pytest.approx(-0.65, abs=COLLISION_SLOP + 1e-4)
    if robot_static:
        # The winch stalls: the rope waits, stretched by a few mm, above min_rope.
        assert world.ugv_pose("a") == (0.0, 0.0, 0.0)
        assert 0.4 < world.rope_length("sled") < anchor_distance(world) < world.rope_length("sled") + 0.01
    else:
        # A mobile robot is winched backwards towards its stuck sled.
        assert world.ugv_pose("a")[0] < -0.05
        assert world.rope_length("sled") == 0.35


def test_segment_queries_see_the_sled_unless_ignored():
    world = World(towing_config())
    row = (sled_x(0.6), -1.0), (sled_x(0.6), 1.0)
    assert world.segment_blocked(*row)
    assert not world.segment_blocked(*row, ignore={"sled"})
    assert world.segment_blocked((-0.2, -1.0), (-0.2, 1.0), ignore={"sled"})  # the robot
    with pytest.raises(KeyError, match="known sleds are \\['sled'\\]"):
        world.segment_blocked(*row, ignore={"sleigh"})


# -- queries, board and camera -------------------------------------------------------------


def test_device_queries_accept_sled_names():
    world = World(towing_config())
    assert world.sled_names == ("sled",) and world.ugv_names == ("a",)
    assert world.is_static("sled")
    world.set_static("sled", False)
    assert not world.is_static("sled")
    world.set_static("sled", np.bool_(True))
    assert world.is_static("sled")
    with pytest.raises(TypeError):
        world.set_static("sled", 1)
    for query in (world.is_static, world.board_transform):
        with pytest.raises(KeyError, match="known ugvs are \\['a'\\], known sleds are \\['sled'\\]"):
            query("sleigh")
    for query in (world.sled_pose, world.sled_transform, world.rope_length, world.reel_rate):
        with pytest.raises(KeyError, match="unknown sled 'a'"):
            query("a")
    with pytest.raises(KeyError, match="unknown ugv 'sled'"):
        world.ugv_pose("sled")


def test_the_backward_camera_sees_the_front_board_of_the_sled():
    world = World(towing_config())
    T_w_m = world.board_transform("sled")
    np.testing.assert_allclose(T_w_m, world.sled_transform("sled") @ board_on_front(0.25, HALF), atol=1e-15)
    T_c_m = invert(world.camera_transform("a/back")) @ T_w_m
    assert T_c_m[2, 2] < 0.0  # board z (out of the printed face) points back at the camera
    assert T_c_m[2, 3] > 0.0  # in front of the camera
    # Straight behind on the optical axis, 5 cm below the camera (image y down).
    np.testing.assert_allclose(T_c_m[:3, 3], [0.0, 0.05, 0.6 + RADIUS - 0.23], atol=1e-12)
    np.testing.assert_allclose(T_c_m[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(T_c_m[:3, 1], [0.0, -1.0, 0.0], atol=1e-12)  # board up is image up
    # Still facing the camera after the robot dragged the sled around a bend.
    world.set_static("sled", False)
    for _ in range(60):
        world.step({"a": (0.3, 0.0, 0.4)})
    T_c_m = invert(world.camera_transform("a/back")) @ world.board_transform("sled")
    assert T_c_m[2, 2] < -0.5 and T_c_m[2, 3] > 0.3


def test_mount_helpers_for_the_sled_build_the_documented_transforms():
    T = camera_backward(0.3, 0.2)
    np.testing.assert_array_equal(T[:3, :3], R_BODY_CAM_BACKWARD)
    np.testing.assert_array_equal(T[:3, 3], [-0.2, 0.0, 0.3])
    np.testing.assert_array_equal(T[:3, 2], [-1.0, 0.0, 0.0])  # optical axis backward
    T = board_on_front(0.25, 0.15)
    np.testing.assert_array_equal(T[:3, :3], R_BODY_BOARD_FRONT)
    np.testing.assert_array_equal(T[:3, 3], [0.15, 0.0, 0.25])
    np.testing.assert_array_equal(T[:3, 2], [1.0, 0.0, 0.0])  # printed face forward
    np.testing.assert_array_equal(SledConfig(robot="a").board_mount, board_on_front(0.25, 0.15))
    np.testing.assert_array_equal(SledConfig(robot="a", size=(0.5, 0.3)).board_mount, board_on_front(0.25, 0.25))
    with pytest.raises(ConfigError, match="camera_backward.height"):
        camera_backward(-0.1)
    with pytest.raises(ConfigError, match="board_on_front.offset"):
        board_on_front(0.25, float("nan"))


# -- configuration ---------------------------------------------------------------------------


def test_sled_defaults_and_resolved_anchors():
    sled = SledConfig(robot="a")
    assert (sled.name, sled.size, sled.mass, sled.friction_accel) == ("sled", (0.3, 0.3), 3.0, 2.0)
    assert (sled.rope_length, sled.min_rope, sled.max_rope, sled.reel_speed) == (0.6, 0.35, 1.5, 0.15)
    assert sled.max_tension == 2000.0
    assert sled.static and sled.board == board_for_robot(1) and sled.board_height == 0.25
    assert sled.robot_anchor is None and sled.sled_anchor == (0.15, 0.0)
    assert sled.moment == pytest.approx(3.0 * 0.18 / 12)
    config = WorldConfig(ugvs=(UGVConfig("a", radius=0.3),), sleds=(SledConfig(robot="a", initial_pose=(-1.1, 0, 0)),))
    assert config.sleds[0].robot_anchor == (-0.3, 0.0)
    assert config.sled("sled") is config.sleds[0] and config.sled_names == ("sled",)
    with pytest.raises(KeyError, match="unknown sled 'x'"):
        config.sled("x")
    custom = WorldConfig(
        ugvs=(UGVConfig("a"),), sleds=(SledConfig(robot="a", initial_pose=(-1.1, 0, 0), robot_anchor=(-0.1, 0.05)),)
    )
    assert custom.sleds[0].robot_anchor == (-0.1, 0.05)
    assert WorldConfig(ugvs=(UGVConfig("a"),)).sleds == ()


def test_a_sled_starting_beyond_its_rope_starts_with_the_rope_taut():
    world = World(towing_config(rope=0.9, rope_length=0.5))
    assert world.config.sleds[0].rope_length == 0.5
    assert world.rope_length("sled") == pytest.approx(0.9, abs=1e-12)
    world = World(towing_config(rope=0.4, rope_length=0.5))  # closer: the rope starts slack
    assert world.rope_length("sled") == 0.5


def one_sled(**sled) -> WorldConfig:
    sled.setdefault("robot", "a")
    sled.setdefault("initial_pose", (sled_x(0.6), 0.0, 0.0))
    robot = UGVConfig("a", cameras=(CameraMount("cam", camera_backward()),))
    return WorldConfig(arena=ARENA, ugvs=(robot,), sleds=(SledConfig(**sled),))


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: SledConfig(robot=""), "sled.robot"),
        (lambda: SledConfig(""), "sled.name"),
        (lambda: SledConfig("wall", "a"), "sled.name"),
        (lambda: SledConfig(robot="a", initial_pose=(0.0, float("nan"), 0.0)), "sled.initial_pose.y"),
        (lambda: SledConfig(robot="a", size=(-0.3, 0.3)), "sled.size.x"),
        (lambda: SledConfig(robot="a", size=(0.3,)), "sled.size"),
        (lambda: SledConfig(robot="a", mass=0.0), "sled.mass"),
        (lambda: SledConfig(robot="a", friction_accel=-1.0), "sled.friction_accel"),
        (lambda: SledConfig(robot="a", board=None), "sled.board"),
        (lambda: SledConfig(robot="a", board_mount=np.eye(3)), "sled.board_mount"),
        (lambda: SledConfig(robot="a", min_rope=0.0), "sled.min_rope"),
        (lambda: SledConfig(robot="a", min_rope=0.8, max_rope=0.7, rope_length=0.75), "sled.max_rope"),
        (lambda: SledConfig(robot="a", rope_length=1.6), "sled.rope_length"),
        (lambda: SledConfig(robot="a", rope_length=0.3), "sled.rope_length"),
        (lambda: SledConfig(robot="a", reel_speed=0.0), "sled.reel_speed"),
        (lambda: SledConfig(robot="a", max_tension=float("inf")), "sled.max_tension"),
        (lambda: SledConfig(robot="a", robot_anchor=(0.0, float("inf"))), "sled.robot_anchor.y"),
        (lambda: SledConfig(robot="a", sled_anchor=(0.0,)), "sled.sled_anchor"),
        (lambda: SledConfig(robot="a", static=1), "sled.static"),
        (lambda: one_sled(robot="b"), "sleds[0].robot"),
        (lambda: one_sled(name="a"), "sleds[0].name"),
        (lambda: one_sled(name="cam"), "sleds[0].name"),
        (lambda: one_sled(board=board_for_robot(0)), "sleds[0].board.marker_ids"),
        (lambda: one_sled(board=BoardLayout(marker_ids=(7, 8, 9, 3))), "sleds[0].board.marker_ids"),
        (lambda: one_sled(initial_pose=(-0.3, 0.0, 0.0)), "sleds[0].initial_pose"),
        (lambda: one_sled(initial_pose=(-3.45, 0.0, 0.3)), "sleds[0].initial_pose"),
        (lambda: one_sled(initial_pose=(sled_x(1.51), 0.0, 0.0)), "sleds[0].initial_pose"),
        (lambda: WorldConfig(ugvs=(UGVConfig("a"),), sleds=(UGVConfig("b", (1, 1, 0)),)), "sleds[0]"),
        (lambda: WorldConfig(sleds=3), "sleds"),
        (lambda: WorldConfig(ugvs=(UGVConfig("a"),), sleds=(SledConfig(robot="a", initial_pose=(-1, 0, 0)),),
                             uavs=(UAVConfig(name="sled"),)), "uavs[0].name"),
    ],
)
def test_bad_sled_values_name_their_field(make, field):
    with pytest.raises(ConfigError) as excinfo:
        make()
    assert field_of(excinfo) == field


def test_sled_placement_checks_the_arena_the_rope_obstacles_robots_and_other_sleds():
    with pytest.raises(ConfigError, match="not inside the arena"):
        one_sled(initial_pose=(-3.45, 0.0, 0.3))
    with pytest.raises(ConfigError, match="beyond max_rope=1.5"):
        one_sled(initial_pose=(sled_x(1.51), 0.0, 0.0))
    one_sled(initial_pose=(sled_x(1.5), 0.0, 0.0))
    robots = (UGVConfig("a"), UGVConfig("b", (0.0, 1.0, 0.0), board=board_for_robot(2)))
    sled_a = SledConfig("sa", "a", (sled_x(0.6), 0.0, 0.0))
    with pytest.raises(ConfigError, match="overlaps arena.obstacles\\[0\\]") as excinfo:
        WorldConfig(arena=ArenaConfig(obstacles=(BoxObstacle(-1.2, 0.2, 0.3, 0.3, 0.5),)), ugvs=robots, sleds=(sled_a,))
    assert field_of(excinfo) == "sleds[0].initial_pose"
    with pytest.raises(ConfigError, match="overlaps ugvs\\[1\\]") as excinfo:
        WorldConfig(ugvs=robots, sleds=(SledConfig("sa", "a", (-0.1, 0.7, 0.0), rope_length=0.35),))
    assert field_of(excinfo) == "sleds[0].initial_pose"
    sled_b = SledConfig("sb", "b", (sled_x(0.6) + 0.1, 0.25, 0.0), board=board_for_robot(3))
    with pytest.raises(ConfigError, match="overlaps sleds\\[0\\]") as excinfo:
        WorldConfig(ugvs=robots, sleds=(sled_a, sled_b))
    assert field_of(excinfo) == "sleds[1].initial_pose"
    behind_b = (sled_x(0.6), 1.0, 0.0)
    with pytest.raises(ConfigError, match="already tows") as excinfo:
        WorldConfig(ugvs=robots, sleds=(sled_a, SledConfig("sb", "a", behind_b, board=board_for_robot(3))))
    assert field_of(excinfo) == "sleds[1].robot"
    # Touching is fine; so is a second sled on another robot.
    WorldConfig(ugvs=robots, sleds=(sled_a, SledConfig("sb", "b", behind_b, board=board_for_robot(3))))
    WorldConfig(ugvs=robots, sleds=(SledConfig("sa", "a", (-RADIUS - HALF, 0.0, 0.0), rope_length=0.35),))


def test_sleds_from_mappings_carry_the_full_path_and_match_python():
    base = {"ugvs": [{"name": "a", "static": False}]}
    sled = {"name": "sled", "robot": "a", "initial_pose": [sled_x(0.6), 0.0, 0.0]}
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({**base, "sleds": [{**sled, "max_rope": 0.2}]})
    assert field_of(excinfo) == "sleds[0].max_rope"
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({**base, "sleds": [{**sled, "board": {"marker_ids": [4, 5, 6, 6]}}]})
    assert field_of(excinfo) == "sleds[0].board.marker_ids"
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({**base, "sleds": [{**sled, "rope": 1.0}]})
    assert field_of(excinfo) == "sleds[0].rope"
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({**base, "sleds": {"name": "sled"}})
    assert field_of(excinfo) == "sleds"
    built = world_config_from_mapping({**base, "sleds": [{**sled, "board": {"marker_ids": [8, 9, 10, 11]}}]})
    expected = WorldConfig(
        ugvs=(UGVConfig("a", static=False),),
        sleds=(SledConfig("sled", "a", (sled_x(0.6), 0.0, 0.0), board=board_for_robot(2)),),
    )
    assert built == expected and hash(built.sleds[0]) == hash(expected.sleds[0])
    assert SledConfig(robot="a", board_mount=board_on_front(0.3)) != SledConfig(robot="a")


# -- geometry helpers -------------------------------------------------------------------------


@pytest.mark.parametrize("size", [(0.3, 0.3), (0.6, 0.2), (0.1, 0.5)])
def test_friction_lever_is_the_mean_distance_from_the_centre(size):
    n = 400
    xs = (np.arange(n) + 0.5) / n - 0.5
    gx, gy = np.meshgrid(xs * size[0], xs * size[1])
    assert friction_lever(*size) == pytest.approx(float(np.hypot(gx, gy).mean()), rel=1e-4)
    assert friction_lever(0.3, 0.3) == pytest.approx(0.3 * (math.sqrt(2) + math.asinh(1)) / 6, rel=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(-1.0, 1.0),
    y=st.floats(-1.0, 1.0),
    yaw_a=st.floats(-math.pi, math.pi),
    yaw_b=st.floats(-math.pi, math.pi),
)
def test_box_overlap_agrees_with_point_sampling(x, y, yaw_a, yaw_b):
    a, b = BoxObstacle(0.0, 0.0, 0.6, 0.3, yaw_a), BoxObstacle(x, y, 0.4, 0.2, yaw_b)
    assert boxes_overlap(a, b) == boxes_overlap(b, a)
    # Sample b's interior; any sample strictly inside a proves an overlap.
    u, v = np.meshgrid(np.linspace(-0.199, 0.199, 41), np.linspace(-0.099, 0.099, 21))
    cb, sb = math.cos(yaw_b), math.sin(yaw_b)
    px, py = x + cb * u - sb * v, y + sb * u + cb * v
    ca, sa = math.cos(yaw_a), math.sin(yaw_a)
    lx, ly = ca * px + sa * py, -sa * px + ca * py
    sampled = bool(np.any((np.abs(lx) < 0.3) & (np.abs(ly) < 0.15)))
    if sampled:
        assert boxes_overlap(a, b)
    # Far apart boxes (farther than the sum of the half diagonals) never overlap.
    if math.hypot(x, y) > math.hypot(0.3, 0.15) + math.hypot(0.2, 0.1):
        assert not boxes_overlap(a, b)


def test_box_inside_rectangle_allows_touching():
    bounds = (0.0, 0.0, 1.0, 1.0)
    assert box_inside_rectangle(BoxObstacle(0.15, 0.5, 0.3, 0.3), bounds)
    assert not box_inside_rectangle(BoxObstacle(0.15, 0.5, 0.3, 0.3, math.pi / 4), bounds)
    assert not boxes_overlap(BoxObstacle(0.0, 0.0, 1.0, 1.0), BoxObstacle(1.0, 0.0, 1.0, 1.0))


# -- whole state ---------------------------------------------------------------------------------


def scripted_run(world: World, steps: int = 200) -> np.ndarray:
    states = []
    for k in range(steps):
        if k == 60:
            world.set_static("a", True)
            world.set_static("sled", False)
            world.set_reel("sled", 0.8)
        if k == 140:
            world.set_static("a", False)
            world.set_reel("sled", -0.3)
        world.step({"a": (0.4, 0.1 * math.sin(0.1 * k), 0.3)})
        states.append(world.state_array())
    return np.array(states)


def test_determinism_two_identical_worlds_with_sleds():
    config = towing_config(rope=0.8)
    first, second = World(config), World(config)
    run_a, run_b = scripted_run(first), scripted_run(second)
    np.testing.assert_array_equal(run_a, run_b)
    assert run_a.shape == (200, 6 + 7)
    assert 0.8 < run_a[0, 12] < run_a[59, 12] - 0.2  # paid out while static
    assert run_a[139, 12] < run_a[59, 12] - 0.3  # reeled in while mobile
    assert not np.array_equal(run_a[59, 6:12], run_a[139, 6:12])  # and the sled moved
    assert run_a[-1, 12] == first.rope_length("sled")
    first.reset(np.random.default_rng(0))
    assert first.is_static("sled") and first.rope_length("sled") == 0.8 and first.reel_rate("sled") == 0.0
    np.testing.assert_array_equal(scripted_run(first), run_a)
