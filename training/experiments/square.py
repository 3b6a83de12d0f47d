"""The paper's waypoint experiment: two UGVs leapfrog around a 1 m square.

Section IV of the paper: the main robot drives a square of side 1 m through the
waypoints (x, y, theta) with pure rotations at (0, 1), (1, 1) and (1, 0), a 4 m
path; a second robot keeps it company about 0.6 m to its left (outside the
square); the two move in turns with a dwell at every switch, and a UAV above them
tracks both boards with its controller. The run itself is the shared leapfrog core
(:mod:`training.experiments.leapfrog_run`); this module says where the robots go.
With the rendered camera the floor is textured along the first half of the square
only (the paper's lab), so that the visual odometry baseline loses track on the
plain half. Printing, files and figures live in
:mod:`training.experiments.square_report`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from agents.leapfrog import Leg
from moma_env.config import ConfigError, check_non_negative, check_positive
from training.experiments.leapfrog_run import LeapfrogConfig, LeapfrogRun, leapfrog_legs, run_leapfrog

__all__ = ["SquareConfig", "square_waypoints", "square_legs", "run_square"]


@dataclass(frozen=True)
class SquareConfig(LeapfrogConfig):
    """The square (defaults: the paper's set-up); the shared fields are :class:`LeapfrogConfig`'s.

    Attributes:
        side: side of the square (m); the main robot's path is ``4 * side``.
        leg: length of one leg of the main robot between switches (m).
        texture_half_width: half-width of the textured floor along the first
            half of the path (m), see :meth:`textured_regions`.
        texture_clearance: distance kept between the texture and the second
            half of the path (m).
    """

    experiment = "square"

    side: float = 1.0
    leg: float = 0.5
    texture_half_width: float = 0.3
    texture_clearance: float = 0.25

    def __post_init__(self) -> None:
        check_positive("square.side", self.side)
        check_positive("square.texture_half_width", self.texture_half_width)
        check_non_negative("square.texture_clearance", self.texture_clearance)
        if self.camera_backend == "rendered" and 2 * self.texture_clearance >= self.side:
            raise ConfigError("square.texture_clearance", f"leaves no textured floor on a side of {self.side} m, got {self.texture_clearance}")
        check_positive("square.leg", self.leg)
        if self.leg > self.side:
            raise ConfigError("square.leg", f"must be <= side ({self.side}), got {self.leg}")
        super().__post_init__()

    def waypoints(self) -> list[tuple[float, float, float]]:
        """The square's waypoints (see :func:`square_waypoints`)."""
        return square_waypoints(self.side, self.leg)

    def start_pose(self) -> tuple[float, float, float]:
        """The origin, heading +y (the first side)."""
        return (0.0, 0.0, math.pi / 2)

    @property
    def path_length(self) -> float:
        """Nominal path of the main robot (m): the paper's 400 cm for a 1 m side."""
        return 4.0 * self.side

    def textured_regions(self) -> tuple[tuple[float, float, float, float], ...]:
        """The paper's lab: texture along the first half of the path only, (0, 0) -> (0, s) -> (s, s).

        Strips ``texture_half_width`` m either side of the first two sides, kept
        ``texture_clearance`` m away from the second half, (s, s) -> (s, 0) ->
        (0, 0), so that the robot's floor camera (20 cm ahead, 40 x 30 cm of
        floor) sees only plain floor there.
        """
        w, c, s = self.texture_half_width, self.texture_clearance, self.side
        return ((-w, c, w, s + w), (-w, s - w, s - c, s + w))


def square_waypoints(side: float, leg: float) -> list[tuple[float, float, float]]:
    """Main robot waypoints: start (0, 0) heading +y, clockwise, turning at the corners.

    Each side is split into legs of at most ``leg`` metres; at a corner the robot
    turns in place to the next side's heading (the paper's pure rotations).
    """
    corners = [(0.0, 0.0), (0.0, side), (side, side), (side, 0.0), (0.0, 0.0)]
    headings = [math.pi / 2, 0.0, -math.pi / 2, math.pi]
    n = max(1, math.ceil(side / leg - 1e-9))
    waypoints: list[tuple[float, float, float]] = []
    for k in range(4):
        (x0, y0), (x1, y1) = corners[k], corners[k + 1]
        for i in range(1, n + 1):
            f = i / n
            heading = headings[k]
            if i == n and k < 3:
                heading = headings[k + 1]
            waypoints.append((x0 + f * (x1 - x0), y0 + f * (y1 - y0), heading))
    return waypoints


def square_legs(config: SquareConfig) -> list[Leg]:
    """Alternating legs: the main robot to its next waypoint, then its buddy beside it."""
    return leapfrog_legs(config)


def run_square(config: SquareConfig, seed: int) -> LeapfrogRun:
    """Run the square once with every random draw seeded by ``seed``."""
    return run_leapfrog(config, seed)
