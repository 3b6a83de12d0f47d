"""Tables, figures and files of the square experiment (the presentation layer).

Kept apart from :mod:`training.experiments.square`, whose functions compute; this
module only formats and writes. Every file is written whole or not at all
(:mod:`moma_env.io`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from moma_env.metrics import position_errors
from training.experiments.leapfrog_run import BUDDY, MAIN, LeapfrogRun
from training.experiments.report_common import COLOURS, LABELS, cm, pct, results_base, save_figure, write_experiment_files
from training.experiments.square import SquareConfig

__all__ = ["PAPER_SQUARE", "format_table", "write_outputs", "plot_run", "results_dict"]

#: The paper's reported square results (section IV; real robots, 10 runs), cm and %.
#: Viso2's statistics cover only the runs where it kept track ("almost 40 %" lost it).
#: Shown beside ours for reference, never used in a computation.
PAPER_SQUARE = {
    "moma": {"ME_f_cm": 0.97, "ME_f_std_cm": 1.51, "ME_cm": 1.97, "ME_std_cm": 0.69, "pct_path": 0.2425, "best_pct_path": 0.12, "track_loss_rate": 0.0},
    "viso2": {"ME_f_cm": 33.08, "ME_f_std_cm": 16.42, "ME_cm": 16.29, "ME_std_cm": 6.98, "pct_path": 8.27, "best_pct_path": 1.32, "track_loss_rate": 0.4},
}


def format_table(summary: dict[str, dict], config: SquareConfig, n_completed: int, n_runs: int) -> str:
    """The paper-style table: ME_f, std, ME, std, % of path, track loss per method, and the paper's rows.

    Statistics of a method cover every run with a known final error; a method
    that lost track in some runs gets a second row over the runs where it kept
    track (the paper's convention for Viso2).
    """
    path_cm = 100.0 * config.path_length
    head = (
        f"{'method':<32}{'ME_f cm':>9}{'std':>8}{'ME cm':>9}{'std':>8}{f'% of {path_cm:.0f} cm':>14}"
        f"{'best %':>8}{'worst E_f':>10}{'lost':>7}"
    )
    title = f"Square {config.side:g} m, {n_runs} runs ({n_completed} completed), observer: {config.observer}, camera: {config.camera_backend}"
    lines = [title, head, "-" * len(head)]
    for method, s in summary.items():
        lines.append(_row(f"{LABELS[method]} (ours)", s, s["track_loss_rate"]))
        if s["track_loss_rate"] > 0.0:
            kept = s["kept_track"]
            lines.append(_row(f"  {LABELS[method]}, kept track", kept, 0.0) if kept else f"  {LABELS[method]}, kept track: no run")
    for method, p in PAPER_SQUARE.items():
        lines.append(
            f"{LABELS[method] + ' (paper, real robots)':<32}{p['ME_f_cm']:>9.2f}{p['ME_f_std_cm']:>8.2f}"
            f"{p['ME_cm']:>9.2f}{p['ME_std_cm']:>8.2f}{p['pct_path']:>14.3f}{p['best_pct_path']:>8.2f}{'':>10}{100 * p['track_loss_rate']:>6.0f}%"
        )
    return "\n".join(lines)


def _row(label: str, s: dict, track_loss_rate: float) -> str:
    return (
        f"{label:<32}{cm(s['mean_final_error']):>9}{cm(s['std_final_error']):>8}"
        f"{cm(s['mean_mean_error']):>9}{cm(s['std_mean_error']):>8}{pct(s['mean_final_error_pct_path']):>14}"
        f"{pct(s['best_final_error_pct_path'], digits=2):>8}{cm(s['worst_final_error']):>10}{100 * track_loss_rate:>6.0f}%"
    )


def plot_run(run: LeapfrogRun, path: Path) -> None:
    """The paper's figure (truth, MOMA, the baselines, waypoints) and E(t) with the switches."""
    fig = Figure(figsize=(12, 5.5), layout="constrained")
    ax, ax_err = fig.subplots(1, 2, width_ratios=[1.1, 1])
    main = run.trajectories[MAIN]
    buddy = run.trajectories.get(BUDDY)
    if buddy is not None:
        ax.plot(*buddy["truth"].xy.T, color="0.75", lw=1, label="second robot (truth)")
    ax.plot(*main["truth"].xy.T, "k--", lw=1.5, label="truth")
    for method in run.methods:
        ax.plot(*main[method].xy.T, color=COLOURS[method], lw=1.2 if method == "moma" else 1.0, label=LABELS[method])
    wp = np.array(run.waypoints)
    ax.scatter(wp[:, 0], wp[:, 1], marker="^", s=70, color="gold", edgecolor="k", zorder=5, label="waypoints")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Main robot, seed {run.seed}")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)

    truth = main["truth"]
    for method in run.methods:
        ax_err.plot(truth.times, 100.0 * position_errors(main[method], truth), color=COLOURS[method], label=LABELS[method])
        if run.lost_at[method] is not None:
            ax_err.axvline(run.lost_at[method], color=COLOURS[method], lw=1.0, ls="--")
    for t in run.switch_times:
        ax_err.axvline(t, color="0.6", lw=0.6, ls=":")
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("position error E(t) [cm]")
    ax_err.set_yscale("log")
    ax_err.set_title("Error over time (dotted: main robot's switches, dashed: track lost)")
    ax_err.legend(loc="best", fontsize=8)
    ax_err.grid(alpha=0.3, which="both")
    save_figure(fig, path)


def _runs_rows(runs: list[LeapfrogRun]) -> list[dict[str, object]]:
    """One CSV row per run and method: E_f, ME, % of path, track loss (m, %, s)."""
    return [
        {
            "run": k,
            "seed": run.seed,
            "completed": run.completed,
            "method": method,
            "final_error_m": run.metrics[method].final_error,
            "mean_error_m": run.metrics[method].mean_error,
            "final_error_pct_path": run.metrics[method].final_error_pct_path,
            "lost_at_s": run.lost_at[method],
        }
        for k, run in enumerate(runs)
        for method in run.methods
    ]


def write_outputs(runs: list[LeapfrogRun], summary: dict[str, dict], config: SquareConfig, out_dir: Path) -> dict[str, Path]:
    """Write the TUM trajectories, ``runs.csv``, ``summary.json`` and ``square.png`` into ``out_dir``."""
    return write_experiment_files(
        out_dir, runs, ("square.png", lambda path: plot_run(runs[0], path)), ("runs.csv", _runs_rows(runs)), results_dict(runs, summary, config)
    )


def results_dict(runs: list[LeapfrogRun], summary: dict[str, dict], config: SquareConfig) -> dict:
    """Everything a reader needs to reproduce the table, as plain JSON data."""
    return results_base("square", runs, summary, config) | {"side_m": config.side, "paper": PAPER_SQUARE}
