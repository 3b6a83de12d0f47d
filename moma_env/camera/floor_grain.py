"""The weak texture of a real lab floor where nothing is printed on it.

A real floor is never one gray level. A vinyl or linoleum lab floor, seen by
the visual odometry's camera (30 cm above it, 160x120 px, f = 120 px: 40 x 30 cm
of floor, 2.5 mm per pixel), shows:

* **grain**: the mottle of the material, a few percent of its reflectance (a
  standard deviation of 2-4 gray levels on a mid-gray floor of 140), at scales
  from centimetres down to the pixel: smooth, no corners a tracker could hold;
* **tiles and seams**: 30 cm tiles (12 inch vinyl tiles; sheet floors have
  welded seams every 2 m) whose tones differ by a percent or two, with joints
  of 1-2 mm that collect dirt (10-20 % darker than the tile): straight lines,
  so only their crossings (every 30 cm) are corners;
* **specks**: dust, grit, crumbs and rubber scuffs of 1-8 mm, about one per square
  decimetre on a swept floor in use (a dozen in the floor camera's view),
  mostly darker than the floor: sub-pixel to a couple of pixels for the floor
  camera, the few point features a tracker finds.

:func:`grain_layer` draws these as gray-level offsets on the floor raster of
:class:`~moma_env.camera.floor.FloorTexture` from a seeded generator, so the
floor is the same for the same seed and configuration. Features smaller than
a raster pixel are drawn with their area preserved (a speck of 1.5 mm on a
2.5 mm pixel darkens it by a third of its contrast), as the camera's pixel
would average them.

Frames and units: world W (x, y on the floor; metres). The raster's pixel
``(col, row)`` is centred on ``x = x0 + (col + 0.5) / px_per_m``,
``y = y0 + (row + 0.5) / px_per_m``. Gray levels are 0-255.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from moma_env.config import ConfigError, check_count, check_non_negative, check_positive, check_range

__all__ = ["FloorGrainConfig", "grain_layer"]

#: A speck is drawn over this many standard deviations of its profile either side.
_SPECK_SIGMAS = 3.0
#: Variance (px^2) of a uniform pixel footprint: added to a speck's, so that a
#: sub-pixel speck sampled at pixel centres keeps its area.
_PIXEL_VARIANCE = 1.0 / 12.0


@dataclass(frozen=True)
class FloorGrainConfig:
    """Grain, tiles with seams and specks of a plain-looking floor (defaults: a vinyl-tiled lab).

    Attributes:
        grain_std: standard deviation of the grain (gray levels, >= 0; 0: none).
        grain_size_m: size of the largest grain mottle (m); each finer octave
            halves it (and its amplitude).
        grain_octaves: number of grain octaves (>= 1).
        tile_size_m: pitch of the tiles and their seams (m); 0: no tiles, no seams.
        tile_gray_std: standard deviation of the tiles' tones (gray levels, >= 0).
        seam_width_m: width of a seam (m), less than ``tile_size_m``.
        seam_contrast: how much darker a seam is than the floor (gray levels, >= 0).
        speck_density: mean number of specks per square metre (>= 0; 0: none).
        speck_min_m, speck_max_m: the specks' diameters are drawn log-uniformly
            in ``[speck_min_m, speck_max_m]`` (m).
        speck_min_contrast, speck_max_contrast: the specks' contrasts are drawn
            uniformly in this range (gray levels, the difference from the floor
            over the speck's area).
        dark_fraction: fraction of the specks darker than the floor (dust,
            grit); the others are lighter (paper bits, light dust), in [0, 1].
    """

    grain_std: float = 3.0
    grain_size_m: float = 0.04
    grain_octaves: int = 4
    tile_size_m: float = 0.30
    tile_gray_std: float = 2.0
    seam_width_m: float = 0.0015
    seam_contrast: float = 20.0
    speck_density: float = 100.0
    speck_min_m: float = 0.001
    speck_max_m: float = 0.008
    speck_min_contrast: float = 15.0
    speck_max_contrast: float = 50.0
    dark_fraction: float = 0.8

    def __post_init__(self) -> None:
        check_range("floor.grain.grain_std", self.grain_std, 0.0, 255.0)
        check_positive("floor.grain.grain_size_m", self.grain_size_m)
        check_count("floor.grain.grain_octaves", self.grain_octaves, minimum=1)
        check_non_negative("floor.grain.tile_size_m", self.tile_size_m)
        check_range("floor.grain.tile_gray_std", self.tile_gray_std, 0.0, 255.0)
        check_positive("floor.grain.seam_width_m", self.seam_width_m)
        if self.tile_size_m > 0.0 and self.seam_width_m >= self.tile_size_m:
            raise ConfigError("floor.grain.seam_width_m", f"must be < tile_size_m={self.tile_size_m}, got {self.seam_width_m}")
        check_range("floor.grain.seam_contrast", self.seam_contrast, 0.0, 255.0)
        check_non_negative("floor.grain.speck_density", self.speck_density)
        check_positive("floor.grain.speck_min_m", self.speck_min_m)
        check_positive("floor.grain.speck_max_m", self.speck_max_m)
        if self.speck_max_m < self.speck_min_m:
            raise ConfigError("floor.grain.speck_max_m", f"must be >= speck_min_m={self.speck_min_m}, got {self.speck_max_m}")
        check_range("floor.grain.speck_min_contrast", self.speck_min_contrast, 0.0, 255.0)
        check_range("floor.grain.speck_max_contrast", self.speck_max_contrast, 0.0, 255.0)
        if self.speck_max_contrast < self.speck_min_contrast:
            raise ConfigError(
                "floor.grain.speck_max_contrast", f"must be >= speck_min_contrast={self.speck_min_contrast}, got {self.speck_max_contrast}"
            )
        check_range("floor.grain.dark_fraction", self.dark_fraction, 0.0, 1.0)


def grain_layer(
    config: FloorGrainConfig, shape: tuple[int, int], origin: tuple[float, float], px_per_m: float, rng: np.random.Generator
) -> np.ndarray:
    """Gray-level offsets (float32, ``shape`` = (rows, cols)) of the floor's grain, tiles, seams and specks.

    Args:
        config: the floor's weak texture.
        shape: the raster's ``(rows, cols)`` (rows along y, columns along x).
        origin: world ``(x0, y0)`` (m) of the raster's outer corner (pixel
            ``(0, 0)`` spans ``[x0, x0 + 1 / px_per_m]``).
        px_per_m: raster resolution (px/m).
        rng: the generator every draw comes from (grain, tile tones, the seam
            grid's offset, specks, in that order).
    """
    rows, cols = shape
    layer = np.zeros((rows, cols), dtype=np.float32)
    if rows == 0 or cols == 0:
        return layer
    _add_grain(layer, config, px_per_m, rng)
    _add_tiles(layer, config, origin, px_per_m, rng)
    _add_specks(layer, config, px_per_m, rng)
    return layer


def _add_grain(layer: np.ndarray, config: FloorGrainConfig, px_per_m: float, rng: np.random.Generator) -> None:
    """Smooth multi-octave noise of standard deviation ``grain_std`` (no thresholding: no edges)."""
    if config.grain_std == 0.0:
        return
    rows, cols = layer.shape
    noise = np.zeros_like(layer)
    for octave in range(config.grain_octaves):
        cell_px = config.grain_size_m * px_per_m / 2**octave
        grid = (max(2, math.ceil(rows / cell_px) + 1), max(2, math.ceil(cols / cell_px) + 1))
        coarse = rng.standard_normal(grid, dtype=np.float32)
        noise += np.float32(0.5**octave) * cv2.resize(coarse, (cols, rows), interpolation=cv2.INTER_CUBIC)
    noise *= np.float32(config.grain_std / max(float(noise.std()), 1e-12))
    layer += noise


def _seam_coverage(centres: np.ndarray, origin: float, pitch: float, width: float, px_per_m: float) -> np.ndarray:
    """Fraction of each pixel (centred at ``centres``, m) covered by the nearest seam ``origin + k * pitch``."""
    nearest = origin + np.round((centres - origin) / pitch) * pitch
    half_px = 0.5 / px_per_m
    overlap = np.minimum(centres + half_px, nearest + width / 2) - np.maximum(centres - half_px, nearest - width / 2)
    return np.clip(overlap * px_per_m, 0.0, 1.0).astype(np.float32)


def _add_tiles(
    layer: np.ndarray, config: FloorGrainConfig, origin: tuple[float, float], px_per_m: float, rng: np.random.Generator
) -> None:
    """Tiles of ``tile_size_m`` with their own tone, and the darker seams between them (grid offset drawn)."""
    pitch = config.tile_size_m
    if pitch == 0.0:
        return
    rows, cols = layer.shape
    x = origin[0] + (np.arange(cols) + 0.5) / px_per_m
    y = origin[1] + (np.arange(rows) + 0.5) / px_per_m
    seam_x, seam_y = rng.uniform(0.0, pitch, size=2)  # where the seam grid sits on the raster
    ix = np.floor((x - seam_x) / pitch).astype(np.int64)
    iy = np.floor((y - seam_y) / pitch).astype(np.int64)
    ix -= ix.min()
    iy -= iy.min()
    tones = rng.normal(0.0, config.tile_gray_std, size=(int(iy.max()) + 1, int(ix.max()) + 1)).astype(np.float32)
    layer += tones[iy[:, None], ix[None, :]]
    if config.seam_contrast > 0.0:
        cover_x = _seam_coverage(x, seam_x, pitch, config.seam_width_m, px_per_m)
        cover_y = _seam_coverage(y, seam_y, pitch, config.seam_width_m, px_per_m)
        layer -= np.float32(config.seam_contrast) * np.maximum(cover_y[:, None], cover_x[None, :])


def _add_specks(layer: np.ndarray, config: FloorGrainConfig, px_per_m: float, rng: np.random.Generator) -> None:
    """Poisson-distributed specks: round Gaussian spots with the area of a disc of the drawn diameter.

    A disc of diameter ``d`` has the second moment of a Gaussian of standard
    deviation ``d / 4``; the spot's variance gets one pixel footprint's more
    (1/12 px^2) and its peak is lowered to keep ``contrast * disc area``, so a
    speck below the raster's resolution darkens its pixel by its area's share.
    """
    rows, cols = layer.shape
    area_m2 = rows * cols / px_per_m**2
    n = int(rng.poisson(config.speck_density * area_m2))
    if n == 0:
        return
    centre = rng.uniform((0.0, 0.0), (cols, rows), size=(n, 2)) - 0.5  # (col, row), pixel centres at integers
    diameter_px = px_per_m * np.exp(rng.uniform(math.log(config.speck_min_m), math.log(config.speck_max_m), size=n))
    contrast = rng.uniform(config.speck_min_contrast, config.speck_max_contrast, size=n)
    sign = np.where(rng.random(n) < config.dark_fraction, -1.0, 1.0)
    variance = (diameter_px / 4.0) ** 2 + _PIXEL_VARIANCE
    peak = sign * contrast * (math.pi * diameter_px**2 / 4.0) / (2.0 * math.pi * variance)
    reach = int(math.ceil(_SPECK_SIGMAS * math.sqrt(float(variance.max())))) + 1
    offsets = np.arange(-reach, reach + 1)
    base = np.rint(centre).astype(np.int64)
    c = base[:, 0, None, None] + offsets[None, None, :]  # (n, 1, w)
    r = base[:, 1, None, None] + offsets[None, :, None]  # (n, w, 1)
    d2 = (c - centre[:, 0, None, None]) ** 2 + (r - centre[:, 1, None, None]) ** 2
    values = peak[:, None, None] * np.exp(-0.5 * d2 / variance[:, None, None])
    c, r = np.broadcast_arrays(c, r)
    inside = (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
    np.add.at(layer, (r[inside], c[inside]), values[inside].astype(np.float32))
