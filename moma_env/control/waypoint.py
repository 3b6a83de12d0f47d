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

from moma_env.config import ConfigError, check_positive
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
        hold_m: once the position has been within ``position_tolerance`` of a
            waypoint, it counts as reached while the estimate stays within this
            distance (m, at least ``position_tolerance``), so that the robot turns
            in place instead of chasing the noise of its estimate back and forth
            across the tolerance; the caller says whether the position was reached
            (the ``held`` argument of :meth:`WaypointFollower.command`). None (the
            default): only within ``position_tolerance``, the authors' follower.
    """

    max_speed: float = 0.25
    max_yaw_rate: float = 0.8
    position_gain: float = 1.5
    yaw_gain: float = 2.0
    position_tolerance: float = 0.02
    yaw_tolerance: float = 0.04
    min_speed: float = 0.02
    hold_m: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_speed", "max_yaw_rate", "position_gain", "yaw_gain", "position_tolerance", "yaw_tolerance", "min_speed"):
            check_positive(f"follower.{name}", getattr(self, name))
        if self.hold_m is not None:
            check_positive("follower.hold_m", self.hold_m)
            if self.hold_m < self.position_tolerance:
                raise ConfigError(
                    "follower.hold_m", f"must be at least position_tolerance ({self.position_tolerance} m), got {self.hold_m}"
                )


class WaypointFollower:
    """Proportional go-to-pose controller: translate first, then rotate in place."""

    def __init__(self, config: WaypointFollowerConfig | None = None):
        self.config = config or WaypointFollowerConfig()

    def position_reached(self, pose: tuple[float, float, float], waypoint: tuple[float, float, float], held: bool = False) -> bool:
        """True when the position of ``pose`` counts as at ``waypoint``'s: within
        ``position_tolerance``, or, when ``held`` (the caller saw it reached since the
        waypoint was set) and ``hold_m`` is set, within ``hold_m``."""
        dist = math.hypot(waypoint[0] - pose[0], waypoint[1] - pose[1])
        return dist <= self.config.position_tolerance or self._held_within(dist, held)

    def _held_within(self, dist: float, held: bool) -> bool:
        """Whether a position ``dist`` m from the waypoint's, ``held`` by the caller, counts as reached by ``hold_m``."""
        hold = self.config.hold_m
        return held and hold is not None and dist <= hold

    def reached(self, pose: tuple[float, float, float], waypoint: tuple[float, float, float], held: bool = False) -> bool:
        """True when ``pose`` is within both tolerances of ``waypoint`` (the position as
        :meth:`position_reached` counts it)."""
        return (
            self.position_reached(pose, waypoint, held)
            and abs(wrap_angle(waypoint[2] - pose[2])) <= self.config.yaw_tolerance
        )

    def command(self, pose: tuple[float, float, float], waypoint: tuple[float, float, float], held: bool = False) -> np.ndarray:
        """Body-frame velocity ``(vx, vy, omega)`` that drives ``pose`` to ``waypoint``: towards
        its position until :meth:`position_reached` (``held``: see there), then turning in place."""
        c = self.config
        x, y, yaw = pose
        gx, gy, gyaw = waypoint
        dx, dy = gx - x, gy - y
        dist = math.hypot(dx, dy)
        if dist > c.position_tolerance and not self._held_within(dist, held):
            speed = min(c.max_speed, max(c.min_speed, c.position_gain * dist))
            wx, wy = dx / dist * speed, dy / dist * speed
            cos_y, sin_y = math.cos(yaw), math.sin(yaw)
            return np.array([cos_y * wx + sin_y * wy, -sin_y * wx + cos_y * wy, 0.0])
        err = wrap_angle(gyaw - yaw)
        if abs(err) <= c.yaw_tolerance:
            return np.zeros(3)
        omega = math.copysign(min(c.max_yaw_rate, max(0.05, c.yaw_gain * abs(err))), err)
        return np.array([0.0, 0.0, omega])
