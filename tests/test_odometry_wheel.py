"""Wheel odometry: exact without noise, drifting with it, reproducible with a seed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.config import ConfigError
from moma_env.geometry import wrap_angle
from moma_env.markers import board_for_robot
from moma_env.odometry import WheelOdometry, WheelOdometryConfig, se2_step
from moma_env.world import UGVConfig, World, WorldConfig


def arc_commands(k: int) -> dict[str, tuple[float, float, float]]:
    """A wandering drive: arcs of changing curvature, sideways motion, stops."""
    if 150 <= k < 175:
        return {}
    return {"a": (0.45 * math.cos(0.01 * k), 0.15 * math.sin(0.03 * k), 1.2 * math.sin(0.02 * k))}


def recorded_drive(steps: int = 450) -> tuple[World, list[tuple[float, float, float]], list, tuple]:
    """Drive robot "a" in the world; return the velocities and true poses per step."""
    world = World(WorldConfig(ugvs=(UGVConfig("a", (0.0, 0.0, 0.3), board=board_for_robot(0), static=False),)))
    start = world.ugv_pose("a")
    velocities, poses = [], []
    for k in range(steps):
        world.step(arc_commands(k))
        velocities.append(world.ugv_body_velocity("a"))
        poses.append(world.ugv_pose("a"))
    return world, velocities, poses, start


def test_ideal_odometry_reproduces_the_world_trajectory():
    world, velocities, poses, start = recorded_drive()
    odometry = WheelOdometry(WheelOdometryConfig.ideal(), start)
    worst = 0.0
    for velocity, (x, y, yaw) in zip(velocities, poses):
        ox, oy, oyaw = odometry.update(velocity, world.dt)
        worst = max(worst, math.hypot(ox - x, oy - y))
        assert abs(wrap_angle(oyaw - yaw)) < 1e-9
    assert odometry.distance > 3.0
    assert worst < 1e-6


def test_odometry_of_a_static_robot_does_not_drift():
    world = World(WorldConfig(ugvs=(UGVConfig("a", (1.0, 1.0, 0.5)),)))
    odometry = WheelOdometry(WheelOdometryConfig(), world.ugv_pose("a"))
    rng = np.random.default_rng(0)
    for _ in range(50):
        world.step({"a": (0.5, 0.0, 1.0)})
        odometry.update(world.ugv_body_velocity("a"), world.dt, rng)
    assert odometry.pose == world.ugv_pose("a") == (1.0, 1.0, 0.5)


def position_errors(velocities, poses, start, dt, seed: int, checkpoints) -> list[float]:
    odometry = WheelOdometry(WheelOdometryConfig(), start)
    rng = np.random.default_rng(seed)
    errors = []
    for k, velocity in enumerate(velocities):
        x, y, _ = odometry.update(velocity, dt, rng)
        if k in checkpoints:
            errors.append(math.hypot(x - poses[k][0], y - poses[k][1]))
    return errors


def test_noisy_odometry_error_grows_with_distance():
    world, velocities, poses, start = recorded_drive()
    checkpoints = (99, 249, 449)
    errors = np.array(
        [position_errors(velocities, poses, start, world.dt, seed, checkpoints) for seed in range(20)]
    )
    mean = errors.mean(axis=0)
    assert mean[0] > 1e-3
    assert mean[0] < mean[1] < mean[2]


def test_seeded_noise_is_reproducible():
    _, velocities, _, start = recorded_drive(120)

    def run(seed: int) -> list[tuple[float, float, float]]:
        odometry = WheelOdometry(WheelOdometryConfig(), start)
        rng = np.random.default_rng(seed)
        return [odometry.update(v, 0.04, rng) for v in velocities]

    assert run(7) == run(7)
    assert run(7) != run(8)


def test_biases_scale_distance_and_turn_the_heading():
    odometry = WheelOdometry(WheelOdometryConfig(0.0, 0.0, scale_bias=0.01, yaw_scale_bias=0.0, yaw_drift_per_m=0.0))
    for _ in range(100):
        odometry.update((0.25, 0.0, 0.0), 0.04)
    assert odometry.pose == pytest.approx((1.01, 0.0, 0.0), abs=1e-12)
    assert odometry.distance == pytest.approx(1.01, abs=1e-12)
    odometry = WheelOdometry(WheelOdometryConfig(0.0, 0.0, scale_bias=0.0, yaw_scale_bias=0.0, yaw_drift_per_m=0.01))
    for _ in range(100):
        odometry.update((0.25, 0.0, 0.0), 0.04)
    assert odometry.pose[2] == pytest.approx(0.01, abs=1e-12)
    odometry = WheelOdometry(WheelOdometryConfig(0.0, 0.0, scale_bias=0.0, yaw_scale_bias=0.02, yaw_drift_per_m=0.0))
    for _ in range(100):
        odometry.update((0.0, 0.0, 0.25), 0.04)
    assert odometry.pose[2] == pytest.approx(1.02, abs=1e-12)


@settings(max_examples=80, deadline=None)
@given(
    pose=st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-math.pi, math.pi)),
    twist=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-3, 3)),
    n=st.integers(2, 20),
)
def test_se2_step_composes_for_a_constant_twist(pose, twist, n):
    dt = 0.04
    x, y, yaw = pose
    for _ in range(n):
        x, y, yaw = se2_step(x, y, yaw, *twist, dt)
    once = se2_step(*pose, *twist, n * dt)
    assert (x, y, yaw) == pytest.approx(once, abs=1e-9)
    # The arc keeps its radius |v| / |omega| about a fixed centre.
    vx, vy, omega = twist
    if abs(omega) > 1e-3:
        speed = math.hypot(vx, vy)
        start = np.array(pose[:2])
        heading = np.array([math.cos(pose[2]), math.sin(pose[2])])
        left = np.array([-heading[1], heading[0]])
        centre = start + (vx * left - vy * heading) / omega
        assert np.linalg.norm(np.array(once[:2]) - centre) == pytest.approx(speed / abs(omega), abs=1e-9)


def test_bad_inputs_are_rejected():
    with pytest.raises(ConfigError) as excinfo:
        WheelOdometryConfig(slip_std=-0.1)
    assert excinfo.value.field == "wheel_odometry.slip_std"
    with pytest.raises(ConfigError) as excinfo:
        WheelOdometryConfig(scale_bias=-1.0)
    assert excinfo.value.field == "wheel_odometry.scale_bias"
    with pytest.raises(ConfigError) as excinfo:
        WheelOdometryConfig(yaw_drift_per_m=float("nan"))
    assert excinfo.value.field == "wheel_odometry.yaw_drift_per_m"
    odometry = WheelOdometry()
    with pytest.raises(ValueError, match="needs rng"):
        odometry.update((0.1, 0.0, 0.0), 0.04)
    with pytest.raises(ValueError, match="body_velocity must be finite"):
        odometry.update((0.1, float("nan"), 0.0), 0.04, np.random.default_rng(0))
    with pytest.raises(ValueError, match="three numbers"):
        odometry.update((0.1, 0.0), 0.04, np.random.default_rng(0))
    with pytest.raises(ValueError, match="dt"):
        odometry.update((0.1, 0.0, 0.0), 0.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="pose"):
        WheelOdometry(initial_pose=(0.0, 0.0, float("inf")))
    with pytest.raises(TypeError):
        WheelOdometry(config={"slip_std": 0.0})


def test_reset_restarts_from_a_pose():
    odometry = WheelOdometry(WheelOdometryConfig.ideal(), (1.0, 2.0, 0.0))
    odometry.update((0.5, 0.0, 0.2), 0.1)
    odometry.reset((0.0, 0.0, 4.0))
    assert odometry.pose == (0.0, 0.0, pytest.approx(4.0 - 2 * math.pi))
    assert odometry.distance == 0.0
