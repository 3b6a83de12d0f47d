"""``leg_lengths``: in switching mode each advance action chooses how far its leg goes."""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest
from gymnasium import spaces

import moma_env  # noqa: F401 - registers the Gymnasium ids
from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from moma_env.tasks import TASKS, TEAM4_LEG_LENGTHS


def _greedy_like_actions(env, advance: int) -> dict[str, int]:
    """Every static robot the masks allow asks to advance with ``advance``; movers keep it."""
    masks = env.action_masks()
    return {a: advance if masks[a][advance] else 0 for a in env.agents}


def test_one_leg_length_is_the_plain_env_with_that_leg_length():
    chosen = parallel_env("top_observer_team4", leg_lengths=(1.5,), max_cycles=300)
    plain = parallel_env("top_observer_team4", leg_length=1.5, max_cycles=300)
    obs_a, _ = chosen.reset(seed=1000003)
    obs_b, _ = plain.reset(seed=1000003)
    steps = 0
    while chosen.agents:
        actions = _greedy_like_actions(chosen, 1)
        assert actions == _greedy_like_actions(plain, 1)
        obs_a, rew_a, term_a, trunc_a, info_a = chosen.step(actions)
        obs_b, rew_b, term_b, trunc_b, info_b = plain.step(actions)
        assert rew_a == rew_b and term_a == term_b and trunc_a == trunc_b
        for agent in obs_a:
            assert np.array_equal(obs_a[agent], obs_b[agent])
            assert info_a[agent]["truth"] == info_b[agent]["truth"] and info_a[agent]["events"] == info_b[agent]["events"]
        steps += 1
    assert steps > 50 and chosen.switches_total == plain.switches_total > 0


@pytest.mark.parametrize("action", [1, 2, 3, 4])
def test_each_advance_action_drives_its_own_leg_length(action):
    env = parallel_env("top_observer_team4_legs")
    env.reset(seed=1000000)
    start = env.frame.estimated["ugv_0"]
    goal = env.scenario.goals["ugv_0"]
    env.step({a: (action if a == "ugv_0" else 0) for a in env.agents})
    leg = env.action_mode.legs["ugv_0"]
    expected = min(TEAM4_LEG_LENGTHS[action - 1], math.hypot(goal[0] - start[0], goal[1] - start[1]))
    assert math.hypot(leg[0] - start[0], leg[1] - start[1]) == pytest.approx(expected, abs=1e-9)


def test_the_advances_share_a_mask_and_a_committed_robot_may_only_continue():
    env = parallel_env("top_observer_team4_legs")
    _, infos = env.reset(seed=1000000)
    assert env.action_space("ugv_0") == spaces.Discrete(1 + len(TEAM4_LEG_LENGTHS))
    for agent in env.agents:
        mask = infos[agent]["action_mask"]
        assert mask.shape == (5,) and len(set(mask[1:].tolist())) == 1
    for _ in range(30):  # ugv_0 drives its longest leg; the others hold
        _, _, _, _, infos = env.step({a: (4 if a == "ugv_0" else 0) for a in env.agents})
    assert "ugv_0" in env.action_mode.committed
    assert infos["ugv_0"]["action_mask"].tolist() == [0, 1, 0, 0, 0]
    for agent in ("ugv_1", "ugv_2", "ugv_3"):  # the rules judge a start, not its length
        assert len(set(infos[agent]["action_mask"][1:].tolist())) == 1


def test_a_towing_robot_reels_with_the_action_after_the_advances():
    env = parallel_env("caterpillar_sled", leg_lengths=(0.3, 0.6), action_masks=True)
    env.reset(seed=0)
    assert env.action_space("ugv_0") == spaces.Discrete(4) and env.action_mode.reel == 3
    sled = env.action_mode.tows["ugv_0"]
    assert env.action_mode.requests({"ugv_0": 3}, frozenset()) == {sled: True}
    assert env.action_mode.requests({"ugv_0": 2}, frozenset()) == {"ugv_0": True}


@pytest.mark.parametrize(
    "options, field",
    [
        ({"action_mode": "velocity", "leg_lengths": (0.5,)}, "env.leg_lengths"),
        ({"leg_lengths": ()}, "env.leg_lengths"),
        ({"leg_lengths": "1.0"}, "env.leg_lengths"),
        ({"leg_lengths": (0.5, -1.0)}, "env.leg_lengths[1]"),
        ({"leg_lengths": (0.5, 0.5)}, "env.leg_lengths"),
    ],
)
def test_bad_leg_lengths_name_the_field(options, field):
    with pytest.raises(ConfigError) as err:
        parallel_env("top_observer", **options)
    assert err.value.field == field


def test_the_leg_task_is_registered_and_batched():
    task = TASKS["top_observer_team4_legs"]
    assert task.options["leg_lengths"] == TEAM4_LEG_LENGTHS
    env = gymnasium.make(task.gymnasium_id)
    assert env.action_space == spaces.MultiDiscrete([5, 5, 5, 5])
    envs = gymnasium.make_vec(task.gymnasium_id, num_envs=2)
    obs, _ = envs.reset(seed=0)
    assert obs.shape[0] == 2 and envs.action_masks().shape == (2, 20)
    envs.close()


def test_greedy_at_a_leg_length_is_the_greedy_policy_on_the_env_with_that_leg_length():
    from training.evaluation.harness import evaluate

    chosen = evaluate("top_observer_team4_legs", "greedy@1.5", 3, 1000000)
    plain = evaluate("top_observer_team4", "greedy", 3, 1000000, leg_length=1.5)
    for a, b in zip(chosen.episodes, plain.episodes):
        assert a.success and b.success
        assert (a.time_to_goal_s, a.n_switches) == (b.time_to_goal_s, b.n_switches)
    first = evaluate("top_observer_team4_legs", "greedy", 1, 1000000).episodes[0]
    default = evaluate("top_observer_team4", "greedy", 1, 1000000).episodes[0]
    assert (first.time_to_goal_s, first.n_switches) == (default.time_to_goal_s, default.n_switches)  # action 1: 0.5 m


def test_greedy_leg_specs_are_checked():
    from agents.policies import GreedyParallelPolicy
    from training.evaluation.policies import PolicyEnvError, PolicyLoadError, builtin_name, load_policy, policy_label
    from training.evaluation.harness import evaluate

    assert builtin_name("greedy@1.5") == "greedy" and builtin_name("greedy") == "greedy" and builtin_name("runs/x@1") is None
    assert policy_label("greedy@1.5") == "greedy@1.5"
    assert load_policy("greedy@1.5", "top_observer_team4_legs").leg_m == 1.5
    for spec in ("greedy@x", "greedy@-1", "greedy@inf", "greedy@"):
        with pytest.raises(PolicyLoadError, match="leg length after '@'"):
            load_policy(spec, "top_observer_team4_legs")
    with pytest.raises(PolicyEnvError, match=r"leg_m=1\.5\) needs an env that offers that leg length"):
        evaluate("top_observer_team4", "greedy@1.5", 1, 0)
    with pytest.raises(PolicyEnvError, match=r"leg_lengths \[0\.5, 1\.0, 1\.5, 2\.0\]"):
        evaluate("top_observer_team4_legs", "greedy@1.25", 1, 0)
    with pytest.raises(ValueError, match="leg_m"):
        GreedyParallelPolicy(leg_m=0.0)
