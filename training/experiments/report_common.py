"""Presentation helpers shared by the experiments' reports (square, line).

Formatting of distances, the methods' labels and colours, the TUM files of every
run, the per-run JSON record and figure saving. Every file is written whole or
not at all (:mod:`moma_env.io`).
"""

from __future__ import annotations

import dataclasses

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from moma_env.io import atomic_path, write_csv, write_json
from moma_env.metrics import covariance_path_for, write_covariances, write_tum
from training.experiments.leapfrog_run import MAIN, LeapfrogConfig, LeapfrogRun
from training.figure_layout import legend_below

__all__ = ["LABELS", "COLOURS", "cm", "pct", "write_run_tums", "run_record", "config_record", "results_base",
           "write_experiment_files", "save_figure", "plot_observer_errors"]

#: Display names of the localisation methods (ours and the paper's).
LABELS = {"moma": "MOMA", "wheel": "wheel odometry", "vo": "visual odometry", "viso2": "Viso2"}
#: Plot colours of the methods (the paper's: MOMA blue, VO red, truth black dashed).
COLOURS = {"moma": "tab:blue", "vo": "tab:red", "wheel": "tab:green"}


def cm(value: float | None, width: int = 6) -> str:
    """A distance in metres as centimetres with two decimals, ``n/a`` if unknown."""
    if value is None or not math.isfinite(value):
        return "n/a".rjust(width)
    return f"{100.0 * value:{width}.2f}"


def pct(value: float | None, width: int = 6, digits: int = 3) -> str:
    """A percentage with ``digits`` decimals, ``n/a`` if unknown."""
    if value is None or not math.isfinite(value):
        return "n/a".rjust(width)
    return f"{value:{width}.{digits}f}"


def write_run_tums(runs: list[LeapfrogRun], out_dir: Path) -> Path:
    """``out_dir/tum/run_XX/<robot>_<method>.tum`` for every trajectory with a valid sample.

    A trajectory that carries covariances (MOMA's) also gets
    ``<robot>_<method>.cov.txt``, line for line beside its TUM file
    (:mod:`moma_env.metrics.tum_covariance`).
    """
    tum_dir = out_dir / "tum"
    for k, run in enumerate(runs):
        run_dir = tum_dir / f"run_{k:02d}"
        run_dir.mkdir(parents=True, exist_ok=True)
        for robot, trajs in run.trajectories.items():
            for method, traj in trajs.items():
                if np.any(traj.valid):
                    path = run_dir / f"{robot.replace('/', '_')}_{method}.tum"
                    write_tum(path, traj)
                    if traj.covariances is not None:
                        write_covariances(covariance_path_for(path), traj)
    return tum_dir


def config_record(config: LeapfrogConfig) -> dict:
    """The settings a reader needs to reproduce a run, as plain JSON data."""
    return {
        "camera_backend": config.camera_backend,
        "observer": config.observer,
        "planar_ugvs": config.planar_ugvs,
        "altitude_m": config.altitude,
        "separation_m": config.separation,
        "dwell_s": config.dwell_s,
        "path_length_m": config.path_length,
        "camera": {
            "width": config.camera.width, "height": config.camera.height, "fx": config.camera.fx, "fy": config.camera.fy,
            "cx": config.camera.cx, "cy": config.camera.cy, "dist": list(config.camera.dist), "noise_px": config.camera.noise_px,
        },
        "board": {"marker_size_m": config.board.marker_size, "gap_m": config.board.gap},
        "floor_grain": None if config.floor.grain is None else dataclasses.asdict(config.floor.grain),
    }


def run_record(run: LeapfrogRun) -> dict:
    """One run's outcome and per-method metrics, as plain JSON data."""
    return {
        "seed": run.seed,
        "completed": run.completed,
        "duration_s": run.duration_s,
        "n_switches_main": len(run.switch_times),
        "lost_at_s": dict(run.lost_at),
        "metrics": {m: run.metrics[m].to_dict() for m in run.methods},
    }


def results_base(experiment: str, runs: list[LeapfrogRun], summary: dict[str, dict], config: LeapfrogConfig) -> dict:
    """What every experiment's JSON holds: its name, settings, summary and runs."""
    return {
        "experiment": experiment,
        "path_length_m": config.path_length,
        "observer": config.observer,
        "config": config_record(config),
        "n_runs": len(runs),
        "n_completed": sum(r.completed for r in runs),
        "summary": summary,
        "runs": [run_record(r) for r in runs],
    }


def write_experiment_files(
    out_dir: Path,
    runs: list[LeapfrogRun],
    figure: tuple[str, Callable[[Path], None]],
    table: tuple[str, list[dict[str, object]]],
    results: dict,
) -> dict[str, Path]:
    """Write an experiment's files into ``out_dir``, each whole or not at all; return their paths.

    Args:
        out_dir: the output folder (created).
        runs: the runs (their TUM trajectories go to ``tum/run_XX/``).
        figure: ``(file name, draw(path))``.
        table: ``(file name, rows)`` of the CSV table.
        results: the JSON summary, written last (``summary.json``).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"figure": out_dir / figure[0], "summary": out_dir / "summary.json", "table": out_dir / table[0]}
    paths["tum"] = write_run_tums(runs, out_dir)
    figure[1](paths["figure"])
    write_csv(paths["table"], table[1])
    write_json(paths["summary"], results)
    return paths


def save_figure(fig: Figure, path: Path, dpi: int = 110) -> None:
    """Write ``fig`` as a PNG at ``path``, whole or not at all."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")


def plot_observer_errors(runs_by_observer: dict[str, list[LeapfrogRun]], path: Path) -> None:
    """The paper's observer comparison: MOMA's E(t) of the main robot under each observer.

    One line per run (thin) and the mean over runs on a common time base where
    every run is still going (thick); time in s, error in cm.
    """
    from moma_env.metrics import position_errors

    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    colours = {"quadcopter": "tab:blue", "handheld": "tab:orange"}
    for observer, runs in runs_by_observer.items():
        colour = colours.get(observer, "tab:gray")
        curves = []
        for run in runs:
            truth = run.trajectories[MAIN]["truth"]
            err = 100.0 * position_errors(run.trajectories[MAIN]["moma"], truth)
            ax.plot(truth.times, err, color=colour, lw=0.5, alpha=0.35)
            curves.append((truth.times, err))
        n = min(len(t) for t, _ in curves)
        mean = np.nanmean(np.stack([e[:n] for _, e in curves]), axis=0)
        ax.plot(curves[0][0][:n], mean, color=colour, lw=2.0, label=f"{observer}: mean of {len(runs)} runs")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("MOMA position error E(t) [cm]")
    ax.set_title("Main robot's error: UAV observer vs hand-held camera")
    ax.grid(alpha=0.3)
    legend_below(fig, [ax], [(Line2D([], [], color="0.5", lw=0.5), "one run")])
    save_figure(fig, path)
