"""Evaluation sweeps on Ray (training/sweep, ``moma-env sweep``) on a local Ray with 2 CPUs:
a 2 x 2 x 4 sweep gives the local backend's table byte for byte, a sweep killed mid-run
resumes on Ray without redoing finished cells, and a task whose worker is killed is retried."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

pytest.importorskip("ray", reason="needs the 'ray' extra")

from ray_session import ray_local  # noqa: E402,F401  (the session's Ray)

# make test (pytest-xdist, --dist loadgroup) runs every test of the session's Ray on one worker: one Ray.
pytestmark = pytest.mark.xdist_group("ray")

from training.sweep.backends import LocalBackend, RayBackend  # noqa: E402
from training.sweep.folder import CELLS_DIR  # noqa: E402
from training.sweep.run import sweep  # noqa: E402
from training.sweep.spec import SweepSpec  # noqa: E402

OUTPUTS = ("results.csv", "results.parquet", "summary.json")


def test_a_2x2x4_sweep_on_ray_matches_the_local_backend(ray_local, tmp_path):
    spec = SweepSpec(scenarios=("top_observer", "caterpillar"), policies=("scripted", "random"), seeds=(0, 1, 2, 3), max_cycles=60)
    on_ray = sweep(spec, tmp_path / "ray", RayBackend(), cells_per_task=3)
    local = sweep(spec, tmp_path / "local", LocalBackend(2), cells_per_task=1)
    assert on_ray.n_run == local.n_run == 16
    for name in OUTPUTS:
        assert (tmp_path / "ray" / name).read_bytes() == (tmp_path / "local" / name).read_bytes(), name


def test_a_partly_done_sweep_resumes_on_ray_with_only_the_missing_cells(ray_local, tmp_path):
    spec = SweepSpec(scenarios=("top_observer",), policies=("scripted", "random"), seeds=(0, 1, 2), max_cycles=60)
    out = tmp_path / "s"
    sweep(spec, out, LocalBackend(1))
    removed = sorted((out / CELLS_DIR).glob("*.json"))[::2]  # as if killed before these finished
    for path in removed:
        path.unlink()
    kept = {p.name: p.stat().st_mtime_ns for p in (out / CELLS_DIR).glob("*.json")}
    report = sweep(spec, out, RayBackend(), resume=True)
    assert report.n_run == len(removed)
    assert {name: (out / CELLS_DIR / name).stat().st_mtime_ns for name in kept} == kept
    sweep(spec, tmp_path / "fresh", LocalBackend(1))
    for name in OUTPUTS:
        assert (out / name).read_bytes() == (tmp_path / "fresh" / name).read_bytes(), name


def _task_workers() -> list[int]:
    """Pids of Ray workers running a sweep task (process title ``ray::run_cells``)."""
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/cmdline", "rb") as f:
                    if f.read().startswith(b"ray::run_cells"):
                        pids.append(int(entry))
            except OSError:
                continue
    return pids


def test_a_killed_worker_costs_a_retry_not_a_cell(ray_local, tmp_path):
    spec = SweepSpec(scenarios=("top_observer",), policies=("scripted",), seeds=tuple(range(8)))
    outcome: dict = {}

    def run() -> None:
        try:
            outcome["report"] = sweep(spec, tmp_path / "ray", RayBackend(retries=2), cells_per_task=4)
        except BaseException as err:  # reported to the test thread
            outcome["error"] = err

    thread = threading.Thread(target=run)
    thread.start()
    killed = None
    deadline = time.monotonic() + 120
    while killed is None and thread.is_alive() and time.monotonic() < deadline:
        pids = _task_workers()
        if pids:
            os.kill(pids[0], signal.SIGKILL)
            killed = pids[0]
        time.sleep(0.01)
    thread.join(timeout=300)
    assert killed is not None, "no task worker was seen running"
    assert "error" not in outcome, outcome.get("error")
    assert outcome["report"].n_run == 8
    sweep(spec, tmp_path / "local", LocalBackend(1))
    for name in OUTPUTS:
        assert (tmp_path / "ray" / name).read_bytes() == (tmp_path / "local" / name).read_bytes(), name


def test_the_command_runs_on_an_existing_cluster_given_its_address(ray_local, tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    address = ray_local.get_runtime_context().gcs_address
    repo = Path(__file__).resolve().parents[1]
    args = ["sweep", "--scenarios", "caterpillar", "--policies", "random", "--seeds", "0:3", "--max-cycles", "30", "--no-progress"]
    done = subprocess.run([sys.executable, "-m", "training.cli", *args, "--address", address, "--out", str(tmp_path / "cluster")],
                          cwd=tmp_path, env=dict(os.environ, PYTHONPATH=str(repo), OMP_NUM_THREADS="1"),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    spec = SweepSpec(scenarios=("caterpillar",), policies=("random",), seeds=(0, 1, 2), max_cycles=30)
    sweep(spec, tmp_path / "local", LocalBackend(1))
    for name in OUTPUTS:
        assert (tmp_path / "cluster" / name).read_bytes() == (tmp_path / "local" / name).read_bytes(), name
