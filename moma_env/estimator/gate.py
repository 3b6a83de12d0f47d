"""Outlier gate on one robot's measured pose stream.

Positions are the robot body origin in the world frame W (m); distances are the
L1 norm ``|dx|+|dy|+|dz|`` as in the authors' code. Rotations are compared by
the angle of the relative rotation (rad). The gate holds small per-robot state
(a few recent poses) and works on plain floats, since it runs for every
measured robot at every update.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from moma_env.estimator.config import OutlierGateConfig

__all__ = ["OutlierGate"]

Position = tuple[float, float, float]
#: A rotation matrix as 9 floats, row by row.
Rotation = tuple[float, ...]


def _l1(a: Position, b: Position) -> float:
    return abs(a[0] - b[0]) + abs(a[1] - b[1]) + abs(a[2] - b[2])


def _angle(a: Rotation, b: Rotation) -> float:
    """Angle (rad) of the rotation between two rotation matrices given as 9 floats."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = a
    b0, b1, b2, b3, b4, b5, b6, b7, b8 = b
    # trace(A^T B), added left to right from 0 (as sum() did before Python 3.12).
    trace = 0 + a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3 + a4 * b4 + a5 * b5 + a6 * b6 + a7 * b7 + a8 * b8
    return math.acos(min(1.0, max(-1.0, 0.5 * (trace - 1.0))))


class OutlierGate:
    """Accepts or rejects the measured poses of one robot.

    * Without accepted history, ``start_samples`` consecutive samples pairwise
      within ``start_tolerance_m`` and ``start_tolerance_rad`` are needed; the
      one completing the set is the first accepted (and the set becomes the
      history).
    * With history, a sample farther than ``jump_tolerance_m`` from the mean of
      the last ``history`` accepted positions, or whose rotation is farther than
      ``jump_tolerance_rad`` from the last accepted rotation, is rejected.
    * History (and pending start samples) older than ``reset_after_s`` are
      forgotten before a new sample is judged.
    """

    __slots__ = ("_config", "_accepted", "_rotation", "_last_accepted_time", "_pending", "_last_pending_time")

    def __init__(self, config: OutlierGateConfig):
        self._config = config
        self._accepted: deque[Position] = deque(maxlen=config.history)
        self._rotation: Rotation | None = None
        self._last_accepted_time = 0.0
        self._pending: deque[tuple[Position, Rotation]] = deque(maxlen=config.start_samples)
        self._last_pending_time = 0.0

    @property
    def has_history(self) -> bool:
        """True when at least one accepted pose is remembered."""
        return bool(self._accepted)

    def reset(self, seed: np.ndarray | None = None, time: float = 0.0) -> None:
        """Forget everything; optionally remember the 4x4 pose ``seed`` as accepted at ``time`` (s)."""
        self._accepted.clear()
        self._pending.clear()
        self._rotation = None
        if seed is not None:
            p, R = self._split(seed)
            self._accepted.append(p)
            self._rotation = R
            self._last_accepted_time = time

    @staticmethod
    def _split(T: np.ndarray) -> tuple[Position, Rotation]:
        (a, b, c, x), (d, e, f, y), (g, h, i, z) = T[:3].tolist()
        return (x, y, z), (a, b, c, d, e, f, g, h, i)

    def accept(self, T: np.ndarray, time: float) -> bool:
        """Judge a measured 4x4 pose ``T_w_b`` (world frame, m) taken at ``time`` (s)."""
        cfg = self._config
        p, R = self._split(T)
        accepted = self._accepted
        if accepted and time - self._last_accepted_time > cfg.reset_after_s:
            accepted.clear()
            self._rotation = None
        if accepted:
            sx = sy = sz = 0.0
            for q in accepted:
                sx += q[0]
                sy += q[1]
                sz += q[2]
            n = len(accepted)
            if abs(p[0] - sx / n) + abs(p[1] - sy / n) + abs(p[2] - sz / n) > cfg.jump_tolerance_m:
                return False
            if self._rotation is not None and _angle(self._rotation, R) > cfg.jump_tolerance_rad:
                return False
            accepted.append(p)
            self._rotation = R
            self._last_accepted_time = time
            return True
        pending = self._pending
        if pending and time - self._last_pending_time > cfg.reset_after_s:
            pending.clear()
        pending.append((p, R))
        self._last_pending_time = time
        if len(pending) < cfg.start_samples:
            return False
        tol, tol_rad = cfg.start_tolerance_m, cfg.start_tolerance_rad
        items = tuple(pending)
        for i in range(len(items)):
            for j in range(i + 1, len(items)):
                if _l1(items[i][0], items[j][0]) > tol or _angle(items[i][1], items[j][1]) > tol_rad:
                    return False
        accepted.extend(q for q, _ in items)
        self._rotation = R
        pending.clear()
        self._last_accepted_time = time
        return True
