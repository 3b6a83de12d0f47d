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
board or any markers. Checks 1-6 are implemented once, in the compiled kernel
:func:`moma_env.camera.kernels.project_boards` that the geometric camera runs;
check 7 is :func:`apply_occlusion`.
"""

from __future__ import annotations

import numpy as np

from moma_env.camera.backend import OcclusionQuery, as_pose
from moma_env.camera.kernels import camera_parameters, project_boards
from moma_env.camera.pinhole import PinholeCamera
from moma_env.geometry import invert
from moma_env.markers import BoardLayout

__all__ = ["apply_occlusion", "marker_visibility", "visible_markers"]


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

    The checks run in the compiled kernel the geometric camera uses
    (:func:`moma_env.camera.kernels.project_boards`), one marker per "board".
    """
    corners_c = np.ascontiguousarray(corners_c, dtype=float)
    if corners_c.ndim != 3 or corners_c.shape[1:] != (4, 3):
        raise ValueError(f"corners_c must have shape (n, 4, 3), got {corners_c.shape}")
    n = corners_c.shape[0]
    normals = np.broadcast_to(np.asarray(normals_c, dtype=float), (n, 3))
    identity = np.zeros((n, 3, 4))
    identity[:, 0, 0] = identity[:, 1, 1] = identity[:, 2, 2] = 1.0
    uv = np.empty((n, 1, 4, 2))
    visible = np.empty((n, 1), dtype=bool)
    centres = np.empty((n, 1, 3))
    real = np.ones((n, 1), dtype=bool)
    project_boards(
        identity, corners_c.reshape(n, 1, 4, 3), real, np.ascontiguousarray(normals), camera_parameters(camera),
        uv, visible, centres,
    )
    return visible.reshape(n), camera.project(corners_c)


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
