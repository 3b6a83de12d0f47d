"""Wheel odometry baseline: dead reckoning of measured body velocities with slip.

Each update takes the body-frame velocity the wheels measured over a step
(``World.ugv_body_velocity``: vx forward m/s, vy left m/s, omega rad/s), corrupts
it with systematic and random errors, and integrates it with the exact SE(2)
exponential of a constant twist over the step. Without noise or bias this
reproduces the true planar pose up to floating-point rounding.

Error model, per update of ``dt`` s (n_x, n_y, n_w independent standard normals):

* ``vx_m = vx * (1 + scale_bias + slip_std * n_x)``, same for ``vy_m`` with n_y;
* ``omega_m = omega * (1 + yaw_scale_bias + yaw_slip_std * n_w)
  + yaw_drift_per_m * hypot(vx_m, vy_m)``.

The noise is multiplicative, so a robot at rest (a static marker) accumulates no
error. The random part is drawn per update, so its effect depends on the update
rate; the defaults assume the world's 25 Hz.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.config import ConfigError, check_finite, check_non_negative

__all__ = ["WheelOdometryConfig", "WheelOdometry", "se2_step"]


@dataclass(frozen=True)
class WheelOdometryConfig:
    """Error model of the wheel odometry of an omnidirectional robot.

    The defaults are illustrative Festo Robotino-like values (omni wheels slip,
    mostly when turning); the paper reports no wheel-odometry figures to
    calibrate them against.

    Attributes:
        slip_std: std of the per-update relative error on each translation axis.
        yaw_slip_std: std of the per-update relative error on the rotation.
        scale_bias: systematic relative error on translation (wheel radius), e.g.
            0.01 reports 1 % more distance than driven.
        yaw_scale_bias: systematic relative error on rotation (wheel base).
        yaw_drift_per_m: heading drift per metre driven (rad/m), from uneven
            wheel slip; its sign is the direction of the drift.
    """

    slip_std: float = 0.03
    yaw_slip_std: float = 0.05
    scale_bias: float = 0.01
    yaw_scale_bias: float = 0.01
    yaw_drift_per_m: float = 0.005

    def __post_init__(self) -> None:
        check_non_negative("wheel_odometry.slip_std", self.slip_std)
        check_non_negative("wheel_odometry.yaw_slip_std", self.yaw_slip_std)
        for name in ("scale_bias", "yaw_scale_bias"):
            value = getattr(self, name)
            check_finite(f"wheel_odometry.{name}", value)
            if value <= -1.0:
                raise ConfigError(f"wheel_odometry.{name}", f"must be > -1 (a relative error), got {value}")
        check_finite("wheel_odometry.yaw_drift_per_m", self.yaw_drift_per_m)

    @classmethod
    def ideal(cls) -> WheelOdometryConfig:
        """No noise and no bias: exact dead reckoning."""
        return cls(slip_std=0.0, yaw_slip_std=0.0, scale_bias=0.0, yaw_scale_bias=0.0, yaw_drift_per_m=0.0)

    @property
    def is_noisy(self) -> bool:
        """Whether updates draw random numbers."""
        return self.slip_std > 0.0 or self.yaw_slip_std > 0.0


def se2_step(
    x: float, y: float, yaw: float, vx: float, vy: float, omega: float, dt: float
) -> tuple[float, float, float]:
    """Pose after moving with the constant body-frame twist (vx, vy, omega) for dt s.

    The exact SE(2) exponential: the robot drives a circular arc (a straight line
    if omega is zero). ``yaw`` is returned unwrapped.
    """
    theta = omega * dt
    if theta == 0.0:
        a, b = 1.0, 0.0
    else:
        a = math.sin(theta) / theta
        b = 2.0 * math.sin(0.5 * theta) ** 2 / theta
    lx = (a * vx - b * vy) * dt
    ly = (b * vx + a * vy) * dt
    c, s = math.cos(yaw), math.sin(yaw)
    return x + c * lx - s * ly, y + s * lx + c * ly, yaw + theta


def _finite_triple(name: str, value: Sequence[float] | np.ndarray) -> tuple[float, float, float]:
    try:
        items = [float(v) for v in value]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers, got {value!r}") from None
    if len(items) != 3:
        raise ValueError(f"{name} must be three numbers, got {len(items)}")
    if not all(math.isfinite(v) for v in items):
        raise ValueError(f"{name} must be finite, got {items}")
    return items[0], items[1], items[2]


class WheelOdometry:
    """Dead-reckoned planar pose ``(x, y, yaw)`` of one robot in W (m, m, rad)."""

    __slots__ = ("config", "_x", "_y", "_yaw", "_distance")

    def __init__(self, config: WheelOdometryConfig | None = None, initial_pose: Sequence[float] = (0.0, 0.0, 0.0)):
        if config is None:
            config = WheelOdometryConfig()
        if not isinstance(config, WheelOdometryConfig):
            raise TypeError(f"config must be a WheelOdometryConfig, got {type(config).__name__}")
        self.config = config
        self.reset(initial_pose)

    def reset(self, pose: Sequence[float]) -> None:
        """Restart dead reckoning from ``pose`` = (x, y, yaw); clears the distance."""
        self._x, self._y, self._yaw = _finite_triple("pose", pose)
        self._distance = 0.0

    @property
    def pose(self) -> tuple[float, float, float]:
        """Current estimate ``(x, y, yaw)``, yaw in [-pi, pi)."""
        return self._x, self._y, (self._yaw + math.pi) % (2.0 * math.pi) - math.pi

    @property
    def distance(self) -> float:
        """Path length dead-reckoned since the last reset (m), from measured velocities."""
        return self._distance

    def update(
        self,
        body_velocity: Sequence[float] | np.ndarray,
        dt: float,
        rng: np.random.Generator | None = None,
    ) -> tuple[float, float, float]:
        """Integrate one measured body-frame velocity (vx, vy, omega) over ``dt`` s.

        Args:
            body_velocity: (vx forward m/s, vy left m/s, omega rad/s) measured over the step.
            dt: duration of the step (s), > 0.
            rng: source of the slip noise; required when the config is noisy
                (three normals are drawn per update, moving or not).

        Returns:
            The new pose estimate ``(x, y, yaw)``.
        """
        vx, vy, omega = _finite_triple("body_velocity", body_velocity)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt!r}")
        cfg = self.config
        fx = fy = fw = 1.0
        if cfg.is_noisy:
            if not isinstance(rng, np.random.Generator):
                raise ValueError("a noisy WheelOdometry needs rng: np.random.Generator")
            nx, ny, nw = rng.standard_normal(3).tolist()
            fx += cfg.slip_std * nx
            fy += cfg.slip_std * ny
            fw += cfg.yaw_slip_std * nw
        vx *= fx + cfg.scale_bias
        vy *= fy + cfg.scale_bias
        speed = math.hypot(vx, vy)
        omega = omega * (fw + cfg.yaw_scale_bias) + cfg.yaw_drift_per_m * speed
        self._x, self._y, self._yaw = se2_step(self._x, self._y, self._yaw, vx, vy, omega, dt)
        self._distance += speed * dt
        return self.pose
