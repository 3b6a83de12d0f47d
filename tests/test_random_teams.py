"""Random layouts that keep the team: ``random(rng, n_ugvs=k)`` and ``random_scenarios=True``.

A random layout of an env keeps its configuration's robots by construction; a
team the generator cannot keep is refused when the env is built, naming the
field and its allowed range. For teams the free generator draws itself (2-4
robots) the layouts are exactly the ones the env has always drawn.
"""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from moma_env.config import ConfigError
from moma_env.env.factory import RandomScenarios, parallel_env, scenario_factory
from moma_env.scenarios import (
    CaterpillarConfig,
    CaterpillarMultiConfig,
    CaterpillarSledConfig,
    Scenario,
    TopObserverConfig,
    missing_views,
    scenario_spec,
)
from moma_env.scenarios import caterpillar_multi, top_observer
from moma_env.scenarios.sampling import MAX_TEAM_DRAWS, first_with_team

TEAM_CONFIGS = (TopObserverConfig, CaterpillarMultiConfig)


def test_team_fields_are_stated():
    assert TopObserverConfig.TEAM_FIELDS == {"n_ugvs": (2, top_observer.MAX_KEPT_UGVS), "goal_spread": (1.0, top_observer.MAX_GOAL_SPREAD)}
    assert CaterpillarMultiConfig.TEAM_FIELDS == {
        "n_ugvs": (2, caterpillar_multi.MAX_KEPT_UGVS),
        "bend": (-caterpillar_multi.MAX_BEND_M, caterpillar_multi.MAX_BEND_M),
    }
    assert CaterpillarConfig.TEAM_FIELDS == {} and CaterpillarSledConfig.TEAM_FIELDS == {}
    assert scenario_spec("top_observer").team_fields is TopObserverConfig.TEAM_FIELDS


@pytest.mark.parametrize(("configuration", "n_ugvs"), [("top_observer", 5), ("caterpillar_multi", 6)])
def test_random_scenarios_keep_a_team_beyond_the_free_range(configuration, n_ugvs):
    env = parallel_env(configuration, n_ugvs=n_ugvs, random_scenarios=True, max_cycles=20)
    robots = [f"ugv_{k}" for k in range(n_ugvs)]
    layouts = set()
    for seed in range(3):
        env.reset(seed=seed)
        assert [a for a in env.agents if a.startswith("ugv_")] == robots
        assert [u.name for u in env.scenario.world.ugvs] == robots
        layouts.add(repr(env.scenario.world))
        env.step({agent: 0 for agent in env.agents})
    assert len(layouts) == 3  # a new layout at every reset


@pytest.mark.parametrize("cls", TEAM_CONFIGS)
@pytest.mark.parametrize("seed", range(4))
def test_the_largest_kept_team_draws_valid_layouts(cls, seed):
    high = cls.TEAM_FIELDS["n_ugvs"][1]
    config = cls.random(np.random.default_rng(seed), n_ugvs=high)
    assert type(config) is cls and config.n_ugvs == high
    scenario = config.scenario()
    assert len(scenario.world.ugvs) == high
    assert missing_views(scenario, config.required_views()) == []
    arena = scenario.world.arena
    assert 4.0 <= arena.width <= 10.0 and 4.0 <= arena.height <= 10.0
    assert 350.0 <= scenario.camera.fx <= 600.0
    for ugv in scenario.world.ugvs:
        start, goal = ugv.initial_pose, scenario.goals[ugv.name]
        assert 1.0 - 1e-9 <= math.hypot(goal[0] - start[0], goal[1] - start[1]) <= 3.0 + 1e-9


@pytest.mark.parametrize("cls", TEAM_CONFIGS)
def test_a_kept_team_is_seeded(cls):
    first = [cls.random(np.random.default_rng(seed), n_ugvs=7) for seed in range(3)]
    again = [cls.random(np.random.default_rng(seed), n_ugvs=7) for seed in range(3)]
    assert first == again and len({repr(c) for c in first}) == 3


@pytest.mark.parametrize("cls", TEAM_CONFIGS)
@pytest.mark.parametrize("n_ugvs", [2, 3, 4])
def test_a_team_of_the_free_range_is_the_first_free_draw_with_it(cls, n_ugvs):
    for seed in range(4):
        kept_rng, free_rng = np.random.default_rng(seed), np.random.default_rng(seed)
        kept = cls.random(kept_rng, n_ugvs=n_ugvs)
        free = cls.random(free_rng)
        while free.n_ugvs != n_ugvs:
            free = cls.random(free_rng)
        assert kept == free
        assert kept_rng.bit_generator.state == free_rng.bit_generator.state


def test_first_with_team_gives_up_with_a_clear_error():
    calls = []

    def always_two(rng: np.random.Generator) -> TopObserverConfig:
        calls.append(rng.uniform())
        return TopObserverConfig(n_ugvs=2)

    with pytest.raises(RuntimeError, match=r"no random top_observer configuration with \{'n_ugvs': 3\}"):
        first_with_team(TopObserverConfig, np.random.default_rng(0), always_two, {"n_ugvs": 3})
    assert len(calls) == MAX_TEAM_DRAWS


@pytest.mark.parametrize(
    ("configuration", "overrides", "field", "message"),
    [
        ("top_observer", {"n_ugvs": 13}, "top_observer.n_ugvs", r"must be in \[2, 12\] for random layouts"),
        ("caterpillar_multi", {"n_ugvs": 12}, "caterpillar_multi.n_ugvs", r"must be in \[2, 11\] for random layouts"),
        ("top_observer", {"n_ugvs": 1}, "top_observer.n_ugvs", "must be >= 2"),
    ],
)
def test_a_team_random_layouts_cannot_keep_is_refused_at_construction(configuration, overrides, field, message):
    with pytest.raises(ConfigError, match=message) as info:
        parallel_env(configuration, random_scenarios=True, **overrides)
    assert info.value.field == field
    with pytest.raises(ConfigError, match=message):
        RandomScenarios(configuration, overrides)
    if overrides["n_ugvs"] > 1:  # the fixed layout of the same team is fine
        assert isinstance(scenario_factory(configuration, **overrides), Scenario)


@pytest.mark.parametrize(
    ("cls", "team", "field", "message"),
    [
        (TopObserverConfig, {"n_ugvs": 13}, "top_observer.n_ugvs", r"\[2, 12\]"),
        (TopObserverConfig, {"n_ugvs": 2.0}, "top_observer.n_ugvs", "must be an integer"),
        (TopObserverConfig, {"formation": "row"}, "top_observer.formation", r"cannot keep.*\['goal_spread', 'n_ugvs'\]"),
        (CaterpillarConfig, {"n_ugvs": 2}, "caterpillar.n_ugvs", "cannot keep.*none"),
        (CaterpillarSledConfig, {"n_ugvs": 1}, "caterpillar_sled.n_ugvs", "cannot keep"),
    ],
)
def test_random_refuses_a_team_it_cannot_keep(cls, team, field, message):
    with pytest.raises(ConfigError, match=message) as info:
        cls.random(np.random.default_rng(0), **team)
    assert info.value.field == field


def test_random_scenarios_is_a_picklable_factory():
    factory = scenario_factory("caterpillar_multi", True, n_ugvs=6, distance=0.9)
    assert isinstance(factory, RandomScenarios)
    assert factory.configuration == "caterpillar_multi" and factory.team == {"n_ugvs": 6, "bend": 0.0}
    assert factory.overrides == {"n_ugvs": 6, "distance": 0.9} and factory.base == CaterpillarMultiConfig(n_ugvs=6, distance=0.9)
    assert factory(None) is factory(None) and factory(None) == factory.base.scenario()
    copy = pickle.loads(pickle.dumps(factory))
    assert repr(copy) == repr(factory) == "RandomScenarios('caterpillar_multi', {'n_ugvs': 6, 'distance': 0.9})"
    for seed in range(3):
        drawn, again = factory(np.random.default_rng(seed)), copy(np.random.default_rng(seed))
        assert drawn == again and len(drawn.world.ugvs) == 6
    # The env's first layout is the base one; a reset draws a random one.
    env = parallel_env("caterpillar_multi", random_scenarios=True, n_ugvs=6, distance=0.9)
    assert env.scenario == factory(None)


def test_unknown_configuration_names_the_configuration():
    with pytest.raises(ConfigError, match="unknown configuration 'kite'") as info:
        RandomScenarios("kite")
    assert info.value.field == "configuration"
