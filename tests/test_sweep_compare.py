"""The comparison table of a sweep (``python -m training.sweep.compare``): one row per
policy from ``summary.json``, training-seed groups pooled with a Student-t interval, and
a bad folder, scenario or group refused with a message naming it."""

from __future__ import annotations

import json
import math

import pytest
from scipy import stats

from training.sweep.compare import CompareError, comparison_table, main, seed_interval


def _entry(policy: str, success: float, time_s: float, e_f_m: float, scenario: str = "top_observer_team6") -> dict:
    stat = lambda mean, std=0.5: {"mean": mean, "std": std, "n": 10}  # noqa: E731
    return {
        "scenario": scenario,
        "policy": policy,
        "n_episodes": 10,
        "success_rate": success,
        "lost_track_rate": 0.0,
        "time_to_goal_s": stat(time_s, 2.0),
        "duration_s": stat(time_s),
        "steps": stat(100.0),
        "total_reward": stat(1.0),
        "n_switches": stat(30.0),
        "n_refused": stat(0.0),
        "me_m": stat(e_f_m),
        "e_f_m": stat(e_f_m),
    }


SUMMARY = [
    _entry("runs/a_s0", 1.0, 24.0, 0.007),
    _entry("runs/a_s1", 0.9, 26.0, 0.008),
    _entry("runs/a_s2", 0.8, 28.0, 0.009),
    _entry("greedy", 1.0, 23.0, 0.0065),
    _entry("scripted", 0.0, math.nan, 0.004),
    _entry("greedy", 0.5, 70.0, 0.01, scenario="caterpillar_multi_bend4"),
]


def test_the_interval_is_students_over_the_values():
    mean, half = seed_interval([1.0, 2.0, 4.0])
    std = math.sqrt(((1 - 7 / 3) ** 2 + (2 - 7 / 3) ** 2 + (4 - 7 / 3) ** 2) / 2)
    assert mean == pytest.approx(7 / 3)
    assert half == pytest.approx(stats.t.ppf(0.975, 2) * std / math.sqrt(3))
    assert seed_interval([5.0, math.nan])[0] == 5.0 and math.isnan(seed_interval([5.0])[1])


def test_rows_follow_the_sweep_and_a_group_row_follows_its_last_policy():
    table = comparison_table(
        SUMMARY,
        "top_observer_team6",
        labels={"runs/a_s0": "learned, seed 0"},
        seeds={"learned": ["runs/a_s0", "runs/a_s1", "runs/a_s2"]},
    )
    lines = table.splitlines()
    assert lines[0].startswith("| policy | success | time to goal s |")
    assert [line.split("|")[1].strip() for line in lines[2:]] == [
        "learned, seed 0",
        "runs/a_s1",
        "runs/a_s2",
        "learned, mean of 3 ± 95 % interval (t, 2 dof)",
        "greedy",
        "scripted",
    ]
    half_success = stats.t.ppf(0.975, 2) * 10.0 / math.sqrt(3)  # 100, 90, 80 %: std 10
    assert f"90 ± {half_success:.0f} %" in lines[5]
    assert "| 24.0 ± 2.0 |" in lines[2] and "| 0.70 |" in lines[2]
    assert lines[7].split("|")[3].strip() == "-"  # no success: no time to goal


def test_the_scenario_must_be_chosen_when_the_sweep_has_several():
    with pytest.raises(CompareError, match="choose one"):
        comparison_table(SUMMARY)
    with pytest.raises(CompareError, match="'nowhere' is not in the sweep"):
        comparison_table(SUMMARY, "nowhere")
    with pytest.raises(CompareError, match=r"group 'x': policies \['runs/a_s9'\]"):
        comparison_table(SUMMARY, "top_observer_team6", seeds={"x": ["runs/a_s0", "runs/a_s9"]})


def test_the_command_prints_the_table_or_names_what_is_wrong(tmp_path, capsys):
    (tmp_path / "summary.json").write_text(json.dumps({"groups": SUMMARY}), encoding="utf-8")
    assert main([str(tmp_path), "--scenario", "caterpillar_multi_bend4"]) == 0
    assert "| greedy | 50 % | 70.0 ± 2.0 |" in capsys.readouterr().out
    assert main([str(tmp_path / "missing"), "--scenario", "x"]) == 2
    assert "is not a sweep folder" in capsys.readouterr().err
    assert main([str(tmp_path), "--scenario", "top_observer_team6", "--seeds", "nameonly"]) == 2
    assert "expected NAME=VALUE" in capsys.readouterr().err


def test_schedule_columns_split_the_time_to_goal_and_old_sweeps_are_refused():
    from training.sweep.compare import SCHEDULE_COLUMNS

    stat = lambda mean: {"mean": mean, "std": 0.5, "n": 10}  # noqa: E731
    entry = _entry("greedy", 1.0, 23.0, 0.0065) | {
        "waiting_s": stat(5.0), "still_s": stat(4.0), "bound_s": stat(17.5),
        "waves": stat(7.25), "fewest_waves": stat(6.5), "fewest_waves_time_s": stat(20.6),
    }
    row = comparison_table([entry], columns=SCHEDULE_COLUMNS).splitlines()[2]
    assert row == "| greedy | 100 % | 23.0 ± 2.0 | 14.0 | 5.0 | 4.0 | 17.5 | 7.25 | 6.50 | 20.6 |"
    with pytest.raises(CompareError, match="waiting_s"):
        comparison_table([_entry("greedy", 1.0, 23.0, 0.0065)], columns=SCHEDULE_COLUMNS)
    # a sweep written before the waves were recorded
    old = {key: value for key, value in entry.items() if key not in ("waves", "fewest_waves", "fewest_waves_time_s")}
    with pytest.raises(CompareError, match="waves"):
        comparison_table([old], columns=SCHEDULE_COLUMNS)


def _result_rows() -> list[dict[str, str]]:
    """``results.csv`` rows: base ``pipeline`` and two policies over seeds 1..4 of one scenario."""
    times = {
        "pipeline": {1: 50.0, 2: 40.0, 3: 60.0, 4: 30.0},
        "lookahead": {1: 45.0, 2: 40.0, 3: 57.0, 4: math.nan},  # seed 4 failed
        "slow": {1: 55.0, 2: 44.0, 3: math.nan, 4: 33.0},
    }
    rows = []
    for policy, per_seed in times.items():
        for seed, t in per_seed.items():
            rows.append({"scenario": "caterpillar_multi_bend4", "policy": policy, "seed": str(seed),
                         "success": "0" if math.isnan(t) else "1", "time_to_goal_s": "" if math.isnan(t) else repr(t)})
    return rows


def test_paired_rows_count_the_seeds_both_reached_and_the_time_saved():
    from training.sweep.compare import paired_table

    lines = paired_table(_result_rows(), "pipeline", labels={"slow": "a slow one"}).splitlines()
    assert lines[0].startswith("| policy | seeds both reached | sooner | as soon | later |")
    assert len(lines) == 4 and "pipeline |" not in "".join(lines[2:])
    # lookahead: seeds 1-3 (4 failed): 5 s and 3 s sooner, one as soon
    cells = [c.strip() for c in lines[2].strip("|").split("|")]
    assert cells[:5] == ["lookahead", "3", "2", "1", "0"]
    assert float(cells[5]) == pytest.approx((5 + 0 + 3) / 3, abs=0.005)
    assert float(cells[6]) == pytest.approx((10.0 + 0.0 + 5.0) / 3, abs=0.05)
    assert float(cells[7]) == pytest.approx(10.0)
    # the slow one, under its label: seeds 1, 2 and 4, later on each
    cells = [c.strip() for c in lines[3].strip("|").split("|")]
    assert cells[:5] == ["a slow one", "3", "0", "0", "3"]
    assert float(cells[5]) == pytest.approx(-(5 + 4 + 3) / 3, abs=0.005)
    assert float(cells[7]) == pytest.approx(-10.0)


def test_paired_refuses_an_unknown_base_and_a_repeated_seed(tmp_path, capsys):
    from training.sweep.compare import paired_table

    with pytest.raises(CompareError, match="'greedy': not swept"):
        paired_table(_result_rows(), "greedy")
    rows = _result_rows()
    with pytest.raises(CompareError, match="seed 1 twice"):
        paired_table(rows + rows[:1], "pipeline")
    assert main([str(tmp_path), "--paired", "pipeline"]) == 2
    assert "is the sweep finished?" in capsys.readouterr().err
    (tmp_path / "summary.json").write_text(json.dumps({"groups": []}), encoding="utf-8")
    assert main([str(tmp_path), "--paired", "pipeline"]) == 2
    assert "results.csv" in capsys.readouterr().err
    assert main([str(tmp_path), "--paired", "pipeline", "--schedule"]) == 2
    assert "--paired makes its own table" in capsys.readouterr().err


def _write_finished_sweep(folder, rows: list[dict]) -> None:
    """A sweep folder holding ``rows`` as its results.csv and an empty summary.json."""
    import csv

    (folder / "summary.json").write_text(json.dumps({"groups": []}), encoding="utf-8")
    with open(folder / "results.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def test_paired_reads_a_sweeps_results_csv(tmp_path, capsys):
    _write_finished_sweep(tmp_path, _result_rows())
    assert main([str(tmp_path), "--paired", "pipeline"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[2].startswith("| lookahead | 3 | 2 | 1 | 0 |")


def _failure_rows() -> list[dict]:
    def row(policy: str, seed: int, success: bool, duration: float, left: dict[str, tuple[float, float, float]]) -> dict:
        out = {"scenario": "top_observer_team4_legs", "policy": policy, "seed": str(seed), "success": str(int(success)),
               "time_to_goal_s": str(duration if success else math.nan), "duration_s": str(duration)}
        for robot in ("ugv_0", "ugv_1"):
            distance, heading, startable = left.get(robot, (0.01, 2.0, 0.0))
            out |= {f"{robot}_goal_time_s": str(math.nan if robot in left else 5.0), f"{robot}_goal_distance_m": str(distance),
                    f"{robot}_goal_heading_error_deg": str(heading), f"{robot}_startable_s": str(startable)}
        return out

    return [
        row("greedy", 1, True, 10.0, {}),
        row("greedy", 2, True, 12.0, {}),
        row("clone", 1, False, 100.0, {"ugv_1": (0.02, 30.0, 80.0)}),
        row("clone", 2, False, 120.0, {"ugv_0": (0.50, 10.0, 100.0), "ugv_1": (0.04, 50.0, 90.0)}),
        row("clone", 3, True, 11.0, {}),
    ]


def test_failures_count_the_robots_left_and_how_they_were_left():
    from training.sweep.compare import failure_table

    lines = failure_table(_failure_rows(), labels={"clone": "the clone"}).splitlines()
    assert lines[0].startswith("| policy | failed | robots left per failure |")
    assert lines[2] == "| greedy | 0 of 2 | - | - | - | - | - |"
    cells = [c.strip() for c in lines[3].strip("|").split("|")]
    # three robots left over two failures: distances 0.02, 0.50, 0.04; headings 30, 10, 50; startable 80, 100, 90
    assert cells == ["the clone", "2 of 3", "1.5", "0.04", "30", "90.0", "110.0"]


def test_startable_time_is_summed_over_each_episodes_robots():
    from training.sweep.compare import startable_table

    lines = startable_table(_failure_rows(), labels={"clone": "the clone"}).splitlines()
    assert lines[0] == "| policy | episodes | startable s per episode (mean) | median | episodes over 10 s |"
    assert lines[2] == "| greedy | 2 | 0.0 | 0.0 | 0 % |"
    # the clone's episodes: 80 (ugv_1), 100 + 90, and 0 s
    assert lines[3] == "| the clone | 3 | 90.0 | 80.0 | 67 % |"


def test_failures_refuse_a_sweep_without_the_goal_columns(tmp_path, capsys):
    from training.sweep.compare import failure_table, startable_table

    old = [{k: v for k, v in r.items() if "goal_distance" not in k} for r in _failure_rows()]
    with pytest.raises(CompareError, match="predates the robots' goal distances"):
        failure_table(old)
    _write_finished_sweep(tmp_path, _failure_rows())
    assert main([str(tmp_path), "--failures"]) == 0
    assert capsys.readouterr().out.splitlines()[3].startswith("| clone | 2 of 3 | 1.5 |")
    assert main([str(tmp_path), "--failures", "--paired", "greedy"]) == 2
    assert "--failures makes its own table" in capsys.readouterr().err
    assert main([str(tmp_path), "--startable"]) == 0
    assert capsys.readouterr().out.splitlines()[3].startswith("| clone | 3 | 90.0 |")
    assert main([str(tmp_path), "--startable", "--failures"]) == 2
    assert "--startable makes its own table" in capsys.readouterr().err
    with pytest.raises(CompareError, match="sweep again for --startable"):
        startable_table(old)
