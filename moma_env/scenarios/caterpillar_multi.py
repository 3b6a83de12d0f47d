"""Multi-robot caterpillar: a file of robots, each follower watching the robot ahead.

``ugv_0`` leads with a board on its back only; ``ugv_1`` .. ``ugv_{N-1}`` each
carry a forward camera (``"ugv_k/camera"``) on the board of the robot ahead and,
except the last, a board on their own back (ids of ``board_for_robot(k)``). No
observer. The robots start static in a file along the heading of ``start``,
``distance`` apart; each goal is the start advanced by ``goal_distance`` along
that heading. Mounts as in :mod:`moma_env.scenarios.caterpillar`: every camera
starts ``standoff`` m from the board ahead.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import ClassVar

import numpy as np

from moma_env.config import check_count
from moma_env.scenarios.caterpillar import RobotFileConfig, file_motion_views
from moma_env.scenarios.common import check_team_boards
from moma_env.scenarios.sampling import (
    draw_until_valid,
    first_with_team,
    random_camera,
    random_goal_distance,
    random_heading,
    random_surroundings,
)
from moma_env.scenarios.spec import ScenarioSpec

__all__ = ["CaterpillarMultiConfig", "MAX_RANDOM_UGVS", "MAX_KEPT_UGVS", "SPEC"]

#: Largest number of robots a random configuration draws (at least 2).
MAX_RANDOM_UGVS = 4
#: Largest file a random configuration keeps (``random(rng, n_ugvs=k)``): at 11 robots
#: (8 m of file plus the goal distance) about one draw in three fits the largest
#: random arena (10 m, diagonally), so the generator's attempts suffice.
MAX_KEPT_UGVS = 11


@dataclass(frozen=True, kw_only=True)
class CaterpillarMultiConfig(RobotFileConfig):
    """A file of ``n_ugvs`` robots (fields of :class:`RobotFileConfig`, plus ``n_ugvs``).

    Attributes:
        n_ugvs: number of robots in the file (>= 2; its ``n_ugvs - 1`` boards take
            ids of ``markers.team_dictionary(n_ugvs - 1)``, so at most
            ``markers.MAX_TEAM_BOARDS + 1`` robots).
    """

    NAME: ClassVar[str] = "caterpillar_multi"
    TEAM_FIELDS: ClassVar[Mapping[str, tuple[int, int]]] = MappingProxyType({"n_ugvs": (2, MAX_KEPT_UGVS)})

    n_ugvs: int = 3

    @property
    def file_length(self) -> int:
        """``n_ugvs``."""
        return self.n_ugvs

    def _check_fields(self) -> None:
        check_count(self._field("n_ugvs"), self.n_ugvs, minimum=2)
        check_team_boards(self._field("n_ugvs"), self.n_ugvs, self.n_ugvs - 1)
        super()._check_fields()

    @classmethod
    def random(cls, rng: np.random.Generator, **team: int) -> CaterpillarMultiConfig:
        """Random number of robots (2-4), heading, goal distance (1-3 m), camera, arena
        and obstacles; every draw from ``rng``.

        ``n_ugvs=k`` keeps the file at ``k`` robots, 2 to :data:`MAX_KEPT_UGVS`
        (ConfigError naming ``caterpillar_multi.n_ugvs`` otherwise): for ``k <= 4``
        the first free draw with ``k`` robots, beyond that a draw with ``k`` fixed
        (see :mod:`moma_env.scenarios.sampling`).
        """
        kept = cls.check_team(team).get("n_ugvs")
        if kept is not None and kept <= MAX_RANDOM_UGVS:
            return first_with_team(cls, rng, cls.random, {"n_ugvs": kept})

        def draw(rng: np.random.Generator) -> CaterpillarMultiConfig:
            config = cls(
                n_ugvs=int(rng.integers(2, MAX_RANDOM_UGVS + 1)) if kept is None else kept,
                start=(0.0, 0.0, random_heading(rng)),
                goal_distance=random_goal_distance(rng),
                camera=random_camera(rng),
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
