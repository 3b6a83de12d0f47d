"""CaterpillarServo: the follower servos to its 0.539 m stand-off on the leader's board."""

from __future__ import annotations

import math

import numpy as np
import pytest
from policy_guard import guarded

from agents.policies import CaterpillarServo, Policy
from agents.policies.caterpillar_servo import standoff_target
from moma_env.env.factory import parallel_env
from moma_env.geometry import se2_to_se3

STANDOFF_M = 0.539


def _true_standoff(env, infos) -> float:
    """Distance (m) from the follower's camera to the leader's board, from the truth poses."""
    world = env.scenario.world
    T_w_leader = se2_to_se3(*infos["ugv_0"]["truth"])
    T_w_follower = se2_to_se3(*infos["ugv_1"]["truth"])
    camera = (T_w_follower @ world.ugv("ugv_1").cameras[0].T_b_c)[:3, 3]
    board = (T_w_leader @ world.ugv("ugv_0").board_mount)[:3, 3]
    return float(np.linalg.norm(camera - board))


def _run(seed: int):
    env = parallel_env("caterpillar", action_mode="velocity")
    observations, infos = env.reset(seed=seed)
    policy = CaterpillarServo()
    policy.reset(env, seed=seed)
    standoffs: list[float] = []
    steps = 0
    terminated = truncated = False
    while env.agents:
        actions = policy.act(observations, guarded(infos))
        for agent, action in actions.items():
            assert env.action_space(agent).contains(action), (agent, action)
        observations, _, terms, truncs, infos = env.step(actions)
        steps += 1
        terminated, truncated = any(terms.values()), any(truncs.values())
        if "static:ugv_1" in infos["ugv_1"]["events"]:
            standoffs.append(_true_standoff(env, infos))
    return env, policy, standoffs, terminated, truncated, steps, infos


@pytest.fixture(scope="module", params=[0, 1])
def episode(request):
    return _run(request.param)


def test_is_a_policy():
    assert isinstance(CaterpillarServo(), Policy)


def test_reaches_goals_before_max_cycles(episode):
    env, policy, _, terminated, truncated, steps, _ = episode
    assert terminated and not truncated
    assert steps < env.max_cycles
    assert policy.follower_turns >= 4  # 2 m in legs of 0.5 m


def test_true_standoff_after_every_follower_turn(episode):
    _, policy, standoffs, *_ = episode
    assert len(standoffs) == policy.follower_turns
    for standoff in standoffs:
        assert abs(standoff - STANDOFF_M) < 0.03, standoffs


def test_final_localisation_errors_small(episode):
    env, *_, infos = episode
    for agent in env.possible_agents:
        error = infos[agent]["localisation_error"]
        assert error is not None and math.isfinite(error)
        assert error < 0.05, (agent, error)


def test_standoff_target_of_default_mounts_is_the_start_spacing():
    env = parallel_env("caterpillar", action_mode="velocity")
    env.reset(seed=0)
    world = env.scenario.world
    x, y, yaw = standoff_target(world.ugv("ugv_1").cameras[0].T_b_c, world.ugv("ugv_0").board_mount, STANDOFF_M)
    # The default scenario starts the follower exactly at the stand-off, 0.8 m behind the leader.
    assert x == pytest.approx(-0.8, abs=1e-9)
    assert y == pytest.approx(0.0, abs=1e-9)
    assert yaw == pytest.approx(0.0, abs=1e-9)


def test_same_seed_same_actions():
    runs = []
    for _ in range(2):
        env = parallel_env("caterpillar", action_mode="velocity")
        observations, infos = env.reset(seed=3)
        policy = CaterpillarServo()
        policy.reset(env, seed=3)
        trace = []
        for _ in range(200):
            actions = policy.act(observations, infos)
            trace.append(np.concatenate([actions[a] for a in sorted(actions)]))
            observations, _, _, _, infos = env.step(actions)
        runs.append(np.array(trace))
    assert np.array_equal(runs[0], runs[1])


def test_wrong_mode_or_configuration_raises():
    with pytest.raises(ValueError, match="velocity"):
        env = parallel_env("caterpillar")
        env.reset(seed=0)
        CaterpillarServo().reset(env)
    with pytest.raises(ValueError, match="caterpillar"):
        env = parallel_env("top_observer", action_mode="velocity")
        env.reset(seed=0)
        CaterpillarServo().reset(env)


@pytest.mark.parametrize("bad", [0.0, -0.5, math.nan, True])
def test_bad_arguments_raise(bad):
    with pytest.raises(ValueError, match="standoff"):
        CaterpillarServo(standoff=bad)


def test_act_before_reset_raises():
    with pytest.raises(RuntimeError):
        CaterpillarServo().act({}, {})
