"""The square experiment end to end: world -> camera -> estimator -> metrics."""

import dataclasses
import json
import math

import numpy as np
import pytest

from moma_env.config import ConfigError
from moma_env.metrics import read_tum, read_tum_with_covariances
from training.cli import main
from training.experiments.square import SquareConfig, run_square, square_legs, square_waypoints
from training.experiments.square_report import format_table


def test_waypoints_form_the_papers_square():
    wps = square_waypoints(1.0, 0.5)
    assert len(wps) == 8
    xy = np.array([(x, y) for x, y, _ in wps])
    # Corners with the pure rotations of the paper: (0, 1), (1, 1), (1, 0), back to (0, 0).
    for corner in [(0.0, 1.0), (1.0, 1.0), (1.0, 0.0), (0.0, 0.0)]:
        assert np.min(np.linalg.norm(xy - corner, axis=1)) < 1e-12
    path = np.sum(np.linalg.norm(np.diff(np.vstack([[0.0, 0.0], xy]), axis=0), axis=1))
    assert path == pytest.approx(4.0)
    assert wps[1][2] == pytest.approx(0.0)  # turned to +x at (0, 1)


def test_legs_alternate_and_keep_the_robots_apart():
    cfg = SquareConfig()
    legs = square_legs(cfg)
    assert [leg.robot for leg in legs[:4]] == ["ugv_0", "ugv_1", "ugv_0", "ugv_1"]
    for main_leg, buddy_leg in zip(legs[::2], legs[1::2]):
        d = math.dist(main_leg.waypoint[:2], buddy_leg.waypoint[:2])
        assert d == pytest.approx(cfg.separation)


def test_zero_noise_run_is_exact_through_every_switch():
    cfg = SquareConfig(camera=dataclasses.replace(SquareConfig().camera, noise_px=0.0))
    run = run_square(cfg, seed=0)
    assert run.completed
    assert len(run.switch_times) == 8
    m = run.metrics["moma"]
    assert m.valid_fraction == 1.0
    assert m.max_error < 1e-6
    # The observer is localised too (it has no initial pose: only from the boards).
    uav = run.trajectories["uav"]
    err = np.linalg.norm(uav["moma"].positions - uav["truth"].positions, axis=1)
    assert np.nanmax(err[1:]) < 1e-6


def test_noisy_run_is_reproducible_and_moma_beats_wheel_odometry():
    cfg = SquareConfig(side=0.5)
    a, b = run_square(cfg, seed=3), run_square(cfg, seed=3)
    assert a.completed
    np.testing.assert_array_equal(a.trajectories["ugv_0"]["moma"].poses, b.trajectories["ugv_0"]["moma"].poses)
    np.testing.assert_array_equal(a.trajectories["ugv_0"]["wheel"].poses, b.trajectories["ugv_0"]["wheel"].poses)
    c = run_square(cfg, seed=4)
    assert not np.array_equal(a.trajectories["ugv_0"]["moma"].poses, c.trajectories["ugv_0"]["moma"].poses)
    assert 0.0 < a.metrics["moma"].final_error < a.metrics["wheel"].final_error


def test_square_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="square.observer"):
        SquareConfig(observer="balloon")
    with pytest.raises(ConfigError, match="square.separation"):
        SquareConfig(separation=0.3)
    with pytest.raises(ConfigError, match="square.leg"):
        SquareConfig(leg=-1.0)
    # The texture is kept clear of the second half: a small rendered square has no room for it.
    SquareConfig(side=0.5)
    with pytest.raises(ConfigError, match="square.texture_clearance"):
        SquareConfig(side=0.5, camera_backend="rendered")
    with pytest.raises(ConfigError, match="square.camera_backend"):
        SquareConfig(camera_backend="pinhole")


def test_cli_writes_table_figure_tum_and_json(tmp_path, capsys):
    out = tmp_path / "square"
    assert main(["experiment", "square", "--side", "0.5", "--runs", "2", "--seed", "5", "--out", str(out), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["n_runs"] == 2 and data["n_completed"] == 2
    assert [r["seed"] for r in data["runs"]] == [5, 6]
    assert data["summary"]["moma"]["mean_final_error"] > 0
    assert (out / "square.png").stat().st_size > 10_000
    assert json.loads((out / "summary.json").read_text())["summary"] == data["summary"]
    truth = read_tum(out / "tum" / "run_00" / "ugv_0_truth.tum")
    moma = read_tum(out / "tum" / "run_01" / "ugv_0_moma.tum")
    assert len(truth) > 100 and len(moma) > 100
    # MOMA's covariances go beside its TUM file, line for line; the other methods have none
    with_cov = read_tum_with_covariances(out / "tum" / "run_01" / "ugv_0_moma.tum")
    np.testing.assert_array_equal(with_cov.times, moma.times)
    assert with_cov.covariances.shape == (len(moma), 6, 6) and np.isfinite(with_cov.covariances).all()
    assert sorted(p.name for p in (out / "tum" / "run_00").glob("*.cov.txt")) == ["uav_moma.cov.txt", "ugv_0_moma.cov.txt", "ugv_1_moma.cov.txt"]
    assert not list(out.rglob("*.tmp*"))

    assert main(["experiment", "square", "--side", "0.5", "--runs", "1", "--out", str(tmp_path / "t")]) == 0
    table = capsys.readouterr().out
    assert "MOMA (ours)" in table and "wheel odometry (ours)" in table and "% of 200 cm" in table
    assert "Viso2 (paper, real robots)" in table


@pytest.mark.parametrize("argv", [["--runs", "0"], ["--seed", "-1"], ["--runs", "x"], ["--observer", "kite"]])
def test_cli_rejects_bad_arguments(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["experiment", "square", *argv])
    assert exit_info.value.code == 2
    assert "error" in capsys.readouterr().err


def test_cli_compares_the_two_observers(tmp_path, capsys):
    out = tmp_path / "both"
    assert main(["experiment", "square", "--side", "0.5", "--runs", "1", "--observer", "both", "--out", str(out), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["observers"]) == {"quadcopter", "handheld"}
    for observer in ("quadcopter", "handheld"):
        assert data["observers"][observer]["observer"] == observer
        assert data["observers"][observer]["path_length_m"] == pytest.approx(2.0)
        saved = json.loads((out / observer / "summary.json").read_text())
        assert saved["summary"] == data["observers"][observer]["summary"]
    assert (out / "observers.png").stat().st_size > 10_000
    assert not list(out.rglob("*.tmp*"))


def test_summary_counts_track_loss_per_method():
    from training.experiments.leapfrog_run import summarise

    run = run_square(SquareConfig(side=0.5), seed=0)
    lost = dataclasses.replace(run, lost_at={"moma": None, "wheel": 12.0})
    summary = summarise([run, lost])
    assert summary["moma"]["track_loss_rate"] == 0.0
    assert summary["wheel"]["track_loss_rate"] == 0.5
    assert summary["moma"]["n_runs"] == 2 and summary["moma"]["kept_track"]["n_runs"] == 2
    # The paper's convention: statistics over the runs that kept track, here the first only.
    assert summary["wheel"]["kept_track"]["n_runs"] == 1
    assert summary["wheel"]["kept_track"]["mean_final_error"] == run.metrics["wheel"].final_error
    assert summarise([lost])["wheel"]["kept_track"] is None
    config = SquareConfig(side=0.5)
    table = format_table(summary, config, 2, 2)
    assert "wheel odometry, kept track" in table and "MOMA, kept track" not in table
