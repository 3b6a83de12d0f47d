"""PlannedPolicy: executes the planner's turns in velocity mode, on estimates only."""

from __future__ import annotations

import math

import numpy as np
import pytest
from policy_guard import guarded

from agents.policies import PlannedPolicy, Policy
from moma_env.env.factory import parallel_env

#: Configuration -> bound (m) on every UGV's final localisation error.
ERROR_BOUND_M = {"top_observer": 0.05, "caterpillar": 0.10, "caterpillar_multi": 0.10, "caterpillar_sled": 0.10}


def _run(configuration: str, seed: int = 0):
    env = parallel_env(configuration, action_mode="velocity")
    observations, infos = env.reset(seed=seed)
    policy = PlannedPolicy()
    policy.reset(env, seed=seed)
    granted: list[str] = []
    terminated = truncated = False
    steps = 0
    last_infos = infos
    while env.agents:
        actions = policy.act(observations, guarded(infos))
        for agent, action in actions.items():
            assert env.action_space(agent).contains(action), (agent, action)
        observations, _, terms, truncs, infos = env.step(actions)
        steps += 1
        terminated, truncated = any(terms.values()), any(truncs.values())
        last_infos = infos
        for info in infos.values():
            granted += [e.split(":", 1)[1] for e in info["events"] if e.startswith("mobile:")]
    return env, policy, granted, terminated, truncated, steps, last_infos


@pytest.mark.parametrize("configuration", sorted(ERROR_BOUND_M))
def test_reaches_goals_in_plan_order_with_small_error(configuration):
    env, policy, granted, terminated, truncated, steps, infos = _run(configuration)
    assert terminated and not truncated
    assert steps < env.max_cycles
    planned = [turn.device for turn in policy.plan.turns]
    # The episode ends when the goals are reached, possibly before a trailing sled turn.
    assert len(granted) >= len(planned) - 1
    assert granted == planned[: len(granted)]
    assert granted == policy.device_order
    for agent in env.possible_agents:
        if agent == "observer":
            continue
        error = infos[agent]["localisation_error"]
        assert error is not None and math.isfinite(error)
        assert error < ERROR_BOUND_M[configuration], (agent, error)


def test_same_seed_same_actions():
    runs = []
    for _ in range(2):
        env = parallel_env("caterpillar", action_mode="velocity")
        observations, infos = env.reset(seed=3)
        policy = PlannedPolicy()
        policy.reset(env, seed=3)
        trace = []
        for _ in range(150):
            actions = policy.act(observations, infos)
            trace.append(np.concatenate([actions[a] for a in sorted(actions)]))
            observations, _, _, _, infos = env.step(actions)
        runs.append(np.array(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_is_a_policy():
    assert isinstance(PlannedPolicy(), Policy)


def test_switching_mode_is_rejected():
    env = parallel_env("caterpillar", action_mode="switching")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="velocity"):
        PlannedPolicy().reset(env, seed=0)


def test_act_before_reset_is_rejected():
    with pytest.raises(RuntimeError, match="reset"):
        PlannedPolicy().act({}, {})


@pytest.mark.parametrize("kwargs", [{"reel_stall_s": 0.0}, {"reel_stall_m": -1.0}, {"reel_stall_s": math.nan}, {"reel_stall_s": True}])
def test_bad_parameters_are_rejected(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        PlannedPolicy(**kwargs)
