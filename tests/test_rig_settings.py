"""The rig's settings (``ScenarioConfig.SETTING_FIELDS``) apply to every random layout,
and ``--set FIELD=VALUE`` gives them (or any configuration field) to evaluate and sweep."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from moma_env.camera import CameraConfig
from moma_env.config import ConfigError
from moma_env.env.factory import RandomScenarios, checked_overrides, parallel_env
from moma_env.estimator import EstimatorConfig
from moma_env.scenarios import SCENARIO_SPECS
from training.cli import main
from training.evaluation.harness import evaluate
from training.sweep.cells import run_cell
from training.sweep.spec import Cell, SweepSpec

CONFIGURATIONS = sorted(SCENARIO_SPECS)
SETTINGS = {"leg_length": 1.5, "dwell_s": 0.5, "goal_tolerance_m": 0.08, "estimator": {"window": 12}}


@pytest.mark.parametrize("configuration", CONFIGURATIONS)
def test_random_draws_leave_the_settings_at_their_defaults(configuration):
    config_type = SCENARIO_SPECS[configuration].config_type
    defaults = {f.name: f.default if f.default is not dataclasses.MISSING else f.default_factory() for f in dataclasses.fields(config_type)}
    for seed in range(4):
        drawn = config_type.random(np.random.default_rng(seed))
        for name in config_type.SETTING_FIELDS:
            assert getattr(drawn, name) == defaults[name], (configuration, seed, name)


@pytest.mark.parametrize("configuration", CONFIGURATIONS)
def test_random_layouts_keep_the_settings_given_and_draw_the_same_layouts(configuration):
    factory = RandomScenarios(configuration, SETTINGS)
    plain = RandomScenarios(configuration)
    assert factory.settings == {
        "leg_length": 1.5, "dwell_s": 0.5, "goal_tolerance_m": 0.08, "estimator": EstimatorConfig(window=12)
    }
    assert plain.settings == {}
    for seed in range(3):
        scenario = factory(np.random.default_rng(seed))
        reference = plain(np.random.default_rng(seed))
        assert (scenario.leg_length, scenario.dwell_s, scenario.goal_tolerance_m) == (1.5, 0.5, 0.08)
        assert scenario.estimator.window == 12 and reference.estimator.window == EstimatorConfig().window
        assert scenario.world == reference.world and scenario.goals == reference.goals  # the same draws
        assert reference.leg_length != 1.5


def test_an_env_with_random_layouts_runs_every_layout_with_the_settings():
    env = parallel_env("top_observer_team4", leg_length=1.5)
    base = parallel_env("top_observer_team4")
    for seed in (1, 2):
        env.reset(seed=seed)
        base.reset(seed=seed)
        assert env.scenario.leg_length == 1.5 and base.scenario.leg_length == 0.5
        assert env.scenario.world == base.scenario.world


@pytest.mark.parametrize("configuration", CONFIGURATIONS)
def test_random_draws_leave_the_cameras_settings_at_their_defaults(configuration):
    config_type = SCENARIO_SPECS[configuration].config_type
    default = CameraConfig()
    for seed in range(4):
        camera = config_type.random(np.random.default_rng(seed)).camera
        for name in CameraConfig.SETTING_FIELDS:
            assert getattr(camera, name) == getattr(default, name), (configuration, seed, name)


CAMERA_SETTINGS = {"pnp_method": "SQPNP", "pose_disambiguation": "min_cost", "attitude_noise_deg": 0.5, "pnp_sigma_floor_px": 0.2}


@pytest.mark.parametrize("configuration", CONFIGURATIONS)
def test_random_layouts_keep_the_cameras_settings_given_and_draw_the_same_layouts(configuration):
    factory = RandomScenarios(configuration, {"camera": {**CAMERA_SETTINGS, "fx": 555.0}})
    plain = RandomScenarios(configuration)
    assert plain.camera_settings == {}
    assert {name: factory.camera_settings[name] for name in CAMERA_SETTINGS} == CAMERA_SETTINGS
    assert set(factory.camera_settings) == set(CameraConfig.SETTING_FIELDS)
    for seed in range(3):
        scenario = factory(np.random.default_rng(seed))
        reference = plain(np.random.default_rng(seed))
        assert scenario.world == reference.world and scenario.goals == reference.goals  # the same draws
        assert dataclasses.replace(reference.camera, **CAMERA_SETTINGS) == scenario.camera  # fx drawn, not 555
        assert reference.camera.pnp_method == "PLANAR_LM"


@pytest.mark.parametrize("configuration", CONFIGURATIONS)
def test_a_camera_override_of_defaults_draws_the_same_scenarios(configuration):
    factory, plain = RandomScenarios(configuration, {"camera": {}}), RandomScenarios(configuration)
    for seed in range(3):
        assert factory(np.random.default_rng(seed)) == plain(np.random.default_rng(seed))


def test_an_env_with_random_layouts_solves_every_layout_with_the_cameras_settings():
    env = parallel_env("top_observer_team4", camera={"pnp_method": "SQPNP", "pnp_warm_start": True})
    for seed in (1, 2):
        env.reset(seed=seed)
        cameras = list(env.simulation.cameras.values())
        assert cameras and all(c.config.pnp_method == "SQPNP" and c.config.pnp_warm_start for c in cameras)
        assert env.scenario.camera.fx != CameraConfig().fx  # drawn


def test_a_cameras_setting_that_a_drawn_camera_does_not_admit_is_an_error_naming_it():
    factory = RandomScenarios("top_observer", {"camera": {"noise_px": 0.0, "pnp_warm_max_rms_px": 0.01}})
    with pytest.raises(ConfigError, match="camera.pnp_warm_max_rms_px"):
        for seed in range(10):
            factory(np.random.default_rng(seed))


def test_checked_overrides_names_the_bad_field():
    assert checked_overrides("top_observer_team4", {"leg_length": 1.5}) == {"leg_length": 1.5}
    with pytest.raises(ConfigError) as err:
        checked_overrides("top_observer_team4", {"leg": 1.5})
    assert err.value.field == "top_observer.leg" and "leg_length" in str(err.value)
    with pytest.raises(ConfigError) as err:
        checked_overrides("caterpillar", {"leg_length": -1.0})
    assert err.value.field == "caterpillar.leg_length"
    with pytest.raises(ConfigError) as err:
        checked_overrides("top_observer_team4", {"estimator": {"window": 0}})
    assert err.value.field == "estimator.window"


def test_evaluate_set_reaches_every_episode_and_is_recorded(tmp_path, capsys):
    out = tmp_path / "long"
    assert main(["evaluate", "--scenario", "top_observer_team4", "--policy", "greedy", "--episodes", "2", "--seed", "1000000",
                 "--set", "leg_length=1.5", "--out", str(out), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    stored = json.loads((out / "summary.json").read_text())
    assert stored["options"]["leg_length"] == 1.5
    direct = evaluate("top_observer_team4", "greedy", 2, 1000000, action_masks=True, leg_length=1.5)
    default = evaluate("top_observer_team4", "greedy", 2, 1000000, action_masks=True)
    assert printed["time_to_goal_s"] == json.loads(json.dumps(direct.summary["time_to_goal_s"]))
    assert direct.summary["n_switches"]["mean"] < default.summary["n_switches"]["mean"]  # longer legs, fewer stops


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--set", "leg=1"], "top_observer.leg"),
        (["--set", "leg_length=1", "--set", "leg_length=2"], "given twice"),
        (["--set", "max_cycles=10"], "--max-cycles"),
    ],
)
def test_evaluate_set_refuses_bad_input_in_one_line(tmp_path, capsys, arguments, message):
    out = tmp_path / "run"
    assert main(["evaluate", "--scenario", "top_observer", "--episodes", "1", "--out", str(out), *arguments]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("moma-env evaluate:") and message in err and "\n" not in err
    assert not out.exists()


def test_set_without_a_value_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["evaluate", "--scenario", "top_observer", "--out", str(tmp_path / "run"), "--set", "leg_length"])
    assert exit_.value.code == 2 and "expected FIELD=VALUE" in capsys.readouterr().err


def test_sweep_spec_carries_overrides_to_every_cell():
    spec = SweepSpec(scenarios=("top_observer_team4",), policies=("greedy",), seeds=(1000000,), overrides={"leg_length": 1.5})
    assert spec.to_dict()["overrides"] == {"leg_length": 1.5}
    assert SweepSpec.from_dict(spec.to_dict()) == spec
    old = {k: v for k, v in spec.to_dict().items() if k != "overrides"}  # a sweep.json written before overrides
    assert SweepSpec.from_dict(old).overrides == {}
    row = run_cell(Cell("top_observer_team4", "greedy", 1000000), spec.options)
    episode = evaluate("top_observer_team4", "greedy", 1, 1000000, action_masks=True, leg_length=1.5).episodes[0].row()
    assert row["time_to_goal_s"] == episode["time_to_goal_s"] and row["n_switches"] == episode["n_switches"]
    for overrides, field in (({"leg": 1.0}, "top_observer.leg"), ({"max_cycles": 10}, "overrides.max_cycles"), ([1], "overrides")):
        with pytest.raises(ConfigError) as err:
            SweepSpec(scenarios=("top_observer_team4",), policies=("greedy",), seeds=(0,), overrides=overrides)
        assert err.value.field == field
