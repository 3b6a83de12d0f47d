"""The line experiment: waypoints, legs and keypoints, its metrics, files and command line."""

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from moma_env.config import ConfigError
from moma_env.metrics import Trajectory, run_metrics
from training.cli import main
from training.experiments.leapfrog_run import BUDDY, MAIN, LeapfrogRun, leapfrog_legs
from training.experiments.line import LineConfig, line_metrics, line_waypoints, run_line, summarise_line

#: A short line for runs in tests: 2 passes of 1 m, 2 switches each.
SHORT = LineConfig(length=1.0, passes=2, switches_per_pass=2)


def test_default_line_is_the_papers():
    cfg = LineConfig()
    assert cfg.path_length == pytest.approx(13.785)
    assert cfg.n_keypoints == 18
    wps = cfg.waypoints()
    assert len(wps) == 18
    xs = np.array([0.0] + [x for x, _, _ in wps])
    steps = np.diff(xs)
    # 6 equal legs per pass, forward, backward, forward.
    assert np.allclose(np.abs(steps), 4.595 / 6)
    assert (steps[:6] > 0).all() and (steps[6:12] < 0).all() and (steps[12:] > 0).all()
    assert np.sum(np.abs(steps)) == pytest.approx(13.785)
    assert all(y == 0.0 and yaw == 0.0 for _, y, yaw in wps)


def test_legs_alternate_with_the_buddy_to_the_left():
    cfg = LineConfig()
    legs = leapfrog_legs(cfg)
    assert len(legs) == 36
    assert [leg.robot for leg in legs] == [MAIN, BUDDY] * 18
    for main_leg, buddy_leg in zip(legs[::2], legs[1::2]):
        assert buddy_leg.waypoint == pytest.approx((main_leg.waypoint[0], cfg.separation, 0.0))
    # The spread peaks when the main robot has driven a leg ahead of its buddy.
    assert cfg.max_spread() == pytest.approx(math.hypot(4.595 / 6, 0.6))


def test_line_waypoints_of_odd_and_even_pass_counts():
    assert line_waypoints(2.0, 1, 2) == [(1.0, 0.0, 0.0), (2.0, 0.0, 0.0)]
    assert line_waypoints(2.0, 2, 1) == [(2.0, 0.0, 0.0), (0.0, 0.0, 0.0)]


def test_short_run_has_one_keypoint_per_leg_at_the_waypoints():
    run = run_line(SHORT, seed=1)
    assert run.completed
    assert len(run.switch_times) == SHORT.n_keypoints == 4
    m = line_metrics(run, "moma")
    # The robot stops within the follower's tolerance (on its estimate) of each waypoint.
    expected_x = [x for x, _, _ in SHORT.waypoints()]
    assert np.allclose(m.true_x, expected_x, atol=0.05)
    assert len(m.x_errors) == len(m.relative_errors) == 4
    assert all(math.isfinite(v) for v in m.x_errors + m.relative_errors)
    assert 0.0 < m.final_error < 0.05
    assert m.final_error_pct_path == pytest.approx(100.0 * m.final_error / SHORT.path_length)


def test_zero_noise_line_has_zero_keypoint_errors():
    cfg = dataclasses.replace(SHORT, camera=dataclasses.replace(SHORT.camera, noise_px=0.0))
    m = line_metrics(run_line(cfg, seed=0), "moma")
    assert np.max(np.abs(m.x_errors)) < 1e-6
    assert np.max(m.relative_errors) < 1e-6


def _planted_run() -> LeapfrogRun:
    """A run whose estimate is off by known amounts: +1 cm x at t=1, -2 cm x and +3 cm y at t=2."""
    times = np.arange(0.0, 3.01, 0.5)
    true_x = np.array([0.0, 0.5, 1.0, 1.0, 1.0, 0.5, 0.0])
    truth = Trajectory.from_planar(times, true_x, np.zeros_like(times), np.zeros_like(times))
    est_x = true_x + np.array([0.0, 0.0, 0.01, 0.0, -0.02, 0.0, 0.0])
    est_y = np.array([0.0, 0.0, 0.0, 0.0, 0.03, 0.0, 0.04])
    estimate = Trajectory.from_planar(times, est_x, est_y, np.zeros_like(times))
    keypoints = (1.0, 2.0, 3.0)
    return LeapfrogRun(
        seed=7,
        trajectories={MAIN: {"truth": truth, "moma": estimate}},
        waypoints=((1.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        switch_times=keypoints,
        metrics={"moma": run_metrics(estimate, truth, switch_times=keypoints, path_length=2.0)},
        lost_at={"moma": None},
        completed=True,
        duration_s=3.0,
    )


def test_metrics_of_a_planted_trajectory():
    m = line_metrics(_planted_run(), "moma")
    assert m.keypoint_times == (1.0, 2.0, 3.0)
    assert m.true_x == pytest.approx((1.0, 1.0, 0.0))
    assert m.x_errors == pytest.approx((0.01, -0.02, 0.0))
    assert m.position_errors == pytest.approx((0.01, math.hypot(0.02, 0.03), 0.04))
    # Distances start -> kp1 -> kp2 -> kp3: true 1, 0, 1; estimated 1.01, |(-0.03, 0.03)|, |(-0.98, 0.01)|.
    expected_rel = (0.01, math.hypot(0.03, 0.03), abs(math.hypot(0.98, 0.01) - 1.0))
    assert m.relative_errors == pytest.approx(expected_rel)
    assert m.final_error == pytest.approx(0.04)
    assert m.final_error_pct_path == pytest.approx(2.0)
    assert m.max_abs_x_error == pytest.approx(0.02)
    summary = summarise_line([_planted_run(), _planted_run()])["moma"]
    assert summary["mean_final_error"] == pytest.approx(0.04)
    assert summary["max_abs_keypoint_x_error"] == pytest.approx(0.02)
    assert summary["mean_relative_error"] == pytest.approx(np.mean(expected_rel))
    assert summary["track_loss_rate"] == 0.0


def test_line_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="line.passes"):
        LineConfig(passes=0)
    with pytest.raises(ConfigError, match="line.length"):
        LineConfig(length=-4.6)
    with pytest.raises(ConfigError, match="line.switches_per_pass"):
        LineConfig(switches_per_pass=1.5)
    with pytest.raises(ConfigError, match="line.camera_backend"):
        LineConfig(camera_backend="pinhole")
    with pytest.raises(ConfigError, match="line.altitude.*too low"):
        LineConfig(altitude=1.2)


SHORT_ARGS = ["--length", "1", "--passes", "2", "--switches-per-pass", "2"]


def test_cli_writes_table_figure_csv_and_json_whole(tmp_path, capsys):
    out = tmp_path / "line"
    assert main(["experiment", "line", *SHORT_ARGS, "--runs", "2", "--seed", "3", "--out", str(out), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["n_runs"] == 2 and data["n_completed"] == 2 and data["passes"] == 2
    assert [r["seed"] for r in data["runs"]] == [3, 4]
    assert len(data["runs"][0]["keypoints"]["moma"]["x_errors"]) == 4
    assert json.loads((out / "summary.json").read_text())["summary"] == data["summary"]
    with open(out / "keypoints.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 2 * 4  # runs x methods x keypoints
    assert {r["method"] for r in rows} == {"moma", "wheel"}
    first = [r for r in rows if r["run"] == "0" and r["method"] == "moma"]
    assert [float(r["x_error_m"]) for r in first] == pytest.approx(data["runs"][0]["keypoints"]["moma"]["x_errors"])
    assert (out / "line.png").stat().st_size > 10_000
    assert (out / "tum" / "run_01" / "ugv_0_moma.tum").exists()
    assert not list(out.rglob("*.tmp*"))

    assert main(["experiment", "line", *SHORT_ARGS, "--runs", "1", "--out", str(tmp_path / "t")]) == 0
    table = capsys.readouterr().out
    assert "MOMA (ours)" in table and "MOMA (paper, real robots, 1 run)" in table and "% of 2 m" in table
    assert "Keypoints of the run with seed 0" in table


def test_a_failed_figure_leaves_no_summary(tmp_path, monkeypatch, capsys):
    from training.experiments import line_report

    def broken(*_args, **_kwargs):
        raise RuntimeError("no figure today")

    monkeypatch.setattr(line_report, "plot_run", broken)
    with pytest.raises(RuntimeError, match="no figure"):
        main(["experiment", "line", *SHORT_ARGS, "--runs", "1", "--out", str(tmp_path)])
    assert not (tmp_path / "summary.json").exists() and not (tmp_path / "keypoints.csv").exists()
    assert not list(tmp_path.rglob("*.tmp*"))


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--passes", "0"], "pass count must be >= 1"),
        (["--length", "-1"], "length (m) must be a finite number > 0"),
        (["--length", "x"], "expected a number"),
        (["--switches-per-pass", "two"], "expected an integer"),
        (["--preset", "lab"], "invalid choice"),
        (["--camera", "pinhole"], "invalid choice"),
    ],
)
def test_cli_rejects_bad_arguments(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["experiment", "line", *argv])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_cli_reports_an_altitude_too_low_for_the_line(capsys, monkeypatch):
    from training.experiments import presets

    low = dataclasses.replace(presets.PAPER, altitude=1.2)
    monkeypatch.setitem(presets.PRESETS, "paper", low)
    assert main(["experiment", "line", "--preset", "paper", "--runs", "1"]) == 2
    assert "line.altitude" in capsys.readouterr().err


def test_runs_in_worker_processes_are_the_same_bit_for_bit():
    from training.experiments.runner import run_many

    cfg = LineConfig(length=0.4, passes=1, switches_per_pass=1)
    serial = run_many(cfg, 2, seed=5)
    parallel = run_many(cfg, 2, seed=5, jobs=2)
    assert [r.seed for r in parallel] == [5, 6]
    for a, b in zip(serial, parallel):
        for method in ("truth", "moma", "wheel"):
            np.testing.assert_array_equal(a.trajectories[MAIN][method].poses, b.trajectories[MAIN][method].poses)
    with pytest.raises(ValueError, match="jobs"):
        run_many(cfg, 1, seed=0, jobs=0)
