"""Files and tables of an evaluation (the presentation layer of :mod:`.harness`).

``write_outputs(result, out_dir)`` writes, each file whole or not at all
(:mod:`moma_env.io`): ``summary.json``, ``episodes.csv``,
``tum/ep_XXX/<robot>_{truth,moma}.tum`` and the figure ``<scenario>.png``
(trajectories of the first episode, and E(t) with the switch instants).
"""

from __future__ import annotations

import math
from pathlib import Path

from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from moma_env.io import atomic_path, write_csv, write_json
from moma_env.metrics import position_errors, write_tum
from training.evaluation.episode import EpisodeResult
from training.evaluation.harness import EvaluationResult
from training.figure_layout import legend_below

__all__ = ["write_outputs", "plot_episode", "format_table"]

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def plot_episode(episode: EpisodeResult, title: str, path: Path) -> None:
    """Left: every robot's truth (dashed) and MOMA estimate, goals (stars); right: E(t), switches dotted."""
    fig = Figure(figsize=(12, 5.5), layout="constrained")
    ax, ax_err = fig.subplots(1, 2, width_ratios=[1.1, 1])
    for k, (name, r) in enumerate(episode.robots.items()):
        colour = _COLOURS[k % len(_COLOURS)]
        ax.plot(*r.truth.xy.T, "--", color=colour, lw=1.2, alpha=0.8)
        ax.plot(*r.moma.xy.T, color=colour, lw=1.0)
        goal = episode.goals.get(name)
        if goal is not None:
            ax.scatter([goal[0]], [goal[1]], marker="*", s=120, color=colour, edgecolor="k", zorder=5)
        err = position_errors(r.moma, r.truth)
        ax_err.plot(r.truth.times, 100.0 * err, color=colour, lw=1.0, label=name)
        for t in r.switch_times:
            ax_err.axvline(t, color=colour, lw=0.6, ls=":", alpha=0.7)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{title}: episode {episode.index} (seed {episode.seed}), {'success' if episode.success else 'no success'}", wrap=True)
    ax.grid(alpha=0.3)
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("position error E(t) [cm]")
    ax_err.set_title("MOMA error over time")
    ax_err.grid(alpha=0.3)
    extra = [(Line2D([], [], color="0.4", ls="--", lw=1.2), "truth (dashed)"), (Line2D([], [], color="0.4", lw=1.0), "MOMA (solid)"),
             (Line2D([], [], color="0.4", ls=":", lw=0.8), "switch of the robot"),
             (Line2D([], [], marker="*", ls="", color="0.4", markeredgecolor="k", ms=10), "goal")]
    legend_below(fig, [ax_err], extra)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")


def write_outputs(result: EvaluationResult, out_dir: Path) -> dict[str, Path]:
    """Write every file of ``result`` into ``out_dir`` (created); return their paths by kind."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tum_dir = out_dir / "tum"
    for ep in result.episodes:
        ep_dir = tum_dir / f"ep_{ep.index:03d}"
        ep_dir.mkdir(parents=True, exist_ok=True)
        for name, r in ep.robots.items():
            write_tum(ep_dir / f"{name}_truth.tum", r.truth)
            write_tum(ep_dir / f"{name}_moma.tum", r.moma)
    paths = {
        "summary": out_dir / "summary.json",
        "episodes": out_dir / "episodes.csv",
        "figure": out_dir / f"{result.configuration}.png",
        "tum": tum_dir,
    }
    write_csv(paths["episodes"], [ep.row() for ep in result.episodes])
    plot_episode(result.episodes[0], f"{result.configuration} / {result.policy}", paths["figure"])
    write_json(paths["summary"], result.to_dict())
    return paths


def _ms(stat: dict, scale: float = 1.0, digits: int = 2) -> str:
    mean, std = stat["mean"], stat["std"]
    if not math.isfinite(mean):
        return "n/a"
    text = f"{scale * mean:.{digits}f}"
    return text + (f" ± {scale * std:.{digits}f}" if math.isfinite(std) else "")


def _cm(value: float) -> str:
    return f"{100.0 * value:.2f}" if math.isfinite(value) else "n/a"


def format_table(result: EvaluationResult) -> str:
    """A readable table: episode-level rates and means, then one row per robot (cm, deg)."""
    s = result.summary
    n = s["n_episodes"]
    lines = [
        f"{result.configuration} / policy {result.policy}: {n} episodes from seed {result.seed} "
        f"({'random layouts' if result.random_scenarios else 'fixed layout'}, {result.action_mode})",
        f"  success {100.0 * s['success_rate']:.0f} %   time to goal {_ms(s['time_to_goal_s'])} s   "
        f"lost track {100.0 * s['lost_track_rate']:.0f} %",
        f"  switches {_ms(s['n_switches'], digits=1)}   refused {_ms(s['n_refused'], digits=1)}   "
        f"return {_ms(s['total_reward'])}",
    ]
    head = f"{'robot':<10}{'distance m':>16}{'ME_f cm':>10}{'std':>8}{'ME cm':>9}{'% path':>9}{'heading deg':>16}{'failed':>8}"
    lines += ["", head, "-" * len(head)]
    for name, r in s["robots"].items():
        m = r["moma"]
        pct = m["mean_final_error_pct_path"]
        lines.append(
            f"{name:<10}{_ms(r['distance_m']):>16}{_cm(m['mean_final_error']):>10}{_cm(m['std_final_error']):>8}"
            f"{_cm(m['mean_mean_error']):>9}{(f'{pct:.2f}' if math.isfinite(pct) else 'n/a'):>9}"
            f"{_ms(r['mean_heading_error_deg']):>16}{m['n_failed']:>8}"
        )
    return "\n".join(lines)
