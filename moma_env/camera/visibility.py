"""Which markers of a board a camera can detect.

A marker is visible when, with the limits of the camera's :class:`CameraConfig`:

1. all four corners are in front of the camera: depth ``z_C > min_range_m``;
2. all four are inside the lens model's one-to-one region (see
   :func:`moma_env.camera.distortion.fold_radius_sq`);
3. all four project inside the image, ``margin_px`` from the sensor border;
4. its shortest imaged side is at least ``min_marker_px`` pixels;
5. the incidence angle, between the printed face's normal z_M and the direction
   from the marker centre to the camera, is at most ``max_incidence_deg`` (this
   also rejects markers seen from behind);
6. the camera centre is at most ``max_range_m`` from the marker centre;
7. an optional occlusion query ``occluded(p_w_from, p_w_to) -> bool``, given the
   world coordinates (m, shape (3,)) of the camera centre and of the marker
   centre, returns False. It is asked only for markers that pass 1-6.

:func:`visible_markers` and :func:`marker_visibility` apply the checks to one
board or any markers. The camera's hot path uses their parts directly:
:func:`screen_board` decides checks 1, 5 and 6 for a whole planar board in plain
floats when it can (conservatively, with a margin against rounding),
:func:`corner_visibility_rows` runs checks 1-4 on corners stored as rows, and
:func:`centre_visibility` runs checks 5 and 6 on marker centres.
"""

from __future__ import annotations

import math

import numpy as np

from moma_env.camera.backend import OcclusionQuery, as_pose
from moma_env.camera.pinhole import PinholeCamera
from moma_env.geometry import invert
from moma_env.markers import BoardLayout

__all__ = [
    "BOARD_CLEAR",
    "BOARD_HIDDEN",
    "BOARD_UNSURE",
    "apply_occlusion",
    "centre_visibility",
    "corner_visibility_rows",
    "marker_visibility",
    "screen_board",
    "visible_markers",
]

#: (4, 4) matrix taking the four corners of a marker (as columns) to its sides:
#: column k of ``corners @ _SIDES`` is corner k+1 minus corner k.
_SIDES = np.eye(4)[:, [1, 2, 3, 0]] - np.eye(4)
_SIDES.setflags(write=False)
#: Safety margin (m) of the conservative board screening against rounding.
_SCREEN_MARGIN_M = 1e-9


#: Outcomes of :func:`screen_board` for the checks 1, 5 and 6 of every marker of a board.
BOARD_HIDDEN = 0  #: every marker fails one of the checks
BOARD_UNSURE = 1  #: the markers must be checked one by one
BOARD_CLEAR = 2  #: every marker passes all three checks


def marker_visibility(
    camera: PinholeCamera, corners_c: np.ndarray, normals_c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Geometric visibility (checks 1-6) of markers given in the camera frame.

    Args:
        camera: the camera model (its config holds the limits).
        corners_c: (n, 4, 3) marker corners in C (m), ArUco order.
        normals_c: (n, 3) unit normals of the printed faces (z_M) in C, or one
            (3,) normal shared by all markers (markers of one board).

    Returns:
        ``(visible, px)``: (n,) boolean mask and (n, 4, 2) pixels of the corners
        (NaN for corners behind the camera).
    """
    corners_c = np.asarray(corners_c, dtype=float)
    centre = np.add.reduce(corners_c, axis=1)
    centre *= 0.25
    range_sq = np.einsum("ni,ni->n", centre, centre)
    facing = centre @ normals_c if normals_c.ndim == 1 else np.einsum("ni,ni->n", normals_c, centre)
    visible, _ = corner_visibility_rows(camera, corners_c.reshape(-1, 3).T)
    visible &= centre_visibility(camera, range_sq, facing)
    return visible, camera.project(corners_c)


def corner_visibility_rows(
    camera: PinholeCamera, corners_rows: np.ndarray, depth_checked: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Checks 1-4 of n markers, with the corners stored as rows (the camera's hot path).

    Args:
        camera: the camera model (its config holds the limits).
        corners_rows: (3, 4n) rows x, y, z (m, in C) of the marker corners,
            marker after marker, four corners each in ArUco order.
        depth_checked: the caller guarantees that every corner passes check 1
            (e.g. by :func:`screen_board`), which is then skipped.

    Returns:
        ``(ok, uv)``: (n,) boolean mask and (2, 4n) corner pixels (rows u, v).
        Pixels of corners closer than ``min_range_m / 2`` (or behind the camera)
        are meaningless; their markers fail check 1.
    """
    cfg = camera.config
    n = corners_rows.shape[1] // 4
    depth = corners_rows[2]
    if depth_checked:
        uv, r2 = camera.project_rows(corners_rows)
    else:
        # Clamping the depth keeps the division finite; the clamped corners fail check 1.
        uv, r2 = camera.distort_rows(corners_rows[:2] / np.maximum(depth, 0.5 * cfg.min_range_m))
    # One row per condition, each >= 0 where the corner passes: u and v inside the
    # margins (4 rows), squared side to the next corner >= min_marker_px^2, then
    # optionally depth > min_range_m and r2 < fold_r2. Differences of floats have
    # the sign of the comparison they replace, so this is exact.
    folds = camera.fold_r2 < math.inf
    margins = np.empty((5 + (not depth_checked) + folds, 4 * n))
    np.subtract(uv, camera.image_limits_rows[0], out=margins[0:2])
    np.subtract(camera.image_limits_rows[1], uv, out=margins[2:4])
    sides = np.matmul(uv.reshape(2 * n, 4), _SIDES)
    sides *= sides
    side_sq = margins[4].reshape(n, 4)
    np.add(sides[:n], sides[n:], out=side_sq)
    side_sq -= cfg.min_marker_px**2
    row = 5
    if not depth_checked:
        np.subtract(depth, np.nextafter(cfg.min_range_m, math.inf), out=margins[row])
        row += 1
    if folds:
        np.subtract(np.nextafter(camera.fold_r2, -math.inf), r2, out=margins[row])
    if np.minimum.reduce(margins, axis=None) >= 0.0:  # the usual case, one cheap reduction
        return np.ones(n, dtype=bool), uv
    return np.minimum.reduce(margins.reshape(-1, n, 4), axis=(0, 2)) >= 0.0, uv


def centre_visibility(camera: PinholeCamera, range_sq: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """Checks 5 and 6 of markers: boolean array of the shape of the inputs.

    Args:
        camera: the camera model (its config holds the limits).
        range_sq: squared distance from the camera centre to each marker centre (m^2).
        facing: dot product of each printed face's unit normal z_M with its marker
            centre, both in C (m); negative when the face is turned towards the camera.
    """
    cfg = camera.config
    ok = range_sq <= cfg.max_range_m**2
    # cos(incidence) = z_M . (-centre) / |centre|.
    ok &= facing <= -math.cos(math.radians(cfg.max_incidence_deg)) * np.sqrt(range_sq)
    return ok


def screen_board(
    camera: PinholeCamera, pose: list[list[float]], corner_radius: float, centre_radius: float
) -> int:
    """Conservative checks 1, 5 and 6 for all markers of a planar board at once, in floats.

    Args:
        camera: the camera model (its config holds the limits).
        pose: top three rows of ``T_c_m`` as nested lists (m).
        corner_radius: largest distance of a marker corner from the origin of M (m).
        centre_radius: largest distance of a marker centre from the origin of M (m).

    Returns:
        BOARD_CLEAR or BOARD_HIDDEN only when that holds for every marker (the board's corners
        lie in its plane z_M = 0 within ``corner_radius`` of the origin, so their
        depths lie within ``corner_radius * hypot(R20, R21)`` of ``t_z``, and
        every point of the plane has the same ``z_M . p_c = z_M . t``);
        BOARD_UNSURE otherwise, when the markers must be checked one by one.
    """
    cfg = camera.config
    (_, _, r02, tx), (_, _, r12, ty), (r20, r21, r22, tz) = pose
    distance = math.sqrt(tx * tx + ty * ty + tz * tz)
    facing = r02 * tx + r12 * ty + r22 * tz
    depth_spread = corner_radius * math.hypot(r20, r21)
    cos_max = math.cos(math.radians(cfg.max_incidence_deg))
    eps = _SCREEN_MARGIN_M
    if (
        tz - depth_spread > cfg.min_range_m + eps
        and distance + centre_radius <= cfg.max_range_m - eps
        and facing <= -cos_max * (distance + centre_radius) - eps
    ):
        return BOARD_CLEAR
    nearest = max(distance - centre_radius, 0.0)
    if (
        tz + depth_spread < cfg.min_range_m - eps
        or nearest > cfg.max_range_m + eps
        or facing > -cos_max * nearest + eps
    ):
        return BOARD_HIDDEN
    return BOARD_UNSURE


def apply_occlusion(
    visible: np.ndarray, T_w_c: np.ndarray, centres_c: np.ndarray, occluded: OcclusionQuery
) -> None:
    """Clear ``visible[i]`` (in place) for every visible marker whose line of sight is blocked.

    ``centres_c`` (n, 3) are marker centres in C; ``occluded`` is called in marker
    order with the camera centre and the marker centre in W.
    """
    idx = np.flatnonzero(visible)
    if idx.size == 0:
        return
    p_from = T_w_c[:3, 3].copy()
    p_to = centres_c[idx] @ T_w_c[:3, :3].T + T_w_c[:3, 3]
    for i, target in zip(idx, p_to):
        if occluded(p_from, target):
            visible[i] = False


def visible_markers(
    camera: PinholeCamera,
    T_w_c: np.ndarray,
    T_w_m: np.ndarray,
    layout: BoardLayout,
    occluded: OcclusionQuery | None = None,
) -> np.ndarray:
    """Boolean mask (n_markers,) of the markers of one board the camera can detect.

    Args:
        camera: camera model.
        T_w_c: 4x4 camera pose in the world.
        T_w_m: 4x4 board pose in the world.
        layout: the board's marker layout (corners in M).
        occluded: optional occlusion query (see module docstring).
    """
    T_w_c = as_pose(T_w_c, "T_w_c")
    T_c_m = invert(T_w_c) @ as_pose(T_w_m, "T_w_m")
    R, t = T_c_m[:3, :3], T_c_m[:3, 3]
    corners_c = layout.marker_corners @ R.T + t
    visible, _ = marker_visibility(camera, corners_c, R[:, 2])
    if occluded is not None:
        apply_occlusion(visible, T_w_c, corners_c.mean(axis=1), occluded)
    return visible
