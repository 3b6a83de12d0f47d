"""``GreedyRolloutPolicy``: the greedy policy with a lookahead over its starts in copies of the env.

What makes it a rollout of the greedy policy: a copy's future is the env's own (the
greedy's choice, rolled out, reaches the goals exactly when the greedy episode does),
the lookahead leaves the env untouched, and the time it expects never grows. Reusing the
last rollout for the greedy's choice changes no decision, and an env driven off that
rollout gets a fresh one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.policies import ADVANCE, HOLD, GreedyParallelPolicy, GreedyRolloutPolicy
from moma_env.env.factory import parallel_env
from training.evaluation.episode import run_episode
from training.evaluation.policies import load_policy

TASK = "top_observer_team4"
SEED = 1_000_003


@pytest.fixture(scope="module")
def greedy_time() -> float:
    result = run_episode(parallel_env(TASK), GreedyParallelPolicy(), 0, SEED)
    assert result.success
    return result.time_to_goal_s


def test_the_greedy_choice_rolled_out_is_the_greedy_episode(greedy_time):
    env = parallel_env(TASK)
    observations, infos = env.reset(seed=SEED)
    policy = GreedyRolloutPolicy()
    policy.reset(env, seed=SEED)
    actions, startable = policy.base.plan(observations, infos)
    assert startable, "at the reset every robot is static and away from its goal"
    state, time = env.state().copy(), env.frame.time
    assert policy.time_to_goal(actions | {startable[0]: ADVANCE}) == greedy_time
    np.testing.assert_array_equal(env.state(), state)  # the lookahead ran in a copy
    assert env.frame.time == time and env.agents
    assert policy.lookaheads == 1


def test_the_expected_time_never_grows_and_starts_at_most_the_greedys(greedy_time):
    env = parallel_env(TASK)
    observations, infos = env.reset(seed=SEED)
    policy = GreedyRolloutPolicy()
    policy.reset(env, seed=SEED)
    assert math.isnan(policy.expected_time_s)
    expected = []
    while env.agents and len(expected) < 3:  # the first decisions: the starts after the reset
        before = policy.lookaheads
        observations, _, _, _, infos = env.step(policy.act(observations, infos))
        if policy.lookaheads > before:
            expected.append(policy.expected_time_s)
    assert len(expected) == 3
    assert expected[0] <= greedy_time
    assert all(later <= earlier for earlier, later in zip(expected, expected[1:]))
    # every decision step tried at least two choices, the greedy's from the last rollout or anew
    assert policy.lookaheads + policy.reused >= len(expected) * 2


def test_reusing_the_last_rollout_changes_no_decision():
    envs, policies, steps = [], [], []
    for reuse in (True, False):
        env = parallel_env(TASK)
        observations, infos = env.reset(seed=SEED)
        policy = GreedyRolloutPolicy(reuse=reuse)
        policy.reset(env, seed=SEED)
        envs.append(env)
        policies.append(policy)
        steps.append((observations, infos))
    reusing, fresh = policies
    decisions = 0
    while envs[0].agents and decisions < 4:
        before = fresh.lookaheads
        chosen = [policy.act(*step) for policy, step in zip(policies, steps)]
        assert chosen[0] == chosen[1]
        if fresh.lookaheads > before:
            decisions += 1
            assert reusing.expected_time_s == fresh.expected_time_s
        steps = [env.step(actions)[::4] for env, actions in zip(envs, chosen)]  # (observations, infos)
        np.testing.assert_array_equal(envs[0].state(), envs[1].state())
    assert decisions == 4
    assert reusing.reused >= 1, "the decision steps after the first continue the last rollout"
    assert reusing.lookaheads + reusing.reused == fresh.lookaheads
    assert fresh.reused == 0


def test_an_env_driven_off_the_rollout_gets_a_fresh_one():
    env = parallel_env(TASK)
    observations, infos = env.reset(seed=SEED)
    policy = GreedyRolloutPolicy()
    policy.reset(env, seed=SEED)
    policy.act(observations, infos)  # the first decision: every robot may start
    assert policy.lookaheads >= 2 and policy.reused == 0
    # Not the decision: every robot holds, so the env leaves the rollout of the chosen start.
    observations, _, _, _, infos = env.step({agent: HOLD for agent in env.agents})
    while env.agents:
        before = policy.lookaheads
        observations, _, _, _, infos = env.step(policy.act(observations, infos))
        if policy.lookaheads > before:
            break
    assert policy.reused == 0, "the state is not the rollout's: the greedy's choice is rolled out again"


def test_bad_use_is_refused():
    with pytest.raises(TypeError, match="wait must be a bool"):
        GreedyRolloutPolicy(wait=1)
    with pytest.raises(TypeError, match="reuse must be a bool"):
        GreedyRolloutPolicy(reuse="yes")
    with pytest.raises(ValueError, match="stall_s"):
        GreedyRolloutPolicy(stall_s=-1.0)
    policy = GreedyRolloutPolicy()
    with pytest.raises(RuntimeError, match="reset"):
        policy.act({}, {})
    with pytest.raises(RuntimeError, match="reset"):
        policy.time_to_goal({})


def test_the_harness_loads_it_by_name():
    policy = load_policy("rollout", TASK)
    assert isinstance(policy, GreedyRolloutPolicy)
    assert policy.env_options == GreedyParallelPolicy.env_options


def test_a_rollout_of_the_file_pipeline_arrives_no_later_than_the_pipeline():
    from agents.policies import FilePipelinePolicy

    bent, seed = "caterpillar_multi_bend4", 100_000
    pipeline = run_episode(parallel_env(bent), FilePipelinePolicy(), 0, seed)
    rollout = GreedyRolloutPolicy(base=FilePipelinePolicy())
    planned = run_episode(parallel_env(bent), rollout, 0, seed)
    assert pipeline.success and planned.success
    assert planned.time_to_goal_s <= pipeline.time_to_goal_s
    assert rollout.lookaheads > 0
    assert isinstance(load_policy("pipeline_rollout", bent).base, FilePipelinePolicy)


def test_the_base_is_a_greedy_policy_and_takes_its_own_settings():
    with pytest.raises(TypeError, match="base must be a GreedyParallelPolicy"):
        GreedyRolloutPolicy(base=object())
    with pytest.raises(ValueError, match="for the default base"):
        GreedyRolloutPolicy(base=GreedyParallelPolicy(), stall_s=3.0)


def test_candidates_of_the_same_rule_as_the_base_change_no_decision():
    runs = []
    for candidates in (None, GreedyParallelPolicy()):
        env = parallel_env(TASK)
        observations, infos = env.reset(seed=SEED)
        policy = GreedyRolloutPolicy(candidates=candidates)
        policy.reset(env, seed=SEED)
        chosen, expected = [], []
        while env.agents and len(expected) < 2:
            before = policy.lookaheads + policy.reused
            actions = policy.act(observations, infos)
            chosen.append(actions)
            if policy.lookaheads + policy.reused > before:
                expected.append(policy.expected_time_s)
            observations, _, _, _, infos = env.step(actions)
        runs.append((chosen, expected, policy.lookaheads, policy.reused))
    assert runs[0] == runs[1]


def test_every_start_the_masks_allow_is_tried_with_the_pipeline_finishing():
    from agents.policies import FilePipelinePolicy

    bent, seed = "caterpillar_multi_bend4", 100_000
    env = parallel_env(bent)
    observations, infos = env.reset(seed=seed)
    own = FilePipelinePolicy()
    own.reset(env, seed=seed)
    pipeline_starts = own.plan(observations, infos)[1]
    greedy = GreedyParallelPolicy()
    greedy.reset(env, seed=seed)
    mask_starts = greedy.plan(observations, infos)[1]
    assert set(pipeline_starts) < set(mask_starts), "at the reset the pipeline starts the leader only"
    tried, expected = {}, {}
    for name, candidates in (("pipeline", None), ("masks", GreedyParallelPolicy())):
        policy = GreedyRolloutPolicy(base=FilePipelinePolicy(), candidates=candidates, reuse=False)
        policy.reset(env, seed=seed)  # both look ahead from the same env, which neither steps
        chosen = policy.act(observations, infos)
        tried[name], expected[name] = policy.lookaheads, policy.expected_time_s
        assert sum(chosen.values()) == 1  # one start, of a robot its candidates allow
        assert {a for a, action in chosen.items() if action == ADVANCE} <= set(mask_starts if candidates else pipeline_starts)
    # each start tried, and waiting; a rollout may stop early, but each counts
    assert tried["pipeline"] == len(pipeline_starts) + 1
    assert tried["masks"] == len(mask_starts) + 1
    # more choices, the pipeline's own first: never a later arrival
    assert expected["masks"] <= expected["pipeline"] < math.inf
    policy = load_policy("pipeline_rollout_masks", bent)
    assert isinstance(policy.base, FilePipelinePolicy)
    assert type(policy.candidates) is GreedyParallelPolicy


def test_the_candidates_are_another_greedy_policy():
    with pytest.raises(TypeError, match="candidates must be a GreedyParallelPolicy"):
        GreedyRolloutPolicy(candidates=object())
    base = GreedyParallelPolicy()
    with pytest.raises(ValueError, match="another policy than base"):
        GreedyRolloutPolicy(base=base, candidates=base)


def test_with_lengths_every_leg_length_of_each_start_is_tried_and_it_arrives_no_later():
    env = parallel_env("top_observer_team4_legs")
    observations, infos = env.reset(seed=SEED)
    policy = load_policy("rollout@1.5", "top_observer_team4_legs")
    assert policy.lengths and policy.base.leg_m == 1.5
    policy.reset(env, seed=SEED)
    base = GreedyParallelPolicy(leg_m=1.5)
    base.reset(env, seed=SEED)
    _, startable = base.plan(observations, infos)
    assert startable
    policy.act(observations, infos)
    # one rollout per choice: the base's start (1.5 m), every other length of it and every
    # length of the other robots that may start, and starting none
    assert policy.lookaheads == 4 * len(startable) + 1
    rolled = run_episode(parallel_env("top_observer_team4_legs"), load_policy("rollout@1.5", "top_observer_team4_legs"), 0, SEED)
    greedy = run_episode(parallel_env("top_observer_team4_legs"), load_policy("greedy@1.5", "top_observer_team4_legs"), 0, SEED)
    assert rolled.success and greedy.success and rolled.time_to_goal_s <= greedy.time_to_goal_s


def test_rollout_nowait_tries_every_start_and_length_but_not_starting_none():
    env = parallel_env("top_observer_team4_legs")
    observations, infos = env.reset(seed=SEED)
    policy = load_policy("rollout_nowait@1.5", "top_observer_team4_legs")
    assert policy.lengths and not policy.wait and policy.base.leg_m == 1.5
    assert not load_policy("rollout_nowait", "top_observer_team4").wait
    policy.reset(env, seed=SEED)
    base = GreedyParallelPolicy(leg_m=1.5)
    base.reset(env, seed=SEED)
    _, startable = base.plan(observations, infos)
    assert startable
    actions = policy.act(observations, infos)
    assert policy.lookaheads == 4 * len(startable)  # rollout@1.5 tries one more: starting none
    assert any(actions[agent] != 0 for agent in startable)  # a robot that may start does
