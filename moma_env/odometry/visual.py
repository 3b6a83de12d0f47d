"""Monocular visual odometry on the floor: the paper's Viso2 baseline.

A camera rigidly mounted on a robot looks at the floor. Every frame:

1. the features of the previous frame are tracked into the new one with
   pyramidal Lucas-Kanade optical flow (``cv2.calcOpticalFlowPyrLK``), kept
   only if tracking back lands within ``max_fb_error_px`` of where they started;
2. both ends of each track are back-projected onto the floor plane (z = 0 of
   the body frame, whose origin is on the floor): the pixel is undistorted to a
   ray ``(x, y, 1)`` in the camera frame C, taken into the body frame B with the
   known mount ``T_b_c`` and cut with the floor. The known camera height makes
   the motion metric, as wheel-robot VO does with a ground-plane prior;
3. the planar motion ``T_prev_curr`` of the body is the rigid 2D transform that
   maps the current floor points onto the previous ones, fitted by RANSAC
   (two-point samples, ``ransac_threshold_m``) and refined by least squares on
   the inliers (:func:`moma_env.geometry.fit_rigid_2d`);
4. the pose accumulates ``T_w_b <- T_w_b @ T_prev_curr``: every frame's error
   adds up, so it drifts;
5. new features (``cv2.goodFeaturesToTrack``) are added when fewer than
   ``min_features`` survive. A feature must have a minimum-eigenvalue corner
   response of at least ``min_corner_response`` (absolute, so noise on a plain
   floor is no feature).

**Track loss.** When fewer than ``min_inliers`` tracks agree on a motion (a
plain floor, motion blur, too fast a motion), the frame is *lost*: the pose is
held (the motion of that frame is missed), the frame is counted in
``lost_frames``, and features are detected afresh so that tracking resumes as
soon as the floor has texture again. ``track_losses`` counts the transitions
from tracking to lost.

The module imports nothing from the simulator (numpy, cv2, the geometry, the
configuration checks and the camera's intrinsic model only): it runs on frames
of a real camera too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from moma_env.camera.config import CameraConfig
from moma_env.camera.pinhole import PinholeCamera
from moma_env.config import ConfigError, check_count, check_positive, check_range, check_rigid_transform
from moma_env.geometry import fit_rigid_2d, se2_to_se3, se3_to_se2

__all__ = ["VisualOdometryConfig", "VisualOdometry", "corner_response"]


@dataclass(frozen=True)
class VisualOdometryConfig:
    """Feature tracking and motion estimation settings.

    Attributes:
        max_features: most features tracked at once.
        min_features: fewer surviving tracks than this trigger a new detection.
        min_inliers: fewer RANSAC inliers than this make the frame lost.
        quality_level: ``goodFeaturesToTrack``'s relative quality level.
        min_corner_response: absolute floor on a feature's corner response:
            the smallest eigenvalue of the gradient structure tensor averaged
            over ``block_size`` x ``block_size`` px, in (gray levels / px)^2.
            Sensor noise of std 3 gray levels on a plain floor stays below 5;
            the features of a fine floor texture have a median above 30 (tested).
        min_distance_px: smallest distance between two features (px).
        block_size: window of the corner response (px).
        window_px: Lucas-Kanade window side (px).
        pyramid_levels: Lucas-Kanade pyramid levels above the image.
        max_fb_error_px: largest forward-backward tracking error (px).
        ransac_threshold_m: inlier distance of a floor point under the fitted motion (m).
        ransac_iterations: RANSAC two-point samples per frame.
    """

    max_features: int = 300
    min_features: int = 80
    min_inliers: int = 15
    quality_level: float = 0.01
    min_corner_response: float = 20.0
    min_distance_px: float = 7.0
    block_size: int = 7
    window_px: int = 21
    pyramid_levels: int = 3
    max_fb_error_px: float = 1.0
    ransac_threshold_m: float = 0.004
    ransac_iterations: int = 60

    def __post_init__(self) -> None:
        check_count("vo.max_features", self.max_features, minimum=2)
        check_count("vo.min_features", self.min_features, minimum=2)
        if self.min_features > self.max_features:
            raise ConfigError("vo.min_features", f"must not exceed max_features={self.max_features}")
        check_count("vo.min_inliers", self.min_inliers, minimum=2)
        check_range("vo.quality_level", self.quality_level, 1e-6, 1.0)
        check_positive("vo.min_corner_response", self.min_corner_response)
        check_positive("vo.min_distance_px", self.min_distance_px)
        check_count("vo.block_size", self.block_size, minimum=3)
        check_count("vo.window_px", self.window_px, minimum=5)
        check_count("vo.pyramid_levels", self.pyramid_levels, minimum=0)
        check_positive("vo.max_fb_error_px", self.max_fb_error_px)
        check_positive("vo.ransac_threshold_m", self.ransac_threshold_m)
        check_count("vo.ransac_iterations", self.ransac_iterations, minimum=1)


class VisualOdometry:
    """Frame-to-frame visual odometry of a robot from a floor-facing camera.

    Args:
        camera: intrinsics and distortion of the camera.
        T_b_c: 4x4 pose of the camera frame C in the body frame B (origin on
            the floor, z up); the camera must be above the floor.
        config: tracking settings (defaults if None).
        initial_pose: the body's starting planar pose ``(x, y, yaw)`` in W (m, rad).
        rng: generator of the RANSAC samples (a fixed seed if None).

    Attributes:
        pose: current planar pose estimate ``(x, y, yaw)`` of the body in W.
        lost: True if the latest frame was lost.
        frames, lost_frames, track_losses: frames processed, frames lost,
            transitions from tracking to lost.
        n_inliers: RANSAC inliers of the latest frame (0 if none).
    """

    def __init__(
        self,
        camera: CameraConfig,
        T_b_c: np.ndarray,
        config: VisualOdometryConfig | None = None,
        initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
        rng: np.random.Generator | None = None,
    ) -> None:
        if not isinstance(camera, CameraConfig):
            raise TypeError(f"camera must be a CameraConfig, got {type(camera).__name__}")
        self.config = VisualOdometryConfig() if config is None else config
        if not isinstance(self.config, VisualOdometryConfig):
            raise TypeError(f"config must be a VisualOdometryConfig, got {type(self.config).__name__}")
        self.camera = PinholeCamera(camera)
        self.T_b_c = check_rigid_transform("vo.T_b_c", T_b_c)
        if self.T_b_c[2, 3] <= 0.0:
            raise ConfigError("vo.T_b_c", f"the camera must be above the floor (z > 0), got z = {self.T_b_c[2, 3]}")
        self._rng = np.random.default_rng(0) if rng is None else rng
        self._lk = {
            "winSize": (self.config.window_px, self.config.window_px),
            "maxLevel": self.config.pyramid_levels,
            "criteria": (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01),
        }
        self.reset(initial_pose)

    def reset(self, initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        """Forget the frames; start again at ``initial_pose``."""
        x, y, yaw = (float(v) for v in initial_pose)
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise ValueError(f"initial_pose must be finite, got {initial_pose!r}")
        self._T_w_b = se2_to_se3(x, y, yaw)
        self._image: np.ndarray | None = None
        self._points = np.empty((0, 1, 2), dtype=np.float32)
        self.lost = False
        self.frames = 0
        self.lost_frames = 0
        self.track_losses = 0
        self.n_inliers = 0

    @property
    def pose(self) -> tuple[float, float, float]:
        """Estimated planar pose ``(x, y, yaw)`` of the body in W (m, rad)."""
        return se3_to_se2(self._T_w_b)

    @property
    def T_w_b(self) -> np.ndarray:
        """Estimated 4x4 pose of the body in W (a copy)."""
        return self._T_w_b.copy()

    def update(self, image: np.ndarray) -> tuple[float, float, float]:
        """Process one grayscale frame (uint8, the camera's size); returns the new :attr:`pose`."""
        image = np.asarray(image)
        shape = (self.camera.config.height, self.camera.config.width)
        if image.dtype != np.uint8 or image.shape != shape:
            raise ValueError(f"image must be uint8 of shape {shape}, got {image.dtype} {image.shape}")
        self.frames += 1
        if self._image is None:
            self._points = self._detect(image, np.empty((0, 1, 2), dtype=np.float32))
            self._image = image.copy()
            return self.pose
        previous, current = self._track(self._image, image, self._points)
        motion, inliers = self._motion(previous, current)
        self.n_inliers = int(np.count_nonzero(inliers)) if motion is not None else 0
        if motion is None:
            if not self.lost:
                self.track_losses += 1
            self.lost = True
            self.lost_frames += 1
            self._points = self._detect(image, np.empty((0, 1, 2), dtype=np.float32))
        else:
            self.lost = False
            self._T_w_b = self._T_w_b @ se2_to_se3(*motion)
            kept = current[inliers].astype(np.float32).reshape(-1, 1, 2)
            self._points = kept if len(kept) >= self.config.min_features else self._detect(image, kept)
        self._image = image.copy()
        return self.pose

    # ------------------------------------------------------------------ steps
    def _detect(self, image: np.ndarray, existing: np.ndarray) -> np.ndarray:
        """``existing`` plus new features away from them, up to ``max_features``: (n, 1, 2) float32."""
        cfg = self.config
        wanted = cfg.max_features - len(existing)
        if wanted <= 0:
            return existing
        mask = np.full(image.shape, 255, dtype=np.uint8)
        for u, v in existing.reshape(-1, 2):
            cv2.circle(mask, (int(round(u)), int(round(v))), int(math.ceil(cfg.min_distance_px)), 0, -1)
        corners = cv2.goodFeaturesToTrack(
            image, wanted, cfg.quality_level, cfg.min_distance_px, mask=mask, blockSize=cfg.block_size
        )
        if corners is None:
            return existing
        response = corner_response(image, cfg.block_size)
        uv = np.rint(corners.reshape(-1, 2)).astype(int)
        strong = response[uv[:, 1], uv[:, 0]] >= cfg.min_corner_response
        return np.concatenate([existing, corners[strong].astype(np.float32)])

    def _track(self, before: np.ndarray, after: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Features of ``before`` and where they are in ``after``, both (n, 2), forward-backward checked."""
        if len(points) == 0:
            return np.empty((0, 2)), np.empty((0, 2))
        points = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 1, 2)
        ahead, ok, _ = cv2.calcOpticalFlowPyrLK(before, after, points, None, **self._lk)
        back, ok_back, _ = cv2.calcOpticalFlowPyrLK(after, before, ahead, None, **self._lk)
        fb = np.linalg.norm((back - points).reshape(-1, 2), axis=1)
        good = (ok.ravel() == 1) & (ok_back.ravel() == 1) & (fb <= self.config.max_fb_error_px)
        return points.reshape(-1, 2)[good].astype(float), ahead.reshape(-1, 2)[good].astype(float)

    def _floor_points(self, px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Floor points (n, 2) in B of pixels (n, 2), and a mask of the rays that meet the floor ahead."""
        xy = self.camera.undistort(px)
        rays = np.column_stack([xy, np.ones(len(xy))]) @ self.T_b_c[:3, :3].T
        origin = self.T_b_c[:3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -origin[2] / rays[:, 2]
        ok = np.isfinite(s) & (s > 0.0)
        return origin[:2] + s[:, None] * rays[:, :2], ok

    def _motion(self, previous: np.ndarray, current: np.ndarray) -> tuple[tuple[float, float, float] | None, np.ndarray]:
        """RANSAC planar motion ``T_prev_curr`` ``(x, y, yaw)`` and its inlier mask, or None if too few agree."""
        cfg = self.config
        n = len(previous)
        if n < cfg.min_inliers:
            return None, np.zeros(n, dtype=bool)
        p, ok_p = self._floor_points(previous)
        q, ok_q = self._floor_points(current)
        valid = ok_p & ok_q
        if np.count_nonzero(valid) < cfg.min_inliers:
            return None, np.zeros(n, dtype=bool)
        index = np.flatnonzero(valid)
        samples = self._rng.integers(0, len(index), size=(cfg.ransac_iterations, 2))
        threshold_sq = cfg.ransac_threshold_m**2
        best = _two_point_consensus(p, q, valid, index[samples], threshold_sq)
        if np.count_nonzero(best) < cfg.min_inliers:
            return None, best
        motion = fit_rigid_2d(p[best], q[best])
        inliers = valid & (_residual_sq(p, q, motion) <= threshold_sq)
        if np.count_nonzero(inliers) < cfg.min_inliers:
            return None, inliers
        return fit_rigid_2d(p[inliers], q[inliers]), inliers


#: ``cv2.cornerMinEigenVal`` on uint8 images divides the 3x3 Sobel derivatives
#: (8x the gradient) by ``4 * block_size * 255`` and sums their products over the
#: block: this factor turns it into the block mean of the gradient's structure
#: tensor's smallest eigenvalue in (gray levels / px)^2.
_RESPONSE_SCALE = 255.0**2 / 4.0


def corner_response(image: np.ndarray, block_size: int) -> np.ndarray:
    """The VO's corner response of every pixel of a uint8 image (h, w), in (gray levels / px)^2.

    The smallest eigenvalue of the gray-level gradient's structure tensor, averaged
    over ``block_size`` x ``block_size`` px: a feature is kept when its response is
    at least ``VisualOdometryConfig.min_corner_response``. float32 array (h, w).
    """
    return cv2.cornerMinEigenVal(image, block_size) * _RESPONSE_SCALE


@numba.njit(cache=True)
def _two_point_consensus(p: np.ndarray, q: np.ndarray, valid: np.ndarray, pairs: np.ndarray, threshold_sq: float) -> np.ndarray:
    """RANSAC's best consensus set: the inlier mask (n,) of the largest set (the first of
    equals) over the motions fitted to the point pairs ``pairs`` (k, 2) of indices.

    ``p``, ``q``: floor points (n, 2) (m), ``q`` mapped onto ``p`` by the motion;
    ``valid``: which may be inliers. A pair of one point twice, or of two points
    closer than twice the threshold (too close to fix a rotation), is skipped.
    Each motion is :func:`moma_env.geometry.fit_rigid_2d` of the pair, computed
    with the same floating-point operations in the same order (same bits), and a
    point is an inlier if its squared residual (as :func:`_residual_sq`) is at
    most ``threshold_sq``.
    """
    n = p.shape[0]
    best = np.zeros(n, dtype=np.bool_)
    best_count = 0
    inliers = np.empty(n, dtype=np.bool_)
    for k in range(pairs.shape[0]):
        a, b = pairs[k, 0], pairs[k, 1]
        if a == b:
            continue
        gx, gy = q[a, 0] - q[b, 0], q[a, 1] - q[b, 1]
        if gx * gx + gy * gy < 4.0 * threshold_sq:
            continue
        pcx, pcy = (p[a, 0] + p[b, 0]) / 2.0, (p[a, 1] + p[b, 1]) / 2.0
        qcx, qcy = (q[a, 0] + q[b, 0]) / 2.0, (q[a, 1] + q[b, 1]) / 2.0
        dpax, dpay, dpbx, dpby = p[a, 0] - pcx, p[a, 1] - pcy, p[b, 0] - pcx, p[b, 1] - pcy
        dqax, dqay, dqbx, dqby = q[a, 0] - qcx, q[a, 1] - qcy, q[b, 0] - qcx, q[b, 1] - qcy
        s_cos = (dqax * dpax + dqay * dpay) + (dqbx * dpbx + dqby * dpby)
        s_sin = (dqax * dpay - dqay * dpax) + (dqbx * dpby - dqby * dpbx)
        yaw = math.atan2(s_sin, s_cos)
        c, s = math.cos(yaw), math.sin(yaw)
        x = pcx - (c * qcx - s * qcy)
        y = pcy - (s * qcx + c * qcy)
        count = 0
        for i in range(n):
            dx = p[i, 0] - (c * q[i, 0] - s * q[i, 1] + x)
            dy = p[i, 1] - (s * q[i, 0] + c * q[i, 1] + y)
            inliers[i] = valid[i] and dx * dx + dy * dy <= threshold_sq
            count += inliers[i]
        if count > best_count:
            best[:] = inliers
            best_count = count
    return best


def _residual_sq(p: np.ndarray, q: np.ndarray, motion: tuple[float, float, float]) -> np.ndarray:
    """Squared distances (n,) between ``p`` and ``q`` mapped by the planar ``motion``."""
    x, y, yaw = motion
    c, s = math.cos(yaw), math.sin(yaw)
    dx = p[:, 0] - (c * q[:, 0] - s * q[:, 1] + x)
    dy = p[:, 1] - (s * q[:, 0] + c * q[:, 1] + y)
    return dx * dx + dy * dy
