"""A sweep's results as the comparison table of the docs, training seeds pooled.

``python -m training.sweep.compare SWEEP_DIR [--scenario NAME] [--label POLICY=TEXT ...]
[--seeds TEXT=POLICY,POLICY,... ...]`` reads the sweep's ``summary.json``
(:mod:`training.sweep.table`) and prints a Markdown table, one row per policy of the
scenario in the sweep's order: success rate, time to goal over the successful episodes
(mean ± sample standard deviation), switches and refused requests per episode, final
and mean localisation error (each episode's mean over its robots, then the mean over
episodes, in cm) and the share of episodes where some robot lost track.

``--seeds`` adds a row per group of policies (the training seeds of one recipe): the
mean of each column over the group's policies with the half width of its 95 %
interval, Student's t with one degree of freedom fewer than the group has policies,
so the interval is over training seeds, not over episodes. Time to goal pools each
policy's mean over its own successes.

``--schedule`` prints where the time to goal went instead
(:func:`training.evaluation.episode.schedule_split`): success, time to goal, and the
part of it the last robot to arrive spent moving, waiting (standing while another
robot moved) and still (no robot moving), means over the successful episodes, so a
row's three parts add up to its time to goal; the schedule bound
(:func:`training.evaluation.episode.schedule_bound`: the soonest any order of the same
moves could arrive, switch windows and dwells left out); and the waves of starts
(:func:`training.evaluation.episode.start_waves`: the starts no stop separates, so each
wave ends in a dwell), the fewest waves the same legs allow
(:func:`training.evaluation.episode.fewest_waves`) and the time to goal scaled by their
ratio (each wave saved worth the episode's mean wave: an estimate of what a better order
of the same legs could gain). Sweeps written before those were recorded are refused
with ``--schedule``.

``--paired BASE`` compares every other policy of the scenario with policy ``BASE``
seed by seed instead, from the sweep's ``results.csv`` (:func:`paired_table`): over the
seeds where both reached every goal, on how many each was sooner, as soon and later,
and the time it saved, in s and as a share of the base's time per seed (their means,
and the largest), so a lookahead or a learned policy is judged on the same layouts as
the policy it is meant to beat.

``--failures`` tabulates, per policy, the episodes that did not reach every goal
(:func:`failure_table`): how many robots each left, how far from their goals' positions
and headings they ended, and how long each stood static with a start allowed (the time
a policy could have sent it on and did not). ``--startable`` gives that time over every
episode, failed or not (:func:`startable_table`).

Units: time in s, errors in cm, rates in %, counts per episode. (The table of
``moma-env evaluate`` folders is :mod:`training.train.compare`.)
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from scipy import stats

from moma_env.io import read_json_in
from training.evaluation.harness import mean_std
from training.sweep.table import TABLE_FILES

__all__ = [
    "COLUMNS", "SCHEDULE_COLUMNS", "CompareError", "seed_interval", "policy_cells", "group_cells", "comparison_table",
    "paired_table", "failure_table", "main",
]

#: Column title -> (summary key, how a policy's value is read, scale to the shown unit).
COLUMNS: Mapping[str, tuple[str, str, float]] = {
    "success": ("success_rate", "rate", 100.0),
    "time to goal s": ("time_to_goal_s", "mean", 1.0),
    "switches": ("n_switches", "mean", 1.0),
    "refused": ("n_refused", "mean", 1.0),
    "ME_f cm": ("e_f_m", "mean", 100.0),
    "ME cm": ("me_m", "mean", 100.0),
    "lost track": ("lost_track_rate", "rate", 100.0),
}

#: The columns of ``--schedule``; ``"moving"`` is the time to goal less waiting and still.
SCHEDULE_COLUMNS: Mapping[str, tuple[str, str, float]] = {
    "success": ("success_rate", "rate", 100.0),
    "time to goal s": ("time_to_goal_s", "mean", 1.0),
    "last robot moving s": ("time_to_goal_s", "moving", 1.0),
    "waiting s": ("waiting_s", "mean", 1.0),
    "team still s": ("still_s", "mean", 1.0),
    "bound s": ("bound_s", "mean", 1.0),
    "waves": ("waves", "mean", 1.0),
    "fewest waves": ("fewest_waves", "mean", 1.0),
    "at fewest waves s": ("fewest_waves_time_s", "mean", 1.0),
}

_DIGITS = {"success": 0, "lost track": 0, "ME_f cm": 2, "ME cm": 2, "waves": 2, "fewest waves": 2}


class CompareError(ValueError):
    """A sweep folder, scenario or policy group the table cannot be made of (the message says which)."""


def seed_interval(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float]:
    """``(mean, half width)`` of the two-sided ``confidence`` Student-t interval of the mean
    of ``values`` (NaN values dropped); the half width is NaN with fewer than two values."""
    stat = mean_std(values)
    n = stat["n"]
    if n < 2:
        return stat["mean"], math.nan
    return stat["mean"], float(stats.t.ppf(0.5 + confidence / 2.0, n - 1)) * stat["std"] / math.sqrt(n)


def _mean(entry: Mapping[str, Any], key: str) -> float:
    if key not in entry:
        raise CompareError(f"the sweep's summary has no {key!r} (written before it was recorded): run the sweep again")
    value = entry[key]["mean"]
    return math.nan if value is None else float(value)


def _value(entry: Mapping[str, Any], column: str, columns: Mapping[str, tuple[str, str, float]] = COLUMNS) -> float:
    key, kind, scale = columns[column]
    if kind == "rate":
        value = entry[key]
        return math.nan if value is None else scale * float(value)
    if kind == "moving":
        return scale * (_mean(entry, key) - _mean(entry, "waiting_s") - _mean(entry, "still_s"))
    return scale * _mean(entry, key)


def _number(value: float, column: str) -> str:
    return "-" if not math.isfinite(value) else f"{value:.{_DIGITS.get(column, 1)}f}"


def _percent(column: str, columns: Mapping[str, tuple[str, str, float]] = COLUMNS) -> str:
    return " %" if columns[column][1] == "rate" else ""


def policy_cells(entry: Mapping[str, Any], columns: Mapping[str, tuple[str, str, float]] = COLUMNS) -> list[str]:
    """The table cells of one policy's summary entry, in ``columns`` order."""
    cells = []
    for column in columns:
        value = _value(entry, column, columns)
        if not math.isfinite(value):
            cells.append("-")
            continue
        text = _number(value, column) + _percent(column, columns)
        std = entry["time_to_goal_s"]["std"] if column == "time to goal s" else None
        if std is not None and math.isfinite(float(std)):
            text += f" ± {float(std):.1f}"
        cells.append(text)
    return cells


def group_cells(entries: Sequence[Mapping[str, Any]], columns: Mapping[str, tuple[str, str, float]] = COLUMNS) -> list[str]:
    """The cells of a group's row: each column's mean over ``entries`` ± its 95 % t half width."""
    cells = []
    for column in columns:
        mean, half = seed_interval([_value(e, column, columns) for e in entries])
        text = _number(mean, column)
        if math.isfinite(mean) and math.isfinite(half):
            text += f" ± {_number(half, column)}"
        cells.append(text + (_percent(column, columns) if math.isfinite(mean) else ""))
    return cells


def _read_summary(folder: Path) -> list[dict[str, Any]]:
    path, data = read_json_in(folder, TABLE_FILES["summary"], CompareError, "a sweep folder", "is the sweep finished?")
    groups = data.get("groups") if isinstance(data, dict) else None
    if not isinstance(groups, list):
        raise CompareError(f"{str(path)!r}: no 'groups' list")
    return groups


def _one_scenario(names: Sequence[str], scenario: str | None) -> str:
    """``scenario``, or the sweep's only scenario when None, checked against the sweep's
    scenarios ``names`` (one per row; CompareError: several and none chosen, or not in them)."""
    scenarios = list(dict.fromkeys(names))
    if scenario is None:
        if len(scenarios) != 1:
            raise CompareError(f"the sweep has scenarios {scenarios}; choose one with --scenario")
        return scenarios[0]
    if scenario not in scenarios:
        raise CompareError(f"scenario {scenario!r} is not in the sweep; it has {scenarios}")
    return scenario


def comparison_table(
    summary: Sequence[Mapping[str, Any]],
    scenario: str | None = None,
    labels: Mapping[str, str] | None = None,
    seeds: Mapping[str, Sequence[str]] | None = None,
    columns: Mapping[str, tuple[str, str, float]] = COLUMNS,
) -> str:
    """The Markdown table of ``summary`` (``summary.json``'s ``groups``) for ``scenario``
    (None: the sweep's only one), with a row per ``seeds`` group after the row of its
    policy that comes last, and policies shown as ``labels`` names them, in ``columns``
    (:data:`COLUMNS` or :data:`SCHEDULE_COLUMNS`).

    Raises:
        CompareError: no such scenario, several and none chosen, or a group naming a
            policy the scenario was not swept with.
    """
    scenario = _one_scenario([e["scenario"] for e in summary], scenario)
    entries = {e["policy"]: e for e in summary if e["scenario"] == scenario}
    labels = dict(labels or {})
    seeds = dict(seeds or {})
    for name, policies in seeds.items():
        missing = [p for p in policies if p not in entries]
        if missing:
            raise CompareError(f"group {name!r}: policies {missing} not swept on {scenario}; swept: {list(entries)}")
    after = {}
    for name, policies in seeds.items():
        last = max(list(entries).index(p) for p in policies)
        after.setdefault(list(entries)[last], []).append(name)
    lines = ["| policy | " + " | ".join(columns) + " |", "|---" * (len(columns) + 1) + "|"]
    for policy, entry in entries.items():
        lines.append(f"| {labels.get(policy, policy)} | " + " | ".join(policy_cells(entry, columns)) + " |")
        for name in after.get(policy, ()):
            group = [entries[p] for p in seeds[name]]
            title = f"{name}, mean of {len(group)} ± 95 % interval (t, {len(group) - 1} dof)"
            lines.append(f"| {title} | " + " | ".join(group_cells(group, columns)) + " |")
    return "\n".join(lines)


def _read_results(folder: Path) -> list[dict[str, str]]:
    _read_summary(folder)  # written last: a sweep without it is not finished (or not a sweep)
    path = folder / TABLE_FILES["csv"]
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.DictReader(handle))
    except FileNotFoundError:
        raise CompareError(f"{str(path)!r} does not exist: is the sweep finished?") from None
    needed = {"scenario", "policy", "seed", "success", "time_to_goal_s"}
    if rows and not needed <= set(rows[0]):
        raise CompareError(f"{str(path)!r} lacks the columns {sorted(needed - set(rows[0]))}")
    return rows


def paired_table(
    rows: Sequence[Mapping[str, str]], base: str, scenario: str | None = None, labels: Mapping[str, str] | None = None
) -> str:
    """The Markdown table of ``--paired``: every policy of ``scenario`` (None: the sweep's
    only one) but ``base`` against ``base``, over the seeds where both reached every goal
    (``rows``: ``results.csv``'s rows, one per episode). Columns: those seeds, on how many
    the policy was sooner, as soon and later than ``base``, the mean time saved (s, base
    less policy), and the mean and the largest of the time saved as a share of the base's
    time on each seed (%). Policies are shown as ``labels`` names them.

    Raises:
        CompareError: no such scenario, several and none chosen, ``base`` not swept on it, or
            a seed that appears twice for one policy.
    """
    scenario = _one_scenario([r["scenario"] for r in rows], scenario)
    times: dict[str, dict[int, float]] = {}
    for row in rows:
        if row["scenario"] != scenario:
            continue
        per_seed = times.setdefault(row["policy"], {})
        seed = int(row["seed"])
        if seed in per_seed:
            raise CompareError(f"policy {row['policy']!r} has seed {seed} twice on {scenario}")
        per_seed[seed] = float(row["time_to_goal_s"]) if int(row["success"]) else math.nan
    if base not in times:
        raise CompareError(f"--paired {base!r}: not swept on {scenario}; swept: {list(times)}")
    lines = [
        "| policy | seeds both reached | sooner | as soon | later | time saved s | saved per seed % | largest saving % |",
        "|---" * 8 + "|",
    ]
    reference = times[base]
    labels = dict(labels or {})
    for policy, per_seed in times.items():
        if policy == base:
            continue
        name = labels.get(policy, policy)
        pairs = [(reference[s], per_seed[s]) for s in sorted(per_seed) if s in reference
                 and math.isfinite(reference[s]) and math.isfinite(per_seed[s])]
        if not pairs:
            lines.append(f"| {name} | 0 | - | - | - | - | - | - |")
            continue
        saved = [b - t for b, t in pairs]
        shares = [100.0 * (b - t) / b for b, t in pairs]
        lines.append(
            f"| {name} | {len(pairs)} | {sum(d > 0 for d in saved)} | {sum(d == 0 for d in saved)} | {sum(d < 0 for d in saved)} "
            f"| {sum(saved) / len(saved):.2f} | {sum(shares) / len(shares):.1f} | {max(shares):.1f} |"
        )
    return "\n".join(lines)


def _median_of(left: Sequence[tuple[Mapping[str, str], str]], column: str) -> float:
    """The median of column ``<robot>_<column>`` over ``(row, robot)`` pairs (NaN if none)."""
    values = [float(row[f"{robot}_{column}"]) for row, robot in left]
    return statistics.median(values) if values else math.nan


def _robot_rows(rows: Sequence[Mapping[str, str]], scenario: str | None, option: str) -> tuple[list[str], dict[str, list[Mapping[str, str]]]]:
    """The robots of ``scenario``'s rows (from their goal columns) and its rows by policy.

    Raises:
        CompareError: no such scenario, several and none chosen, or rows written before the
            robots' goal columns (``option`` names the view that needs them).
    """
    scenario = _one_scenario([r["scenario"] for r in rows], scenario)
    rows = [r for r in rows if r["scenario"] == scenario]
    robots = [key[: -len("_goal_distance_m")] for key in (rows[0] if rows else {}) if key.endswith("_goal_distance_m")]
    if rows and not robots:
        raise CompareError(f"this sweep predates the robots' goal distances in results.csv: sweep again for {option}")
    by_policy: dict[str, list[Mapping[str, str]]] = {}
    for row in rows:
        by_policy.setdefault(row["policy"], []).append(row)
    return robots, by_policy


def startable_table(
    rows: Sequence[Mapping[str, str]], scenario: str | None = None, labels: Mapping[str, str] | None = None, longer_than_s: float = 10.0
) -> str:
    """The Markdown table of ``--startable``: for every policy of ``scenario`` (None: the
    sweep's only one), over all its episodes, the time its robots stood static, off their
    goals, with a start allowed, summed over the robots of an episode (s): its mean and
    median, and the share of episodes with more than ``longer_than_s`` of it (a policy
    holding a robot it could send on).

    Raises:
        CompareError: as :func:`failure_table`.
    """
    robots, by_policy = _robot_rows(rows, scenario, "--startable")
    lines = [
        f"| policy | episodes | startable s per episode (mean) | median | episodes over {longer_than_s:g} s |",
        "|---" * 5 + "|",
    ]
    labels = dict(labels or {})
    for policy, episodes in by_policy.items():
        totals = [sum(float(r[f"{robot}_startable_s"]) for robot in robots) for r in episodes]
        over = sum(t > longer_than_s for t in totals)
        lines.append(f"| {labels.get(policy, policy)} | {len(totals)} | {statistics.fmean(totals):.1f} | {statistics.median(totals):.1f} "
                     f"| {100 * over / len(totals):.0f} % |")
    return "\n".join(lines)


def failure_table(
    rows: Sequence[Mapping[str, str]], scenario: str | None = None, labels: Mapping[str, str] | None = None
) -> str:
    """The Markdown table of ``--failures``: for every policy of ``scenario`` (None: the
    sweep's only one), its episodes that did not reach every goal and the robots they left
    (``rows``: ``results.csv``'s rows): how many failed, robots left per failure, the
    median distance (m) and heading error (deg) from a robot left to its goal at the end
    (:class:`training.evaluation.episode.RobotEpisode`), the mean time a robot left stood
    static with a start allowed (s), and the failures' mean duration (s).

    Raises:
        CompareError: no such scenario, several and none chosen, or a sweep written before
            the robots' final goal distances were recorded.
    """
    robots, by_policy = _robot_rows(rows, scenario, "--failures")
    lines = [
        "| policy | failed | robots left per failure | distance left m (median) | heading error left deg (median) "
        "| startable s per robot left | failure duration s |",
        "|---" * 7 + "|",
    ]
    labels = dict(labels or {})
    for policy, episodes in by_policy.items():
        failed = [r for r in episodes if not int(r["success"])]
        left = [(r, robot) for r in failed for robot in robots if not math.isfinite(float(r[f"{robot}_goal_time_s"]))]
        name = labels.get(policy, policy)
        if not failed:
            lines.append(f"| {name} | 0 of {len(episodes)} | - | - | - | - | - |")
            continue
        startable = [float(r[f"{robot}_startable_s"]) for r, robot in left]
        lines.append(
            f"| {name} | {len(failed)} of {len(episodes)} | {len(left) / len(failed):.1f} | {_median_of(left, 'goal_distance_m'):.2f} "
            f"| {_median_of(left, 'goal_heading_error_deg'):.0f} | {sum(startable) / max(len(startable), 1):.1f} "
            f"| {sum(float(r['duration_s']) for r in failed) / len(failed):.1f} |"
        )
    return "\n".join(lines)


def _pairs(texts: Sequence[str], option: str) -> list[tuple[str, str]]:
    out = []
    for text in texts:
        key, sep, value = text.partition("=")
        if not sep or not key or not value:
            raise CompareError(f"{option} {text!r}: expected NAME=VALUE")
        out.append((key, value))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Print the comparison table of a sweep folder; exit status 2 on a bad folder or option."""
    parser = argparse.ArgumentParser(prog="python -m training.sweep.compare", description=__doc__.splitlines()[0])
    parser.add_argument("sweep", type=Path, help="a finished sweep folder (moma-env sweep --out)")
    parser.add_argument("--scenario", default=None, help="the scenario to tabulate (default: the sweep's only one)")
    parser.add_argument("--label", action="append", default=[], metavar="POLICY=TEXT",
                        help="show POLICY (its spec in the sweep) as TEXT (default: the spec)")
    parser.add_argument("--seeds", action="append", default=[], metavar="TEXT=POLICY,POLICY,...",
                        help="a row TEXT pooling these policies (training seeds) with a 95 %% t interval (default: none)")
    parser.add_argument("--schedule", action="store_true",
                        help="where the time to goal went (moving, waiting, still), its schedule bound and its waves of starts "
                             "instead of the default columns")
    parser.add_argument("--paired", default=None, metavar="BASE",
                        help="every other policy against policy BASE, seed by seed over the seeds both reached every goal "
                             "(from results.csv) instead of the default columns")
    parser.add_argument("--failures", action="store_true",
                        help="the episodes that did not reach every goal and the robots they left (from results.csv) "
                             "instead of the default columns")
    parser.add_argument("--startable", action="store_true",
                        help="over all episodes, how long robots stood static off their goals with a start allowed "
                             "(from results.csv) instead of the default columns")
    args = parser.parse_args(argv)
    try:
        if args.startable:
            if args.schedule or args.seeds or args.paired is not None or args.failures:
                raise CompareError("--startable makes its own table: give it without --schedule, --seeds, --paired and --failures")
            print(startable_table(_read_results(args.sweep), args.scenario, dict(_pairs(args.label, "--label"))))
            return 0
        if args.failures:
            if args.schedule or args.seeds or args.paired is not None:
                raise CompareError("--failures makes its own table: give it without --schedule, --seeds and --paired")
            print(failure_table(_read_results(args.sweep), args.scenario, dict(_pairs(args.label, "--label"))))
            return 0
        if args.paired is not None:
            if args.schedule or args.seeds:
                raise CompareError("--paired makes its own table: give it without --schedule and --seeds")
            print(paired_table(_read_results(args.sweep), args.paired, args.scenario, dict(_pairs(args.label, "--label"))))
            return 0
        seeds = {name: [p for p in value.split(",") if p] for name, value in _pairs(args.seeds, "--seeds")}
        table = comparison_table(_read_summary(args.sweep), args.scenario, dict(_pairs(args.label, "--label")), seeds,
                                 SCHEDULE_COLUMNS if args.schedule else COLUMNS)
    except (CompareError, OSError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
