"""Calibrate the rendered camera's board-shift error model against the truth.

    python -m training.experiments.rendered_calibration [--seeds 10 11] [--window 25] [--preset paper] [--json]

runs the square (``--experiment``, under ``--preset``, rendered camera) and,
at every frame, compares each detection's ``T_c_m`` with the true pose of the
board in the camera (the backend is given the true poses to draw the image;
a recording wrapper keeps them beside the detections). The camera's board
shift is switched off for the run, so the covariance recorded is that of the
PnP (independent corner noise, ``sigma`` from the residuals); the shift adds
nothing to the poses, so the run is otherwise the same.

The fit (:func:`fit_board_shift`) works on the lateral errors (x and y of C,
where a shift of the board's image moves it), in pixels at the board's depth
``z`` (``u = e_x fx / z``, ``v = e_y fy / z``):

* **shift** ``sigma^2 = mean((u^2 + v^2) / 2) - mean((r_u + r_v) / 2)`` (at
  least 0): the per-frame variance the PnP covariance (``r_u = C_xx (fx / z)^2``,
  ``r_v`` likewise) leaves unexplained;
* **persistence** ``rho``: over blocks of ``window`` consecutive frames in
  which the board stands still in W (its true pose moves less than
  ``still_m`` from frame to frame), the variance of the block means
  ``s_w = mean((u_mean^2 + v_mean^2) / 2)`` against the model's
  ``r_w / n + sigma^2 (rho + (1 - rho) / n)`` (``r_w`` the blocks' mean PnP
  variance): ``rho = (s_w - r_w / n - sigma^2 / n) / (sigma^2 (1 - 1 / n))``,
  clipped to [0, 1].

It also reports, for information, the NEES of the lateral errors per frame
and per block under the PnP covariance alone and under the fitted model.

Frames: C is the camera frame (OpenCV: x right, y down, z along the optical
axis); errors are ``e = (dt, dtheta)`` with ``T_true = [exp([dtheta]x) R, t + dt]``
(:func:`moma_env.estimator.uncertainty.pose_error`), m and rad.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.camera import make_camera
from moma_env.estimator.uncertainty import pose_error
from moma_env.geometry import invert
from training.experiments.leapfrog_run import LeapfrogConfig, run_leapfrog
from training.experiments.line import LineConfig
from training.experiments.presets import get_preset
from training.experiments.square import SquareConfig

__all__ = ["DetectionRecords", "ShiftFit", "fit_board_shift", "record_detections", "calibration_config", "main"]

#: Experiments the calibration can run, by name.
EXPERIMENTS: dict[str, type[LeapfrogConfig]] = {"square": SquareConfig, "line": LineConfig}


@dataclass(frozen=True)
class DetectionRecords:
    """Rendered detections beside the truth, one row per detection, in time order per run and board.

    Attributes:
        run: (n,) index of the run (a block of still frames never spans two runs).
        board: (n,) board id.
        time: (n,) time of the frame (s).
        error: (n, 6) error of ``T_c_m`` (m, rad; see the module docstring).
        covariance: (n, 6, 6) the detection's reported covariance (camera frame).
        depth: (n,) true depth of the board's origin in C (m).
        board_world: (n, 3) true position of the board in W (m), to tell still boards.
    """

    run: np.ndarray
    board: np.ndarray
    time: np.ndarray
    error: np.ndarray
    covariance: np.ndarray
    depth: np.ndarray
    board_world: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.board)
        shapes = {"run": (n,), "time": (n,), "error": (n, 6), "covariance": (n, 6, 6), "depth": (n,), "board_world": (n, 3)}
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"records.{name} must have shape {shape}, got {np.shape(getattr(self, name))}")

    @staticmethod
    def concatenate(parts: Sequence[DetectionRecords]) -> DetectionRecords:
        """The rows of every part, in order; part k's runs are renumbered after those of the parts before it."""
        if not parts:
            raise ValueError("concatenate needs at least one part")
        fields = [f.name for f in dataclasses.fields(DetectionRecords) if f.name != "run"]
        runs, offset = [], 0
        for p in parts:
            runs.append(p.run + offset)
            offset += int(p.run.max()) + 1 if len(p.run) else 0
        return DetectionRecords(run=np.concatenate(runs), **{name: np.concatenate([getattr(p, name) for p in parts]) for name in fields})


@dataclass(frozen=True)
class ShiftFit:
    """The fitted board shift and what it explains.

    Attributes:
        sigma_px: std of the board shift in u and in v (px).
        persistence: fraction of its variance persistent over a window, in [0, 1].
        n_frames: detections used for ``sigma_px``.
        n_windows: still blocks of ``window`` frames used for ``persistence``.
        window: frames per block.
        error_px: RMS lateral error per frame (px, over u and v).
        pnp_px: RMS lateral std of the PnP covariance (px).
        window_error_px: RMS lateral error of the block means (px).
        nees_frame_pnp, nees_frame_model: mean lateral NEES per frame (2 dof, divided by 2)
            under the PnP covariance alone and with the model.
        nees_window_pnp, nees_window_model: the same for the block means, the
            PnP covariance divided by ``window`` (independent frames) and the
            model's ``r / n + sigma^2 (rho + (1 - rho) / n)``.
        yaw_frame_nees: mean normalised squared yaw error (rotation about z of
            C) per frame under the PnP covariance (the model leaves yaw alone).
        yaw_window_nees: the same for the block means, the PnP variance divided
            by ``window``.
        depth_bias_m: mean depth error (z of C, m; positive: the board is
            nearer than measured, ``T_true = T_est + dt``).
    """

    sigma_px: float
    persistence: float
    n_frames: int
    n_windows: int
    window: int
    error_px: float
    pnp_px: float
    window_error_px: float
    nees_frame_pnp: float
    nees_frame_model: float
    nees_window_pnp: float
    nees_window_model: float
    yaw_frame_nees: float
    yaw_window_nees: float
    depth_bias_m: float


def _still_blocks(records: DetectionRecords, window: int, still_m: float, frame_s: float) -> list[np.ndarray]:
    """Index arrays of ``window`` consecutive frames of one board standing still, not overlapping."""
    blocks = []
    for run, b in sorted({(int(r), int(b)) for r, b in zip(records.run, records.board)}):
        idx = np.flatnonzero((records.run == run) & (records.board == b))
        idx = idx[np.argsort(records.time[idx], kind="stable")]
        run: list[int] = []
        for k, i in enumerate(idx):
            if run:
                j = idx[k - 1]
                consecutive = abs(records.time[i] - records.time[j] - frame_s) <= 0.25 * frame_s
                still = float(np.linalg.norm(records.board_world[i] - records.board_world[j])) <= still_m
                if not (consecutive and still):
                    run = []
            run.append(int(i))
            if len(run) == window:
                blocks.append(np.array(run))
                run = []
    return blocks


def fit_board_shift(
    records: DetectionRecords, fx: float, fy: float, window: int = 25, still_m: float = 5e-4, frame_s: float = 0.04
) -> ShiftFit:
    """Fit the board shift (``sigma_px``) and its persistence to ``records`` (see the module docstring).

    Args:
        records: detections with their truth (covariances without a board shift).
        fx, fy: the camera's focal lengths (px).
        window: frames per still block (the estimator's switch window).
        still_m: largest frame-to-frame motion (m) of a still board's true position.
        frame_s: the frame period (s); frames further apart break a block.

    Raises:
        ValueError: no detection, or no still block of ``window`` frames (naming the argument).
    """
    if len(records.board) == 0:
        raise ValueError("records: no detection to fit")
    if int(window) != window or window < 2:
        raise ValueError(f"window must be an integer >= 2, got {window!r}")
    if not (fx > 0.0 and fy > 0.0):
        raise ValueError(f"fx and fy must be > 0, got {fx!r}, {fy!r}")
    to_px = np.stack([fx / records.depth, fy / records.depth], axis=1)  # (n, 2) px per m
    err = records.error[:, :2] * to_px
    var = np.stack([records.covariance[:, 0, 0], records.covariance[:, 1, 1]], axis=1) * to_px**2
    s_tot = float(np.mean(err**2))
    s_rep = float(np.mean(var))
    sigma2 = max(s_tot - s_rep, 0.0)
    blocks = _still_blocks(records, int(window), still_m, frame_s)
    if not blocks:
        raise ValueError(f"records: no still block of {window} consecutive frames (window, still_m, frame_s)")
    n = int(window)
    means = np.array([err[i].mean(axis=0) for i in blocks])
    rep_w = np.array([var[i].mean(axis=0) for i in blocks])
    s_w = float(np.mean(means**2))
    r_w = float(np.mean(rep_w))
    rho = (s_w - r_w / n - sigma2 / n) / (sigma2 * (1.0 - 1.0 / n)) if sigma2 > 0.0 else 0.0
    rho = min(max(rho, 0.0), 1.0)
    yaw, yaw_var = records.error[:, 5], records.covariance[:, 5, 5]
    yaw_means = np.array([yaw[i].mean() for i in blocks])
    yaw_rep = np.array([yaw_var[i].mean() for i in blocks])
    model_frame = var + sigma2
    model_window = rep_w / n + sigma2 * (rho + (1.0 - rho) / n)
    return ShiftFit(
        sigma_px=math.sqrt(sigma2),
        persistence=rho,
        n_frames=len(records.board),
        n_windows=len(blocks),
        window=n,
        error_px=math.sqrt(s_tot),
        pnp_px=math.sqrt(s_rep),
        window_error_px=math.sqrt(s_w),
        nees_frame_pnp=float(np.mean(err**2 / var)),
        nees_frame_model=float(np.mean(err**2 / model_frame)),
        nees_window_pnp=float(np.mean(means**2 / (rep_w / n))),
        nees_window_model=float(np.mean(means**2 / model_window)),
        yaw_frame_nees=float(np.mean(yaw**2 / yaw_var)),
        yaw_window_nees=float(np.mean(yaw_means**2 / (yaw_rep / n))),
        depth_bias_m=float(np.mean(records.error[:, 2])),
    )


class _Recorder:
    """A camera backend that keeps every detection beside the true pose of its board (this module only)."""

    def __init__(self, inner, rows: list) -> None:
        self._inner = inner
        self._rows = rows

    def __getattr__(self, name: str):
        return getattr(self._inner, name)

    def measure(self, T_w_c, boards, time, rng, occluded=None):
        detections = self._inner.measure(T_w_c, boards, time, rng, occluded)
        T_c_w = invert(np.asarray(T_w_c, dtype=float))
        truth = {b.board_id: b.T_w_m for b in boards}
        for d in detections:
            T_w_m = truth[d.board_id]
            T_true = T_c_w @ T_w_m
            cov = np.full((6, 6), np.nan) if d.covariance is None else d.covariance
            self._rows.append((d.board_id, float(time), pose_error(T_true, d.T_c_m), cov, float(T_true[2, 3]), T_w_m[:3, 3].copy()))
        return detections


def calibration_config(experiment: str = "square", preset: str = "paper") -> LeapfrogConfig:
    """The experiment under ``preset`` with the rendered camera and its board shift off (ValueError / ConfigError naming a bad name)."""
    if experiment not in EXPERIMENTS:
        raise ValueError(f"experiment: unknown experiment {experiment!r}; known: {', '.join(EXPERIMENTS)}")
    config = get_preset(preset).apply(EXPERIMENTS[experiment](), camera_backend="rendered")
    return dataclasses.replace(config, camera=dataclasses.replace(config.camera, board_shift_px=0.0))


def record_detections(config: LeapfrogConfig, seed: int, max_time_s: float | None = None) -> DetectionRecords:
    """One seeded run of ``config`` (rendered) with every observer detection and its truth recorded."""
    if config.camera_backend != "rendered":
        raise ValueError(f"config.camera_backend must be 'rendered', got {config.camera_backend!r}")
    if max_time_s is not None:
        config = dataclasses.replace(config, max_time_s=max_time_s)
    rows: list = []

    def factory(cfg: LeapfrogConfig, name: str, floor):
        return _Recorder(make_camera(name, cfg.camera, backend="rendered", render=cfg.render, floor=floor), rows)

    run_leapfrog(config, seed, camera_factory=factory)
    if not rows:
        return DetectionRecords(
            np.empty(0, int), np.empty(0, int), np.empty(0), np.empty((0, 6)), np.empty((0, 6, 6)), np.empty(0), np.empty((0, 3))
        )
    board, t, err, cov, depth, world = zip(*rows)
    return DetectionRecords(
        np.zeros(len(board), int), np.array(board), np.array(t), np.array(err), np.array(cov), np.array(depth), np.array(world)
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Record the runs, fit the model and print it (or, with ``--json``, the fit as JSON)."""
    parser = argparse.ArgumentParser(prog="python -m training.experiments.rendered_calibration", description=__doc__.split("\n\n")[0])
    parser.add_argument("--experiment", default="square", choices=sorted(EXPERIMENTS), help="experiment run (default square)")
    parser.add_argument("--preset", default="paper", help="experiment preset (default paper)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[10], help="seeds of the runs (default 10)")
    parser.add_argument("--window", type=int, default=25, help="frames per still block: the switch window (default 25)")
    parser.add_argument("--max-time", type=float, default=None, help="simulated time limit of a run (s)")
    parser.add_argument("--json", action="store_true", help="print the fit as JSON")
    args = parser.parse_args(argv)
    try:
        config = calibration_config(args.experiment, args.preset)
    except ValueError as error:
        parser.error(str(error))
    start = time.perf_counter()
    parts = []
    for seed in args.seeds:
        parts.append(record_detections(config, seed, args.max_time))
        print(f"seed {seed}: {len(parts[-1].board)} detections", file=sys.stderr)
    fit = fit_board_shift(DetectionRecords.concatenate(parts), config.camera.fx, config.camera.fy, args.window)
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps({"fit": dataclasses.asdict(fit), "seeds": args.seeds, "experiment": args.experiment,
                          "preset": args.preset, "wall_time_s": wall}, indent=2))
    else:
        print(f"board shift {fit.sigma_px:.3f} px, persistence {fit.persistence:.3f} "
              f"({fit.n_frames} detections, {fit.n_windows} still windows of {fit.window} frames)")
        print(f"lateral error per frame {fit.error_px:.3f} px RMS, PnP std {fit.pnp_px:.3f} px; window means {fit.window_error_px:.3f} px RMS")
        print(f"lateral NEES / 2 per frame: PnP {fit.nees_frame_pnp:.2f}, model {fit.nees_frame_model:.2f}; "
              f"per window: PnP {fit.nees_window_pnp:.2f}, model {fit.nees_window_model:.2f}")
        print(f"yaw NEES per frame {fit.yaw_frame_nees:.2f}, per window {fit.yaw_window_nees:.2f} (PnP covariance, not modelled); "
              f"depth error {100 * fit.depth_bias_m:+.2f} cm on average")
        print(f"wall time: {wall:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
