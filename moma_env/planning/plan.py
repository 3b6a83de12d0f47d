"""Data types of a MOMA navigation plan: :class:`Turn`, :class:`Plan`, :class:`PlanningError`.

A plan moves the devices of a scenario (UGVs and sleds) *in turns*: in each
turn exactly one device drives along a polyline while every other device stays
where it is (MOMA motion rules 1 and 2). Poses are planar ``(x, y, yaw)`` of
the device's body frame (a sled: its frame S) in the world frame W (m, m, rad).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

__all__ = ["Pose2D", "Turn", "Plan", "PlanningError"]

Pose2D = tuple[float, float, float]


class PlanningError(RuntimeError):
    """No plan satisfying the MOMA rules was found; the message says why."""


def _pose(what: str, value: object) -> Pose2D:
    try:
        x, y, yaw = (float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be (x, y, yaw), got {value!r}") from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ValueError(f"{what} must be finite, got {value!r}")
    return (x, y, yaw)


@dataclass(frozen=True)
class Turn:
    """One device's move while all others stay static.

    Attributes:
        device: name of the moving UGV or sled.
        waypoints: polyline of poses ``(x, y, yaw)`` in W (m, rad), at least two:
            the first is the device's pose before the turn, the last the turn's
            goal. Between waypoints the position moves on a straight line and the
            yaw turns linearly (the short way round); a pure rotation is two
            waypoints at the same position.
    """

    device: str
    waypoints: tuple[Pose2D, ...]

    def __post_init__(self) -> None:
        if not isinstance(self.device, str) or not self.device:
            raise ValueError(f"turn.device must be a non-empty device name, got {self.device!r}")
        points = tuple(_pose(f"turn.waypoints[{k}]", p) for k, p in enumerate(self.waypoints))
        if len(points) < 2:
            raise ValueError(f"turn.waypoints needs at least 2 poses (start and goal), got {len(points)}")
        object.__setattr__(self, "waypoints", points)

    @property
    def length(self) -> float:
        """Length of the polyline's translation (m); a pure rotation has length 0."""
        return sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(self.waypoints, self.waypoints[1:]))

    @property
    def goal(self) -> Pose2D:
        """The device's pose at the end of the turn."""
        return self.waypoints[-1]


@dataclass(frozen=True)
class Plan:
    """A sequence of turns from the start poses of a scenario.

    Attributes:
        scenario_name: name of the scenario's configuration, e.g. ``"caterpillar"``.
        start: device name -> start pose ``(x, y, yaw)`` (read-only mapping).
        turns: the turns, in order.
    """

    scenario_name: str
    start: Mapping[str, Pose2D]
    turns: tuple[Turn, ...]

    def __post_init__(self) -> None:
        start = {str(name): _pose(f"plan.start[{name!r}]", pose) for name, pose in dict(self.start).items()}
        object.__setattr__(self, "start", MappingProxyType(start))
        turns = tuple(self.turns)
        for k, turn in enumerate(turns):
            if not isinstance(turn, Turn):
                raise ValueError(f"plan.turns[{k}] must be a Turn, got {type(turn).__name__}")
        object.__setattr__(self, "turns", turns)

    def poses_after(self, k: int) -> dict[str, Pose2D]:
        """Every device's pose after turn ``k`` (0-based; ``-1``: the start poses)."""
        if isinstance(k, bool) or not isinstance(k, int) or not -1 <= k < len(self.turns):
            raise IndexError(f"turn index must be an int in [-1, {len(self.turns) - 1}], got {k!r}")
        poses = dict(self.start)
        for turn in self.turns[: k + 1]:
            poses[turn.device] = turn.goal
        return poses

    @property
    def final_poses(self) -> dict[str, Pose2D]:
        """Every device's pose after the last turn."""
        return self.poses_after(len(self.turns) - 1)

    @property
    def path_length(self) -> dict[str, float]:
        """Device name -> total translation over the plan (m)."""
        total = {name: 0.0 for name in self.start}
        for turn in self.turns:
            total[turn.device] = total.get(turn.device, 0.0) + turn.length
        return total
