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

Batches: the frames of many cameras with the same PnP solver (the copies of a
vector env, each camera with its own intrinsics and noise in random scenarios) are
measured together by :func:`moma_env.camera.batch.measure_batch`: one projection
kernel call (:func:`~moma_env.camera.kernels.project_markers`, every board of every
frame with its own camera pose and parameters) and one solve kernel call
(:func:`~moma_env.camera.kernels.solve_boards`, every seen board, each with its
camera's world up, parameters and settings), bit for bit the frames measured one
by one. ``measure`` is
the one-frame case of the same code (:class:`FrameGroup`).

Warm start (``CameraConfig.pnp_warm_start``, off by default): the camera
remembers each detected board's ``T_c_m`` and the next frame's solve of that
board starts from it, falling back to the full solve when in doubt (see
:func:`~moma_env.camera.kernels.solve_boards`).

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
from moma_env.camera.board_shift import board_shift_for
from moma_env.camera.config import CameraConfig
from moma_env.camera.pinhole import PinholeCamera
from moma_env.camera.kernels import (
    board_offsets,
    camera_parameters,
    covariance_finite,
    project_markers,
    solve_boards,
    solve_settings,
    undistort_points,
)
from moma_env.camera.visibility import apply_occlusion
from moma_env.estimator.detection import Detection
from moma_env.geometry import rotvec_to_matrix
from moma_env.markers import BoardLayout

__all__ = ["FrameGroup", "GeometricCamera", "check_frame"]

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
#: ``given`` argument of solve_boards without an OpenCV method (read only with one).
_NOTHING_GIVEN = np.zeros(0, dtype=bool)
_NOTHING_GIVEN.setflags(write=False)
#: Placeholder world up of a frame that sees nothing (never read).
_NO_UP = np.full(3, np.nan)
_NO_UP.setflags(write=False)
#: In-plane angle (rad) of a face-on board in the auxiliary PnP frame (see GeometricCamera._solve).
_AUX_FRAME_ANGLE = math.pi / 6
#: Number of board-set geometries a camera keeps (a scene rarely has more than a few).
_GEOMETRY_CACHE_SIZE = 16


class _BoardSetGeometry:
    """Marker geometry of one sequence of board layouts, arranged for the kernels.

    The markers of all boards are stacked, board after board (no padding).

    Attributes:
        layouts: the layouts, in board order (holding them keeps their ids, the
            cache key, from being reused).
        counts: markers per board (list of ints).
        marker_counts: (B,) int64, the same as an array.
        board_markers: (B + 1,) int64: board ``b`` owns markers
            ``board_markers[b]:board_markers[b + 1]``.
        corners_m: (M, 4, 3) marker corners in their board frames M (m), ArUco order.

    The kernel inputs of a frame of one camera that sees every marker of every board
    (the usual frame of a single env), made once here instead of per frame:

    Attributes:
        boards: ``list(range(B))``, every board index (read only).
        board_zeros: (B,) int64 zeros: every board's row in a one-camera table.
        corner_rows: (4 M, 3) the corners of ``corners_m`` as rows.
        corner_starts: (B + 1,) int64 ``4 * board_markers``: board ``b``'s rows of ``corner_rows``.
        corner_bounds: the same as a list of ints.

    The arrays are never written but left writable: the kernels are compiled for writable
    arrays, what a batch of frames stacks from them (a read-only one is another type to
    numba, so another compilation of the kernel and of every kernel it calls).
    """

    __slots__ = (
        "layouts", "counts", "marker_counts", "board_markers", "corners_m", "boards", "board_zeros", "corner_rows",
        "corner_starts", "corner_bounds",
    )

    def __init__(self, layouts: tuple[BoardLayout, ...]) -> None:
        parts = []
        for lay in layouts:
            corners = lay.marker_corners
            if np.any(corners[..., 2] != 0.0):
                raise ValueError("board layouts must be planar (z_M = 0)")
            parts.append(corners)
        self.layouts = layouts
        self.counts = [part.shape[0] for part in parts]
        self.marker_counts = np.array(self.counts, dtype=np.int64)
        self.board_markers = np.zeros(len(layouts) + 1, dtype=np.int64)
        np.cumsum(self.marker_counts, out=self.board_markers[1:])
        self.corners_m = np.ascontiguousarray(np.concatenate(parts), dtype=np.float64)
        self.boards = list(range(len(layouts)))
        self.board_zeros = np.zeros(len(layouts), dtype=np.int64)
        self.corner_rows = self.corners_m.reshape(-1, 3).copy()
        self.corner_starts = 4 * self.board_markers
        self.corner_bounds = self.corner_starts.tolist()


class GeometricCamera:
    """Geometric camera backend (implements :class:`~moma_env.camera.backend.CameraBackend`).

    Args:
        camera_id: name copied into every detection.
        config: intrinsics, noise and visibility limits.

    The camera keeps a small cache of marker geometry per sequence of board
    layout objects it is shown. Without ``config.pnp_warm_start`` it never
    caches poses or results, so every call depends only on its arguments. With
    it, the camera remembers the pose ``T_c_m`` of each board (by board id) it
    detected in its last frame, and the next frame (a later ``time``) starts
    that board's PnP from it (see :func:`moma_env.camera.kernels.solve_boards`);
    :meth:`reset` forgets them (a new episode), as does a frame at a time not
    after the last. Copies (:mod:`copy`, :mod:`pickle`) keep these poses (a copy
    continues the same sequence bit for bit) but start with an empty geometry
    cache: its keys are ids of the original's layout objects, which mean
    nothing to a copy (and could name other objects in another process).

    Several frames of cameras with the same solver (e.g. the copies of a
    vector env) are measured together by :func:`moma_env.camera.batch.measure_batch`;
    :meth:`measure` is its one-frame case.
    """

    def __init__(self, camera_id: str, config: CameraConfig) -> None:
        if not isinstance(camera_id, str) or not camera_id:
            raise ValueError(f"camera_id must be a non-empty string, got {camera_id!r}")
        self.camera_id = camera_id
        self.camera = PinholeCamera(config)
        self.config = self.camera.config
        board_shift_for(self.config, "geometric")  # ConfigError for a board shift: this backend draws none
        self._first_solver = _FIRST_SOLVER[config.pnp_method]
        self._refine_lm = config.pnp_method == "ITERATIVE"
        self._geometries: dict[tuple[int, ...], _BoardSetGeometry] = {}
        self._parameters = camera_parameters(self.camera)
        cfg = self.config
        self._upright = cfg.pose_disambiguation == "upright"
        self._prior_rad = math.radians(math.hypot(cfg.upright_prior_deg, cfg.attitude_noise_deg))
        self._attitude_noise_rad = math.radians(cfg.attitude_noise_deg)
        self._sigma_px = math.nan if cfg.pnp_sigma_source == "residuals" else cfg.noise_px
        self._settings = solve_settings(
            self._upright, self._sigma_px, cfg.pnp_sigma_floor_px, self._prior_rad, cfg.warm_max_rms_px
        )
        self._settings.setflags(write=False)
        # The kernels' tables of one camera (a frame measured alone): one row each, made once,
        # writable like the tables a batch of frames stacks (one compilation of the kernels).
        self._parameter_rows, self._settings_rows = self._parameters[None].copy(), self._settings[None].copy()
        self._warm_start = cfg.pnp_warm_start and self._first_solver is None
        #: Frames measured together must agree on these (the solver; the kernels take each
        #: board's own camera parameters and settings).
        self.batch_key = (self._first_solver, self._refine_lm)
        self._warm_poses: dict[int, np.ndarray] = {}
        self._warm_time = -math.inf
        #: Boards solved from a warm start: ``[accepted, rejected (solved in full)]`` since construction.
        self.warm_counts = [0, 0]

    def reset(self) -> None:
        """Forget the remembered board poses (call at the start of an episode): the next
        frame solves every board from scratch."""
        self._warm_poses = {}
        self._warm_time = -math.inf

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
                call, in board order, skipped when ``noise_px == 0`` (then three
                draws of the attitude error if ``attitude_noise_deg > 0``);
                nothing is drawn when no marker is visible.
            occluded: optional line-of-sight query, called for each geometrically
                visible marker with the camera centre and marker centre in W.

        Returns:
            One :class:`Detection` per board with at least one visible marker.
        """
        T_w_c, time = check_frame(T_w_c, time, rng)
        if not boards:
            self._remember(time, {})
            return []
        frames = FrameGroup([self], [T_w_c], [boards], [time], [rng], [occluded])
        frames.draw(0)
        return frames.solve()[0]

    def _remember(self, time: float, poses: dict[int, np.ndarray]) -> None:
        """After a frame at ``time`` (s): the board poses to warm-start the next frame from."""
        if self._warm_start:
            self._warm_poses = poses
            self._warm_time = time

    def _warm_memory(self, time: float) -> dict[int, np.ndarray]:
        """The remembered poses ``T_c_m`` by board id, usable in a frame at ``time`` (s):
        those of the previous frame if ``time`` is later than it, else none."""
        if self._warm_start and time > self._warm_time:
            return self._warm_poses
        return {}

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
        if up_m is None:
            up_m = np.full((n_boards, 3), np.nan)
            up_c = np.full(3, np.nan)
        elif up_c is None:
            raise ValueError("up_c (world up in C) is needed with up_m")
        settings = self._settings_rows
        if sigma_px is not None:
            settings = solve_settings(self._upright, float(sigma_px), self.config.pnp_sigma_floor_px, self._prior_rad)[None]
        up_rows = np.empty((n_boards, 3))
        up_rows[:] = up_c
        T = np.zeros((n_boards, 4, 4))
        rms, cov, _ = self._solve_boards(
            obj, px, starts, up_m, up_rows, np.zeros(n_boards, dtype=np.int8), T,
            self._parameter_rows, settings, np.zeros(n_boards, dtype=np.int64),
        )
        return T, rms, cov

    def _solve_boards(
        self,
        obj: np.ndarray,
        px: np.ndarray,
        starts: np.ndarray,
        up_m: np.ndarray,
        up_c: np.ndarray,
        status: np.ndarray,
        T: np.ndarray,
        parameters: np.ndarray,
        settings: np.ndarray,
        board_camera: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`solve_boards` of boards from any frames of cameras with this camera's
        solver (``batch_key``): ``up_c`` (K, 3) world up in C per board, ``status`` (K,)
        int8, in: 1 where ``T[k]`` (K, 4, 4, in and out) holds a warm start, out: how
        each board was solved; ``parameters`` (C, P) and ``settings`` (C, S) the kernel
        inputs of the cameras, ``board_camera`` (K,) int64 the row of each board's. Returns
        ``(rms, cov, status)`` (see :func:`moma_env.camera.kernels.solve_boards`)."""
        n_boards = len(starts) - 1
        rms = np.empty(n_boards)
        cov = np.empty((n_boards, 6, 6))  # written for every solved board
        use_given = self._first_solver is not None
        given = (
            np.array(self._solve_with_opencv(obj, px, starts, T, parameters, board_camera), dtype=bool)
            if use_given
            else _NOTHING_GIVEN
        )
        solve_boards(obj, px, starts, parameters, settings, board_camera, up_m, up_c, use_given, given, T, rms, cov, status)
        return rms, cov, status

    def _solve_with_opencv(
        self, obj: np.ndarray, px: np.ndarray, starts: np.ndarray, T: np.ndarray, parameters: np.ndarray,
        board_camera: np.ndarray,
    ) -> list[bool]:
        """OpenCV's solvePnP (methods IPPE, ITERATIVE, SQPNP) of every board, its pixels
        undistorted with its camera's row of ``parameters`` (``board_camera``): poses into
        ``T``; per board, True if it was solved."""
        xy = np.empty_like(px)
        bounds = starts.tolist()
        if len(parameters) == 1:
            undistort_points(px, parameters[0], xy)
        else:
            for k, camera in enumerate(board_camera.tolist()):
                undistort_points(px[bounds[k] : bounds[k + 1]], parameters[camera], xy[bounds[k] : bounds[k + 1]])
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
        """The camera's attributes, for :mod:`copy` and :mod:`pickle`, with an empty geometry
        cache (the remembered warm-start poses are kept: they are keyed by board id)."""
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


def check_frame(T_w_c: object, time: object, rng: object) -> tuple[np.ndarray, float]:
    """The arguments of one frame, validated: ``T_w_c`` as a finite float 4x4 array and
    ``time`` as a finite float (s); ValueError / TypeError naming the bad argument."""
    T_w_c = as_pose(T_w_c, "T_w_c")
    time = float(time)
    if not math.isfinite(time):
        raise ValueError(f"time must be finite, got {time!r}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return T_w_c, time


class FrameGroup:
    """Frames of geometric cameras with the same solver (``batch_key``), measured together.

    Each frame's boards are projected and solved with its own camera's parameters
    and settings (rows of per-frame tables handed to the kernels), so the cameras
    may differ in intrinsics, lens, limits and noise.

    Three stages, so that a batch of many cameras keeps every frame's random
    draws in the order of sequential ``measure`` calls: the constructor projects
    the boards of all frames (one kernel call) and applies the occlusion queries;
    :meth:`draw` draws one frame's noise from its generator (the caller calls it
    for every frame, in order, interleaved with other backends' frames);
    :meth:`solve` solves every seen board of all frames (one kernel call per
    wave, see below) and makes the detections.

    A camera may appear in several frames. With warm starts, a frame must start
    from the poses of the same camera's previous frame, so the frames are
    solved in waves: wave ``w`` holds every camera's ``w``-th frame.

    Args:
        cameras, poses, boards, times, rngs, occluded: per frame, the camera, its
            validated pose ``T_w_c`` (4x4), the boards (possibly none), the validated
            time (s), the generator and the occlusion query (or None).
    """

    __slots__ = (
        "cameras", "poses", "boards", "times", "rngs", "geos", "first_board", "any_visible", "board_visible",
        "board_markers", "visible", "rows", "px", "obj", "noise", "up_c", "owner", "visible_counts", "parameters",
        "settings", "all_seen",
    )

    def __init__(
        self,
        cameras: Sequence[GeometricCamera],
        poses: Sequence[np.ndarray],
        boards: Sequence[Sequence[BoardView]],
        times: Sequence[float],
        rngs: Sequence[np.random.Generator],
        occluded: Sequence[OcclusionQuery | None],
    ) -> None:
        self.cameras, self.poses, self.boards, self.times, self.rngs = cameras, poses, boards, times, rngs
        n_frames = len(cameras)
        self.any_visible = False
        self.owner: np.ndarray | None = None
        if n_frames == 1:
            self.first_board = [0, len(boards[0])]
            if not boards[0]:
                self.geos = [None]
                return
            self.geos = geos = [cameras[0]._geometry(boards[0])]
        else:
            self.geos = geos = [cam._geometry(b) if b else None for cam, b in zip(cameras, boards)]
            sizes = [len(b) for b in boards]
            self.first_board = [0]
            for size in sizes:
                self.first_board.append(self.first_board[-1] + size)
            if not self.first_board[-1]:
                return
        if n_frames == 1:
            T_w_c, geo = poses[0], geos[0]
            # Board poses in C, top three rows of T_c_m = inv(T_w_c) @ T_w_m: (B, 3, 4).
            relative = board_offsets(np.array([b.T_w_m for b in boards[0]]), T_w_c[None], geo.board_zeros)
            board_poses = np.matmul(T_w_c[:3, :3].T, relative)
            corners, board_markers = geo.corners_m, geo.board_markers
        else:
            # The same arithmetic on stacked frames (numpy's matmul gives the same bits per board).
            self.owner = owner = np.repeat(np.arange(n_frames), sizes)
            stack = np.array(poses)
            relative = board_offsets(np.array([b.T_w_m for frame in boards for b in frame]), stack, owner)
            board_poses = np.matmul(stack[:, :3, :3].transpose(0, 2, 1)[owner], relative)
            present = [g for g in geos if g is not None]
            corners = np.concatenate([g.corners_m for g in present])
            board_markers = np.zeros(len(owner) + 1, dtype=np.int64)
            np.cumsum(np.concatenate([g.marker_counts for g in present]), out=board_markers[1:])
        n_markers, n_boards = corners.shape[0], board_poses.shape[0]
        uv = np.empty((n_markers, 4, 2))
        visible = np.empty(n_markers, dtype=bool)
        centres = np.empty((n_markers, 3))
        board_visible = np.empty(n_boards, dtype=np.int64)
        if n_frames == 1:
            self.parameters, self.settings = cameras[0]._parameter_rows, cameras[0]._settings_rows
            board_camera = geo.board_zeros
        else:
            # Per frame: its camera's kernel inputs (row f of each table).
            self.parameters = np.array([camera._parameters for camera in cameras])
            self.settings = np.array([camera._settings for camera in cameras])
            board_camera = owner
        if not project_markers(board_poses, board_markers, corners, self.parameters, board_camera, uv, visible, centres, board_visible):
            return
        self.any_visible = True
        first_board = self.first_board
        if occluded.count(None) < n_frames:
            counts, marker_bounds = board_visible.tolist(), board_markers.tolist()
            for f, query in enumerate(occluded):
                b0, b1 = first_board[f], first_board[f + 1]
                if query is None or not any(counts[b0:b1]):
                    continue  # no query, or no visible marker to hide
                m0, m1 = marker_bounds[b0], marker_bounds[b1]
                apply_occlusion(visible[m0:m1], poses[f], centres[m0:m1], query)
                board_visible[b0:b1] = np.add.reduceat(visible[m0:m1], board_markers[b0:b1] - m0, dtype=np.int64)
        self.visible_counts = board_visible
        self.board_visible = counts = board_visible.tolist()
        self.board_markers = board_markers
        self.visible = visible
        n_visible = sum(counts)
        # Every marker of every board seen (each board has at least one marker): the
        # measured corners are all corners, no selection (one frame: see _solve_wave).
        self.all_seen = n_visible == n_markers
        # Corner rows of each frame in the stacked measurements, frame after frame.
        if n_frames == 1:
            self.rows = [0, 4 * n_visible]
        else:
            rows = [0]
            for f in range(n_frames):
                rows.append(rows[-1] + 4 * sum(counts[first_board[f] : first_board[f + 1]]))
            self.rows = rows
        # Measured corners of the visible markers, board after board: (n, 2) pixels.
        if self.all_seen:
            self.px = uv.reshape(-1, 2)
            self.obj = geo.corner_rows if n_frames == 1 else corners.reshape(-1, 3)
        else:
            self.px = uv[visible].reshape(-1, 2)
            self.obj = corners[visible].reshape(-1, 3)
        self.noise: np.ndarray | None = None
        self.up_c: list[np.ndarray | None] = [None] * n_frames

    def draw(self, f: int) -> None:
        """Frame ``f``'s random draws from its generator: the corner noise (if
        ``noise_px > 0``), then the attitude error (if ``attitude_noise_deg > 0``);
        none if it sees no marker."""
        if not self.any_visible:
            return
        first, end = self.rows[f], self.rows[f + 1]
        if first == end:
            return
        camera, rng = self.cameras[f], self.rngs[f]
        if camera.config.noise_px > 0.0:
            if end - first == len(self.px):
                self.noise = rng.standard_normal(self.px.shape)
            else:
                if self.noise is None:
                    self.noise = np.empty_like(self.px)
                rng.standard_normal(out=self.noise[first:end])
        self.up_c[f] = camera.up_in_camera(self.poses[f], rng)

    def solve(self) -> list[list[Detection]]:
        """The detections of every frame (after :meth:`draw` of every frame)."""
        n_frames = len(self.cameras)
        if not self.any_visible:
            for camera, time in zip(self.cameras, self.times):
                camera._remember(time, {})
            return [[] for _ in range(n_frames)]
        self._add_noise()
        results: list[list[Detection]] = [[] for _ in range(n_frames)]
        if n_frames == 1:
            self._solve_wave([0], results)
            return results
        # Waves: the k-th frame of each camera is in wave k.
        seen_count: dict[int, int] = {}
        waves = []
        for camera in self.cameras:
            k = seen_count.get(id(camera), 0)
            seen_count[id(camera)] = k + 1
            waves.append(k)
        if len(seen_count) == n_frames:
            self._solve_wave(list(range(n_frames)), results)
        else:
            for wave in range(max(waves) + 1):
                self._solve_wave([f for f in range(n_frames) if waves[f] == wave], results)
        return results

    def _add_noise(self) -> None:
        """Scale each frame's standard normal draws by its camera's ``noise_px`` and add them."""
        noise = self.noise
        if noise is None:
            return
        cameras = self.cameras
        scale = cameras[0].config.noise_px
        if len(cameras) == 1 or all(camera.config.noise_px == scale for camera in cameras):
            noise *= scale
            self.px += noise
            return
        for f, camera in enumerate(cameras):
            first, end = self.rows[f], self.rows[f + 1]
            scale = camera.config.noise_px
            if scale > 0.0 and first < end:
                part = noise[first:end]
                part *= scale
                self.px[first:end] += part

    def _solve_wave(self, frames: list[int], results: list[list[Detection]]) -> None:
        """Solve the seen boards of ``frames`` (at most one frame per camera), into ``results``."""
        first_board, board_visible, rows = self.first_board, self.board_visible, self.rows
        cameras, times, all_boards = self.cameras, self.times, self.boards
        whole = len(frames) == len(cameras)
        # Seen boards, frame after frame: global board index, frame, board index in the frame
        # (parallel lists of ints: few container objects for the garbage collector to track).
        if self.owner is None and self.all_seen:  # one frame that sees every marker: the geometry's tables
            geo = self.geos[0]
            seen_g = seen_b = geo.boards
            seen_f = [0] * len(seen_g)
            board_camera, starts, bounds = geo.board_zeros, geo.corner_starts, geo.corner_bounds
        elif self.owner is None:  # one frame
            seen_g = [g for g in range(first_board[1]) if board_visible[g]]
            seen_f = [0] * len(seen_g)
            seen_b = seen_g
            board_camera = np.zeros(len(seen_g), dtype=np.int64)
            bounds = [0]
            for g in seen_g:
                bounds.append(bounds[-1] + 4 * board_visible[g])
            starts = np.array(bounds, dtype=np.int64)
        else:
            mask = self.visible_counts > 0
            if not whole:
                in_wave = np.zeros(len(cameras), dtype=bool)
                in_wave[frames] = True
                mask &= in_wave[self.owner]
            index_g = np.flatnonzero(mask)
            board_camera = index_f = self.owner[index_g]
            seen_g, seen_f = index_g.tolist(), index_f.tolist()
            seen_b = (index_g - np.array(first_board)[index_f]).tolist()
            starts = np.zeros(len(seen_g) + 1, dtype=np.int64)
            np.cumsum(4 * self.visible_counts[index_g], out=starts[1:])
            bounds = starts.tolist()
        if not seen_g:
            for f in frames:
                cameras[f]._remember(times[f], {})
            return
        n_seen = len(seen_g)
        if whole:
            obj, px = self.obj, self.px
        else:
            index = np.concatenate([np.arange(rows[f], rows[f + 1]) for f in frames])
            obj, px = self.obj[index], self.px[index]
        if len(frames) == 1 and len(seen_g) == len(all_boards[frames[0]]):
            up_m = board_up_rows(all_boards[frames[0]])  # every board of the frame seen
        else:
            up_m = board_up_rows([all_boards[f][b] for f, b in zip(seen_f, seen_b)])
        up_c = np.empty((n_seen, 3))
        if len(frames) == 1:
            up_c[:] = self.up_c[frames[0]]
        else:
            up_c[:] = np.array([self.up_c[f] if self.up_c[f] is not None else _NO_UP for f in range(len(cameras))])[index_f]
        T = np.zeros((n_seen, 4, 4))
        status = np.zeros(n_seen, dtype=np.int8)
        any_warm = cameras[frames[0]]._warm_start if len(frames) == 1 else any([cameras[f]._warm_start for f in frames])
        if any_warm:
            memories = {f: cameras[f]._warm_memory(times[f]) for f in frames}
            for k in range(n_seen):
                f = seen_f[k]
                start = memories[f].get(all_boards[f][seen_b[k]].board_id)
                if start is not None:
                    T[k] = start
                    status[k] = 1
        rms, cov, status = cameras[frames[0]]._solve_boards(
            obj, px, starts, up_m, up_c, status, T, self.parameters, self.settings, board_camera
        )
        rms_list = rms.tolist()
        finite = np.empty(n_seen, dtype=bool)
        covariance_finite(cov, finite)  # finite_or_none's test, every covariance in one call
        cov_finite = finite.tolist()
        status_list = status.tolist() if any_warm else None
        kept = T.copy() if any_warm else T  # the poses the cameras remember (views of one copy)
        visible, board_markers = self.visible, self.board_markers
        copy_out = len(cameras) > 1
        k = 0
        for f in frames:
            cam, time, boards, geo = cameras[f], times[f], all_boards[f], self.geos[f]
            detections = []
            remembered: dict[int, np.ndarray] = {}
            k0 = k
            while k < n_seen and seen_f[k] == f:
                k += 1
            if k == k0:
                cam._remember(time, remembered)
                results[f] = detections
                continue
            T_f, cov_f, px_f, row0 = T, cov, px, 0
            if copy_out:
                # The frame's own arrays: a detection kept must not keep the whole batch's alive.
                row0 = bounds[k0]
                T_f, cov_f, px_f = T[k0:k].copy(), cov[k0:k].copy(), px[row0 : bounds[k]].copy()
                k_f = -k0
            else:
                k_f = 0
            for j in range(k0, k):
                b, g = seen_b[j], seen_g[j]
                rms_b = rms_list[j]
                if status_list is not None and status_list[j]:
                    cam.warm_counts[status_list[j] - 1] += 1
                if math.isfinite(rms_b):
                    layout = geo.layouts[b]
                    if board_visible[g] == len(layout.marker_ids):
                        ids = layout.marker_ids
                    else:
                        m0 = int(board_markers[g])
                        ids = tuple(compress(layout.marker_ids, visible[m0 : m0 + geo.counts[b]].tolist()))
                    board_id = boards[b].board_id
                    detections.append(
                        Detection(
                            cam.camera_id, board_id, T_f[j + k_f], px_f[bounds[j] - row0 : bounds[j + 1] - row0], ids,
                            time, rms_b, cov_f[j + k_f] if cov_finite[j] else None,
                        )
                    )
                    if status_list is not None:
                        remembered[board_id] = kept[j]
            cam._remember(time, remembered)
            results[f] = detections


def board_up_rows(boards: Sequence[BoardView]) -> np.ndarray:
    """(K, 3) the boards' ``up_m``, NaN rows for boards without one."""
    if not boards:
        return np.full((0, 3), np.nan)
    # One array call on the rows (a float64 3-vector per view), not a row assignment per board.
    return np.array([_NO_UP if board.up_m is None else board.up_m for board in boards])


def finite_or_none(cov: np.ndarray) -> np.ndarray | None:
    """The covariance ``cov`` (6x6 float64, not copied) if every entry is finite, else None
    (a singular solve): the test of :func:`~moma_env.camera.kernels.covariance_finite`."""
    finite = np.empty(1, dtype=bool)
    covariance_finite(cov.reshape(1, 6, 6), finite)
    return cov if finite[0] else None


def _finite(rvec: np.ndarray, tvec: np.ndarray) -> bool:
    """True if both (3, 1) vectors are finite."""
    return math.isfinite(sum(rvec[:, 0].tolist() + tvec[:, 0].tolist()))
