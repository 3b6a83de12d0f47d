"""``moma-env warm-up`` (:func:`moma_env.warm_up.warm_up`): a short seeded run of each
configuration in each action mode, reported per run; bad input refused before any runs."""

import pytest

from moma_env.config import ConfigError
from moma_env.warm_up import ACTION_MODES, warm_up
from training.cli import main


def test_each_configuration_is_run_in_each_action_mode_in_order():
    done = warm_up(["caterpillar", "top_observer"], steps=2)
    assert [(step.configuration, step.action_mode) for step in done] == [
        (name, mode) for name in ("caterpillar", "top_observer") for mode in ACTION_MODES
    ]
    assert all(step.seconds > 0.0 for step in done)


def test_bad_input_is_refused_before_anything_runs():
    with pytest.raises(ConfigError, match="nope"):
        warm_up(["caterpillar", "nope"])
    with pytest.raises(ValueError, match="steps must be an integer >= 1, got 0"):
        warm_up(["caterpillar"], steps=0)


def test_the_command_prints_each_run_and_the_total(capsys):
    assert main(["warm-up", "--configuration", "caterpillar_sled"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines[:-1]] == [f"caterpillar_sled {mode}" for mode in ACTION_MODES]
    assert lines[-1].startswith("kernels compiled and cached in ")
    with pytest.raises(SystemExit) as exited:
        main(["warm-up", "--configuration", "nope"])
    assert exited.value.code == 2
