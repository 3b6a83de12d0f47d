"""Tables, figures and files of the square experiment (the presentation layer).

Kept apart from :mod:`training.experiments.square`, whose functions compute; this
module only formats and writes. Every file is written whole or not at all
(:mod:`moma_env.io`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from moma_env.io import atomic_path, write_json
from moma_env.metrics import position_errors, write_tum
from training.experiments.square import MAIN, METHODS, SquareConfig, SquareRun

__all__ = ["PAPER_SQUARE", "format_table", "write_outputs", "plot_run"]

#: The paper's reported square results (section IV; real robots, 10 runs), cm and %.
#: Shown beside ours for reference, never used in a computation.
PAPER_SQUARE = {
    "moma": {"ME_f_cm": 0.97, "ME_f_std_cm": 1.51, "ME_cm": 1.97, "ME_std_cm": 0.69, "pct_path": 0.2425},
    "viso2": {"ME_f_cm": 33.08, "ME_f_std_cm": 16.42, "ME_cm": 16.29, "ME_std_cm": 6.98, "pct_path": 8.27},
}

_LABELS = {"moma": "MOMA", "wheel": "wheel odometry", "viso2": "Viso2"}


def _cm(value: float) -> str:
    return "   n/a" if value is None or not math.isfinite(value) else f"{100.0 * value:6.2f}"


def format_table(summary: dict[str, dict], config: SquareConfig, n_completed: int, n_runs: int) -> str:
    """The paper-style table: ME_f, std, ME, std, % of path per method, and the paper's rows."""
    path_cm = 100.0 * config.path_length
    head = f"{'method':<28}{'ME_f cm':>9}{'std':>8}{'ME cm':>9}{'std':>8}{f'% of {path_cm:.0f} cm':>14}{'best E_f':>10}{'worst E_f':>10}"
    lines = [f"Square {config.side:g} m, {n_runs} runs ({n_completed} completed), observer: {config.observer}", head, "-" * len(head)]
    for method in METHODS:
        s = summary[method]
        lines.append(
            f"{_LABELS[method] + ' (ours)':<28}{_cm(s['mean_final_error']):>9}{_cm(s['std_final_error']):>8}"
            f"{_cm(s['mean_mean_error']):>9}{_cm(s['std_mean_error']):>8}{s['mean_final_error_pct_path']:>14.3f}"
            f"{_cm(s['best_final_error']):>10}{_cm(s['worst_final_error']):>10}"
        )
    for method, p in PAPER_SQUARE.items():
        lines.append(
            f"{_LABELS[method] + ' (paper, real)':<28}{p['ME_f_cm']:>9.2f}{p['ME_f_std_cm']:>8.2f}"
            f"{p['ME_cm']:>9.2f}{p['ME_std_cm']:>8.2f}{p['pct_path']:>14.3f}{'':>10}{'':>10}"
        )
    return "\n".join(lines)


def plot_run(run: SquareRun, path: Path) -> None:
    """Trajectory figure (truth, MOMA, wheel odometry, waypoints) and E(t) with switches."""
    fig = Figure(figsize=(12, 5.5), layout="constrained")
    ax, ax_err = fig.subplots(1, 2, width_ratios=[1.1, 1])
    main = run.trajectories[MAIN]
    buddy = run.trajectories.get("ugv_1")
    if buddy is not None:
        ax.plot(*buddy["truth"].xy.T, color="0.75", lw=1, label="second robot (truth)")
    ax.plot(*main["truth"].xy.T, "k--", lw=1.5, label="truth")
    ax.plot(*main["moma"].xy.T, color="tab:blue", lw=1.2, label="MOMA")
    ax.plot(*main["wheel"].xy.T, color="tab:red", lw=1.0, label="wheel odometry")
    wp = np.array(run.waypoints)
    ax.scatter(wp[:, 0], wp[:, 1], marker="^", s=70, color="gold", edgecolor="k", zorder=5, label="waypoints")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Main robot, seed {run.seed}")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)

    truth = main["truth"]
    for method, colour in (("moma", "tab:blue"), ("wheel", "tab:red")):
        err = position_errors(main[method], truth)
        ax_err.plot(truth.times, 100.0 * err, color=colour, label=_LABELS[method])
    for t in run.switch_times:
        ax_err.axvline(t, color="0.6", lw=0.6, ls=":")
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("position error E(t) [cm]")
    ax_err.set_yscale("log")
    ax_err.set_title("Error over time (dotted: main robot's switches)")
    ax_err.legend(loc="best", fontsize=8)
    ax_err.grid(alpha=0.3, which="both")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")


def write_outputs(runs: list[SquareRun], summary: dict[str, dict], config: SquareConfig, out_dir: Path) -> dict[str, Path]:
    """Write the TUM trajectories, the summary JSON and the figure into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for k, run in enumerate(runs):
        run_dir = out_dir / "tum" / f"run_{k:02d}"
        run_dir.mkdir(parents=True, exist_ok=True)
        for robot, trajs in run.trajectories.items():
            for method, traj in trajs.items():
                if np.any(traj.valid):
                    write_tum(run_dir / f"{robot.replace('/', '_')}_{method}.tum", traj)
    paths = {"figure": out_dir / "square.png", "summary": out_dir / "summary.json", "tum": out_dir / "tum"}
    plot_run(runs[0], paths["figure"])
    write_json(paths["summary"], results_dict(runs, summary, config))
    return paths


def results_dict(runs: list[SquareRun], summary: dict[str, dict], config: SquareConfig) -> dict:
    """Everything a reader needs to reproduce the table, as plain JSON data."""
    return {
        "experiment": "square",
        "side_m": config.side,
        "path_length_m": config.path_length,
        "observer": config.observer,
        "n_runs": len(runs),
        "n_completed": sum(r.completed for r in runs),
        "summary": summary,
        "runs": [
            {
                "seed": r.seed,
                "completed": r.completed,
                "duration_s": r.duration_s,
                "n_switches_main": len(r.switch_times),
                "metrics": {m: r.metrics[m].to_dict() for m in METHODS},
            }
            for r in runs
        ],
        "paper": PAPER_SQUARE,
    }
