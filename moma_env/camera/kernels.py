"""Compiled hot paths of the geometric camera: marker visibility and projection,
undistortion, and the PnP solve plus reprojection error of every board.

On arrays of a few dozen corners, each numpy call costs a microsecond or two
however little it computes; these numba kernels do the same work in one call
each. They implement the visibility checks listed in
:mod:`moma_env.camera.visibility` and the lens model of
:mod:`moma_env.camera.distortion` / :mod:`moma_env.camera.pinhole` (the tests
compare them with those and with per-marker definitions).

Camera parameters travel as one float64 vector, built by :func:`camera_parameters`.
:func:`project_markers` and :func:`solve_boards` take boards of many frames at once
(each board with its own camera pose and world up, and its row of a table of camera
parameters and solve settings), so that a batch of frames costs one call each, even
when every frame's camera has its own intrinsics and noise (the random scenarios of a
vector env; see :mod:`moma_env.camera.batch`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from moma_env.camera.planar_pnp import (
    pose_information,
    refine_pose,
    refine_warm_start,
    refine_two_starts,
    solve_planar_pnp_candidates,
    spd_inverse,
)
from moma_env.camera.pinhole import PinholeCamera

__all__ = [
    "SOLVED_FULL",
    "SOLVED_WARM",
    "WARM_REJECTED",
    "board_offsets",
    "camera_parameters",
    "covariance_finite",
    "pixel_weights",
    "project_boards",
    "project_markers",
    "reprojection_sq",
    "solve_boards",
    "solve_settings",
    "undistort_points",
]

# Indices into the parameter vector.
_FX, _FY, _CX, _CY, _K1, _K2, _P1, _P2, _K3 = range(9)
_LO, _HI_U, _HI_V, _MIN_SIDE_SQ, _MIN_RANGE, _MAX_RANGE_SQ, _COS_MAX, _FOLD_R2 = range(9, 17)
_N_PARAMETERS = 17
# Indices into the settings vector of solve_boards (see solve_settings).
_UPRIGHT, _SIGMA, _SIGMA_FLOOR, _PRIOR, _WARM_MAX_RMS = range(5)
#: Values of solve_boards' ``status`` output.
SOLVED_FULL, SOLVED_WARM, WARM_REJECTED = 0, 1, 2
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
def board_offsets(T_w_m: np.ndarray, T_w_c: np.ndarray, board_camera: np.ndarray) -> np.ndarray:
    """The boards' poses in W relative to their cameras' positions, the right factor of
    the top rows of ``T_c_m = inv(T_w_c) @ T_w_m``, which are ``R_w_c^T @ [R_w_m | p_w_m - p_w_c]``.

    Args:
        T_w_m: (B, 4, 4) board poses in W (m).
        T_w_c: (F, 4, 4) camera poses in W (m).
        board_camera: (B,) int64 index in ``T_w_c`` of each board's camera.

    Returns:
        (B, 3, 4) ``[R_w_m | p_w_m - p_w_c]`` of each board (m): its top three rows with its
        camera's position subtracted from the translation column.
    """
    n = T_w_m.shape[0]
    out = np.empty((n, 3, 4))
    for b in range(n):
        f = board_camera[b]
        for i in range(3):
            out[b, i, 0] = T_w_m[b, i, 0]
            out[b, i, 1] = T_w_m[b, i, 1]
            out[b, i, 2] = T_w_m[b, i, 2]
            out[b, i, 3] = T_w_m[b, i, 3] - T_w_c[f, i, 3]
    return out


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
def _project_marker(
    T: np.ndarray,
    corners: np.ndarray,
    nx: float,
    ny: float,
    nz: float,
    p: np.ndarray,
    uv: np.ndarray,
    centre: np.ndarray,
) -> bool:
    """Project one marker and decide whether it is visible (checks 1-6).

    Args:
        T: (3, 4) top rows of its board's ``T_c_m`` (m).
        corners: (4, 3) its corners in the board frame M (m), ArUco order.
        nx, ny, nz: unit normal of the printed face (z_M) in C.
        p: camera parameters (:func:`camera_parameters`).
        uv: (4, 2) output pixels (meaningless for corners with depth below
            ``min_range_m / 2``; the marker then fails check 1).
        centre: (3,) output marker centre in C (m).

    Returns:
        True if the marker passes checks 1-6.
    """
    min_depth = 0.5 * p[_MIN_RANGE]
    ok = True
    sx = 0.0
    sy = 0.0
    sz = 0.0
    for k in range(4):
        X = corners[k, 0]
        Y = corners[k, 1]
        Z = corners[k, 2]
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
        uv[k, 0] = u
        uv[k, 1] = v
        if not r2 < p[_FOLD_R2]:  # check 2
            ok = False
        if not (u >= p[_LO] and v >= p[_LO] and u <= p[_HI_U] and v <= p[_HI_V]):  # check 3
            ok = False
    for k in range(4):  # check 4
        du = uv[(k + 1) % 4, 0] - uv[k, 0]
        dv = uv[(k + 1) % 4, 1] - uv[k, 1]
        if not du * du + dv * dv >= p[_MIN_SIDE_SQ]:
            ok = False
    cx = 0.25 * sx
    cy = 0.25 * sy
    cz = 0.25 * sz
    centre[0] = cx
    centre[1] = cy
    centre[2] = cz
    range_sq = cx * cx + cy * cy + cz * cz
    if not range_sq <= p[_MAX_RANGE_SQ]:  # check 6
        ok = False
    # check 5: cos(incidence) = z_M . (-centre) / |centre| >= cos_max.
    if not nx * cx + ny * cy + nz * cz <= -p[_COS_MAX] * np.sqrt(range_sq):
        ok = False
    return ok


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
    count = 0
    for b in range(n_boards):
        for j in range(n_markers):
            ok = _project_marker(
                poses[b], corners_m[b, j], normals[b, 0], normals[b, 1], normals[b, 2], p, uv[b, j], centres[b, j]
            )
            ok = ok and real[b, j]
            visible[b, j] = ok
            if ok:
                count += 1
    return count


@numba.njit(cache=True)
def project_markers(
    poses: np.ndarray,
    board_markers: np.ndarray,
    corners_m: np.ndarray,
    parameters: np.ndarray,
    board_camera: np.ndarray,
    uv: np.ndarray,
    visible: np.ndarray,
    centres: np.ndarray,
    board_visible: np.ndarray,
) -> int:
    """:func:`project_boards` on boards of any number of markers, without padding.

    The markers of all boards are stacked: board ``b`` owns the markers
    ``board_markers[b]:board_markers[b + 1]``. Every board is planar (markers in
    ``z_M = 0``), so its face normal in C is ``poses[b, :, 2]``. The boards may
    come from several camera poses (a batch of measurements): each carries its
    own ``T_c_m`` and names the row of ``parameters`` of the camera that saw it.

    Args:
        poses: (B, 3, 4) top rows of ``T_c_m`` of each board (m).
        board_markers: (B + 1,) int64, non-decreasing, ``board_markers[B] == M``.
        corners_m: (M, 4, 3) marker corners in their board frames M (m), ArUco order.
        parameters: (C, P) camera parameters (:func:`camera_parameters`), one row per camera.
        board_camera: (B,) int64 row of ``parameters`` of each board's camera.
        uv: (M, 4, 2) output pixels (see :func:`_project_marker`).
        visible: (M,) output mask.
        centres: (M, 3) output marker centres in C (m).
        board_visible: (B,) int64 output: visible markers per board.

    Returns:
        The number of visible markers.
    """
    count = 0
    for b in range(poses.shape[0]):
        T = poses[b]
        p = parameters[board_camera[b]]
        nx = T[0, 2]
        ny = T[1, 2]
        nz = T[2, 2]
        seen = 0
        for j in range(board_markers[b], board_markers[b + 1]):
            ok = _project_marker(T, corners_m[j], nx, ny, nz, p, uv[j], centres[j])
            visible[j] = ok
            if ok:
                seen += 1
        board_visible[b] = seen
        count += seen
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


def solve_settings(
    upright: bool, sigma_px: float, sigma_floor_px: float, prior_rad: float, warm_max_rms_px: float = math.inf
) -> np.ndarray:
    """The settings vector of :func:`solve_boards`.

    Args:
        upright: choose between the two poses of the planar ambiguity with the
            upright prior (else: the lower reprojection cost).
        sigma_px: corner noise std (px), or NaN to estimate it per board from the
            chosen pose's residuals, ``sqrt(cost / (2 n - 6))`` (n corners; a board
            with a single marker has 2 degrees of freedom left).
        sigma_floor_px: smallest estimated std (px); unused with a given ``sigma_px``.
        prior_rad: std of the angle between a board's up direction as its mount
            declares it and as the camera's attitude predicts it (rad), > 0.
        warm_max_rms_px: largest RMS reprojection error (px) of an accepted warm
            start (see :func:`solve_boards`); unused without warm starts.
    """
    return np.array([1.0 if upright else 0.0, sigma_px, sigma_floor_px, prior_rad, warm_max_rms_px])


@numba.njit(cache=True)
def pixel_weights(xy: np.ndarray, p: np.ndarray, W: np.ndarray) -> None:
    """Per corner, the 2x2 Jacobian of the pixel with respect to the undistorted
    normalised coordinates ``xy`` (n, 2), ``diag(fx, fy) @ D``, row-major into ``W`` (n, 4).

    ``D`` is the Jacobian of the distortion (k1, k2, p1, p2, k3) at the point:
    a normalised residual ``e`` is the pixel residual ``W_i e`` to first order.
    """
    fx = p[_FX]
    fy = p[_FY]
    k1 = p[_K1]
    k2 = p[_K2]
    k3 = p[_K3]
    p1 = p[_P1]
    p2 = p[_P2]
    for i in range(xy.shape[0]):
        x = xy[i, 0]
        y = xy[i, 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dradial = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3)  # d radial / d r2
        W[i, 0] = fx * (radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x)
        W[i, 1] = fx * (2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y)
        W[i, 2] = fy * (2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y)
        W[i, 3] = fy * (radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x)


@numba.njit(cache=True)
def _skip_second(candidates: np.ndarray, costs: np.ndarray, prior: np.ndarray) -> bool:
    """True if candidate 1 need not be refined with the prior: it is candidate 0
    (both starts reached the same minimum), or its cost exceeds candidate 0's
    posterior cost at its present pose (its posterior minimum is at least its
    pixel cost, the minimum of its basin)."""
    same = True
    for i in range(3):
        for j in range(4):
            if abs(candidates[0, i, j] - candidates[1, i, j]) > 1e-9:
                same = False
    if same:
        return True
    lam = prior[0]
    s2 = 0.0
    for i in range(3):  # |up_c x R up_m|^2 at candidate 0
        j1 = (i + 1) % 3
        j2 = (i + 2) % 3
        u1 = candidates[0, j1, 0] * prior[1] + candidates[0, j1, 1] * prior[2] + candidates[0, j1, 2] * prior[3]
        u2 = candidates[0, j2, 0] * prior[1] + candidates[0, j2, 1] * prior[2] + candidates[0, j2, 2] * prior[3]
        g = prior[4 + j1] * u2 - prior[4 + j2] * u1
        s2 += g * g
    return costs[1] >= costs[0] + lam * lam * s2


@numba.njit(cache=True)
def _board_sigma(settings: np.ndarray, cost: float, n: int) -> float:
    """Corner noise std (px) of a board: the configured one, or estimated from ``cost`` (px^2) of ``n`` corners."""
    sigma = settings[_SIGMA]
    if np.isnan(sigma):
        sigma = max(np.sqrt(cost / (2 * n - 6)), settings[_SIGMA_FLOOR])
    return sigma


@numba.njit(cache=True)
def _set_prior(prior: np.ndarray, lam: float, up_m: np.ndarray, up_c: np.ndarray) -> None:
    """``prior = [lam, up_m, up_c]`` (see :func:`~moma_env.camera.planar_pnp.prior_vector`)."""
    prior[0] = lam
    for i in range(3):
        prior[1 + i] = up_m[i]
        prior[4 + i] = up_c[i]


@numba.njit(cache=True)
def _warm_solve(
    T: np.ndarray,
    o: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    obj: np.ndarray,
    px: np.ndarray,
    p: np.ndarray,
    up_m: np.ndarray,
    up_c: np.ndarray,
    settings: np.ndarray,
    prior: np.ndarray,
) -> bool:
    """The warm-started solve of one board (see :func:`solve_boards`): True if accepted.

    ``T`` (4x4) holds the start and, when accepted, the pose; ``prior`` comes
    out as the cost's prior (``prior[0] == 0``: none), for the covariance.
    """
    n = obj.shape[0]
    prior[0] = 0.0
    with_prior = settings[_UPRIGHT] != 0.0 and np.isfinite(up_m[0])
    sigma = settings[_SIGMA]
    if with_prior and np.isnan(sigma):
        # sigma from the residuals at the pixel cost's minimum, as the full solve takes it.
        cost = refine_pose(T, o, x, w, prior)
        if not np.isfinite(cost):
            return False
        sigma = _board_sigma(settings, cost, n)
    if with_prior and sigma > 0.0:
        _set_prior(prior, sigma / settings[_PRIOR], up_m, up_c)
    if not np.isfinite(refine_warm_start(T, o, x, w, prior)):
        return False
    return np.sqrt(reprojection_sq(T, obj, px, p) / n) <= settings[_WARM_MAX_RMS]


@numba.njit(cache=True)
def solve_boards(
    obj: np.ndarray,
    px: np.ndarray,
    starts: np.ndarray,
    parameters: np.ndarray,
    all_settings: np.ndarray,
    board_camera: np.ndarray,
    up_m: np.ndarray,
    up_c: np.ndarray,
    use_given: bool,
    given: np.ndarray,
    T: np.ndarray,
    rms: np.ndarray,
    cov: np.ndarray,
    status: np.ndarray,
) -> None:
    """PnP (:mod:`moma_env.camera.planar_pnp`), upright prior, covariance and RMS reprojection error of each board.

    Each board gets the two poses of the planar ambiguity, Levenberg-Marquardt
    minima of the pixel residuals (normalised residuals weighted by
    :func:`pixel_weights`, so the costs are in px^2): from the homography's pose
    and its mirror image, or, with ``use_given``, from the pose already in
    ``T[b]`` (an OpenCV solution) and its mirror image. Then:

    * ``settings[upright]`` off (rule ``min_cost``): the lower cost (a given
      pose: unchanged).
    * ``settings[upright]`` on, ``up_m[b]`` finite and ``sigma > 0``: both
      candidates (one if they coincide, or if the second's pixel cost alone
      exceeds the first's posterior cost) are refined again with the upright
      prior added to the cost,
      ``sigma^2 sin^2(angle) / prior^2`` where ``angle`` is between ``R @ up_m[b]``
      (world up as the pose and the board's mount predict it in C) and ``up_c[b]``
      (world up in C from the attitude of the camera that saw the board): the
      maximum a posteriori pose under a Gaussian prior of std ``prior`` (rad) on
      that angle, and of the two the one with the lower posterior cost is kept.
      The prior decides where the corners cannot (nearly face-on boards, where
      the two poses' costs differ by less than the noise); where it cannot tell
      them apart (equal angles, e.g. a vertical board seen level) the lower cost
      decides. With ``sigma == 0`` (noise-free corners) or no ``up_m`` the lower
      cost decides.
    * **Warm start** (``status[b] != 0`` on input, without ``use_given``): ``T[b]`` holds the
      board's pose from the camera's previous frame. Levenberg-Marquardt from it
      on the cost the full solve ends on (the pixel cost, plus the upright prior
      when it applies), then the mirror test of
      :func:`~moma_env.camera.planar_pnp.refine_warm_start`: the result is kept
      (``status[b] = SOLVED_WARM``) only if the mirror image of the pose is
      abandoned on the pixel cost by the full solve's own rule (so the full
      solve would have had a single candidate too) and its RMS reprojection
      error is at most ``settings[warm_max_rms]`` px; otherwise the board is
      solved in full (``status[b] = WARM_REJECTED``).
    * **Covariance** of the kept pose, ``sigma^2 inv(J^T J)`` (6x6, camera
      frame C, translation first, rotation perturbed on the left: see
      :func:`~moma_env.camera.planar_pnp.pose_information`), ``J`` the Jacobian
      of the pixel residuals (focal lengths and lens distortion included) and,
      when the prior was applied, of the prior's residual (the posterior
      covariance). ``sigma`` is ``settings[sigma]`` px, or, if that is NaN,
      estimated from the pose's cost (see :func:`solve_settings`). ``sigma = 0``
      gives an exactly zero covariance; a singular ``J^T J`` gives NaN.

    The boards may come from several frames and cameras (a batch): each board
    carries its own ``up_c`` row and the row ``board_camera[b]`` of ``parameters``
    and ``all_settings`` of the camera that saw it (the same arithmetic as a call
    with that camera's alone); ``settings`` above is that row.

    Args:
        obj: (n, 3) visible corners in their board frames M (m), board after board.
        px: (n, 2) their measured pixels.
        starts: (K + 1,) first row of each board in ``obj``/``px``, then ``n``.
        parameters: (C, P) camera parameters (:func:`camera_parameters`), one row per camera.
        all_settings: (C, S) the cameras' settings (:func:`solve_settings`), one row per camera.
        board_camera: (K,) int64 row of ``parameters`` and ``all_settings`` of each board's camera.
        up_m: (K, 3) world up in each board's frame M as its mount declares it
            (unit vectors); a NaN row: not known (lower cost).
        up_c: (K, 3) world up in the camera frame C of the camera that saw each
            board (unit vectors).
        use_given: start from the poses in ``T`` instead of the homographies.
        given: (K,) bool, read only with ``use_given``: True where ``T[b]`` holds
            a pose; the other boards failed (NaN error).
        T: (K, 4, 4) output poses ``T_c_m`` (and input where ``given`` or warm).
        rms: (K,) output RMS reprojection errors (px); NaN where the solve failed.
        cov: (K, 6, 6) output covariances.
        status: (K,) int8. Input (read without ``use_given``): non-zero where
            ``T[b]`` holds a warm start (``T_c_m`` of the previous frame). Output:
            ``SOLVED_FULL``, ``SOLVED_WARM`` or ``WARM_REJECTED``.
    """
    n = px.shape[0]
    xy = np.empty((n, 2))
    W = np.empty((n, 4))
    for b in range(starts.shape[0] - 1):
        p = parameters[board_camera[b]]
        undistort_points(px[starts[b] : starts[b + 1]], p, xy[starts[b] : starts[b + 1]])
        pixel_weights(xy[starts[b] : starts[b + 1]], p, W[starts[b] : starts[b + 1]])
    obj_xy = np.ascontiguousarray(obj[:, :2])
    candidates = np.empty((2, 4, 4))
    costs = np.empty(2)
    info = np.empty((6, 6))
    prior = np.zeros(7)
    start = np.empty((4, 4))
    for b in range(starts.shape[0] - 1):
        first = starts[b]
        end = starts[b + 1]
        p = parameters[board_camera[b]]
        settings = all_settings[board_camera[b]]
        upright = settings[_UPRIGHT] != 0.0
        o = obj_xy[first:end]
        x = xy[first:end]
        w = W[first:end]
        prior[0] = 0.0
        warm = not use_given and status[b] != 0
        status[b] = SOLVED_FULL
        if warm:
            start[:, :] = T[b]
            if _warm_solve(start, o, x, w, obj[first:end], px[first:end], p, up_m[b], up_c[b], settings, prior):
                status[b] = SOLVED_WARM
                T[b] = start
            else:
                status[b] = WARM_REJECTED
                prior[0] = 0.0
        if status[b] != SOLVED_WARM:
            if use_given:
                if not given[b]:
                    rms[b] = np.nan
                    continue
                k = 0
                if upright:
                    k = refine_two_starts(T[b, :3, :3], T[b, :3, 3], o, x, w, prior, True, candidates, costs)
                if k == 0:
                    candidates[0] = T[b]
                    k = 1
            else:
                k = solve_planar_pnp_candidates(o, x, w, prior, False, candidates, costs)
            if k == 0:
                rms[b] = np.nan
                continue
            choice = 0
            if upright and np.isfinite(up_m[b, 0]):
                sigma = _board_sigma(settings, costs[0], end - first)
                if sigma > 0.0:
                    _set_prior(prior, sigma / settings[_PRIOR], up_m[b], up_c[b])
                    if k == 2 and _skip_second(candidates, costs, prior):
                        k = 1
                    for j in range(k):
                        costs[j] = refine_pose(candidates[j], o, x, w, prior)
                    if k == 2 and costs[1] < costs[0]:
                        choice = 1
                    if not np.isfinite(costs[choice]):
                        rms[b] = np.nan
                        continue
            T[b] = candidates[choice]
        cost = pose_information(T[b], o, x, w, prior, info)
        if prior[0] > 0.0:
            sigma = prior[0] * settings[_PRIOR]
        else:
            sigma = _board_sigma(settings, cost, end - first)
        if sigma == 0.0:
            cov[b] = 0.0
        elif spd_inverse(info, cov[b]):
            cov[b] *= sigma * sigma
        rms[b] = np.sqrt(reprojection_sq(T[b], obj[first:end], px[first:end], p) / (end - first))


@numba.njit(cache=True)
def covariance_finite(cov: np.ndarray, finite: np.ndarray) -> None:
    """Whether each covariance has only finite entries: ``finite[k]`` for ``cov[k]``, ``cov``
    (K, 6, 6) float64 and ``finite`` (K,) bool output (a singular solve gives NaN)."""
    for k in range(cov.shape[0]):
        ok = True
        for i in range(6):
            for j in range(6):
                if not np.isfinite(cov[k, i, j]):
                    ok = False
        finite[k] = ok
