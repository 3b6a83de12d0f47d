"""The UAV's tracking controller: keep every board in view from relative poses only.

As in the paper (section IV, "Tracking Controller"), the controller needs only the
board poses relative to the camera (``Detection.T_c_m``), not the MOMA estimate:
it centres the boards in the image and adjusts the altitude so that their spread
fills a chosen fraction of the image, flying lower when the robots are close and
higher when they spread (the coverage S = f(FOV, h) of section III).

Output: ``(vx, vy, yaw_rate, climb_rate)`` with ``(vx, vy)`` in the UAV's yaw frame
(x forward, y left; m/s), ``yaw_rate`` in rad/s and ``climb_rate`` in m/s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.config import ConfigError, check_numbers, check_positive, check_range

__all__ = ["TrackingControllerConfig", "BoardTrackingController"]


@dataclass(frozen=True)
class TrackingControllerConfig:
    """Gains and targets of the board-tracking controller.

    Attributes:
        gain: proportional gain from the boards' centroid offset (m) to velocity (1/s).
        altitude_gain: proportional gain from depth error (m) to climb rate (1/s).
        max_speed, max_climb: command limits (m/s).
        fill: fraction of the half-image (smaller side) that the boards' spread,
            plus ``board_radius``, should occupy.
        board_radius: half-diagonal of a board (m), kept inside the image too.
        min_depth, max_depth: limits of the target distance camera->boards (m).
        search_climb: climb rate when no board is visible (m/s).
        target_offset: where the boards' centroid is held, ``(forward, left)`` (m)
            in the UAV's body frame from below the camera (default: centred); an
            observer beside another holds the team off its axis, and its view
            widens by the offset's length to keep every board in the image.
    """

    gain: float = 0.8
    altitude_gain: float = 0.6
    max_speed: float = 0.6
    max_climb: float = 0.4
    fill: float = 0.55
    board_radius: float = 0.25
    min_depth: float = 0.9
    max_depth: float = 3.0
    search_climb: float = 0.2
    target_offset: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "target_offset", check_numbers("tracking.target_offset", self.target_offset, ("forward", "left")))
        for name in ("gain", "altitude_gain", "max_speed", "max_climb", "board_radius", "min_depth", "max_depth", "search_climb"):
            check_positive(f"tracking.{name}", getattr(self, name))
        check_range("tracking.fill", self.fill, 0.05, 1.0)
        if self.max_depth < self.min_depth:
            raise ConfigError("tracking.max_depth", f"must be >= min_depth ({self.min_depth}), got {self.max_depth}")


class BoardTrackingController:
    """Centre the visible boards and keep their spread at a fixed image fraction.

    Args:
        R_b_c: 3x3 rotation of the camera in the UAV body frame (its mount).
        focal_px: focal length (px) used to turn the image fraction into depth.
        image_size: ``(width, height)`` in pixels.
        config: gains and targets.
    """

    def __init__(self, R_b_c: np.ndarray, focal_px: float, image_size: tuple[int, int], config: TrackingControllerConfig | None = None):
        check_positive("tracking.focal_px", focal_px)
        self.config = config or TrackingControllerConfig()
        self._R_b_c_rows = np.asarray(R_b_c, dtype=float)[:3, :3].tolist()
        self._half_fov_tan = min(image_size) / 2.0 / focal_px
        ox, oy = self.config.target_offset
        self._offset = None if ox == 0.0 and oy == 0.0 else (ox, oy, math.hypot(ox, oy))

    def target_depth(self, spread: float) -> float:
        """Distance (m) at which boards ``spread`` metres apart (held :attr:`TrackingControllerConfig.target_offset`
        off the axis) fill the image fraction."""
        c = self.config
        reach = spread / 2.0 + c.board_radius
        if self._offset is not None:
            reach += self._offset[2]
        needed = reach / (c.fill * self._half_fov_tan)
        return min(c.max_depth, max(c.min_depth, needed))

    def command(self, board_positions_c: Sequence[np.ndarray]) -> np.ndarray:
        """Command from the boards' positions in the camera frame (m), e.g. ``T_c_m[:3, 3]``."""
        c = self.config
        if len(board_positions_c) == 0:
            return np.array([0.0, 0.0, 0.0, c.search_climb])
        # Plain floats: a handful of boards, where numpy calls would cost more than the arithmetic.
        xs = [float(p[0]) for p in board_positions_c]
        ys = [float(p[1]) for p in board_positions_c]
        zs = [float(p[2]) for p in board_positions_c]
        n = len(xs)
        cx = sum(xs) / n
        cy = sum(ys) / n
        cz = sum(zs) / n
        spread = 2.0 * max([math.hypot(x - cx, y - cy) for x, y in zip(xs, ys)])
        # Offset of the centroid from the optical axis, in the body frame.
        R = self._R_b_c_rows
        vx = c.gain * (R[0][0] * cx + R[0][1] * cy)
        vy = c.gain * (R[1][0] * cx + R[1][1] * cy)
        if self._offset is not None:
            vx -= c.gain * self._offset[0]
            vy -= c.gain * self._offset[1]
        speed = math.hypot(vx, vy)
        if speed > c.max_speed:
            vx *= c.max_speed / speed
            vy *= c.max_speed / speed
        depth_error = cz - self.target_depth(spread)
        climb = min(c.max_climb, max(-c.max_climb, -c.altitude_gain * depth_error))
        return np.array([vx, vy, 0.0, climb])
