"""Two-robot leapfrog schedule on MOMA estimates: one moves while the other is static.

The schedule is the perception-interaction cycle of the paper for two UGVs under a
top observer: the *mover* drives to its next waypoint on its estimated pose while
the other robot is the static reference; when it arrives it is declared static,
both stay static for ``dwell_s`` (the estimator averages its switch window), then
the other robot is declared mobile and takes its turn.

The schedule only decides; the caller applies its decisions to the world (the
lock) and to the estimator (``set_static``), so the same object drives a
simulation or real robots.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from moma_env.control.waypoint import WaypointFollower

__all__ = ["Leg", "StateChange", "LeapfrogSchedule"]

Pose2D = tuple[float, float, float]


@dataclass(frozen=True)
class Leg:
    """One turn: ``robot`` drives to ``waypoint`` (x, y, theta) while the others are static."""

    robot: str
    waypoint: Pose2D


@dataclass(frozen=True)
class StateChange:
    """A declaration to apply: ``robot`` becomes static (True) or mobile (False)."""

    robot: str
    static: bool


@dataclass
class LeapfrogSchedule:
    """Runs a list of legs in order, with a dwell at every switch.

    Args:
        legs: the turns, in order.
        follower: waypoint controller used for the mover.
        dwell_s: time both robots stay static at each switch (s).
        robots: names of all robots; all start static.
        start_after_s: time before the first leg starts (s), e.g. for the
            observer to find the boards.
    """

    legs: Sequence[Leg]
    follower: WaypointFollower
    dwell_s: float
    robots: Sequence[str]
    start_after_s: float = 0.0
    _index: int = field(default=0, init=False)
    _moving: bool = field(default=False, init=False)
    _dwell_until: float = field(default=0.0, init=False)

    def __post_init__(self) -> None:
        self._dwell_until = self.start_after_s

    @property
    def done(self) -> bool:
        """True once every leg has been driven and its robot is static again."""
        return self._index >= len(self.legs)

    @property
    def current_leg(self) -> Leg | None:
        """The leg in progress (or about to start), None when done."""
        return None if self.done else self.legs[self._index]

    @property
    def leg_index(self) -> int:
        """Index of the current leg."""
        return self._index

    def step(
        self, time: float, poses: dict[str, Pose2D | None], ready: Callable[[str], bool] | None = None
    ) -> tuple[dict[str, np.ndarray], list[StateChange]]:
        """Commands and declarations for this control step.

        Args:
            time: current time (s).
            poses: estimated planar pose of each robot, None where the estimate
                is not fresh (the mover then waits where it is).
            ready: ``ready(robot)``: whether a static robot's switch window is
                ready (``MomaEstimator.window_ready``); the next leg starts
                only once the dwell is over and every other robot is ready, so
                that the mover always leaves a frozen reference behind. None:
                the dwell alone decides.

        Returns:
            Body-frame velocity commands for every robot and the state changes to
            apply now.
        """
        commands = {name: np.zeros(3) for name in self.robots}
        changes: list[StateChange] = []
        if self.done:
            return commands, changes
        leg = self.legs[self._index]
        if not self._moving:
            others_ready = ready is None or all(ready(name) for name in self.robots if name != leg.robot)
            if time >= self._dwell_until and others_ready:
                self._moving = True
                changes.append(StateChange(leg.robot, static=False))
            return commands, changes
        pose = poses.get(leg.robot)
        if pose is None:
            return commands, changes
        if self.follower.reached(pose, leg.waypoint):
            changes.append(StateChange(leg.robot, static=True))
            self._moving = False
            self._dwell_until = time + self.dwell_s
            self._index += 1
            return commands, changes
        commands[leg.robot] = self.follower.command(pose, leg.waypoint)
        return commands, changes
