"""Ground robots in the pymunk world: motion, limits, collisions, static lock, queries."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.markers import board_for_robot
from moma_env.world import (
    COLLISION_SLOP,
    ArenaConfig,
    BoxObstacle,
    UAVConfig,
    UGVConfig,
    World,
    WorldConfig,
)


def robot(name: str, pose=(0.0, 0.0, 0.0), index: int = 0, **kw) -> UGVConfig:
    kw.setdefault("static", False)
    if "board" not in kw:
        kw["board"] = board_for_robot(index)
    return UGVConfig(name, pose, **kw)


def one_robot_world(pose=(0.0, 0.0, 0.0), arena: ArenaConfig | None = None, **kw) -> World:
    return World(WorldConfig(arena=arena or ArenaConfig(), ugvs=(robot("a", pose, **kw),)))


def drive(world: World, commands, steps: int) -> None:
    for _ in range(steps):
        world.step(commands)


def test_forward_moves_along_the_heading_and_left_along_body_y():
    yaw = 0.7
    world = one_robot_world((0.0, 0.0, yaw))
    drive(world, {"a": (0.3, 0.0, 0.0)}, 50)
    x, y, heading = world.ugv_pose("a")
    assert math.hypot(x, y) > 0.4
    assert math.atan2(y, x) == pytest.approx(yaw, abs=1e-9)
    assert heading == pytest.approx(yaw, abs=1e-12)

    world = one_robot_world((0.0, 0.0, yaw))
    drive(world, {"a": (0.0, 0.3, 0.0)}, 50)
    x, y, _ = world.ugv_pose("a")
    assert math.hypot(x, y) > 0.4
    assert math.atan2(y, x) == pytest.approx(yaw + math.pi / 2, abs=1e-9)


def test_rotation_command_turns_counter_clockwise_and_arcs_are_circles():
    world = one_robot_world((0.0, 0.0, 0.0))
    drive(world, {"a": (0.3, 0.0, 0.6)}, 25)  # past the acceleration phase
    points = []
    for _ in range(100):
        world.step({"a": (0.3, 0.0, 0.6)})
        points.append(world.ugv_pose("a")[:2])
    xy = np.array(points)
    # Least-squares circle x^2 + y^2 + D x + E y + F = 0 through the steady arc.
    A = np.column_stack([xy, np.ones(len(xy))])
    (D, E, F), *_ = np.linalg.lstsq(A, -(xy**2).sum(axis=1), rcond=None)
    centre = np.array([-D / 2, -E / 2])
    radius = math.sqrt(centre @ centre - F)
    assert radius == pytest.approx(0.3 / 0.6, rel=1e-4)
    assert np.max(np.abs(np.linalg.norm(xy - centre, axis=1) - radius)) < 1e-5
    assert centre[1] > 0.45  # counter-clockwise: the centre is on the robot's left
    assert world.ugv_body_velocity("a") == pytest.approx((0.3, 0.0, 0.6), rel=1e-6)


@settings(max_examples=25, deadline=None)
@given(
    vx=st.floats(-3.0, 3.0),
    vy=st.floats(-3.0, 3.0),
    omega=st.floats(-5.0, 5.0),
)
def test_speed_acceleration_and_yaw_rate_limits_hold(vx, vy, omega):
    world = one_robot_world((1.5, 1.5, 0.0), max_speed=0.5, max_yaw_rate=1.5, max_accel=1.0, max_yaw_accel=3.0)
    velocity = np.zeros(3)  # world-frame (vx, vy, omega) of the pymunk body
    for _ in range(40):
        world.step({"a": (vx, vy, omega)})
        bvx, bvy, bomega = world.ugv_body_velocity("a")
        assert math.hypot(bvx, bvy) <= 0.5 + 1e-9
        assert abs(bomega) <= 1.5 + 1e-9
        new_velocity = world.state_array()[3:6]
        # Traction limits: velocity changes by at most max_accel * dt per step.
        assert math.hypot(*(new_velocity[:2] - velocity[:2])) <= 1.0 * world.dt + 1e-9
        assert abs(new_velocity[2] - velocity[2]) <= 3.0 * world.dt + 1e-9
        velocity = new_velocity
    expected_speed = min(math.hypot(vx, vy), 0.5)
    assert math.hypot(bvx, bvy) == pytest.approx(expected_speed, abs=1e-9)
    assert bomega == pytest.approx(min(max(omega, -1.5), 1.5), abs=1e-9)


def substep_travel(world: World, speed: float) -> float:
    """Distance (m) covered in one physics substep: the deepest a shape can go before contact."""
    return speed * world.dt / world.config.substeps


def test_a_robot_stops_at_a_wall_and_reports_the_contact():
    world = one_robot_world((3.5, 0.0, 0.0))
    contact_x = world.config.arena.bounds[2] - 0.225
    contacts = set()
    for _ in range(150):
        world.step({"a": (0.5, 0.0, 0.0)})
        contacts |= world.collisions_since_last_step
        assert world.ugv_pose("a")[0] <= contact_x + substep_travel(world, 0.5)
    assert 0.0 <= world.ugv_pose("a")[0] - contact_x <= COLLISION_SLOP + 1e-9
    assert contacts == {frozenset({"a", "wall"})}
    assert world.ugv_body_velocity("a") == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


def test_a_robot_is_stopped_by_an_obstacle():
    arena = ArenaConfig(obstacles=(BoxObstacle(1.5, 0.0, 0.4, 1.0),))
    world = one_robot_world((0.0, 0.0, 0.0), arena=arena)
    seen = set()
    for _ in range(150):
        world.step({"a": (0.5, 0.0, 0.0)})
        seen |= world.collisions_since_last_step
    assert 0.0 <= world.ugv_pose("a")[0] - (1.3 - 0.225) <= COLLISION_SLOP + 1e-9
    assert seen == {frozenset({"a", "obstacle[0]"})}


def test_two_robots_pushing_head_on_do_not_overlap():
    config = WorldConfig(ugvs=(robot("a", (0.0, 0.0, 0.0), 0), robot("b", (1.5, 0.0, math.pi), 1)))
    world = World(config)
    for _ in range(150):
        world.step({"a": (0.5, 0.0, 0.0), "b": (0.5, 0.0, 0.0)})
        (xa, _, _), (xb, _, _) = world.ugv_pose("a"), world.ugv_pose("b")
        assert xb - xa >= 0.45 - substep_travel(world, 1.0)
    assert frozenset({"a", "b"}) in world.collisions_since_last_step
    assert 0.0 <= 0.45 - (xb - xa) <= COLLISION_SLOP + 1e-9
    assert xa + xb == pytest.approx(1.5, abs=1e-9)  # equal robots, equal pushes


def test_an_off_centre_hit_deflects_both_robots():
    config = WorldConfig(ugvs=(robot("a", (0.0, 0.0, 0.0), 0), robot("b", (1.5, 0.05, math.pi), 1)))
    world = World(config)
    touched = False
    for _ in range(150):
        world.step({"a": (0.5, 0.0, 0.0), "b": (0.5, 0.0, 0.0)})
        (xa, ya, _), (xb, yb, _) = world.ugv_pose("a"), world.ugv_pose("b")
        assert math.hypot(xa - xb, ya - yb) >= 0.45 - substep_travel(world, 1.0)
        touched |= frozenset({"a", "b"}) in world.collisions_since_last_step
    assert touched
    assert ya < -0.05 and yb > 0.1  # pushed apart sideways
    assert xa > xb  # and slid past each other


def test_a_static_robot_does_not_move_even_when_pushed():
    config = WorldConfig(ugvs=(robot("a", (0.0, 0.0, 0.0), 0), robot("b", (0.7, 0.0, 0.3), 1, static=True)))
    world = World(config)
    assert world.is_static("b") and not world.is_static("a")
    pose = world.ugv_pose("b")
    transform = world.ugv_transform("b")
    pushed = False
    for _ in range(100):
        world.step({"a": (0.5, 0.0, 0.0), "b": (0.5, 0.5, 1.0)})
        assert world.ugv_pose("b") == pose
        assert world.ugv_body_velocity("b") == (0.0, 0.0, 0.0)
        pushed |= frozenset({"a", "b"}) in world.collisions_since_last_step
    assert pushed
    np.testing.assert_array_equal(world.ugv_transform("b"), transform)

    world.set_static("b", False)
    body = world._ugvs[1].body
    assert (body.mass, body.moment) == (20.0, pytest.approx(0.5 * 20.0 * 0.225**2))
    drive(world, {"b": (0.3, 0.0, 0.0)}, 25)
    x, y, _ = world.ugv_pose("b")
    assert math.hypot(x - pose[0], y - pose[1]) > 0.1
    world.set_static("b", True)
    locked = world.ugv_pose("b")
    drive(world, {"b": (0.3, 0.0, 0.0)}, 5)
    assert world.ugv_pose("b") == locked


def test_robots_without_a_command_brake():
    world = one_robot_world()
    drive(world, {"a": (0.5, 0.0, 0.0)}, 25)
    assert world.ugv_body_velocity("a")[0] > 0.49
    drive(world, {}, 25)
    assert world.ugv_body_velocity("a") == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


@pytest.mark.parametrize(
    ("command", "message"),
    [
        ((float("nan"), 0.0, 0.0), "command for 'a' must be finite"),
        ((0.0, float("inf"), 0.0), "command for 'a' must be finite"),
        ((0.0, 0.0), "command for 'a' must be \\(vx, vy, omega\\) with shape \\(3,\\)"),
        (np.zeros((3, 1)), "shape \\(3,\\)"),
        ("fast", "command for 'a' must be"),
    ],
)
def test_bad_commands_raise_value_errors_naming_the_robot(command, message):
    world = one_robot_world()
    with pytest.raises(ValueError, match=message):
        world.step({"a": command})


def test_commands_must_be_a_mapping():
    with pytest.raises(TypeError, match="ugv_commands must map"):
        one_robot_world().step([(0.1, 0.0, 0.0)])


def test_segment_queries_see_walls_obstacles_and_robots():
    arena = ArenaConfig(obstacles=(BoxObstacle(2.0, 2.0, 0.4, 0.4),))
    config = WorldConfig(arena=arena, ugvs=(robot("a", (0.0, 0.0, 0.0), 0), robot("b", (1.0, 0.0, 0.0), 1)))
    world = World(config)
    assert not world.segment_blocked((-1.0, 1.0), (3.0, 1.0))
    assert world.segment_blocked((-1.0, 0.0), (3.0, 0.0))
    assert world.segment_blocked((-1.0, 0.0), (3.0, 0.0), ignore={"a"})
    assert not world.segment_blocked((-1.0, 0.0), (3.0, 0.0), ignore={"a", "b"})
    assert world.segment_blocked((0.0, 2.0), (3.0, 2.0), ignore={"a", "b"})
    assert world.segment_blocked((0.0, 0.0), (6.0, 0.0), ignore=("a", "b"))  # east wall
    with pytest.raises(ValueError, match="p_to_xy"):
        world.segment_blocked((0.0, 0.0), (float("nan"), 0.0))
    with pytest.raises(KeyError):
        world.segment_blocked((0.0, 0.0), (1.0, 0.0), ignore={"c"})


def test_segment_queries_with_many_robots_ignore_the_named_ones():
    ugvs = tuple(robot(f"r{i}", (-1.2 + 0.46 * (i % 12), -1.0 + 0.5 * (i // 12), 0.0), i, board=None) for i in range(36))
    world = World(WorldConfig(ugvs=ugvs))
    row = (-1.4, -0.5), (4.4, -0.5)  # through r12 .. r23
    assert world.segment_blocked(*row, ignore=[f"r{i}" for i in range(12, 23)])
    assert not world.segment_blocked(*row, ignore=[f"r{i}" for i in range(12, 24)])
    row = (-1.4, 0.0), (4.4, 0.0)  # through r24 .. r35, beyond the dedicated filter bits
    assert world.segment_blocked(*row, ignore=[f"r{i}" for i in range(24, 35)])
    assert not world.segment_blocked(*row, ignore=[f"r{i}" for i in range(24, 36)])


def scripted_run(world: World, steps: int = 120) -> np.ndarray:
    states = []
    for k in range(steps):
        if k == 60:
            world.set_static("b", False)
        commands = {"a": (0.5, 0.2 * math.sin(0.1 * k), 1.0), "b": (0.4, 0.0, -0.5)}
        world.step(commands, (1.0, 0.3, 0.2, 0.3 * math.cos(0.05 * k)))
        states.append(world.state_array())
    return np.array(states)


def test_determinism_same_commands_give_identical_states():
    config = WorldConfig(
        ugvs=(robot("a", (0.0, 0.0, 0.0), 0), robot("b", (0.8, 0.3, 1.0), 1, static=True)),
        uavs=(UAVConfig(initial=(0.5, 0.5, 0.0)),),
    )
    first, second = World(config), World(config)
    run_a, run_b = scripted_run(first), scripted_run(second)
    np.testing.assert_array_equal(run_a, run_b)
    assert run_a.shape == (120, 12 + 10)
    first.reset(np.random.default_rng(3))
    assert first.time == 0.0 and first.is_static("b")
    np.testing.assert_array_equal(scripted_run(first), run_a)


def test_time_counts_control_steps():
    world = World(WorldConfig(ugvs=(robot("a"),), control_hz=20.0, substeps=3))
    drive(world, {}, 7)
    assert world.step_count == 7 and world.time == pytest.approx(0.35)
    world.reset()
    assert world.step_count == 0 and world.time == 0.0
