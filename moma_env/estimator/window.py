"""The switch window: samples of a static robot's pose averaged before it is frozen."""

from __future__ import annotations

import numpy as np

from moma_env.geometry import project_to_rotation

__all__ = ["SwitchWindow"]

_LAST_ROW = (0.0, 0.0, 0.0, 1.0)


class SwitchWindow:
    """Running average of up to ``capacity`` 4x4 poses (world frame W, metres).

    The mean is :func:`moma_env.geometry.mean_pose`'s: arithmetic mean of the
    translations and chordal mean of the rotations (the arithmetic mean of the
    rotation matrices projected back onto SO(3)). Sums are kept, so appending
    and averaging cost the same whatever the number of samples.
    """

    __slots__ = ("capacity", "_count", "_rotation_sum", "_translation_sum", "_first")

    def __init__(self, capacity: int):
        if capacity < 1:
            raise ValueError(f"window capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self._count = 0
        self._rotation_sum = np.zeros((3, 3))
        self._translation_sum = np.zeros(3)
        self._first: np.ndarray | None = None

    def __len__(self) -> int:
        return self._count

    @property
    def full(self) -> bool:
        """True when ``capacity`` samples have been added."""
        return self._count >= self.capacity

    def clear(self) -> None:
        """Forget every sample."""
        self._count = 0
        self._rotation_sum[:] = 0.0
        self._translation_sum[:] = 0.0
        self._first = None

    def append(self, T: np.ndarray) -> None:
        """Add a 4x4 pose; raises if the window is already full."""
        if self._count >= self.capacity:
            raise ValueError(f"switch window already holds {self.capacity} samples")
        if self._count == 0:
            self._first = T.copy()
        self._rotation_sum += T[:3, :3]
        self._translation_sum += T[:3, 3]
        self._count += 1

    def mean(self) -> np.ndarray:
        """Average pose of the samples so far (a new 4x4 array); raises when empty."""
        n = self._count
        if n == 0:
            raise ValueError("the switch window is empty")
        if n == 1:
            return self._first.copy()  # type: ignore[union-attr]
        T = np.empty((4, 4))
        T[:3, :3] = project_to_rotation(self._rotation_sum)
        T[:3, 3] = self._translation_sum / n
        T[3] = _LAST_ROW
        return T
