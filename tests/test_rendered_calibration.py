"""The board-shift calibration: the fit on synthetic records of known shift and persistence."""

from __future__ import annotations

import numpy as np
import pytest

from training.experiments.rendered_calibration import DetectionRecords, calibration_config, fit_board_shift

FX, FY = 500.0, 530.0


def _records(sigma_px: float, rho: float, pnp_px: float, blocks: int, window: int, seed: int, run: int = 0) -> DetectionRecords:
    """Two still boards per block (moved between blocks), lateral errors of a board shift (persistent part
    drawn once per block) plus white PnP noise of ``pnp_px``, reported as the PnP covariance."""
    rng = np.random.default_rng(seed)
    rows = {"run": [], "board": [], "time": [], "error": [], "covariance": [], "depth": [], "board_world": []}
    t = 0.0
    for k in range(blocks):
        depth = {b: rng.uniform(1.5, 2.5) for b in (0, 1)}
        world = {b: np.array([k * 0.3, b * 0.6, 0.4]) for b in (0, 1)}
        persistent = {b: rng.normal(0.0, sigma_px * np.sqrt(rho), 2) for b in (0, 1)}
        for _ in range(window):
            t = round(t + 0.04, 10)
            for b in (0, 1):
                z = depth[b]
                px = persistent[b] + rng.normal(0.0, sigma_px * np.sqrt(1.0 - rho), 2) + rng.normal(0.0, pnp_px, 2)
                e = np.zeros(6)
                e[0], e[1] = px[0] * z / FX, px[1] * z / FY
                cov = np.diag([(pnp_px * z / FX) ** 2, (pnp_px * z / FY) ** 2, 1e-5, 1e-4, 1e-4, 1e-5])
                for name, value in (("run", run), ("board", b), ("time", t), ("error", e), ("covariance", cov), ("depth", z), ("board_world", world[b])):
                    rows[name].append(value)
        t += 1.0  # the robots move: the next block is not consecutive
    return DetectionRecords(**{k: np.array(v) for k, v in rows.items()})


def test_fit_recovers_shift_and_persistence() -> None:
    records = _records(sigma_px=0.4, rho=0.7, pnp_px=0.2, blocks=200, window=10, seed=0)
    fit = fit_board_shift(records, FX, FY, window=10)
    assert fit.n_windows == 400 and fit.n_frames == 4000
    assert fit.sigma_px == pytest.approx(0.4, rel=0.05)
    assert fit.persistence == pytest.approx(0.7, abs=0.1)
    assert fit.nees_frame_model == pytest.approx(1.0, abs=0.1)
    assert fit.nees_window_model == pytest.approx(1.0, abs=0.15)
    assert fit.nees_window_pnp > 5.0 * fit.nees_window_model
    assert fit.yaw_frame_nees == 0.0 and fit.depth_bias_m == 0.0  # no yaw or depth error drawn


def test_yaw_and_depth_summaries() -> None:
    records = _records(sigma_px=0.0, rho=0.0, pnp_px=0.2, blocks=50, window=10, seed=5)
    rng = np.random.default_rng(6)
    error = records.error.copy()
    error[:, 2] = -0.01  # every board 1 cm farther than it is
    error[:, 5] = rng.normal(0.0, np.sqrt(1e-5), len(error))  # white yaw error of the reported variance
    fit = fit_board_shift(
        DetectionRecords(records.run, records.board, records.time, error, records.covariance, records.depth, records.board_world), FX, FY, window=10
    )
    assert fit.depth_bias_m == pytest.approx(-0.01)
    assert fit.yaw_frame_nees == pytest.approx(1.0, abs=0.15)  # white yaw of the reported variance
    assert fit.yaw_window_nees == pytest.approx(1.0, abs=0.3)


def test_white_pnp_noise_alone_needs_no_shift() -> None:
    fit = fit_board_shift(_records(sigma_px=0.0, rho=0.0, pnp_px=0.2, blocks=100, window=10, seed=1), FX, FY, window=10)
    assert fit.sigma_px < 0.05
    assert fit.nees_window_pnp == pytest.approx(1.0, abs=0.2)


def test_blocks_never_span_two_runs() -> None:
    a = _records(0.4, 1.0, 0.2, blocks=1, window=10, seed=2)
    b = _records(0.4, 1.0, 0.2, blocks=1, window=10, seed=3)
    both = DetectionRecords.concatenate([a, b])
    assert sorted(set(both.run.tolist())) == [0, 1]
    assert fit_board_shift(both, FX, FY, window=10).n_windows == 4
    # windows longer than the still blocks: nothing to fit the persistence on
    with pytest.raises(ValueError, match="no still block of 11"):
        fit_board_shift(both, FX, FY, window=11)


def test_bad_input_is_named() -> None:
    records = _records(0.4, 1.0, 0.2, blocks=1, window=10, seed=4)
    with pytest.raises(ValueError, match="window"):
        fit_board_shift(records, FX, FY, window=1)
    with pytest.raises(ValueError, match="records.error"):
        DetectionRecords(records.run, records.board, records.time, records.error[:, :3], records.covariance, records.depth, records.board_world)
    with pytest.raises(ValueError, match="experiment"):
        calibration_config("circle")


def test_calibration_config_is_rendered_without_a_shift() -> None:
    config = calibration_config()
    assert config.camera_backend == "rendered" and config.camera.board_shift_px == 0.0
