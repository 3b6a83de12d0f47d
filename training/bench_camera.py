"""Micro-benchmark of the geometric camera: microseconds per ``GeometricCamera.measure`` call.

The scene is the paper's top view: a downward UAV camera at 1.8 m (slightly
tilted, its pose varying from call to call) above ``n_boards`` face-up boards on
robots 0.4 m high, all in view. Board views and camera poses are built before
timing; only ``measure`` is timed, one ``time.perf_counter`` pair per call.

Run ``python -m training.bench_camera`` (or ``python training/bench_camera.py``)
from the repository root to print the table for 1, 2 and 4 boards.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time

import numpy as np

from moma_env.camera import PNP_METHODS, BoardView, CameraConfig, GeometricCamera, up_in_board
from moma_env.geometry import R_BODY_BOARD_UP, R_BODY_CAM_DOWN, make_transform, rot_x, rot_y, se2_to_se3
from moma_env.markers import board_for_robot

__all__ = ["bench_camera"]

#: Planar offsets (m) and yaws (rad) of up to 8 boards around the point under the camera.
_BOARD_SLOTS = (
    (0.35, 0.25, 0.3),
    (-0.35, -0.2, 2.0),
    (0.3, -0.35, -1.2),
    (-0.3, 0.3, 3.0),
    (0.0, 0.55, 0.8),
    (0.0, -0.6, -2.4),
    (0.6, 0.0, 1.5),
    (-0.6, 0.0, -0.4),
)
_BOARD_HEIGHT_M = 0.4
_ALTITUDE_M = 1.8
#: Number of distinct camera poses cycled through (so no call sees the exact same scene twice in a row).
_N_POSES = 64


def _scene(n_boards: int, rng: np.random.Generator) -> tuple[list[np.ndarray], list[BoardView]]:
    boards = []
    for i, (x, y, yaw) in enumerate(_BOARD_SLOTS[:n_boards]):
        T_w_m = se2_to_se3(x, y, yaw, _BOARD_HEIGHT_M) @ make_transform(R_BODY_BOARD_UP)
        boards.append(BoardView(i, board_for_robot(i), T_w_m, up_in_board(make_transform(R_BODY_BOARD_UP))))
    poses = []
    for _ in range(_N_POSES):
        x, y = rng.uniform(-0.05, 0.05, 2)
        yaw = rng.uniform(-math.pi, math.pi)
        roll, pitch = rng.uniform(-0.08, 0.08, 2)
        T_w_b = se2_to_se3(x, y, yaw, _ALTITUDE_M) @ make_transform(rot_x(roll) @ rot_y(pitch))
        poses.append(T_w_b @ make_transform(R_BODY_CAM_DOWN))
    return poses, boards


def bench_camera(
    n_boards: int,
    iters: int,
    *,
    pnp_method: str | None = None,
    noise_px: float = 0.5,
    seed: int = 0,
) -> dict[str, float | int | str]:
    """Time ``iters`` calls of ``GeometricCamera.measure`` with ``n_boards`` boards in view.

    Args:
        n_boards: number of boards in the scene, 1 to 8 (all visible).
        iters: number of timed calls (>= 1), after 20 untimed warm-up calls.
        pnp_method: the camera's ``pnp_method`` (``None``: the config default).
        noise_px: corner noise std (px).
        seed: seed of the scene's camera poses and of the pixel noise.

    Returns:
        ``{"n_boards", "iters", "pnp_method", "median_us", "mean_us", "min_us",
        "detections_per_call"}`` (times in microseconds per call).
    """
    if not 1 <= n_boards <= len(_BOARD_SLOTS):
        raise ValueError(f"n_boards must be in 1..{len(_BOARD_SLOTS)}, got {n_boards}")
    if iters < 1:
        raise ValueError(f"iters must be >= 1, got {iters}")
    options = {} if pnp_method is None else {"pnp_method": pnp_method}
    config = CameraConfig(noise_px=noise_px, **options)
    camera = GeometricCamera("bench", config)
    rng = np.random.default_rng(seed)
    poses, boards = _scene(n_boards, rng)
    for k in range(20):
        camera.measure(poses[k % _N_POSES], boards, 0.0, rng)
    times = []
    n_detections = 0
    clock = time.perf_counter
    for k in range(iters):
        T_w_c = poses[k % _N_POSES]
        start = clock()
        dets = camera.measure(T_w_c, boards, 0.0, rng)
        times.append(clock() - start)
        n_detections += len(dets)
    return {
        "n_boards": n_boards,
        "iters": iters,
        "pnp_method": config.pnp_method,
        "median_us": 1e6 * statistics.median(times),
        "mean_us": 1e6 * statistics.fmean(times),
        "min_us": 1e6 * min(times),
        "detections_per_call": n_detections / iters,
    }


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _noise(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def main(argv: list[str] | None = None) -> int:
    """Print microseconds per ``measure`` call for 1, 2 and 4 boards."""
    parser = argparse.ArgumentParser(description="Micro-benchmark of GeometricCamera.measure.")
    parser.add_argument("--iters", type=_positive_int, default=5000, help="timed calls per row (default 5000)")
    parser.add_argument(
        "--pnp-method", choices=PNP_METHODS, default=None, help="camera pnp_method (default: the config default)"
    )
    parser.add_argument("--noise-px", type=_noise, default=0.5, help="corner noise std in px (default 0.5)")
    args = parser.parse_args(argv)
    print(f"{'boards':>6} {'method':>10} {'median us':>10} {'mean us':>9} {'min us':>8} {'dets/call':>9}")
    for n in (1, 2, 4):
        r = bench_camera(n, args.iters, pnp_method=args.pnp_method, noise_px=args.noise_px)
        print(
            f"{r['n_boards']:>6} {r['pnp_method']:>10} {r['median_us']:>10.1f} {r['mean_us']:>9.1f} "
            f"{r['min_us']:>8.1f} {r['detections_per_call']:>9.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
