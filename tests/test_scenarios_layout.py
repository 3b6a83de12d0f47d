"""Planar layout helpers: poses, formations, convex hulls and polygon distances."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.scenarios.layout import advanced, convex_hull, convex_polygons_distance, in_body_frame, shifted
from moma_env.scenarios.top_observer import formation_offsets
from moma_env.world import BoxObstacle
from moma_env.world.arena import box_corners

COORD = st.floats(min_value=-5.0, max_value=5.0, allow_nan=False)
SIDE = st.floats(min_value=0.05, max_value=2.0, allow_nan=False)
ANGLE = st.floats(min_value=-math.pi, max_value=math.pi, allow_nan=False)


def test_pose_helpers():
    assert advanced((1.0, 2.0, math.pi / 2), 0.5) == pytest.approx((1.0, 2.5, math.pi / 2))
    assert advanced((1.0, 2.0, 0.0), -0.8) == pytest.approx((0.2, 2.0, 0.0))
    assert in_body_frame((1.0, 2.0, math.pi / 2), 0.3, 0.4, 0.1) == pytest.approx((0.6, 2.3, math.pi / 2 + 0.1))
    assert shifted((1.0, 2.0, 0.5), (0.5, -1.0, 0.25)) == pytest.approx((1.5, 1.0, 0.75))


def test_convex_hull_shapes():
    square = [(0, 0), (1, 0), (1, 1), (0, 1), (0.5, 0.5), (0.5, 0.0)]
    hull = convex_hull(square)
    assert len(hull) == 4 and {tuple(p) for p in hull.tolist()} == {(0, 0), (1, 0), (1, 1), (0, 1)}
    signed_area = 0.5 * np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1])
    assert signed_area == pytest.approx(1.0)  # counter-clockwise
    np.testing.assert_array_equal(convex_hull([(0, 0), (2, 2), (1, 1)]), [[0, 0], [2, 2]])
    np.testing.assert_array_equal(convex_hull([(3, 4), (3, 4)]), [[3, 4]])


def test_polygon_distances_known_cases():
    unit = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
    assert convex_polygons_distance(unit, unit + (2.0, 0.0)) == pytest.approx(1.0)
    assert convex_polygons_distance(unit, unit + (2.0, 2.0)) == pytest.approx(math.sqrt(2.0))
    assert convex_polygons_distance(unit, unit + (0.5, 0.5)) == 0.0  # overlap
    assert convex_polygons_distance(unit, 0.25 * unit + 0.3) == 0.0  # containment
    assert convex_polygons_distance(0.25 * unit + 0.3, unit) == 0.0
    cross = np.array([(0.5, -1.0), (0.5, 2.0)])  # a segment through the square
    assert convex_polygons_distance(cross, unit) == 0.0
    assert convex_polygons_distance(np.array([(-1.0, -1.0), (-1.0, 3.0)]), unit) == pytest.approx(1.0)
    assert convex_polygons_distance(np.array([(3.0, 0.5)]), unit) == pytest.approx(2.0)


def _point_box_distance(x: float | np.ndarray, y: float | np.ndarray, box: BoxObstacle) -> np.ndarray:
    """Independent reference: distance from points to a box, in the box's frame."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    lx, ly = c * (x - box.x) + s * (y - box.y), -s * (x - box.x) + c * (y - box.y)
    dx = np.maximum(np.abs(lx) - box.width / 2.0, 0.0)
    dy = np.maximum(np.abs(ly) - box.height / 2.0, 0.0)
    return np.hypot(dx, dy)


@settings(max_examples=100, deadline=None)
@given(x=COORD, y=COORD, bx=COORD, by=COORD, w=SIDE, h=SIDE, yaw=ANGLE)
def test_point_to_box_distance_matches_reference(x, y, bx, by, w, h, yaw):
    box = BoxObstacle(bx, by, w, h, yaw)
    got = convex_polygons_distance(np.array([(x, y)]), box_corners(box))
    assert got == pytest.approx(float(_point_box_distance(x, y, box)), abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(
    ax=COORD, ay=COORD, bx=COORD, by=COORD, bx2=COORD, by2=COORD, w=SIDE, h=SIDE, yaw=ANGLE,
)
def test_segment_to_box_distance_is_the_min_over_the_segment(ax, ay, bx, by, bx2, by2, w, h, yaw):
    box = BoxObstacle(bx2, by2, w, h, yaw)
    segment = np.array([(ax, ay), (bx, by)])
    got = convex_polygons_distance(segment, box_corners(box))
    t = np.linspace(0.0, 1.0, 2001)[:, None]
    points = (1.0 - t) * segment[0] + t * segment[1]
    closest = float(_point_box_distance(points[:, 0], points[:, 1], box).min())
    # Exact minimum <= any sample, and the dense samples get within the step size of it.
    step = float(np.linalg.norm(segment[1] - segment[0])) / 2000
    assert got <= closest + 1e-9
    assert got >= closest - step - 1e-9


@pytest.mark.parametrize("formation", ["compact", "row"])
@pytest.mark.parametrize("n", range(2, 10))
def test_formations_are_centred_with_spacing(formation, n):
    offsets = formation_offsets(n, 0.6, formation)
    assert offsets.shape == (n, 2)
    np.testing.assert_allclose(offsets.min(axis=0) + offsets.max(axis=0), 0.0, atol=1e-12)
    gaps = np.linalg.norm(offsets[:, None] - offsets[None], axis=-1) + np.eye(n) * 1e9
    assert gaps.min() == pytest.approx(0.6)
    if formation == "compact":  # no wider than it is deep by more than one robot
        extent = offsets.max(axis=0) - offsets.min(axis=0)
        assert extent[1] - extent[0] <= 0.6 + 1e-12
