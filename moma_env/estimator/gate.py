"""Outlier gate on one robot's measured position stream.

Positions are the robot body origin in the world frame W (m); distances are the
L1 norm ``|dx|+|dy|+|dz|`` as in the authors' code. The gate holds small
per-robot state (a few recent positions) and works on plain floats, since it runs
for every measured robot at every update.
"""

from __future__ import annotations

from collections import deque

from moma_env.estimator.config import OutlierGateConfig

__all__ = ["OutlierGate"]

Position = tuple[float, float, float]


def _l1(a: Position, b: Position) -> float:
    return abs(a[0] - b[0]) + abs(a[1] - b[1]) + abs(a[2] - b[2])


class OutlierGate:
    """Accepts or rejects the measured positions of one robot.

    * Without accepted history, ``start_samples`` consecutive samples pairwise
      within ``start_tolerance_m`` are needed; the one completing the set is the
      first accepted (and the set becomes the history).
    * With history, a sample farther than ``jump_tolerance_m`` from the mean of
      the last ``history`` accepted ones is rejected.
    * History (and pending start samples) older than ``reset_after_s`` are
      forgotten before a new sample is judged.
    """

    __slots__ = ("_config", "_accepted", "_last_accepted_time", "_pending", "_last_pending_time")

    def __init__(self, config: OutlierGateConfig):
        self._config = config
        self._accepted: deque[Position] = deque(maxlen=config.history)
        self._last_accepted_time = 0.0
        self._pending: deque[Position] = deque(maxlen=config.start_samples)
        self._last_pending_time = 0.0

    @property
    def has_history(self) -> bool:
        """True when at least one accepted position is remembered."""
        return bool(self._accepted)

    def reset(self, seed: Position | None = None, time: float = 0.0) -> None:
        """Forget everything; optionally remember ``seed`` as accepted at ``time`` (s)."""
        self._accepted.clear()
        self._pending.clear()
        if seed is not None:
            self._accepted.append((float(seed[0]), float(seed[1]), float(seed[2])))
            self._last_accepted_time = time

    def accept(self, position: Position, time: float) -> bool:
        """Judge a measured position (m, world frame) taken at ``time`` (s)."""
        cfg = self._config
        p = (float(position[0]), float(position[1]), float(position[2]))
        accepted = self._accepted
        if accepted and time - self._last_accepted_time > cfg.reset_after_s:
            accepted.clear()
        if accepted:
            sx = sy = sz = 0.0
            for q in accepted:
                sx += q[0]
                sy += q[1]
                sz += q[2]
            n = len(accepted)
            if abs(p[0] - sx / n) + abs(p[1] - sy / n) + abs(p[2] - sz / n) > cfg.jump_tolerance_m:
                return False
            accepted.append(p)
            self._last_accepted_time = time
            return True
        pending = self._pending
        if pending and time - self._last_pending_time > cfg.reset_after_s:
            pending.clear()
        pending.append(p)
        self._last_pending_time = time
        if len(pending) < cfg.start_samples:
            return False
        tol = cfg.start_tolerance_m
        items = tuple(pending)
        for i in range(len(items)):
            for j in range(i + 1, len(items)):
                if _l1(items[i], items[j]) > tol:
                    return False
        accepted.extend(items)
        pending.clear()
        self._last_accepted_time = time
        return True
