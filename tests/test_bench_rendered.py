"""The rendered-camera benchmark (training.bench_rendered): what it reports, not how fast."""

from __future__ import annotations

import math

from training.bench import format_bench
from training.bench_rendered import VARIANTS, bench_rendered


def test_bench_rendered_reports_every_variant_with_its_camera_times():
    rows = bench_rendered(steps=2)
    assert [(r["floor"], r["floor_reuse_px"], r["noise_std"]) for r in rows] == [
        ("textured", 0.0, 3.0),
        ("plain", 0.0, 3.0),
        ("textured", 0.25, 3.0),
        ("textured", 0.0, 0.0),
    ]
    assert len(rows) == len(VARIANTS)
    for r in rows:
        assert r["image"] == "720x576" and r["steps"] == 2
        assert r["steps_per_s"] > 0 and r["detect_ms"] > 0 and r["render_ms"] > 0
        # The step contains the drawing and the detection.
        assert r["step_ms"] > r["render_ms"] + r["detect_ms"]
        assert math.isclose(r["step_over_detect"], r["step_ms"] / r["detect_ms"])
    text = format_bench({"configurations": [], "rendered": rows})
    assert "step/detect" in text and text.count("top_observer") == len(rows)


def test_bench_rendered_keeps_the_fastest_round_of_each_variant():
    rows = bench_rendered(steps=2, rounds=2)
    assert len(rows) == len(VARIANTS)
    for r in rows:
        assert len(r["rounds_steps_per_s"]) == 2 and r["steps_per_s"] == max(r["rounds_steps_per_s"])
        assert math.isclose(r["step_ms"], 1e3 / r["steps_per_s"])
