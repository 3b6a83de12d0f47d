"""Planar geometry for laying out a configuration: poses, footprints, corridors.

World frame W (m, rad): x, y on the floor. A planar pose is ``(x, y, yaw)`` of a
body frame B (x forward, y left). A *disk* ``(x, y, radius)`` is the floor area
a robot (or a sled's circumscribed circle) covers. A configuration's *corridor*
is the convex hull of the centres of the disks its devices cover at the start
and at their goals: for a team that translates from start to goal it holds every
intermediate position, so an obstacle farther than the largest radius from it
leaves the way to the goals free.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = [
    "Pose2D",
    "Disk",
    "advanced",
    "in_body_frame",
    "shifted",
    "convex_hull",
    "convex_polygons_distance",
]

Pose2D = tuple[float, float, float]

#: ``(label, x, y, radius)``: floor disk (m) covered by a device at a named instant,
#: e.g. ``("ugv_0 start", 0.0, 0.0, 0.225)``.
Disk = tuple[str, float, float, float]


def advanced(pose: Pose2D, distance: float) -> Pose2D:
    """``pose`` moved ``distance`` m along its heading (negative: backward)."""
    x, y, yaw = pose
    return (x + distance * math.cos(yaw), y + distance * math.sin(yaw), yaw)


def in_body_frame(pose: Pose2D, forward: float, left: float, yaw: float = 0.0) -> Pose2D:
    """The pose at ``(forward, left)`` m and relative heading ``yaw`` rad in the body frame of ``pose``."""
    x, y, heading = pose
    c, s = math.cos(heading), math.sin(heading)
    return (x + c * forward - s * left, y + s * forward + c * left, heading + yaw)


def shifted(pose: Pose2D, offset: Sequence[float]) -> Pose2D:
    """``pose`` translated by ``offset[:2]`` m in W and turned by ``offset[2]`` rad."""
    return (pose[0] + offset[0], pose[1] + offset[1], pose[2] + offset[2])


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def convex_hull(points: np.ndarray | Sequence[Sequence[float]]) -> np.ndarray:
    """Convex hull (k, 2) of 2D points, counter-clockwise, without repeated vertices.

    Collinear input gives its two end points, a single (repeated) point gives one row.
    """
    pts = np.unique(np.asarray(points, dtype=float).reshape(-1, 2), axis=0)  # sorted by x, then y
    if len(pts) <= 2:
        return pts
    lower: list[np.ndarray] = []
    for p in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], p) <= 0.0:
            lower.pop()
        lower.append(p)
    upper: list[np.ndarray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], p) <= 0.0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _edges(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (k, 2) of the closed polygon's edges (a point is one zero-length edge)."""
    return poly, np.roll(poly, -1, axis=0)


def _point_segment_distances(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, m) distances from n points to m segments ``a[j]-b[j]``."""
    ab = b - a
    length2 = np.einsum("mi,mi->m", ab, ab)
    ap = points[:, None, :] - a[None, :, :]
    t = np.einsum("nmi,mi->nm", ap, ab) / np.where(length2 > 0.0, length2, 1.0)
    np.clip(t, 0.0, 1.0, out=t)
    gap = ap - t[..., None] * ab[None, :, :]
    return np.sqrt(np.einsum("nmi,nmi->nm", gap, gap))


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _edges_cross(p: np.ndarray, q: np.ndarray) -> bool:
    """Whether an edge of polygon ``p`` properly crosses an edge of polygon ``q``."""
    a0, a1 = (e[:, None, :] for e in _edges(p))
    b0, b1 = (e[None, :, :] for e in _edges(q))
    o1 = _orientation(a0, a1, b0)
    o2 = _orientation(a0, a1, b1)
    o3 = _orientation(b0, b1, a0)
    o4 = _orientation(b0, b1, a1)
    return bool(np.any((o1 * o2 < 0.0) & (o3 * o4 < 0.0)))


def _any_inside(points: np.ndarray, poly: np.ndarray) -> bool:
    """Whether any point lies inside (or on) the counter-clockwise convex polygon ``poly`` (>= 3 vertices)."""
    if len(poly) < 3:
        return False
    a, b = _edges(poly)
    side = _orientation(a[None, :, :], b[None, :, :], points[:, None, :])
    return bool(np.any(np.all(side >= 0.0, axis=1)))


def convex_polygons_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Distance (m) between two convex polygons given counter-clockwise; 0 if they intersect.

    Either may be degenerate (a segment of two points or a single point).
    """
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    if _any_inside(p, q) or _any_inside(q, p) or _edges_cross(p, q):
        return 0.0
    d_pq = _point_segment_distances(p, *_edges(q)).min()
    d_qp = _point_segment_distances(q, *_edges(p)).min()
    return float(min(d_pq, d_qp))
