"""The UAV's 2.5D dynamics: limits, tilt signs, hand-held vs quadcopter, transforms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.geometry import rot_x, rot_y, rot_z
from moma_env.markers import board_for_robot
from moma_env.world import UAVConfig, UGVConfig, World, WorldConfig, uav_body_transform


def uav_world(uav: UAVConfig | None = None) -> World:
    return World(WorldConfig(uavs=(uav or UAVConfig(),)))


def fly(world: World, command, steps: int) -> list:
    states = []
    for _ in range(steps):
        world.step(uav_command=command)
        states.append(world.uav_state)
    return states


def test_climbs_and_descends_within_rate_and_altitude_limits():
    world = uav_world(UAVConfig(altitude=1.6, min_altitude=0.6, max_altitude=3.0, max_climb=0.5))
    previous = world.uav_state.z
    states = fly(world, (0.0, 0.0, 0.0, 2.0), 150)
    for state in states:
        assert 0.0 <= state.z - previous <= 0.5 * world.dt + 1e-12
        assert state.z <= 3.0
        previous = state.z
    assert states[-1].z == 3.0 and states[-1].vz == 0.0
    assert max(s.vz for s in states) == pytest.approx(0.5, rel=1e-3)
    states = fly(world, (0.0, 0.0, 0.0, -0.5), 250)
    assert all(s.z >= 0.6 for s in states)
    assert states[-1].z == 0.6 and states[-1].vz == 0.0
    assert all(s.x == 0.0 and s.y == 0.0 and s.roll == 0.0 and s.pitch == 0.0 for s in states)


def test_horizontal_command_is_in_the_yaw_frame_and_speed_is_limited():
    world = uav_world(UAVConfig(initial=(0.0, 0.0, math.pi / 2), max_speed=1.0))
    states = fly(world, (3.0, 0.0, 0.0, 0.0), 100)
    final = states[-1]
    assert final.y > 2.0 and abs(final.x) < 1e-9  # forward is +y when facing +y
    assert all(math.hypot(s.vx, s.vy) <= 1.0 + 1e-12 for s in states)
    assert final.vy == pytest.approx(1.0, rel=1e-4)


def test_yaw_rate_follows_the_command_within_limits():
    world = uav_world(UAVConfig(max_yaw_rate=1.0))
    states = fly(world, (0.0, 0.0, 5.0, 0.0), 50)
    assert all(0.0 <= s.yaw_rate <= 1.0 for s in states)
    assert states[-1].yaw_rate == pytest.approx(1.0, rel=1e-2)
    assert states[-1].yaw > 1.0  # counter-clockwise


def test_accelerating_forward_pitches_the_nose_down():
    world = uav_world(UAVConfig(initial=(0.0, 0.0, 0.4)))
    fly(world, (1.0, 0.0, 0.0, 0.0), 5)
    state = world.uav_state
    assert state.pitch > 0.02 and abs(state.roll) < 1e-12
    T = world.uav_transform()
    assert T[2, 0] < -0.02  # body x axis points below the horizon
    camera_axis = world.camera_transform("uav/camera")[:3, 2]
    heading = np.array([math.cos(0.4), math.sin(0.4), 0.0])
    assert camera_axis @ heading < -0.02  # the downward camera tilts backward
    # Braking pitches the nose up.
    fly(world, (1.0, 0.0, 0.0, 0.0), 60)
    fly(world, (0.0, 0.0, 0.0, 0.0), 5)
    assert world.uav_state.pitch < -0.02


def test_accelerating_left_rolls_the_left_side_down():
    world = uav_world()
    fly(world, (0.0, 1.0, 0.0, 0.0), 5)
    state = world.uav_state
    assert state.roll < -0.02 and abs(state.pitch) < 1e-12
    assert world.uav_transform()[2, 1] < -0.02  # body y axis (left) points down


def peak_tilt(uav: UAVConfig) -> float:
    states = fly(uav_world(uav), (1.0, 0.5, 0.0, 0.0), 60)
    return max(max(abs(s.pitch), abs(s.roll)) for s in states)


def test_a_handheld_camera_tilts_less_than_a_quadcopter():
    quad, hand = peak_tilt(UAVConfig()), peak_tilt(UAVConfig.handheld())
    assert quad > 0.05
    assert hand < 0.2 * quad


@settings(max_examples=30, deadline=None)
@given(
    commands=st.lists(
        st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=8
    ),
    gain=st.floats(0.0, 30.0),
)
def test_tilt_and_altitude_stay_within_limits(commands, gain):
    world = uav_world(UAVConfig(tilt_gain=gain, max_tilt_deg=15.0, max_accel=8.0, response_time=0.0))
    limit = math.radians(15.0)
    for command in commands:
        for state in fly(world, command, 5):
            assert abs(state.roll) <= limit and abs(state.pitch) <= limit
            assert 0.6 <= state.z <= 4.0
            assert math.hypot(state.vx, state.vy) <= 1.0 + 1e-9
            assert -math.pi <= state.yaw < math.pi


@settings(max_examples=50, deadline=None)
@given(
    yaw=st.floats(-4.0, 4.0),
    pitch=st.floats(-0.5, 0.5),
    roll=st.floats(-0.5, 0.5),
)
def test_body_transform_matches_the_rotation_product(yaw, pitch, roll):
    T = uav_body_transform(0.1, -0.2, 1.5, yaw, pitch, roll)
    np.testing.assert_allclose(T[:3, :3], rot_z(yaw) @ rot_y(pitch) @ rot_x(roll), atol=1e-15)
    np.testing.assert_array_equal(T[:3, 3], [0.1, -0.2, 1.5])
    np.testing.assert_array_equal(T[3], [0.0, 0.0, 0.0, 1.0])


def test_level_uav_camera_looks_straight_down_from_below_the_body():
    world = World(WorldConfig(uavs=(UAVConfig(initial=(1.0, 2.0, 0.3), altitude=1.6),)))
    T_w_c = world.camera_transform("uav/camera")
    np.testing.assert_allclose(T_w_c[:3, 2], [0.0, 0.0, -1.0], atol=1e-15)
    np.testing.assert_allclose(T_w_c[:3, 3], [1.0, 2.0, 1.55], atol=1e-15)
    # The top of the image (-y_C) looks forward along the UAV's heading.
    np.testing.assert_allclose(-T_w_c[:3, 1], [math.cos(0.3), math.sin(0.3), 0.0], atol=1e-15)
    assert world.camera_names == ("uav/camera",)


def test_reset_returns_the_uav_to_its_initial_hover():
    world = uav_world(UAVConfig(initial=(0.5, -0.5, 1.0), altitude=2.0))
    fly(world, (1.0, -1.0, 0.5, 0.3), 30)
    world.reset()
    state = world.uav_state
    assert state.as_array().tolist() == [0.5, -0.5, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]


def test_worlds_without_a_uav_reject_uav_commands_and_queries():
    world = World(WorldConfig(ugvs=(UGVConfig("a", board=board_for_robot(0)),)))
    assert not world.has_uav
    with pytest.raises(ValueError, match="no UAV"):
        world.step(uav_command=(0.0, 0.0, 0.0, 0.0))
    with pytest.raises(LookupError, match="no UAV"):
        world.uav_state
    with pytest.raises(LookupError, match="no UAV"):
        world.uav_transform()


@pytest.mark.parametrize("command", [(0.0, 0.0, 0.0), (0.0, float("nan"), 0.0, 0.0), [[0.0, 0.0, 0.0, 0.0]]])
def test_bad_uav_commands_raise_value_errors_naming_the_uav(command):
    with pytest.raises(ValueError, match="command for 'uav'"):
        uav_world().step(uav_command=command)
