"""Static geometry of the arena: walls and box obstacles, as pymunk shapes.

World frame W: x, y on the floor (m). The arena's interior is the rectangle
``[x0, x0 + width] x [y0, y0 + height]`` with ``(x0, y0) = origin``; the four
walls lie outside it, each ``wall_thickness`` thick. A box obstacle is a
rectangle centred at ``(x, y)``, ``width`` along its own x axis, ``height``
along its own y axis, rotated by ``yaw`` (rad) about +z.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pymunk

if TYPE_CHECKING:
    from moma_env.world.config import ArenaConfig, BoxObstacle

__all__ = [
    "WALL_NAME",
    "STATIC_FRICTION",
    "obstacle_name",
    "box_corners",
    "disk_overlaps_box",
    "disk_inside_rectangle",
    "boxes_overlap",
    "box_inside_rectangle",
    "add_static_shapes",
]

#: Name reported for the walls in collision pairs.
WALL_NAME = "wall"
#: Coulomb friction coefficient of walls and obstacles (robots slide along them).
STATIC_FRICTION = 0.3
#: Overlap (m) below which two shapes count as touching, not intersecting.
_OVERLAP_TOLERANCE = 1e-9


def obstacle_name(index: int) -> str:
    """Name reported for obstacle ``index`` in collision pairs."""
    return f"obstacle[{index}]"


def box_corners(obstacle: BoxObstacle) -> np.ndarray:
    """(4, 2) world xy (m) of the corners of a box obstacle, counter-clockwise."""
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    hw, hh = obstacle.width / 2.0, obstacle.height / 2.0
    local = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    R = np.array([[c, -s], [s, c]])
    return local @ R.T + np.array([obstacle.x, obstacle.y])


def disk_overlaps_box(x: float, y: float, radius: float, obstacle: BoxObstacle) -> bool:
    """True if the disk of ``radius`` (m) at ``(x, y)`` intersects the box (touching is not overlap)."""
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    dx, dy = x - obstacle.x, y - obstacle.y
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    hw, hh = obstacle.width / 2.0, obstacle.height / 2.0
    nearest_x = min(max(lx, -hw), hw)
    nearest_y = min(max(ly, -hh), hh)
    return math.hypot(lx - nearest_x, ly - nearest_y) < radius - _OVERLAP_TOLERANCE


def disk_inside_rectangle(x: float, y: float, radius: float, bounds: tuple[float, float, float, float]) -> bool:
    """True if the disk lies within ``bounds = (xmin, ymin, xmax, ymax)`` (touching allowed)."""
    xmin, ymin, xmax, ymax = bounds
    tol = _OVERLAP_TOLERANCE
    return (
        x - radius >= xmin - tol
        and x + radius <= xmax + tol
        and y - radius >= ymin - tol
        and y + radius <= ymax + tol
    )


def boxes_overlap(a: BoxObstacle, b: BoxObstacle) -> bool:
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
            if min(pa.max(), pb.max()) - max(pa.min(), pb.min()) <= _OVERLAP_TOLERANCE:
                return False
    return True


def box_inside_rectangle(box: BoxObstacle, bounds: tuple[float, float, float, float]) -> bool:
    """True if the rotated box lies within ``bounds = (xmin, ymin, xmax, ymax)`` (touching allowed)."""
    xmin, ymin, xmax, ymax = bounds
    corners = box_corners(box)
    tol = _OVERLAP_TOLERANCE
    return bool(
        corners[:, 0].min() >= xmin - tol
        and corners[:, 0].max() <= xmax + tol
        and corners[:, 1].min() >= ymin - tol
        and corners[:, 1].max() <= ymax + tol
    )


def add_static_shapes(space: pymunk.Space, arena: ArenaConfig, shape_filter: pymunk.ShapeFilter) -> dict[pymunk.Shape, str]:
    """Add the walls and obstacles of ``arena`` to ``space`` as static polygons.

    Returns:
        The added shapes mapped to the names reported in collision pairs
        (:data:`WALL_NAME` or :func:`obstacle_name`).
    """
    xmin, ymin, xmax, ymax = arena.bounds
    t = arena.wall_thickness
    wall_boxes = (
        (xmin - t, ymin - t, xmax + t, ymin),  # south
        (xmin - t, ymax, xmax + t, ymax + t),  # north
        (xmin - t, ymin, xmin, ymax),  # west
        (xmax, ymin, xmax + t, ymax),  # east
    )
    named: dict[pymunk.Shape, str] = {}
    body = space.static_body
    for x0, y0, x1, y1 in wall_boxes:
        named[pymunk.Poly(body, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)])] = WALL_NAME
    for i, obstacle in enumerate(arena.obstacles):
        corners = [(float(px), float(py)) for px, py in box_corners(obstacle)]
        named[pymunk.Poly(body, corners)] = obstacle_name(i)
    for shape in named:
        shape.friction = STATIC_FRICTION
        shape.elasticity = 0.0
        shape.filter = shape_filter
    space.add(*named)
    return named
