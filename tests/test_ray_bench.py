"""training.bench_ray's driver row: the bytes a sweep task ships and returns, and the
driver's time to store a task, measured (the Ray and RLlib rows are the benchmark's own run)."""

from __future__ import annotations

import pytest

pytest.importorskip("ray", reason="needs the 'ray' extra")

from training.bench_ray import driver_row, format_rows  # noqa: E402


def test_driver_row_measures_what_a_task_ships_and_costs():
    row = driver_row(cells_per_task=4, tasks=3)
    assert 0 < row["task_args_bytes"] < 1000
    assert row["row_bytes_6_ugvs"] > row["row_bytes_2_ugvs"] > 0  # a larger team has more columns
    assert row["store_task_ms"] > 0
    table = format_rows({"cpus": 2, "python": "3", "ray": "2", "rows": [row]})
    assert "storing a task of 4 cells" in table
