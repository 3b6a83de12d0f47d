"""Static geometry of the arena: walls and box obstacles, as pymunk shapes.

World frame W: x, y on the floor (m). The arena's interior is the rectangle
``[x0, x0 + width] x [y0, y0 + height]`` with ``(x0, y0) = origin``; the four
walls lie outside it, each ``wall_thickness`` thick. A box obstacle is a
rectangle centred at ``(x, y)``, ``width`` along its own x axis, ``height``
along its own y axis, rotated by ``yaw`` (rad) about +z.

The planar tests on boxes and disks live in :mod:`moma_env.world.footprints`
and the names of the static shapes in :mod:`moma_env.world.config`; both are
exported here too, where they have always been importable.
"""

from __future__ import annotations

import pymunk

from moma_env.world.config import WALL_NAME, ArenaConfig, obstacle_name
from moma_env.world.footprints import (
    box_corners,
    box_inside_rectangle,
    boxes_overlap,
    disk_inside_rectangle,
    disk_overlaps_box,
)

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

#: Coulomb friction coefficient of walls and obstacles (robots slide along them).
STATIC_FRICTION = 0.3


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
