"""The greedy parallel baseline: several movers at once, never against the rules."""

from __future__ import annotations

import math

import pytest
from policy_guard import guarded

from agents.policies import GreedyParallelPolicy, TopObserverLeapfrog
from agents.policies.base import HOLD
from moma_env.env.factory import parallel_env


def run(policy, n_ugvs: int, seed: int) -> dict:
    """One episode on a random top_observer layout of ``n_ugvs`` robots (truth-guarded infos)."""
    env = parallel_env("top_observer", random_scenarios=True, n_ugvs=n_ugvs, action_masks=True)
    observations, infos = env.reset(seed=seed)
    policy.reset(env, seed=seed)
    most_movers = refused = 0
    terminations: dict[str, bool] = {}
    while env.agents:
        observations, _, terminations, _, infos = env.step(policy.act(observations, guarded(infos)))
        most_movers = max(most_movers, sum(not info["static"] for info in infos.values()))
        refused += sum(len(info["refused"]) for info in infos.values())
    return {"success": bool(terminations) and all(terminations.values()), "time": env.frame.time, "movers": most_movers, "refused": refused}


def test_greedy_moves_several_robots_at_once_without_refusals_and_beats_turn_taking():
    greedy = run(GreedyParallelPolicy(), n_ugvs=4, seed=3)
    turns = run(TopObserverLeapfrog(), n_ugvs=4, seed=3)
    assert greedy["success"] and turns["success"]
    assert greedy["movers"] >= 2
    assert turns["movers"] == 1
    assert greedy["refused"] == 0
    assert greedy["time"] < turns["time"]


def test_greedy_needs_the_action_masks():
    env = parallel_env("top_observer")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action_masks=True"):
        GreedyParallelPolicy().reset(env)


def test_greedy_refuses_velocity_mode_and_sleds():
    env = parallel_env("top_observer", action_mode="velocity", action_masks=False)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action_masks=True|switching"):
        GreedyParallelPolicy().reset(env)
    env = parallel_env("caterpillar_sled", action_masks=True)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="sled"):
        GreedyParallelPolicy().reset(env)


@pytest.mark.parametrize("value", [0, -1.0, float("nan"), True])
def test_greedy_rejects_bad_stall_settings(value):
    with pytest.raises(ValueError, match="stall_s"):
        GreedyParallelPolicy(stall_s=value)


@pytest.mark.parametrize("seed", [3, 8])
def test_greedy_starts_the_static_robot_farthest_from_its_goal_that_may_start(seed):
    """Every leg the policy starts goes to the robot that is, by the truth, the farthest from
    its goal among the static robots not at their goal whose masks allow a start (up to the
    estimates' error: a candidate more than 5 cm farther would be a wrong choice)."""
    env = parallel_env("top_observer", random_scenarios=True, n_ugvs=4, action_masks=True)
    observations, infos = env.reset(seed=seed)
    policy = GreedyParallelPolicy()
    policy.reset(env, seed=seed)
    goals = env.scenario.goals
    starts = 0
    while env.agents:
        actions = policy.act(observations, guarded(infos))
        static = {a for a in env.agents if infos[a]["static"]}
        started = [a for a in static if actions[a] != HOLD]
        assert len(started) <= 1  # one new mover a step
        if started:
            starts += 1
            distance = {a: math.dist(env.frame.truth[a][:2], goals[a][:2]) for a in static}
            candidates = [a for a in static if infos[a]["action_mask"][actions[started[0]]] and distance[a] > env.scenario.goal_tolerance_m]
            assert all(distance[a] <= distance[started[0]] + 0.05 for a in candidates), (distance, started)
        observations, _, _, _, infos = env.step(actions)
    assert starts >= 8  # four robots, several legs each
