"""Action masks of the switching mode (EnvConfig.action_masks, MomaParallelEnv.action_mask):
what they predict is what the motion rules then decide."""

import numpy as np
import pytest

from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env

CONFIGURATIONS = ["top_observer", "caterpillar", "caterpillar_sled", "caterpillar_multi"]


def _keep(env, agent: str) -> int:
    """The switching action that changes nothing: advance while mobile, hold while static."""
    return 1 if agent in env.mobile_devices else 0


@pytest.mark.parametrize("random_scenarios", [False, True])
@pytest.mark.parametrize("name", CONFIGURATIONS)
def test_the_mask_predicts_the_rules_decision(name, random_scenarios):
    """Every step one agent sends a request (advance, or reel its sled in) and the others keep
    their state; the mask of the previous step says whether the rules grant it."""
    env = parallel_env(name, action_masks=True, random_scenarios=random_scenarios, max_cycles=200)
    rng = np.random.default_rng(7)
    checked = {"granted": 0, "refused": 0}
    for episode in range(2):
        _, infos = env.reset(seed=100 * episode + len(name))
        while env.agents:
            agent = env.agents[int(rng.integers(len(env.agents)))]
            n = env.action_space(agent).n
            action = int(rng.integers(1, n))
            mask = infos[agent]["action_mask"]
            assert mask.dtype == np.int8 and mask.shape == (n,) and mask[0] == 1
            sled = {s.robot: s.name for s in env.scenario.world.sleds}.get(agent)
            device = agent if action == 1 else sled
            already_mobile = device in env.mobile_devices
            robot_mobile = agent in env.mobile_devices
            actions = {a: _keep(env, a) for a in env.agents}
            actions[agent] = action
            _, _, _, _, infos = env.step(actions)
            events = infos[agent]["events"]
            if already_mobile:
                assert mask[action] == 1
                continue
            granted = f"mobile:{device}" in events
            refused = any(e.startswith(f"refused:{device}:") for e in events)
            assert granted != refused, (events, mask)
            assert bool(mask[action]) == granted, (name, action, events, mask)
            if action == 2 and robot_mobile:
                assert f"static:{agent}" in events  # reeling stops the robot first
            checked["granted" if granted else "refused"] += 1
    assert checked["granted"] > 0 and checked["refused"] > 0, checked


def test_masked_sampling_avoids_most_refusals_and_masks_are_off_by_default():
    """Random actions drawn through the masks are refused only when two agents change at
    once (each mask assumes the others keep their state); unmasked, most requests are."""
    refused = {}
    for masked in (True, False):
        env = parallel_env("top_observer", action_masks=True)
        _, infos = env.reset(seed=0)
        for agent in env.possible_agents:
            env.action_space(agent).seed(0)
        for _ in range(200):
            if not env.agents:
                break
            actions = {a: int(env.action_space(a).sample(infos[a]["action_mask"] if masked else None)) for a in env.agents}
            _, _, _, _, infos = env.step(actions)
        refused[masked] = env.refused_total
    assert refused[True] * 10 < refused[False], refused
    plain = parallel_env("top_observer")
    _, infos = plain.reset(seed=0)
    assert all("action_mask" not in info for info in infos.values())
    np.testing.assert_array_equal(plain.action_mask("ugv_0"), np.array([1, 1], dtype=np.int8))


def test_bad_mask_requests_raise():
    with pytest.raises(ConfigError, match="env.action_masks"):
        parallel_env("top_observer", action_mode="velocity", action_masks=True)
    with pytest.raises(ConfigError, match="env.action_masks"):
        parallel_env("top_observer", action_masks="yes")
    env = parallel_env("top_observer", observer_agent=True)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="switching actions"):
        env.action_mask("observer")
    with pytest.raises(KeyError, match="unknown agent"):
        env.action_mask("ugv_9")


def test_the_centralised_env_gives_the_agents_masks_side_by_side():
    from moma_env.env.factory import centralised_env

    team = centralised_env("caterpillar_multi")
    team.reset(seed=3)
    env = team.parallel_env
    for _ in range(30):
        masks = team.action_masks()
        assert masks.dtype == bool and masks.shape == (int(team.action_space.nvec.sum()),)
        expected = np.concatenate([env.action_mask(a) for a in env.possible_agents]).astype(bool)
        np.testing.assert_array_equal(masks, expected)
        team.step(team.action_space.sample())
    with pytest.raises(ValueError, match="MultiDiscrete"):
        centralised_env("top_observer", action_mode="velocity").action_masks()


@pytest.mark.parametrize("name", CONFIGURATIONS)
def test_pettingzoo_checkers_pass_with_masks_in_infos(name):
    from pettingzoo.test import api_test, parallel_api_test

    from moma_env.env.factory import aec_env

    parallel_api_test(parallel_env(name, action_masks=True), num_cycles=40)
    api_test(aec_env(name, action_masks=True), num_cycles=20)


def test_an_observer_agent_gets_no_mask():
    env = parallel_env("top_observer", action_masks=True, observer_agent=True)
    _, infos = env.reset(seed=0)
    _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    assert "action_mask" not in infos["observer"]
    assert all(infos[a]["action_mask"].shape == (2,) for a in env.agents if a != "observer")


def test_all_masks_at_once_are_each_agents_mask():
    env = parallel_env("caterpillar_sled", random_scenarios=True, observer_agent=False, max_cycles=60)
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    for _ in range(60):
        if not env.agents:
            break
        every = env.action_masks()
        assert sorted(every) == sorted(env.possible_agents)
        for agent, mask in every.items():
            np.testing.assert_array_equal(mask, env.action_mask(agent))
        env.step({a: int(rng.integers(0, env.action_space(a).n)) for a in env.agents})
    with pytest.raises(ValueError, match="switching"):
        velocity = parallel_env("top_observer", action_mode="velocity")
        velocity.reset(seed=0)
        velocity.action_masks()
