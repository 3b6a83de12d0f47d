"""``follower_hold_m``: a switching-mode robot that has reached its leg's position turns in place
while its estimate stays within the hold distance, instead of driving back at every noisy estimate."""

from __future__ import annotations

import numpy as np
import pytest

from agents.policies import GreedyParallelPolicy
from moma_env.config import ConfigError
from moma_env.control.waypoint import WaypointFollower, WaypointFollowerConfig
from moma_env.env.factory import parallel_env
from training.evaluation.episode import run_episode

WAYPOINT = (1.0, 0.0, 1.0)
OFF = (1.03, 0.0, 0.0)  # 3 cm from the waypoint's position, 1 rad from its heading


def test_a_held_position_turns_in_place_within_the_hold_distance():
    held = WaypointFollower(WaypointFollowerConfig(hold_m=0.05))
    plain = WaypointFollower(WaypointFollowerConfig())
    # not yet reached: both drive towards the position
    for follower in (held, plain):
        command = follower.command(OFF, WAYPOINT)
        assert command[2] == 0.0 and command[0] < 0.0
        assert not follower.position_reached(OFF, WAYPOINT)
    # reached before: the held follower turns in place, the plain one drives back
    command = held.command(OFF, WAYPOINT, held=True)
    assert command[0] == 0.0 and command[1] == 0.0 and command[2] > 0.0
    assert held.position_reached(OFF, WAYPOINT, held=True)
    assert np.array_equal(plain.command(OFF, WAYPOINT, held=True), plain.command(OFF, WAYPOINT))
    # the heading reached: the waypoint is, with the position held
    turned = (OFF[0], OFF[1], WAYPOINT[2])
    assert held.reached(turned, WAYPOINT, held=True) and not held.reached(turned, WAYPOINT)
    assert not plain.reached(turned, WAYPOINT, held=True)
    # beyond the hold distance the position is not held any more
    far = (1.06, 0.0, 0.0)
    assert not held.position_reached(far, WAYPOINT, held=True) and held.command(far, WAYPOINT, held=True)[2] == 0.0


def test_the_hold_distance_is_checked_where_it_is_given():
    with pytest.raises(ConfigError, match="follower.hold_m"):
        WaypointFollowerConfig(hold_m=0.01)  # below the 2 cm position tolerance
    with pytest.raises(ConfigError, match="env.follower_hold_m"):
        parallel_env("top_observer_team4", follower_hold_m=0.01)
    with pytest.raises(ConfigError, match="env.follower_hold_m"):
        parallel_env("top_observer", action_mode="velocity", follower_hold_m=0.05)
    with pytest.raises(ConfigError, match="env.follower_hold_m"):
        parallel_env("top_observer_team4", follower_hold_m=-1.0)


def test_holding_the_position_brings_the_team_in_sooner_on_a_noisy_end():
    # On this layout a robot's last leg turns 1.2 rad at the UAV's ceiling, where its
    # estimate jitters by a few centimetres: the plain follower drives back and forth for
    # seconds (docs/learning.md, "The follower at the UAV's ceiling").
    seed = 1_000_011
    plain = run_episode(parallel_env("top_observer_team4"), GreedyParallelPolicy(), 0, seed)
    held = run_episode(parallel_env("top_observer_team4", follower_hold_m=0.06), GreedyParallelPolicy(), 0, seed)
    assert plain.success and held.success
    assert held.time_to_goal_s < plain.time_to_goal_s - 3.0
    env = parallel_env("top_observer_team4", follower_hold_m=0.06)
    env.reset(seed=seed)
    assert env.action_mode.held == set()
