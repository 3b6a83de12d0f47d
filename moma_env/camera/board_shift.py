"""The board-shift error model: an error shared by every corner of a board, persistent in time.

The covariance of a PnP pose, ``sigma^2 inv(J^T J)``, assumes corner errors
independent from corner to corner and from frame to frame. That holds for the
geometric backend, which draws them so. ArUco's corners on a rendered image
break both: the blurred, quantised, interlaced edges of a board displace its
corners together (its image as a whole is shifted by a fraction of a pixel,
which a per-corner sigma divides by the number of corners), and while the
camera and the board stand still relative to each other the displacement
barely changes from frame to frame, so averaging a switch window does not
reduce it (``docs/consistency.md``).

The model adds to a detection's covariance (camera frame C, translation
first, the convention of :class:`~moma_env.estimator.Detection`) the lateral
translation that a shift of the board's image by ``sigma_px`` in u and in v
gives, to first order, at the board's depth ``z`` (m)::

    S = diag((z sigma / fx)^2, (z sigma / fy)^2, 0, 0, 0, 0)      (m^2)

and declares the fraction ``persistence`` of it persistent
(``Detection.persistent_covariance = persistence * S``): the estimators then
average it down only by the frames they fuse beyond that part
(:func:`moma_env.estimator.uncertainty.window_mean_noise`,
:func:`moma_env.estimator.detection.frame_fusion_covariance`).

``sigma_px`` and ``persistence`` are measured against the truth by
``python -m training.experiments.rendered_calibration`` (rendered detections of
the paper's square compared with the true board poses): :data:`RENDERED_SHIFT_PX`
and :data:`RENDERED_SHIFT_PERSISTENCE` are its result (see that module and
``docs/consistency.md`` for the command, the date and the numbers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from moma_env.camera.config import CameraConfig
from moma_env.config import ConfigError, check_non_negative, check_range

__all__ = ["BoardShift", "RENDERED_SHIFT_PX", "RENDERED_SHIFT_PERSISTENCE", "board_shift_for"]

#: The rendered backend's board shift (px, std in u and in v), measured by
#: ``python -m training.experiments.rendered_calibration`` on 2026-12-02.
RENDERED_SHIFT_PX = 0.40
#: The fraction of its variance that persists over a switch window (same command).
RENDERED_SHIFT_PERSISTENCE = 1.0


@dataclass(frozen=True)
class BoardShift:
    """A board-shift error model (see the module docstring).

    Attributes:
        sigma_px: std of the shift of a board's image, in u and in v (px, >= 0);
            0 adds nothing.
        persistence: fraction of its variance that persists while the camera
            and the board stand still (in [0, 1]).
    """

    sigma_px: float = 0.0
    persistence: float = 0.0

    def __post_init__(self) -> None:
        check_non_negative("camera.board_shift_px", self.sigma_px)
        check_range("camera.board_shift_persistence", self.persistence, 0.0, 1.0)

    @property
    def active(self) -> bool:
        """True when it adds anything to a covariance."""
        return self.sigma_px > 0.0

    def shift_covariance(self, z: float, fx: float, fy: float) -> np.ndarray:
        """``S`` of the module docstring (6x6, m^2) for a board at depth ``z`` (m) and focal lengths in px."""
        S = np.zeros((6, 6))
        S[0, 0] = (z * self.sigma_px / fx) ** 2
        S[1, 1] = (z * self.sigma_px / fy) ** 2
        return S

    def apply(self, T_c_m: np.ndarray, covariance: np.ndarray | None, fx: float, fy: float) -> tuple[np.ndarray | None, np.ndarray | None]:
        """``(covariance + S, persistence * S)`` for the pose ``T_c_m`` (4x4, its depth ``T_c_m[2, 3]``).

        A detection without a covariance (None) gets none; an inactive model
        returns ``(covariance, None)`` unchanged.
        """
        if covariance is None or not self.active:
            return covariance, None
        S = self.shift_covariance(float(T_c_m[2, 3]), fx, fy)
        return covariance + S, self.persistence * S


def board_shift_for(config: CameraConfig, backend: str) -> BoardShift:
    """The board-shift model of a camera: ``config``'s fields, or the backend's defaults where None.

    Defaults: none for ``"geometric"`` (its corner noise is independent by
    construction; setting a shift there is an error, as it draws none), and
    :data:`RENDERED_SHIFT_PX` / :data:`RENDERED_SHIFT_PERSISTENCE` for
    ``"rendered"``.

    Raises:
        ConfigError: a non-zero ``board_shift_px`` with the geometric backend.
    """
    sigma, persistence = config.board_shift_px, config.board_shift_persistence
    if backend == "geometric":
        if sigma is not None and sigma > 0.0:
            raise ConfigError(
                "camera.board_shift_px",
                f"the geometric backend draws independent corner noise only, so its covariance has no board shift; got {sigma!r}",
            )
        return BoardShift()
    return BoardShift(
        RENDERED_SHIFT_PX if sigma is None else sigma,
        RENDERED_SHIFT_PERSISTENCE if persistence is None else persistence,
    )
