"""Tables, figures and files of the square experiment (the presentation layer).

Kept apart from :mod:`training.experiments.square`, whose functions compute; this
module only formats and writes. Every file is written whole or not at all
(:mod:`moma_env.io`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from moma_env.metrics import position_errors
from training.experiments.leapfrog_run import BUDDY, MAIN, LeapfrogRun
from training.experiments.report_common import COLOURS, LABELS, cm, pct, results_base, save_figure, write_experiment_files
from training.experiments.square import SquareConfig
from training.figure_layout import legend_below, zoom_inset

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
    """The paper's figure (truth, MOMA, the baselines, waypoints) and E(t) with the switches.

    An inset in the middle of the square shows the main robot's final position in mm,
    MOMA against the truth (and the baselines) at the scale of MOMA's final error; one
    legend below the panels.
    """
    fig = Figure(figsize=(12, 6), layout="constrained")
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
    ax.grid(alpha=0.3)
    _final_position_inset(ax, run, wp)

    truth = main["truth"]
    positive = False
    for method in run.methods:
        err = 100.0 * position_errors(main[method], truth)
        positive |= bool(np.any(err[np.isfinite(err)] > 0.0))
        ax_err.plot(truth.times, err, color=COLOURS[method], label=LABELS[method])
        if run.lost_at[method] is not None:
            ax_err.axvline(run.lost_at[method], color=COLOURS[method], lw=1.0, ls="--")
    for t in run.switch_times:
        ax_err.axvline(t, color="0.6", lw=0.6, ls=":")
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("position error E(t) [cm]")
    if positive:
        ax_err.set_yscale("log")
    ax_err.set_title("Main robot's position error over time")
    ax_err.grid(alpha=0.3, which="both")
    extra = [(Line2D([], [], color="0.6", lw=0.8, ls=":"), "main robot's switch")]
    if any(run.lost_at[m] is not None for m in run.methods):
        extra.append((Line2D([], [], color="0.3", lw=1.0, ls="--"), "track lost"))
    legend_below(fig, [ax, ax_err], extra)
    save_figure(fig, path)


def _final_position_inset(ax, run: LeapfrogRun, waypoints: np.ndarray) -> None:
    """Zoom on the main robot's final position inside the square: truth, MOMA and the
    baselines in mm around the true final position, the window 2.5 times MOMA's final
    error (at least 2 mm) on each side."""
    main = run.trajectories[MAIN]
    truth_end = main["truth"].xy[-1]
    moma_end = main["moma"].xy[-1] if "moma" in main else truth_end
    error = float(np.linalg.norm(moma_end - truth_end)) if np.all(np.isfinite(moma_end)) else 0.0
    half = max(2.5 * error, 0.002)
    low, high = waypoints.min(axis=0), waypoints.max(axis=0)
    side = float(np.min(high - low))
    if not side > 0.0:
        return
    curves = [(main["truth"].xy, {"color": "k", "ls": "--", "lw": 1.2})]
    curves += [(main[m].xy, {"color": COLOURS[m], "lw": 1.2 if m == "moma" else 0.9}) for m in run.methods]
    corner = low + 0.2 * (high - low)
    inset = zoom_inset(ax, curves, truth_end, half, (corner[0], corner[1], 0.6 * side, 0.6 * side),
                       f"final position: MOMA {100 * error:.2f} cm off")
    inset.plot([0.0], [0.0], "o", color="k", ms=4)
    offset = 1000.0 * (moma_end - truth_end)
    inset.plot([offset[0]], [offset[1]], "x", color=COLOURS["moma"], ms=6, mew=1.5)


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
