"""The paper preset's grainy floor against a perfectly plain one, three checks.

    python -m training.experiments.floor_check [--json] [--cost-frames 60] [--vo-frames 30] [--detection-seeds 15] ...

prints three Markdown tables for the square under
:data:`training.experiments.presets.PAPER` (``docs/paper_preset.md``):

1. **Frame cost** (:func:`frame_cost`): wall time of one rendered observer frame
   (``CameraBackend.measure``: render, detect, PnP) on each floor, a moving
   camera with both boards in view; the floors alternate frame by frame (the
   order swapped every frame) so that a busy machine slows both alike, and the
   ratio grain / plain is the median of the per-frame ratios.
2. **What the VO finds** (:func:`vo_features`): on frames of the main robot's
   floor camera over the square's third side, how many features the VO's
   detector (``cv2.goodFeaturesToTrack`` with the VO's settings) returns with a
   corner response at or above the VO's threshold, the strongest response and
   the 15th strongest (the VO needs 15 inliers per frame).
3. **Detection error** (:func:`detection_errors`): position error and depth bias
   of the rendered observer's detections of a board 2.1 m below it, over a few
   poses and noise seeds.

Frames: W is the world (floor z = 0, z up, m); C a camera frame (OpenCV axes:
x right, y down, z along the optical axis); B a robot's body frame (origin on
the floor, x forward). Every random draw comes from a seeded numpy Generator.
The plain floor is the same configuration with ``FloorConfig.grain`` None.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Sequence

import cv2
import numpy as np

from moma_env.camera import BoardView, CameraBackend, FloorCamera, FloorTexture, make_camera
from moma_env.geometry import R_BODY_CAM_DOWN, invert, make_transform, rot_z
from moma_env.markers import board_for_robot
from moma_env.odometry import VisualOdometryConfig
from moma_env.odometry.visual import corner_response
from training.experiments.leapfrog_run import floor_texture
from training.experiments.presets import PAPER
from training.experiments.square import SquareConfig

__all__ = [
    "DETECTION_POSES",
    "FLOORS",
    "FloorCheckConfig",
    "detection_errors",
    "format_detection_table",
    "format_frame_cost_table",
    "format_vo_table",
    "frame_cost",
    "frame_features",
    "main",
    "observer_floors",
    "timed_observer_floors",
    "paper_square_config",
    "run_floor_check",
    "vo_features",
]

#: The two floors compared, in table order.
FLOORS = ("grain", "plain")

#: Main robot poses ``(x, y, yaw)`` in W (m, m, rad) of the detection check; the
#: second board is 0.6 m to its left, the observer 2.5 m up between them.
DETECTION_POSES: tuple[tuple[float, float, float], ...] = ((1.0, 0.5, 0.3), (1.0, 0.1, 1.2), (0.6, 0.0, 2.0), (0.95, 0.8, -0.7))

#: Height of the boards' centres above the floor (m), as on the robots.
_BOARD_Z = 0.4
#: Height of the observer camera (m): the preset's altitude.
_OBSERVER_Z = 2.5


@dataclasses.dataclass(frozen=True)
class FloorCheckConfig:
    """Counts and seeds of the three checks (defaults: those quoted in ``docs/paper_preset.md``).

    Attributes:
        cost_frames: observer frames timed per floor (>= 2).
        cost_warmup: first frames left out of the medians (caches, JIT), < ``cost_frames``.
        vo_frames: floor camera frames per floor (>= 1).
        vo_position_seed: seed of the floor camera's positions.
        noise_seed: seed of the sensor noise (each floor gets its own Generator of this seed).
        detection_poses: how many of :data:`DETECTION_POSES` to use (1-4).
        detection_seeds: noise seeds 0..n-1 per pose (>= 1).
    """

    cost_frames: int = 60
    cost_warmup: int = 5
    vo_frames: int = 30
    vo_position_seed: int = 5
    noise_seed: int = 0
    detection_poses: int = 4
    detection_seeds: int = 15

    def __post_init__(self) -> None:
        if self.cost_frames < 2 or not 0 <= self.cost_warmup < self.cost_frames:
            raise ValueError(f"need cost_frames >= 2 and 0 <= cost_warmup < cost_frames, got {self.cost_frames}, {self.cost_warmup}")
        if self.vo_frames < 1 or self.detection_seeds < 1:
            raise ValueError(f"vo_frames and detection_seeds must be >= 1, got {self.vo_frames}, {self.detection_seeds}")
        if not 1 <= self.detection_poses <= len(DETECTION_POSES):
            raise ValueError(f"detection_poses must be in 1..{len(DETECTION_POSES)}, got {self.detection_poses}")
        if self.vo_position_seed < 0 or self.noise_seed < 0:
            raise ValueError("seeds must be >= 0")


# ----------------------------------------------------------------- set-up


def paper_square_config() -> SquareConfig:
    """The square under the paper preset (grainy floor, rendered PAL observer)."""
    return PAPER.apply(SquareConfig())


def observer_floors(config: SquareConfig) -> dict[str, FloorTexture]:
    """The floors of a run of ``config``: ``"grain"`` as configured, ``"plain"`` with ``floor.grain`` None.

    Each is :func:`training.experiments.leapfrog_run.floor_texture` of its
    configuration: what the observer and the main robot's floor camera see in a
    run (the plain floor's raster spans the textured regions only; outside
    them it is one gray level).
    """
    return timed_observer_floors(config)[0]


def timed_observer_floors(config: SquareConfig) -> tuple[dict[str, FloorTexture], dict[str, float]]:
    """:func:`observer_floors` and the wall time (s) each floor took to build (its raster drawn once per run)."""
    plain = dataclasses.replace(config, floor=dataclasses.replace(config.floor, grain=None))
    floors, seconds = {}, {}
    for name, floor_config in (("grain", config), ("plain", plain)):
        start = time.perf_counter()
        floors[name] = floor_texture(floor_config)
        seconds[name] = time.perf_counter() - start
    return floors, seconds


def _boards(config: SquareConfig, T_w_m0: np.ndarray, T_w_m1: np.ndarray) -> list[BoardView]:
    """The two robots' boards (``config.board``'s layout) at ``T_w_m0``, ``T_w_m1`` (4x4, M in W)."""
    layout = {"marker_size": config.board.marker_size, "gap": config.board.gap, "dictionary": config.board.dictionary}
    return [BoardView(0, board_for_robot(0, **layout), T_w_m0), BoardView(1, board_for_robot(1, **layout), T_w_m1)]


def _observer(config: SquareConfig, floor: FloorTexture) -> CameraBackend:
    """The preset's rendered observer camera over ``floor``."""
    return make_camera("uav", config.camera, backend="rendered", render=config.render, floor=floor)


# ------------------------------------------------------------ 1. frame cost


def frame_cost(config: SquareConfig, floors: dict[str, FloorTexture], frames: int = 60, warmup: int = 5, seed: int = 0) -> dict:
    """Wall time of one rendered observer frame on each floor, timed interleaved.

    The camera (``R_BODY_CAM_DOWN``, 2.5 m up) moves 2 mm per frame along x of
    W from (0.25, 0.55), at 25 frames/s, over two boards 0.4 m up at (0.5, 0.5)
    and (0.0, 0.6); frame k is timed on every floor back to back, in an order
    that alternates with k. Each floor's camera has its own Generator of
    ``seed``, so both draw the same noise.

    Returns:
        ``{"frames": n, "median_ms": {floor: ms}, "ratio": r}``: n = ``frames -
        warmup`` frames counted; the median wall time per frame (ms); r the
        median over the counted frames of time(grain) / time(plain) of the same
        frame (floors named as in ``floors``, which must hold "grain" and "plain").
    """
    cameras = {name: _observer(config, floor) for name, floor in floors.items()}
    rngs = {name: np.random.default_rng(seed) for name in floors}
    boards = _boards(config, make_transform(np.eye(3), [0.5, 0.5, _BOARD_Z]), make_transform(np.eye(3), [0.0, 0.6, _BOARD_Z]))
    names = list(floors)
    times: dict[str, list[float]] = {name: [] for name in names}
    for k in range(frames):
        T_w_c = make_transform(R_BODY_CAM_DOWN, [0.25 + 0.002 * k, 0.55, _OBSERVER_Z])
        for name in names if k % 2 == 0 else names[::-1]:
            start = time.perf_counter()
            cameras[name].measure(T_w_c, boards, 0.04 * k, rngs[name])
            times[name].append(time.perf_counter() - start)
    counted = {name: np.array(t[warmup:]) for name, t in times.items()}
    return {
        "frames": frames - warmup,
        "median_ms": {name: 1000.0 * float(np.median(t)) for name, t in counted.items()},
        "ratio": float(np.median(counted["grain"] / counted["plain"])),
    }


# ------------------------------------------------------- 2. what the VO finds


def frame_features(image: np.ndarray, tracking: VisualOdometryConfig) -> np.ndarray:
    """Corner responses ((gray levels / px)^2) of the features the VO's detector finds in ``image``, strongest first.

    The features are ``cv2.goodFeaturesToTrack`` with the VO's ``max_features``,
    ``quality_level``, ``min_distance_px`` and ``block_size`` on the whole image
    (a fresh detection); each one's response is :func:`corner_response` at its
    rounded pixel. An empty array if none.
    """
    corners = cv2.goodFeaturesToTrack(
        image, tracking.max_features, tracking.quality_level, tracking.min_distance_px, blockSize=tracking.block_size
    )
    if corners is None:
        return np.empty(0)
    uv = np.rint(corners.reshape(-1, 2)).astype(int)
    return np.sort(corner_response(image, tracking.block_size)[uv[:, 1], uv[:, 0]])[::-1]


def vo_features(config: SquareConfig, floor: FloorTexture, frames: int = 30, position_seed: int = 5, noise_seed: int = 0) -> dict:
    """What the main robot's floor camera (``config.vo``) finds on ``floor`` over the square's third side.

    The robot heads -y of W (the third side, from (1, 1) to (1, 0)) at positions
    drawn uniformly in x 0.75-1.05 m, y -0.1-0.6 m (Generator of
    ``position_seed``); the sensor noise comes from a Generator of ``noise_seed``.

    Returns:
        ``{"frames", "threshold", "strong", "best", "fifteenth"}``: the VO's
        ``min_corner_response`` ((gray levels / px)^2) and, per frame, the number
        of features at or above it, the strongest feature's response and the
        15th strongest's (NaN if fewer than 15 features), see :func:`frame_features`.
    """
    tracking = config.vo.tracking
    camera = FloorCamera(config.vo.camera, config.vo.T_b_c, floor, config.vo.render)
    rng, where = np.random.default_rng(noise_seed), np.random.default_rng(position_seed)
    heading_minus_y = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # rot_z(-pi/2), exact
    strong, best, fifteenth = [], [], []
    for _ in range(frames):
        x, y = where.uniform(0.75, 1.05), where.uniform(-0.1, 0.6)
        responses = frame_features(camera.frame(make_transform(heading_minus_y, [x, y, 0.0]), rng), tracking)
        strong.append(int(np.count_nonzero(responses >= tracking.min_corner_response)))
        best.append(float(responses[0]) if len(responses) else float("nan"))
        fifteenth.append(float(responses[14]) if len(responses) >= 15 else float("nan"))
    return {"frames": frames, "threshold": float(tracking.min_corner_response), "strong": strong, "best": best, "fifteenth": fifteenth}


# --------------------------------------------------------- 3. detection error


def detection_errors(config: SquareConfig, floor: FloorTexture, poses: Sequence[tuple[float, float, float]] = DETECTION_POSES, seeds: int = 15) -> dict:
    """Error of the rendered observer's detections of the main robot's board on ``floor``.

    For each main robot pose ``(x, y, yaw)`` (m, m, rad in W): its board 0.4 m up
    at (x, y) turned by yaw, the second robot's 0.6 m to its left, the camera
    (``R_BODY_CAM_DOWN``) 2.5 m up, 0.3 m to the main robot's left plus (+3, -2)
    cm in W: the board 2.1 m below it. Each of ``seeds`` noise seeds renders one
    frame (time 1 s) with a fresh camera and a Generator of the seed.

    Returns:
        ``{"detections": n, "mean_position_error_m", "depth_bias_m"}``: over the
        n detections of the main robot's board, the mean norm of the error of
        ``T_c_m``'s translation and the mean error of its z (along the optical
        axis, positive = too far), in m, both in C.
    """
    errors, depth = [], []
    for x, y, yaw in poses:
        left = np.array([-np.sin(yaw), np.cos(yaw)])
        T_w_m = make_transform(rot_z(yaw), [x, y, _BOARD_Z])
        T_w_m1 = make_transform(rot_z(yaw), [x + 0.6 * left[0], y + 0.6 * left[1], _BOARD_Z])
        T_w_c = make_transform(R_BODY_CAM_DOWN, [x + 0.3 * left[0] + 0.03, y + 0.3 * left[1] - 0.02, _OBSERVER_Z])
        t_true = (invert(T_w_c) @ T_w_m)[:3, 3]
        boards = _boards(config, T_w_m, T_w_m1)
        for seed in range(seeds):
            for detection in _observer(config, floor).measure(T_w_c, boards, 1.0, np.random.default_rng(seed)):
                if detection.board_id == 0:
                    errors.append(float(np.linalg.norm(detection.T_c_m[:3, 3] - t_true)))
                    depth.append(float(detection.T_c_m[2, 3] - t_true[2]))
    nan = float("nan")
    return {
        "detections": len(errors),
        "mean_position_error_m": float(np.mean(errors)) if errors else nan,
        "depth_bias_m": float(np.mean(depth)) if depth else nan,
    }


# ------------------------------------------------------------------ all three


def run_floor_check(check: FloorCheckConfig | None = None, config: SquareConfig | None = None) -> dict:
    """The three checks on both floors of ``config`` (default :func:`paper_square_config`).

    Returns ``{"settings", "rasters", "frame_cost", "vo", "detections"}``: the
    settings (``check``'s fields); per floor its raster's size (Mpx) and the
    wall time to build it (s, :func:`timed_observer_floors`);
    :func:`frame_cost`'s result; and per floor
    :func:`vo_features`'s and :func:`detection_errors`' results.
    """
    check = check or FloorCheckConfig()
    config = config or paper_square_config()
    floors, build_s = timed_observer_floors(config)
    poses = DETECTION_POSES[: check.detection_poses]
    return {
        "settings": dataclasses.asdict(check),
        "rasters": {name: {"megapixels": floor.raster.size / 1e6, "build_s": build_s[name]} for name, floor in floors.items()},
        "frame_cost": frame_cost(config, floors, check.cost_frames, check.cost_warmup, check.noise_seed),
        "vo": {
            name: vo_features(config, floor, check.vo_frames, check.vo_position_seed, check.noise_seed)
            for name, floor in floors.items()
        },
        "detections": {name: detection_errors(config, floor, poses, check.detection_seeds) for name, floor in floors.items()},
    }


# ----------------------------------------------------------------- tables

_LABELS = {"grain": "grain (paper preset)", "plain": "perfectly plain"}


def format_frame_cost_table(result: dict, warmup: int, rasters: dict[str, dict] | None = None) -> str:
    """Markdown table of :func:`frame_cost`'s ``result`` (``warmup``: the frames left out), with each
    floor's raster (Mpx, build time in s) if ``rasters`` (as :func:`run_floor_check`'s) is given."""
    n = result["frames"]
    raster_head, raster_sep = (" raster, Mpx | raster drawn in, s |", "---|---|") if rasters else ("", "")
    lines = [f"| floor |{raster_head} ms per observer frame (median of frames {warmup + 1}-{warmup + n}) |", f"|---|{raster_sep}---|"]
    for name, ms in result["median_ms"].items():
        raster = f" {rasters[name]['megapixels']:.2f} | {rasters[name]['build_s']:.2f} |" if rasters else ""
        lines.append(f"| {_LABELS.get(name, name)} |{raster} {ms:.1f} |")
    lines.append(f"| grain / plain (median of the {n} per-frame ratios) |{' | |' if rasters else ''} {result['ratio']:.3f} |")
    return "\n".join(lines)


def format_vo_table(results: dict[str, dict]) -> str:
    """Markdown table of :func:`vo_features`' results per floor."""
    threshold = next(iter(results.values()))["threshold"]
    lines = [
        f"| floor | features >= {threshold:g} per frame (mean, max) | strongest response (median, max) | 15th strongest (median) |",
        "|---|---|---|---|",
    ]
    for name, r in results.items():
        lines.append(
            f"| {_LABELS.get(name, name)} | {np.mean(r['strong']):.1f}, {max(r['strong'])} | "
            f"{np.nanmedian(r['best']):.1f}, {np.nanmax(r['best']):.1f} | {np.nanmedian(r['fifteenth']):.1f} |"
        )
    return "\n".join(lines)


def format_detection_table(results: dict[str, dict]) -> str:
    """Markdown table of :func:`detection_errors`' results per floor (cm)."""
    lines = ["| floor | detections | mean position error, cm | depth bias, cm |", "|---|---|---|---|"]
    for name, r in results.items():
        lines.append(
            f"| {_LABELS.get(name, name)} | {r['detections']} | {100 * r['mean_position_error_m']:.3f} | {100 * r['depth_bias_m']:+.3f} |"
        )
    return "\n".join(lines)


def _markdown(result: dict) -> str:
    s = result["settings"]
    return "\n\n".join(
        [
            f"Observer frame cost, moving camera, both boards in view, floors interleaved:\n\n"
            f"{format_frame_cost_table(result['frame_cost'], s['cost_warmup'], result['rasters'])}",
            f"What the VO's floor camera finds over the square's third side ({s['vo_frames']} frames, "
            f"positions seed {s['vo_position_seed']}, noise seed {s['noise_seed']}), responses in (gray levels/px)^2:\n\n"
            f"{format_vo_table(result['vo'])}",
            f"Rendered detections of a board 2.1 m below the observer ({s['detection_poses']} poses x "
            f"{s['detection_seeds']} noise seeds):\n\n{format_detection_table(result['detections'])}",
        ]
    )


def _jsonable(obj: object) -> object:
    """``obj`` with NaN as None (strict JSON)."""
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, float) and obj != obj:
        return None
    return obj


def main(argv: Sequence[str] | None = None) -> int:
    """Run the three checks and print their tables (or, with ``--json``, the results as JSON)."""
    defaults = FloorCheckConfig()
    parser = argparse.ArgumentParser(prog="python -m training.experiments.floor_check", description=__doc__.split("\n\n")[0])
    parser.add_argument("--cost-frames", type=int, default=defaults.cost_frames, help=f"observer frames timed per floor (default {defaults.cost_frames})")
    parser.add_argument("--cost-warmup", type=int, default=defaults.cost_warmup, help=f"first frames not counted (default {defaults.cost_warmup})")
    parser.add_argument("--vo-frames", type=int, default=defaults.vo_frames, help=f"floor camera frames per floor (default {defaults.vo_frames})")
    parser.add_argument("--vo-position-seed", type=int, default=defaults.vo_position_seed, help=f"seed of the floor camera's positions (default {defaults.vo_position_seed})")
    parser.add_argument("--noise-seed", type=int, default=defaults.noise_seed, help=f"seed of the sensor noise (default {defaults.noise_seed})")
    parser.add_argument("--detection-poses", type=int, default=defaults.detection_poses, help=f"poses of the detection check, 1-4 (default {defaults.detection_poses})")
    parser.add_argument("--detection-seeds", type=int, default=defaults.detection_seeds, help=f"noise seeds per pose (default {defaults.detection_seeds})")
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of tables")
    args = parser.parse_args(argv)
    try:
        check = FloorCheckConfig(
            cost_frames=args.cost_frames,
            cost_warmup=args.cost_warmup,
            vo_frames=args.vo_frames,
            vo_position_seed=args.vo_position_seed,
            noise_seed=args.noise_seed,
            detection_poses=args.detection_poses,
            detection_seeds=args.detection_seeds,
        )
    except ValueError as error:
        parser.error(str(error))
    result = run_floor_check(check)
    print(json.dumps(_jsonable(result), indent=2, allow_nan=False) if args.json else _markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
