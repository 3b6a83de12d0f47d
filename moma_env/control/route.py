"""A robot's route: a polyline from its start through via poses to its goal, by arc length.

The switching executive advances a robot along its route ``leg_length`` metres of
arc at a time, so robots that share a trail keep their spacing along it whatever
corners their legs pass. Points are ``(x, y)`` in the world frame W (m); the
heading of a segment (rad) is the yaw of the pose that ends it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["Route"]

Pose2D = tuple[float, float, float]


class Route:
    """The polyline ``start, vias..., goal`` with each segment's heading.

    Args:
        start: ``(x, y)`` or a pose where the route begins (m).
        poses: the via poses and, last, the goal, each ``(x, y, yaw)``; a segment
            is driven with the yaw of the pose that ends it.
    """

    def __init__(self, start: Sequence[float], poses: Sequence[Pose2D]):
        if not poses:
            raise ValueError("a route needs at least its goal")
        self._points = [(float(start[0]), float(start[1]))] + [(float(p[0]), float(p[1])) for p in poses]
        self._headings = [float(p[2]) for p in poses]
        self._goal = tuple(float(v) for v in poses[-1])
        self._starts = [0.0]
        for a, b in zip(self._points, self._points[1:]):
            self._starts.append(self._starts[-1] + math.dist(a, b))

    @property
    def length(self) -> float:
        """Arc length (m) from the start to the goal."""
        return self._starts[-1]

    def project(self, x: float, y: float, not_before: float = 0.0) -> float:
        """Arc length (m) of the route's point closest to ``(x, y)`` among those at or
        beyond ``not_before`` m."""
        best, best_d = min(max(not_before, 0.0), self.length), math.inf
        for k, (a, b) in enumerate(zip(self._points, self._points[1:])):
            s0, s1 = self._starts[k], self._starts[k + 1]
            if s1 < not_before or s1 == s0:
                continue
            dx, dy = b[0] - a[0], b[1] - a[1]
            t = ((x - a[0]) * dx + (y - a[1]) * dy) / (dx * dx + dy * dy)
            t = min(max(t, (not_before - s0) / (s1 - s0), 0.0), 1.0)
            d = math.hypot(a[0] + t * dx - x, a[1] + t * dy - y)
            if d < best_d:
                best, best_d = s0 + t * (s1 - s0), d
        return best

    def pose_at(self, s: float) -> Pose2D:
        """The point at arc length ``s`` (clipped to the route) with the heading of its
        segment; the goal pose itself at the end."""
        if s >= self.length:
            return self._goal  # type: ignore[return-value]
        s = max(s, 0.0)
        k = 0
        while k + 2 < len(self._starts) and s > self._starts[k + 1]:
            k += 1
        a, b = self._points[k], self._points[k + 1]
        span = self._starts[k + 1] - self._starts[k]
        t = 0.0 if span == 0.0 else (s - self._starts[k]) / span
        return (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), self._headings[k])
