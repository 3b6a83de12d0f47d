"""Camera requests: what a simulation asks its cameras to measure in one frame."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from moma_env.camera import BoardView, CameraBackend, OcclusionQuery

__all__ = ["CameraRequest", "measure_each"]


class CameraRequest(NamedTuple):
    """One camera's measurement of one frame: the arguments of ``CameraBackend.measure``.

    Attributes:
        camera: the backend.
        T_w_c: 4x4 pose of the camera frame C in the world W (m).
        boards: the boards in the scene.
        time: acquisition time (s).
        rng: the generator of the noise draws.
        occluded: line-of-sight query, or None.
    """

    camera: CameraBackend
    T_w_c: np.ndarray
    boards: Sequence[BoardView]
    time: float
    rng: np.random.Generator
    occluded: OcclusionQuery | None


def measure_each(requests: Sequence[CameraRequest]) -> list[Any]:
    """The detections of every request, request after request, in one list."""
    detections: list[Any] = []
    for r in requests:
        detections += r.camera.measure(r.T_w_c, r.boards, r.time, r.rng, r.occluded)
    return detections
