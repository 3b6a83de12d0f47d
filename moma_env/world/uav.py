"""2.5D state and dynamics of the observer (quadcopter or hand-held camera).

The UAV flies over everything and is not a physics collider. Its state is the
position (x, y) and altitude z of its body frame B in the world W, the yaw, and
the roll and pitch it takes while accelerating; velocities are in W.

Dynamics per control step of ``dt`` s:

* The command is ``(vx, vy, yaw_rate, climb)``: (vx, vy) in the UAV's yaw frame
  (x forward, y left; m/s), yaw rate (rad/s), climb rate (m/s). It is clipped to
  ``max_speed`` (norm of (vx, vy)), ``max_yaw_rate`` and ``max_climb``.
* Velocities (horizontal, vertical, yaw rate) follow the command with a
  first-order response of time constant ``response_time``; the horizontal
  acceleration's norm and the vertical acceleration are clipped to ``max_accel``.
  Positions integrate the mean velocity over the step (trapezoid rule).
* The altitude is clipped to [min_altitude, max_altitude]; at a limit the
  vertical velocity pointing out of the range is zeroed.
* Tilt follows the horizontal acceleration (a_fwd, a_left) expressed in the yaw
  frame, as a quadcopter leans into it: target pitch = tilt_gain*atan(a_fwd/g)
  (accelerating forward pitches the nose down: positive pitch about +y),
  target roll = -tilt_gain*atan(a_left/g) (accelerating left lowers the left
  side). The tilt follows the target through a first-order low-pass of time
  constant ``tilt_time_constant`` and is clipped to ``max_tilt_deg``.

``T_w_b = translation(x, y, z) @ rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from moma_env.records import slot_setter_init
from moma_env.world.config import UAVConfig

__all__ = ["GRAVITY", "UAVState", "UAVDynamics", "uav_body_transform"]

#: Gravitational acceleration (m/s^2), sets the tilt for a given acceleration.
GRAVITY = 9.81


@slot_setter_init
@dataclass(frozen=True, slots=True, init=False)
class UAVState:
    """Snapshot of the observer's state.

    Attributes:
        x, y, z: position of B in W (m); z is the altitude.
        yaw, roll, pitch: attitude (rad), ``R_w_b = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)``.
        vx, vy, vz: velocity in W (m/s).
        yaw_rate: rate of the yaw (rad/s).
    """

    x: float
    y: float
    z: float
    yaw: float
    roll: float
    pitch: float
    vx: float
    vy: float
    vz: float
    yaw_rate: float

    def as_array(self) -> np.ndarray:
        """``[x, y, z, yaw, roll, pitch, vx, vy, vz, yaw_rate]`` as a float array."""
        return np.array(
            [self.x, self.y, self.z, self.yaw, self.roll, self.pitch, self.vx, self.vy, self.vz, self.yaw_rate]
        )


def uav_body_transform(x: float, y: float, z: float, yaw: float, pitch: float, roll: float) -> np.ndarray:
    """``T_w_b = translation(x, y, z) @ rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)`` (closed form)."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    # One flat list reshaped (a third cheaper than numpy reading nested rows), row-major.
    return np.array(
        [
            cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr, x,
            sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr, y,
            -sp, cp * sr, cp * cr, z,
            0.0, 0.0, 0.0, 1.0,
        ]
    ).reshape(4, 4)


def _smoothing(dt: float, time_constant: float) -> float:
    """Fraction of the gap to the target closed in ``dt`` by a first-order lag."""
    return 1.0 if time_constant == 0.0 else -math.expm1(-dt / time_constant)


class UAVDynamics:
    """Integrates the observer's state; one instance per world, reset with the world."""

    __slots__ = (
        "config",
        "dt",
        "_k_velocity",
        "_k_tilt",
        "_max_tilt",
        "x",
        "y",
        "z",
        "yaw",
        "roll",
        "pitch",
        "vx",
        "vy",
        "vz",
        "yaw_rate",
    )

    def __init__(self, config: UAVConfig, dt: float):
        self.config = config
        self.dt = dt
        self._k_velocity = _smoothing(dt, config.response_time)
        self._k_tilt = _smoothing(dt, config.tilt_time_constant)
        self._max_tilt = config.max_tilt
        self.reset()

    def reset(self) -> None:
        """Hover at the initial pose and altitude, level, at rest."""
        self.x, self.y, self.yaw = self.config.initial
        self.z = self.config.altitude
        self.roll = self.pitch = 0.0
        self.vx = self.vy = self.vz = self.yaw_rate = 0.0

    def step(self, forward: float, left: float, yaw_rate: float, climb: float) -> None:
        """Advance one step under a command already checked to be finite (clipped here)."""
        cfg = self.config
        dt = self.dt
        speed = math.hypot(forward, left)
        if speed > cfg.max_speed:
            forward *= cfg.max_speed / speed
            left *= cfg.max_speed / speed
        yaw_rate = min(max(yaw_rate, -cfg.max_yaw_rate), cfg.max_yaw_rate)
        climb = min(max(climb, -cfg.max_climb), cfg.max_climb)

        c, s = math.cos(self.yaw), math.sin(self.yaw)
        k = self._k_velocity / dt
        ax = (c * forward - s * left - self.vx) * k
        ay = (s * forward + c * left - self.vy) * k
        accel = math.hypot(ax, ay)
        if accel > cfg.max_accel:
            ax *= cfg.max_accel / accel
            ay *= cfg.max_accel / accel
        az = min(max((climb - self.vz) * k, -cfg.max_accel), cfg.max_accel)

        vx, vy, vz = self.vx + ax * dt, self.vy + ay * dt, self.vz + az * dt
        new_yaw_rate = self.yaw_rate + (yaw_rate - self.yaw_rate) * self._k_velocity
        self.x += 0.5 * (self.vx + vx) * dt
        self.y += 0.5 * (self.vy + vy) * dt
        z = self.z + 0.5 * (self.vz + vz) * dt
        if z >= cfg.max_altitude:
            z, vz = cfg.max_altitude, min(vz, 0.0)
        elif z <= cfg.min_altitude:
            z, vz = cfg.min_altitude, max(vz, 0.0)
        self.z = z
        yaw = self.yaw + 0.5 * (self.yaw_rate + new_yaw_rate) * dt
        self.yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
        self.vx, self.vy, self.vz, self.yaw_rate = vx, vy, vz, new_yaw_rate

        c, s = math.cos(self.yaw), math.sin(self.yaw)
        a_forward = c * ax + s * ay
        a_left = -s * ax + c * ay
        gain, limit = cfg.tilt_gain, self._max_tilt
        pitch = self.pitch + (gain * math.atan(a_forward / GRAVITY) - self.pitch) * self._k_tilt
        roll = self.roll + (-gain * math.atan(a_left / GRAVITY) - self.roll) * self._k_tilt
        self.pitch = min(max(pitch, -limit), limit)
        self.roll = min(max(roll, -limit), limit)

    def state(self) -> UAVState:
        """The current state as an immutable snapshot."""
        return UAVState(
            self.x, self.y, self.z, self.yaw, self.roll, self.pitch, self.vx, self.vy, self.vz, self.yaw_rate
        )

    def body_transform(self) -> np.ndarray:
        """4x4 ``T_w_b`` of the UAV body."""
        return uav_body_transform(self.x, self.y, self.z, self.yaw, self.pitch, self.roll)
