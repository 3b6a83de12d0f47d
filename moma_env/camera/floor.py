"""The floor as a camera sees it: a seeded world-frame texture on the plane z = 0.

:class:`FloorConfig` says where the floor is textured (rectangles in world x, y)
and how; everything else is plain: one gray level, where a feature tracker
finds nothing, or, with ``grain`` set, the weak texture of a real floor
(grain, tiles and seams, specks: :mod:`moma_env.camera.floor_grain`) over the
raster's extent. :class:`FloorTexture` draws the raster once from a seeded
generator and renders it as seen by a pinhole camera with lens distortion:
every pixel's ray (see :mod:`moma_env.camera.rays`) is followed to the floor,
one exact resampling of the raster.

Frames and units: world W (x, y on the floor, z up; metres). The raster's pixel
``(col, row)`` is centred on ``x = xmin + (col + 0.5) / px_per_m``,
``y = ymin + (row + 0.5) / px_per_m``. Gray levels are 0-255.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np

from moma_env.camera.backend import as_pose
from moma_env.camera.floor_grain import FloorGrainConfig, grain_layer
from moma_env.camera.rays import PixelRays
from moma_env.config import ConfigError, check_count, check_numbers, check_positive, check_range, from_mapping

__all__ = ["FloorConfig", "FloorTexture"]

#: The floor's sampling map is interpolated from a coarse grid
#: (:meth:`PixelRays.smooth_map`) when every ray of the image border points at
#: least this steeply down (sine of the angle below the horizontal), where the
#: map is nearly affine; otherwise it is computed at every pixel.
_SMOOTH_MAP_MIN_SINE = math.sin(math.radians(20.0))
#: Where the edges of a textured rectangle are sampled (fractions of each edge).
_EDGE_FRACTIONS = np.linspace(0.0, 1.0, 8, endpoint=False)
#: Index of the next corner of a quadrilateral (cyclic).
_NEXT_CORNER = np.array([1, 2, 3, 0])


def remap_into(raster: np.ndarray, sample_map: np.ndarray, out: np.ndarray, border_value: int) -> None:
    """``out[...] = raster`` sampled bilinearly at ``sample_map`` (float32 (rows, cols, 2)); ``border_value`` outside."""
    if out.flags.c_contiguous:
        cv2.remap(raster, sample_map, None, cv2.INTER_LINEAR, dst=out, borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)
    else:
        out[...] = cv2.remap(raster, sample_map, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)

_RECT = ("xmin", "ymin", "xmax", "ymax")
#: Largest floor raster (pixels) a configuration may ask for (~64 MB of uint8).
_MAX_RASTER_PX = 64_000_000
#: Octaves of the texture: each halves the blob size and the amplitude.
_OCTAVES = 3
#: The grain's generator is seeded with ``(seed, _GRAIN_STREAM)``: a stream of its own,
#: so that the textured rectangles are the same with and without grain.
_GRAIN_STREAM = 1


def _check_rect(field: str, value: object) -> tuple[float, float, float, float]:
    rect = check_numbers(field, value, _RECT)
    if rect[2] <= rect[0] or rect[3] <= rect[1]:
        raise ConfigError(field, f"needs xmin < xmax and ymin < ymax, got {rect}")
    return rect  # type: ignore[return-value]


@dataclass(frozen=True)
class FloorConfig:
    """Where and how the floor is textured.

    Attributes:
        extent: ``(xmin, ymin, xmax, ymax)`` of the rastered floor in W (m);
            outside it the floor is plain.
        textured: rectangles ``(xmin, ymin, xmax, ymax)`` in W (m) that carry
            texture; ``None`` means the whole extent, ``()`` a plain floor.
        px_per_m: raster resolution (px/m); finer than the cameras' ground
            resolution keeps the texture sharp.
        feature_size_m: size of the texture's largest blobs (m); two finer
            octaves (1/2 and 1/4 of it) are added.
        contrast: texture amplitude as a fraction of the gray range, in (0, 1].
        sharpness: gain of the tanh that turns the smooth noise into blobs with
            crisp edges (> 0; larger is closer to black and white).
        gray: gray level of the plain floor and mean of the texture (0-255).
        background_gray: gray level drawn where a pixel's ray misses the floor
            (above the horizon of a forward camera).
        seed: seed of the texture's generator (same seed, same floor).
        grain: the weak texture of the untextured floor inside ``extent``
            (:class:`~moma_env.camera.floor_grain.FloorGrainConfig`, or a
            mapping of its fields); ``None``: perfectly plain (one gray level).
    """

    extent: tuple[float, float, float, float] = (-2.0, -2.0, 5.0, 5.0)
    textured: tuple[tuple[float, float, float, float], ...] | None = None
    px_per_m: float = 250.0
    feature_size_m: float = 0.06
    contrast: float = 0.3
    sharpness: float = 1.0
    gray: float = 140.0
    background_gray: float = 90.0
    seed: int = 0
    grain: FloorGrainConfig | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "extent", _check_rect("floor.extent", self.extent))
        if isinstance(self.grain, Mapping):
            object.__setattr__(self, "grain", from_mapping(FloorGrainConfig, self.grain, name="floor.grain"))
        if self.grain is not None and not isinstance(self.grain, FloorGrainConfig):
            raise ConfigError("floor.grain", f"must be a FloorGrainConfig, a mapping or None, got {type(self.grain).__name__}")
        if self.textured is not None:
            try:
                rects = tuple(self.textured)
            except TypeError:
                raise ConfigError("floor.textured", f"must be a sequence of rectangles, got {self.textured!r}") from None
            object.__setattr__(
                self, "textured", tuple(_check_rect(f"floor.textured[{i}]", r) for i, r in enumerate(rects))
            )
        check_positive("floor.px_per_m", self.px_per_m)
        x0, y0, x1, y1 = self.extent
        n_px = math.ceil((x1 - x0) * self.px_per_m) * math.ceil((y1 - y0) * self.px_per_m)
        if n_px > _MAX_RASTER_PX:
            raise ConfigError("floor.px_per_m", f"raster of {n_px} px exceeds {_MAX_RASTER_PX}; lower it or the extent")
        check_positive("floor.feature_size_m", self.feature_size_m)
        check_range("floor.contrast", self.contrast, 0.0, 1.0)
        if self.contrast == 0.0:
            raise ConfigError("floor.contrast", "must be > 0 (use textured=() for a plain floor)")
        check_positive("floor.sharpness", self.sharpness)
        check_range("floor.gray", self.gray, 0.0, 255.0)
        check_range("floor.background_gray", self.background_gray, 0.0, 255.0)
        check_count("floor.seed", self.seed, minimum=0)

    @property
    def textured_rects(self) -> tuple[tuple[float, float, float, float], ...]:
        """The textured rectangles, ``None`` resolved to the whole extent."""
        return (self.extent,) if self.textured is None else self.textured  # type: ignore[return-value]

    @property
    def detailed_rects(self) -> tuple[tuple[float, float, float, float], ...]:
        """Rectangles in W (m) outside which the floor is one gray level: the
        textured ones, or the whole extent when the plain floor has grain."""
        return self.textured_rects if self.grain is None else (self.extent,)


class FloorTexture:
    """The floor raster of a :class:`FloorConfig`, and its rendering by a camera.

    Attributes:
        config: the configuration.
        raster: read-only uint8 array (rows along y, columns along x).
        A_px_w: read-only 3x3 affine map from world ``(x, y, 1)`` (m) to raster
            pixel ``(col, row, 1)``.
    """

    def __init__(self, config: FloorConfig | None = None) -> None:
        config = FloorConfig() if config is None else config
        if not isinstance(config, FloorConfig):
            raise TypeError(f"config must be a FloorConfig, got {type(config).__name__}")
        self.config = config
        x0, y0, x1, y1 = config.extent
        ppm = config.px_per_m
        cols, rows = math.ceil((x1 - x0) * ppm), math.ceil((y1 - y0) * ppm)
        self.A_px_w = np.array([[ppm, 0.0, -x0 * ppm - 0.5], [0.0, ppm, -y0 * ppm - 0.5], [0.0, 0.0, 1.0]])
        self.A_px_w.setflags(write=False)
        self.raster = self._make_raster(rows, cols, np.random.default_rng(config.seed))
        self.raster.setflags(write=False)
        self._pyramid = [self.raster]  # halved copies, built when a camera first needs them
        self._plain = int(round(config.gray))
        self._background = int(round(config.background_gray))

    def _make_raster(self, rows: int, cols: int, rng: np.random.Generator) -> np.ndarray:
        """Plain gray (with its grain if configured), with seeded multi-octave blob
        texture inside the textured rectangles."""
        cfg = self.config
        if cfg.grain is None:
            raster = np.full((rows, cols), round(cfg.gray), dtype=np.uint8)
        else:
            grain_rng = np.random.default_rng([cfg.seed, _GRAIN_STREAM])
            plain = grain_layer(cfg.grain, (rows, cols), cfg.extent[:2], cfg.px_per_m, grain_rng)
            plain += np.float32(cfg.gray)
            raster = np.clip(np.rint(plain), 0, 255).astype(np.uint8)
        windows = []
        for rect in cfg.textured_rects:
            c0, r0 = (self.A_px_w @ (rect[0], rect[1], 1.0))[:2] + 0.5
            c1, r1 = (self.A_px_w @ (rect[2], rect[3], 1.0))[:2] + 0.5
            c0, r0 = max(int(round(c0)), 0), max(int(round(r0)), 0)
            c1, r1 = min(int(round(c1)), cols), min(int(round(r1)), rows)
            if c0 < c1 and r0 < r1:
                windows.append((r0, r1, c0, c1))
        if not windows:
            return raster
        # One texture over the whole raster, so overlapping rectangles agree.
        noise = np.zeros((rows, cols), dtype=np.float32)
        extent_m = (rows / cfg.px_per_m, cols / cfg.px_per_m)
        for octave in range(_OCTAVES):
            cell = cfg.feature_size_m / 2**octave
            grid = (max(2, math.ceil(extent_m[0] / cell) + 1), max(2, math.ceil(extent_m[1] / cell) + 1))
            coarse = rng.standard_normal(grid, dtype=np.float32)
            noise += 0.5**octave * cv2.resize(coarse, (cols, rows), interpolation=cv2.INTER_CUBIC)
        noise *= cfg.sharpness / max(float(noise.std()), 1e-12)
        texture = cfg.gray + 127.5 * cfg.contrast * np.tanh(noise)
        texture = np.clip(np.rint(texture), 0, 255).astype(np.uint8)
        for r0, r1, c0, c1 in windows:
            raster[r0:r1, c0:c1] = texture[r0:r1, c0:c1]
        return raster

    def homography(self, T_w_c: np.ndarray) -> np.ndarray:
        """3x3 map from normalised camera coordinates ``(x, y, 1)`` to raster pixels.

        The ray ``d = R_w_c @ (x, y, 1)`` from the camera centre ``t`` meets the
        floor at ``t + s d`` with ``s = -t_z / d_z``, so the floor point's ``(x, y)``
        is ``(t_xy d_z - t_z d_xy) / d_z``: a homography of ``(x, y, 1)``. It is
        only meaningful where ``s > 0`` (see :meth:`render`).
        """
        T = as_pose(T_w_c, "T_w_c")
        R, t = T[:3, :3], T[:3, 3]
        H_w_n = np.vstack([t[0] * R[2] - t[2] * R[0], t[1] * R[2] - t[2] * R[1], R[2]])
        return self.A_px_w @ H_w_n

    def _level_for(self, rays: PixelRays, H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pyramid level to sample and its homography: the coarsest level with at
        least one raster pixel per image pixel at the principal point (no aliasing of
        a texture finer than the camera resolves; level 0 when the camera is close).
        For a camera looking steeply down, where the scale varies little over the image.

        Level k is ``cv2.pyrDown`` applied k times; its pixel ``c`` sits on ``2**k c``
        of the full raster, so its homography is ``diag(2**-k, 2**-k, 1) @ H``.
        """
        camera = rays.camera
        x, y = rays.border_xy[-1]  # the principal point's ray
        step = 1.0 / camera.config.fx, 1.0 / camera.config.fy
        centre, right, down = (H @ np.array([[x, x + step[0], x], [y, y, y + step[1]], [1.0, 1.0, 1.0]])).T
        c = centre[:2] / centre[2]
        scale = max(np.hypot(*(right[:2] / right[2] - c)), np.hypot(*(down[:2] / down[2] - c)))
        if not math.isfinite(scale) or scale < 2.0:
            return self.raster, H
        level = int(math.floor(math.log2(scale)))
        while len(self._pyramid) <= level and min(self._pyramid[-1].shape) >= 2:
            smaller = cv2.pyrDown(self._pyramid[-1])
            smaller.setflags(write=False)
            self._pyramid.append(smaller)
        level = min(level, len(self._pyramid) - 1)
        factor = 0.5**level
        return self._pyramid[level], np.diag([factor, factor, 1.0]) @ H

    def _textured_window(
        self, rays: PixelRays, T: np.ndarray, border_dz: np.ndarray
    ) -> tuple[int, int, int, int] | None:
        """Image window ``(x0, y0, x1, y1)`` holding every textured floor pixel in view, or None.

        For a camera whose border rays all point down: the floor in view lies
        within the bounding box of where those rays meet the floor. If one
        textured rectangle holds that box, the window is the whole image;
        otherwise each textured rectangle is clipped to the box and its border
        (sampled, as the lens bends straight edges) projected into the image.
        """
        R, t = T[:3, :3], T[:3, 3]
        d = np.column_stack([rays.border_xy, np.ones(len(rays.border_xy))]) @ R.T
        ground = t[:2] + (-t[2] / border_dz)[:, None] * d[:, :2]
        gx0, gy0 = ground.min(axis=0)
        gx1, gy1 = ground.max(axis=0)
        rects = self.config.detailed_rects
        if any(x0 <= gx0 and y0 <= gy0 and gx1 <= x1 and gy1 <= y1 for x0, y0, x1, y1 in rects):
            return (0, 0, rays.shape[1], rays.shape[0])  # the floor in view is all textured
        samples = []
        for x0, y0, x1, y1 in rects:
            x0, y0, x1, y1 = max(x0, gx0), max(y0, gy0), min(x1, gx1), min(y1, gy1)
            if x0 < x1 and y0 < y1:
                box = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
                # Side k sampled at the fractions f: box[k] + f * (box[k + 1] - box[k]).
                samples.append((box[:, None, :] + _EDGE_FRACTIONS[None, :, None] * (box[_NEXT_CORNER] - box)[:, None, :]).reshape(-1, 2))
        if not samples:
            return None
        points_w = np.column_stack([np.concatenate(samples), np.zeros(sum(len(part) for part in samples))])
        uv, r2 = rays.camera.project_with_r2((points_w - t) @ R)
        if not float(r2.max()) < rays.camera.fold_r2:
            return (0, 0, rays.shape[1], rays.shape[0])  # beyond the lens model's fold: bound by the image
        return rays.roi_of(uv)

    def render(self, rays: PixelRays, T_w_c: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The floor seen from ``T_w_c`` (4x4, C in W) by the camera of ``rays``: uint8 (height, width).

        Looking steeply down (every border ray 20 degrees or more below the
        horizontal) the sampling map is interpolated from a 4 px grid (error
        below 0.01 raster px for a downward camera tilted by up to 17 degrees,
        see the tests), only the image window of the textured rectangles is
        resampled, and from the pyramid level that matches the camera's ground
        resolution (no aliasing of a raster finer than the camera resolves);
        otherwise the full raster is sampled with a map exact at every pixel.

        Pixels whose ray does not meet the floor in front of the camera (above
        the horizon, or a camera below the floor) get ``background_gray``; the
        floor outside the raster is plain. ``out``, if given, is filled and returned.
        """
        if out is None:
            out = np.empty(rays.shape, dtype=np.uint8)
        self.draw(rays, T_w_c, out)
        return out

    def draw(self, rays: PixelRays, T_w_c: np.ndarray, out: np.ndarray) -> tuple[int, int, int, int] | None:
        """Fill ``out`` (uint8, the camera's shape) as :meth:`render` does; return the image
        window ``(x0, y0, x1, y1)`` outside which every pixel is one gray level, or None if all are."""
        T = as_pose(T_w_c, "T_w_c")
        h, w = rays.shape
        full = (0, 0, w, h)
        if T[2, 3] <= 0.0:
            out[:] = self._background
            return None
        Rz = T[2, :3]
        border_dz = rays.border_xy @ Rz[:2] + Rz[2]
        if float(border_dz.min()) >= 0.0:
            out[:] = self._background  # every border ray points up: no floor in view
            return None
        H = self.homography(T)
        border_norm = np.sqrt(np.einsum("ij,ij->i", rays.border_xy, rays.border_xy) + 1.0)
        if float((border_dz / border_norm).max()) > -_SMOOTH_MAP_MIN_SINE:
            remap_into(self.raster, rays.sample_map(H), out, self._plain)
            if float(border_dz.max()) >= 0.0:
                # The horizon crosses the image: rays pointing up see no floor.
                xy = rays.xy
                dz = xy[..., 0] * np.float32(Rz[0])
                dz += xy[..., 1] * np.float32(Rz[1])
                dz += np.float32(Rz[2])
                out[dz >= 0.0] = self._background
            return full
        # Steeply down: only the image window of the textured rectangles is resampled.
        roi = self._textured_window(rays, T, border_dz)
        if roi is None:
            out[:] = self._plain
            return None
        x0, y0, x1, y1 = roi
        if roi != full:
            out[:] = self._plain
        raster, H = self._level_for(rays, H)
        remap_into(raster, rays.smooth_map(H)[y0:y1, x0:x1], out[y0:y1, x0:x1], self._plain)
        return roi
