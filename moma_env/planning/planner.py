"""MOMA navigation: :func:`plan` the turns that take a scenario's team to its goals.

Each UGV gets a shortest collision-free path from its start to its goal
(:func:`moma_env.planning.paths.shortest_path`, obstacles and walls kept
``radius + CLEARANCE_M + PATH_SLACK_M`` away; other devices are left to the
turn checks). Progress along a path is its arc length ``s`` (m). A schedule
per configuration (named by its ``ScenarioSpec.schedule``, a callable taking the
:class:`Team`) then picks, turn after turn, one device and how far it
advances; every candidate leg is checked with
:class:`~moma_env.planning.validate.RuleChecker` (leg length, collisions,
observability) and shortened (``ADVANCE_FRACTIONS`` of the wanted advance)
until it passes. During translation a robot keeps its heading (the robots are
omnidirectional); final turns rotate each robot in place to its goal yaw.

Schedules:

* ``top_observer`` (:func:`top_observer_schedule`): the robot farthest behind
  (smallest fraction of its path done; ties: the one farthest ahead along its
  way, so the front robot of a formation clears the way) advances up to
  ``leg_length``; the coverage rule shortens the leg if the team would spread
  too far.
* ``caterpillar`` / ``caterpillar_multi`` (:func:`robot_file_schedule`): rounds
  down the file; the leader advances up to ``leg_length`` (shortened while its
  follower would lose its board), then each follower advances up to
  ``leg_length`` but no farther than the progress of the robot ahead (so it
  keeps at least its start stand-off).
* ``caterpillar_sled`` (:func:`sled_schedule`): the robot advances up to
  ``leg_length`` (the rope's ``max_rope`` and the camera's range shorten it)
  with the sled static; then the sled turn: the sled is reeled straight
  towards the robot's back anchor until the rope is back to its start length
  (``rope_length``, whose view of the board the scenario generator checked;
  ``min_rope`` itself can be too close for a whole view), keeping its yaw.

:func:`plan` raises :class:`~moma_env.planning.plan.PlanningError` when a
schedule stalls (no device can advance), exceeds ``max_turns``, or its result
fails :func:`~moma_env.planning.validate.validate` (never returns an invalid plan).
"""

from __future__ import annotations

import math

import numpy as np

from moma_env.geometry import wrap_angle
from moma_env.planning.paths import point_along, polyline_length, shortest_path
from moma_env.planning.plan import Plan, PlanningError, Pose2D, Turn
from moma_env.planning.validate import CLEARANCE_M, RuleChecker, enclosing_circle
from moma_env.scenarios.base import Scenario
from moma_env.scenarios.registry import SCENARIO_SPECS

__all__ = [
    "plan",
    "SUPPORTED_CONFIGURATIONS",
    "Team",
    "top_observer_schedule",
    "robot_file_schedule",
    "sled_schedule",
    "PATH_SLACK_M",
    "ADVANCE_FRACTIONS",
    "MIN_ADVANCE_M",
    "PREFERRED_COVERAGE_FRACTION",
    "team_spread",
]

#: Extra clearance (m) of the planned paths beyond the rule's CLEARANCE_M.
PATH_SLACK_M = 0.01
#: Fractions of the wanted advance tried, in order, until a leg passes the checks.
ADVANCE_FRACTIONS = (1.0, 0.8, 0.6, 0.4, 0.25, 0.1)
#: Top observer: switch points are preferred where the team's spread (enclosing circle
#: plus a board) stays within this fraction of the camera's coverage radius, so that at
#: a switch, with the UAV centred over the team, the boards are away from the image
#: border (where lens distortion and a tilting UAV hurt the estimate most). A leg that
#: cannot meet the preference falls back to the hard coverage rule.
PREFERRED_COVERAGE_FRACTION = 0.6
#: Advances shorter than this (m) are not worth a turn.
MIN_ADVANCE_M = 0.01
#: Progress (m) within which a path counts as done.
_DONE_M = 1e-9


class Team:
    """Devices' poses, paths and progress while a plan is built: what a schedule works on.

    A schedule (a configuration's ``ScenarioSpec.schedule``) is a callable
    ``schedule(team) -> None`` that advances devices with :meth:`try_advance` and
    :meth:`move_to` until every UGV's path is :meth:`done`, raising :meth:`stall`'s
    error when no device can advance. Progress and lengths are arc lengths (m).

    Args:
        scenario: the episode layout.
        checker: the rule checker of ``scenario`` (legs are tested with it).
        max_turns: most turns the plan may have.

    Attributes:
        scenario, checker: as given.
        poses: device -> current pose ``(x, y, yaw)`` (m, rad).
        turns: turns committed so far.
        paths: UGV -> its path (polyline of ``(x, y)``, m) from start to goal.
        length: UGV -> its path's length (m).
        progress: UGV -> arc length done along its path (m).
        last_reason: the last rule violation that shortened or refused a leg.
    """

    def __init__(self, scenario: Scenario, checker: RuleChecker, max_turns: int) -> None:
        self.scenario, self.checker, self.max_turns = scenario, checker, max_turns
        self.poses: dict[str, Pose2D] = dict(checker.start)
        self.turns: list[Turn] = []
        self.paths: dict[str, list[tuple[float, float]]] = {}
        self.length: dict[str, float] = {}
        self.progress: dict[str, float] = {}
        self.last_reason = ""
        for name, goal in scenario.goals.items():
            start = self.poses[name]
            clearance = checker.radius[name] + CLEARANCE_M + PATH_SLACK_M
            try:
                path = shortest_path(start[:2], goal[:2], clearance, scenario.world.arena)
            except ValueError as error:
                raise PlanningError(f"{scenario.name}: {name}: {error}") from None
            self.paths[name] = path
            self.length[name] = polyline_length(path)
            self.progress[name] = 0.0

    def remaining(self, name: str) -> float:
        """Arc length (m) left on the path of UGV ``name``."""
        return self.length[name] - self.progress[name]

    def done(self, name: str) -> bool:
        """Whether UGV ``name`` has reached the end of its path."""
        return self.remaining(name) <= _DONE_M

    def _leg(self, name: str, s_to: float) -> tuple[Pose2D, ...]:
        """Waypoints from the current pose to progress ``s_to`` along the path, heading kept."""
        path, yaw = self.paths[name], self.poses[name][2]
        (x0, y0), k0 = point_along(path, self.progress[name])
        (x1, y1), k1 = point_along(path, s_to)
        points = [self.poses[name]]
        points += [(p[0], p[1], yaw) for p in path[k0 + 1 : k1 + 1]]
        points.append((x1, y1, yaw))
        return tuple(points)

    def commit(self, name: str, waypoints: tuple[Pose2D, ...]) -> None:
        """Append a turn of ``name`` along ``waypoints`` (unchecked); PlanningError past ``max_turns``."""
        if len(self.turns) >= self.max_turns:
            raise PlanningError(f"{self.scenario.name}: more than max_turns={self.max_turns} turns needed")
        self.turns.append(Turn(name, waypoints))
        self.poses[name] = waypoints[-1]

    def try_advance(self, name: str, wanted: float) -> float:
        """Advance ``name`` by the largest fraction of ``wanted`` (m) whose leg passes; the advance made (0 if none).

        With a top observer, legs whose end keeps the team's spread within
        :data:`PREFERRED_COVERAGE_FRACTION` of the coverage are tried first.
        """
        wanted = min(wanted, self.remaining(name), self.scenario.leg_length)
        coverage = self.checker.coverage
        passes = (True, False) if coverage is not None else (False,)
        for prefer_centre in passes:
            for fraction in ADVANCE_FRACTIONS:
                advance = wanted * fraction
                if advance < MIN_ADVANCE_M and advance < self.remaining(name) - _DONE_M:
                    break
                s_to = self.length[name] if advance >= self.remaining(name) - _DONE_M else self.progress[name] + advance
                waypoints = self._leg(name, s_to)
                if name in self.scenario.goals and s_to >= self.length[name]:
                    goal = self.scenario.goals[name]
                    waypoints = waypoints[:-1] + ((goal[0], goal[1], waypoints[-1][2]),)
                if prefer_centre:
                    ends = dict(self.poses) | {name: waypoints[-1]}
                    if team_spread(self.checker, ends) > PREFERRED_COVERAGE_FRACTION * coverage:
                        continue
                violations = self.checker.leg_violations(name, waypoints, self.poses)
                if not violations:
                    self.commit(name, waypoints)
                    self.progress[name] = s_to
                    return advance
                self.last_reason = f"{name}: {violations[0]}"
        return 0.0

    def move_to(self, name: str, target: Pose2D) -> bool:
        """One straight turn of ``name`` to ``target`` if it passes the checks."""
        waypoints = (self.poses[name], target)
        violations = self.checker.leg_violations(name, waypoints, self.poses)
        if violations:
            self.last_reason = f"{name}: {violations[0]}"
            return False
        self.commit(name, waypoints)
        return True

    def rotate_to_goals(self) -> None:
        """Final turns rotating every UGV in place to its goal yaw; PlanningError if one is refused."""
        for name, goal in self.scenario.goals.items():
            x, y, yaw = self.poses[name]
            if abs(float(wrap_angle(goal[2] - yaw))) > 1e-12:
                if not self.move_to(name, (x, y, yaw + float(wrap_angle(goal[2] - yaw)))):
                    raise PlanningError(f"{self.scenario.name}: cannot turn to the goal yaw: {self.last_reason}")

    def stall(self) -> PlanningError:
        """The error a schedule raises when no device can advance (with the last rejection)."""
        return PlanningError(f"{self.scenario.name}: no device can advance; last rejection: {self.last_reason}")


def team_spread(checker: RuleChecker, poses: dict[str, Pose2D]) -> float:
    """Radius (m) of the circle enclosing every robot's centre, plus a board's half-diagonal."""
    pts = np.array([poses[name][:2] for name in checker.radius if name in poses])
    return enclosing_circle(pts)[2] + checker.board_half_diagonal


def top_observer_schedule(team: Team) -> None:
    """Top observer: the robot farthest behind advances (see the module docstring)."""
    names = list(team.scenario.goals)
    direction = {}
    for name in names:
        (x0, y0), (x1, y1) = team.paths[name][0], team.paths[name][-1]
        norm = math.hypot(x1 - x0, y1 - y0) or 1.0
        direction[name] = ((x1 - x0) / norm, (y1 - y0) / norm)

    def key(name: str) -> tuple[float, float]:
        x, y, _ = team.poses[name]
        ahead = x * direction[name][0] + y * direction[name][1]
        return (round(team.progress[name] / max(team.length[name], 1e-9), 6), -ahead)

    while not all(team.done(n) for n in names):
        for name in sorted((n for n in names if not team.done(n)), key=key):
            if team.try_advance(name, team.scenario.leg_length) > 0.0 or team.done(name):
                break
        else:
            raise team.stall()


def robot_file_schedule(team: Team) -> None:
    """A file of robots (caterpillar, caterpillar_multi): rounds down the file (see the module docstring)."""
    names = sorted(team.scenario.goals, key=lambda n: team.scenario.world.ugv_index(n))
    while not all(team.done(n) for n in names):
        moved = False
        for k, name in enumerate(names):
            if team.done(name):
                continue
            wanted = team.scenario.leg_length
            if k > 0:  # keep behind the robot ahead (at least the start stand-off)
                wanted = min(wanted, team.progress[names[k - 1]] - team.progress[name])
                if team.done(names[k - 1]):
                    wanted = max(wanted, min(team.scenario.leg_length, team.remaining(name)))
            if wanted <= _DONE_M:
                continue
            moved |= team.try_advance(name, wanted) > 0.0
        if not moved:
            raise team.stall()


def _sled_target(team: Team, sled_name: str) -> Pose2D:
    """Sled pose with its anchor ``rope_length`` m from the robot's anchor, on the line between them, same yaw."""
    sled = team.scenario.world.sled(sled_name)
    rx, ry, ryaw = team.poses[sled.robot]
    sx, sy, syaw = team.poses[sled_name]
    (ax, ay), (bx, by) = sled.robot_anchor, sled.sled_anchor
    c, s = math.cos(ryaw), math.sin(ryaw)
    p = np.array([rx + c * ax - s * ay, ry + s * ax + c * ay])
    c, s = math.cos(syaw), math.sin(syaw)
    offset = np.array([c * bx - s * by, s * bx + c * by])
    q = np.array([sx, sy]) + offset
    rope = float(np.hypot(*(q - p)))
    reel = min(max(rope - sled.rope_length, 0.0), team.scenario.leg_length)
    if rope <= 0.0 or reel <= 0.0:
        return (sx, sy, syaw)
    q_new = q + (p - q) / rope * reel
    centre = q_new - offset
    return (float(centre[0]), float(centre[1]), syaw)


def sled_schedule(team: Team) -> None:
    """Robots towing sleds (caterpillar_sled): the robot advances, then its sled is reeled in
    (see the module docstring)."""
    sleds = team.scenario.world.sleds
    robots = [s.robot for s in sleds]
    while not all(team.done(r) for r in robots):
        moved = False
        for sled in sleds:
            if team.done(sled.robot):
                continue
            if team.try_advance(sled.robot, team.scenario.leg_length) > 0.0:
                moved = True
                target = _sled_target(team, sled.name)
                if target != team.poses[sled.name] and not team.move_to(sled.name, target):
                    raise PlanningError(f"{team.scenario.name}: cannot reel {sled.name} in: {team.last_reason}")
        if not moved:
            raise team.stall()


#: Configuration names :func:`plan` schedules: those whose ``ScenarioSpec`` names a schedule.
SUPPORTED_CONFIGURATIONS = tuple(name for name, spec in SCENARIO_SPECS.items() if spec.schedule is not None)


def plan(scenario: Scenario, *, max_turns: int = 500) -> Plan:
    """Turns that take every UGV of ``scenario`` to its goal under the MOMA rules.

    Args:
        scenario: the episode layout (its ``name`` selects the configuration's
            ``ScenarioSpec.schedule``, see the module docstring).
        max_turns: most turns the plan may have.

    Returns:
        A plan that :func:`~moma_env.planning.validate.validate` accepts.

    Raises:
        PlanningError: with the reason, if no plan was found (unsupported
            configuration, no path, stalled schedule, too many turns).
        TypeError, ValueError: on bad arguments.
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    if isinstance(max_turns, bool) or not isinstance(max_turns, int) or max_turns < 1:
        raise ValueError(f"max_turns must be an integer >= 1, got {max_turns!r}")
    spec = SCENARIO_SPECS.get(scenario.name)
    if spec is None or spec.schedule is None:
        raise PlanningError(
            f"configuration {scenario.name!r} is not supported yet; supported: {list(SUPPORTED_CONFIGURATIONS)}"
        )
    schedule = spec.load_schedule()
    checker = RuleChecker(scenario)
    team = Team(scenario, checker, max_turns)
    schedule(team)
    team.rotate_to_goals()
    result = Plan(scenario_name=scenario.name, start=checker.start, turns=tuple(team.turns))
    violations = checker.plan_violations(result)
    if violations:
        raise PlanningError(f"{scenario.name}: the schedule broke a rule: {violations[0]}")
    return result
