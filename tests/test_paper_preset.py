"""Experiment presets: named, validated, applied to either experiment from Python or the CLI."""

import dataclasses

import pytest

from moma_env.camera import CameraConfig
from moma_env.config import ConfigError
from moma_env.markers import BoardLayout
from training.cli import _experiment_config, build_parser
from training.experiments.line import LineConfig
from training.experiments.presets import DEFAULT, PAPER, PRESETS, ExperimentPreset, get_preset
from training.experiments.square import SquareConfig


def test_presets_by_name():
    assert get_preset("paper") is PAPER and get_preset("default") is DEFAULT
    assert set(PRESETS) == {"default", "paper"}
    with pytest.raises(ConfigError, match="preset: unknown preset 'lab'; known: default, paper"):
        get_preset("lab")


def test_paper_preset_models_the_authors_hardware():
    # PAL analogue video, the DESIGN.md boards (16 cm markers, 2 cm gaps, 34 cm overall).
    assert (PAPER.camera.width, PAPER.camera.height) == (720, 576)
    assert PAPER.board.marker_size == 0.16 and PAPER.board.gap == 0.02
    assert PAPER.board.width == pytest.approx(0.34)
    assert PAPER.planar_ugvs is False  # the paper's system estimated full 6-DoF poses
    assert PAPER.altitude is not None
    # The analogue link: rendered images, interlaced PAL fields 20 ms apart, blur and noise.
    assert PAPER.camera_backend == "rendered"
    assert PAPER.render.interlaced and PAPER.render.field_period_s == 0.02
    assert PAPER.render.blur_sigma_px > 0 and PAPER.render.noise_std > 0
    # The authors' calibrated camera (tud_momana ardrone_ext_cam.yaml) and a lab floor with grain.
    assert (PAPER.camera.fx, PAPER.camera.fy) == (492.856172, 526.006429)
    assert PAPER.camera.dist[0] == -0.419143
    assert PAPER.floor_grain is not None and DEFAULT.floor_grain is None


def test_apply_sets_the_sensing_and_keeps_the_experiment():
    square = PAPER.apply(SquareConfig(observer="handheld", side=0.8, leg=0.4))
    assert (square.observer, square.side, square.leg) == ("handheld", 0.8, 0.4)
    assert square.camera == PAPER.camera and square.altitude == PAPER.altitude and square.render == PAPER.render
    assert square.board == PAPER.board and square.planar_ugvs == PAPER.planar_ugvs
    assert square.camera_backend == PAPER.camera_backend
    assert PAPER.apply(SquareConfig(), camera_backend="geometric").camera_backend == "geometric"
    line = PAPER.apply(LineConfig(passes=1))
    assert line.passes == 1 and line.altitude == PAPER.altitude
    # With the altitude fixed, the tracking controller holds that depth to the boards.
    tracking = line.tracking_config()
    assert tracking.min_depth == tracking.max_depth == pytest.approx(PAPER.altitude - 0.40)


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"name": ""}, "preset.name"),
        ({"description": ""}, "preset.description"),
        ({"camera_backend": "pinhole"}, "preset.camera_backend"),
        ({"camera": {"width": 720}}, "preset.camera"),
        ({"render": {"interlaced": True}}, "preset.render"),
        ({"altitude": -2.0}, "preset.altitude"),
        ({"board": "aruco"}, "preset.board"),
        ({"planar_ugvs": 1}, "preset.planar_ugvs"),
        ({"floor_grain": {"grain_std": 2.0}}, "preset.floor_grain"),
    ],
)
def test_bad_presets_are_rejected_naming_the_field(changes, field):
    with pytest.raises(ConfigError, match=field):
        dataclasses.replace(PAPER, **changes)


def test_a_preset_too_low_for_the_experiment_is_rejected_when_applied():
    low = ExperimentPreset(name="low", description="flies too low", altitude=1.0)
    with pytest.raises(ConfigError, match="square.altitude.*too low"):
        low.apply(SquareConfig())
    big_boards = ExperimentPreset(name="big", description="huge boards", altitude=2.0, board=BoardLayout(marker_size=0.5))
    with pytest.raises(ConfigError, match="line.altitude"):
        big_boards.apply(LineConfig())
    narrow = ExperimentPreset(name="narrow", description="long lens", altitude=2.0, camera=CameraConfig(fx=1200.0))
    with pytest.raises(ConfigError, match="square.altitude"):
        narrow.apply(SquareConfig())
    # The view is measured from the principal point (where the tracker centres the boards):
    # one near the top edge leaves too little view upward, however wide the image.
    centred = ExperimentPreset(name="centred", description="centred", altitude=2.5, camera=CameraConfig(fx=420.0))
    assert centred.apply(SquareConfig()).altitude == 2.5
    off_centre = dataclasses.replace(centred, camera=CameraConfig(fx=420.0, cy=100.0))
    with pytest.raises(ConfigError, match="square.altitude.*too low"):
        off_centre.apply(SquareConfig())


def test_cli_flags_override_the_preset():
    parser = build_parser()
    args = parser.parse_args(["experiment", "square", "--preset", "paper", "--noise-px", "0.2", "--camera", "geometric"])
    config = _experiment_config(args, args.observer)
    assert config.camera.noise_px == 0.2 and config.camera.width == 720
    assert config.altitude == PAPER.altitude and config.planar_ugvs is False
    assert config.floor.grain == PAPER.floor_grain
    args = parser.parse_args(["experiment", "square", "--preset", "paper", "--plain-floor"])
    config = _experiment_config(args, args.observer)
    assert config.floor.grain is None and config.camera == PAPER.camera
    args = parser.parse_args(["experiment", "line", "--full-6dof"])
    config = _experiment_config(args, args.observer)
    assert config.planar_ugvs is False and config.altitude is None and config.camera_backend == "geometric"


def test_the_preset_study_derives_its_candidates_from_the_preset():
    from training.experiments.preset_study import CANDIDATES, candidate_config

    final = list(CANDIDATES)[-1]
    assert CANDIDATES[final] is PAPER
    assert candidate_config(final) == PAPER.apply(SquareConfig())
    # Each earlier step differs from the preset in the one thing it studies.
    changed = {name: {f.name for f in dataclasses.fields(PAPER) if getattr(p, f.name) != getattr(PAPER, f.name)} for name, p in CANDIDATES.items()}
    assert changed[final] == set()
    assert all(
        fields and fields <= {"camera_backend", "render", "altitude", "planar_ugvs", "camera", "floor_grain"}
        for name, fields in changed.items()
        if name != final
    )
    # The calibrated lens and the lab floor are each studied on their own.
    assert {"camera"} in changed.values() and {"floor_grain"} in changed.values()
    with pytest.raises(KeyError, match="unknown candidate"):
        candidate_config("lab floor")
