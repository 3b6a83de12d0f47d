"""Compiled hot paths of the geometric camera: marker visibility and projection,
undistortion, and the PnP solve plus reprojection error of every board.

On arrays of a few dozen corners, each numpy call costs a microsecond or two
however little it computes; these numba kernels do the same work in one call
each. They implement the visibility checks listed in
:mod:`moma_env.camera.visibility` and the lens model of
:mod:`moma_env.camera.distortion` / :mod:`moma_env.camera.pinhole` (the tests
compare them with those and with per-marker definitions).

Camera parameters travel as one float64 vector, built by :func:`camera_parameters`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from moma_env.camera.planar_pnp import solve_planar_pnp_kernel
from moma_env.camera.pinhole import PinholeCamera

__all__ = ["camera_parameters", "project_boards", "undistort_points", "solve_boards", "reprojection_sq"]

# Indices into the parameter vector.
_FX, _FY, _CX, _CY, _K1, _K2, _P1, _P2, _K3 = range(9)
_LO, _HI_U, _HI_V, _MIN_SIDE_SQ, _MIN_RANGE, _MAX_RANGE_SQ, _COS_MAX, _FOLD_R2 = range(9, 17)
_N_PARAMETERS = 17
#: Undistortion stops when an iteration moves a point by less than this (normalised units) ...
_UNDISTORT_TOLERANCE = 1e-15
#: ... or after this many iterations (each contracts the error by ~|k1| r^2, a few percent).
_UNDISTORT_ITERATIONS = 100


def camera_parameters(camera: PinholeCamera) -> np.ndarray:
    """The kernels' float64 parameter vector of ``camera`` (intrinsics, distortion, limits)."""
    cfg = camera.config
    p = np.empty(_N_PARAMETERS)
    p[_FX], p[_FY], p[_CX], p[_CY] = cfg.fx, cfg.fy, cfg.cx, cfg.cy
    p[_K1], p[_K2], p[_P1], p[_P2], p[_K3] = cfg.dist
    p[_LO] = cfg.margin_px - 0.5
    p[_HI_U] = cfg.width - 0.5 - cfg.margin_px
    p[_HI_V] = cfg.height - 0.5 - cfg.margin_px
    p[_MIN_SIDE_SQ] = cfg.min_marker_px**2
    p[_MIN_RANGE] = cfg.min_range_m
    p[_MAX_RANGE_SQ] = cfg.max_range_m**2
    p[_COS_MAX] = math.cos(math.radians(cfg.max_incidence_deg))
    p[_FOLD_R2] = camera.fold_r2
    p.setflags(write=False)
    return p


@numba.njit(cache=True)
def _distort_to_pixel(x: float, y: float, p: np.ndarray) -> tuple[float, float, float]:
    """Pixel ``(u, v)`` of normalised ``(x, y)`` with distortion, and ``r2 = x^2 + y^2``."""
    r2 = x * x + y * y
    radial = 1.0 + r2 * (p[_K1] + r2 * (p[_K2] + r2 * p[_K3]))
    xd = x * radial
    yd = y * radial
    p1 = p[_P1]
    p2 = p[_P2]
    if p1 != 0.0 or p2 != 0.0:
        xy2 = 2.0 * x * y
        xd += p1 * xy2 + p2 * (r2 + 2.0 * x * x)
        yd += p1 * (r2 + 2.0 * y * y) + p2 * xy2
    return p[_FX] * xd + p[_CX], p[_FY] * yd + p[_CY], r2


@numba.njit(cache=True)
def project_boards(
    poses: np.ndarray,
    corners_m: np.ndarray,
    real: np.ndarray,
    normals: np.ndarray,
    p: np.ndarray,
    uv: np.ndarray,
    visible: np.ndarray,
    centres: np.ndarray,
) -> int:
    """Project every marker corner and decide which markers are visible (checks 1-6).

    Args:
        poses: (B, 3, 4) top rows of ``T_c_m`` of each board (m).
        corners_m: (B, m, 4, 3) marker corners in the board frames M (m), ArUco order.
        real: (B, m) False for padding markers (never visible).
        normals: (B, 3) unit normal of each board's printed face (z_M) in C, i.e.
            ``poses[:, :, 2]`` for boards whose markers lie in ``z_M = 0``.
        p: camera parameters (:func:`camera_parameters`).
        uv: (B, m, 4, 2) output pixels (meaningless for corners with depth below
            ``min_range_m / 2``; their markers fail check 1).
        visible: (B, m) output mask.
        centres: (B, m, 3) output marker centres in C (m).

    Returns:
        The number of visible markers.
    """
    n_boards, n_markers = real.shape
    min_depth = 0.5 * p[_MIN_RANGE]
    count = 0
    for b in range(n_boards):
        T = poses[b]
        nx = normals[b, 0]
        ny = normals[b, 1]
        nz = normals[b, 2]
        for j in range(n_markers):
            ok = real[b, j]
            sx = 0.0
            sy = 0.0
            sz = 0.0
            for k in range(4):
                X = corners_m[b, j, k, 0]
                Y = corners_m[b, j, k, 1]
                Z = corners_m[b, j, k, 2]
                x = T[0, 0] * X + T[0, 1] * Y + T[0, 2] * Z + T[0, 3]
                y = T[1, 0] * X + T[1, 1] * Y + T[1, 2] * Z + T[1, 3]
                z = T[2, 0] * X + T[2, 1] * Y + T[2, 2] * Z + T[2, 3]
                sx += x
                sy += y
                sz += z
                if not z > p[_MIN_RANGE]:  # check 1
                    ok = False
                zc = z if z > min_depth else min_depth
                u, v, r2 = _distort_to_pixel(x / zc, y / zc, p)
                uv[b, j, k, 0] = u
                uv[b, j, k, 1] = v
                if not r2 < p[_FOLD_R2]:  # check 2
                    ok = False
                if not (u >= p[_LO] and v >= p[_LO] and u <= p[_HI_U] and v <= p[_HI_V]):  # check 3
                    ok = False
            for k in range(4):  # check 4
                du = uv[b, j, (k + 1) % 4, 0] - uv[b, j, k, 0]
                dv = uv[b, j, (k + 1) % 4, 1] - uv[b, j, k, 1]
                if not du * du + dv * dv >= p[_MIN_SIDE_SQ]:
                    ok = False
            cx = 0.25 * sx
            cy = 0.25 * sy
            cz = 0.25 * sz
            centres[b, j, 0] = cx
            centres[b, j, 1] = cy
            centres[b, j, 2] = cz
            range_sq = cx * cx + cy * cy + cz * cz
            if not range_sq <= p[_MAX_RANGE_SQ]:  # check 6
                ok = False
            # check 5: cos(incidence) = z_M . (-centre) / |centre| >= cos_max.
            if not nx * cx + ny * cy + nz * cz <= -p[_COS_MAX] * np.sqrt(range_sq):
                ok = False
            visible[b, j] = ok
            if ok:
                count += 1
    return count


@numba.njit(cache=True)
def _undistort_one(u: float, v: float, p: np.ndarray) -> tuple[float, float]:
    """Normalised undistorted ``(x, y)`` of pixel ``(u, v)`` (OpenCV's fixed-point iteration)."""
    x0 = (u - p[_CX]) / p[_FX]
    y0 = (v - p[_CY]) / p[_FY]
    x = x0
    y = y0
    k1 = p[_K1]
    k2 = p[_K2]
    k3 = p[_K3]
    p1 = p[_P1]
    p2 = p[_P2]
    if k1 == 0.0 and k2 == 0.0 and k3 == 0.0 and p1 == 0.0 and p2 == 0.0:
        return x, y
    for _ in range(_UNDISTORT_ITERATIONS):
        r2 = x * x + y * y
        icdist = 1.0 / (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        xn = (x0 - dx) * icdist
        yn = (y0 - dy) * icdist
        done = abs(xn - x) < _UNDISTORT_TOLERANCE and abs(yn - y) < _UNDISTORT_TOLERANCE
        x = xn
        y = yn
        if done:
            break
    return x, y


@numba.njit(cache=True)
def undistort_points(px: np.ndarray, p: np.ndarray, xy: np.ndarray) -> None:
    """Normalised undistorted coordinates of pixels ``px`` (n, 2), into ``xy`` (n, 2)."""
    for i in range(px.shape[0]):
        x, y = _undistort_one(px[i, 0], px[i, 1], p)
        xy[i, 0] = x
        xy[i, 1] = y


@numba.njit(cache=True)
def reprojection_sq(T: np.ndarray, obj: np.ndarray, px: np.ndarray, p: np.ndarray) -> float:
    """Sum of squared pixel distances between ``px`` (k, 2) and the corners ``obj`` (k, 3)
    (in M) reprojected with the pose ``T`` (``T_c_m``, 4x4) and the lens distortion."""
    total = 0.0
    for i in range(obj.shape[0]):
        X = obj[i, 0]
        Y = obj[i, 1]
        Z = obj[i, 2]
        x = T[0, 0] * X + T[0, 1] * Y + T[0, 2] * Z + T[0, 3]
        y = T[1, 0] * X + T[1, 1] * Y + T[1, 2] * Z + T[1, 3]
        z = T[2, 0] * X + T[2, 1] * Y + T[2, 2] * Z + T[2, 3]
        u, v, _ = _distort_to_pixel(x / z, y / z, p)
        du = u - px[i, 0]
        dv = v - px[i, 1]
        total += du * du + dv * dv
    return total


@numba.njit(cache=True)
def solve_boards(
    obj: np.ndarray, px: np.ndarray, starts: np.ndarray, p: np.ndarray, T: np.ndarray, rms: np.ndarray
) -> None:
    """PnP (:mod:`moma_env.camera.planar_pnp`) and RMS reprojection error of each board.

    Args:
        obj: (n, 3) visible corners in their board frames M (m), board after board.
        px: (n, 2) their measured pixels.
        starts: (K + 1,) first row of each board in ``obj``/``px``, then ``n``.
        p: camera parameters (:func:`camera_parameters`).
        T: (K, 4, 4) output poses ``T_c_m``.
        rms: (K,) output RMS reprojection errors (px); NaN where the solve failed.
    """
    n = px.shape[0]
    xy = np.empty((n, 2))
    undistort_points(px, p, xy)
    obj_xy = np.ascontiguousarray(obj[:, :2])
    for b in range(starts.shape[0] - 1):
        first = starts[b]
        end = starts[b + 1]
        if solve_planar_pnp_kernel(obj_xy[first:end], xy[first:end], T[b]):
            rms[b] = np.sqrt(reprojection_sq(T[b], obj[first:end], px[first:end], p) / (end - first))
        else:
            rms[b] = np.nan
