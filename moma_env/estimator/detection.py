"""The measurement the estimator consumes: one board seen by one camera.

Any camera pipeline produces these: the simulator's geometric and rendered
backends, or a real camera running ``cv2.aruco`` and ``solvePnP``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Detection", "frame_fusion_covariance"]


@dataclass(frozen=True, eq=False)
class Detection:
    """A board detected in one image.

    Attributes:
        camera_id: name of the camera that took the image.
        board_id: integer id of the board (not of a single marker).
        T_c_m: 4x4 pose of the board frame M in the camera frame C (OpenCV
            conventions; metres), i.e. solvePnP's rvec/tvec as a matrix.
        corners_px: (k, 2) pixel coordinates of the detected marker corners used
            for the pose, in ArUco corner order, marker by marker; may be empty
            for a source that only provides poses.
        marker_ids: ids of the markers whose corners are in ``corners_px``.
        time: acquisition time of the image (s).
        reprojection_error_px: RMS reprojection error of the pose (px), or NaN.
        covariance: 6x6 covariance of the error of ``T_c_m`` (m^2, rad^2, m rad),
            or None when the source gives none. The error is expressed in the
            camera frame C, translation first, as a ROS ``PoseWithCovariance``:
            ``T_c_m(true) = [exp([dtheta]x) R, t + dt]`` with ``(dt, dtheta)``
            zero-mean of this covariance (rotation perturbed on the left, i.e.
            about the axes of C; translation additive).
        persistent_covariance: 6x6 part of ``covariance`` (same frame and
            convention) that persists from frame to frame while the camera and
            the board stand still relative to each other, so that averaging
            the frames of a switch window does not reduce it; None (default):
            none, the error is independent from frame to frame. The mean of
            ``n`` such frames has covariance ``P + (covariance - P) / n``.
    """

    camera_id: str
    board_id: int
    T_c_m: np.ndarray
    corners_px: np.ndarray
    marker_ids: tuple[int, ...]
    time: float
    reprojection_error_px: float = float("nan")
    covariance: np.ndarray | None = None
    persistent_covariance: np.ndarray | None = None

    @property
    def n_markers(self) -> int:
        """Number of markers that contributed to the pose."""
        return len(self.marker_ids)


def frame_fusion_covariance(d: Detection, frames: int) -> np.ndarray | None:
    """The covariance an estimator that fuses every frame as independent gives detection ``d``.

    An EKF or a pose graph weighs every detection by its covariance and treats
    the frames as independent. When a part ``P`` of the covariance ``C``
    persists from frame to frame (``d.persistent_covariance``), the detection
    stands for ``C + (frames - 1) P``: fusing ``frames`` still frames of it as
    independent gives ``P + (C - P) / frames``, the covariance of their mean
    (fewer frames: a cautious result, more: an over-confident one).

    Returns ``d.covariance`` itself (None when it has none, or without a
    persistent part).
    """
    P = d.persistent_covariance
    if P is None or d.covariance is None:
        return d.covariance
    return d.covariance + (frames - 1) * P
