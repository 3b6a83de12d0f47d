"""Run metrics (ME, E_f, % of path, switches) and their aggregate over runs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.config import ConfigError
from moma_env.io import write_json
from moma_env.metrics import AggregateMetrics, RunMetrics, Trajectory, aggregate, run_metrics


def straight(t: np.ndarray, dy: float = 0.0) -> Trajectory:
    return Trajectory.from_planar(t, t.copy(), np.full(len(t), dy), np.zeros(len(t)))


def square_truth() -> Trajectory:
    """1 m square, 4 m path, 10 samples per side plus the closing corner."""
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])
    s = np.linspace(0.0, 1.0, 10, endpoint=False)
    xy = np.concatenate([a + s[:, None] * (b - a) for a, b in zip(corners[:-1], corners[1:])] + [corners[-1:]])
    yaw = np.zeros(len(xy))
    return Trajectory.from_planar(np.arange(len(xy)) * 0.5, xy[:, 0], xy[:, 1], yaw)


def make_run(final: float, mean: float = 0.02, path: float = 4.0) -> RunMetrics:
    return RunMetrics(
        mean_error=mean,
        final_error=final,
        max_error=0.1,
        rmse=0.05,
        path_length=path,
        final_error_pct_path=100.0 * final / path,
        mean_heading_error_deg=1.0,
        final_heading_error_deg=1.0,
        switch_times=(),
        errors_at_switches=(),
        valid_fraction=1.0,
        n_samples=10,
    )


def test_offset_3cm_gives_me_and_ef_3cm() -> None:
    t = np.linspace(0.0, 4.0, 21)
    m = run_metrics(straight(t, dy=0.03), straight(t))
    assert m.mean_error == pytest.approx(0.03, abs=1e-15)
    assert m.final_error == pytest.approx(0.03, abs=1e-15)
    assert m.max_error == pytest.approx(0.03, abs=1e-15) and m.rmse == pytest.approx(0.03, abs=1e-15)
    assert m.path_length == pytest.approx(4.0)
    assert m.final_error_pct_path == pytest.approx(0.75)
    assert m.valid_fraction == 1.0 and m.n_samples == 21 and not m.failed


def test_square_percentage_of_path_matches_paper_arithmetic() -> None:
    truth = square_truth()
    assert truth.path_length() == pytest.approx(4.0, abs=1e-12)
    # the paper: ME_f = 0.97 cm over a 400 cm path is 0.2425 %
    xy = truth.xy.copy()
    xy[-1, 0] += 0.0097
    est = Trajectory.from_planar(truth.times, xy[:, 0], xy[:, 1], truth.yaw)
    m = run_metrics(est, truth)
    assert m.final_error == pytest.approx(0.0097, abs=1e-15)
    assert m.final_error_pct_path == pytest.approx(0.2425, abs=1e-12)
    assert m.mean_error == pytest.approx(0.0097 / len(truth), abs=1e-15)


def test_explicit_path_length_overrides_truth() -> None:
    t = np.arange(5.0)
    m = run_metrics(straight(t, dy=0.05), straight(t), path_length=10.0)
    assert m.path_length == 10.0 and m.final_error_pct_path == pytest.approx(0.5)
    with pytest.raises(ConfigError, match="path_length"):
        run_metrics(straight(t), straight(t), path_length=0.0)


def test_static_truth_has_undefined_percentage() -> None:
    t = np.arange(3.0)
    truth = Trajectory.from_planar(t, np.zeros(3), np.zeros(3), np.zeros(3))
    m = run_metrics(truth, truth)
    assert m.path_length == 0.0 and math.isnan(m.final_error_pct_path) and m.final_error == 0.0


def test_nan_estimates_excluded_from_me_and_counted_in_valid_fraction() -> None:
    t = np.arange(5.0)
    y = np.array([0.01, np.nan, 0.03, np.nan, 0.05])
    est = Trajectory.from_planar(t, t, y, np.zeros(5))
    m = run_metrics(est, straight(t))
    assert m.mean_error == pytest.approx(0.03)
    assert m.max_error == pytest.approx(0.05)
    assert m.rmse == pytest.approx(math.sqrt((0.01**2 + 0.03**2 + 0.05**2) / 3))
    assert m.valid_fraction == pytest.approx(0.6)
    assert m.final_error == pytest.approx(0.05)


def test_invalid_estimate_at_the_end_fails_the_run() -> None:
    t = np.arange(4.0)
    est = Trajectory.from_planar(t, [0.0, 1.0, 2.0, np.nan], [0.02] * 4, [0.0] * 4)
    m = run_metrics(est, straight(t))
    assert math.isnan(m.final_error) and math.isnan(m.final_error_pct_path) and m.failed
    assert m.mean_error == pytest.approx(0.02)


def test_final_error_uses_last_valid_truth_sample() -> None:
    t = np.arange(4.0)
    truth = Trajectory.from_planar(t, [0.0, 1.0, 2.0, np.nan], [0.0] * 4, [0.0] * 4)
    est = Trajectory.from_planar(t, [0.0, 1.0, 2.0, 3.0], [0.0, 0.0, 0.04, 0.09], [0.0, 0.0, 0.3, 0.0])
    m = run_metrics(est, truth)
    assert m.final_error == pytest.approx(0.04)
    assert m.final_heading_error_deg == pytest.approx(math.degrees(0.3))
    assert m.n_samples == 3 and m.valid_fraction == 1.0


def test_switch_errors_picked_at_the_nearest_samples() -> None:
    t = np.arange(8.0) * 0.5
    est = Trajectory.from_planar(t, t, 0.01 * np.arange(8), np.zeros(8))  # E at sample k = 0.01 k
    m = run_metrics(est, straight(t), switch_times=[0.6, 1.3, 2.25, 3.5])
    # 0.6 -> sample 1 (0.5), 1.3 -> sample 3 (1.5), 2.25 tie -> earlier sample 4 (2.0), 3.5 -> sample 7
    np.testing.assert_allclose(m.errors_at_switches, [0.01, 0.03, 0.04, 0.07], atol=1e-15)
    assert m.switch_times == (0.6, 1.3, 2.25, 3.5)
    with pytest.raises(ValueError, match="outside"):
        run_metrics(est, straight(t), switch_times=[4.0])


def test_heading_metrics_in_degrees() -> None:
    t = np.arange(3.0)
    truth = Trajectory.from_planar(t, t, np.zeros(3), [math.pi - 0.01] * 3)
    est = Trajectory.from_planar(t, t, np.zeros(3), [-math.pi + 0.01, -math.pi + 0.03, math.pi - 0.01])
    m = run_metrics(est, truth)
    assert m.mean_heading_error_deg == pytest.approx(math.degrees(0.06 / 3))
    assert m.final_heading_error_deg == pytest.approx(0.0, abs=1e-9)


def test_truth_without_valid_samples_is_rejected() -> None:
    t = np.arange(2.0)
    truth = Trajectory.from_planar(t, [np.nan] * 2, [0.0] * 2, [0.0] * 2)
    with pytest.raises(ValueError, match="at least one valid sample"):
        run_metrics(straight(t), truth)


def test_aggregate_known_values() -> None:
    runs = [make_run(0.01, mean=0.01), make_run(0.02, mean=0.03), make_run(0.03, mean=0.02), make_run(math.nan)]
    a = aggregate(runs)
    assert (a.n_runs, a.n_failed, a.ddof) == (4, 1, 1)
    assert a.failure_fraction == 0.25
    assert a.mean_final_error == pytest.approx(0.02)
    assert a.std_final_error == pytest.approx(0.01)  # sample std of 1, 2, 3 cm
    assert a.mean_mean_error == pytest.approx(0.02)
    assert a.std_mean_error == pytest.approx(0.01)
    assert a.mean_final_error_pct_path == pytest.approx(0.5)
    assert (a.best_final_error, a.worst_final_error) == (0.01, 0.03)
    assert a.best_final_error_pct_path == pytest.approx(0.25)
    assert a.worst_final_error_pct_path == pytest.approx(0.75)
    population = aggregate(runs, ddof=0)
    assert population.std_final_error == pytest.approx(0.01 * math.sqrt(2.0 / 3.0))


def test_aggregate_edge_cases() -> None:
    single = aggregate([make_run(0.01)])
    assert single.mean_final_error == 0.01 and math.isnan(single.std_final_error)
    assert aggregate([make_run(0.01)], ddof=0).std_final_error == 0.0
    all_failed = aggregate([make_run(math.nan), make_run(math.nan)])
    assert all_failed.n_failed == 2 and math.isnan(all_failed.mean_final_error)
    assert math.isnan(all_failed.best_final_error)
    with pytest.raises(ValueError, match="at least one run"):
        aggregate([])
    with pytest.raises(ValueError, match="ddof"):
        aggregate([make_run(0.01)], ddof=2)


def test_to_dict_is_json_ready(tmp_path: Path) -> None:
    t = np.arange(4.0)
    m = run_metrics(straight(t, dy=0.01), straight(t), switch_times=[1.0, 2.0])
    a = aggregate([m, make_run(math.nan)])
    write_json(tmp_path / "m.json", {"run": m, "aggregate": a})
    data = json.loads((tmp_path / "m.json").read_text())
    assert data["run"]["errors_at_switches"] == pytest.approx([0.01, 0.01])
    assert data["run"]["failed"] is False
    assert data["aggregate"]["n_failed"] == 1 and data["aggregate"]["failure_fraction"] == 0.5
    assert data["aggregate"]["std_final_error"] is None  # one successful run: NaN -> null
    assert set(m.to_dict()) >= {"mean_error", "final_error", "final_error_pct_path", "valid_fraction"}
    assert isinstance(a, AggregateMetrics)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0.0, 1.0), min_size=2, max_size=12),
    st.floats(0.001, 0.5),
)
def test_aggregate_of_constant_offset_runs(offsets: list[float], spacing: float) -> None:
    t = np.arange(6) * spacing
    truth = straight(t)
    runs = [run_metrics(straight(t, dy=d), truth) for d in offsets]
    a = aggregate(runs)
    assert a.n_failed == 0
    assert a.mean_final_error == pytest.approx(float(np.mean(offsets)), abs=1e-12)
    assert a.std_final_error == pytest.approx(float(np.std(offsets, ddof=1)), abs=1e-12)
    assert a.mean_mean_error == pytest.approx(a.mean_final_error, abs=1e-12)
    assert a.best_final_error == pytest.approx(min(offsets), abs=1e-15)
