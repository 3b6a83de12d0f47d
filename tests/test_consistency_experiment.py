"""The consistency study end to end: cases, MOMA's NEES in the loop with detections of known covariance, the command."""

from __future__ import annotations

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.camera import make_camera
from training.cli import main
from training.experiments.consistency import consistency_cases, run_case
from training.experiments.consistency_report import format_table, steps_rows, write_outputs

#: Covariance of the detections' pose errors (camera frame C, translation first): 2 mm, 2 mm, 8 mm, 0.6 deg, 0.6 deg, 0.2 deg.
DETECTION_COVARIANCE = np.diag([0.002, 0.002, 0.008, 0.01, 0.01, 0.004]) ** 2


class GaussianPoseCamera:
    """The geometric camera's detections, with ``T_c_m`` replaced by the truth perturbed by
    ``N(0, covariance)`` (the estimator's error convention) and that covariance attached."""

    def __init__(self, inner, covariance: np.ndarray):
        self.inner = inner
        self.camera_id = inner.camera_id
        self.camera = inner.camera
        self.covariance = covariance
        self.chol = np.linalg.cholesky(covariance)

    def measure(self, T_w_c, boards, time, rng, occluded=None):
        detections = self.inner.measure(T_w_c, boards, time, rng, occluded)
        T_c_w = g.invert(T_w_c)
        views = {b.board_id: b for b in boards}
        out = []
        for d in detections:
            T = T_c_w @ views[d.board_id].T_w_m
            e = self.chol @ rng.standard_normal(6)
            noisy = g.make_transform(g.rotvec_to_matrix(e[3:]) @ T[:3, :3], T[:3, 3] + e[:3])
            out.append(dataclasses.replace(d, T_c_m=noisy, covariance=self.covariance))
        return out


def gaussian_camera(config, name, floor):
    return GaussianPoseCamera(make_camera(name, config.camera), DETECTION_COVARIANCE)


def test_cases_cover_experiments_modes_and_cameras():
    cases = consistency_cases(5, 2)
    assert [c.name for c in cases] == [
        "square/planar/geometric", "square/6dof/geometric", "line/planar/geometric", "line/6dof/geometric",
        "square/planar/rendered", "square/6dof/rendered", "line/planar/rendered", "line/6dof/rendered",
    ]
    assert [c.n_runs for c in cases] == [5] * 4 + [2] * 4
    assert [c.config.planar_ugvs for c in cases[:2]] == [True, False]
    assert cases[-1].config.camera_backend == "rendered"
    assert cases[0].position_components == (0, 1) and cases[1].position_components == (0, 1, 2)
    only = consistency_cases(1, 0, experiments=("line",), max_time_s=12.0)
    assert [c.name for c in only] == ["line/planar/geometric", "line/6dof/geometric"]
    assert only[0].config.max_time_s == 12.0
    with pytest.raises(ValueError, match="n_runs"):
        consistency_cases(0, 1)
    with pytest.raises(ValueError, match="rendered_runs"):
        consistency_cases(1, -1)
    with pytest.raises(ValueError, match="experiments: unknown experiment 'kite'"):
        consistency_cases(1, 0, experiments=("kite",))


@pytest.mark.parametrize("mode", ["planar", "6dof"])
def test_moma_is_consistent_with_detections_of_known_covariance(mode, tmp_path):
    case = next(c for c in consistency_cases(4, 0, experiments=("square",), max_time_s=45.0) if c.mode == mode)
    result = run_case(case, seed=3, camera_factory=gaussian_camera)
    p, h = result.position, result.heading
    assert p.dof == (2 if mode == "planar" else 3) and h.dof == 1
    assert p.n_steps > 500 and p.counts.max() == 4
    # the main robot starts as a reference at its known pose: zero covariance, skipped
    assert p.n_singular > 0
    for avg in (p, h):
        assert 0.6 < avg.mean_anees < 1.6, avg.to_dict()
        assert avg.fraction_inside > 0.85, avg.to_dict()
    # the recorded covariances are MOMA's: fresh samples have a positive position variance
    run = result.runs[0]
    cov = run.trajectories["ugv_0"]["moma"].covariances
    assert cov.shape == (len(run.trajectories["ugv_0"]["truth"]), 6, 6)
    assert (cov[run.localised["ugv_0"], 0, 0] > 0).any()
    if mode == "planar":
        assert not cov[np.isfinite(cov[:, 0, 0]), 2, 2].any()  # upright: no z variance

    paths = write_outputs([result], 3, tmp_path)
    assert paths[f"figure {case.name}"].stat().st_size > 20_000
    rows = list(csv.DictReader(paths["steps"].open()))
    assert len(rows) == len(steps_rows([result])) and rows[0]["case"] == case.name
    data = json.loads(paths["summary"].read_text())
    assert data["cases"][case.name]["position"]["mean_anees"] == pytest.approx(p.mean_anees)
    assert not list(tmp_path.glob(".*tmp*"))
    assert case.name in format_table([result])


def test_command_runs_end_to_end_and_writes_its_files(tmp_path, capsys):
    out = tmp_path / "cons"
    argv = ["experiment", "consistency", "--runs", "2", "--rendered-runs", "0", "--experiments", "square",
            "--max-time", "15", "--seed", "4", "--out", str(out), "--json"]
    assert main(argv) == 1  # stopped by --max-time before the square is driven: flagged, files still written
    data = json.loads(capsys.readouterr().out)
    assert data["experiment"] == "consistency" and data["seed"] == 4 and data["confidence"] == 0.95
    assert "LOCALISED" in data["definition"]
    assert sorted(data["cases"]) == ["square/6dof/geometric", "square/planar/geometric"]
    case = data["cases"]["square/6dof/geometric"]
    assert case["n_runs"] == 2 and case["n_completed"] == 0 and case["seeds"] == [4, 5]
    assert case["mode"] == "6dof" and case["config"]["planar_ugvs"] is False
    for key in ("mean_anees", "nominal_lower", "nominal_upper", "fraction_inside", "fraction_above", "fraction_below",
                "n_steps", "n_samples", "n_singular_skipped", "dof", "n_runs", "confidence"):
        assert key in case["position"] and key in case["heading"]
    assert case["position"]["dof"] == 3 and data["cases"]["square/planar/geometric"]["position"]["dof"] == 2
    lo, hi = case["position"]["nominal_lower"], case["position"]["nominal_upper"]
    assert 0 < lo < 1 < hi
    # the default geometric camera gives no detection covariance yet: every sample is singular, none averaged
    if case["position"]["n_steps"] == 0:
        assert case["position"]["mean_anees"] is None and case["position"]["n_singular_skipped"] > 0
    else:
        assert math.isfinite(case["position"]["mean_anees"])
    for name in ("square_planar_geometric.png", "square_6dof_geometric.png", "steps.csv", "summary.json"):
        assert (out / name).is_file()
    assert json.loads((out / "summary.json").read_text())["cases"] == data["cases"]
    assert not [p for p in out.iterdir() if ".tmp" in p.name]

    assert main(argv[:-1]) == 1
    table = capsys.readouterr().out
    assert "square/planar/geometric" in table and "pos ANEES" in table and "wall time" in table


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["--runs", "0"], "count must be >= 1"), (["--rendered-runs", "-1"], "count must be >= 0"),
     (["--experiments", "kite"], "invalid choice"), (["--max-time", "0"], "time limit")],
)
def test_command_rejects_bad_arguments(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["experiment", "consistency", *argv])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
