"""Trajectories in the TUM RGB-D text format, readable by evo and similar tools.

One pose per line: ``timestamp tx ty tz qx qy qz qw`` (seconds, metres, unit
quaternion of the rotation of ``T_w_b``, scalar last). Lines starting with
``#`` and blank lines are comments. Values are written with Python's shortest
round-trip float representation (``repr``), so a written-then-read trajectory
has bit-identical times and positions and rotations equal to round-off
(quaternion <-> matrix). Invalid samples (NaN poses) are not written.
"""

from __future__ import annotations

import math
import os

import numpy as np

from moma_env.geometry import matrix_to_quaternion
from moma_env.io import atomic_write_text
from moma_env.metrics.trajectory import Trajectory

__all__ = ["TUM_HEADER", "format_tum", "write_tum", "read_tum", "read_timed_rows", "quaternions_to_matrices"]

#: Comment line written at the top of a TUM file.
TUM_HEADER = "# timestamp tx ty tz qx qy qz qw"


def format_tum(trajectory: Trajectory, header: bool = True) -> str:
    """The TUM text of the valid samples of ``trajectory`` (one line each, ending in a newline)."""
    lines = [TUM_HEADER] if header else []
    valid = trajectory.valid
    times = trajectory.times[valid].tolist()
    positions = trajectory.positions[valid].tolist()
    for t, (x, y, z), T in zip(times, positions, trajectory.poses[valid]):
        qx, qy, qz, qw = matrix_to_quaternion(T).tolist()
        lines.append(f"{t!r} {x!r} {y!r} {z!r} {qx!r} {qy!r} {qz!r} {qw!r}")
    return "\n".join(lines) + "\n" if lines else ""


def write_tum(path: str | os.PathLike[str], trajectory: Trajectory, header: bool = True) -> None:
    """Write the valid samples of ``trajectory`` to ``path`` in TUM format, atomically."""
    atomic_write_text(path, format_tum(trajectory, header))


def quaternions_to_matrices(q: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotation matrices of ``(n, 4)`` quaternions ``(qx, qy, qz, qw)``.

    The quaternions are normalised first; they must be non-zero.
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    R = np.empty((q.shape[0], 3, 3))
    R[:, 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[:, 0, 1] = 2.0 * (x * y - z * w)
    R[:, 0, 2] = 2.0 * (x * z + y * w)
    R[:, 1, 0] = 2.0 * (x * y + z * w)
    R[:, 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[:, 1, 2] = 2.0 * (y * z - x * w)
    R[:, 2, 0] = 2.0 * (x * z - y * w)
    R[:, 2, 1] = 2.0 * (y * z + x * w)
    R[:, 2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return R


def read_timed_rows(path: str | os.PathLike[str], n_fields: int, layout: str) -> list[tuple[int, list[float]]]:
    """The data lines of a text file of timestamped rows, as ``(line number, values)``.

    Lines are fields separated by spaces, tabs or commas; blank lines and lines
    starting with ``#`` are skipped. Every data line must hold ``n_fields``
    numbers (``layout`` names them in the error), the first a finite timestamp
    after the previous line's. Other checks are the caller's.

    Raises:
        ValueError: naming the file and the 1-based line number.
    """
    name = os.fspath(path)
    rows: list[tuple[int, list[float]]] = []
    last_time = -math.inf
    with open(path, encoding="utf-8") as f:
        for lineno, line in enumerate(f, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            fields = text.replace(",", " ").split()
            if len(fields) != n_fields:
                raise ValueError(f"{name}:{lineno}: expected {n_fields} values {layout}, got {len(fields)}")
            try:
                values = [float(v) for v in fields]
            except ValueError:
                raise ValueError(f"{name}:{lineno}: not a number in {text!r}") from None
            if not math.isfinite(values[0]):
                raise ValueError(f"{name}:{lineno}: the timestamp must be finite, got {fields[0]!r}")
            if not values[0] > last_time:
                raise ValueError(f"{name}:{lineno}: timestamp {values[0]!r} is not after the previous one {last_time!r}")
            last_time = values[0]
            rows.append((lineno, values))
    return rows


def read_tum(path: str | os.PathLike[str]) -> Trajectory:
    """Read a TUM trajectory file (fields separated by spaces, tabs or commas).

    Raises:
        ValueError: a malformed line (not 8 numbers, a non-finite value, a zero
            quaternion, a timestamp not after the previous one); the message
            names the file and the 1-based line number.
    """
    name = os.fspath(path)
    rows: list[list[float]] = []
    for lineno, values in read_timed_rows(path, 8, "'timestamp tx ty tz qx qy qz qw'"):
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"{name}:{lineno}: non-finite value in {values!r}")
        if math.hypot(*values[4:]) < 1e-9:
            raise ValueError(f"{name}:{lineno}: zero quaternion")
        rows.append(values)
    if not rows:
        return Trajectory.empty()
    data = np.array(rows)
    poses = np.zeros((data.shape[0], 4, 4))
    poses[:, :3, :3] = quaternions_to_matrices(data[:, 4:])
    poses[:, :3, 3] = data[:, 1:4]
    poses[:, 3, 3] = 1.0
    return Trajectory(data[:, 0], poses)
