"""Timestamped pose sequences (ground truth or estimates) and their recorder.

A :class:`Trajectory` holds ``n`` samples: ``times`` (s, strictly increasing)
and ``poses`` (``(n, 4, 4)`` poses ``T_w_b`` of a body frame b in the world
frame W, metres; see :mod:`moma_env.geometry` for the conventions). A sample
whose pose is unknown (an estimator that reported nothing, a lost visual
odometry) is stored as an all-NaN pose and is *invalid*; ``valid`` masks the
others. Planar quantities (``xy``, ``yaw``, path length) use the world's x-y
floor plane.

An estimate that reports its uncertainty (MOMA) may carry ``covariances``:
``(n, 6, 6)`` covariances of the pose errors in the world frame W, translation
first, rotation perturbed on the left (the convention of
:mod:`moma_env.estimator.uncertainty`, a ROS ``PoseWithCovariance``): m^2 in
``[:3, :3]``, rad^2 in ``[3:, 3:]``, m rad off the diagonal blocks. A sample
without a covariance (an invalid pose, or a method that gave none at that
time) is all NaN.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.geometry import set_planar

__all__ = ["Trajectory", "TrajectoryRecorder"]

_ROTATION_TOLERANCE = 1e-6
#: Largest asymmetry |C - C^T| accepted in a covariance, relative to its largest entry.
_SYMMETRY_TOLERANCE = 1e-9
_BOTTOM_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def _planar_poses(x: np.ndarray, y: np.ndarray, yaw: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Stack of 4x4 poses from planar arrays of equal length (m, m, rad, m)."""
    n = x.shape[0]
    poses = np.zeros((n, 4, 4))
    c, s = np.cos(yaw), np.sin(yaw)
    poses[:, 0, 0] = c
    poses[:, 0, 1] = -s
    poses[:, 1, 0] = s
    poses[:, 1, 1] = c
    poses[:, 2, 2] = 1.0
    poses[:, 3, 3] = 1.0
    poses[:, 0, 3] = x
    poses[:, 1, 3] = y
    poses[:, 2, 3] = z
    return poses


@dataclass(frozen=True, eq=False)
class Trajectory:
    """An immutable sequence of timestamped poses ``T_w_b``.

    Attributes:
        times: ``(n,)`` sample times (s), finite and strictly increasing.
        poses: ``(n, 4, 4)`` rigid poses ``T_w_b`` (m). An invalid sample is an
            all-NaN pose; on construction a pose with any NaN entry becomes all
            NaN.
        covariances: None (the method reports no uncertainty), or ``(n, 6, 6)``
            covariances of the pose errors (world frame W, translation first,
            rotation perturbed on the left; m^2, m rad, rad^2; see the module
            docstring). A covariance with any NaN entry becomes all NaN, and so
            does the covariance of an invalid pose.

    The arrays are copied on construction and made read-only.

    Raises:
        ValueError: wrong shapes, non-finite or non-increasing times, infinite
            pose entries, or a valid pose that is not a rigid transform
            (rotation not orthonormal with determinant +1 within 1e-6, or
            bottom row not ``[0, 0, 0, 1]``); a covariance with an infinite
            entry, a negative diagonal entry or not symmetric (within 1e-9 of
            its largest entry). The message names the first bad sample.
    """

    times: np.ndarray
    poses: np.ndarray
    covariances: np.ndarray | None = None

    def __post_init__(self) -> None:
        times = np.array(self.times, dtype=float, copy=True)
        poses = np.array(self.poses, dtype=float, copy=True)
        if times.ndim != 1:
            raise ValueError(f"times must be a 1-D array, got shape {times.shape}")
        n = times.shape[0]
        if poses.shape != (n, 4, 4):
            raise ValueError(f"poses must have shape ({n}, 4, 4) to match times, got {poses.shape}")
        finite_times = np.isfinite(times)
        if not finite_times.all():
            i = int(np.argmin(finite_times))
            raise ValueError(f"times must be finite; times[{i}] = {times[i]}")
        if n > 1:
            steps = np.diff(times)
            if not (steps > 0.0).all():
                i = int(np.argmin(steps > 0.0))
                raise ValueError(
                    f"times must be strictly increasing; times[{i}] = {times[i]!r} "
                    f">= times[{i + 1}] = {times[i + 1]!r}"
                )
        if np.isinf(poses).any():
            i = int(np.argmax(np.isinf(poses).any(axis=(1, 2))))
            raise ValueError(f"poses must be finite or NaN (invalid sample); poses[{i}] contains inf")
        invalid = np.isnan(poses).any(axis=(1, 2))
        poses[invalid] = np.nan
        valid = ~invalid
        if valid.any():
            _check_rigid(poses[valid], np.flatnonzero(valid))
        covariances = None
        if self.covariances is not None:
            covariances = _checked_covariances(self.covariances, n, invalid)
            covariances.flags.writeable = False
        times.flags.writeable = False
        poses.flags.writeable = False
        valid.flags.writeable = False
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "covariances", covariances)
        object.__setattr__(self, "_valid", valid)

    # -- construction -------------------------------------------------------

    @classmethod
    def from_poses(cls, times: Sequence[float] | np.ndarray, poses: Sequence[np.ndarray] | np.ndarray) -> Trajectory:
        """Trajectory from ``(n,)`` times (s) and ``(n, 4, 4)`` poses ``T_w_b`` (m)."""
        return cls(np.asarray(times, dtype=float), np.asarray(poses, dtype=float))

    @classmethod
    def from_planar(
        cls,
        times: Sequence[float] | np.ndarray,
        x: Sequence[float] | np.ndarray,
        y: Sequence[float] | np.ndarray,
        yaw: Sequence[float] | np.ndarray,
        z: float | Sequence[float] | np.ndarray = 0.0,
    ) -> Trajectory:
        """Trajectory from planar samples: positions (m), headings (rad), height (m).

        ``x``, ``y``, ``yaw`` have one entry per time; ``z`` is a scalar or one
        entry per time. A NaN in any of them marks the sample invalid.
        """
        t = np.asarray(times, dtype=float)
        if t.ndim != 1:
            raise ValueError(f"times must be a 1-D array, got shape {t.shape}")
        n = t.shape[0]
        arrays = []
        for name, values in (("x", x), ("y", y), ("yaw", yaw)):
            a = np.asarray(values, dtype=float)
            if a.shape != (n,):
                raise ValueError(f"{name} must have shape ({n},) to match times, got {a.shape}")
            arrays.append(a)
        zs = np.asarray(z, dtype=float)
        if zs.ndim == 0:
            zs = np.full(n, float(zs))
        elif zs.shape != (n,):
            raise ValueError(f"z must be a scalar or have shape ({n},), got {zs.shape}")
        return cls(t, _planar_poses(arrays[0], arrays[1], arrays[2], zs))

    @classmethod
    def empty(cls) -> Trajectory:
        """A trajectory with no samples."""
        return cls(np.empty(0), np.empty((0, 4, 4)))

    # -- views --------------------------------------------------------------

    def __len__(self) -> int:
        return int(self.times.shape[0])

    @property
    def valid(self) -> np.ndarray:
        """``(n,)`` bool mask of samples with a known pose (read-only)."""
        return self._valid  # type: ignore[attr-defined]

    @property
    def positions(self) -> np.ndarray:
        """``(n, 3)`` positions of b in W (m); NaN rows for invalid samples. Read-only view."""
        return self.poses[:, :3, 3]

    @property
    def xy(self) -> np.ndarray:
        """``(n, 2)`` planar positions (m); NaN rows for invalid samples. Read-only view."""
        return self.poses[:, :2, 3]

    @property
    def yaw(self) -> np.ndarray:
        """``(n,)`` heading of b's x axis in the floor plane (rad, in [-pi, pi]); NaN if invalid."""
        return np.arctan2(self.poses[:, 1, 0], self.poses[:, 0, 0])

    @property
    def duration(self) -> float:
        """Time from the first to the last sample (s); 0 with fewer than two samples."""
        return float(self.times[-1] - self.times[0]) if len(self) > 1 else 0.0

    def path_length(self) -> float:
        """Planar length (m) of the polyline through the valid samples, in time order.

        Invalid samples are skipped: a gap is bridged by the straight segment
        between the valid samples on either side.
        """
        xy = self.xy[self.valid]
        if xy.shape[0] < 2:
            return 0.0
        return float(np.hypot(*np.diff(xy, axis=0).T).sum())

    def window(self, start: float, stop: float) -> Trajectory:
        """The samples with ``start <= time <= stop`` (s), as a new trajectory."""
        if math.isnan(start) or math.isnan(stop):
            raise ValueError(f"window bounds must not be NaN, got start={start!r}, stop={stop!r}")
        if start > stop:
            raise ValueError(f"window start {start!r} is after stop {stop!r}")
        lo = int(np.searchsorted(self.times, start, side="left"))
        hi = int(np.searchsorted(self.times, stop, side="right"))
        return self._subset(slice(lo, hi))

    def valid_only(self) -> Trajectory:
        """The valid samples only, as a new trajectory."""
        return self._subset(self.valid)

    def with_covariances(self, covariances: np.ndarray | None) -> Trajectory:
        """This trajectory with ``(n, 6, 6)`` pose covariances (or None: without), as a new trajectory."""
        return Trajectory(self.times, self.poses, covariances)

    @property
    def has_covariances(self) -> bool:
        """True if the samples carry covariances (:attr:`covariances` is not None)."""
        return self.covariances is not None

    def _subset(self, index: slice | np.ndarray) -> Trajectory:
        covariances = None if self.covariances is None else self.covariances[index]
        return Trajectory(self.times[index], self.poses[index], covariances)

    def __repr__(self) -> str:
        if len(self) == 0:
            return "Trajectory(n=0)"
        return (
            f"Trajectory(n={len(self)}, t=[{self.times[0]:.6g}, {self.times[-1]:.6g}] s, "
            f"valid={int(self.valid.sum())})"
        )


def _checked_covariances(covariances: np.ndarray, n: int, invalid: np.ndarray) -> np.ndarray:
    """A validated copy of ``(n, 6, 6)`` covariances: NaN-containing and invalid-pose samples all NaN.

    Raises ValueError naming the first sample with an infinite entry, a negative
    diagonal entry or an asymmetry beyond ``_SYMMETRY_TOLERANCE``.
    """
    cov = np.array(covariances, dtype=float, copy=True)
    if cov.shape != (n, 6, 6):
        raise ValueError(f"covariances must have shape ({n}, 6, 6) to match times, got {cov.shape}")
    if np.isinf(cov).any():
        i = int(np.argmax(np.isinf(cov).any(axis=(1, 2))))
        raise ValueError(f"covariances must be finite or NaN (no covariance); covariances[{i}] contains inf")
    missing = np.isnan(cov).any(axis=(1, 2)) | invalid
    cov[missing] = np.nan
    known = ~missing
    if known.any():
        c = cov[known]
        indices = np.flatnonzero(known)
        negative = (np.diagonal(c, axis1=1, axis2=2) < 0.0).any(axis=1)
        if negative.any():
            raise ValueError(f"covariances[{int(indices[np.argmax(negative)])}] has a negative diagonal entry (a variance)")
        scale = np.abs(c).max(axis=(1, 2))
        asymmetric = np.abs(c - c.transpose(0, 2, 1)).max(axis=(1, 2)) > _SYMMETRY_TOLERANCE * scale
        if asymmetric.any():
            raise ValueError(f"covariances[{int(indices[np.argmax(asymmetric)])}] is not symmetric")
    return cov


def _check_rigid(poses: np.ndarray, indices: np.ndarray) -> None:
    """Raise ValueError naming the first pose that is not a rigid transform."""
    bottom_bad = np.abs(poses[:, 3, :] - _BOTTOM_ROW).max(axis=1) > _ROTATION_TOLERANCE
    R = poses[:, :3, :3]
    gram = np.einsum("nji,njk->nik", R, R)
    ortho_bad = np.abs(gram - np.eye(3)).max(axis=(1, 2)) > _ROTATION_TOLERANCE
    det_bad = np.linalg.det(R) < 0.0
    bad = bottom_bad | ortho_bad | det_bad
    if bad.any():
        k = int(np.argmax(bad))
        what = "bottom row is not [0, 0, 0, 1]" if bottom_bad[k] else "rotation is not a proper orthonormal matrix"
        raise ValueError(f"poses[{int(indices[k])}] is not a rigid transform: {what}")


class TrajectoryRecorder:
    """Collects samples one at a time (e.g. once per env step) into a :class:`Trajectory`.

    Storage is a preallocated array that doubles when full, so :meth:`append`
    costs O(1) amortised (about a microsecond) and allocates nothing per call.

    Args:
        planar_z: height (m) given to samples appended as planar ``(x, y, yaw)``.
        capacity: initial number of samples to preallocate.
        covariances: also record a 6x6 pose covariance per sample (see
            :class:`Trajectory`; world frame W, translation first, m^2, m rad,
            rad^2), passed to :meth:`append`; the trajectory then carries them.
    """

    __slots__ = ("_times", "_poses", "_covariances", "_n", "_planar_z", "_last_time")

    # Invariant: slots at index >= _n hold the planar template, so a planar
    # append writes only its six varying entries.

    def __init__(self, planar_z: float = 0.0, capacity: int = 1024, covariances: bool = False):
        if not math.isfinite(planar_z):
            raise ValueError(f"planar_z must be finite, got {planar_z!r}")
        if int(capacity) < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity!r}")
        if not isinstance(covariances, bool):
            raise ValueError(f"covariances must be a bool, got {covariances!r}")
        self._planar_z = float(planar_z)
        self._times = np.empty(int(capacity))
        self._poses = self._blank_poses(int(capacity))
        self._covariances = np.empty((int(capacity), 6, 6)) if covariances else None
        self._n = 0
        self._last_time = -math.inf

    def __len__(self) -> int:
        return self._n

    def append(
        self, time: float, pose: np.ndarray | Sequence[float] | None, covariance: np.ndarray | None = None
    ) -> None:
        """Record a sample at ``time`` (s, later than the previous one).

        ``pose`` is a 4x4 pose ``T_w_b`` (m), a planar ``(x, y, yaw)`` (m, m,
        rad, placed at height ``planar_z``), or ``None`` for an invalid sample
        (no estimate at this time). ``covariance`` is the pose's 6x6 covariance
        (see :class:`Trajectory`), or None for none (recorded as NaN); only a
        recorder made with ``covariances=True`` takes one. It is checked when
        the trajectory is built (:meth:`to_trajectory`), not here.

        Raises:
            ValueError: ``time`` not finite or not after the previous sample's,
                ``pose`` of another shape, ``covariance`` not 6x6, or a
                covariance given to a recorder without covariances.
        """
        t = float(time)
        if not t > self._last_time or t == math.inf:
            raise ValueError(f"sample time must be finite and after the previous one ({self._last_time!r}), got {t!r}")
        n = self._n
        if n == self._times.shape[0]:
            self._grow()
        covariances = self._covariances
        if covariances is not None:
            if covariance is None:
                covariances[n].fill(math.nan)
            elif getattr(covariance, "shape", None) == (6, 6):
                covariances[n] = covariance
            else:
                raise ValueError(f"covariance must be a 6x6 array or None, got shape {np.shape(covariance)}")
        elif covariance is not None:
            raise ValueError("covariance given to a recorder made without covariances (pass covariances=True)")
        slot = self._poses[n]
        if pose is None:
            slot.fill(math.nan)
        elif isinstance(pose, np.ndarray) and pose.shape == (4, 4):
            slot[...] = pose
        else:
            shape = getattr(pose, "shape", None)
            if shape is None:
                shape = (len(pose),) if hasattr(pose, "__len__") else None
            if shape != (3,):
                got = f"shape {shape}" if shape is not None else f"a {type(pose).__name__}"
                raise ValueError(f"pose must be a 4x4 matrix, an (x, y, yaw) triple or None, got {got}")
            x, y, yaw = pose
            # unused slots hold the planar template (identity at planar_z):
            # only the six planar entries change
            set_planar(slot, x, y, yaw)
        self._times[n] = t
        self._last_time = t
        self._n = n + 1

    def _blank_poses(self, capacity: int) -> np.ndarray:
        """``(capacity, 4, 4)`` copies of the planar template: identity at height ``planar_z``."""
        poses = np.zeros((capacity, 4, 4))
        poses[:, [0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
        poses[:, 2, 3] = self._planar_z
        return poses

    def _grow(self) -> None:
        capacity = 2 * self._times.shape[0]
        times = np.empty(capacity)
        poses = self._blank_poses(capacity)
        times[: self._n] = self._times[: self._n]
        poses[: self._n] = self._poses[: self._n]
        if self._covariances is not None:
            covariances = np.empty((capacity, 6, 6))
            covariances[: self._n] = self._covariances[: self._n]
            self._covariances = covariances
        self._times, self._poses = times, poses

    def to_trajectory(self) -> Trajectory:
        """The samples recorded so far, as a (validated, independent) :class:`Trajectory`."""
        covariances = None if self._covariances is None else self._covariances[: self._n]
        return Trajectory(self._times[: self._n], self._poses[: self._n], covariances)
