"""A file of robots on a bent trail: a sideways jog around a wall.

The leader's *trail* starts at its start pose ``(x, y, h)``: straight ahead for
:data:`JOG_START_M`, then a diagonal turned by :data:`JOG_ANGLE_RAD` towards the
side of ``bend`` (left for ``bend > 0``) until it is ``|bend|`` m to that side,
then straight again with heading ``h``. Arc length ``s`` (m) measures the trail
from the leader's start; behind it (``s < 0``) the trail continues straight
backwards, where the followers start.

Every robot of the file travels the same trail: robot ``k`` starts at
``s = -k * distance`` and its goal lies ``goal_distance`` m of trail farther on,
with the heading of the segment it lies on. The trail's corners between its
start and its goal are its route (``Scenario.routes``): the robot drives to each
with the heading of the segment that leads there. A wall (:func:`jog_wall`) on
the straight line beyond the jog makes the way straight ahead a dead end.

Units: metres and radians, poses ``(x, y, yaw)`` in the world frame W.
"""

from __future__ import annotations

import math

from moma_env.scenarios.layout import Pose2D, in_body_frame
from moma_env.world import BoxObstacle

__all__ = ["JOG_START_M", "JOG_ANGLE_RAD", "WALL_DEPTH_M", "WALL_GAP_M", "jog_length", "trail_corners", "trail_pose", "jog_wall"]

#: Straight run (m) of the leader's trail before the jog starts.
JOG_START_M = 0.5
#: Angle (rad) between the jog's diagonal and the file's heading.
JOG_ANGLE_RAD = math.radians(30.0)
#: Depth (m) of the wall along the file's heading.
WALL_DEPTH_M = 1.0
#: Gap (m) between the wall and the footprint of a robot on the trail.
WALL_GAP_M = 0.2
#: How far (m) the wall reaches beyond the straight line, away from the jog.
WALL_OVERHANG_M = 0.5


def jog_length(bend: float) -> float:
    """Length (m) of the jog's diagonal for a sideways offset of ``bend`` m."""
    return abs(bend) / math.sin(JOG_ANGLE_RAD)


def trail_corners(start: Pose2D, bend: float) -> tuple[tuple[float, Pose2D], ...]:
    """The trail's two corners as ``(s, pose)``: the pose's position is the corner and its
    yaw the heading of the segment that arrives there (the start's heading, then the
    diagonal's)."""
    side = math.copysign(1.0, bend)
    run = jog_length(bend) * math.cos(JOG_ANGLE_RAD)
    first = in_body_frame(start, JOG_START_M, 0.0)
    second = in_body_frame(start, JOG_START_M + run, bend, side * JOG_ANGLE_RAD)
    return ((JOG_START_M, first), (JOG_START_M + jog_length(bend), second))


def trail_pose(start: Pose2D, bend: float, s: float) -> Pose2D:
    """The pose at arc length ``s`` (m) of the trail, heading along the segment it lies on
    (at a corner: the segment that arrives there)."""
    (s1, first), (s2, second) = trail_corners(start, bend)
    if s <= s1:
        return in_body_frame(start, s, 0.0)
    if s <= s2:
        heading = second[2]
        d = s - s1
        return (first[0] + d * math.cos(heading), first[1] + d * math.sin(heading), heading)
    return in_body_frame((second[0], second[1], start[2]), s - s2, 0.0)


def jog_wall(start: Pose2D, bend: float, radius: float) -> BoxObstacle:
    """The wall beyond the jog: from the end of the diagonal on, ``WALL_DEPTH_M`` deep along
    the heading, from ``WALL_OVERHANG_M`` beyond the straight line to ``radius +
    WALL_GAP_M`` short of the trail after the jog."""
    side = math.copysign(1.0, bend)
    run = jog_length(bend) * math.cos(JOG_ANGLE_RAD)
    near = abs(bend) - radius - WALL_GAP_M  # the wall's edge towards the jog, from the straight line
    far = -WALL_OVERHANG_M
    centre = in_body_frame(start, JOG_START_M + run + 0.5 * WALL_DEPTH_M, side * 0.5 * (near + far))
    return BoxObstacle(x=centre[0], y=centre[1], width=WALL_DEPTH_M, height=near - far, yaw=start[2])
