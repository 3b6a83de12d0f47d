"""Pose covariances beside a TUM trajectory file: one line per pose of the TUM file.

The TUM format (:mod:`moma_env.metrics.tum`) has no room for an uncertainty, so
a trajectory that carries covariances (MOMA's) gets a second text file, by
convention named like the TUM file with ``.cov.txt`` instead of ``.tum``
(``ugv_0_moma.tum`` and ``ugv_0_moma.cov.txt``). Each line is::

    timestamp c00 c01 c02 c03 c04 c05 c10 c11 ... c55

the time (s) followed by the 36 entries of the 6x6 covariance, row-major (the
order of a ROS ``PoseWithCovariance.covariance``). The covariance is that of the
error ``(dx, dy, dz, rx, ry, rz)`` of the pose ``T_w_b``: translation first,
additive in the world frame W (m), then the rotation perturbed on the left,
about W's axes (rad), as in :mod:`moma_env.estimator.uncertainty`. Units: m^2
in the translation block, rad^2 in the rotation block, m rad in the cross
blocks. A sample whose pose is known but whose covariance is not is written as
36 ``nan``. Only the samples with a valid pose are written, in time order, so
line k of the covariance file belongs to line k of the TUM file, with the same
timestamp. Lines starting with ``#`` and blank lines are comments.

Values are written with Python's shortest round-trip representation (``repr``),
so :func:`read_covariances` gives back the written times and covariances bit
for bit.
"""

from __future__ import annotations

import math
import os

import numpy as np

from moma_env.io import atomic_write_text
from moma_env.metrics.trajectory import Trajectory
from moma_env.metrics.tum import read_timed_rows, read_tum

__all__ = [
    "COVARIANCE_HEADER",
    "COVARIANCE_SUFFIX",
    "covariance_path_for",
    "format_covariances",
    "write_covariances",
    "read_covariances",
    "read_tum_with_covariances",
]

#: Comment lines at the top of a covariance file: the field order and the units.
COVARIANCE_HEADER = (
    "# timestamp (s) then the 36 entries of the 6x6 pose covariance, row-major (ROS PoseWithCovariance order)\n"
    "# error of T_w_b = (dx dy dz rx ry rz): translation in the world frame W (m), then rotation\n"
    "# perturbed on the left about W's axes (rad); units m^2, m rad (cross blocks), rad^2; nan: no covariance"
)
#: File name ending of a covariance file, replacing the TUM file's ``.tum``.
COVARIANCE_SUFFIX = ".cov.txt"
#: Largest asymmetry |C - C^T| accepted by the reader, relative to the largest entry.
_SYMMETRY_TOLERANCE = 1e-9
_FIELDS = 37


def covariance_path_for(tum_path: str | os.PathLike[str]) -> str:
    """The covariance file's path that goes with a TUM file's (``x.tum`` -> ``x.cov.txt``)."""
    path = os.fspath(tum_path)
    stem = path[: -len(".tum")] if path.endswith(".tum") else path
    return stem + COVARIANCE_SUFFIX


def format_covariances(trajectory: Trajectory, header: bool = True) -> str:
    """The covariance text of the valid samples of ``trajectory`` (one line each, ending in a newline).

    Raises:
        ValueError: the trajectory carries no covariances.
    """
    if trajectory.covariances is None:
        raise ValueError("the trajectory carries no covariances (Trajectory.covariances is None)")
    lines = [COVARIANCE_HEADER] if header else []
    valid = trajectory.valid
    times = trajectory.times[valid].tolist()
    rows = trajectory.covariances[valid].reshape(-1, 36).tolist()
    for t, row in zip(times, rows):
        lines.append(" ".join([repr(t)] + [repr(v) for v in row]))
    return "\n".join(lines) + "\n" if lines else ""


def write_covariances(path: str | os.PathLike[str], trajectory: Trajectory, header: bool = True) -> None:
    """Write the covariances of the valid samples of ``trajectory`` to ``path``, atomically.

    Raises:
        ValueError: the trajectory carries no covariances.
    """
    atomic_write_text(path, format_covariances(trajectory, header))


def read_covariances(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Read a covariance file: ``(n,)`` times (s) and ``(n, 6, 6)`` covariances (see the module docstring).

    Fields may be separated by spaces, tabs or commas.

    Raises:
        ValueError: a malformed line: not 37 values, not a number, an infinite
            value, a NaN time, a covariance partly NaN, a negative variance, an
            asymmetric covariance, or a timestamp not after the previous one;
            the message names the file and the 1-based line number.
    """
    name = os.fspath(path)
    rows: list[list[float]] = []
    for lineno, values in read_timed_rows(path, _FIELDS, "'timestamp' and 36 covariance entries"):
        if any(math.isinf(v) for v in values):
            raise ValueError(f"{name}:{lineno}: infinite value")
        cov = np.array(values[1:]).reshape(6, 6)
        nans = np.isnan(cov)
        if nans.any() and not nans.all():
            raise ValueError(f"{name}:{lineno}: a covariance is either all nan (unknown) or has no nan")
        if not nans.any():
            if (np.diag(cov) < 0.0).any():
                raise ValueError(f"{name}:{lineno}: negative variance on the diagonal")
            if np.abs(cov - cov.T).max() > _SYMMETRY_TOLERANCE * np.abs(cov).max():
                raise ValueError(f"{name}:{lineno}: the covariance is not symmetric")
        rows.append(values)
    if not rows:
        return np.empty(0), np.empty((0, 6, 6))
    data = np.array(rows)
    return data[:, 0].copy(), data[:, 1:].reshape(-1, 6, 6)


def read_tum_with_covariances(tum_path: str | os.PathLike[str], covariance_path: str | os.PathLike[str] | None = None) -> Trajectory:
    """A TUM file and its covariance file read into one :class:`Trajectory` with covariances.

    ``covariance_path`` defaults to :func:`covariance_path_for` ``(tum_path)``.

    Raises:
        ValueError: either file is malformed, or the two do not hold the same
            timestamps, line for line (the message names the first mismatch).
    """
    cov_path = covariance_path_for(tum_path) if covariance_path is None else covariance_path
    trajectory = read_tum(tum_path)
    times, covariances = read_covariances(cov_path)
    if times.shape != trajectory.times.shape:
        raise ValueError(
            f"{os.fspath(cov_path)} has {times.shape[0]} samples but {os.fspath(tum_path)} has {len(trajectory)}; "
            "they must hold the same timestamps"
        )
    mismatch = times != trajectory.times
    if mismatch.any():
        k = int(np.argmax(mismatch))
        raise ValueError(
            f"{os.fspath(cov_path)}: sample {k} has timestamp {times[k]!r} but {os.fspath(tum_path)} has {trajectory.times[k]!r}"
        )
    return trajectory.with_covariances(covariances)
