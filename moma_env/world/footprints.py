"""Planar footprints on the floor: rotated boxes and disks, and their overlap tests.

Pure geometry in the world frame W (x, y on the floor, metres; yaw in radians
about +z), with no physics and no configuration: the configuration checks
placements with it (:mod:`moma_env.world.config`), the arena turns boxes into
pymunk shapes (:mod:`moma_env.world.arena`, which also exports these names).

A box is anything with the fields of :class:`Box` (``BoxObstacle``, a sled's
footprint): centred at ``(x, y)``, ``width`` along its own x axis, ``height``
along its own y axis, rotated by ``yaw``. Touching is never overlap: two shapes
overlap only if they intersect by more than :data:`OVERLAP_TOLERANCE`.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

__all__ = [
    "OVERLAP_TOLERANCE",
    "Box",
    "box_corners",
    "disk_overlaps_box",
    "disk_inside_rectangle",
    "boxes_overlap",
    "box_inside_rectangle",
]

#: Overlap (m) below which two shapes count as touching, not intersecting.
OVERLAP_TOLERANCE = 1e-9


class Box(Protocol):
    """A rotated rectangle on the floor (W): centre ``x, y`` (m), ``width`` along
    its own x axis and ``height`` along its own y axis (m), ``yaw`` about +z (rad)."""

    @property
    def x(self) -> float: ...

    @property
    def y(self) -> float: ...

    @property
    def width(self) -> float: ...

    @property
    def height(self) -> float: ...

    @property
    def yaw(self) -> float: ...


def box_corners(box: Box) -> np.ndarray:
    """(4, 2) world xy (m) of the corners of a box, counter-clockwise."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    hw, hh = box.width / 2.0, box.height / 2.0
    local = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    R = np.array([[c, -s], [s, c]])
    return local @ R.T + np.array([box.x, box.y])


def disk_overlaps_box(x: float, y: float, radius: float, box: Box) -> bool:
    """True if the disk of ``radius`` (m) at ``(x, y)`` (W, m) intersects the box (touching is not overlap)."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    dx, dy = x - box.x, y - box.y
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    hw, hh = box.width / 2.0, box.height / 2.0
    nearest_x = min(max(lx, -hw), hw)
    nearest_y = min(max(ly, -hh), hh)
    return math.hypot(lx - nearest_x, ly - nearest_y) < radius - OVERLAP_TOLERANCE


def disk_inside_rectangle(x: float, y: float, radius: float, bounds: tuple[float, float, float, float]) -> bool:
    """True if the disk lies within the axis-aligned ``bounds = (xmin, ymin, xmax, ymax)`` (W, m; touching allowed)."""
    xmin, ymin, xmax, ymax = bounds
    tol = OVERLAP_TOLERANCE
    return (
        x - radius >= xmin - tol
        and x + radius <= xmax + tol
        and y - radius >= ymin - tol
        and y + radius <= ymax + tol
    )


def boxes_overlap(a: Box, b: Box) -> bool:
    """True if two rotated boxes intersect (touching is not overlap).

    Separating-axis test: two convex polygons are disjoint if and only if their
    projections on the normal of some edge do not overlap.
    """
    corners_a, corners_b = box_corners(a), box_corners(b)
    for yaw in (a.yaw, b.yaw):
        c, s = math.cos(yaw), math.sin(yaw)
        for axis in ((c, s), (-s, c)):
            pa = corners_a @ axis
            pb = corners_b @ axis
            if min(pa.max(), pb.max()) - max(pa.min(), pb.min()) <= OVERLAP_TOLERANCE:
                return False
    return True


def box_inside_rectangle(box: Box, bounds: tuple[float, float, float, float]) -> bool:
    """True if the rotated box lies within the axis-aligned ``bounds = (xmin, ymin, xmax, ymax)`` (W, m; touching allowed)."""
    xmin, ymin, xmax, ymax = bounds
    corners = box_corners(box)
    tol = OVERLAP_TOLERANCE
    return bool(
        corners[:, 0].min() >= xmin - tol
        and corners[:, 0].max() <= xmax + tol
        and corners[:, 1].min() >= ymin - tol
        and corners[:, 1].max() <= ymax + tol
    )
