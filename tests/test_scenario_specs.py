"""One place per configuration: every name lookup derives from the registered ScenarioSpecs.

The registry's specs, the versioned ``moma_env/<name>_v0.py`` modules and the
Gymnasium and PettingZoo registries must name the same configurations (so they
cannot drift), and the derived views (CONFIGURATIONS, GYMNASIUM_IDS,
SCRIPTED_POLICIES, the planner's schedules, the plan checker's rules) must agree
with the specs.
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
import re
import subprocess
import sys

import gymnasium
import numpy as np
import pytest

import moma_env
from moma_env.config import ConfigError
from moma_env.planning import SUPPORTED_CONFIGURATIONS, RuleChecker, plan, validate
from moma_env.planning import planner
from moma_env.registration import GYMNASIUM_IDS
from moma_env.scenarios import (
    CONFIGURATIONS,
    SCENARIO_SPECS,
    SPECS,
    CaterpillarConfig,
    ScenarioSpec,
    TopObserverConfig,
    make_scenario,
    scenario_spec,
)
from moma_env.scenarios.caterpillar import file_views
from moma_env.scenarios.spec import load_entry_point, no_motion_views

NAMES = tuple(spec.name for spec in SPECS)
VERSIONED = re.compile(r"[a-z][a-z0-9_]*_v[0-9]+")


def test_the_registry_lists_the_four_configurations_once():
    assert NAMES == ("top_observer", "caterpillar", "caterpillar_sled", "caterpillar_multi")
    assert tuple(SCENARIO_SPECS) == NAMES
    assert all(SCENARIO_SPECS[name] is spec for name, spec in zip(NAMES, SPECS))
    for spec in SPECS:
        module = importlib.import_module(spec.config_type.__module__)
        assert module.SPEC is spec  # defined in the configuration's own module
        assert spec.name == spec.config_type.NAME


def test_name_views_derive_from_the_specs():
    from agents.policies import SCRIPTED_POLICIES, scripted_policy

    assert dict(CONFIGURATIONS) == {spec.name: spec.config_type for spec in SPECS}
    assert dict(GYMNASIUM_IDS) == {spec.gymnasium_id: spec.name for spec in SPECS}
    assert dict(SCRIPTED_POLICIES) == {spec.name: spec.load_scripted_policy() for spec in SPECS}
    assert SUPPORTED_CONFIGURATIONS == NAMES
    for name in NAMES:
        assert type(scripted_policy(name)) is SCRIPTED_POLICIES[name]
    for view in (CONFIGURATIONS, GYMNASIUM_IDS, SCRIPTED_POLICIES, SCENARIO_SPECS):
        with pytest.raises(TypeError):
            view["kite"] = None  # read-only


def test_scenario_spec_lookup_names_the_known_configurations():
    assert scenario_spec("caterpillar") is SCENARIO_SPECS["caterpillar"]
    with pytest.raises(ConfigError, match=r"unknown configuration 'kite'.*caterpillar_multi"):
        scenario_spec("kite")


def test_every_spec_has_its_versioned_module_and_every_module_a_spec():
    modules = {m.name for m in pkgutil.iter_modules(moma_env.__path__) if VERSIONED.fullmatch(m.name)}
    assert modules == {spec.pettingzoo_module for spec in SPECS}
    for spec in SPECS:
        module = importlib.import_module(f"moma_env.{spec.pettingzoo_module}")
        assert callable(module.parallel_env) and callable(module.env) and module.raw_env is module.parallel_env
        env = module.parallel_env(max_cycles=5)
        assert env.metadata["name"] == spec.pettingzoo_module
        env.reset(seed=0)
        assert env.scenario.name == spec.name
        assert module.env(max_cycles=5).metadata["name"] == spec.pettingzoo_module


def test_every_spec_has_its_gymnasium_id_and_every_id_a_spec_or_a_task():
    from moma_env.tasks import TASKS

    ours = {env_id: entry for env_id, entry in gymnasium.registry.items() if env_id.startswith("moma_env/")}
    assert set(ours) == {spec.gymnasium_id for spec in SPECS} | {task.gymnasium_id for task in TASKS.values()}
    named = [(spec.gymnasium_id, spec.name) for spec in SPECS] + [(task.gymnasium_id, task.name) for task in TASKS.values()]
    for env_id, name in named:
        entry = ours[env_id]
        assert entry.entry_point == "moma_env.env.factory:centralised_env"
        assert entry.kwargs == {"configuration": name}


def test_every_spec_has_its_pettingzoo_ids():
    import pettingzoo

    if not hasattr(pettingzoo, "register"):
        pytest.skip("this PettingZoo has no registry")
    for kind in ("parallel", "aec"):
        registry = getattr(pettingzoo, f"{kind}_registry")
        ours = {env_id for env_id in registry if str(env_id).startswith("moma_env/")}
        assert ours == {spec.pettingzoo_id for spec in SPECS}
    assert SCENARIO_SPECS["caterpillar_sled"].pettingzoo_id == "moma_env/caterpillar_sled-v0"


@pytest.mark.parametrize("spec", SPECS, ids=NAMES)
def test_entry_points_resolve(spec):
    schedule = spec.load_schedule()
    assert schedule in (planner.top_observer_schedule, planner.robot_file_schedule, planner.sled_schedule)
    from agents.policies import Policy, TurnTakingPolicy

    policy_type = spec.load_scripted_policy()
    assert issubclass(policy_type, TurnTakingPolicy) and isinstance(policy_type(), Policy)


def test_plan_uses_the_spec_schedule():
    scenario = make_scenario("caterpillar")
    result = plan(scenario)
    assert result.scenario_name == "caterpillar" and validate(scenario, result) == []
    assert {turn.device for turn in result.turns} == {"ugv_0", "ugv_1"}


def test_checker_rules_come_from_the_spec():
    top = RuleChecker(make_scenario("top_observer"))
    assert top.coverage is not None and top.coverage > 0.0 and top.views == []
    multi = RuleChecker(make_scenario("caterpillar_multi", n_ugvs=4))
    assert multi.coverage is None
    assert [(v.camera, v.camera_owner, v.board_owner) for v in multi.views] == [
        (camera, camera.split("/")[0], owner) for camera, (owner,) in file_views(4).items()
    ]
    sled = RuleChecker(make_scenario("caterpillar_sled"))
    assert [(v.camera, v.camera_owner, v.board_owner) for v in sled.views] == [("ugv_0/camera", "ugv_0", "sled")]
    # A scenario whose name is not registered has no coverage rule and no views.
    custom = RuleChecker(dataclasses.replace(make_scenario("caterpillar"), name="custom"))
    assert custom.coverage is None and custom.views == []


@pytest.mark.parametrize(
    ("views", "message"),
    [({"ugv_0/camera": ("ugv_1",)}, "unknown camera 'ugv_0/camera'"), ({"ugv_1/camera": ("ugv_1",)}, "carries no board")],
)
def test_a_spec_whose_motion_views_do_not_fit_the_world_is_reported(monkeypatch, views, message):
    validate_module = importlib.import_module("moma_env.planning.validate")

    spec = dataclasses.replace(SCENARIO_SPECS["caterpillar"], motion_views=lambda world: views)
    monkeypatch.setattr(validate_module, "SCENARIO_SPECS", {"caterpillar": spec})
    with pytest.raises(ValueError, match=message):
        RuleChecker(make_scenario("caterpillar"))


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"config_type": dict}, "scenario_spec.config_type"),
        ({"gymnasium_id": "TopObserver-v0"}, "top_observer.spec.gymnasium_id"),
        ({"gymnasium_id": "moma_env/Top Observer-v0"}, "top_observer.spec.gymnasium_id"),
        ({"pettingzoo_module": "caterpillar_v0"}, "top_observer.spec.pettingzoo_module"),
        ({"pettingzoo_module": "top_observer"}, "top_observer.spec.pettingzoo_module"),
        ({"schedule": "moma_env.planning.planner.top_observer_schedule"}, "top_observer.spec.schedule"),
        ({"scripted_policy": "agents.policies:"}, "top_observer.spec.scripted_policy"),
        ({"observer_coverage": 1}, "top_observer.spec.observer_coverage"),
        ({"motion_views": {}}, "top_observer.spec.motion_views"),
    ],
)
def test_bad_specs_name_the_field(changes, field):
    fields = {f.name: getattr(SCENARIO_SPECS["top_observer"], f.name) for f in dataclasses.fields(ScenarioSpec)}
    with pytest.raises(ConfigError) as info:
        ScenarioSpec(**(fields | changes))
    assert info.value.field == field


def test_optional_schedule_and_policy():
    spec = ScenarioSpec(config_type=TopObserverConfig, gymnasium_id="moma_env/Other-v1", pettingzoo_module="top_observer_v1")
    assert spec.pettingzoo_id == "moma_env/top_observer-v1" and spec.motion_views is no_motion_views
    with pytest.raises(ValueError, match="no planner schedule"):
        spec.load_schedule()
    with pytest.raises(ValueError, match="no scripted policy"):
        spec.load_scripted_policy()
    assert not spec.observer_coverage
    assert no_motion_views(make_scenario("caterpillar").world) == {}
    assert spec.random(np.random.default_rng(0)) == TopObserverConfig.random(np.random.default_rng(0))


def test_load_entry_point():
    assert load_entry_point("moma_env.scenarios.caterpillar:CaterpillarConfig") is CaterpillarConfig
    with pytest.raises(ValueError, match="entry point"):
        load_entry_point("moma_env.scenarios.caterpillar.CaterpillarConfig")
    with pytest.raises(ImportError, match="has no 'Nope'"):
        load_entry_point("moma_env.scenarios.caterpillar:Nope")
    with pytest.raises(ImportError):
        load_entry_point("moma_env.no_such_module:X")


def test_moma_env_never_imports_agents():
    code = (
        "import sys, moma_env, moma_env.planning, moma_env.env.factory\n"
        "from moma_env.planning import plan\n"
        "from moma_env.scenarios import make_scenario\n"
        "for name in ('top_observer', 'caterpillar', 'caterpillar_sled', 'caterpillar_multi'):\n"
        "    plan(make_scenario(name))\n"
        "moma_env.env.factory.parallel_env('top_observer').reset(seed=0)\n"
        "print(sorted(m for m in sys.modules if m == 'agents' or m.startswith('agents.')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
