"""The experiments with the rendered camera: MOMA on ArUco detections, the VO baseline, track loss."""

import dataclasses
import json
import math

import numpy as np
import pytest

from moma_env.camera import CameraConfig
from training.cli import main
from training.experiments import presets
from moma_env.odometry.visual import VisualOdometryConfig
from training.experiments.leapfrog_run import MAIN, FloorVOSetup, floor_texture, summarise
from training.experiments.line import LineConfig
from training.experiments.presets import ExperimentPreset
from training.experiments.square import SquareConfig, run_square

#: Half the PAL image, same field of view: 4x fewer pixels to render and detect.
SMALL = CameraConfig(width=360, height=288, fx=210.0)
#: A cheaper VO for tests: fewer features and RANSAC samples.
FAST_VO = FloorVOSetup(tracking=VisualOdometryConfig(max_features=120, min_features=50, ransac_iterations=15))


def _inside(rects, x, y):
    return any(x0 <= x <= x1 and y0 <= y <= y1 for x0, y0, x1, y1 in rects)


def _footprint(config: SquareConfig, x: float, y: float, yaw: float) -> list[tuple[float, float]]:
    """Floor corners seen by the robot's floor camera at body pose (x, y, yaw)."""
    vo = config.vo
    half_w = vo.height * (vo.camera.width / 2) / vo.camera.fx  # across the robot
    half_h = vo.height * (vo.camera.height / 2) / vo.camera.fx  # along the heading
    c, s = math.cos(yaw), math.sin(yaw)
    cx, cy = x + vo.offset * c, y + vo.offset * s
    return [(cx + a * c - b * s, cy + a * s + b * c) for a in (-half_h, half_h) for b in (-half_w, half_w)]


def test_square_floor_is_textured_on_the_first_half_only():
    cfg = SquareConfig()
    rects = cfg.textured_regions()
    # First half, (0, 0) -> (0, 1) -> (1, 1): the camera's view centre is on texture, up to the clearance.
    for t in np.linspace(0.0, 1.0, 21):
        centre = (0.0, t + cfg.vo.offset)
        assert _inside(rects, *centre) == (centre[1] >= cfg.texture_clearance)
        centre = (t + cfg.vo.offset, 1.0)
        assert _inside(rects, *centre) == (centre[0] <= 1.0 - cfg.texture_clearance)
    # Second half, (1, 1) -> (1, 0) -> (0, 0): no corner of the camera's view touches texture.
    for t in np.linspace(0.0, 1.0, 21):
        for corner in _footprint(cfg, 1.0, 1.0 - t, -math.pi / 2) + _footprint(cfg, 1.0 - t, 0.0, math.pi):
            assert not _inside(rects, *corner)
    floor = floor_texture(cfg)
    assert floor.raster.std() > 20  # textured inside its extent


def test_rendered_partial_square_runs_moma_and_the_vo_on_texture():
    cfg = SquareConfig(camera_backend="rendered", camera=SMALL, vo=FAST_VO, max_time_s=4.0)
    run = run_square(cfg, seed=2)
    assert not run.completed and run.duration_s == pytest.approx(4.0, abs=0.05)
    assert run.methods == ("moma", "wheel", "vo")
    assert run.lost_at["vo"] is None  # the first side is textured
    main_traj = run.trajectories[MAIN]
    truth_moved = np.linalg.norm(main_traj["truth"].xy[-1] - main_traj["truth"].xy[0])
    assert truth_moved > 0.3
    for method in ("moma", "vo"):
        assert run.metrics[method].final_error < 0.03
    # Same seed, same run: a shorter run is a bit-exact prefix of it.
    again = run_square(dataclasses.replace(cfg, max_time_s=2.0), seed=2)
    for method in ("moma", "vo"):
        prefix = again.trajectories[MAIN][method].poses
        np.testing.assert_array_equal(prefix, main_traj[method].poses[: len(prefix)])


@dataclasses.dataclass(frozen=True)
class PlainSquare(SquareConfig):
    """The square on a floor without any texture."""

    def textured_regions(self):
        return ()


def test_vo_loses_track_on_a_plain_floor_and_holds_its_pose():
    run = run_square(PlainSquare(camera_backend="rendered", camera=SMALL, vo=FAST_VO, max_time_s=4.0), seed=0)
    assert run.lost_at["vo"] is not None and run.lost_at["vo"] < 1.0
    vo = run.trajectories[MAIN]["vo"]
    assert np.allclose(vo.xy, vo.xy[0])  # held where it was lost (the start)
    assert run.metrics["vo"].final_error > 0.3  # the robot drove on
    assert run.lost_at["moma"] is None
    summary = summarise([run])
    assert summary["vo"]["track_loss_rate"] == 1.0 and summary["vo"]["kept_track"] is None
    assert summary["moma"]["track_loss_rate"] == 0.0


def test_cli_line_with_the_rendered_camera_end_to_end(tmp_path, capsys, monkeypatch):
    small = ExperimentPreset(name="small", description="small rendered images", camera_backend="rendered", camera=SMALL)
    monkeypatch.setitem(presets.PRESETS, "small", small)
    import training.cli

    monkeypatch.setattr(training.cli, "PRESET_NAMES", (*training.cli.PRESET_NAMES, "small"))  # the parser's names-only list
    out = tmp_path / "line"
    argv = ["experiment", "line", "--length", "0.4", "--passes", "1", "--switches-per-pass", "1", "--preset", "small", "--out", str(out)]
    assert main([*argv, "--runs", "1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["config"]["camera_backend"] == "rendered"
    summary = data["summary"]
    assert set(summary) == {"moma", "wheel", "vo"}
    assert summary["vo"]["track_loss_rate"] == 0.0  # the line is textured throughout
    assert summary["moma"]["mean_final_error"] < 0.03 and summary["vo"]["mean_final_error"] < 0.05
    assert len(data["runs"][0]["keypoints"]["vo"]["x_errors"]) == 1
    assert json.loads((out / "summary.json").read_text())["summary"] == data["summary"]
    assert (out / "tum" / "run_00" / "ugv_0_vo.tum").exists()
    assert not list(out.rglob("*.tmp*"))
    assert LineConfig(camera_backend="rendered").textured_regions()
