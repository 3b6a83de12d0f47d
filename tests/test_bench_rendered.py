"""The rendered-camera benchmark (training.bench_rendered): what it reports, not how fast."""

from __future__ import annotations

import math

from training.bench import format_bench
from training.bench_rendered import STAGES, TARGET_STEP_OVER_DETECT, VARIANTS, _CameraTimes, bench_rendered


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
        # The timed stages are parts of the drawing; the rest of the step outside detection is "other".
        stages = [r[f"{stage}_ms"] for stage in STAGES]
        assert all(t >= 0.0 for t in stages) and sum(stages) <= r["render_ms"]
        assert r["boards_ms"] > 0 and r["blur_ms"] > 0
        assert math.isclose(r["other_ms"] + sum(stages) + r["detect_ms"], r["step_ms"])
        assert math.isclose(r["allowed_ms"], (TARGET_STEP_OVER_DETECT - 1.0) * r["detect_ms"])
    # The floor is resampled only where it is textured; the noise-free row reads out nothing.
    assert rows[0]["floor_ms"] > 0 and rows[0]["read_out_ms"] > 0
    text = format_bench({"configurations": [], "rendered": rows})
    assert "step/detect" in text and text.count("top_observer") == len(rows)
    assert "outside detection" in text and "allowed" in text


def test_camera_times_follow_a_camera_rebuilt_by_reset():
    from moma_env.env.factory import parallel_env

    env = parallel_env("top_observer", camera_backend="rendered", random_scenarios=True, max_cycles=5)
    env.reset(seed=0)
    timed = _CameraTimes(env, env.scenario.world.uav.camera_name)
    actions = {a: env.action_space(a).sample() for a in env.agents}
    timed.step(actions)
    first = dict(timed.stage_s)
    assert first["boards"] > 0 and first["read_out"] > 0
    old = timed.camera
    timed.reset(seed=1)
    assert timed.camera is not old  # a new random scenario builds new cameras
    during_reset = dict(timed.stage_s)
    assert during_reset == first  # reset's own drawing is not counted
    timed.step({a: env.action_space(a).sample() for a in env.agents})
    assert timed.stage_s["boards"] > first["boards"] and timed.stage_s["read_out"] > first["read_out"]


def test_bench_rendered_keeps_the_fastest_round_of_each_variant():
    rows = bench_rendered(steps=2, rounds=2)
    assert len(rows) == len(VARIANTS)
    for r in rows:
        assert len(r["rounds_steps_per_s"]) == 2 and r["steps_per_s"] == max(r["rounds_steps_per_s"])
        assert math.isclose(r["step_ms"], 1e3 / r["steps_per_s"])
