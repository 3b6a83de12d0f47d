"""The switch window: samples of a static robot's pose averaged before it is frozen."""

from __future__ import annotations

from typing import Any

import numpy as np

from moma_env.geometry import project_to_rotation

__all__ = ["SwitchWindow"]

_LAST_ROW = (0.0, 0.0, 0.0, 1.0)


class SwitchWindow:
    """Up to ``capacity`` 4x4 poses (world frame W, metres), averaged robustly.

    Each sample may carry a payload (the estimator keeps its error model there).

    The mean (:meth:`inliers`, :meth:`mean`) leaves out outliers, so that one
    sample of the wrong planar-PnP pose among good ones does not drag it:
    the centre is the coordinate-wise median of the translations and the medoid
    of the rotations (the sample whose rotation is closest, in chordal distance,
    to all the others); a sample is an inlier when its translation lies within
    ``max(k * median distance, floor_m)`` of that centre and its rotation within
    ``max(k * median angle, floor_rad)``. With at most two samples every sample
    is an inlier. The mean of the inliers is the arithmetic mean of their
    translations and the chordal mean of their rotations (the arithmetic mean
    of the matrices projected back onto SO(3)).

    Args:
        capacity: most samples.
        outlier_k: the ``k`` above (> 0).
        floor_m: translation floor (m), so that noise-free samples all agree.
        floor_rad: rotation floor (rad).
    """

    __slots__ = ("capacity", "outlier_k", "floor_m", "floor_rad", "_poses", "_payloads", "_inliers")

    def __init__(self, capacity: int, outlier_k: float = 3.0, floor_m: float = 0.002, floor_rad: float = 0.002):
        if capacity < 1:
            raise ValueError(f"window capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self.outlier_k = outlier_k
        self.floor_m = floor_m
        self.floor_rad = floor_rad
        self._poses: list[np.ndarray] = []
        self._payloads: list[Any] = []
        self._inliers: list[int] | None = None

    def __len__(self) -> int:
        return len(self._poses)

    @property
    def full(self) -> bool:
        """True when ``capacity`` samples have been added."""
        return len(self._poses) >= self.capacity

    def clear(self) -> None:
        """Forget every sample."""
        self._poses.clear()
        self._payloads.clear()
        self._inliers = None

    def append(self, T: np.ndarray, payload: Any = None) -> None:
        """Add a 4x4 pose (copied) and its payload; raises if the window is already full."""
        if len(self._poses) >= self.capacity:
            raise ValueError(f"switch window already holds {self.capacity} samples")
        self._poses.append(np.array(T, dtype=float))
        self._payloads.append(payload)
        self._inliers = None

    def payloads(self, indices: list[int] | None = None) -> list[Any]:
        """The payloads of the samples at ``indices`` (all when None)."""
        if indices is None:
            return list(self._payloads)
        return [self._payloads[i] for i in indices]

    def inliers(self) -> list[int]:
        """Indices of the samples the mean uses (see the class docstring); raises when empty."""
        n = len(self._poses)
        if n == 0:
            raise ValueError("the switch window is empty")
        if self._inliers is not None:
            return self._inliers
        if n <= 2:
            self._inliers = list(range(n))
            return self._inliers
        stack = np.array(self._poses)
        t = stack[:, :3, 3]
        d_t = np.sqrt(((t - np.median(t, axis=0)) ** 2).sum(axis=1))
        flat = stack[:, :3, :3].reshape(n, 9)
        traces = flat @ flat.T  # trace(R_i^T R_j)
        medoid = int(np.argmax(traces.sum(axis=1)))
        d_r = np.arccos(np.clip((traces[medoid] - 1.0) / 2.0, -1.0, 1.0))
        k = self.outlier_k
        limit_t = max(k * float(np.median(d_t)), self.floor_m)
        limit_r = max(k * float(np.median(d_r)), self.floor_rad)
        self._inliers = [i for i in range(n) if d_t[i] <= limit_t and d_r[i] <= limit_r]
        return self._inliers

    def mean(self) -> np.ndarray:
        """Average pose of the inliers so far (a new 4x4 array); raises when empty."""
        index = self.inliers()
        if len(index) == 1:
            return self._poses[index[0]].copy()
        R_sum = np.zeros((3, 3))
        t_sum = np.zeros(3)
        for i in index:
            T = self._poses[i]
            R_sum += T[:3, :3]
            t_sum += T[:3, 3]
        T = np.empty((4, 4))
        T[:3, :3] = project_to_rotation(R_sum)
        T[:3, 3] = t_sum / len(index)
        T[3] = _LAST_ROW
        return T
