"""The geometric camera backend: project board corners, add pixel noise, solve PnP.

For every board it is shown, :class:`GeometricCamera` transforms the marker corners
into the camera frame C, keeps the visible markers (see
:mod:`moma_env.camera.visibility`), projects their corners with lens distortion,
adds Gaussian pixel noise and recovers the board pose ``T_c_m`` from all visible
corners of the board, as a real ArUco board pipeline would. It never looks at the
true pose after adding noise.

Everything up to the pose solve runs as one batch over all boards (a few numpy
operations on arrays whose rows are coordinates); the solve itself is either one
``cv2.solvePnP`` call per board or one batched call of the planar solver of
:mod:`moma_env.camera.planar_pnp` (see :data:`~moma_env.camera.config.PNP_METHODS`).

Without noise the recovered pose equals the truth to ~1e-8 m and rad. Three
details make that hold over every visible pose:

* PnP runs on undistorted normalised coordinates (identity camera matrix, no
  distortion) after a precise undistortion of the noisy pixels; OpenCV's
  undistortion inside solvePnP stops after 5 iterations (~1e-5 m of error).
* OpenCV's PnP runs in an auxiliary board frame (see :func:`solve_pnp_opencv`),
  since OpenCV's IPPE returns a wrong or NaN rotation for rotations near 0 and
  180 degrees, and a board seen face-on is a 180 degree rotation in its frame M.
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
from moma_env.camera.visibility import apply_occlusion, marker_visibility_rows
from moma_env.estimator.detection import Detection
from moma_env.geometry import invert
from moma_env.markers import BoardLayout

__all__ = ["GeometricCamera", "solve_pnp_opencv"]

_FIRST_SOLVER = {"IPPE": cv2.SOLVEPNP_IPPE, "ITERATIVE": cv2.SOLVEPNP_IPPE, "SQPNP": cv2.SOLVEPNP_SQPNP}
_IDENTITY_K = np.eye(3)
_IDENTITY_K.setflags(write=False)
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_LAST_ROW.setflags(write=False)
#: In-plane angle (rad) of a face-on board in the auxiliary PnP frame (see solve_pnp_opencv).
_AUX_FRAME_ANGLE = math.pi / 6
#: Number of board-set geometries a camera keeps (a scene rarely has more than a few).
_GEOMETRY_CACHE_SIZE = 16


class _BoardSetGeometry:
    """Marker geometry of one sequence of board layouts, arranged for batched projection.

    Every board is padded to ``n_markers`` markers (the most of any layout);
    padded markers are never visible. Arrays are read-only.

    Attributes:
        layouts: the layouts, in board order (kept so that cached ids stay valid).
        n_markers: markers per board after padding, ``m``.
        corners_h: (B, 4, 4m) homogeneous corners in M, as columns, marker after marker.
        centres_h: (B, 4, m) homogeneous marker centres in M, as columns.
        object_points: (B * 4m, 1, 3) corners in M, in solvePnP's layout.
        real: (B * m,) True for markers that exist, or None when no board is padded.
    """

    __slots__ = ("layouts", "n_markers", "corners_h", "centres_h", "object_points", "real")

    def __init__(self, layouts: tuple[BoardLayout, ...]) -> None:
        counts = [lay.marker_corners.shape[0] for lay in layouts]
        m = max(counts)
        corners = np.empty((len(layouts), m, 4, 3))
        for b, lay in enumerate(layouts):
            corners[b, : counts[b]] = lay.marker_corners
            corners[b, counts[b] :] = lay.marker_corners[0]  # padding: a copy of the first marker
        self.layouts = layouts
        self.n_markers = m
        ones = np.ones(corners.shape[:-1] + (1,))
        homogeneous = np.concatenate([corners, ones], axis=-1)  # (B, m, 4, 4)
        self.corners_h = np.ascontiguousarray(homogeneous.reshape(len(layouts), 4 * m, 4).transpose(0, 2, 1))
        self.centres_h = np.ascontiguousarray(homogeneous.mean(axis=2).transpose(0, 2, 1))
        self.object_points = corners.reshape(-1, 1, 3).copy()
        self.real = None
        if min(counts) < m:
            self.real = np.array([[k < c for k in range(m)] for c in counts]).ravel()
            self.real.setflags(write=False)
        for a in (self.corners_h, self.centres_h, self.object_points):
            a.setflags(write=False)


def _finite(rvec: np.ndarray, tvec: np.ndarray) -> bool:
    """True if both (3, 1) vectors are finite."""
    return math.isfinite(sum(rvec[:, 0].tolist() + tvec[:, 0].tolist()))


def solve_pnp_opencv(
    object_points: np.ndarray, image_xy: np.ndarray, flags: int, refine_lm: bool = False
) -> tuple[np.ndarray, np.ndarray] | None:
    """Pose of a board from OpenCV's solvePnP on undistorted normalised points.

    Args:
        object_points: (n, 1, 3) corners in the board frame M (m), ArUco corner
            order, marker after marker (at least one marker).
        image_xy: (n, 1, 2) their undistorted normalised image coordinates.
        flags: ``cv2.SOLVEPNP_IPPE`` or ``cv2.SOLVEPNP_SQPNP``.
        refine_lm: refine the solution by Levenberg-Marquardt (SOLVEPNP_ITERATIVE).

    Returns:
        ``(R_c_m, t_c_m)`` ((3, 3), (3,)), or None if solvePnP fails.

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
    x0, y0, x1, y1 = image_xy[:2].ravel().tolist()
    psi = math.atan2(y1 - y0, x1 - x0) - _AUX_FRAME_ANGLE
    c, s = math.cos(psi), math.sin(psi)
    # G is symmetric (G.T == G), so object_points @ G gives the object points in B'.
    G = np.array(((c, s, 0.0), (s, -c, 0.0), (0.0, 0.0, -1.0)))
    obj_b = object_points @ G
    try:
        ok, rvec, tvec = cv2.solvePnP(obj_b, image_xy, _IDENTITY_K, None, flags=flags)
        if ok and flags == cv2.SOLVEPNP_IPPE and not _finite(rvec, tvec):
            # IPPE's closed form takes sqrt(1 - |.|^2) and returns NaN (reporting
            # success) when the board normal is exactly along the ray to the
            # centroid of the points and rounding pushes the argument below 0.
            ok, rvec, tvec = cv2.solvePnP(obj_b, image_xy, _IDENTITY_K, None, flags=cv2.SOLVEPNP_SQPNP)
        if ok and refine_lm:
            ok, rvec, tvec = cv2.solvePnP(obj_b, image_xy, _IDENTITY_K, None, rvec, tvec, True, cv2.SOLVEPNP_ITERATIVE)
    except cv2.error:
        return None
    if not (ok and _finite(rvec, tvec)):
        return None
    return cv2.Rodrigues(rvec)[0] @ G, tvec[:, 0]


class GeometricCamera:
    """Geometric camera backend (implements :class:`~moma_env.camera.backend.CameraBackend`).

    Args:
        camera_id: name copied into every detection.
        config: intrinsics, noise and visibility limits.

    The camera keeps a small cache of marker geometry per sequence of board
    layouts it is shown (keyed by the layout objects); it never caches poses,
    so every call depends only on its arguments.
    """

    def __init__(self, camera_id: str, config: CameraConfig) -> None:
        if not isinstance(camera_id, str) or not camera_id:
            raise ValueError(f"camera_id must be a non-empty string, got {camera_id!r}")
        self.camera_id = camera_id
        self.camera = PinholeCamera(config)
        self.config = self.camera.config
        self._first_solver = _FIRST_SOLVER[config.pnp_method]
        self._refine_lm = config.pnp_method == "ITERATIVE"
        self._geometries: dict[tuple[int, ...], _BoardSetGeometry] = {}

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
        geo = self._geometry(boards)
        m = geo.n_markers

        # Board poses in C, top three rows of T_c_m: (B, 3, 4).
        T_c_w = invert(T_w_c)[:3]
        poses = np.empty((n_boards, 3, 4))
        for b, board in enumerate(boards):
            np.matmul(T_c_w, board.T_w_m, out=poses[b])
        # All marker corners in C as rows x, y, z: (3, B, 4m), and the marker centres (B, 3, m).
        corners = np.empty((3, n_boards, 4 * m))
        np.matmul(poses, geo.corners_h, out=corners.transpose(1, 0, 2))
        centres = np.matmul(poses, geo.centres_h)
        range_sq = np.add.reduce(centres * centres, axis=1).ravel()
        facing = np.add.reduce(centres * poses[:, :, 2:3], axis=1).ravel()
        visible, uv = marker_visibility_rows(self.camera, corners.reshape(3, -1), range_sq, facing)
        if geo.real is not None:
            visible &= geo.real
        if occluded is not None:
            apply_occlusion(visible, T_w_c, centres.transpose(0, 2, 1).reshape(-1, 3), occluded)

        # Measured corners of the visible markers, board after board: (n, 2) pixels.
        visible_list = visible.tolist()
        if False in visible_list:
            if True not in visible_list:
                return []
            corner_mask = np.repeat(visible, 4)
            uv = uv.compress(corner_mask, axis=1)
            object_points = geo.object_points.compress(corner_mask, axis=0)
        else:
            object_points = geo.object_points
        if self.config.noise_px > 0.0:
            px = rng.standard_normal((uv.shape[1], 2))
            px *= self.config.noise_px
            px += uv.T
        else:
            px = np.ascontiguousarray(uv.T)
        xy = self.camera.undistort(px).reshape(-1, 1, 2)

        # One solve per board with a visible marker.
        detections = []
        start = 0
        for b in range(n_boards):
            mask = visible_list[b * m : (b + 1) * m]
            k = mask.count(True)
            if k == 0:
                continue
            stop = start + 4 * k
            solution = solve_pnp_opencv(object_points[start:stop], xy[start:stop], self._first_solver, self._refine_lm)
            if solution is not None:
                layout = geo.layouts[b]
                ids = layout.marker_ids if k == len(layout.marker_ids) else tuple(compress(layout.marker_ids, mask))
                T = np.empty((4, 4))
                T[:3, :3], T[:3, 3] = solution
                T[3] = _LAST_ROW
                rms = self._rms_reprojection_px(T, object_points[start:stop], px[start:stop])
                if math.isfinite(rms):
                    detections.append(Detection(self.camera_id, boards[b].board_id, T, px[start:stop], ids, time, rms))
            start = stop
        return detections

    def _rms_reprojection_px(self, T_c_m: np.ndarray, object_points: np.ndarray, px: np.ndarray) -> float:
        """RMS distance (px) between the measured pixels (n, 2) and the object points (n, 1, 3) reprojected with T_c_m."""
        xyz = T_c_m[:3, :3] @ object_points.reshape(-1, 3).T
        xyz += T_c_m[:3, 3:]
        if not (xyz[2] > 0.0).all():
            return math.inf
        err = self.camera.project_rows(xyz)[0]
        err -= px.T
        err *= err
        return math.sqrt(float(np.add.reduce(err, axis=None)) / px.shape[0])

    def _geometry(self, boards: Sequence[BoardView]) -> _BoardSetGeometry:
        """Cached marker geometry of the boards' layouts (built on first use)."""
        key = tuple([id(b.layout) for b in boards])
        geo = self._geometries.get(key)
        if geo is None or any(a is not b.layout for a, b in zip(geo.layouts, boards)):
            if len(self._geometries) >= _GEOMETRY_CACHE_SIZE:
                self._geometries.clear()
            geo = _BoardSetGeometry(tuple(b.layout for b in boards))
            self._geometries[key] = geo
        return geo
