"""Waypoint following for an omnidirectional UGV, on its estimated pose only.

A waypoint is ``(x, y, theta)`` in the world frame (m, m, rad), as in the paper's
square experiment. The robot first drives to ``(x, y)`` (holonomic, keeping its
heading), then turns in place to ``theta``: the pure rotations at the square's
corners that the paper reports. The output is the body-frame velocity command
``(vx forward, vy left, omega)`` in m/s and rad/s that the world accepts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from moma_env.config import check_positive
from moma_env.geometry import wrap_angle

__all__ = ["WaypointFollowerConfig", "WaypointFollower"]


@dataclass(frozen=True)
class WaypointFollowerConfig:
    """Gains and limits of the waypoint follower.

    Attributes:
        max_speed: translational speed limit (m/s).
        max_yaw_rate: turn rate limit (rad/s).
        position_gain: proportional gain on the position error (1/s).
        yaw_gain: proportional gain on the heading error (1/s).
        position_tolerance: distance at which the position counts as reached (m);
            the authors' caterpillar follower used 2 cm.
        yaw_tolerance: heading error at which the waypoint counts as reached
            (rad); the authors used 0.04 rad.
        min_speed: speed floor while outside the tolerance (m/s), so that the
            proportional law does not stall just outside it.
    """

    max_speed: float = 0.25
    max_yaw_rate: float = 0.8
    position_gain: float = 1.5
    yaw_gain: float = 2.0
    position_tolerance: float = 0.02
    yaw_tolerance: float = 0.04
    min_speed: float = 0.02

    def __post_init__(self) -> None:
        for name in ("max_speed", "max_yaw_rate", "position_gain", "yaw_gain", "position_tolerance", "yaw_tolerance", "min_speed"):
            check_positive(f"follower.{name}", getattr(self, name))


class WaypointFollower:
    """Proportional go-to-pose controller: translate first, then rotate in place."""

    def __init__(self, config: WaypointFollowerConfig | None = None):
        self.config = config or WaypointFollowerConfig()

    def reached(self, pose: tuple[float, float, float], waypoint: tuple[float, float, float]) -> bool:
        """True when ``pose`` is within both tolerances of ``waypoint``."""
        x, y, yaw = pose
        gx, gy, gyaw = waypoint
        return (
            math.hypot(gx - x, gy - y) <= self.config.position_tolerance
            and abs(wrap_angle(gyaw - yaw)) <= self.config.yaw_tolerance
        )

    def command(self, pose: tuple[float, float, float], waypoint: tuple[float, float, float]) -> np.ndarray:
        """Body-frame velocity ``(vx, vy, omega)`` that drives ``pose`` to ``waypoint``."""
        c = self.config
        x, y, yaw = pose
        gx, gy, gyaw = waypoint
        dx, dy = gx - x, gy - y
        dist = math.hypot(dx, dy)
        if dist > c.position_tolerance:
            speed = min(c.max_speed, max(c.min_speed, c.position_gain * dist))
            wx, wy = dx / dist * speed, dy / dist * speed
            cos_y, sin_y = math.cos(yaw), math.sin(yaw)
            return np.array([cos_y * wx + sin_y * wy, -sin_y * wx + cos_y * wy, 0.0])
        err = wrap_angle(gyaw - yaw)
        if abs(err) <= c.yaw_tolerance:
            return np.zeros(3)
        omega = math.copysign(min(c.max_yaw_rate, max(0.05, c.yaw_gain * abs(err))), err)
        return np.array([0.0, 0.0, omega])
