"""The floor check (``python -m training.experiments.floor_check``) on small counts."""

import json
import math

import cv2
import numpy as np
import pytest

from moma_env.odometry.visual import corner_response
from training.experiments.floor_check import (
    FLOORS,
    FloorCheckConfig,
    main,
    run_floor_check,
)

SMALL = FloorCheckConfig(cost_frames=3, cost_warmup=1, vo_frames=4, detection_poses=1, detection_seeds=2)
TINY_ARGS = ["--cost-frames", "2", "--cost-warmup", "1", "--vo-frames", "1", "--detection-poses", "1", "--detection-seeds", "1"]


@pytest.fixture(scope="module")
def result():
    return run_floor_check(SMALL)


def test_structure(result):
    assert set(result) == {"settings", "rasters", "frame_cost", "vo", "detections"}
    # With grain the raster spans the arena, without it the textured strips only.
    assert result["rasters"]["grain"]["megapixels"] > result["rasters"]["plain"]["megapixels"] > 0.0
    assert all(r["build_s"] > 0.0 for r in result["rasters"].values())
    assert result["settings"]["vo_frames"] == SMALL.vo_frames
    cost = result["frame_cost"]
    assert cost["frames"] == SMALL.cost_frames - SMALL.cost_warmup
    assert set(cost["median_ms"]) == set(FLOORS)
    assert all(0.0 < ms < 10_000.0 for ms in cost["median_ms"].values())
    assert 0.0 < cost["ratio"] < math.inf
    for name in FLOORS:
        vo = result["vo"][name]
        assert len(vo["strong"]) == len(vo["best"]) == len(vo["fifteenth"]) == SMALL.vo_frames
        assert result["detections"][name]["detections"] == SMALL.detection_poses * SMALL.detection_seeds


def test_plain_floor_has_no_vo_features_and_grain_at_least_as_many(result):
    plain, grain = result["vo"]["plain"], result["vo"]["grain"]
    assert plain["threshold"] == grain["threshold"] > 0.0
    assert sum(plain["strong"]) == 0
    assert max(plain["best"]) < plain["threshold"]
    # Same positions and noise on both floors: the grain only adds structure.
    assert all(g >= p for g, p in zip(grain["strong"], plain["strong"]))
    assert np.median(grain["best"]) >= np.median(plain["best"])


def test_detection_errors_finite_and_alike_on_both_floors(result):
    errors = [result["detections"][name]["mean_position_error_m"] for name in FLOORS]
    biases = [result["detections"][name]["depth_bias_m"] for name in FLOORS]
    assert all(math.isfinite(v) for v in errors + biases)
    assert all(0.0 < e < 0.05 for e in errors)  # within 5 cm at 2.1 m
    assert 0.5 < errors[0] / errors[1] < 2.0


def test_corner_response_is_the_block_mean_smallest_eigenvalue():
    image = cv2.GaussianBlur(np.random.default_rng(3).integers(0, 256, size=(40, 40)).astype(np.uint8), (0, 0), 1.5)
    block = 7
    gx = cv2.Sobel(image.astype(float), cv2.CV_64F, 1, 0, ksize=3) / 8.0  # gray levels / px
    gy = cv2.Sobel(image.astype(float), cv2.CV_64F, 0, 1, ksize=3) / 8.0
    v, u, h = 20, 17, block // 2
    window = np.s_[v - h : v + h + 1, u - h : u + h + 1]
    a, b, c = (np.mean(p[window]) for p in (gx * gx, gx * gy, gy * gy))
    smallest = (a + c) / 2 - math.sqrt(((a - c) / 2) ** 2 + b * b)
    assert corner_response(image, block)[v, u] == pytest.approx(smallest, rel=1e-3)


def test_cli_json_parses(capsys):
    assert main([*TINY_ARGS, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["settings"]["cost_frames"] == 2
    assert set(data["vo"]) == set(data["detections"]) == set(FLOORS)
    assert data["frame_cost"]["ratio"] > 0.0


def test_cli_markdown_has_three_tables(capsys):
    assert main(TINY_ARGS) == 0
    out = capsys.readouterr().out
    assert sum(line.startswith("|---") for line in out.splitlines()) == 3
    assert "grain / plain" in out and "features >= 20" in out and "depth bias" in out


def test_cli_rejects_bad_counts():
    with pytest.raises(SystemExit):
        main(["--cost-frames", "3", "--cost-warmup", "3"])
