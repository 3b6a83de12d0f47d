"""Tables, figures and files of the line experiment (the presentation layer).

Kept apart from :mod:`training.experiments.line`, whose functions compute; this
module only formats and writes, whole or not at all (:mod:`moma_env.io`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from training.experiments.leapfrog_run import MAIN, LeapfrogRun
from training.experiments.line import LineConfig, line_metrics
from training.experiments.report_common import COLOURS, LABELS, cm, pct, results_base, save_figure, write_experiment_files
from training.figure_layout import legend_below

__all__ = ["PAPER_LINE", "format_table", "format_keypoints", "plot_run", "write_outputs", "results_dict"]

#: The paper's line result (section IV; one real run), cm and %. "Single keypoint
#: errors up to 10 cm" is read off its figure of the keypoint errors. Shown beside
#: ours for reference, never used in a computation.
PAPER_LINE = {"path_length_m": 13.785, "n_keypoints": 18, "final_error_cm": 7.8, "pct_path": 0.56, "max_abs_keypoint_x_error_cm": 10.0}


def format_table(summary: dict[str, dict], config: LineConfig, n_completed: int, n_runs: int) -> str:
    """Final error, % of path, keypoint and relative errors per method, and the paper's row."""
    head = (
        f"{'method':<32}{'E_f cm':>8}{'std':>7}{f'% of {config.path_length:g} m':>15}"
        f"{'|kp x| cm':>11}{'max':>7}{'rel cm':>8}{'max':>7}{'lost':>7}"
    )
    title = (
        f"Line {config.length:g} m x {config.passes} passes ({config.path_length:g} m), {config.n_keypoints} keypoints, "
        f"{n_runs} runs ({n_completed} completed), observer: {config.observer}, camera: {config.camera_backend}"
    )
    lines = [title, head, "-" * len(head)]
    for method, s in summary.items():
        lines.append(
            f"{LABELS[method] + ' (ours)':<32}{cm(s['mean_final_error']):>8}{cm(s['std_final_error']):>7}"
            f"{pct(s['mean_final_error_pct_path']):>15}{cm(s['mean_abs_keypoint_x_error']):>11}{cm(s['max_abs_keypoint_x_error']):>7}"
            f"{cm(s['mean_relative_error']):>8}{cm(s['max_relative_error']):>7}{100 * s['track_loss_rate']:>6.0f}%"
        )
    p = PAPER_LINE
    lines.append(
        f"{'MOMA (paper, real robots, 1 run)':<32}{p['final_error_cm']:>8.2f}{'':>7}{p['pct_path']:>15.3f}"
        f"{'':>11}{p['max_abs_keypoint_x_error_cm']:>7.1f}{'':>8}{'':>7}{'':>7}"
    )
    return "\n".join(lines)


def format_keypoints(run: LeapfrogRun) -> str:
    """One row per keypoint of ``run``: time, true x, each method's x error and relative error (cm)."""
    per_method = {method: line_metrics(run, method) for method in run.methods}
    first = next(iter(per_method.values()))
    head = f"{'kp':>3}{'time s':>9}{'true x m':>10}" + "".join(f"{LABELS[m][:10] + ' dx':>15}{'rel':>8}" for m in run.methods)
    lines = [f"Keypoints of the run with seed {run.seed} (dx = estimated - true x, rel = error in the distance from the previous keypoint; cm)", head]
    for k, t in enumerate(first.keypoint_times):
        row = f"{k + 1:>3}{t:>9.1f}{first.true_x[k]:>10.3f}"
        for m in run.methods:
            row += f"{cm(per_method[m].x_errors[k], 15)}{cm(per_method[m].relative_errors[k], 8)}"
        lines.append(row)
    return "\n".join(lines)


def plot_run(run: LeapfrogRun, config: LineConfig, path: Path) -> None:
    """The paper's three line figures for one run, as panels of one PNG.

    Left: x(t) of the main robot over the first pass (truth, the methods; the
    pass's keypoints as vertical lines). Middle: x error at every keypoint.
    Right: |error in the distance between consecutive keypoints|.
    """
    fig = Figure(figsize=(15, 4.8), layout="constrained")
    ax_x, ax_kp, ax_rel = fig.subplots(1, 3)
    main = run.trajectories[MAIN]
    per_method = {method: line_metrics(run, method) for method in run.methods}
    first_pass = run.switch_times[: config.switches_per_pass]
    end = first_pass[-1] if first_pass else main["truth"].times[-1]
    truth = main["truth"].window(main["truth"].times[0], end)
    ax_x.plot(truth.times, truth.xy[:, 0], "k--", lw=1.5, label="truth")
    for method in run.methods:
        est = main[method].window(truth.times[0], end)
        ax_x.plot(est.times, est.xy[:, 0], color=COLOURS[method], lw=1.1, label=LABELS[method])
    for t in first_pass:
        ax_x.axvline(t, color="0.5", lw=0.7)
    ax_x.set_xlabel("time [s]")
    ax_x.set_ylabel("x [m]")
    ax_x.set_title(f"First pass (1/{config.passes}), seed {run.seed}")
    ax_x.grid(alpha=0.3)

    n_methods = len(run.methods)
    width = 0.8 / n_methods
    for i, method in enumerate(run.methods):
        m = per_method[method]
        k = np.arange(1, len(m.x_errors) + 1) + (i - (n_methods - 1) / 2) * width
        ax_kp.bar(k, 100.0 * np.asarray(m.x_errors), width=width, color=COLOURS[method], label=LABELS[method])
        ax_rel.bar(k, 100.0 * np.asarray(m.relative_errors), width=width, color=COLOURS[method], label=LABELS[method])
    for ax, title, ylabel in (
        (ax_kp, "x error at every keypoint", "estimated - true x [cm]"),
        (ax_rel, "error in the distance between keypoints", "|relative error| [cm]"),
    ):
        for p in range(1, config.passes):
            ax.axvline(p * config.switches_per_pass + 0.5, color="0.5", lw=0.7, ls=":")
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xticks(range(1, len(run.switch_times) + 1))
        ax.set_xlabel("keypoint")
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(alpha=0.3, axis="y")
    extra = [(Line2D([], [], color="0.5", lw=0.7), "keypoint (a switch)"), (Line2D([], [], color="0.5", lw=0.7, ls=":"), "end of a pass")]
    legend_below(fig, [ax_x, ax_kp], extra)
    save_figure(fig, path)


def _keypoint_rows(runs: list[LeapfrogRun]) -> list[dict[str, object]]:
    """One CSV row per run, method and keypoint (s, m)."""
    rows = []
    for r, run in enumerate(runs):
        for method in run.methods:
            m = line_metrics(run, method)
            for k, t in enumerate(m.keypoint_times):
                rows.append(
                    {
                        "run": r,
                        "seed": run.seed,
                        "method": method,
                        "keypoint": k + 1,
                        "time_s": t,
                        "true_x_m": m.true_x[k],
                        "estimated_x_m": m.estimated_x[k],
                        "x_error_m": m.x_errors[k],
                        "position_error_m": m.position_errors[k],
                        "relative_error_m": m.relative_errors[k],
                    }
                )
    return rows


def write_outputs(runs: list[LeapfrogRun], summary: dict[str, dict], config: LineConfig, out_dir: Path) -> dict[str, Path]:
    """Write the TUM trajectories, ``keypoints.csv``, ``summary.json`` and ``line.png`` into ``out_dir``."""
    return write_experiment_files(
        out_dir,
        runs,
        ("line.png", lambda path: plot_run(runs[0], config, path)),
        ("keypoints.csv", _keypoint_rows(runs)),
        results_dict(runs, summary, config),
    )


def results_dict(runs: list[LeapfrogRun], summary: dict[str, dict], config: LineConfig) -> dict:
    """Everything a reader needs to reproduce the table, as plain JSON data (with every run's keypoint errors)."""
    data = results_base("line", runs, summary, config)
    for record, run in zip(data["runs"], runs):
        record["keypoints"] = {m: line_metrics(run, m).to_dict() for m in run.methods}
    return data | {"length_m": config.length, "passes": config.passes, "switches_per_pass": config.switches_per_pass, "paper": PAPER_LINE}
