"""Top observer: ground robots with boards on top, a downward camera above them.

The paper's main configuration (section IV, the 1 m square): UGVs ``ugv_0`` ..
``ugv_{N-1}`` carry face-up ArUco boards (``markers.board_for_robot(i)``: ids
``4i..4i+3``, of ``markers.team_dictionary(N)``: DICT_4X4_50 up to 12 robots, a
larger 4x4 dictionary beyond, at most ``markers.MAX_TEAM_BOARDS`` robots) and an
observer (an Ar.Drone quadcopter or a hand-held camera) looks down on them from
``altitude``. All robots start static; each one's goal is its start shifted by
``goal_offset``, and with ``goal_spread`` above 1 also moved away from the
formation's centre: the team arrives spread out (``goal_spread`` times its starting
offsets from the centre), and the observer must climb to keep everyone in view
until its ceiling (``UAVConfig.max_altitude``) stops it.

Formation (m, in the frame of ``start``: x along the robots' heading, y to
their left), ``spacing`` between neighbours, centred on ``start``:

* ``"row"``: side by side along y, ``ugv_0`` on the right (like the square's
  main robot with its buddy on its left).
* ``"compact"``: rows of ``ceil(sqrt(N))`` robots, front row first, each row
  filled from the right and centred (2 robots: a row; 3: a triangle; 4: a
  square), so that more robots fit in the camera's view.

The observer starts above ``start`` with the robots' heading: its image's long
side (720 px) spans the row. Several observers (``observer`` a tuple of kinds,
e.g. ``("quadcopter", "handheld")``) watch the same team at once: the k-th of n
starts ``(k - (n - 1) / 2) * observer_spacing`` to the left of ``start``, all at
``altitude``; they are named ``uav_0``, ``uav_1``, ... (cameras ``uav_k/camera``),
a single observer ``uav`` (camera ``uav/camera``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import ClassVar

import numpy as np

from moma_env.config import ConfigError, check_choice, check_count, check_positive, check_range
from moma_env.geometry import wrap_angle
from moma_env.markers import board_for_robot, team_dictionary
from moma_env.scenarios.common import (
    Layout,
    ScenarioConfig,
    check_team_boards,
    default_ugv_radius,
    field_default,
    planar_pose,
    ugv_name,
)
from moma_env.scenarios.layout import Pose2D, in_body_frame, shifted
from moma_env.scenarios.sampling import (
    ALTITUDE_RANGE_M,
    draw_until_valid,
    first_with_team,
    random_camera,
    random_goal_distance,
    random_heading,
    random_surroundings,
)
from moma_env.scenarios.spec import ScenarioSpec
from moma_env.world import UAV_KINDS, UAVConfig, UGVConfig, checked_observer_kinds

__all__ = [
    "TopObserverConfig",
    "FORMATIONS",
    "formation_offsets",
    "MAX_RANDOM_UGVS",
    "MAX_KEPT_UGVS",
    "MAX_GOAL_SPREAD",
    "MAX_OBSERVERS",
    "SPEC",
]

#: Formations the robots may start in.
FORMATIONS = ("compact", "row")
#: Largest number of robots a random configuration draws (at least 2).
MAX_RANDOM_UGVS = 4
#: Largest team a random configuration keeps (``random(rng, n_ugvs=k)``): at 12 robots
#: about one draw in four still sees every board from the observer (a compact team
#: under a high observer with a short lens), so the generator's attempts suffice.
MAX_KEPT_UGVS = 12
#: Largest ``goal_spread``: the team arrives at most this many times as spread out as it starts.
MAX_GOAL_SPREAD = 3.0
#: Largest number of observers watching the team at once.
MAX_OBSERVERS = 4
#: Largest turn (rad) of a random goal relative to the start.
_MAX_RANDOM_GOAL_TURN = math.pi / 2


def formation_offsets(n_ugvs: int, spacing: float, formation: str) -> np.ndarray:
    """(n, 2) positions ``(forward, left)`` (m) of the robots relative to the formation centre."""
    if formation == "row":
        return np.column_stack([np.zeros(n_ugvs), (np.arange(n_ugvs) - (n_ugvs - 1) / 2.0) * spacing])
    cols = math.ceil(math.sqrt(n_ugvs))
    rows = math.ceil(n_ugvs / cols)
    offsets = np.empty((n_ugvs, 2))
    for k in range(n_ugvs):
        row, col = divmod(k, cols)
        in_row = min(cols, n_ugvs - row * cols)
        offsets[k] = ((rows - 1) / 2.0 - row) * spacing, (col - (in_row - 1) / 2.0) * spacing
    return offsets


@dataclass(frozen=True, kw_only=True)
class TopObserverConfig(ScenarioConfig):
    """UGVs with boards on top seen from above (fields in addition to :class:`ScenarioConfig`'s).

    Attributes:
        n_ugvs: number of ground robots (>= 2: one moves while another is its reference).
        spacing: distance between neighbouring robots' centres (m), at least
            their diameter (the square experiment: 0.6 m).
        formation: ``"compact"`` or ``"row"`` (see the module docstring).
        start: ``(x, y, yaw)`` of the formation centre and the robots' common heading.
        goal_offset: ``(dx, dy, dyaw)`` in W from every robot's start to its goal
            (default: 2 m along +x).
        observer: ``"quadcopter"`` (Ar.Drone) or ``"handheld"``; or a tuple of
            those kinds, one per observer, for several observers (up to
            :data:`MAX_OBSERVERS`) watching the team at once.
        observer_spacing: distance (m) between neighbouring observers at the
            start, across the robots' heading (several observers only).
        altitude: height of the observers' bodies above the floor at the start (m).
        goal_spread: how spread out the team arrives, in [1, :data:`MAX_GOAL_SPREAD`]:
            each goal is the start shifted by ``goal_offset`` plus
            ``(goal_spread - 1)`` times the robot's offset from the formation's centre
            (1: the formation is kept).
    """

    NAME: ClassVar[str] = "top_observer"
    TEAM_FIELDS: ClassVar[Mapping[str, tuple[float, float]]] = MappingProxyType(
        {"n_ugvs": (2, MAX_KEPT_UGVS), "goal_spread": (1.0, MAX_GOAL_SPREAD)}
    )

    n_ugvs: int = 2
    spacing: float = 0.6
    formation: str = "compact"
    start: Pose2D = (0.0, 0.0, 0.0)
    goal_offset: Pose2D = (2.0, 0.0, 0.0)
    observer: str | tuple[str, ...] = "quadcopter"
    observer_spacing: float = 0.5
    altitude: float = 1.6
    goal_spread: float = 1.0

    def _check_fields(self) -> None:
        check_count(self._field("n_ugvs"), self.n_ugvs, minimum=2)
        check_team_boards(self._field("n_ugvs"), self.n_ugvs, self.n_ugvs)
        check_positive(self._field("spacing"), self.spacing)
        diameter = 2.0 * default_ugv_radius()
        if self.spacing < diameter:
            raise ConfigError(
                self._field("spacing"), f"must be at least the robots' diameter {diameter} m, got {self.spacing}"
            )
        check_choice(self._field("formation"), self.formation, FORMATIONS)
        object.__setattr__(self, "start", planar_pose(self._field("start"), self.start))
        object.__setattr__(self, "goal_offset", planar_pose(self._field("goal_offset"), self.goal_offset))
        object.__setattr__(self, "observer", checked_observer_kinds(self._field("observer"), self.observer, MAX_OBSERVERS))
        check_positive(self._field("observer_spacing"), self.observer_spacing)
        low, high = field_default(UAVConfig, "min_altitude"), field_default(UAVConfig, "max_altitude")
        check_range(self._field("altitude"), self.altitude, low, high)
        check_range(self._field("goal_spread"), self.goal_spread, 1.0, MAX_GOAL_SPREAD)

    def _make_layout(self) -> Layout:
        radius = default_ugv_radius()
        ugvs, goals, disks = [], {}, []
        dictionary = team_dictionary(self.n_ugvs)
        centre = self.start
        for i, (forward, left) in enumerate(formation_offsets(self.n_ugvs, self.spacing, self.formation).tolist()):
            name = ugv_name(i)
            start = in_body_frame(self.start, forward, left)
            start = (start[0], start[1], float(wrap_angle(start[2])))
            goal = shifted(start, self.goal_offset)
            if self.goal_spread != 1.0:
                away = self.goal_spread - 1.0
                goal = (goal[0] + away * (start[0] - centre[0]), goal[1] + away * (start[1] - centre[1]), goal[2])
            goal = (goal[0], goal[1], float(wrap_angle(goal[2])))
            ugvs.append(UGVConfig(name=name, initial_pose=start, board=board_for_robot(i, dictionary=dictionary)))
            goals[name] = goal
            disks += [(f"{name} start", start[0], start[1], radius), (f"{name} goal", goal[0], goal[1], radius)]
        kinds = self.observer_kinds
        uavs = []
        for k, kind in enumerate(kinds):
            if len(kinds) == 1:
                x, y, yaw = self.start
            else:
                x, y, yaw = in_body_frame(self.start, 0.0, (k - (len(kinds) - 1) / 2.0) * self.observer_spacing)
            placement = {"initial": (x, y, float(wrap_angle(yaw))), "altitude": float(self.altitude)}
            if len(kinds) > 1:
                placement |= {"name": f"uav_{k}", "camera_name": f"uav_{k}/camera"}
            uavs.append(UAVConfig.handheld(**placement) if kind == "handheld" else UAVConfig(**placement))
        return Layout(
            ugvs=tuple(ugvs),
            goals=goals,
            disks=tuple(disks),
            movers=self.n_ugvs,
            path_m=self._longest_path(ugvs, goals),
            uavs=tuple(uavs),
        )

    def _longest_path(self, ugvs: list[UGVConfig], goals: Mapping[str, Pose2D]) -> float:
        """Distance (m) the robot farthest from its goal travels: the goal offset's
        length when the formation is kept."""
        if self.goal_spread == 1.0:
            return math.hypot(self.goal_offset[0], self.goal_offset[1])
        return max(math.hypot(goals[u.name][0] - u.initial_pose[0], goals[u.name][1] - u.initial_pose[1]) for u in ugvs)

    @property
    def observer_kinds(self) -> tuple[str, ...]:
        """The observers' kinds, one per observer."""
        return (self.observer,) if isinstance(self.observer, str) else tuple(self.observer)

    def required_views(self) -> Mapping[str, tuple[str, ...]]:
        """Every observer's camera sees every robot's board."""
        team = tuple(ugv_name(i) for i in range(self.n_ugvs))
        return {uav.camera_name: team for uav in self.layout.uavs}

    @classmethod
    def random(cls, rng: np.random.Generator, **team: float) -> TopObserverConfig:
        """Random robots (2-4, random formation), start heading, goal (1-3 m in a random
        direction, turned by up to 90 degrees), observer kind and altitude (1.2-2.5 m),
        camera, arena and obstacles; every draw from ``rng``.

        ``n_ugvs=k`` keeps the team at ``k`` robots, 2 to :data:`MAX_KEPT_UGVS`
        (ConfigError naming ``top_observer.n_ugvs`` otherwise): for ``k <= 4`` the
        first free draw with ``k`` robots, beyond that a draw with ``k`` fixed (see
        :mod:`moma_env.scenarios.sampling`). ``goal_spread=s`` keeps every draw's
        ``goal_spread`` at ``s`` (default 1: the draws are those without it).
        """
        checked = cls.check_team(team)
        kept = checked.get("n_ugvs")
        spread = checked.get("goal_spread", 1.0)
        if kept is not None and kept <= MAX_RANDOM_UGVS:
            free = cls.random if spread == 1.0 else (lambda rng: cls.random(rng, goal_spread=spread))
            return first_with_team(cls, rng, free, {"n_ugvs": kept})

        def draw(rng: np.random.Generator) -> TopObserverConfig:
            n_ugvs = int(rng.integers(2, MAX_RANDOM_UGVS + 1)) if kept is None else kept
            formation = FORMATIONS[int(rng.integers(len(FORMATIONS)))]
            heading = random_heading(rng)
            distance, direction = random_goal_distance(rng), random_heading(rng)
            turn = float(rng.uniform(-_MAX_RANDOM_GOAL_TURN, _MAX_RANDOM_GOAL_TURN))
            observer = UAV_KINDS[int(rng.integers(len(UAV_KINDS)))]
            altitude = float(rng.uniform(*ALTITUDE_RANGE_M))
            config = cls(
                n_ugvs=n_ugvs,
                formation=formation,
                start=(0.0, 0.0, heading),
                goal_offset=(distance * math.cos(direction), distance * math.sin(direction), turn),
                observer=observer,
                altitude=altitude,
                camera=random_camera(rng),
                goal_spread=spread,
            )
            return replace(config, **random_surroundings(rng, config.occupied_disks))

        return draw_until_valid(cls, rng, draw)


#: The top observer's place in the registry: the plan checker keeps the team within
#: the observer's coverage (no per-camera motion views).
SPEC = ScenarioSpec(
    config_type=TopObserverConfig,
    gymnasium_id="moma_env/TopObserver-v0",
    pettingzoo_module="top_observer_v0",
    schedule="moma_env.planning.planner:top_observer_schedule",
    scripted_policy="agents.policies.top_observer:TopObserverLeapfrog",
    observer_coverage=True,
)
