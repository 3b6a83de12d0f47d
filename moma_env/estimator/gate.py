"""Outlier gate on one robot's measured pose stream.

Positions are the robot body origin in the world frame W (m); distances are the
L1 norm ``|dx|+|dy|+|dz|`` as in the authors' code. Rotations are compared by
the angle of the relative rotation (rad). The gate holds small per-robot state
(a few recent poses) in one float64 array and judges a sample in one compiled
call, since it runs for every measured robot at every update.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from moma_env.estimator.config import OutlierGateConfig

__all__ = ["OutlierGate"]

# Layout of the state vector: counts and times, the last accepted rotation (9 floats,
# row by row), then the accepted positions (3 each) and the pending samples (3 + 9 each),
# oldest first.
_N_ACCEPTED = 0
_N_PENDING = 1
_HAS_ROTATION = 2
_LAST_ACCEPTED_TIME = 3
_LAST_PENDING_TIME = 4
_ROTATION = 5
_ACCEPTED = _ROTATION + 9
# Layout of the settings vector.
_HISTORY = 0
_START_SAMPLES = 1
_START_TOL_M = 2
_START_TOL_RAD = 3
_JUMP_TOL_M = 4
_JUMP_TOL_RAD = 5
_RESET_AFTER_S = 6


@numba.njit(cache=True)
def _angle(a: np.ndarray, ia: int, b: np.ndarray, ib: int) -> float:
    """Angle (rad) of the rotation between the rotation matrices ``a[ia:ia + 9]`` and
    ``b[ib:ib + 9]`` (row by row): ``acos`` of ``(trace(A^T B) - 1) / 2`` clipped to
    [-1, 1], the trace added left to right from 0."""
    trace = 0.0
    for k in range(9):
        trace += a[ia + k] * b[ib + k]
    return math.acos(min(1.0, max(-1.0, 0.5 * (trace - 1.0))))


@numba.njit(cache=True)
def _push(state: np.ndarray, at: int, width: int, capacity: int, count: int, values: np.ndarray) -> int:
    """Append the ``width`` floats ``values[:width]`` to the first-in first-out rows of
    ``width`` floats at ``state[at:]`` (``count`` rows of at most ``capacity``, oldest
    first), the oldest leaving when it is full; the new count."""
    if count == capacity:
        for k in range(width, width * capacity):
            state[at + k - width] = state[at + k]
        count -= 1
    for k in range(width):
        state[at + width * count + k] = values[k]
    return count + 1


@numba.njit(cache=True)
def _accepted_now(state: np.ndarray, sample: np.ndarray, time: float) -> None:
    """The sample's rotation becomes the last accepted one, at ``time``."""
    for k in range(9):
        state[_ROTATION + k] = sample[3 + k]
    state[_HAS_ROTATION] = 1.0
    state[_LAST_ACCEPTED_TIME] = time


@numba.njit(cache=True)
def _accept(T: np.ndarray, time: float, settings: np.ndarray, state: np.ndarray) -> bool:
    """:meth:`OutlierGate.accept` on the state vector (see :class:`OutlierGate`)."""
    history = int(settings[_HISTORY])
    start_samples = int(settings[_START_SAMPLES])
    pending_at = _ACCEPTED + 3 * history
    sample = np.empty(12)  # position, then rotation row by row
    for r in range(3):
        sample[r] = T[r, 3]
        for c in range(3):
            sample[3 + 3 * r + c] = T[r, c]
    n = int(state[_N_ACCEPTED])
    if n > 0 and time - state[_LAST_ACCEPTED_TIME] > settings[_RESET_AFTER_S]:
        n = 0
        state[_N_ACCEPTED] = 0.0
        state[_HAS_ROTATION] = 0.0
    if n > 0:
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for k in range(n):
            sx += state[_ACCEPTED + 3 * k]
            sy += state[_ACCEPTED + 3 * k + 1]
            sz += state[_ACCEPTED + 3 * k + 2]
        if abs(sample[0] - sx / n) + abs(sample[1] - sy / n) + abs(sample[2] - sz / n) > settings[_JUMP_TOL_M]:
            return False
        if state[_HAS_ROTATION] != 0.0 and _angle(state, _ROTATION, sample, 3) > settings[_JUMP_TOL_RAD]:
            return False
        state[_N_ACCEPTED] = _push(state, _ACCEPTED, 3, history, n, sample)
        _accepted_now(state, sample, time)
        return True
    m = int(state[_N_PENDING])
    if m > 0 and time - state[_LAST_PENDING_TIME] > settings[_RESET_AFTER_S]:
        m = 0
    m = _push(state, pending_at, 12, start_samples, m, sample)
    state[_N_PENDING] = m
    state[_LAST_PENDING_TIME] = time
    if m < start_samples:
        return False
    for i in range(m):
        a = pending_at + 12 * i
        for j in range(i + 1, m):
            b = pending_at + 12 * j
            l1 = abs(state[a] - state[b]) + abs(state[a + 1] - state[b + 1]) + abs(state[a + 2] - state[b + 2])
            if l1 > settings[_START_TOL_M] or _angle(state, a + 3, state, b + 3) > settings[_START_TOL_RAD]:
                return False
    kept = min(m, history)  # the last ``history`` pending positions become the accepted ones
    for i in range(kept):
        a = pending_at + 12 * (m - kept + i)
        for k in range(3):
            state[_ACCEPTED + 3 * i + k] = state[a + k]
    state[_N_ACCEPTED] = kept
    state[_N_PENDING] = 0.0
    _accepted_now(state, sample, time)
    return True


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

    Its state is one float64 vector (counts, times, the last accepted rotation,
    the accepted positions and the pending samples, oldest first), judged by one
    compiled call per sample.
    """

    __slots__ = ("_config", "_settings", "_state")

    def __init__(self, config: OutlierGateConfig):
        self._config = config
        self._settings = np.array(
            [
                config.history,
                config.start_samples,
                config.start_tolerance_m,
                config.start_tolerance_rad,
                config.jump_tolerance_m,
                config.jump_tolerance_rad,
                config.reset_after_s,
            ],
            dtype=np.float64,
        )
        self._state = np.zeros(_ACCEPTED + 3 * config.history + 12 * config.start_samples)

    @property
    def has_history(self) -> bool:
        """True when at least one accepted pose is remembered."""
        return bool(self._state[_N_ACCEPTED] > 0.0)

    def reset(self, seed: np.ndarray | None = None, time: float = 0.0) -> None:
        """Forget everything; optionally remember the 4x4 pose ``seed`` as accepted at ``time`` (s)."""
        state = self._state
        state[:] = 0.0
        if seed is not None:
            state[_ACCEPTED : _ACCEPTED + 3] = seed[:3, 3]
            state[_ROTATION:_ACCEPTED] = seed[:3, :3].ravel()
            state[_N_ACCEPTED] = 1.0
            state[_HAS_ROTATION] = 1.0
            state[_LAST_ACCEPTED_TIME] = time

    def accept(self, T: np.ndarray, time: float) -> bool:
        """Judge a measured 4x4 pose ``T_w_b`` (world frame, m) taken at ``time`` (s)."""
        return _accept(T, float(time), self._settings, self._state)
