"""The geometric camera backend: project board corners, add pixel noise, solve PnP.

For every board it is shown, :class:`GeometricCamera` transforms the marker corners
into the camera frame C, keeps the visible markers (see
:mod:`moma_env.camera.visibility`), projects their corners with lens distortion,
adds Gaussian pixel noise and recovers the board pose ``T_c_m`` with one
``cv2.solvePnP`` call per board on all visible corners, as a real ArUco board
pipeline would. It never looks at the true pose after adding noise.

Speed: on small arrays every numpy call costs about a microsecond or two however
little it computes, so the hot path is written to make few of them. Everything
but the solve runs once over all boards (corners stored as rows x, y, z, so each
step is one call on contiguous rows); a board as a whole is first screened in
plain floats for depth, range and incidence, so that the per-marker checks of
those limits run only when a board is near one of them; the reprojection errors
of all boards are computed together; marker geometry is cached per sequence of
board layouts. solvePnP gets float64 (n, 1, 3) and (n, 1, 2) arrays, the layout
it uses without converting (about 40 % cheaper than (n, 3) and (n, 2)).

Without noise the recovered pose equals the truth to ~1e-8 m and rad. Three
details make that hold over every visible pose:

* PnP runs on undistorted normalised coordinates (identity camera matrix, no
  distortion): the noise-free projections' own normalised coordinates, or a
  precise undistortion of the noisy pixels; OpenCV's undistortion inside
  solvePnP stops after 5 iterations (~1e-5 m of error).
* PnP runs in an auxiliary board frame (see ``GeometricCamera._solve``), since
  OpenCV's IPPE returns a wrong or NaN rotation for rotations near 0 and 180
  degrees, and a board seen face-on is a 180 degree rotation in its frame M.
* If IPPE still returns NaN (board normal exactly along the ray to the centroid
  of the corners), the board is solved with SQPNP instead.

The reprojection error of a detection is the root mean square, over its corners,
of the pixel distance between the measured corners and the corners reprojected
with the estimated pose (with distortion).

Every detection carries the first-order covariance of its pose, and the pose is
chosen between the two of the planar ambiguity by ``CameraConfig.pose_disambiguation``
(see :func:`moma_env.camera.kernels.solve_boards` and ``docs/pnp.md``); the
camera's attitude gives world up in C (``T_w_c``'s rotation, perturbed by
``attitude_noise_deg``), each ``BoardView.up_m`` the board's.
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
from moma_env.camera.kernels import camera_parameters, project_boards, solve_boards, solve_settings, undistort_points
from moma_env.camera.visibility import apply_occlusion
from moma_env.estimator.detection import Detection
from moma_env.geometry import rotvec_to_matrix
from moma_env.markers import BoardLayout

__all__ = ["GeometricCamera"]

_FIRST_SOLVER = {
    "IPPE": cv2.SOLVEPNP_IPPE,
    "ITERATIVE": cv2.SOLVEPNP_IPPE,
    "SQPNP": cv2.SOLVEPNP_SQPNP,
    "PLANAR_LM": None,  # moma_env.camera.planar_pnp, not OpenCV
}
_IDENTITY_K = np.eye(3)
_IDENTITY_K.setflags(write=False)
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_LAST_ROW.setflags(write=False)
#: In-plane angle (rad) of a face-on board in the auxiliary PnP frame (see GeometricCamera._solve).
_AUX_FRAME_ANGLE = math.pi / 6
#: Number of board-set geometries a camera keeps (a scene rarely has more than a few).
_GEOMETRY_CACHE_SIZE = 16


class _BoardSetGeometry:
    """Marker geometry of one sequence of board layouts, arranged for the kernels.

    Every board is padded to ``n_markers`` markers (the most of any layout);
    padded markers are never visible. Arrays are read-only.

    Attributes:
        layouts: the layouts, in board order (holding them keeps their ids, the
            cache key, from being reused).
        n_markers: markers per board after padding, ``m``.
        corners_m: (B, m, 4, 3) marker corners in M (m), ArUco order.
        real: (B, m) True for markers that exist.
    """

    __slots__ = ("layouts", "n_markers", "corners_m", "real")

    def __init__(self, layouts: tuple[BoardLayout, ...]) -> None:
        counts = [lay.marker_corners.shape[0] for lay in layouts]
        m = max(counts)
        corners = np.empty((len(layouts), m, 4, 3))
        for b, lay in enumerate(layouts):
            if np.any(lay.marker_corners[..., 2] != 0.0):
                raise ValueError("board layouts must be planar (z_M = 0)")
            corners[b, : counts[b]] = lay.marker_corners
            corners[b, counts[b] :] = lay.marker_corners[0]  # padding: a copy of the first marker
        self.layouts = layouts
        self.n_markers = m
        self.corners_m = corners
        self.real = np.array([[k < c for k in range(m)] for c in counts], dtype=bool).reshape(len(layouts), m)
        for a in (self.corners_m, self.real):
            a.setflags(write=False)


class GeometricCamera:
    """Geometric camera backend (implements :class:`~moma_env.camera.backend.CameraBackend`).

    Args:
        camera_id: name copied into every detection.
        config: intrinsics, noise and visibility limits.

    The camera keeps a small cache of marker geometry per sequence of board
    layout objects it is shown; it never caches poses or results, so every call
    depends only on its arguments. Copies (:mod:`copy`, :mod:`pickle`) start with
    an empty cache: its keys are ids of the original's layout objects, which mean
    nothing to a copy (and could name other objects in another process).
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
        self._parameters = camera_parameters(self.camera)
        cfg = self.config
        self._upright = cfg.pose_disambiguation == "upright"
        self._prior_rad = math.radians(math.hypot(cfg.upright_prior_deg, cfg.attitude_noise_deg))
        self._attitude_noise_rad = math.radians(cfg.attitude_noise_deg)
        self._sigma_px = math.nan if cfg.pnp_sigma_source == "residuals" else cfg.noise_px
        self._settings = solve_settings(self._upright, self._sigma_px, cfg.pnp_sigma_floor_px, self._prior_rad)

    def up_in_camera(self, T_w_c: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """World up in C (unit 3-vector) as the camera knows it from ``T_w_c`` (4x4, validated).

        The third row of ``R_w_c``, turned by a random rotation vector of std
        ``attitude_noise_deg`` per axis (three draws from ``rng``) if that is > 0.
        """
        up = T_w_c[2, :3].copy()
        if self._attitude_noise_rad > 0.0:
            up = rotvec_to_matrix(rng.standard_normal(3) * self._attitude_noise_rad) @ up
        return up

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
        if not boards:
            return []
        geo = self._geometry(boards)
        n_boards, m = len(boards), geo.n_markers

        # Board poses in C, top three rows of T_c_m = inv(T_w_c) @ T_w_m: (B, 3, 4).
        relative = np.array([b.T_w_m[:3] for b in boards])
        relative[:, :, 3] -= T_w_c[:3, 3]
        poses = np.matmul(T_w_c[:3, :3].T, relative)
        uv = np.empty((n_boards, m, 4, 2))
        visible = np.empty((n_boards, m), dtype=bool)
        centres = np.empty((n_boards, m, 3))
        if not project_boards(poses, geo.corners_m, geo.real, poses[:, :, 2], self._parameters, uv, visible, centres):
            return []
        if occluded is not None:
            apply_occlusion(visible.reshape(-1), T_w_c, centres.reshape(-1, 3), occluded)
        visible_rows = visible.tolist()
        counts = [sum(row) for row in visible_rows]
        if not any(counts):
            return []

        # Measured corners of the visible markers, board after board: (n, 2) pixels.
        px = uv[visible].reshape(-1, 2)
        obj = geo.corners_m[visible].reshape(-1, 3)
        if self.config.noise_px > 0.0:
            noise = rng.standard_normal(px.shape)
            noise *= self.config.noise_px
            px += noise
        up_c = self.up_in_camera(T_w_c, rng)
        seen = [b for b, k in enumerate(counts) if k]
        bounds = [0]
        for b in seen:
            bounds.append(bounds[-1] + 4 * counts[b])
        up_m = board_up_rows([boards[b] for b in seen])
        T, rms, cov = self.solve_boards(obj, px, np.array(bounds, dtype=np.int64), up_m, up_c)

        detections = []
        for i, b in enumerate(seen):
            rms_b = float(rms[i])
            if not math.isfinite(rms_b):
                continue
            layout = geo.layouts[b]
            first, end = bounds[i], bounds[i + 1]
            all_seen = counts[b] == len(layout.marker_ids)
            ids = layout.marker_ids if all_seen else tuple(compress(layout.marker_ids, visible_rows[b]))
            detections.append(
                Detection(self.camera_id, boards[b].board_id, T[i], px[first:end], ids, time, rms_b, finite_or_none(cov[i]))
            )
        return detections

    def solve_boards(
        self,
        obj: np.ndarray,
        px: np.ndarray,
        starts: np.ndarray,
        up_m: np.ndarray | None = None,
        up_c: np.ndarray | None = None,
        sigma_px: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Board poses and their covariances from measured corners, with the configured
        ``pnp_method`` and ``pose_disambiguation``.

        The PnP step of every backend (the rendered camera calls it on the corners
        its detector found).

        Args:
            obj: (n, 3) float64 corners in their board frames M (m), board after board,
                each board's corners in the plane ``z_M = 0``.
            px: (n, 2) float64 their measured pixels (with lens distortion).
            starts: (K + 1,) int64: board ``k`` owns rows ``starts[k]:starts[k + 1]``.
            up_m: (K, 3) world up in each board's frame M (:attr:`BoardView.up_m`;
                NaN rows: unknown), or None: unknown for all (the lower cost decides).
            up_c: (3,) world up in C (unit vector); needed with ``up_m``.
            sigma_px: corner noise std (px) of the covariances; NaN: estimated
                from each board's residuals; None: from ``pnp_sigma_source``
                (``auto`` is ``noise_px`` here).

        Returns:
            ``(T, rms, cov)``: (K, 4, 4) poses ``T_c_m``, (K,) RMS reprojection
            errors (px), NaN for a board that could not be solved, and (K, 6, 6)
            covariances (camera frame C, translation first; see
            :class:`~moma_env.estimator.detection.Detection`).
        """
        n_boards = len(starts) - 1
        T = np.zeros((n_boards, 4, 4))
        rms = np.empty(n_boards)
        cov = np.empty((n_boards, 6, 6))  # written for every solved board
        if up_m is None:
            up_m = np.full((n_boards, 3), np.nan)
            up_c = np.full(3, np.nan)
        elif up_c is None:
            raise ValueError("up_c (world up in C) is needed with up_m")
        settings = self._settings
        if sigma_px is not None:
            settings = solve_settings(self._upright, float(sigma_px), self.config.pnp_sigma_floor_px, self._prior_rad)
        given = np.zeros(n_boards, dtype=bool)
        use_given = self._first_solver is not None
        if use_given:
            given[:] = self._solve_with_opencv(obj, px, starts, T)
        solve_boards(obj, px, starts, self._parameters, up_m, up_c, settings, use_given, given, T, rms, cov)
        return T, rms, cov

    def _solve_with_opencv(self, obj: np.ndarray, px: np.ndarray, starts: np.ndarray, T: np.ndarray) -> list[bool]:
        """OpenCV's solvePnP (methods IPPE, ITERATIVE, SQPNP) of every board: poses into ``T``;
        per board, True if it was solved."""
        xy = np.empty_like(px)
        undistort_points(px, self._parameters, xy)
        bounds = starts.tolist()
        spans = [(i, i, bounds[i], bounds[i + 1], None) for i in range(len(bounds) - 1)]
        T[:, 2:, 3] = 1.0  # a board whose solve fails stays at R = 0, t = (0, 0, 1)
        return self._solve(obj.reshape(-1, 1, 3), xy.reshape(-1, 1, 2), spans, T)

    def _solve(
        self, object_points: np.ndarray, image_xy: np.ndarray, spans: list[tuple], T: np.ndarray
    ) -> list[bool]:
        """Board poses, written into the rows of ``T``.

        OpenCV's solvePnP (``PLANAR_LM`` runs in :func:`~moma_env.camera.kernels.solve_boards`).

        Args:
            object_points: (n, 1, 3) corners in the board frames M (m), ArUco corner
                order, marker after marker, board after board.
            image_xy: (n, 1, 2) their undistorted normalised image coordinates.
            spans: per board, ``(row of T, board index, first corner, end corner, mask)``.
            T: (K, 4, 4) output poses ``T_c_m``; the rows of failed boards are left as they are.

        Returns:
            Per span, True if its board was solved.

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

        The solvePnP calls of all boards run back to back (OpenCV's code stays in
        the CPU caches: measurably faster than interleaving them with numpy).
        """
        frames = []
        for _, _, first, end, _ in spans:
            x0, y0, x1, y1 = image_xy[first : first + 2].ravel().tolist()
            psi = math.atan2(y1 - y0, x1 - x0) - _AUX_FRAME_ANGLE
            c, s = math.cos(psi), math.sin(psi)
            # G is symmetric (G.T == G), so object_points @ G gives the object points in B'.
            G = np.array(((c, s, 0.0), (s, -c, 0.0), (0.0, 0.0, -1.0)))
            frames.append((G, object_points[first:end] @ G, image_xy[first:end]))
        first_solver = self._first_solver
        try:
            results = [cv2.solvePnP(obj_b, xy, _IDENTITY_K, None, flags=first_solver) for _, obj_b, xy in frames]
        except cv2.error:
            results = [self._solve_one(obj_b, xy, first_solver) for _, obj_b, xy in frames]
        solved = []
        for (i, *_), (G, obj_b, xy), (ok, rvec, tvec) in zip(spans, frames, results):
            try:
                finite = ok and _finite(rvec, tvec)
                if ok and not finite and first_solver == cv2.SOLVEPNP_IPPE:
                    # IPPE's closed form takes sqrt(1 - |.|^2) and returns NaN (reporting
                    # success) when the board normal is exactly along the ray to the
                    # centroid of the points and rounding pushes the argument below 0.
                    ok, rvec, tvec = cv2.solvePnP(obj_b, xy, _IDENTITY_K, None, flags=cv2.SOLVEPNP_SQPNP)
                    finite = ok and _finite(rvec, tvec)
                if finite and self._refine_lm:
                    ok, rvec, tvec = cv2.solvePnP(
                        obj_b, xy, _IDENTITY_K, None, rvec, tvec, True, cv2.SOLVEPNP_ITERATIVE
                    )
                    finite = ok and _finite(rvec, tvec)
                if finite:
                    np.matmul(cv2.Rodrigues(rvec)[0], G, out=T[i, :3, :3])
                    T[i, :3, 3] = tvec[:, 0]
            except cv2.error:
                finite = False
            solved.append(finite)
        return solved

    @staticmethod
    def _solve_one(object_points: np.ndarray, image_xy: np.ndarray, flags: int) -> tuple:
        """solvePnP of one board, with OpenCV's errors turned into a failure."""
        try:
            return cv2.solvePnP(object_points, image_xy, _IDENTITY_K, None, flags=flags)
        except cv2.error:
            return False, None, None

    def __getstate__(self) -> dict[str, object]:
        """The camera's attributes, for :mod:`copy` and :mod:`pickle`, with an empty geometry cache."""
        state = self.__dict__.copy()
        state["_geometries"] = {}
        return state

    def _geometry(self, boards: Sequence[BoardView]) -> _BoardSetGeometry:
        """Cached marker geometry of the boards' layouts (built on first use).

        Keyed by the ids of the layout objects; the cached geometry holds the
        layouts, so an id in the cache cannot be reused by another object.
        """
        key = tuple([id(b.layout) for b in boards])
        geo = self._geometries.get(key)
        if geo is None:
            if len(self._geometries) >= _GEOMETRY_CACHE_SIZE:
                self._geometries.clear()
            geo = _BoardSetGeometry(tuple(b.layout for b in boards))
            self._geometries[key] = geo
        return geo


def board_up_rows(boards: Sequence[BoardView]) -> np.ndarray:
    """(K, 3) the boards' ``up_m``, NaN rows for boards without one."""
    rows = np.full((len(boards), 3), np.nan)
    for k, board in enumerate(boards):
        if board.up_m is not None:
            rows[k] = board.up_m
    return rows


def finite_or_none(cov: np.ndarray) -> np.ndarray | None:
    """The covariance ``cov`` (not copied) if it is finite, else None (a singular solve)."""
    return cov if math.isfinite(float(cov.sum())) else None


def _finite(rvec: np.ndarray, tvec: np.ndarray) -> bool:
    """True if both (3, 1) vectors are finite."""
    return math.isfinite(sum(rvec[:, 0].tolist() + tvec[:, 0].tolist()))
