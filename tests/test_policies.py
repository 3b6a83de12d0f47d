"""Scripted baseline policies: they reach the goals on estimates only, handle refusals,
and never read ground truth from infos."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from policy_guard import guarded

from agents.policies import (
    ADVANCE,
    HOLD,
    CaterpillarMulti,
    CaterpillarSled,
    CaterpillarTwo,
    Policy,
    RandomPolicy,
    TopObserverLeapfrog,
    scripted_policy,
)
from moma_env.env.factory import parallel_env

CONFIGURATIONS = ("top_observer", "caterpillar", "caterpillar_sled", "caterpillar_multi")
#: Final localisation error bound (m): the top view is accurate, the caterpillars
#: measure depth along the optical axis of a forward camera.
ERROR_BOUND_M = {"top_observer": 0.05, "caterpillar": 0.15, "caterpillar_sled": 0.15, "caterpillar_multi": 0.15}


def run_episode(configuration: str, seed: int, random_scenarios: bool = False) -> dict[str, Any]:
    """One episode of the scripted policy; the policy only ever sees truth-guarded infos."""
    env = parallel_env(configuration, random_scenarios=random_scenarios)
    observations, infos = env.reset(seed=seed)
    policy = scripted_policy(configuration)
    policy.reset(env, seed=seed)
    terminations: dict[str, bool] = {}
    last_infos = infos
    steps = 0
    while env.agents:
        actions = policy.act(observations, guarded(infos))
        observations, _, terminations, _, infos = env.step(actions)
        last_infos = infos
        steps += 1
    errors = {agent: info["localisation_error"] for agent, info in last_infos.items()}
    success = bool(terminations) and all(terminations.values())
    return {"success": success, "steps": steps, "max_cycles": env.max_cycles, "errors": errors}


# ---------------------------------------------------------------------- default scenarios
@pytest.mark.parametrize(
    "configuration",
    [
        "top_observer",
        "caterpillar",
        "caterpillar_sled",
        "caterpillar_multi",
    ],
)
def test_scripted_policy_reaches_every_goal_on_the_default_scenario(configuration):
    result = run_episode(configuration, seed=0)
    assert result["success"], result
    assert result["steps"] < result["max_cycles"]
    for agent, error in result["errors"].items():
        assert error is not None and error < ERROR_BOUND_M[configuration], (agent, error)


# ---------------------------------------------------------------------- random scenarios
@pytest.mark.parametrize("configuration", CONFIGURATIONS)
def test_scripted_policy_success_rate_on_random_scenarios(configuration):
    results = [run_episode(configuration, seed, random_scenarios=True) for seed in range(5)]
    successes = sum(r["success"] for r in results)
    print(f"{configuration}: {successes}/5 random scenarios reached every goal")
    assert successes >= 4, [(r["success"], r["errors"]) for r in results]


# ---------------------------------------------------------------------- protocol, factory
@pytest.mark.parametrize(
    ("configuration", "cls"),
    [
        ("top_observer", TopObserverLeapfrog),
        ("caterpillar", CaterpillarTwo),
        ("caterpillar_sled", CaterpillarSled),
        ("caterpillar_multi", CaterpillarMulti),
    ],
)
def test_scripted_policy_factory_builds_the_configuration_policy(configuration, cls):
    policy = scripted_policy(configuration)
    assert type(policy) is cls
    assert isinstance(policy, Policy)


def test_scripted_policy_rejects_unknown_configuration():
    with pytest.raises(ValueError, match="no_such"):
        scripted_policy("no_such")


def test_scripted_policy_rejects_velocity_mode():
    env = parallel_env("caterpillar", action_mode="velocity")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="switching"):
        scripted_policy("caterpillar").reset(env)


def test_caterpillar_two_rejects_a_file_of_three():
    env = parallel_env("caterpillar_multi")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="robots"):
        CaterpillarTwo().reset(env)


def test_act_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        TopObserverLeapfrog().act({}, {})


# ---------------------------------------------------------------------- truth is off limits
def test_guard_catches_a_policy_that_reads_truth():
    class Cheater:
        def reset(self, env, seed=None):
            pass

        def act(self, observations, infos):
            return {a: HOLD if infos[a]["truth"] else ADVANCE for a in observations}

    env = parallel_env("caterpillar")
    observations, infos = env.reset(seed=0)
    with pytest.raises(AssertionError, match="truth"):
        Cheater().act(observations, guarded(infos))


@pytest.mark.parametrize("configuration", CONFIGURATIONS)
def test_scripted_policy_never_reads_truth_and_moves(configuration):
    env = parallel_env(configuration)
    observations, infos = env.reset(seed=1)
    policy = scripted_policy(configuration)
    policy.reset(env, seed=1)
    for _ in range(150):  # guarded() raises inside act() on a forbidden key
        observations, _, _, _, infos = env.step(policy.act(observations, guarded(infos)))
    assert policy.legs_done >= 1


# ---------------------------------------------------------------------- refusals
def _refused(reason: str) -> dict[str, Any]:
    return {"events": [f"refused:x:{reason}"], "refused": [reason], "status": "localised", "static": True, "estimate": None}


def test_no_reference_refusals_pass_the_turn_and_cycle_without_deadlock():
    env = parallel_env("caterpillar")
    observations, _ = env.reset(seed=0)
    policy = CaterpillarTwo(give_up_s=0.2)  # 5 steps at 25 Hz
    policy.reset(env)
    refused = {a: _refused("no_reference") for a in observations}
    movers = []
    for _ in range(40):
        actions = policy.act(observations, refused)
        assert sum(a != HOLD for a in actions.values()) <= 1  # one mover at a time
        movers.append(next((a for a, act in actions.items() if act != HOLD), None))
    assert movers[0] == "ugv_0"  # the leader goes first
    assert "ugv_1" in movers  # ugv_0 refused: the follower is tried
    assert movers[-1] is not None  # still requesting: never stuck holding
    changes = sum(1 for a, b in zip(movers, movers[1:]) if a != b)
    assert changes >= 3  # it keeps cycling between the candidates


def test_dwell_refusals_are_retried_by_the_same_mover():
    env = parallel_env("caterpillar")
    observations, _ = env.reset(seed=0)
    policy = CaterpillarTwo(give_up_s=0.2)
    policy.reset(env)
    refused = {a: _refused("dwell") for a in observations}
    for _ in range(40):
        actions = policy.act(observations, refused)
        assert actions == {"ugv_0": ADVANCE, "ugv_1": HOLD}


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True])
def test_turn_taking_rejects_bad_timing(bad):
    with pytest.raises(ValueError, match="give_up_s"):
        TopObserverLeapfrog(give_up_s=bad)


# ---------------------------------------------------------------------- random policy
def _random_rollout(policy_seed: int, steps: int = 30, configuration: str = "caterpillar_sled", **env_kwargs) -> list:
    env = parallel_env(configuration, **env_kwargs)
    observations, infos = env.reset(seed=0)
    policy = RandomPolicy(policy_seed)
    policy.reset(env)
    trace = []
    for _ in range(steps):
        if not env.agents:
            break
        actions = policy.act(observations, guarded(infos))
        trace.append({a: np.asarray(v).tolist() for a, v in actions.items()})
        for agent, action in actions.items():
            assert env.action_space(agent).contains(action)
        observations, _, _, _, infos = env.step(actions)
    return trace


@pytest.mark.parametrize("kwargs", [{}, {"action_mode": "velocity"}])
def test_random_policy_is_reproducible_with_a_seed(kwargs):
    assert _random_rollout(3, **kwargs) == _random_rollout(3, **kwargs)
    assert _random_rollout(3, **kwargs) != _random_rollout(4, **kwargs)


def test_random_policy_reset_seed_reseeds():
    env = parallel_env("top_observer")
    observations, _ = env.reset(seed=0)
    policy = RandomPolicy(0)
    policy.reset(env, seed=7)
    first = [policy.act(observations, {}) for _ in range(20)]
    policy.reset(env, seed=7)
    assert [policy.act(observations, {}) for _ in range(20)] == first
