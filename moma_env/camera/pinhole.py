"""Pinhole camera with OpenCV lens distortion: projection, undistortion, footprint.

Frames and units: points are in the camera frame C (OpenCV: x right, y down,
z along the optical axis; metres); pixels are ``(u, v)`` with ``u`` right and ``v``
down, pixel centres at integer coordinates, so the sensor spans
``[-0.5, width - 0.5] x [-0.5, height - 0.5]``. A camera pose ``T_w_c`` maps
points of C to the world W (``p_w = T_w_c @ p_c``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from moma_env.camera.config import CameraConfig
from moma_env.camera.distortion import distort, fold_radius_sq

__all__ = ["PinholeCamera"]

# Iterative undistortion: stop when the reprojection is within 1e-13 (normalised
# units) or after 100 iterations; OpenCV's default (5 iterations) leaves errors of
# ~1e-7 that would show up as ~1e-5 m in a PnP pose.
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-13)
#: Rays along the principal row that outline :meth:`PinholeCamera.view_wedge`'s arc.
_WEDGE_SAMPLES = 9


class PinholeCamera:
    """The intrinsic model of one camera, built from a :class:`CameraConfig`.

    Attributes:
        config: the configuration.
        K: read-only 3x3 camera matrix (px).
        dist: read-only array of the five distortion coefficients.
        fold_r2: squared normalised radius beyond which the lens model folds over
            (``inf`` if it never does); points beyond it are not imaged.
        sensor_corners_px: read-only (4, 2) sensor corners (px): top-left,
            top-right, bottom-right, bottom-left.
    """

    def __init__(self, config: CameraConfig) -> None:
        if not isinstance(config, CameraConfig):
            raise TypeError(f"config must be a CameraConfig, got {type(config).__name__}")
        self.config = config
        self._dist = tuple(config.dist)
        self.K = np.array([[config.fx, 0.0, config.cx], [0.0, config.fy, config.cy], [0.0, 0.0, 1.0]])
        self.K.setflags(write=False)
        self.dist = np.array(self._dist)
        self.dist.setflags(write=False)
        self.fold_r2 = fold_radius_sq(self._dist)
        self._tangential = self._dist[2] != 0.0 or self._dist[3] != 0.0
        self._distorted = any(c != 0.0 for c in self._dist)
        self._focal = np.array([config.fx, config.fy])
        self._centre = np.array([config.cx, config.cy])
        self._lo = config.margin_px - 0.5
        self._hi = np.array([config.width - 0.5 - config.margin_px, config.height - 0.5 - config.margin_px])
        w, h = config.width, config.height
        self.sensor_corners_px = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
        self.sensor_corners_px.setflags(write=False)
        # Rays (z = 1) through the sensor corners and the edge midpoints through
        # the principal point, undistorted once here.
        edges = np.array([[-0.5, config.cy], [w - 0.5, config.cy], [config.cx, -0.5], [config.cx, h - 0.5]])
        rays = self.undistort(np.vstack([self.sensor_corners_px, edges]))
        self._corner_rays = np.column_stack([rays[:4], np.ones(4)])
        (xl, _), (xr, _), (_, yt), (_, yb) = rays[4:]
        # The same four rays, ``margin_px`` inside the border (where a corner still counts).
        m = config.margin_px
        inset = self.undistort(np.array([[m - 0.5, config.cy], [w - 0.5 - m, config.cy], [config.cx, m - 0.5], [config.cx, h - 0.5 - m]]))
        self._half_view_tan = float(min(-inset[0, 0], inset[1, 0], -inset[2, 1], inset[3, 1]))
        # Rays (z = 1) through the row of the principal point, left edge to right edge.
        row = np.column_stack([np.linspace(-0.5, w - 0.5, _WEDGE_SAMPLES), np.full(_WEDGE_SAMPLES, config.cy)])
        self._row_rays = np.column_stack([self.undistort(row), np.ones(_WEDGE_SAMPLES)])
        self._fov_deg = (
            math.degrees(math.atan(xr) - math.atan(xl)),
            math.degrees(math.atan(yb) - math.atan(yt)),
        )

    # ------------------------------------------------------------------ projection
    def project(self, points_c: np.ndarray) -> np.ndarray:
        """Pixels ``(..., 2)`` of points ``(..., 3)`` given in C (m), with distortion.

        Matches ``cv2.projectPoints`` with zero rvec/tvec for points in front of
        the camera; points with ``z <= 0`` give NaN.
        """
        return self.project_with_r2(points_c)[0]

    def project_with_r2(self, points_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Like :meth:`project`, also returning ``r2 = (x**2 + y**2) / z**2`` ``(...)``,
        the squared undistorted normalised radius (compare with :attr:`fold_r2`).
        Both are NaN where ``z <= 0``."""
        p = np.asarray(points_c, dtype=float)
        if p.shape[-1] != 3:
            raise ValueError(f"points must have shape (..., 3), got {p.shape}")
        z = p[..., 2:]
        xy = p[..., :2] / np.where(z > 0.0, z, np.nan)
        if self._tangential:
            xd, yd, r2 = distort(xy[..., 0], xy[..., 1], self._dist)
            px = np.stack((xd, yd), axis=-1)
        else:
            # Radial only (the usual case): the same formula in fewer array ops.
            k1, k2, _, _, k3 = self._dist
            r2 = np.einsum("...i,...i->...", xy, xy)
            if k3 != 0.0:
                radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            else:
                radial = 1.0 + r2 * (k1 + r2 * k2)
            px = xy * radial[..., None]
        px *= self._focal
        px += self._centre
        return px, r2

    def undistort(self, px: np.ndarray) -> np.ndarray:
        """Normalised undistorted coordinates ``(x/z, y/z)`` of pixels ``(n, 2)``.

        Inverts :meth:`project` to ~1e-13 (normalised units) inside the image.
        The result is a view of an (n, 1, 2) array, so ``reshape(-1, 1, 2)``
        gives solvePnP's layout without a copy.
        """
        pts = np.ascontiguousarray(px, dtype=float).reshape(-1, 1, 2)
        if pts.shape[0] == 0:
            return np.empty((0, 2))
        if not self._distorted:
            return ((pts - self._centre) / self._focal).reshape(-1, 2)
        return cv2.undistortPoints(pts, self.K, self.dist, criteria=_UNDISTORT_CRITERIA).reshape(-1, 2)

    def in_image(self, px: np.ndarray, margin: float | None = None) -> np.ndarray:
        """Boolean mask ``(...)``: pixels ``(..., 2)`` at least ``margin`` px inside the sensor.

        ``margin`` defaults to ``config.margin_px``. NaN pixels are outside.
        """
        return np.logical_and.reduce(self.in_image_xy(px, margin), axis=-1)

    def in_image_xy(self, px: np.ndarray, margin: float | None = None) -> np.ndarray:
        """Per coordinate: boolean ``(..., 2)``, True where ``u`` (resp. ``v``) is
        inside the sensor by ``margin`` px (default ``config.margin_px``)."""
        if margin is None:
            lo, hi = self._lo, self._hi
        else:
            m = float(margin)
            lo, hi = m - 0.5, np.array([self.config.width - 0.5 - m, self.config.height - 0.5 - m])
        px = np.asarray(px, dtype=float)
        ok = px >= lo
        ok &= px <= hi
        return ok

    # ------------------------------------------------------------------ geometry
    @property
    def field_of_view_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view (deg) through the principal point,
        edge to edge of the sensor, distortion included."""
        return self._fov_deg

    @property
    def axis_half_view_tan(self) -> float:
        """Tangent of the narrowest half field of view from the optical axis:
        the smallest of the four normalised distances (``|x|`` or ``|y|`` of the
        undistorted ray) from the principal point to the sensor edges along the
        principal row and column, ``margin_px`` inside the border, distortion
        included. A point at depth ``z`` (m) on the optical axis's plane is in
        view within ``z * axis_half_view_tan`` (m) of the axis in every direction
        along the image axes."""
        return self._half_view_tan

    def view_wedge(self, T_w_c: np.ndarray, range_m: float) -> np.ndarray:
        """The horizontal field of view of a camera looking forward, as a floor polygon.

        World ``(x, y)`` (m), ``(10, 2)``: the camera centre, then the points at
        ``range_m`` (m) from it along the rays of the principal row (left edge of
        the image to the right edge), each ray's direction projected on the floor.
        What a ground robot's camera can see up to its range; for a camera looking
        straight down, where that projection vanishes, use :meth:`ground_footprint`
        (rows of a ray with no horizontal direction are NaN).
        """
        T = np.asarray(T_w_c, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"T_w_c must be 4x4, got {T.shape}")
        range_m = float(range_m)
        if not range_m > 0.0:
            raise ValueError(f"range_m must be > 0, got {range_m}")
        d = (self._row_rays @ T[:3, :3].T)[:, :2]
        norm = np.hypot(d[:, 0], d[:, 1])
        level = norm > 1e-9  # rays with a horizontal direction (each ray has length >= 1)
        arc = np.full(d.shape, np.nan)
        arc[level] = T[:2, 3] + range_m * d[level] / norm[level, None]
        return np.vstack([T[:2, 3], arc])

    def ground_footprint(self, T_w_c: np.ndarray, z: float = 0.0) -> np.ndarray:
        """World ``(x, y)`` (m) where the rays of the four sensor corners meet the plane ``z``.

        Rows in the order of :attr:`sensor_corners_px` (top-left, top-right,
        bottom-right, bottom-left of the image). A ray that does not hit the plane
        in front of the camera (above the horizon) gives a NaN row. The rays are
        exact (undistorted) corner rays; the footprint's edges between corners are
        drawn straight.
        """
        T = np.asarray(T_w_c, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"T_w_c must be 4x4, got {T.shape}")
        d = self._corner_rays @ T[:3, :3].T
        origin = T[:3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (float(z) - origin[2]) / d[:, 2]
        s = np.where(np.isfinite(s) & (s > 0.0), s, np.nan)
        return origin[:2] + s[:, None] * d[:, :2]
