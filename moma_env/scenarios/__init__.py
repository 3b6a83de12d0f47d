"""Typed configurations of the paper's robot set-ups and their random generators.

* :class:`Scenario` -- the contract with the environment: one episode's layout.
* :class:`TopObserverConfig` -- UGVs with boards on top, an observer above them.
* :class:`CaterpillarConfig` -- a follower's forward camera on its leader's back board.
* :class:`CaterpillarSledConfig` -- one robot's backward camera on the sled it tows.
* :class:`CaterpillarMultiConfig` -- a file of robots, each watching the one ahead.
* :class:`ScenarioSpec` -- everything specific to one configuration, in its module
  (``SPEC``); :data:`SPECS` / :data:`SCENARIO_SPECS` -- the registered ones.
* :data:`CONFIGURATIONS`, :func:`make_scenario`, :func:`random_config` -- by name.
* :func:`missing_views` -- boards a configuration's cameras fail to see at the start.
* :func:`view_neighbours` -- the devices that share a camera's view (a file's neighbours).

Every configuration is a frozen dataclass validated at construction (errors name
the field, e.g. ``"caterpillar.standoff"``); ``config.scenario()`` lays out the
episode and ``Config.random(rng)`` draws a valid random one from a seeded
``np.random.Generator``.
"""

from moma_env.scenarios.base import Scenario
from moma_env.scenarios.caterpillar import CaterpillarConfig, RobotFileConfig
from moma_env.scenarios.caterpillar_multi import CaterpillarMultiConfig
from moma_env.scenarios.caterpillar_sled import CaterpillarSledConfig
from moma_env.scenarios.common import ScenarioConfig
from moma_env.scenarios.registry import (
    CONFIGURATIONS,
    SCENARIO_SPECS,
    SPECS,
    config_type,
    make_config,
    make_scenario,
    random_config,
    scenario_spec,
)
from moma_env.scenarios.spec import ScenarioSpec
from moma_env.scenarios.top_observer import FORMATIONS, TopObserverConfig
from moma_env.scenarios.views import missing_views, start_boards, start_camera_poses, view_neighbours, visible_marker_counts

__all__ = [
    "Scenario",
    "ScenarioConfig",
    "TopObserverConfig",
    "FORMATIONS",
    "CaterpillarConfig",
    "RobotFileConfig",
    "CaterpillarSledConfig",
    "CaterpillarMultiConfig",
    "ScenarioSpec",
    "SPECS",
    "SCENARIO_SPECS",
    "scenario_spec",
    "CONFIGURATIONS",
    "config_type",
    "make_config",
    "make_scenario",
    "random_config",
    "missing_views",
    "view_neighbours",
    "start_boards",
    "start_camera_poses",
    "visible_marker_counts",
]
