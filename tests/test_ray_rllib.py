"""moma_env on RLlib's new API stack (moma_env/integrations): registration, the policy
mapping, the action masks, the batched vector env against RLlib's PettingZoo wrapper,
and one PPO iteration per route on the session's local Ray (2 CPUs)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("ray.rllib", reason="needs the 'ray' extra")

import torch  # noqa: E402
from ray.rllib.core.columns import Columns  # noqa: E402
from ray.tune.registry import ENV_CREATOR, _global_registry  # noqa: E402
from ray_session import ray_local  # noqa: E402,F401

# make test (pytest-xdist, --dist loadgroup) runs every test of the session's Ray on one worker: one Ray.
pytestmark = pytest.mark.xdist_group("ray")

from moma_env.integrations.rllib import (  # noqa: E402
    OBSERVER_POLICY, UGV_POLICY, MaskedObservations, env_name, make_multi_agent_env, policies_of, ppo_config, register_envs)
from moma_env.integrations.rllib_masking import MASK_KEY, OBS_KEY, MaskedPPOTorchRLModule  # noqa: E402
from moma_env.integrations.rllib_vector import BatchedMultiAgentEnv  # noqa: E402
from moma_env.scenarios import CONFIGURATIONS  # noqa: E402
from moma_env.tasks import TASKS  # noqa: E402

OPTIONS = {"max_cycles": 30, "observer_agent": False, "random_scenarios": True}


def test_every_configuration_and_task_is_registered_and_builds():
    names = register_envs()
    assert sorted(names) == sorted(env_name(c) for c in [*CONFIGURATIONS, *TASKS])
    for configuration in CONFIGURATIONS:
        creator = _global_registry.get(ENV_CREATOR, env_name(configuration))
        env = creator(dict(OPTIONS))
        obs, _ = env.reset(seed=0)
        assert set(obs) == set(env.possible_agents)
        for agent, o in obs.items():
            assert env.observation_space[agent].contains(o), (configuration, agent)
        env.close()


def test_policy_mapping_one_shared_ugv_policy_and_the_observer_its_own():
    with_observer = make_multi_agent_env("top_observer", {"observer_agent": True, "action_mode": "velocity", "max_cycles": 5})
    assert policies_of(list(with_observer.possible_agents)) == {UGV_POLICY, OBSERVER_POLICY}
    without = make_multi_agent_env("top_observer", {"observer_agent": False, "max_cycles": 5})
    assert policies_of(list(without.possible_agents)) == {UGV_POLICY}


def test_switching_mode_observes_the_rules_masks():
    env = make_multi_agent_env("top_observer", dict(OPTIONS))
    assert isinstance(env.par_env, MaskedObservations)
    obs, _ = env.reset(seed=3)
    raw = env.par_env.unwrapped
    for agent, o in obs.items():
        np.testing.assert_array_equal(o[MASK_KEY], raw.action_mask(agent).astype(np.float32))
    velocity = make_multi_agent_env("top_observer", {**OPTIONS, "action_mode": "velocity"})
    assert not isinstance(velocity.par_env, MaskedObservations)


def test_the_masked_module_acts_only_among_unmasked_actions():
    env = make_multi_agent_env("top_observer", dict(OPTIONS))
    space, actions = env.observation_space["ugv_0"], env.action_space["ugv_0"]
    module = MaskedPPOTorchRLModule(observation_space=space, action_space=actions, model_config={"fcnet_hiddens": [16]})
    obs, _ = env.reset(seed=0)
    batch_obs = np.stack([obs["ugv_0"][OBS_KEY]] * 64)
    for allowed in range(actions.n):
        mask = np.zeros((64, actions.n), np.float32)
        mask[:, allowed] = 1.0
        batch = {Columns.OBS: {OBS_KEY: torch.as_tensor(batch_obs), MASK_KEY: torch.as_tensor(mask)}}
        logits = module.forward_exploration(batch)[Columns.ACTION_DIST_INPUTS]
        sampled = torch.distributions.Categorical(logits=logits).sample()
        assert (sampled == allowed).all()
        assert (module.forward_inference(batch)[Columns.ACTION_DIST_INPUTS].argmax(-1) == allowed).all()


def test_the_batched_vector_env_steps_like_rllibs_pettingzoo_copies():
    copies = [make_multi_agent_env("top_observer", dict(OPTIONS)) for _ in range(3)]
    batched = BatchedMultiAgentEnv("top_observer", dict(OPTIONS), 3)
    obs_b, _ = batched.reset(seed=5)
    obs_c = [c.reset(seed=5 + i)[0] for i, c in enumerate(copies)]
    rng = np.random.default_rng(0)
    ended = [False] * 3
    resets = 0
    for _ in range(40):
        for i in range(3):
            for agent in obs_c[i]:
                np.testing.assert_array_equal(obs_b[i][agent][OBS_KEY], obs_c[i][agent][OBS_KEY])
                np.testing.assert_array_equal(obs_b[i][agent][MASK_KEY], obs_c[i][agent][MASK_KEY])
        actions = [{a: int(rng.integers(batched.single_action_spaces[a].n)) for a in obs_c[i]} for i in range(3)]
        obs_b, rew_b, term_b, trunc_b, _ = batched.step(actions)
        for i, c in enumerate(copies):
            if ended[i]:  # next-step autoreset: the batch reset this copy, do the same
                obs_c[i], _ = c.reset()
                assert not term_b[i]["__all__"] and all(v == 0.0 for v in rew_b[i].values())
                ended[i] = False
                resets += 1
                continue
            obs_c[i], rew, term, trunc, _ = c.step(actions[i])
            assert rew_b[i] == rew and term_b[i]["__all__"] == term["__all__"] and trunc_b[i]["__all__"] == trunc["__all__"]
            ended[i] = term["__all__"] or trunc["__all__"]
    assert resets >= 3  # every copy ended (max_cycles 30) and was reset by the batch


@pytest.mark.parametrize(("route", "observer_agent"), [("pettingzoo", False), ("vector", False), ("pettingzoo", True)])
def test_one_ppo_iteration_per_route(ray_local, route, observer_agent):
    config = ppo_config("top_observer", {**OPTIONS, "observer_agent": observer_agent}, route=route, num_envs_per_env_runner=2,
                        rollout_fragment_length=32, train_batch_size=128, minibatch_size=64, num_epochs=1)
    policies = [UGV_POLICY, OBSERVER_POLICY] if observer_agent else [UGV_POLICY]
    assert sorted(config.policies) == sorted(policies)
    algo = config.build_algo()
    try:
        if route == "vector":
            assert isinstance(algo.env_runner.env, BatchedMultiAgentEnv)
        before = {p: {k: v.detach().clone() for k, v in algo.get_module(p).state_dict().items()} for p in policies}
        result = algo.train()
        assert result["env_runners"]["num_env_steps_sampled_lifetime"] >= 128
        for p in policies:
            after = algo.get_module(p).state_dict()
            assert any(not torch.equal(before[p][k], after[k]) for k in before[p]), f"PPO did not update policy {p}"
    finally:
        algo.stop()
