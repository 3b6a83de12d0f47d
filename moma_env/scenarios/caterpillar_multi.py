"""Multi-robot caterpillar: a file of robots, each follower watching the robot ahead.

``ugv_0`` leads with a board on its back only; ``ugv_1`` .. ``ugv_{N-1}`` each
carry a forward camera (``"ugv_k/camera"``) on the board of the robot ahead and,
except the last, a board on their own back (ids of ``board_for_robot(k)``). No
observer. The robots start static in a file along the heading of ``start``,
``distance`` apart; each goal is the start advanced by ``goal_distance`` along
that heading. Mounts as in :mod:`moma_env.scenarios.caterpillar`: every camera
starts ``standoff`` m from the board ahead.

With ``bend`` set, the file's way is a jog around a wall instead of a straight
line (:mod:`moma_env.scenarios.trail`): every robot follows the leader's trail,
passing its corners (the scenario's ``routes``), and its goal lies
``goal_distance`` m of trail ahead of its start.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import ClassVar

import numpy as np

from moma_env.config import ConfigError, check_count, check_finite
from moma_env.scenarios.caterpillar import RobotFileConfig, file_layout, file_motion_views
from moma_env.scenarios.common import Layout, check_team_boards, default_ugv_radius, ugv_name
from moma_env.scenarios.trail import JOG_START_M, jog_length, jog_wall, trail_corners, trail_pose
from moma_env.scenarios.sampling import (
    draw_until_valid,
    first_with_team,
    random_camera,
    random_goal_distance,
    random_heading,
    random_surroundings,
)
from moma_env.scenarios.spec import ScenarioSpec

__all__ = ["CaterpillarMultiConfig", "MAX_RANDOM_UGVS", "MAX_KEPT_UGVS", "MIN_BEND_M", "MAX_BEND_M", "SPEC"]

#: Largest number of robots a random configuration draws (at least 2).
MAX_RANDOM_UGVS = 4
#: Largest file a random configuration keeps (``random(rng, n_ugvs=k)``): at 11 robots
#: (8 m of file plus the goal distance) about one draw in three fits the largest
#: random arena (10 m, diagonally), so the generator's attempts suffice.
MAX_KEPT_UGVS = 11
#: Smallest sideways offset (m) of a bent file's jog (0 is a straight file).
MIN_BEND_M = 0.5
#: Largest sideways offset (m) of a bent file's jog.
MAX_BEND_M = 1.5
#: Trail (m) a bent file's leader drives beyond the end of its jog, at least, in random layouts.
_RANDOM_BEND_RUN_OUT_M = (0.5, 1.5)


@dataclass(frozen=True, kw_only=True)
class CaterpillarMultiConfig(RobotFileConfig):
    """A file of ``n_ugvs`` robots (fields of :class:`RobotFileConfig`, plus ``n_ugvs``).

    Attributes:
        n_ugvs: number of robots in the file (>= 2; its ``n_ugvs - 1`` boards take
            ids of ``markers.team_dictionary(n_ugvs - 1)``, so at most
            ``markers.MAX_TEAM_BOARDS + 1`` robots).
        bend: sideways offset (m, to the left of the heading if positive) of the
            jog the file drives around a wall; 0 (the default) is a straight file,
            else ``MIN_BEND_M <= |bend| <= MAX_BEND_M`` and ``goal_distance`` must
            take the leader past the jog. ``goal_distance`` is then measured along
            the trail.
    """

    NAME: ClassVar[str] = "caterpillar_multi"
    TEAM_FIELDS: ClassVar[Mapping[str, tuple[float, float]]] = MappingProxyType(
        {"n_ugvs": (2, MAX_KEPT_UGVS), "bend": (-MAX_BEND_M, MAX_BEND_M)}
    )

    n_ugvs: int = 3
    bend: float = 0.0

    @property
    def file_length(self) -> int:
        """``n_ugvs``."""
        return self.n_ugvs

    def _check_fields(self) -> None:
        check_count(self._field("n_ugvs"), self.n_ugvs, minimum=2)
        check_team_boards(self._field("n_ugvs"), self.n_ugvs, self.n_ugvs - 1)
        super()._check_fields()
        check_finite(self._field("bend"), self.bend)
        object.__setattr__(self, "bend", float(self.bend))
        if self.bend != 0.0:
            if not MIN_BEND_M <= abs(self.bend) <= MAX_BEND_M:
                raise ConfigError(
                    self._field("bend"), f"must be 0 or of size {MIN_BEND_M} to {MAX_BEND_M} m, got {self.bend}"
                )
            past_jog = JOG_START_M + jog_length(self.bend)
            if self.goal_distance <= past_jog:
                raise ConfigError(
                    self._field("goal_distance"),
                    f"must take the leader past the jog of bend={self.bend} (more than {past_jog:.3f} m), "
                    f"got {self.goal_distance}",
                )

    def _make_layout(self) -> Layout:
        straight = file_layout(self.start, self.n_ugvs, self.distance, self.standoff, self.goal_distance)
        if self.bend == 0.0:
            return straight
        radius = default_ugv_radius()
        corners = trail_corners(self.start, self.bend)
        goals, routes, disks = {}, {}, []
        for k, ugv in enumerate(straight.ugvs):
            name = ugv_name(k)
            first, last = -k * self.distance, self.goal_distance - k * self.distance
            goals[name] = trail_pose(self.start, self.bend, last)
            routes[name] = tuple(pose for s, pose in corners if first < s < last)
            start = ugv.initial_pose
            disks += [(f"{name} start", start[0], start[1], radius), (f"{name} goal", goals[name][0], goals[name][1], radius)]
            disks += [(f"{name} via {j}", p[0], p[1], radius) for j, p in enumerate(routes[name])]
        return replace(
            straight,
            goals=goals,
            routes={name: route for name, route in routes.items() if route},
            disks=tuple(disks),
            obstacles=(jog_wall(self.start, self.bend, radius),),
        )

    @classmethod
    def random(cls, rng: np.random.Generator, **team: float) -> CaterpillarMultiConfig:
        """Random number of robots (2-4), heading, goal distance (1-3 m), camera, arena
        and obstacles; every draw from ``rng``.

        ``n_ugvs=k`` keeps the file at ``k`` robots, 2 to :data:`MAX_KEPT_UGVS`
        (ConfigError naming ``caterpillar_multi.n_ugvs`` otherwise): for ``k <= 4``
        the first free draw with ``k`` robots, beyond that a draw with ``k`` fixed
        (see :mod:`moma_env.scenarios.sampling`). ``bend=b`` keeps every draw's jog
        at ``b`` m (0, the default, gives the straight draws), with a goal distance
        of the jog's trail plus 0.5-1.5 m.
        """
        checked = cls.check_team(team)
        kept = checked.get("n_ugvs")
        bend = float(checked.get("bend", 0.0))
        if bend != 0.0 and abs(bend) < MIN_BEND_M:
            raise ConfigError(cls.NAME + ".bend", f"must be 0 or of size {MIN_BEND_M} to {MAX_BEND_M} m, got {bend}")
        if kept is not None and kept <= MAX_RANDOM_UGVS:
            free = cls.random if bend == 0.0 else (lambda rng: cls.random(rng, bend=bend))
            return first_with_team(cls, rng, free, {"n_ugvs": kept})

        def draw(rng: np.random.Generator) -> CaterpillarMultiConfig:
            n_ugvs = int(rng.integers(2, MAX_RANDOM_UGVS + 1)) if kept is None else kept
            start = (0.0, 0.0, random_heading(rng))
            if bend == 0.0:
                goal_distance = random_goal_distance(rng)
            else:
                goal_distance = JOG_START_M + jog_length(bend) + float(rng.uniform(*_RANDOM_BEND_RUN_OUT_M))
            config = cls(
                n_ugvs=n_ugvs,
                start=start,
                goal_distance=goal_distance,
                camera=random_camera(rng),
                bend=bend,
            )
            return replace(config, **random_surroundings(rng, config.occupied_disks))

        return draw_until_valid(cls, rng, draw)


#: The multi-robot caterpillar's place in the registry.
SPEC = ScenarioSpec(
    config_type=CaterpillarMultiConfig,
    gymnasium_id="moma_env/CaterpillarMulti-v0",
    pettingzoo_module="caterpillar_multi_v0",
    schedule="moma_env.planning.planner:robot_file_schedule",
    scripted_policy="agents.policies.caterpillar_multi:CaterpillarMulti",
    motion_views=file_motion_views,
)
