"""Scripted controllers: waypoint follower, leapfrog schedule, UAV board tracking."""

import math

import numpy as np
import pytest

from agents.leapfrog import LeapfrogSchedule, Leg, StateChange
from moma_env.control.tracking import BoardTrackingController, TrackingControllerConfig
from moma_env.control.waypoint import WaypointFollower, WaypointFollowerConfig
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_CAM_DOWN


def integrate(pose, cmd, dt):
    x, y, yaw = pose
    vx, vy, w = cmd
    return (x + dt * (math.cos(yaw) * vx - math.sin(yaw) * vy), y + dt * (math.sin(yaw) * vx + math.cos(yaw) * vy), yaw + dt * w)


@pytest.mark.parametrize("goal", [(1.0, 0.0, 0.0), (0.0, -0.5, math.pi / 2), (-0.3, 0.4, -2.5)])
def test_follower_reaches_waypoint_translating_then_rotating(goal):
    f = WaypointFollower()
    pose = (0.0, 0.0, 0.3)
    rotated_while_far = False
    for _ in range(2000):
        if f.reached(pose, goal):
            break
        cmd = f.command(pose, goal)
        far = math.hypot(goal[0] - pose[0], goal[1] - pose[1]) > f.config.position_tolerance
        rotated_while_far |= far and cmd[2] != 0.0
        assert math.hypot(cmd[0], cmd[1]) <= f.config.max_speed + 1e-12
        assert abs(cmd[2]) <= f.config.max_yaw_rate + 1e-12
        pose = integrate(pose, cmd, 0.04)
    assert f.reached(pose, goal)
    assert not rotated_while_far
    np.testing.assert_array_equal(f.command(pose, goal), np.zeros(3))


def test_follower_body_frame_command():
    f = WaypointFollower()
    # Robot faces +y; the goal is at +y: the command is forward (+vx), not sideways.
    cmd = f.command((0.0, 0.0, math.pi / 2), (0.0, 1.0, math.pi / 2))
    assert cmd[0] == pytest.approx(f.config.max_speed) and abs(cmd[1]) < 1e-12
    # Goal to the robot's left.
    cmd = f.command((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    assert cmd[1] > 0 and abs(cmd[0]) < 1e-12


def test_follower_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="follower.max_speed"):
        WaypointFollowerConfig(max_speed=0.0)


def test_leapfrog_moves_one_robot_at_a_time_with_dwell():
    legs = [Leg("a", (0.5, 0.0, 0.0)), Leg("b", (0.5, 0.6, 0.0)), Leg("a", (1.0, 0.0, 0.0))]
    sched = LeapfrogSchedule(legs, WaypointFollower(), dwell_s=1.0, robots=["a", "b"])
    poses = {"a": (0.0, 0.0, 0.0), "b": (0.0, 0.6, 0.0)}
    mobile: set[str] = set()
    t, dt = 0.0, 0.04
    history = []
    static_since = {"a": 0.0, "b": 0.0}
    while not sched.done and t < 60:
        cmds, changes = sched.step(t, poses)
        for c in changes:
            history.append((t, c))
            if c.static:
                mobile.discard(c.robot)
                static_since[c.robot] = t
            else:
                # Rule 3 of the paper: a dwell with both static before anyone moves.
                assert not mobile
                assert t - max(static_since.values()) >= 1.0 - 1e-9 or len(history) == 1
                mobile.add(c.robot)
        assert len(mobile) <= 1
        for name, cmd in cmds.items():
            if name not in mobile:
                np.testing.assert_array_equal(cmd, np.zeros(3))
            poses[name] = integrate(poses[name], cmd, dt)
        t += dt
    assert sched.done
    assert [c for _, c in history] == [
        StateChange("a", False), StateChange("a", True), StateChange("b", False), StateChange("b", True), StateChange("a", False), StateChange("a", True)
    ]
    assert math.hypot(poses["a"][0] - 1.0, poses["a"][1]) <= 0.02


def test_leapfrog_waits_while_the_mover_is_not_localised():
    sched = LeapfrogSchedule([Leg("a", (1.0, 0.0, 0.0))], WaypointFollower(), dwell_s=0.0, robots=["a"])
    sched.step(0.0, {"a": (0.0, 0.0, 0.0)})
    cmds, changes = sched.step(0.04, {"a": None})
    np.testing.assert_array_equal(cmds["a"], np.zeros(3))
    assert changes == []


def test_tracking_centres_boards_and_sets_altitude_from_spread():
    ctrl = BoardTrackingController(R_BODY_CAM_DOWN, focal_px=420.0, image_size=(720, 576))
    # Boards right of the optical axis (x_c > 0) and below it in the image (y_c > 0):
    # the UAV must fly right (body -y) and backward (body -x).
    cmd = ctrl.command([np.array([0.3, 0.2, 1.5])])
    assert cmd[1] < 0 and cmd[0] < 0
    # Close boards -> descend to min depth; far apart -> climb.
    close = ctrl.command([np.array([0.0, 0.0, 2.0]), np.array([0.05, 0.0, 2.0])])
    spread = ctrl.command([np.array([-1.0, 0.0, 1.0]), np.array([1.0, 0.0, 1.0])])
    assert close[3] < 0 < spread[3]
    assert ctrl.target_depth(0.0) < ctrl.target_depth(1.0) < ctrl.target_depth(3.0) or ctrl.target_depth(3.0) == ctrl.config.max_depth
    # Nothing seen: climb to search.
    np.testing.assert_array_equal(ctrl.command([]), [0.0, 0.0, 0.0, ctrl.config.search_climb])


def test_tracking_target_depth_fits_spread_in_image():
    cfg = TrackingControllerConfig(min_depth=0.1, max_depth=100.0)
    ctrl = BoardTrackingController(R_BODY_CAM_DOWN, focal_px=420.0, image_size=(720, 576), config=cfg)
    d = ctrl.target_depth(1.0)
    half_width_px = (0.5 + cfg.board_radius) * 420.0 / d
    assert half_width_px == pytest.approx(cfg.fill * 288.0)
