"""Table, figures and files of the consistency study (the presentation layer).

Kept apart from :mod:`training.experiments.consistency`, which computes; this
module only formats and writes. Every file is written whole or not at all
(:mod:`moma_env.io`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from moma_env.io import write_csv, write_json
from moma_env.metrics import pose_errors
from moma_env.metrics.consistency import matched_covariances
from training.experiments.consistency import CaseResult
from training.experiments.leapfrog_run import MAIN
from training.experiments.report_common import config_record, save_figure
from training.figure_layout import legend_below

__all__ = ["DEFINITION", "format_table", "plot_case", "figure_name", "write_outputs", "results_dict", "steps_rows"]

#: What the numbers are, for the JSON and the table's footer.
DEFINITION = (
    "Main robot's MOMA estimate, samples where it is LOCALISED. NEES = e^T P^-1 e of the position error (x, y: 2 dof "
    "planar; x, y, z: 3 dof 6-DoF) and of the heading error (rotation about world z, 1 dof), e in the world frame, "
    "rotation perturbed on the left. ANEES_k = mean NEES over the N_k runs with a value at time step k, divided by the "
    "dof (1 when consistent); bounds chi2.ppf({lo}, N_k d) / (N_k d), chi2.ppf({hi}, N_k d) / (N_k d). 'ANEES' is the "
    "mean of ANEES_k over the steps, 'inside' the fraction of steps inside their bounds. Samples whose covariance block "
    "is singular (the zero covariance of a pose frozen from the known initial pose) are skipped and counted."
)


def _definition(confidence: float) -> str:
    a = (1.0 - confidence) / 2.0
    return DEFINITION.format(lo=f"{a:g}", hi=f"{1.0 - a:g}")


def _num(value: float, width: int, digits: int = 2) -> str:
    return f"{value:{width}.{digits}f}" if math.isfinite(value) else "n/a".rjust(width)


def _pct(fraction: float, width: int) -> str:
    return f"{100 * fraction:{width - 1}.1f}%" if math.isfinite(fraction) else "n/a".rjust(width)


def format_table(results: list[CaseResult]) -> str:
    """One row per case: runs, position and heading ANEES, nominal bounds, fraction inside, skipped samples."""
    head = (
        f"{'case':<28}{'runs':>5}{'done':>5}{'pos d':>6}{'pos ANEES':>10}{'bounds':>14}{'inside':>8}"
        f"{'head ANEES':>11}{'bounds':>14}{'inside':>8}{'skipped':>9}"
    )
    lines = ["MOMA consistency (main robot, LOCALISED samples)", head, "-" * len(head)]
    for r in results:
        p, h = r.position, r.heading
        plo, phi = p.nominal_bounds
        hlo, hhi = h.nominal_bounds
        lines.append(
            f"{r.case.name:<28}{r.case.n_runs:>5}{r.n_completed:>5}{p.dof:>6}{_num(p.mean_anees, 10)}"
            f"{f'[{plo:.2f}, {phi:.2f}]':>14}{_pct(p.fraction_inside, 8)}"
            f"{_num(h.mean_anees, 11)}{f'[{hlo:.2f}, {hhi:.2f}]':>14}{_pct(h.fraction_inside, 8)}{p.n_singular:>9}"
        )
    if results and any(r.position.n_steps == 0 for r in results):
        lines.append("n/a: no LOCALISED sample with a non-singular covariance (do the detections carry a covariance?)")
    if results:
        lines.append(f"bounds: the {100 * results[0].position.confidence:g} % chi-square bounds of ANEES_k with all runs; "
                     "inside: fraction of time steps inside their bounds; skipped: samples with a singular position covariance")
    return "\n".join(lines)


def figure_name(result: CaseResult) -> str:
    """``square_planar_geometric.png`` for the case ``square/planar/geometric``."""
    return result.case.name.replace("/", "_") + ".png"


def plot_case(result: CaseResult, path: Path) -> None:
    """The first run's errors against their 2-sigma envelopes (x, y in cm, heading in deg) and ANEES_k over time.

    Errors are drawn where MOMA is LOCALISED; the envelope is +-2 sqrt of the
    matching diagonal entry of its covariance (world frame). The bottom panel is
    ANEES_k of position and heading with their chi-square bounds.
    """
    run = result.runs[0]
    main = run.trajectories[MAIN]
    truth, moma = main["truth"], main["moma"]
    usable = run.localised[MAIN]
    err = pose_errors(moma, truth)
    cov = matched_covariances(moma, truth)
    err[~usable] = np.nan
    sigma = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
    sigma[~usable] = np.nan
    t = truth.times

    fig = Figure(figsize=(11, 10), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    panels = ((0, "x error [cm]", 100.0), (1, "y error [cm]", 100.0), (5, "heading error [deg]", 180.0 / math.pi))
    for ax, (k, label, scale) in zip(axes[:3], panels):
        ax.fill_between(t, -2 * scale * sigma[:, k], 2 * scale * sigma[:, k], color="tab:blue", alpha=0.2, lw=0, label="±2σ (MOMA)")
        ax.plot(t, scale * err[:, k], color="tab:blue", lw=0.9, label="error (truth − estimate)")
        for s in run.switch_times:
            ax.axvline(s, color="0.6", lw=0.5, ls=":")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{result.case.name}: main robot, seed {run.seed}")

    ax = axes[3]
    for avg, colour, label in ((result.position, "tab:blue", f"position ({result.position.dof} dof)"),
                               (result.heading, "tab:orange", "heading (1 dof)")):
        s = avg.steps
        ax.plot(avg.times[s], avg.anees[s], color=colour, lw=0.8, label=f"ANEES {label}")
        ax.plot(avg.times[s], avg.lower[s], color=colour, lw=0.8, ls="--")
        ax.plot(avg.times[s], avg.upper[s], color=colour, lw=0.8, ls="--")
    ax.axhline(1.0, color="k", lw=0.6)
    if result.position.n_steps or result.heading.n_steps:
        ax.set_yscale("log")
    ax.set_ylabel(f"ANEES over {result.case.n_runs} runs")
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3, which="both")
    extra = [(Line2D([], [], color="0.3", lw=0.8, ls="--"), "ANEES 95 % bounds"), (Line2D([], [], color="0.6", lw=0.8, ls=":"), "main robot's switch")]
    legend_below(fig, [axes[0], ax], extra, ncol=3)
    save_figure(fig, path)


def steps_rows(results: list[CaseResult]) -> list[dict[str, object]]:
    """One CSV row per case and time step with a NEES: runs N_k, ANEES_k and bounds of position and heading."""
    rows = []
    for r in results:
        p, h = r.position, r.heading
        for k in np.flatnonzero(p.steps | h.steps):
            rows.append({
                "case": r.case.name, "time_s": float(p.times[k]),
                "position_runs": int(p.counts[k]), "position_anees": float(p.anees[k]),
                "position_lower": float(p.lower[k]), "position_upper": float(p.upper[k]),
                "heading_runs": int(h.counts[k]), "heading_anees": float(h.anees[k]),
                "heading_lower": float(h.lower[k]), "heading_upper": float(h.upper[k]),
            })
    return rows


_STEP_FIELDS = ("case", "time_s", "position_runs", "position_anees", "position_lower", "position_upper",
                "heading_runs", "heading_anees", "heading_lower", "heading_upper")


def results_dict(results: list[CaseResult], seed: int) -> dict:
    """Everything a reader needs to reproduce the table, as plain JSON data."""
    confidence = results[0].position.confidence if results else 0.95
    return {
        "experiment": "consistency",
        "seed": seed,
        "confidence": confidence,
        "definition": _definition(confidence),
        "cases": {
            r.case.name: {
                "experiment": r.case.experiment,
                "mode": r.case.mode,
                "camera_backend": r.case.camera,
                "n_runs": r.case.n_runs,
                "n_completed": r.n_completed,
                "seeds": [run.seed for run in r.runs],
                "config": config_record(r.case.config),
                "position": r.position.to_dict(),
                "heading": r.heading.to_dict(),
                "figure": figure_name(r),
            }
            for r in results
        },
    }


def write_outputs(results: list[CaseResult], seed: int, out_dir: Path) -> dict[str, Path]:
    """Write a figure per case, ``steps.csv`` (ANEES_k per step) and ``summary.json`` (last) into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    for r in results:
        paths[f"figure {r.case.name}"] = out_dir / figure_name(r)
        plot_case(r, paths[f"figure {r.case.name}"])
    paths["steps"] = out_dir / "steps.csv"
    write_csv(paths["steps"], steps_rows(results), fieldnames=_STEP_FIELDS)
    paths["summary"] = out_dir / "summary.json"
    write_json(paths["summary"], results_dict(results, seed))
    return paths
