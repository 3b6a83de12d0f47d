"""The rendered camera backend: draw the image, detect the markers with OpenCV, solve PnP.

:class:`RenderedCamera` implements :class:`~moma_env.camera.backend.CameraBackend`
with the real pipeline a camera on the robots would run:

1. **Scene.** The floor (:class:`~moma_env.camera.floor.FloorTexture`, or a
   plain gray floor) and every board facing the camera, drawn from
   ``cv2.aruco`` marker images on white paper with a quiet zone
   (:class:`~moma_env.camera.board_raster.BoardRaster`). Each plane is sampled
   through the exact camera model: for every pixel its undistorted ray (see
   :mod:`moma_env.camera.rays`) is mapped to the plane by a homography, one
   ``cv2.remap`` per plane, so perspective and lens distortion are exact up to
   the bilinear interpolation. Boards are warped only inside their image window.
   Boards are drawn far to near (painter's order). A board seen from behind, or
   crossing the plane of the camera centre, is not drawn; a marker whose line
   of sight is blocked (``occluded``) is painted over before nearer boards are drawn.
2. **Optics and sensor** (:class:`~moma_env.camera.sensor.SensorModel`): blur;
   optional PAL interlacing, the odd rows drawn one field period earlier, from
   poses interpolated with the previous frame; contrast and brightness, noise.
3. **Detection.** ``cv2.aruco.ArucoDetector`` with the configured corner
   refinement. Of the camera's visibility limits, ``min_marker_px`` becomes
   the detector's perimeter limit and ``margin_px`` its distance to the image
   border; range, incidence and occlusion are whatever the image allows. One
   Detection per board with a detected marker, ``T_c_m`` from PnP on all of
   its detected corners with the configured ``pnp_method``
   (``GeometricCamera.solve_boards``, so both backends solve identically),
   the same choice between the two poses of the planar ambiguity and a
   covariance whose corner noise is, by default, estimated from each board's
   residuals (``CameraConfig.pnp_sigma_source``), plus the board-shift error
   model (:mod:`moma_env.camera.board_shift`: an error shared by a board's
   corners, mostly persistent in time, measured against the truth), which
   also gives each detection's ``persistent_covariance``.

Speed: the floor view is kept while the camera does not move (or, with
``RenderConfig.floor_reuse_px``, while it moves the view by less than that);
the floor is resampled only inside the window of its textured rectangles and
the blur applied only where the scene is not uniform; rays are computed once
per camera; noise is one random byte per pixel through a lookup table.
``last_render_s`` and
``last_detect_s`` hold the wall-clock time of the latest frame's stages
(for ``moma-env bench``; nothing depends on them).

State: the camera keeps its latest image (:attr:`last_image`, for pixel
observations), the cached floor view and the previous frame's poses (for
interlacing); detections depend only on the arguments and the rng, except
through interlacing, which needs the previous frame.

Copies (:mod:`copy`, :mod:`pickle`) keep all of that state and continue like
the original; they leave out what is rebuilt on first use and cannot be
copied or would be wrong in a copy: the OpenCV detectors (not picklable) and
the board rasters and marker lookups (keyed by ids of the original's layout
objects).
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from collections.abc import Sequence

import cv2
import numpy as np

from moma_env.camera.backend import BoardView, OcclusionQuery, as_pose
from moma_env.camera.board_raster import BoardRaster, aruco_dictionary
from moma_env.camera.board_shift import board_shift_for
from moma_env.camera.config import CameraConfig
from moma_env.camera.floor import FloorConfig, FloorTexture
from moma_env.camera.geometric import GeometricCamera, board_up_rows, finite_or_none
from moma_env.camera.pinhole import PinholeCamera
from moma_env.camera.rays import PixelRays
from moma_env.camera.render_config import RenderConfig
from moma_env.camera.sensor import SensorModel
from moma_env.estimator.detection import Detection
from moma_env.geometry import interpolate_pose, invert
from moma_env.markers import BoardLayout

__all__ = ["RenderedCamera"]

#: A board is drawn only if every point of its paper is at least this deep in front of the camera (m).
_NEAR_M = 0.01
#: Interlacing interpolates poses only across a gap of at most this many field periods
#: (a longer gap, or time going back, is a new sequence: both fields show the present).
_MAX_FIELD_GAP = 10.0
#: Columns x, y and t of a pose T_c_m: the homography from the board plane z = 0 to C.
_PLANE_COLUMNS = np.array([0, 1, 3])


class RenderedCamera:
    """Rendered camera backend (implements :class:`~moma_env.camera.backend.CameraBackend`).

    Args:
        camera_id: name copied into every detection.
        config: intrinsics, distortion, visibility limits and PnP method.
            ``noise_px`` adds no noise (the noise is in the image, ``render``);
            it is the covariances' corner noise only with
            ``pnp_sigma_source="noise_px"``.
        render: image formation and detector settings (defaults if None).
        floor: the floor texture; None draws a plain floor of
            ``FloorConfig.gray``.

    Attributes:
        last_image: the latest output image (uint8, (height, width)), or None.
        last_render_s, last_detect_s: wall-clock seconds the latest frame spent
            drawing (scene and sensor) and in the ArUco detector.
    """

    def __init__(
        self,
        camera_id: str,
        config: CameraConfig,
        render: RenderConfig | None = None,
        floor: FloorTexture | None = None,
    ) -> None:
        # The solver validates camera_id and config; the board shift is this backend's, not the solver's.
        self._solver = GeometricCamera(camera_id, dataclasses.replace(config, board_shift_px=None))
        #: The board-shift error model added to every detection's covariance (``CameraConfig.board_shift_px``).
        self.board_shift = board_shift_for(config, "rendered")
        self.camera_id = camera_id
        self.camera: PinholeCamera = self._solver.camera
        self.config = config
        self._sigma_px = config.noise_px if config.pnp_sigma_source == "noise_px" else math.nan
        self.render_config = RenderConfig() if render is None else render
        if not isinstance(self.render_config, RenderConfig):
            raise TypeError(f"render must be a RenderConfig, got {type(self.render_config).__name__}")
        if floor is not None and not isinstance(floor, FloorTexture):
            raise TypeError(f"floor must be a FloorTexture or None, got {type(floor).__name__}")
        self.floor = floor
        self.rays = PixelRays(self.camera)
        #: The image formation after the optics (blur, then noise, quantisation and interlacing at read-out).
        self.sensor = SensorModel(self.render_config)
        self._plain_gray = int(round(FloorConfig.gray))
        self._rasters: dict[int, BoardRaster] = {}
        self._lookups: dict[tuple[int, ...], tuple[tuple[BoardLayout, ...], dict[str, dict[int, tuple[int, int]]]]] = {}
        self._detectors: dict[str, cv2.aruco.ArucoDetector] = {}
        self._floor_key: bytes | None = None
        self._floor_view: np.ndarray | None = None
        self._floor_window: tuple[int, int, int, int] | None = None
        self._floor_pose = np.eye(4)
        self._previous: tuple[float, np.ndarray, dict[int, np.ndarray]] | None = None
        self.last_image: np.ndarray | None = None
        self.last_render_s = math.nan
        self.last_detect_s = math.nan

    def __getstate__(self) -> dict[str, object]:
        """The camera's attributes, for :mod:`copy` and :mod:`pickle`, without the caches
        that are rebuilt on first use (see the module's notes on copies)."""
        state = self.__dict__.copy()
        state["_detectors"] = {}
        state["_rasters"] = {}
        state["_lookups"] = {}
        return state

    # ------------------------------------------------------------------ public
    def measure(
        self,
        T_w_c: np.ndarray,
        boards: Sequence[BoardView],
        time: float,
        rng: np.random.Generator,
        occluded: OcclusionQuery | None = None,
    ) -> list[Detection]:
        """Detections of ``boards`` in the image rendered from ``T_w_c`` (4x4, C in W) at ``time`` (s).

        Same contract as :meth:`GeometricCamera.measure`; the image is kept in
        :attr:`last_image`.
        """
        image = self.render(T_w_c, boards, rng, time=time, occluded=occluded)
        return self.detect(image, boards, time, up_c=self._solver.up_in_camera(as_pose(T_w_c, "T_w_c"), rng))

    def render(
        self,
        T_w_c: np.ndarray,
        boards: Sequence[BoardView],
        rng: np.random.Generator,
        time: float | None = None,
        occluded: OcclusionQuery | None = None,
    ) -> np.ndarray:
        """The camera image (uint8, (height, width)) of the scene seen from ``T_w_c``.

        Args:
            T_w_c: 4x4 camera pose in W.
            boards: the boards in the scene.
            rng: source of the sensor noise (one byte per pixel per frame).
            time: acquisition time (s); needed only for interlacing, which
                draws the odd rows at ``time - field_period_s``.
            occluded: optional line-of-sight query (see :data:`OcclusionQuery`).
        """
        start = _time.perf_counter()
        T_w_c = as_pose(T_w_c, "T_w_c")
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        poses = {b.board_id: b.T_w_m for b in boards}
        scene = self.sensor.blur(*self._scene(T_w_c, boards, [b.T_w_m for b in boards], occluded, cache_floor=True))
        if time is not None:
            time = float(time)
            if not math.isfinite(time):
                raise ValueError(f"time must be finite, got {time!r}")
            if self.render_config.interlaced:
                self._draw_odd_field(scene, T_w_c, boards, time, occluded)
            self._previous = (time, T_w_c.copy(), {k: v.copy() for k, v in poses.items()})
        image = self.sensor.read_out(scene, rng)
        self.last_image = image
        self.last_render_s = _time.perf_counter() - start
        return image

    def detect(
        self, image: np.ndarray, boards: Sequence[BoardView], time: float, up_c: np.ndarray | None = None
    ) -> list[Detection]:
        """Board detections in a grayscale ``image`` (uint8, this camera's size): ArUco, then PnP.

        Works on any image of this camera (rendered or real). Markers whose ids
        belong to no board are ignored. ``up_c`` is world up in C (unit 3-vector,
        e.g. from an IMU) for the upright prior; None: unknown (the lower
        reprojection cost decides between the two poses of a flip).
        """
        time = float(time)
        if not math.isfinite(time):
            raise ValueError(f"time must be finite, got {time!r}")
        image = np.asarray(image)
        if image.dtype != np.uint8 or image.shape != self.rays.shape:
            raise ValueError(f"image must be uint8 of shape {self.rays.shape}, got {image.dtype} {image.shape}")
        if up_c is not None:
            up_c = np.asarray(up_c, dtype=float)
            if up_c.shape != (3,) or not np.isfinite(up_c).all() or abs(float(up_c @ up_c) - 1.0) > 1e-6:
                raise ValueError(f"up_c must be a finite unit 3-vector, got {up_c!r}")
        if not boards:
            self.last_detect_s = 0.0
            return []
        layouts, lookup = self._marker_lookup(boards)
        found: dict[int, list[tuple[int, np.ndarray]]] = {}
        start = _time.perf_counter()
        for dictionary, markers in lookup.items():
            corners, ids, _ = self._detector(dictionary).detectMarkers(image)
            if ids is None:
                continue
            for marker_id, quad in zip(ids.ravel().tolist(), corners):
                owner = markers.get(marker_id)
                if owner is not None:
                    found.setdefault(owner[0], []).append((owner[1], quad.reshape(4, 2)))
        self.last_detect_s = _time.perf_counter() - start
        if not found:
            return []
        order, objects, pixels, starts = [], [], [], [0]
        for b in sorted(found):
            seen = dict(sorted(found[b], key=lambda item: item[0]))  # marker index -> corners (a duplicate: one kept)
            order.append((b, tuple(seen)))
            objects.append(layouts[b].marker_corners[list(seen)].reshape(-1, 3))
            pixels.append(np.concatenate(list(seen.values())))
            starts.append(starts[-1] + 4 * len(seen))
        px = np.concatenate(pixels).astype(np.float64)
        up_m = board_up_rows([boards[b] for b, _ in order]) if up_c is not None else None
        T, rms, cov = self._solver.solve_boards(
            np.concatenate(objects), px, np.array(starts, dtype=np.int64), up_m, up_c, self._sigma_px
        )
        detections = []
        shift = self.board_shift
        fx, fy = self.config.fx, self.config.fy
        for i, (b, indices) in enumerate(order):
            if not math.isfinite(rms[i]):
                continue
            ids = tuple(layouts[b].marker_ids[k] for k in indices)
            first, end = starts[i], starts[i + 1]
            covariance, persistent = shift.apply(T[i], finite_or_none(cov[i]), fx, fy)
            detections.append(
                Detection(
                    self.camera_id, boards[b].board_id, T[i], px[first:end], ids, time, float(rms[i]), covariance, persistent
                )
            )
        return detections

    # ------------------------------------------------------------------ scene
    def _scene(
        self,
        T_w_c: np.ndarray,
        boards: Sequence[BoardView],
        board_poses: Sequence[np.ndarray],
        occluded: OcclusionQuery | None,
        cache_floor: bool,
    ) -> tuple[np.ndarray, tuple[int, int, int, int] | None]:
        """Floor and boards (uint8, before the sensor), boards at ``board_poses`` (T_w_m),
        and the image window outside which the scene is one gray level (None: everywhere)."""
        scene, window = self._floor(T_w_c, cache_floor)
        windows = [window]
        T_c_w = invert(T_w_c)
        in_camera = [(T_c_w @ T_w_m, board, T_w_m) for board, T_w_m in zip(boards, board_poses)]
        # Painter's order: the farthest board first, each with its occluded markers painted
        # over, so that nearer boards cover both.
        in_camera.sort(key=lambda item: -float(np.dot(item[0][:3, 3], item[0][:3, 3])))
        for T_c_m, board, T_w_m in in_camera:
            roi = self._draw_board(scene, board.layout, T_c_m)
            windows.append(roi)
            if roi is not None and occluded is not None:
                for quad in self._occluded_markers(board.layout, T_w_c, T_w_m, T_c_m, occluded):
                    cv2.fillConvexPoly(scene, np.rint(quad).astype(np.int32), self.render_config.occluder_gray)
                    windows.append(self.rays.roi_of(quad))
        return scene, _union(windows)

    def _floor(self, T_w_c: np.ndarray, use_cache: bool) -> tuple[np.ndarray, tuple[int, int, int, int] | None]:
        """A fresh copy of the floor view from ``T_w_c`` (cached while the camera does not move),
        and its non-uniform window (see :meth:`FloorTexture.draw`)."""
        if self.floor is None:
            return np.full(self.rays.shape, self._plain_gray, dtype=np.uint8), None
        if not use_cache:
            image = np.empty(self.rays.shape, dtype=np.uint8)
            return image, self.floor.draw(self.rays, T_w_c, image)
        key = T_w_c.tobytes()
        if self._floor_view is None or (key != self._floor_key and not self._floor_view_holds(T_w_c)):
            self._floor_view = np.empty(self.rays.shape, dtype=np.uint8)
            self._floor_window = self.floor.draw(self.rays, T_w_c, self._floor_view)
            self._floor_key = key
            self._floor_pose = T_w_c.copy()
        return self._floor_view.copy(), self._floor_window

    def _floor_view_holds(self, T_w_c: np.ndarray) -> bool:
        """True if the cached floor view is within ``floor_reuse_px`` of the view from ``T_w_c``.

        The floor points seen by the border pixels and the principal point of
        the cached view are projected from the new pose; the view holds if none
        moved by more than the tolerance (a small camera motion moves the floor
        image smoothly, so these points bound the shift). Only for a view that
        is all floor (no horizon).
        """
        tolerance = self.render_config.floor_reuse_px
        if tolerance <= 0.0:
            return False
        T0 = self._floor_pose
        rays = self.rays
        d = np.column_stack([rays.border_xy, np.ones(len(rays.border_xy))]) @ T0[:3, :3].T
        if T0[2, 3] <= 0.0 or float(d[:, 2].max()) >= 0.0:
            return False
        floor_w = T0[:3, 3] + (-T0[2, 3] / d[:, 2])[:, None] * d
        p_c = (floor_w - T_w_c[:3, 3]) @ T_w_c[:3, :3]
        if float(p_c[:, 2].min()) <= 0.0:
            return False
        uv, r2 = self.camera.project_with_r2(p_c)
        if not float(r2.max()) < self.camera.fold_r2:
            return False
        shift_sq = np.einsum("ij,ij->i", uv - rays.border_px, uv - rays.border_px)
        return float(shift_sq.max()) <= tolerance * tolerance

    def _raster(self, layout: BoardLayout) -> BoardRaster:
        raster = self._rasters.get(id(layout))
        if raster is None or raster.layout is not layout:
            cfg = self.render_config
            raster = BoardRaster(layout, cfg.quiet_zone_m, cfg.bit_px, cfg.paper_gray, cfg.ink_gray)
            self._rasters[id(layout)] = raster
        return raster

    def _draw_board(self, scene: np.ndarray, layout: BoardLayout, T_c_m: np.ndarray) -> tuple[int, int, int, int] | None:
        """Warp the board into ``scene`` inside its image window, returned; None if it is not drawn."""
        R, t = T_c_m[:3, :3], T_c_m[:3, 3]
        if float(t @ R[:, 2]) >= 0.0:
            return None  # seen from behind (or edge-on)
        raster = self._raster(layout)
        outline = raster.outline_m @ R.T + t
        if float(outline[:, 2].min()) <= _NEAR_M:
            return None
        uv, r2 = self.camera.project_with_r2(outline)
        if float(r2.max()) >= self.camera.fold_r2:
            roi = (0, 0, self.rays.shape[1], self.rays.shape[0])  # beyond the lens model's fold: bound by the image
        else:
            roi = self.rays.roi_of(uv)
        if roi is None:
            return None
        x, y = uv[:, 0], uv[:, 1]
        following = raster.next_index
        area_px = 0.5 * abs(float(np.dot(x, y[following]) - np.dot(y, x[following])))  # shoelace
        image, A = raster.level_for(math.sqrt(area_px / raster.area_m2))
        H_n_m = T_c_m[:3, _PLANE_COLUMNS]
        x0, y0, x1, y1 = roi
        window = np.ascontiguousarray(scene[y0:y1, x0:x1])
        cv2.remap(
            image,
            self.rays.sample_map(A @ np.linalg.inv(H_n_m), roi),
            None,
            cv2.INTER_LINEAR,
            dst=window,
            borderMode=cv2.BORDER_TRANSPARENT,
        )
        scene[y0:y1, x0:x1] = window
        return roi

    def _occluded_markers(
        self, layout: BoardLayout, T_w_c: np.ndarray, T_w_m: np.ndarray, T_c_m: np.ndarray, occluded: OcclusionQuery
    ) -> list[np.ndarray]:
        """Image quads (4, 2) of the markers whose line of sight from the camera is blocked."""
        quads = []
        centres_m = layout.marker_corners.mean(axis=1)
        centres_w = centres_m @ T_w_m[:3, :3].T + T_w_m[:3, 3]
        p_from = T_w_c[:3, 3].copy()
        for corners, centre in zip(layout.marker_corners, centres_w):
            if occluded(p_from, centre):
                quads.append(self.camera.project(corners @ T_c_m[:3, :3].T + T_c_m[:3, 3]))
        return quads

    def _draw_odd_field(
        self, scene: np.ndarray, T_w_c: np.ndarray, boards: Sequence[BoardView], time: float, occluded: OcclusionQuery | None
    ) -> None:
        """Replace the odd rows of ``scene`` by the scene one field period earlier."""
        if self._previous is None:
            return
        t0, T0, boards0 = self._previous
        gap = time - t0
        period = self.render_config.field_period_s
        if not 0.0 < gap <= _MAX_FIELD_GAP * period:
            return
        f = max(0.0, (gap - period) / gap)  # fraction of the way from the previous frame to this one
        moved = not np.array_equal(T0, T_w_c) or any(
            not np.array_equal(boards0.get(b.board_id, b.T_w_m), b.T_w_m) for b in boards
        )
        if not moved:
            return
        camera_then = interpolate_pose(T0, T_w_c, f)
        boards_then = [interpolate_pose(boards0.get(b.board_id, b.T_w_m), b.T_w_m, f) for b in boards]
        earlier = self.sensor.blur(*self._scene(camera_then, boards, boards_then, occluded, cache_floor=False))
        scene[1::2] = earlier[1::2]

    # ------------------------------------------------------------------ detection set-up
    def _detector(self, dictionary: str) -> cv2.aruco.ArucoDetector:
        detector = self._detectors.get(dictionary)
        if detector is None:
            params = cv2.aruco.DetectorParameters()
            params.cornerRefinementMethod = getattr(cv2.aruco, "CORNER_REFINE_" + self.render_config.corner_refinement)
            w, h = self.config.width, self.config.height
            params.minMarkerPerimeterRate = 4.0 * self.config.min_marker_px / max(w, h)
            params.minDistanceToBorder = int(math.ceil(self.config.margin_px))
            detector = cv2.aruco.ArucoDetector(aruco_dictionary(dictionary), params)
            self._detectors[dictionary] = detector
        return detector

    def _marker_lookup(
        self, boards: Sequence[BoardView]
    ) -> tuple[tuple[BoardLayout, ...], dict[str, dict[int, tuple[int, int]]]]:
        """Per dictionary, marker id -> (board index, marker index); cached per sequence of layouts."""
        key = tuple(id(b.layout) for b in boards)
        entry = self._lookups.get(key)
        if entry is None:
            layouts = tuple(b.layout for b in boards)
            lookup: dict[str, dict[int, tuple[int, int]]] = {}
            for b, layout in enumerate(layouts):
                markers = lookup.setdefault(layout.dictionary, {})
                for k, marker_id in enumerate(layout.marker_ids):
                    if marker_id in markers:
                        raise ValueError(
                            f"marker id {marker_id} of {layout.dictionary} is on boards {markers[marker_id][0]} and {b}; "
                            "the rendered camera needs unique marker ids"
                        )
                    markers[marker_id] = (b, k)
            if len(self._lookups) >= 16:
                self._lookups.clear()
            entry = (layouts, lookup)
            self._lookups[key] = entry
        return entry


def _union(windows: list[tuple[int, int, int, int] | None]) -> tuple[int, int, int, int] | None:
    """Bounding box of the windows ``(x0, y0, x1, y1)`` that are not None (None if all are)."""
    real = [w for w in windows if w is not None]
    if not real:
        return None
    return min(w[0] for w in real), min(w[1] for w in real), max(w[2] for w in real), max(w[3] for w in real)
