"""Shortest collision-free paths of a disk among box obstacles: a visibility graph.

A robot of radius ``r`` is a disk; it is clear of a box obstacle when the
distance from its centre to the box is at least ``r + clearance`` and clear of
the walls when its centre stays ``r + clearance`` inside the arena. The graph's
nodes are the start, the goal and the corners of every box grown by
``r + clearance + CORNER_SLACK_M`` on each side (a rectangle around the grown
disk-swept region, so a straight edge between two neighbouring grown corners
stays clear of its box); an edge exists when its segment keeps the required
distance from every box and stays inside the shrunken arena. Dijkstra on the
graph gives the shortest such polyline.

Units: metres; points ``(x, y)`` in the world frame W.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np

from moma_env.world import ArenaConfig, BoxObstacle

__all__ = ["CORNER_SLACK_M", "box_distances", "segment_clear", "shortest_path", "polyline_length", "point_along"]

#: Extra growth (m) of the boxes' corners beyond the required clearance (numerical room).
CORNER_SLACK_M = 0.01


def box_distances(points: np.ndarray, box: BoxObstacle) -> np.ndarray:
    """(n,) distances (m) from the points (n, 2) to the box (0 inside it)."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    d = np.asarray(points, dtype=float).reshape(-1, 2) - (box.x, box.y)
    lx = np.abs(c * d[:, 0] + s * d[:, 1]) - 0.5 * box.width
    ly = np.abs(-s * d[:, 0] + c * d[:, 1]) - 0.5 * box.height
    return np.hypot(np.maximum(lx, 0.0), np.maximum(ly, 0.0))


def _segment_box_distance(a: np.ndarray, b: np.ndarray, box: BoxObstacle) -> float:
    """Distance (m) from the segment a-b to the box (0 if they meet)."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    R = np.array([[c, s], [-s, c]])  # W -> box frame
    p, q = R @ (a - (box.x, box.y)), R @ (b - (box.x, box.y))
    hw, hh = 0.5 * box.width, 0.5 * box.height
    # The segment meets the box if clipping it to the box (Liang-Barsky) leaves something.
    t0, t1, d = 0.0, 1.0, q - p
    inside = True
    for pk, dk, lo, hi in ((p[0], d[0], -hw, hw), (p[1], d[1], -hh, hh)):
        if abs(dk) < 1e-15:
            if pk < lo or pk > hi:
                inside = False
                break
            continue
        ta, tb = sorted(((lo - pk) / dk, (hi - pk) / dk))
        t0, t1 = max(t0, ta), min(t1, tb)
        if t0 > t1:
            inside = False
            break
    if inside:
        return 0.0
    corners = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    # Otherwise the closest pair involves a segment end point or a box corner.
    ends = np.clip(np.array([p, q]), (-hw, -hh), (hw, hh))
    best = float(min(np.hypot(*(p - ends[0])), np.hypot(*(q - ends[1]))))
    length2 = float(d @ d)
    if length2 > 0.0:
        t = np.clip((corners - p) @ d / length2, 0.0, 1.0)
        gaps = corners - (p + t[:, None] * d)
        best = min(best, float(np.sqrt((gaps**2).sum(axis=1)).min()))
    return best


def segment_clear(a: Sequence[float], b: Sequence[float], clearance: float, arena: ArenaConfig) -> bool:
    """Whether a disk centre moving on the segment a-b keeps ``clearance`` (m) from every box
    and from the walls of ``arena``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    xmin, ymin, xmax, ymax = arena.bounds
    for p in (a, b):
        if not (xmin + clearance <= p[0] <= xmax - clearance and ymin + clearance <= p[1] <= ymax - clearance):
            return False
    return all(_segment_box_distance(a, b, box) >= clearance for box in arena.obstacles)


def _grown_corners(box: BoxObstacle, growth: float) -> np.ndarray:
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    hw, hh = 0.5 * box.width + growth, 0.5 * box.height + growth
    local = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    return local @ np.array([[c, s], [-s, c]]) + (box.x, box.y)


def shortest_path(
    start: Sequence[float], goal: Sequence[float], clearance: float, arena: ArenaConfig
) -> list[tuple[float, float]]:
    """Shortest polyline ``[start, ..., goal]`` (m, in W) whose every point keeps ``clearance``
    (m; robot radius + safety margin) from the boxes and walls of ``arena``.

    Raises ValueError if no such path exists in the visibility graph.
    """
    a = (float(start[0]), float(start[1]))
    g = (float(goal[0]), float(goal[1]))
    if segment_clear(a, g, clearance, arena):
        return [a, g]
    nodes = [a, g]
    for box in arena.obstacles:
        nodes += [tuple(p) for p in _grown_corners(box, clearance + CORNER_SLACK_M).tolist()]
    n = len(nodes)
    dist = [math.inf] * n
    previous = [-1] * n
    dist[0] = 0.0
    queue = [(0.0, 0)]
    edge_cache: dict[tuple[int, int], bool] = {}
    while queue:
        d, i = heapq.heappop(queue)
        if d > dist[i]:
            continue
        if i == 1:
            break
        for j in range(1, n):
            if j == i:
                continue
            key = (min(i, j), max(i, j))
            if key not in edge_cache:
                edge_cache[key] = segment_clear(nodes[i], nodes[j], clearance, arena)
            if not edge_cache[key]:
                continue
            nd = d + math.dist(nodes[i], nodes[j])
            if nd < dist[j] - 1e-12:
                dist[j], previous[j] = nd, i
                heapq.heappush(queue, (nd, j))
    if math.isinf(dist[1]):
        raise ValueError(f"no collision-free path from {a} to {g} with {clearance:.3f} m clearance")
    path, k = [], 1
    while k != -1:
        path.append(nodes[k])
        k = previous[k]
    return path[::-1]


def polyline_length(points: Sequence[Sequence[float]]) -> float:
    """Length (m) of the polyline through ``points``."""
    return sum(math.dist(p[:2], q[:2]) for p, q in zip(points, points[1:]))


def point_along(points: Sequence[Sequence[float]], s: float) -> tuple[tuple[float, float], int]:
    """The point at arc length ``s`` (m, clipped to the polyline) and the index of the
    vertex that starts its segment."""
    for k, (p, q) in enumerate(zip(points, points[1:])):
        length = math.dist(p[:2], q[:2])
        if s <= length or k == len(points) - 2:
            t = 0.0 if length == 0.0 else min(max(s / length, 0.0), 1.0)
            return (p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])), k
        s -= length
    return (float(points[-1][0]), float(points[-1][1])), max(len(points) - 2, 0)
