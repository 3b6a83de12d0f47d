"""The results of a sweep: one table (Parquet and CSV), a summary and a figure.

The table has one row per cell, in the spec's order (scenarios, policies, seeds, as
given), whatever order the cells finished in: the columns ``scenario``, ``policy``,
``seed``, then the episode's columns (:meth:`training.evaluation.episode.EpisodeResult.row`:
m, deg, s) in order of first appearance. A column a scenario lacks (a robot of a
larger team) is empty in the CSV and null in the Parquet file. The bytes of both files
depend only on the rows, so the same cells give the same files on any backend.

The summary (``summary.json``) gives, per scenario and policy, the number of
episodes, the success and lost-track rates and the mean and sample standard deviation
of the episode's numbers and of ME and E_f (m, averaged over the robots of each
episode); the figure (``sweep.png``) plots success rate and E_f per scenario and policy.
Every file is written whole or not at all (:mod:`moma_env.io`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from moma_env.io import atomic_path, write_csv, write_json
from training.evaluation.harness import mean_std
from training.sweep.cells import CELL_KEYS

__all__ = ["columns", "write_table", "write_outputs", "summarise_rows", "plot_summary", "policy_labels", "TABLE_FILES"]

#: File names of the outputs.
TABLE_FILES = {"parquet": "results.parquet", "csv": "results.csv", "summary": "summary.json", "figure": "sweep.png"}


def columns(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The table's columns: the cell keys, then every other key in order of first appearance."""
    seen: dict[str, None] = dict.fromkeys(CELL_KEYS)
    for row in rows:
        for key in row:
            seen.setdefault(key, None)
    return list(seen)


def _parquet(path: Path, rows: Sequence[Mapping[str, Any]], names: Sequence[str]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = []
    for name in names:
        values = [row.get(name) for row in rows]
        kinds = {type(v) for v in values if v is not None}
        if kinds <= {int}:
            arrays.append(pa.array(values, type=pa.int64()))
        elif kinds <= {int, float}:
            arrays.append(pa.array([None if v is None else float(v) for v in values], type=pa.float64()))
        else:
            arrays.append(pa.array([None if v is None else str(v) for v in values], type=pa.string()))
    table = pa.Table.from_arrays(arrays, names=list(names))
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def write_table(out: Path, rows: Sequence[Mapping[str, Any]]) -> dict[str, Path]:
    """``results.parquet`` and ``results.csv`` of ``rows`` (already in table order) in ``out``."""
    out = Path(out)
    names = columns(rows)
    paths = {"parquet": out / TABLE_FILES["parquet"], "csv": out / TABLE_FILES["csv"]}
    _parquet(paths["parquet"], rows, names)
    write_csv(paths["csv"], rows, fieldnames=names)
    return paths


def _robot_mean(row: Mapping[str, Any], suffix: str) -> float:
    """Mean over the robots of a row's ``<robot><suffix>`` columns (NaN where none is finite)."""
    values = [float(v) for k, v in row.items() if k.endswith(suffix) and v is not None and math.isfinite(float(v))]
    return sum(values) / len(values) if values else math.nan


def summarise_rows(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per (scenario, policy), in table order: ``n_episodes``, ``success_rate``,
    ``lost_track_rate``, and ``{"mean", "std", "n"}`` of ``time_to_goal_s`` (over
    successes), ``duration_s``, ``steps``, ``total_reward``, ``n_switches``,
    ``n_refused``, ``waiting_s`` and ``still_s`` (over successes:
    :func:`training.evaluation.episode.schedule_split`), ``bound_s`` (over successes:
    :func:`training.evaluation.episode.schedule_bound`), ``waves``, ``fewest_waves`` and
    ``fewest_waves_time_s`` (over successes: :func:`training.evaluation.episode.start_waves`),
    ``me_m`` and ``e_f_m`` (each
    episode's mean over its robots)."""
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["scenario"], row["policy"]), []).append(row)
    out = []
    for (scenario, policy), group in groups.items():
        n = len(group)
        entry: dict[str, Any] = {
            "scenario": scenario,
            "policy": policy,
            "n_episodes": n,
            "success_rate": sum(int(r["success"]) for r in group) / n,
            "lost_track_rate": sum(int(r["lost_track"]) for r in group) / n,
        }
        for key in ("time_to_goal_s", "duration_s", "steps", "total_reward", "n_switches", "n_refused"):
            entry[key] = mean_std([float(r[key]) for r in group])
        # absent from rows written before they were recorded
        for key in ("waiting_s", "still_s", "bound_s", "waves", "fewest_waves", "fewest_waves_time_s"):
            entry[key] = mean_std([float(r[key]) if r.get(key) is not None else math.nan for r in group])
        entry["me_m"] = mean_std([_robot_mean(r, "_ME_m") for r in group])
        entry["e_f_m"] = mean_std([_robot_mean(r, "_E_f_m") for r in group])
        out.append(entry)
    return out


def policy_labels(policies: Sequence[str]) -> list[str]:
    """Short legend labels: a training folder's path by its last component (``runs/train/x``
    -> ``x``) unless two of ``policies`` share it; other names as they are."""
    short = [Path(p).name if "/" in p else p for p in policies]
    return [label if short.count(label) == 1 else policy for label, policy in zip(short, policies)]


def plot_summary(summary: Sequence[Mapping[str, Any]], path: Path) -> None:
    """Bars per scenario, one per policy: success rate (left) and E_f in cm with its std
    (right), one legend of the policies below both."""
    scenarios = list(dict.fromkeys(s["scenario"] for s in summary))
    policies = list(dict.fromkeys(s["policy"] for s in summary))
    by_cell = {(s["scenario"], s["policy"]): s for s in summary}
    fig = Figure(figsize=(max(6.0, 2.5 * len(scenarios) + 3), 4.5 + 0.2 * len(policies)), layout="constrained")
    ax_success, ax_error = fig.subplots(1, 2)
    width = 0.8 / len(policies)
    for k, (policy, label) in enumerate(zip(policies, policy_labels(policies))):
        xs = [i + (k - (len(policies) - 1) / 2) * width for i in range(len(scenarios))]
        cells = [by_cell.get((s, policy)) for s in scenarios]
        ax_success.bar(xs, [100.0 * c["success_rate"] if c else 0.0 for c in cells], width, label=label)
        means = [100.0 * c["e_f_m"]["mean"] if c and math.isfinite(c["e_f_m"]["mean"]) else 0.0 for c in cells]
        stds = [100.0 * c["e_f_m"]["std"] if c and math.isfinite(c["e_f_m"]["std"]) else 0.0 for c in cells]
        ax_error.bar(xs, means, width, yerr=stds, capsize=3)
    for ax, label in ((ax_success, "success rate [%]"), (ax_error, "final error E_f [cm] (mean ± std)")):
        ax.set_xticks(range(len(scenarios)), scenarios, rotation=15)
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    fig.legend(loc="outside lower center", fontsize=8)
    n = sum(s["n_episodes"] for s in summary)
    fig.suptitle(f"sweep: {len(scenarios)} scenarios x {len(policies)} policies, {n} episodes")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")


def write_outputs(out: Path, rows: Sequence[Mapping[str, Any]], extra: Mapping[str, Any] | None = None) -> dict[str, Path]:
    """The table, ``summary.json`` (with ``extra`` entries) and the figure; their paths by kind."""
    out = Path(out)
    paths = write_table(out, rows)
    summary = summarise_rows(rows)
    paths["summary"] = out / TABLE_FILES["summary"]
    write_json(paths["summary"], {**(extra or {}), "groups": summary})
    paths["figure"] = out / TABLE_FILES["figure"]
    plot_summary(summary, paths["figure"])
    return paths
