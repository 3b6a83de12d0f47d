"""The measurement the estimator consumes: one board seen by one camera.

Any camera pipeline produces these: the simulator's geometric and rendered
backends, or a real camera running ``cv2.aruco`` and ``solvePnP``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from moma_env.records import slot_setter_init

__all__ = ["Detection", "frame_fusion_covariance"]


@slot_setter_init
@dataclass(frozen=True, eq=False, slots=True, init=False)
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


def frame_fusion_covariance(d: Detection, k: int) -> np.ndarray | None:
    """The covariance an estimator that fuses frames as independent gives detection ``d``, the
    ``k``-th frame (1, 2, ...) in which its board stands still.

    An EKF or a pose graph weighs every detection by its covariance and treats
    the frames as independent. When a part ``P`` of the covariance ``C``
    persists from frame to frame (``d.persistent_covariance``), the mean of
    ``k`` still frames has covariance ``P + (C - P) / k``; frame ``k`` then
    brings the information ``I_k - I_(k-1)`` with ``I_j = inv(P + (C - P) / j)``
    (``I_0 = 0``), and this returns its inverse, so that ``k`` frames fused as
    independent add up to exactly ``I_k``. Frame 1 gets ``C``; later frames
    get ever less information on the persistent part.

    Returns ``d.covariance`` itself when ``k`` is 1, without a persistent part
    or without a covariance (None).
    """
    P = d.persistent_covariance
    C = d.covariance
    if P is None or C is None or k <= 1:
        return C
    W = C - P
    gain = np.linalg.inv(P + W / k) - np.linalg.inv(P + W / (k - 1))
    cov = np.linalg.inv(0.5 * (gain + gain.T))
    return 0.5 * (cov + cov.T)
