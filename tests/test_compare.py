"""moma-env experiment compare: the estimators on the same runs (short runs here; the table is a command)."""

from __future__ import annotations

import math

import pytest

from moma_env.config import ConfigError
from moma_env.estimator import EstimatorConfig
from moma_env.sim import OdometryConsumer
from training.cli import build_parser, main
from training.experiments.compare import TimedFactory, compare_case, compare_config, format_table, run_compare

#: Simulated seconds of a test run: the first legs of the square.
SHORT = 8.0


def test_the_timing_wrapper_takes_odometry_only_for_an_estimator_that_does():
    assert not isinstance(TimedFactory("moma")(EstimatorConfig()), OdometryConsumer)
    assert isinstance(TimedFactory("ekf")(EstimatorConfig()), OdometryConsumer)


def test_a_case_times_every_update_and_summarises_errors_and_consistency():
    row = compare_case("square", "geometric", "ekf", 1, seed=0, max_time_s=SHORT)
    frames = round(SHORT * 25)  # one update per control step at 25 Hz
    assert abs(row.n_updates - frames) <= 1
    assert row.time_per_update_s > 0.0
    assert row.position_dof == 3  # the paper preset estimates the UGVs in 6-DoF
    for value in (row.final_error, row.mean_error, row.position_anees, row.heading_anees):
        assert math.isfinite(value) and value >= 0.0
    assert row.n_completed == 0  # 8 s is not the whole square
    table = format_table([row])
    assert table.count("\n") == 2 and "| square | geometric | ekf | quadcopter | 1 (0) |" in table


def test_the_paper_preset_with_planar_ugvs_off_and_the_default_preset_planar():
    assert not compare_config("line", "geometric", "graph").planar_ugvs
    assert compare_config("square", "geometric", "moma", preset="default").planar_ugvs


def test_bad_arguments_are_refused_before_any_run():
    with pytest.raises(ConfigError, match="estimator"):
        run_compare(["moma", "kalman"], ["square"], ["geometric"], 1, 0)
    with pytest.raises(ValueError, match="experiments"):
        run_compare(["moma"], ["circle"], ["geometric"], 1, 0)
    with pytest.raises(ValueError, match="runs"):
        run_compare(["moma"], ["square"], ["geometric"], 0, 0)


def test_the_command_prints_one_row_per_estimator(capsys):
    code = main(["experiment", "compare", "--estimators", "moma,fused", "--runs", "1", "--experiments", "square", "--max-time", "4"])
    out = capsys.readouterr().out
    assert code == 1  # the runs were cut short by --max-time
    assert "| square | geometric | moma |" in out and "| square | geometric | fused |" in out


def test_the_command_names_an_unknown_estimator(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["experiment", "compare", "--estimators", "moma,kalman"])
    assert exit_info.value.code == 2
    assert "unknown estimator kalman" in capsys.readouterr().err


def test_the_square_and_the_line_take_an_estimator_by_name(tmp_path, capsys):
    code = main(["experiment", "square", "--estimator", "ekf", "--runs", "1", "--max-time", "3", "--out", str(tmp_path / "sq"), "--json"])
    assert code == 1  # cut short by --max-time
    assert '"moma"' in capsys.readouterr().out
    assert build_parser().parse_args(["experiment", "line", "--estimator", "graph"]).estimator == "graph"
    assert build_parser().parse_args(["experiment", "line"]).estimator == "moma"
    with pytest.raises(SystemExit):
        main(["experiment", "line", "--estimator", "kalman"])
