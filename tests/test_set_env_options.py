"""``--set`` of ``moma-env evaluate`` and ``sweep`` reaching the env options (``EnvConfig``
fields such as ``tracking``) besides the configuration's fields, checked at the boundary."""

from __future__ import annotations

import json

import pytest

from extras import installed
from moma_env.config import ConfigError
from moma_env.env.factory import SETTABLE_ENV_OPTIONS, checked_overrides, env_config, parallel_env
from training.cli import main
from training.evaluation.harness import evaluate
from training.evaluation.policies import overrides_beside_policy
from training.sweep.spec import SweepSpec

TRACKING = {"fill": 0.3, "max_depth": 2.0}


def test_checked_overrides_take_env_options_and_name_a_bad_one():
    assert checked_overrides("top_observer_team4", {"tracking": TRACKING, "leg_length": 1.0}) == {"tracking": TRACKING, "leg_length": 1.0}
    with pytest.raises(ConfigError, match=r"^tracking\.fill"):
        checked_overrides("top_observer_team4", {"tracking": {"fill": -1}})
    with pytest.raises(ConfigError, match=r"env\.switch_horizon_s"):
        checked_overrides("top_observer", {"switch_horizon_s": -3})
    with pytest.raises(ConfigError, match=r"top_observer\.bogus: no such field .* nor an env option"):
        checked_overrides("top_observer", {"bogus": 1})
    for own in ("action_mode", "max_cycles"):  # options of their own on the command line
        assert own not in SETTABLE_ENV_OPTIONS
    assert "tracking" in SETTABLE_ENV_OPTIONS and "leg_lengths" in SETTABLE_ENV_OPTIONS


def test_env_config_is_what_the_env_runs_with():
    env = parallel_env("top_observer_team4", tracking=TRACKING, switch_horizon_s=40.0)
    config = env_config(tracking=TRACKING, switch_horizon_s=40.0, action_masks=True, commit_legs=True)
    assert env.config.tracking == config.tracking and env.config.switch_horizon_s == 40.0
    assert env_config().tracking.fill != TRACKING["fill"]


def test_evaluate_cli_sets_an_env_option_as_python_does(tmp_path):
    args = ["evaluate", "--scenario", "top_observer_team4", "--policy", "greedy", "--episodes", "1", "--seed", "3", "--max-cycles", "60", "--json"]
    assert main([*args, "--set", f"tracking={json.dumps(TRACKING)}", "--out", str(tmp_path / "set")]) == 0
    assert main([*args, "--out", str(tmp_path / "default")]) == 0
    chosen, default = (json.loads((tmp_path / name / "summary.json").read_text()) for name in ("set", "default"))
    assert chosen["options"]["tracking"] == TRACKING and "tracking" not in default["options"]
    python = evaluate("top_observer_team4", "greedy", 1, 3, max_cycles=60, tracking=TRACKING)
    me = [robot["moma"]["mean_mean_error"] for robot in python.summary["robots"].values()]
    assert [robot["moma"]["mean_mean_error"] for robot in chosen["summary"]["robots"].values()] == pytest.approx(me, rel=1e-12)
    assert [robot["moma"]["mean_mean_error"] for robot in default["summary"]["robots"].values()] != pytest.approx(me, rel=1e-6)


def test_evaluate_cli_refuses_a_bad_env_option_and_one_the_policy_fixes(tmp_path, capsys):
    args = ["evaluate", "--scenario", "top_observer_team4", "--episodes", "1", "--max-cycles", "10"]
    assert main([*args, "--set", 'tracking={"fill": 2}', "--out", str(tmp_path / "bad")]) == 2
    assert "tracking.fill" in capsys.readouterr().err
    assert main([*args, "--policy", "top_observer_team4_mppo", "--set", "observer_agent=true", "--out", str(tmp_path / "fixed")]) == 2
    refusal = capsys.readouterr().err
    if not installed("train"):  # make test-base: the policy cannot be loaded, and says why
        assert "needs stable-baselines3 (the 'train' extra)" in refusal
    else:
        assert "overrides.observer_agent: the policy 'top_observer_team4_mppo' was trained with observer_agent=False" in refusal
    assert not (tmp_path / "bad").exists() and not (tmp_path / "fixed").exists()


def test_overrides_beside_policy_drop_what_the_policy_fixes_and_refuse_a_change():
    assert overrides_beside_policy("p", {"action_masks": True}, {"action_masks": True, "tracking": TRACKING}) == {"tracking": TRACKING}
    with pytest.raises(ConfigError, match=r"overrides\.action_masks"):
        overrides_beside_policy("p", {"action_masks": True}, {"action_masks": False})


def test_a_sweep_spec_takes_env_options():
    spec = SweepSpec(scenarios=("top_observer_team4",), policies=("greedy",), seeds=(0,), overrides={"tracking": TRACKING})
    assert dict(spec.overrides) == {"tracking": TRACKING}
    with pytest.raises(ConfigError, match=r"tracking\.max_depth"):
        SweepSpec(scenarios=("top_observer_team4",), policies=("greedy",), seeds=(0,), overrides={"tracking": {"max_depth": -1.0}})
