"""The greedy parallel baseline: several movers at once, never against the rules."""

from __future__ import annotations

import pytest
from policy_guard import guarded

from agents.policies import GreedyParallelPolicy, TopObserverLeapfrog
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
