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
"""

from __future__ import annotations

import math

import numpy as np

from moma_env.camera.backend import OcclusionQuery, as_pose
from moma_env.camera.pinhole import PinholeCamera
from moma_env.geometry import invert
from moma_env.markers import BoardLayout

__all__ = ["marker_visibility", "marker_visibility_rows", "visible_markers", "apply_occlusion"]

_NEXT_CORNER = np.array([1, 2, 3, 0])
_NEXT_CORNER.setflags(write=False)


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
    visible, _ = marker_visibility_rows(camera, corners_c.reshape(-1, 3).T, range_sq, facing)
    return visible, camera.project(corners_c)


def marker_visibility_rows(
    camera: PinholeCamera, corners_rows: np.ndarray, range_sq: np.ndarray, facing: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Checks 1-6 of n markers, with the corners stored as rows (the camera's hot path).

    Args:
        camera: the camera model (its config holds the limits).
        corners_rows: (3, 4n) rows x, y, z (m, in C) of the marker corners,
            marker after marker, four corners each in ArUco order.
        range_sq: (n,) squared distance from the camera centre to each marker
            centre (m^2).
        facing: (n,) dot product of each printed face's unit normal z_M with its
            marker centre, both in C (m); negative when the face is turned
            towards the camera.

    Returns:
        ``(visible, uv)``: (n,) boolean mask and (2, 4n) corner pixels (rows u, v).
        Pixels of corners closer than ``min_range_m / 2`` (or behind the camera)
        are meaningless; their markers are never visible.
    """
    cfg = camera.config
    depth = corners_rows[2]
    ok = depth > cfg.min_range_m
    # Clamping the depth keeps the division finite; the clamped corners failed the depth check.
    uv, r2 = camera.distort_rows(corners_rows[:2] / np.maximum(depth, 0.5 * cfg.min_range_m))
    if camera.fold_r2 < math.inf:
        ok &= r2 < camera.fold_r2
    ok &= camera.in_image_rows(uv)
    # Squared imaged sides, corner k to corner k+1 of each marker: (n, 4).
    n = ok.shape[0] // 4
    uv_markers = uv.reshape(2, n, 4)
    sides = uv_markers[:, :, _NEXT_CORNER]
    sides -= uv_markers
    sides *= sides
    ok_markers = ok.reshape(n, 4)
    ok_markers &= sides[0] + sides[1] >= cfg.min_marker_px**2
    visible = np.logical_and.reduce(ok_markers, axis=1)
    visible &= range_sq <= cfg.max_range_m**2
    # cos(incidence) = z_M . (-centre) / |centre|.
    visible &= facing <= -math.cos(math.radians(cfg.max_incidence_deg)) * np.sqrt(range_sq)
    return visible, uv


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
