"""The geometric camera backend: project board corners, add pixel noise, solve PnP.

For every board it is shown, :class:`GeometricCamera` transforms the marker corners
into the camera frame C, keeps the visible markers (see
:mod:`moma_env.camera.visibility`), projects their corners with lens distortion,
adds Gaussian pixel noise and recovers the board pose ``T_c_m`` with one
``cv2.solvePnP`` call per board on all visible corners, as a real ArUco board
pipeline would. It never looks at the true pose after adding noise.

Without noise the recovered pose equals the truth to ~1e-8 m and rad. Three
details make that hold over every visible pose:

* PnP runs on undistorted normalised coordinates (identity camera matrix, no
  distortion) after a precise undistortion of the noisy pixels; OpenCV's
  undistortion inside solvePnP stops after 5 iterations (~1e-5 m of error).
* PnP runs in an auxiliary board frame (see ``GeometricCamera._solve``), since
  OpenCV's IPPE returns a wrong or NaN rotation for rotations near 0 and 180
  degrees, and a board seen face-on is a 180 degree rotation in its frame M.
* If IPPE still returns NaN (board normal exactly along the ray to the centroid
  of the corners), the board is solved with SQPNP instead.

The reprojection error of a detection is the root mean square, over its corners,
of the pixel distance between the measured corners and the corners reprojected
with the estimated pose (with distortion).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import compress

import cv2
import numpy as np

from moma_env.camera.backend import BoardView, OcclusionQuery, as_pose
from moma_env.camera.config import CameraConfig
from moma_env.camera.pinhole import PinholeCamera
from moma_env.camera.visibility import apply_occlusion, marker_visibility
from moma_env.estimator.detection import Detection

__all__ = ["GeometricCamera"]

_FIRST_SOLVER = {"IPPE": cv2.SOLVEPNP_IPPE, "ITERATIVE": cv2.SOLVEPNP_IPPE, "SQPNP": cv2.SOLVEPNP_SQPNP}
_IDENTITY_K = np.eye(3)
_IDENTITY_K.setflags(write=False)
_EYE4 = np.eye(4)
_EYE4.setflags(write=False)
#: In-plane angle (rad) of a face-on board in the auxiliary PnP frame (see GeometricCamera._solve).
_AUX_FRAME_ANGLE = math.pi / 6


class GeometricCamera:
    """Geometric camera backend (implements :class:`~moma_env.camera.backend.CameraBackend`).

    Args:
        camera_id: name copied into every detection.
        config: intrinsics, noise and visibility limits.
    """

    def __init__(self, camera_id: str, config: CameraConfig) -> None:
        if not isinstance(camera_id, str) or not camera_id:
            raise ValueError(f"camera_id must be a non-empty string, got {camera_id!r}")
        self.camera_id = camera_id
        self.camera = PinholeCamera(config)
        self.config = self.camera.config
        self._first_solver = _FIRST_SOLVER[config.pnp_method]
        self._refine_lm = config.pnp_method == "ITERATIVE"

    def measure(
        self,
        T_w_c: np.ndarray,
        boards: Sequence[BoardView],
        time: float,
        rng: np.random.Generator,
        occluded: OcclusionQuery | None = None,
    ) -> list[Detection]:
        """Detections of ``boards`` seen from ``T_w_c`` at ``time`` (s).

        Args:
            T_w_c: 4x4 pose of the camera frame C in the world W.
            boards: the boards in the scene; detections come out in this order.
            time: acquisition time (s), copied into the detections.
            rng: source of the pixel noise; one draw of all visible corners per
                call, in board order, skipped when ``noise_px == 0``.
            occluded: optional line-of-sight query, called for each geometrically
                visible marker with the camera centre and marker centre in W.

        Returns:
            One :class:`Detection` per board with at least one visible marker.
        """
        T_w_c = as_pose(T_w_c, "T_w_c")
        time = float(time)
        if not math.isfinite(time):
            raise ValueError(f"time must be finite, got {time!r}")
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        n_boards = len(boards)
        if n_boards == 0:
            return []

        # All marker corners of all boards in C, in one batch: (n_markers, 4, 3).
        layouts = [b.layout for b in boards]
        R_w_c, t_w_c = T_w_c[:3, :3], T_w_c[:3, 3]
        if n_boards == 1:
            T_w_m = boards[0].T_w_m
            R = R_w_c.T @ T_w_m[:3, :3]
            corners_m = layouts[0].marker_corners
            corners_c = corners_m @ R.T + (T_w_m[:3, 3] - t_w_c) @ R_w_c
            normals_c = R[:, 2]
            counts = [corners_m.shape[0]]
        else:
            T_w_m = np.stack([b.T_w_m for b in boards])
            counts = [lay.marker_corners.shape[0] for lay in layouts]
            corners_m = np.concatenate([lay.marker_corners for lay in layouts])
            R = np.repeat(R_w_c.T @ T_w_m[:, :3, :3], counts, axis=0)
            t = np.repeat((T_w_m[:, :3, 3] - t_w_c) @ R_w_c, counts, axis=0)
            corners_c = corners_m @ R.transpose(0, 2, 1) + t[:, None, :]
            normals_c = R[:, :, 2]

        visible, px = marker_visibility(self.camera, corners_c, normals_c)
        if occluded is not None:
            apply_occlusion(visible, T_w_c, corners_c.mean(axis=1), occluded)
        visible_list = visible.tolist()
        if True not in visible_list:
            return []

        # Measured corners of the visible markers, board after board: (n_seen, 4, 2).
        px_seen = px.compress(visible, axis=0)
        if self.config.noise_px > 0.0:
            px_seen += self.config.noise_px * rng.standard_normal(px_seen.shape)
        xy_seen = self.camera.undistort(px_seen.reshape(-1, 2)).reshape(-1, 4, 2)
        obj_seen = corners_m.compress(visible, axis=0)

        detections = []
        first_marker = 0
        start = 0
        for b in range(n_boards):
            mask = visible_list[first_marker : first_marker + counts[b]]
            first_marker += counts[b]
            k = mask.count(True)
            if k == 0:
                continue
            stop = start + k
            corners_px = px_seen[start:stop].reshape(-1, 2)
            solution = self._solve(obj_seen[start:stop].reshape(-1, 3), xy_seen[start:stop].reshape(-1, 2), corners_px)
            start = stop
            if solution is None:
                continue
            detections.append(
                Detection(
                    camera_id=self.camera_id,
                    board_id=boards[b].board_id,
                    T_c_m=solution[0],
                    corners_px=corners_px,
                    marker_ids=tuple(compress(layouts[b].marker_ids, mask)),
                    time=time,
                    reprojection_error_px=solution[1],
                )
            )
        return detections

    def _solve(self, obj: np.ndarray, xy: np.ndarray, px: np.ndarray) -> tuple[np.ndarray, float] | None:
        """Board pose from object points (n, 3) in M, their undistorted normalised
        coordinates (n, 2) and their measured pixels (n, 2), in ArUco corner order.

        Returns ``(T_c_m, rms_reprojection_error_px)``, or None if solvePnP fails.

        OpenCV's IPPE turns its rotation matrix into a rotation vector with a
        formula that fails at 0 and 180 degrees (NaN or garbage, with success
        reported), and a board seen face-on in its own frame M (z_M towards the
        camera) is exactly a 180 degree rotation. So PnP is solved in an auxiliary
        board frame B' = M rotated by ``G = rot_x(pi) @ rot_z(-psi)``: z_B' = -z_M,
        and x_B' turned so that a face-on board appears rotated by
        ``_AUX_FRAME_ANGLE`` (30 degrees) about the optical axis, using the image
        direction of the first marker's top edge. Over all visible poses the
        rotation C <- B' then stays 0.3 rad or more away from both 0 and 180
        degrees (checked by sampling). Then ``R_c_m = R_c_b' @ G.T``.
        """
        # G is symmetric (G.T == G), so obj @ G gives the object points in B'.
        psi = math.atan2(xy[1, 1] - xy[0, 1], xy[1, 0] - xy[0, 0]) - _AUX_FRAME_ANGLE
        c, s = math.cos(psi), math.sin(psi)
        G = np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])
        obj_b = obj @ G
        try:
            ok, rvec, tvec = cv2.solvePnP(obj_b, xy, _IDENTITY_K, None, flags=self._first_solver)
            nan_pose = not (np.isfinite(rvec).all() and np.isfinite(tvec).all())
            if ok and nan_pose and self._first_solver == cv2.SOLVEPNP_IPPE:
                # IPPE's closed form takes sqrt(1 - |.|^2) and returns NaN (reporting
                # success) when the board normal is exactly along the ray to the
                # centroid of the points and rounding pushes the argument below 0.
                ok, rvec, tvec = cv2.solvePnP(obj_b, xy, _IDENTITY_K, None, flags=cv2.SOLVEPNP_SQPNP)
            if ok and self._refine_lm:
                ok, rvec, tvec = cv2.solvePnP(obj_b, xy, _IDENTITY_K, None, rvec, tvec, True, cv2.SOLVEPNP_ITERATIVE)
            if not ok:
                return None
            reproj = cv2.projectPoints(obj_b, rvec, tvec, self.camera.K, self.camera.dist)[0]
        except cv2.error:
            return None
        rms = cv2.norm(px, reproj.reshape(-1, 2), cv2.NORM_L2) / math.sqrt(px.shape[0])
        if not math.isfinite(rms):  # a non-finite pose reprojects to non-finite pixels
            return None
        T = _EYE4.copy()
        T[:3, :3] = cv2.Rodrigues(rvec)[0] @ G
        T[:3, 3] = tvec[:, 0]
        return T, rms
