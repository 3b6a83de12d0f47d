"""``schedule_split``: where a successful episode's time went, seen from the last robot to arrive,
and the harness's episodes carrying it (time to goal = moving + waiting + still); ``schedule_bound``:
the soonest any order of the same moves could arrive; ``start_waves`` and ``fewest_waves``: the
waves of starts an episode took and the fewest its legs allow."""

from __future__ import annotations

import math

import pytest

from training.evaluation.episode import fewest_waves, mobile_times, schedule_bound, schedule_split, start_waves
from training.evaluation.harness import evaluate


def test_split_counts_the_last_robots_standing_steps_by_what_the_others_did():
    times = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    mobile = {
        "a": [False, True, True, False, False, False, False],   # arrives at 3 s
        "b": [False, False, False, False, True, True, False],   # arrives last, at 6 s
        "c": [False, False, True, False, False, True, False],
    }
    waiting, still = schedule_split(times, mobile, {"a": 3.0, "b": 6.0, "c": 5.0})
    # b stands in steps 1-2 while others move (waiting), in step 3 and 6 with everyone (still); it moves in 4-5
    assert waiting == pytest.approx(2.0)
    assert still == pytest.approx(2.0)
    moving = 6.0 - waiting - still
    assert moving == pytest.approx(sum(1.0 for k in range(1, 7) if mobile["b"][k]))


def test_split_is_nan_when_some_robot_never_arrived():
    waiting, still = schedule_split([0.0, 1.0], {"a": [False, True], "b": [False, False]}, {"a": 1.0, "b": math.nan})
    assert math.isnan(waiting) and math.isnan(still)


def test_mobile_times_count_the_steps_after_which_a_robot_was_mobile():
    times = [0.0, 0.5, 1.5, 2.0, 4.0]
    mobile = {"a": [False, True, True, False, True], "b": [True, False, False, False, False]}
    assert mobile_times(times, mobile) == {"a": pytest.approx(3.5), "b": 0.0}  # b's flag at the reset counts no step


def test_schedule_bound_is_the_longest_mover_or_the_work_of_all_but_one_robot():
    assert schedule_bound({"a": 18.0, "b": 14.4, "c": 13.8, "d": 11.0}) == pytest.approx(57.2 / 3)  # the team's work binds
    assert schedule_bound({"a": 23.8, "b": 14.9, "c": 14.9, "d": 14.4}) == 23.8                     # the longest mover binds
    assert schedule_bound({"a": 3.0, "b": 4.0}) == 7.0       # two robots: never both mobile
    assert schedule_bound({"a": 3.0}) == 3.0
    with pytest.raises(ValueError, match="at least one robot"):
        schedule_bound({})
    with pytest.raises(ValueError, match="'b'"):
        schedule_bound({"a": 1.0, "b": math.nan})
    with pytest.raises(ValueError, match="'a'"):
        schedule_bound({"a": -1.0})


def test_waves_are_the_starts_no_stop_separates():
    mobile = {
        #     reset  1      2      3      4      5      6      7
        "a": [False, True, True, False, False, True, True, False],  # starts at 1 and 5
        "b": [False, False, True, True, True, False, False, False],  # starts at 2 (no stop since 1: same wave)
        "c": [False, False, False, False, True, True, False, False],  # starts at 4, after a's stop at 3: a new wave
    }
    # a's start at 5 follows b's stop at 5 in the same step: starts come first, so it joins c's wave
    starts, waves = start_waves(mobile)
    assert starts == {"a": 2, "b": 1, "c": 1}
    assert waves == 2
    # the same start one step later, after that stop: a third wave
    later = dict(mobile, a=[False, True, True, False, False, False, True, False])
    assert start_waves(later) == ({"a": 2, "b": 1, "c": 1}, 3)
    assert start_waves({"a": [False, False], "b": [False, False]}) == ({"a": 0, "b": 0}, 0)
    assert start_waves({"a": [True, True, False]}) == ({"a": 0}, 0)  # mobile from the reset: no start


def test_fewest_waves_hold_one_start_per_robot_and_all_robots_but_one():
    assert fewest_waves({"a": 5, "b": 4, "c": 4, "d": 3}) == 6   # 16 starts, 3 a wave
    assert fewest_waves({"a": 7, "b": 2, "c": 2, "d": 1}) == 7   # a's own legs, one a wave
    assert fewest_waves({"a": 3, "b": 4}) == 7                   # two robots: one at a time
    assert fewest_waves({"a": 3}) == 3
    assert fewest_waves({"a": 0, "b": 0, "c": 0}) == 0
    with pytest.raises(ValueError, match="at least one robot"):
        fewest_waves({})
    with pytest.raises(ValueError, match="'b'"):
        fewest_waves({"a": 1, "b": -1})
    with pytest.raises(ValueError, match="'a'"):
        fewest_waves({"a": 1.5})
    with pytest.raises(ValueError, match="'a'"):
        fewest_waves({"a": True})


def test_evaluated_episodes_split_their_time_to_goal():
    result = evaluate("top_observer_team4", "greedy", 2, 1_000_000)
    for ep in result.episodes:
        assert ep.success
        moving = ep.time_to_goal_s - ep.waiting_s - ep.still_s
        assert 0.0 < moving <= ep.time_to_goal_s
        assert ep.waiting_s >= 0.0 and ep.still_s > 0.0  # every leg ends in a dwell
        row = ep.row()
        assert row["waiting_s"] == ep.waiting_s and row["still_s"] == ep.still_s
        # the greedy schedule is one schedule of its own moves: never sooner than their bound
        assert 0.0 < ep.bound_s <= ep.time_to_goal_s and row["bound_s"] == ep.bound_s
        # and never in fewer waves than its legs allow; every robot starts, so at least one wave
        assert 1.0 <= ep.fewest_waves <= ep.waves and row["waves"] == ep.waves
        assert ep.fewest_waves_time_s == pytest.approx(ep.time_to_goal_s * ep.fewest_waves / ep.waves)
    assert result.summary["waiting_s"]["n"] == 2 and result.summary["bound_s"]["n"] == 2
    assert result.summary["waves"]["n"] == 2 and result.summary["fewest_waves_time_s"]["n"] == 2
