"""The weak texture of a real floor (grain, tiles and seams, specks) and the floors that use it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from moma_env.camera import CameraConfig, FloorConfig, FloorGrainConfig, FloorTexture, PinholeCamera
from moma_env.camera.floor_grain import grain_layer
from moma_env.camera.rays import PixelRays
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_CAM_DOWN, make_transform

PPM = 400.0
NOTHING = dict(grain_std=0.0, tile_size_m=0.0, speck_density=0.0)


def _layer(seed: int = 0, shape=(800, 1000), **fields) -> np.ndarray:
    return grain_layer(FloorGrainConfig(**fields), shape, (-1.0, -1.0), PPM, np.random.default_rng(seed))


def test_same_seed_same_floor_other_seed_other_floor():
    config = FloorConfig(extent=(0.0, 0.0, 1.0, 1.0), px_per_m=PPM, textured=(), grain=FloorGrainConfig())
    a, b = FloorTexture(config).raster, FloorTexture(config).raster
    assert np.array_equal(a, b)
    assert not np.array_equal(a, FloorTexture(dataclasses.replace(config, seed=1)).raster)


def test_grain_is_smooth_noise_of_the_configured_std():
    layer = _layer(**{**NOTHING, "grain_std": 3.0})
    assert layer.std() == pytest.approx(3.0, rel=1e-3)
    assert abs(float(layer.mean())) < 1.0
    # Smooth: neighbouring pixels differ by far less than the std (no pixel-scale edges).
    assert np.abs(np.diff(layer, axis=1)).mean() < 0.5


def test_seams_darken_by_their_area_at_the_tile_pitch():
    """Seams only: each row crossing a vertical seam loses contrast * width * px_per_m gray levels."""
    layer = _layer(**{**NOTHING, "tile_size_m": 0.3, "tile_gray_std": 0.0, "seam_width_m": 0.0015, "seam_contrast": 20.0})
    # A row between the horizontal seams: darkened only where it crosses the vertical ones.
    clear_row = next(r for r in range(layer.shape[0]) if np.count_nonzero(layer[r]) < layer.shape[1] // 2)
    column_darkening = -layer[clear_row]
    seams = np.flatnonzero(column_darkening > 0)
    groups = np.split(seams, np.flatnonzero(np.diff(seams) > 1) + 1)
    assert len(groups) == math.floor(layer.shape[1] / (0.3 * PPM)) or len(groups) == math.ceil(layer.shape[1] / (0.3 * PPM))
    starts = np.array([g[0] for g in groups])
    assert np.allclose(np.diff(starts), 0.3 * PPM, atol=1)
    for g in groups[1:-1]:
        assert column_darkening[g].sum() == pytest.approx(20.0 * 0.0015 * PPM, rel=1e-4)
    assert column_darkening.max() <= 20.0 + 1e-4


def test_tiles_have_their_own_tone():
    layer = _layer(**{**NOTHING, "tile_size_m": 0.3, "tile_gray_std": 2.0, "seam_contrast": 0.0})
    tones = np.unique(np.round(layer, 4))
    n_tiles = (math.ceil(800 / 120) + 1) * (math.ceil(1000 / 120) + 1)
    assert 20 <= len(tones) <= n_tiles
    assert 1.0 < tones.std() < 3.5


def test_specks_keep_their_expected_area_and_sign():
    """Specks only, over 5 m^2: the layer's sum matches density * area * E[sign * contrast * disc area]."""
    cfg = dict(**{**NOTHING, "speck_density": 100.0}, speck_min_m=0.001, speck_max_m=0.008, speck_min_contrast=15.0, speck_max_contrast=50.0)
    shape = (1000, 2000)
    total, lo, hi = 0.0, 0.001 * PPM, 0.008 * PPM
    mean_d2 = (hi**2 - lo**2) / (2.0 * math.log(hi / lo))  # log-uniform diameter (px)
    for dark, sign in ((1.0, -1.0), (0.0, 1.0)):
        layer = _layer(seed=3, shape=shape, **cfg, dark_fraction=dark)
        assert np.sign(layer[layer != 0]).tolist() == [sign] * np.count_nonzero(layer)
        expected = 100.0 * (shape[0] * shape[1] / PPM**2) * 32.5 * math.pi * mean_d2 / 4.0
        total = float(layer.sum())
        assert abs(total) == pytest.approx(expected, rel=0.1)


def test_textured_rectangles_are_the_same_with_and_without_grain():
    plain = FloorConfig(extent=(0.0, 0.0, 1.0, 1.0), px_per_m=200.0, textured=((0.0, 0.0, 0.5, 1.0),))
    grainy = dataclasses.replace(plain, grain=FloorGrainConfig())
    a, b = FloorTexture(plain).raster, FloorTexture(grainy).raster
    assert np.array_equal(a[:, :100], b[:, :100])
    assert np.all(a[:, 100:] == round(plain.gray))  # perfectly plain
    untextured = b[:, 100:].astype(float)
    assert 2.0 < untextured.std() < 8.0 and abs(untextured.mean() - plain.gray) < 3.0
    assert plain.detailed_rects == ((0.0, 0.0, 0.5, 1.0),) and grainy.detailed_rects == (grainy.extent,)


def test_a_downward_camera_over_the_untextured_floor_sees_the_grain_only_if_configured():
    camera = PinholeCamera(CameraConfig(width=160, height=120, fx=120.0, dist=()))
    rays = PixelRays(camera)
    config = FloorConfig(extent=(-1.0, -1.0, 1.0, 1.0), px_per_m=PPM, textured=((-1.0, -1.0, -0.5, 1.0),))
    T_w_c = make_transform(R_BODY_CAM_DOWN, [0.3, 0.0, 0.3])
    plain = FloorTexture(config)
    out = np.empty((120, 160), dtype=np.uint8)
    assert plain.draw(rays, T_w_c, out) is None and np.all(out == round(config.gray))
    grainy = FloorTexture(dataclasses.replace(config, grain=FloorGrainConfig()))
    assert grainy.draw(rays, T_w_c, out) == (0, 0, 160, 120)
    assert out.std() > 2.0


def test_grain_from_a_mapping_and_bad_values_name_the_field():
    assert FloorConfig(grain={"grain_std": 2.0}).grain == FloorGrainConfig(grain_std=2.0)
    with pytest.raises(ConfigError, match="floor.grain.bogus"):
        FloorConfig(grain={"bogus": 1.0})
    with pytest.raises(ConfigError, match="floor.grain"):
        FloorConfig(grain="vinyl")


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"grain_std": -1.0}, "floor.grain.grain_std"),
        ({"grain_size_m": 0.0}, "floor.grain.grain_size_m"),
        ({"grain_octaves": 0}, "floor.grain.grain_octaves"),
        ({"tile_size_m": -0.3}, "floor.grain.tile_size_m"),
        ({"tile_gray_std": float("nan")}, "floor.grain.tile_gray_std"),
        ({"seam_width_m": 0.4}, "floor.grain.seam_width_m"),
        ({"seam_contrast": 300.0}, "floor.grain.seam_contrast"),
        ({"speck_density": -1.0}, "floor.grain.speck_density"),
        ({"speck_min_m": 0.0}, "floor.grain.speck_min_m"),
        ({"speck_max_m": 0.0005}, "floor.grain.speck_max_m"),
        ({"speck_max_contrast": 10.0}, "floor.grain.speck_max_contrast"),
        ({"dark_fraction": 1.5}, "floor.grain.dark_fraction"),
    ],
)
def test_bad_grain_is_rejected_naming_the_field(changes, field):
    with pytest.raises(ConfigError, match=field):
        FloorGrainConfig(**changes)


def test_the_paper_preset_lays_a_grainy_floor_over_the_arena_and_the_default_a_plain_one():
    from training.experiments.leapfrog_run import floor_texture
    from training.experiments.presets import DEFAULT, PAPER
    from training.experiments.square import SquareConfig

    paper = PAPER.apply(SquareConfig())
    assert paper.floor.grain == PAPER.floor_grain and PAPER.floor_grain is not None
    assert DEFAULT.apply(SquareConfig(camera_backend="rendered")).floor == SquareConfig().floor  # unchanged: plain
    floor = floor_texture(paper)
    x0, y0, x1, y1 = floor.config.extent
    # The whole arena (walls 1.5 m beyond the poses) is rastered, the textured strips inside it.
    assert x0 <= -1.5 and y0 <= -1.5 and x1 >= 2.5 and y1 >= 2.5
    assert floor.config.textured == paper.textured_regions()
    # A perfectly plain floor rasters the textured strips only.
    regions = np.array(SquareConfig().textured_regions())
    plain_square = floor_texture(SquareConfig(camera_backend="rendered"))
    assert plain_square.config.extent == (*regions[:, :2].min(axis=0), *regions[:, 2:].max(axis=0))
