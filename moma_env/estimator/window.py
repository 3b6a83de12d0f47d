"""The switch window: samples of a static robot's pose averaged before it is frozen."""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from moma_env.estimator.uncertainty import LinearError, covariance_kernel, covariance_one_kernel, window_mean_noise_into
from moma_env.geometry import polar_rotation_kernel, project_to_rotation

__all__ = ["SwitchWindow", "SettlingWindow"]

_LAST_ROW = (0.0, 0.0, 0.0, 1.0)


def _gram(flat: np.ndarray) -> np.ndarray:
    """``flat @ flat.T`` for ``(n, 9)`` rows, as a general matrix product of two buffers
    (``A @ A.T`` of one buffer takes BLAS's symmetric kernel, whose bits differ)."""
    return flat @ np.ascontiguousarray(flat.T)


@numba.njit(cache=True)
def _sorted_median(values: np.ndarray) -> float:
    """The middle of ``values`` sorted, or the mean of the middle two (``np.median``'s bits)."""
    s = np.sort(values)
    h = s.size // 2
    return s[h] if s.size % 2 else (s[h - 1] + s[h]) / 2.0


@numba.njit(cache=True)
def inlier_mask_kernel(rotations: np.ndarray, xyz: np.ndarray, k: float, floor_m: float, floor_rad: float) -> np.ndarray:
    """Which of ``n`` finite samples the window's mean keeps (see :class:`SwitchWindow`), compiled.

    ``rotations``: ``(n, 9)`` rotation blocks row by row; ``xyz``: ``(n, 3)`` translations (m).
    The arithmetic of docs/estimator.md ("Its arithmetic"): coordinate-wise medians,
    distances ``sqrt(dx*dx + dy*dy + dz*dz)``, the Gram matrix of the rotations as one
    general product, its rows summed left to right, the first largest the medoid, the C
    library's acos.
    """
    n = rotations.shape[0]
    # Each column contiguous, like d_t and d_r: one compilation of _sorted_median.
    mx = _sorted_median(np.ascontiguousarray(xyz[:, 0]))
    my = _sorted_median(np.ascontiguousarray(xyz[:, 1]))
    mz = _sorted_median(np.ascontiguousarray(xyz[:, 2]))
    d_t = np.empty(n)
    for i in range(n):
        dx, dy, dz = xyz[i, 0] - mx, xyz[i, 1] - my, xyz[i, 2] - mz
        d_t[i] = math.sqrt(dx * dx + dy * dy + dz * dz)
    traces = np.dot(rotations, np.ascontiguousarray(rotations.T))  # trace(R_i^T R_j)
    medoid, best = 0, 0.0
    for i in range(n):
        total = 0.0
        for j in range(n):
            total += traces[i, j]
        if i == 0 or total > best:
            medoid, best = i, total
    d_r = np.empty(n)
    for j in range(n):
        d_r[j] = math.acos(min(1.0, max(-1.0, (traces[medoid, j] - 1.0) / 2.0)))
    limit_t = max(k * _sorted_median(d_t), floor_m)
    limit_r = max(k * _sorted_median(d_r), floor_rad)
    return (d_t <= limit_t) & (d_r <= limit_r)


@numba.njit(cache=True)
def store_sample_kernel(T: np.ndarray, rotations: np.ndarray, xyz: np.ndarray, n: int) -> bool:
    """Row ``n`` of ``rotations`` (the rotation block of the float64 4x4 ``T``, row by row)
    and of ``xyz`` (its translation, m), in one call; whether ``T`` is finite, decided as
    Python's ``math.isfinite(sum(row0) + sum(row1) + sum(row2) + sum(row3))`` of its rows
    (each row summed left to right from 0, then the four sums left to right)."""
    for r in range(3):
        for c in range(3):
            rotations[n, 3 * r + c] = T[r, c]
        xyz[n, r] = T[r, 3]
    total = 0.0
    for r in range(4):
        row = 0.0
        for c in range(4):
            row += T[r, c]
        total = row if r == 0 else total + row
    return math.isfinite(total)


@numba.njit(cache=True)
def summed_prefix(summed: np.ndarray, n_summed: int, index: np.ndarray, count: int) -> int:
    """How many of running sums' samples ``summed[:n_summed]`` carry over to the samples
    ``index[:count]``: ``n_summed`` when they are its first ones, else 0 (start afresh)."""
    if n_summed > count:
        return 0
    for j in range(n_summed):
        if summed[j] != index[j]:
            return 0
    return n_summed


@numba.njit(cache=True)
def _window_sums(
    rotations: np.ndarray, xyz: np.ndarray, inliers: np.ndarray, count: int, summed: np.ndarray, n_summed: int,
    R_sum: np.ndarray, t_sum: np.ndarray,
) -> int:
    """Bring the running sums ``R_sum`` (9) and ``t_sum`` (3) of the samples ``summed[:n_summed]``
    to those of ``inliers[:count]``, in place: only the new ones are added when the summed
    samples are a prefix of the inliers, else the sums start afresh (each added left to
    right, in inlier order, as summing them anew adds). Returns the new ``n_summed``."""
    m = summed_prefix(summed, n_summed, inliers, count)
    if m == 0:
        R_sum[:] = 0.0
        t_sum[:] = 0.0
    for j in range(m, count):
        i = inliers[j]
        for c in range(9):
            R_sum[c] += rotations[i, c]
        for c in range(3):
            t_sum[c] += xyz[i, c]
        summed[j] = i
    return count


@numba.njit(cache=True)
def window_mean_kernel(
    rotations: np.ndarray, xyz: np.ndarray, n: int, k: float, floor_m: float, floor_rad: float,
    inliers: np.ndarray, summed: np.ndarray, n_summed: int, R_sum: np.ndarray, t_sum: np.ndarray, T: np.ndarray,
) -> tuple[int, int, bool]:
    """The inliers and the mean of a window of ``n`` finite samples in one call (see
    :class:`SwitchWindow`): the inliers into ``inliers`` (all of them when ``n <= 2``,
    else :func:`inlier_mask_kernel`'s), the running sums brought up to them
    (:func:`_window_sums`) and, when there are several, their mean pose into ``T``: the
    chordal mean of the rotations by :func:`~moma_env.geometry.polar_rotation_kernel`,
    the mean translation. Returns ``(inlier count, new n_summed, T written)``; ``T`` is
    not written for a single inlier (its own pose is the mean) nor when the polar
    iteration does not converge (the caller projects ``R_sum`` by SVD)."""
    count = 0
    if n <= 2:
        for i in range(n):
            inliers[i] = i
        count = n
    else:
        mask = inlier_mask_kernel(rotations[:n], xyz[:n], k, floor_m, floor_rad)
        for i in range(n):
            if mask[i]:
                inliers[count] = i
                count += 1
    if count == 1:
        return count, n_summed, False
    n_summed = _window_sums(rotations, xyz, inliers, count, summed, n_summed, R_sum, t_sum)
    R = np.empty((3, 3))
    if not polar_rotation_kernel(R_sum.reshape((3, 3)), R):
        return count, n_summed, False
    for r in range(3):
        for c in range(3):
            T[r, c] = R[r, c]
        T[r, 3] = t_sum[r] / count
        T[3, r] = 0.0
    T[3, 3] = 1.0
    return count, n_summed, True


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

    It runs at every update of a settling robot, so it keeps what the next call
    can reuse: the samples' rotations and translations in preallocated
    ``(capacity, 9)`` and ``(capacity, 3)`` arrays, the inliers and the mean until
    the next change, and the running sums of the inliers' rotations and translations
    while the inliers only grow at the end (the same additions in the same
    order as summing them afresh, so the mean is the same to the bit). The inliers
    and the mean of a window of finite samples come from one compiled call
    (:func:`window_mean_kernel`).

    Args:
        capacity: most samples.
        outlier_k: the ``k`` above (> 0).
        floor_m: translation floor (m), so that noise-free samples all agree.
        floor_rad: rotation floor (rad).
    """

    __slots__ = (
        "capacity",
        "outlier_k",
        "floor_m",
        "floor_rad",
        "_poses",
        "_payloads",
        "_inliers",
        "_rotations",
        "_xyz",
        "_finite",
        "_mean",
        "_index",
        "_summed",
        "_n_summed",
        "_R_sum",
        "_t_sum",
    )

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
        self._rotations = np.empty((capacity, 9))  # row i: the rotation block of sample i, row by row
        self._xyz = np.empty((capacity, 3))  # row i: the translation of sample i (m)
        self._finite = True  # every sample finite (else the exact numpy statistics decide)
        self._mean: np.ndarray | None = None  # mean of the current inliers
        self._index = np.empty(capacity, dtype=np.int64)  # the kernel's inliers
        self._summed = np.empty(capacity, dtype=np.int64)  # the samples summed in _R_sum, _t_sum, in order
        self._n_summed = 0
        self._R_sum = np.zeros(9)
        self._t_sum = np.zeros(3)

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
        self._finite = True
        self._mean = None
        self._n_summed = 0

    def _new_sample(self, T: np.ndarray) -> tuple[int, np.ndarray]:
        """The next sample's index and a float64 4x4 copy of ``T``; ValueError if the window is
        full or ``T`` is not 4x4 (nothing stored yet)."""
        n = len(self._poses)
        if n >= self.capacity:
            raise ValueError(f"switch window already holds {self.capacity} samples")
        T = T.copy() if type(T) is np.ndarray and T.dtype.char == "d" and T.shape == (4, 4) else np.array(T, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"a window sample must be a 4x4 pose, got shape {T.shape}")
        return n, T

    def append(self, T: np.ndarray, payload: Any = None) -> None:
        """Add a 4x4 pose (copied) and its payload; raises if the window is already full."""
        n, T = self._new_sample(T)
        if not store_sample_kernel(T, self._rotations, self._xyz, n):
            self._finite = False
        self._poses.append(T)
        self._payloads.append(payload)
        self._inliers = None
        self._mean = None

    def payloads(self, indices: list[int] | None = None) -> list[Any]:
        """The payloads of the samples at ``indices`` (all when None)."""
        if indices is None:
            return list(self._payloads)
        payloads = self._payloads
        return [payloads[i] for i in indices]

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
        if not self._finite:
            self._inliers = self._inliers_numpy()
            return self._inliers
        mask = inlier_mask_kernel(self._rotations[:n], self._xyz[:n], float(self.outlier_k), float(self.floor_m), float(self.floor_rad))
        self._inliers = np.flatnonzero(mask).tolist()
        return self._inliers

    def _inliers_numpy(self) -> list[int]:
        """:meth:`inliers` with numpy's statistics (NaN-aware), for windows holding a non-finite sample."""
        n = len(self._poses)
        stack = np.array(self._poses)
        t = stack[:, :3, 3]
        d_t = np.sqrt(((t - np.median(t, axis=0)) ** 2).sum(axis=1))
        flat = stack[:, :3, :3].reshape(n, 9)
        traces = _gram(flat)  # trace(R_i^T R_j)
        medoid = int(np.argmax(traces.sum(axis=1)))
        d_r = np.array([math.acos(c) if c == c else c for c in np.clip((traces[medoid] - 1.0) / 2.0, -1.0, 1.0).tolist()])
        k = self.outlier_k
        limit_t = max(k * float(np.median(d_t)), self.floor_m)
        limit_r = max(k * float(np.median(d_r)), self.floor_rad)
        return [i for i in range(n) if d_t[i] <= limit_t and d_r[i] <= limit_r]

    def mean(self) -> np.ndarray:
        """Average pose of the inliers so far (a new 4x4 array); raises when empty."""
        if self._mean is not None:
            return self._mean.copy()
        n = len(self._poses)
        if n == 0:
            raise ValueError("the switch window is empty")
        T = np.empty((4, 4))
        if self._finite:
            count, self._n_summed, written = window_mean_kernel(
                self._rotations, self._xyz, n, float(self.outlier_k), float(self.floor_m), float(self.floor_rad),
                self._index, self._summed, self._n_summed, self._R_sum, self._t_sum, T,
            )
            if self._inliers is None:
                self._inliers = self._index[:count].tolist()
        else:
            index = self.inliers()
            count, written = len(index), False
            if count > 1:
                self._n_summed = _window_sums(
                    self._rotations, self._xyz, np.array(index, dtype=np.int64), count, self._summed, self._n_summed, self._R_sum, self._t_sum
                )
        return self._finish_mean(T, count, written)

    def _finish_mean(self, T: np.ndarray, count: int, written: bool) -> np.ndarray:
        """The mean of ``count`` inliers after :func:`window_mean_kernel` (``written``: it wrote
        ``T``), kept until the next change; a copy of it is returned."""
        if count == 1:
            self._mean = self._poses[self._inliers[0]]
            return self._mean.copy()
        if not written:
            T[:3, :3] = project_to_rotation(self._R_sum.reshape(3, 3))
            T[:3, 3] = self._t_sum / count
            T[3] = _LAST_ROW
        self._mean = T
        return T.copy()


@numba.njit(cache=True, error_model="numpy")
def window_error_mean_kernel(
    err_slots: np.ndarray, err_counts: np.ndarray, err_J: np.ndarray, err_Q: np.ndarray, err_P: np.ndarray, err_has_P: np.ndarray,
    index: np.ndarray, count: int, sums: np.ndarray, sum_slots: np.ndarray, sum_J: np.ndarray, sum_Q: np.ndarray, sum_P: np.ndarray,
    summed: np.ndarray, out_slots: np.ndarray, out_J: np.ndarray, out_Q: np.ndarray, out_P: np.ndarray,
) -> tuple[int, bool]:
    """The error of the mean of the window samples ``index[:count]``: their Jacobians and
    fresh noise averaged, their persistent parts taken as one draw (the arithmetic below,
    in this order).

    Sample ``i``'s error: the Jacobians ``err_J[i, :err_counts[i]]`` with respect to the
    references of key slots ``err_slots[i, :err_counts[i]]``, its fresh noise ``err_Q[i]``
    and, if ``err_has_P[i]``, its persistent part ``err_P[i]`` (6x6 each). The samples'
    sums: each Jacobian (per slot, in the order the slots first appear: the samples in
    inlier order, each in its own order) and ``P`` the first one's copy plus the others
    in order, ``Q`` zero plus every one. They are running sums, kept in ``sum_slots``,
    ``sum_J``, ``sum_Q``, ``sum_P`` for the samples ``summed[:sums[0]]`` (``sums``: that
    count, the slots summed, whether ``P`` is), and only the new samples are added while
    the inliers only grow at the end (the same additions in the same order), else they
    start afresh. The mean into ``out_slots[:k]``, ``out_J[:k]``, ``out_Q``, ``out_P``:
    ``J / n``, ``(Q + (n - 1) P) / n^2`` and ``P / n`` (``Q / n^2`` without a persistent
    part: :func:`~moma_env.estimator.uncertainty.window_mean_noise_into`). One sample is its own
    mean, copied; none (a window whose samples are not all finite may keep none) gives
    ``Q = 0 / 0`` as numpy divides (hence numpy's error model). Returns ``(k, whether the
    mean has a persistent part)``.
    """
    if count == 1:
        i = index[0]
        for a in range(err_counts[i]):
            out_slots[a] = err_slots[i, a]
            out_J[a] = err_J[i, a]
        out_Q[:] = err_Q[i]
        if err_has_P[i]:
            out_P[:] = err_P[i]
        sums[0] = 0
        return err_counts[i], err_has_P[i]
    m = summed_prefix(summed, sums[0], index, count)
    if m == 0:
        k = 0
        has_P = False
        sum_Q[:] = 0.0
    else:
        k = sums[1]
        has_P = sums[2] != 0
    for j in range(m, count):
        i = index[j]
        for a in range(err_counts[i]):
            slot = err_slots[i, a]
            b = 0
            while b < k and sum_slots[b] != slot:
                b += 1
            if b == k:
                sum_slots[k] = slot
                sum_J[k] = err_J[i, a]
                k += 1
            else:
                for r in range(6):
                    for c in range(6):
                        sum_J[b, r, c] = sum_J[b, r, c] + err_J[i, a, r, c]
        for r in range(6):
            for c in range(6):
                sum_Q[r, c] = sum_Q[r, c] + err_Q[i, r, c]
        if err_has_P[i]:
            if has_P:
                for r in range(6):
                    for c in range(6):
                        sum_P[r, c] = sum_P[r, c] + err_P[i, r, c]
            else:
                sum_P[:] = err_P[i]
                has_P = True
        summed[j] = i
    sums[0] = count
    sums[1] = k
    sums[2] = 1 if has_P else 0
    for b in range(k):
        out_slots[b] = sum_slots[b]
        for r in range(6):
            for c in range(6):
                out_J[b, r, c] = sum_J[b, r, c] / count
    window_mean_noise_into(sum_Q, sum_P, has_P, count, out_Q)
    if has_P:
        for r in range(6):
            for c in range(6):
                out_P[r, c] = sum_P[r, c] / count
    return k, has_P


@numba.njit(cache=True)
def slot_covariance_kernel(slots: np.ndarray, k: int, J: np.ndarray, Q: np.ndarray, blocks: np.ndarray, n_slots: int) -> np.ndarray:
    """:meth:`LinearError.covariance` of the error ``J[:k]`` (with respect to the references of
    key slots ``slots[:k]``) plus fresh noise ``Q``, given the joint covariance of the slots'
    references as ``blocks[u * n_slots + v]`` (slots ``u``, ``v``); the same calls, the same bits."""
    if k == 1:
        u = slots[0]
        return covariance_one_kernel(J[0], blocks[u * n_slots + u], Q)
    chosen = np.empty((k * k, 6, 6))
    for a in range(k):
        for b in range(k):
            chosen[a * k + b] = blocks[slots[a] * n_slots + slots[b]]
    return covariance_kernel(np.ascontiguousarray(J[:k]), chosen, Q)


@numba.njit(cache=True)
def settling_add_kernel(
    T: np.ndarray, rotations: np.ndarray, xyz: np.ndarray, n: int, finite_before: bool, k: float, floor_m: float, floor_rad: float,
    index: np.ndarray, summed: np.ndarray, n_summed: int, R_sum: np.ndarray, t_sum: np.ndarray, T_mean: np.ndarray,
    err_slots: np.ndarray, err_counts: np.ndarray, err_J: np.ndarray, err_Q: np.ndarray, err_P: np.ndarray, err_has_P: np.ndarray,
    slots: np.ndarray, J: np.ndarray, Q: np.ndarray, P: np.ndarray, has_P: bool, blocks: np.ndarray, n_slots: int,
    sums: np.ndarray, sum_slots: np.ndarray, sum_J: np.ndarray, sum_Q: np.ndarray, sum_P: np.ndarray, err_summed: np.ndarray,
    out_slots: np.ndarray, out_J: np.ndarray, out_Q: np.ndarray, out_P: np.ndarray,
) -> tuple:
    """:meth:`SettlingWindow.add` in one call: sample ``n`` (the pose ``T`` with its error:
    Jacobians ``J`` for the key slots ``slots``, noise ``Q``, persistent part ``P`` if
    ``has_P``) stored (:func:`store_sample_kernel`), then, if every sample is finite, the
    inliers and the mean pose (:func:`window_mean_kernel`), the mean's error
    (:func:`window_error_mean_kernel`) and its covariance (:func:`slot_covariance_kernel`).

    Returns ``(sample finite, inlier count, n_summed, T_mean written, mean error's key
    count, whether it has a persistent part, covariance)``; the count is -1 (nothing else
    computed) when a sample is not finite."""
    finite = store_sample_kernel(T, rotations, xyz, n)
    m = slots.shape[0]
    err_counts[n] = m
    for a in range(m):
        err_slots[n, a] = slots[a]
        err_J[n, a] = J[a]
    err_Q[n] = Q
    err_has_P[n] = has_P
    if has_P:
        err_P[n] = P
    if not (finite and finite_before):
        return finite, -1, n_summed, False, 0, False, Q
    count, n_summed, written = window_mean_kernel(rotations, xyz, n + 1, k, floor_m, floor_rad, index, summed, n_summed, R_sum, t_sum, T_mean)
    n_out, has_P_out = window_error_mean_kernel(
        err_slots, err_counts, err_J, err_Q, err_P, err_has_P, index, count,
        sums, sum_slots, sum_J, sum_Q, sum_P, err_summed, out_slots, out_J, out_Q, out_P,
    )
    return finite, count, n_summed, written, n_out, has_P_out, slot_covariance_kernel(out_slots, n_out, out_J, out_Q, blocks, n_slots)


class SettlingWindow(SwitchWindow):
    """The switch window of a settling robot, whose samples carry their errors
    (:class:`~moma_env.estimator.uncertainty.LinearError`, with respect to the frozen
    references' errors): :meth:`add` stores a sample and its error and gives the mean pose
    and the covariance of its error in one compiled call (:func:`settling_add_kernel`).

    The mean's error is the mean of the inliers' errors, their persistent parts one draw
    (:func:`window_error_mean_kernel`), and its covariance is what
    :meth:`~moma_env.estimator.uncertainty.LinearError.covariance` gives under ``joint``,
    bit for bit; the errors are kept in arrays, each reference key in a
    slot of its own, and the joint covariance of the slots' references is copied from
    ``joint`` when a key first appears (a frozen pose's joint entries never change while
    a sample depends on it).

    Args:
        capacity, outlier_k, floor_m, floor_rad: those of :class:`SwitchWindow`.
        joint: the estimator's joint covariance of the frozen poses' errors, ``(key, key)
            -> 6x6``, read when a sample brings a new key.
    """

    __slots__ = (
        "_joint", "_keys", "_slot_of", "_blocks", "_last_keys", "_last_slots",
        "_err_slots", "_err_counts", "_err_J", "_err_Q", "_err_P", "_err_has_P",
        "_sums", "_sum_slots", "_sum_J", "_sum_Q", "_sum_P", "_err_summed",
        "_out_slots", "_out_J", "_out_Q", "_out_P", "_error",
    )

    def __init__(
        self, capacity: int, outlier_k: float = 3.0, floor_m: float = 0.002, floor_rad: float = 0.002,
        joint: dict | None = None,
    ):
        super().__init__(capacity, outlier_k, floor_m, floor_rad)
        self._joint = {} if joint is None else joint
        # The samples' errors, allocated at the first sample (a robot that never settles
        # keeps none); persistent parts in a stand-in row until a sample brings one.
        self._err_counts: np.ndarray | None = None
        self._err_has_P: np.ndarray | None = None
        self._err_Q: np.ndarray | None = None
        self._err_slots: np.ndarray | None = None
        self._err_J: np.ndarray | None = None
        self._err_P = np.empty((1, 6, 6))
        self._sums = np.zeros(3, dtype=np.int64)  # samples summed, slots summed, whether P is
        self._err_summed = np.empty(capacity, dtype=np.int64)  # the samples summed, in order
        self._sum_Q = np.empty((6, 6))
        self._sum_P = np.empty((6, 6))
        self._out_Q = np.empty((6, 6))
        self._out_P = np.empty((6, 6))
        self._sum_J: np.ndarray | None = None
        self._size_slots(1)
        self._clear_errors()

    def _size_samples(self, per_sample: int, has_P: bool) -> None:
        """Room for ``per_sample`` keys in every sample's error (and a persistent part if
        ``has_P``), keeping what is stored."""
        capacity = self.capacity
        if self._err_J is None:
            self._err_counts = np.zeros(capacity, dtype=np.int64)
            self._err_has_P = np.zeros(capacity, dtype=np.bool_)
            self._err_Q = np.empty((capacity, 6, 6))
            self._err_slots = np.zeros((capacity, max(per_sample, 1)), dtype=np.int64)
            self._err_J = np.empty((capacity, max(per_sample, 1), 6, 6))
        elif self._err_J.shape[1] < per_sample:
            old = self._err_J.shape[1]
            err_slots = np.zeros((capacity, per_sample), dtype=np.int64)
            err_J = np.empty((capacity, per_sample, 6, 6))
            err_slots[:, :old] = self._err_slots
            err_J[:, :old] = self._err_J
            self._err_slots, self._err_J = err_slots, err_J
        if has_P and self._err_P.shape[0] < capacity:  # no sample had one: nothing to keep
            self._err_P = np.empty((capacity, 6, 6))

    def _size_slots(self, slots: int) -> None:
        """Room for ``slots`` reference keys in the sums and the mean, keeping the running sums."""
        if self._sum_J is not None and self._sum_J.shape[0] >= slots:
            return
        self._out_slots = np.zeros(slots, dtype=np.int64)
        self._out_J = np.empty((slots, 6, 6))
        sum_slots = np.zeros(slots, dtype=np.int64)
        sum_J = np.empty((slots, 6, 6))
        if self._sum_J is not None:  # the running sums carry on
            old = self._sum_J.shape[0]
            sum_slots[:old] = self._sum_slots
            sum_J[:old] = self._sum_J
        self._sum_slots, self._sum_J = sum_slots, sum_J

    def _clear_errors(self) -> None:
        self._keys: list = []  # slot -> reference key
        self._slot_of: dict = {}  # reference key -> slot
        self._blocks = np.zeros((0, 6, 6))  # [u * len(keys) + v]: joint[(keys[u], keys[v])]
        self._last_keys: list | None = None
        self._last_slots = np.zeros(0, dtype=np.int64)
        self._error: tuple[int, bool] | None = None  # the mean error's key count and persistent flag
        self._sums[0] = 0

    def clear(self) -> None:
        """Forget every sample and its error."""
        super().clear()
        self._clear_errors()

    def payloads(self, indices: list[int] | None = None) -> list[LinearError]:
        """The errors of the samples at ``indices`` (all when None): a new
        :class:`~moma_env.estimator.uncertainty.LinearError` each, of the stored arrays."""
        if indices is None:
            indices = range(len(self._poses))
        keys, slots, counts, has_P = self._keys, self._err_slots, self._err_counts, self._err_has_P
        return [
            LinearError(
                {keys[slots[i, a]]: self._err_J[i, a].copy() for a in range(counts[i])},
                self._err_Q[i].copy(),
                self._err_P[i].copy() if has_P[i] else None,
            )
            for i in indices
        ]

    def references(self) -> list:
        """The reference keys the samples' errors depend on (every sample, inlier or not)."""
        return list(self._keys)

    def append(self, T: np.ndarray, payload: Any = None) -> None:
        """:meth:`add` without its results; ``payload`` must be the sample's
        :class:`~moma_env.estimator.uncertainty.LinearError`."""
        self.add(T, payload)

    def _slots(self, keys: list) -> np.ndarray:
        """The slots of ``keys`` (an int64 array), new keys given slots and their joint covariance."""
        if keys == self._last_keys:
            return self._last_slots
        slot_of = self._slot_of
        added = False
        slots = []
        for key in keys:
            slot = slot_of.get(key)
            if slot is None:
                slot = slot_of[key] = len(self._keys)
                self._keys.append(key)
                added = True
            slots.append(slot)
        if added:
            joint, every = self._joint, self._keys
            self._blocks = np.array([joint[(s, r)] for s in every for r in every]).reshape(-1, 6, 6)
            self._size_slots(len(every))
        self._last_keys = keys
        self._last_slots = np.array(slots, dtype=np.int64)
        return self._last_slots

    def add(self, T: np.ndarray, error: LinearError) -> tuple[np.ndarray, np.ndarray]:
        """Add a 4x4 pose (copied, in W) and its error; returns the mean pose (a new 4x4
        array, :meth:`mean`) and the 6x6 covariance of its error (a new array). Raises if
        the window is already full."""
        n, T = self._new_sample(T)
        if not isinstance(error, LinearError):
            raise TypeError(f"a settling window sample's error must be a LinearError, got {type(error).__name__}")
        return self._add(n, T, *error.operands())

    def add_operands(
        self, T: np.ndarray, keys: list, stack: np.ndarray, Q: np.ndarray, P: np.ndarray, has_P: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`add` of the error whose :meth:`~moma_env.estimator.uncertainty.LinearError.operands`
        are ``(keys, stack, Q, P, has_P)`` (what the estimator's compiled samples give:
        :func:`~moma_env.estimator.uncertainty.packed_operands`), without making the error.
        ``stack``, ``Q`` and ``P`` are read, not kept. ValueError for operands of other shapes."""
        n, T = self._new_sample(T)
        if stack.shape != (len(keys), 6, 6) or Q.shape != (6, 6) or P.shape != (6, 6):
            raise ValueError(
                f"error operands must be {len(keys)} 6x6 Jacobians, a 6x6 Q and a 6x6 P, "
                f"got shapes {stack.shape}, {Q.shape}, {P.shape}"
            )
        return self._add(n, T, keys, stack, Q, P, has_P)

    def _add(
        self, n: int, T: np.ndarray, keys: list, stack: np.ndarray, Q: np.ndarray, P: np.ndarray, has_P: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """Store sample ``n`` (``T``, this window's copy) with the error of those operands; the
        mean pose and the covariance of its error (:meth:`add`)."""
        if not has_P:  # the kernel's arrays writable, as always, so that it is compiled once
            P = self._out_P
        if not keys:
            stack = np.empty((0, 6, 6))
        slots = self._slots(keys)
        if self._err_J is None or len(keys) > self._err_J.shape[1] or (has_P and self._err_P.shape[0] < self.capacity):
            self._size_samples(len(keys), has_P)
        T_mean = np.empty((4, 4))
        finite, count, n_summed, written, n_out, has_P_out, covariance = settling_add_kernel(
            T, self._rotations, self._xyz, n, self._finite, float(self.outlier_k), float(self.floor_m), float(self.floor_rad),
            self._index, self._summed, self._n_summed, self._R_sum, self._t_sum, T_mean,
            self._err_slots, self._err_counts, self._err_J, self._err_Q, self._err_P, self._err_has_P,
            slots, stack, Q, P, has_P, self._blocks, len(self._keys),
            self._sums, self._sum_slots, self._sum_J, self._sum_Q, self._sum_P, self._err_summed,
            self._out_slots, self._out_J, self._out_Q, self._out_P,
        )
        self._poses.append(T)
        self._payloads.append(None)  # the error is in the arrays (payloads() reads them)
        self._mean = None
        if not finite:
            self._finite = False
        if count < 0:  # a sample not finite: numpy's statistics (SwitchWindow), the same error kernels
            self._inliers = None
            pose = self.mean()
            covariance = self._error_statistics(self._inliers)
            return pose, covariance
        self._n_summed = n_summed
        self._inliers = self._index[:count].tolist()
        self._error = (n_out, has_P_out)
        return self._finish_mean(T_mean, count, written), covariance

    def _error_statistics(self, inliers: list[int]) -> np.ndarray:
        """The mean error of the samples ``inliers`` into the window's buffers; its covariance."""
        index = np.array(inliers, dtype=np.int64)
        n_out, has_P_out = window_error_mean_kernel(
            self._err_slots, self._err_counts, self._err_J, self._err_Q, self._err_P, self._err_has_P,
            index, index.size, self._sums, self._sum_slots, self._sum_J, self._sum_Q, self._sum_P, self._err_summed,
            self._out_slots, self._out_J, self._out_Q, self._out_P,
        )
        self._error = (n_out, has_P_out)
        return slot_covariance_kernel(self._out_slots, n_out, self._out_J, self._out_Q, self._blocks, len(self._keys))

    def mean_error(self) -> LinearError:
        """The error of :meth:`mean` (of the current inliers), a new
        :class:`~moma_env.estimator.uncertainty.LinearError`; raises when empty."""
        if self._error is None:
            self._error_statistics(self.inliers())
        n_out, has_P = self._error
        keys, slots = self._keys, self._out_slots
        J = {keys[slots[b]]: self._out_J[b].copy() for b in range(n_out)}
        return LinearError(J, self._out_Q.copy(), self._out_P.copy() if has_P else None)
