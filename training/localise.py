"""``moma-env localise LOG --out DIR``: an estimator run on a detection log.

The log (:mod:`moma_env.estimator.log`) is what a localiser was told: robots, their
static/mobile declarations and every camera frame's detections, recorded by an
experiment (``moma-env experiment square --record-detections``) or written from a real
robot's detector. The estimator named by ``--estimator`` (with the log's
configuration) takes those calls again, and every robot's estimated trajectory is
written as a TUM file with its covariances beside it, for ``evo`` or
:mod:`moma_env.metrics`:

* ``DIR/<robot>.tum``: the robot's estimated ``T_w_b`` after every frame (one sample
  for frames of one instant; and once after the robots are declared), the samples with
  an estimate;
* ``DIR/<robot>.cov.txt``: their 6x6 covariances, line for line
  (:mod:`moma_env.metrics.tum_covariance`);
* ``DIR/summary.json``: the log, the estimator and its configuration, and per robot
  the samples, those with an estimate and those LOCALISED (fresh); with ``--truth
  TRUTH_DIR``, also each robot's errors against its ground truth, ``TRUTH_DIR/<robot>.tum``
  or ``TRUTH_DIR/<robot>_truth.tum`` (an experiment's ``tum/run_XX`` folder, or a motion
  capture's TUM files): :func:`moma_env.metrics.run_metrics`'s planar position errors
  at the truth's timestamps, each matched to the estimate within ``--max-dt`` seconds
  (mean ME, final E_f, largest, RMSE, in m, and the share of the truth's samples matched).

Replaying a log an experiment recorded on this machine gives that run's trajectories
bit for bit (``tests/test_detection_log.py``).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from moma_env.estimator import Status
from moma_env.estimator.log import DetectionLog, DetectionLogError, FrameRecord, read_detection_log, replay
from moma_env.metrics import Trajectory, TrajectoryRecorder, covariance_path_for, read_tum, run_metrics, write_covariances, write_tum

__all__ = ["replay_trajectories", "truth_files", "errors_against_truth", "write_detection_logs", "run_localise_command"]


def replay_trajectories(log: DetectionLog, localiser: Any) -> tuple[dict[str, Trajectory], dict[str, int]]:
    """Every robot's estimated trajectory (with covariances) over a replay of ``log`` on
    ``localiser`` (:func:`moma_env.estimator.log.replay`), and per robot the number of
    samples where it was LOCALISED. A robot's samples start when it is declared; frames
    that share a time (two cameras' images of one instant, sent as two updates) give one
    sample, the estimate after the last of them."""
    samples: dict[str, list[tuple[float, Any, Any, bool]]] = {}

    def sample(time: float, estimates: Mapping[str, Any]) -> None:
        for name, estimate in estimates.items():
            row = (time, estimate.T_w_b, estimate.covariance, estimate.status is Status.LOCALISED)
            rows = samples.setdefault(name, [])
            if rows and rows[-1][0] == time:
                rows[-1] = row
            else:
                rows.append(row)

    replay(log, localiser, sample)
    trajectories, localised = {}, {}
    for name, rows in samples.items():
        recorder = TrajectoryRecorder(capacity=len(rows), covariances=True)
        for time, pose, covariance, _ in rows:
            recorder.append(time, pose, covariance)
        trajectories[name] = recorder.to_trajectory()
        localised[name] = sum(fresh for *_, fresh in rows)
    return trajectories, localised


def write_detection_logs(logs: list[str], out_dir: Path, name: str) -> Path:
    """``out_dir/detections/<name % k>``: log ``k`` of ``logs`` (each a detection log's text,
    :mod:`moma_env.estimator.log`), each whole or not at all; ``name`` a %-pattern such as
    ``"run_%02d.jsonl"``. Returns the folder."""
    from moma_env.io import atomic_write_text

    log_dir = out_dir / "detections"
    log_dir.mkdir(parents=True, exist_ok=True)
    for k, text in enumerate(logs):
        atomic_write_text(log_dir / (name % k), text)
    return log_dir


def _fail(message: str) -> int:
    print(f"moma-env localise: {message}", file=sys.stderr)
    return 2


def truth_files(truth_dir: Path, robots: list[str]) -> dict[str, Path]:
    """Robot -> its ground-truth TUM file in ``truth_dir`` (``<robot>.tum``, else
    ``<robot>_truth.tum``), for the robots that have one."""
    found = {}
    for name in robots:
        safe = name.replace("/", "_")
        for candidate in (truth_dir / f"{safe}.tum", truth_dir / f"{safe}_truth.tum"):
            if candidate.is_file():
                found[name] = candidate
                break
    return found


def errors_against_truth(estimate: Trajectory, truth: Trajectory, max_dt: float) -> dict[str, float]:
    """The planar position errors of ``estimate`` against ``truth`` (m; see the module docstring)."""
    metrics = run_metrics(estimate, truth, max_dt=max_dt)
    return {
        "mean_error_m": metrics.mean_error,
        "final_error_m": metrics.final_error,
        "max_error_m": metrics.max_error,
        "rmse_m": metrics.rmse,
        "matched_fraction": metrics.valid_fraction,
    }


def run_localise_command(
    log_path: Path, out: Path, estimator: str, as_json: bool, truth_dir: Path | None = None, max_dt: float = 1e-6
) -> int:
    """The command (see the module docstring); its exit status (2: a log, estimator or truth that cannot be used)."""
    from moma_env.estimator.registry import localiser_factory
    from moma_env.io import RunFolderError, run_folder, to_jsonable, write_json

    try:
        log = read_detection_log(log_path)
    except (OSError, DetectionLogError) as err:
        return _fail(str(err))
    try:
        localiser = localiser_factory(estimator)(log.estimator)
    except ImportError as err:
        return _fail(f"estimator {estimator!r}: {err}")
    try:
        trajectories, localised = replay_trajectories(log, localiser)
    except (ValueError, TypeError, KeyError) as err:  # a call the estimator refuses: the log is not one it can run
        return _fail(f"{log_path}: the {estimator} estimator refused a record: {err}")
    against: dict[str, dict[str, float]] = {}
    if truth_dir is not None:
        truths = truth_files(truth_dir, list(trajectories))
        if not truths:
            names = ", ".join(f"{n}.tum or {n}_truth.tum" for n in trajectories)
            return _fail(f"--truth {truth_dir}: no ground-truth file of the log's robots ({names})")
        try:
            for name, path in truths.items():
                against[name] = errors_against_truth(trajectories[name], read_tum(path), max_dt)
        except (OSError, ValueError) as err:
            return _fail(f"--truth {path}: {err}")
    frames = [r for r in log.records if isinstance(r, FrameRecord)]
    summary = {
        "log": str(log_path),
        "estimator": estimator,
        "estimator_config": to_jsonable(log.estimator),
        "frames": len(frames),
        "detections": sum(len(r.detections) for r in frames),
        "robots": {
            name: {"samples": len(traj), "with_estimate": int(traj.valid.sum()), "localised": localised[name]}
            | ({"against_truth": against[name]} if name in against else {})
            for name, traj in trajectories.items()
        },
    }
    try:
        with run_folder(out, "localise") as run:
            files: dict[str, Path] = {}
            for name, traj in trajectories.items():
                if traj.valid.any():
                    path = run.path / f"{name.replace('/', '_')}.tum"
                    write_tum(path, traj)
                    write_covariances(covariance_path_for(path), traj)
                    files[name] = path
            write_json(run.path / "summary.json", summary)
            files = run.final(files)
    except RunFolderError as err:
        return _fail(str(err))
    if as_json:
        print(json.dumps(to_jsonable(summary | {"files": files}), indent=2, sort_keys=True))
    else:
        print(f"{log_path}: {summary['frames']} frames, {summary['detections']} detections, estimator {estimator}")
        print(f"{'robot':<16}{'samples':>9}{'estimated':>11}{'localised':>11}" + (f"{'ME cm':>9}{'E_f cm':>9}" if against else ""))
        for name, row in summary["robots"].items():
            errors = row.get("against_truth")
            extra = f"{100 * errors['mean_error_m']:>9.2f}{100 * errors['final_error_m']:>9.2f}" if errors else ""
            print(f"{name:<16}{row['samples']:>9}{row['with_estimate']:>11}{row['localised']:>11}" + extra)
        print("\n".join(f"{name}: {path}" for name, path in files.items()))
    return 0
