"""The reset-memory benchmark (training.bench_memory): what it counts, not how much memory anything takes."""

from __future__ import annotations

import pytest

from training.bench_memory import format_reset_memory, main, reset_memory


def test_reset_memory_rows_count_resets_and_growth():
    row = reset_memory("world", resets=5, steps=2, every=2)
    assert [k for k, _ in row["samples"]] == [1, 2, 4, 5]
    assert row["start_mb"] == row["samples"][0][1] and row["end_mb"] == row["samples"][-1][1]
    assert row["per_1000_mb"] == (row["end_mb"] - row["start_mb"]) / 4 * 1000.0
    assert row["peak_mb"] == max(mb for _, mb in row["samples"])
    (_, a), (_, b), (_, c) = row["samples"][1:]
    assert row["steepest_per_1000_mb"] == max((b - a) / 2 * 1000.0, (c - b) * 1000.0)
    assert isinstance(row["full_collections"], int) and row["full_collections"] >= 0
    assert "world" in format_reset_memory([row])


def test_reset_memory_refuses_unknown_targets_and_short_runs():
    with pytest.raises(ValueError, match="unknown target"):
        reset_memory("nowhere", resets=5)
    with pytest.raises(ValueError, match="resets >= 2"):
        reset_memory("world", resets=1)


def test_the_command_runs_the_environment_row(capsys):
    assert main(["--resets", "3", "--steps", "1", "--targets", "top_observer", "--every", "2"]) == 0
    out = capsys.readouterr().out
    assert "top_observer" in out and "MB/1000" in out
