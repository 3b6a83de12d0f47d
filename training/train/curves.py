"""Learning curves of training runs: ``curves.csv`` and ``curves.png`` from the held-out evaluations.

The evaluation callback of ``moma-env train`` (:class:`training.train.callbacks.EvaluationCallback`)
calls :func:`write_curves` after every evaluation: ``<run>/curves.csv`` holds one
row per evaluation (:data:`CURVE_COLUMNS`) and ``<run>/curves.png`` plots success
rate, time to goal and final localisation error against env steps (against timesteps
for records made before they recorded env steps). Both are written whole or not at all
(:mod:`moma_env.io`), from the records of ``evaluations.json``.

``python -m training.train.curves RUN_DIR [RUN_DIR ...] [--out FIGURE.png]`` redraws
them from run folders: one folder rewrites its own ``curves.csv`` and ``curves.png``
(or ``--out``); several (typically the seeds of one configuration) are overlaid in
``--out`` (required), each run a thin line, with the mean over runs and the band
from their minimum to their maximum at every env step (timestep) all runs were evaluated at,
and those numbers in a CSV beside the figure (same name, ``.csv``). Runs evaluated
on other held-out episodes (scenario, first seed, episode count) are refused.

Units: timesteps are SB3 timesteps (agent steps on the shared route, env steps on
the centralised one; the TorchRL and RLlib backends count env steps); env steps are
steps of one env copy, each moving its whole team one control step (on SB3's shared
route, timesteps over the UGV slots of a copy); wall time and time to goal in seconds; errors in metres in
the CSV files (centimetres on the figure's axis, as labelled); switches and
refusals per episode; return is the mean team return per episode.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from moma_env.io import atomic_path, read_json_in, write_csv

__all__ = [
    "EVALUATIONS",
    "CURVES_CSV",
    "CURVES_PNG",
    "CURVE_COLUMNS",
    "OPTIONAL_COLUMNS",
    "CurvesError",
    "curve_rows",
    "x_column",
    "read_run",
    "write_curves",
    "plot_curves",
    "main",
]

#: File names in the run's folder: the evaluation callback's records, and the curves drawn from them.
EVALUATIONS = "evaluations.json"
CURVES_CSV = "curves.csv"
CURVES_PNG = "curves.png"

#: Columns of ``curves.csv`` -> the key of the evaluation record they come from.
CURVE_COLUMNS: Mapping[str, str] = MappingProxyType({
    "timesteps": "num_timesteps",
    "env_steps": "env_steps",
    "wall_time_s": "wall_time_s",
    "success_rate": "success_rate",
    "time_to_goal_mean_s": "time_to_goal_s",
    "final_error_mean_m": "e_f_m",
    "mean_error_m": "me_m",
    "switches": "n_switches",
    "refusals": "n_refused",
    "return": "total_reward",
})

#: Columns a record may lack (written before it carried them): NaN in the CSV.
OPTIONAL_COLUMNS = frozenset({"env_steps"})

#: The figure's panels: (column, axis label, scale from the CSV's unit to the axis's).
_PANELS = (
    ("success_rate", "success rate (%)", 100.0),
    ("time_to_goal_mean_s", "time to goal (s, successful episodes)", 1.0),
    ("final_error_mean_m", "final localisation error (cm)", 100.0),
)
_TITLES = ("Success rate", "Time to goal", "Final localisation error")


class CurvesError(ValueError):
    """A run folder whose curves cannot be drawn (one-line message)."""


def _number(value: Any) -> float:
    """A record's number; None (NaN as JSON writes it) is NaN."""
    return math.nan if value is None else float(value)


def curve_rows(records: Sequence[Mapping[str, Any]]) -> list[dict[str, float]]:
    """One ``curves.csv`` row per evaluation record (:data:`CURVE_COLUMNS`), in timestep order.

    Raises:
        CurvesError: a record lacks one of the keys but :data:`OPTIONAL_COLUMNS`' (naming it
            and the record's index).
    """
    rows = []
    for index, record in enumerate(records):
        row: dict[str, float] = {}
        for column, key in CURVE_COLUMNS.items():
            if key not in record:
                if column in OPTIONAL_COLUMNS:
                    row[column] = math.nan
                    continue
                raise CurvesError(f"evaluation record {index} lacks {key!r}")
            row[column] = int(record[key]) if column in ("timesteps", "env_steps") else _number(record[key])
        rows.append(row)
    return sorted(rows, key=lambda r: r["timesteps"])


def x_column(runs: Sequence[tuple[str, list[dict[str, float]]]]) -> str:
    """What the curves of ``runs`` are drawn against: ``"env_steps"`` when every row of
    every run has them, else ``"timesteps"`` (records made before they carried env steps)."""
    rows = [r for _, run_rows in runs for r in run_rows]
    return "env_steps" if rows and all(not math.isnan(r["env_steps"]) for r in rows) else "timesteps"


_X_LABELS = {"env_steps": "env steps", "timesteps": "timesteps"}


def _figure(runs: Sequence[tuple[str, list[dict[str, float]]]], title: str):
    """The three-panel figure of ``runs`` ((label, rows) each); several runs add their mean and min-max band."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12.0, 3.8), layout="constrained")
    axes = fig.subplots(1, len(_PANELS), sharex=True)
    key = x_column(runs)
    common = _common_x(runs, key) if len(runs) > 1 else []
    for ax, (column, label, scale), panel_title in zip(axes, _PANELS, _TITLES):
        for name, rows in runs:
            x = [r[key] for r in rows]
            y = [scale * r[column] for r in rows]
            if len(runs) == 1:
                ax.plot(x, y, marker="o", color="C0", label=name)
            else:
                ax.plot(x, y, linewidth=0.8, alpha=0.45, label=name)
        if common:
            stats = _band(runs, column, common, key)
            ax.fill_between(common, scale * stats["min"], scale * stats["max"], color="0.6", alpha=0.3, label="min-max")
            ax.plot(common, scale * stats["mean"], color="k", linewidth=2.0, marker="o", markersize=3, label=f"mean of {len(runs)}")
        if all(math.isnan(r[column]) for _, rows in runs for r in rows):
            ax.text(0.5, 0.5, "no value yet\n(no successful episode)" if column == "time_to_goal_mean_s" else "no value yet",
                    transform=ax.transAxes, ha="center", va="center", color="0.4")
        ax.set_title(panel_title)
        ax.set_xlabel(_X_LABELS[key])
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        if column == "success_rate":
            ax.set_ylim(-5.0, 105.0)
    axes[0].legend(fontsize="small", loc="best")
    fig.suptitle(title)
    return fig


def _common_x(runs: Sequence[tuple[str, list[dict[str, float]]]], key: str) -> list[int]:
    """The values of ``key`` (env steps or timesteps) every run was evaluated at, ascending."""
    sets = [{r[key] for r in rows} for _, rows in runs]
    return sorted(set.intersection(*sets)) if sets else []


def _band(
    runs: Sequence[tuple[str, list[dict[str, float]]]], column: str, xs: Sequence[int], key: str
) -> dict[str, np.ndarray]:
    """Mean, minimum and maximum of ``column`` over the runs at each of ``xs`` (values of
    ``key``) (NaN values, such as the time to goal of an evaluation without a success, are
    left out; NaN where every run's is NaN)."""
    table = np.full((len(runs), len(xs)), np.nan)
    where = {t: k for k, t in enumerate(xs)}
    for i, (_, rows) in enumerate(runs):
        for r in rows:
            if r[key] in where:
                table[i, where[r[key]]] = r[column]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns give NaN, as intended
        return {"mean": np.nanmean(table, axis=0), "min": np.nanmin(table, axis=0), "max": np.nanmax(table, axis=0)}


def plot_curves(runs: Sequence[tuple[str, list[dict[str, float]]]], path: str | Path, title: str = "") -> Path:
    """Draw ``runs`` ((label, :func:`curve_rows`) each) into the PNG ``path``, whole or not at all.

    Raises:
        CurvesError: no runs, or several runs without an env step (timestep) common to all.
    """
    if not runs:
        raise CurvesError("no runs to draw")
    if len(runs) > 1 and not _common_x(runs, x_column(runs)):
        raise CurvesError("the runs share no evaluation step: nothing to average")
    path = Path(path)
    fig = _figure(runs, title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight")
    return path


def write_curves(out: str | Path, records: Sequence[Mapping[str, Any]], title: str = "") -> dict[str, Path]:
    """Write ``<out>/curves.csv`` and ``<out>/curves.png`` of a run's evaluation ``records``
    (each file whole or not at all); return their paths. No records: nothing written."""
    out = Path(out)
    rows = curve_rows(records)
    if not rows:
        return {}
    paths = {"csv": out / CURVES_CSV, "png": out / CURVES_PNG}
    write_csv(paths["csv"], rows, fieldnames=list(CURVE_COLUMNS))
    plot_curves([(out.name or "run", rows)], paths["png"], title)
    return paths


def read_run(folder: str | Path) -> tuple[dict[str, Any], list[dict[str, float]]]:
    """``(evaluations.json's content, its curve rows)`` of a run folder.

    Raises:
        CurvesError: not a folder, no or unreadable ``evaluations.json``, no records,
            a record lacking a number.
    """
    path, data = read_json_in(folder, EVALUATIONS, CurvesError, hint="a run of moma-env train with --eval-every")
    if not isinstance(data, dict) or not isinstance(data.get("records"), list):
        raise CurvesError(f"{str(path)!r} has no list of records")
    if not data["records"]:
        raise CurvesError(f"{str(path)!r} holds no evaluation yet")
    try:
        rows = curve_rows(data["records"])
    except CurvesError as err:
        raise CurvesError(f"{str(path)!r}: {err}") from None
    except (TypeError, ValueError) as err:
        raise CurvesError(f"{str(path)!r}: a record holds a value that is not a number ({err})") from None
    return data, rows


def _title(data: Mapping[str, Any], n_runs: int) -> str:
    runs = f", {n_runs} runs" if n_runs > 1 else ""
    episodes = data.get("episodes", "?")
    return (f"{data.get('scenario', '?')}: {episodes} held-out episode{'' if episodes == 1 else 's'} per evaluation "
            f"from seed {data.get('first_seed', '?')}{runs}")


def _write_band_csv(path: Path, runs: Sequence[tuple[str, list[dict[str, float]]]]) -> None:
    """The mean, min and max over ``runs`` of every curve column at their common env steps
    (timesteps, for runs without them: :func:`x_column`), the first column named by which."""
    key = x_column(runs)
    xs = _common_x(runs, key)
    columns = [c for c in CURVE_COLUMNS if c not in ("timesteps", "env_steps")]
    stats = {c: _band(runs, c, xs, key) for c in columns}
    rows = []
    for k, t in enumerate(xs):
        row: dict[str, float] = {key: t, "runs": len(runs)}
        for c in columns:
            for kind in ("mean", "min", "max"):
                row[f"{c}_{kind}"] = float(stats[c][kind][k])
        rows.append(row)
    write_csv(path, rows, fieldnames=[key, "runs"] + [f"{c}_{k}" for c in columns for k in ("mean", "min", "max")])


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m training.train.curves RUN_DIR [RUN_DIR ...] [--out FIGURE.png]``: exit 0, or 2 with one line."""
    parser = argparse.ArgumentParser(prog="python -m training.train.curves", description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="folders of moma-env train runs (each with evaluations.json)")
    parser.add_argument("--out", type=Path, default=None,
                        help="figure to write (one run: default <run>/curves.png with <run>/curves.csv; several: required, "
                             "with the mean/min/max table beside it as .csv)")
    args = parser.parse_args(argv)
    try:
        loaded = [(folder, *read_run(folder)) for folder in args.runs]
        keys = {(d.get("scenario"), d.get("first_seed"), d.get("episodes")) for _, d, _ in loaded}
        if len(keys) > 1:
            raise CurvesError(f"the runs were evaluated on different held-out episodes (scenario, first seed, episodes): {sorted(map(str, keys))}")
        runs = [(folder.resolve().name, rows) for folder, _, rows in loaded]
        title = _title(loaded[0][1], len(runs))
        if len(runs) == 1 and args.out is None:
            paths = write_curves(args.runs[0], loaded[0][1]["records"], title)
        elif args.out is None:
            raise CurvesError("several runs are drawn into one figure: give --out FIGURE.png")
        else:
            if args.out.suffix.lower() != ".png":
                raise CurvesError(f"--out must name a .png file, got {str(args.out)!r}")
            if not args.out.parent.is_dir():
                raise CurvesError(f"--out {str(args.out)!r}: folder {str(args.out.parent)!r} does not exist")
            paths = {"png": plot_curves(runs, args.out, title), "csv": args.out.with_suffix(".csv")}
            if len(runs) > 1:
                _write_band_csv(paths["csv"], runs)
            else:
                write_csv(paths["csv"], runs[0][1], fieldnames=list(CURVE_COLUMNS))
    except CurvesError as err:
        print(f"curves: {err}", file=sys.stderr)
        return 2
    print("\n".join(f"{kind}: {path}" for kind, path in paths.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
