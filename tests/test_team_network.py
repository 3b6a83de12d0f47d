"""The team network (agents/team_network.py): weights shared across robots, robots'
logits permuted with the robots, the value independent of their order, saved and
loaded with its SB3 class, and chosen by ``moma-env train --network team``."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from sb3_contrib import MaskablePPO
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback

from agents.learned import LearnedPolicy
from agents.team_network import MaskableTeamActorCriticPolicy, TeamActorCriticPolicy
from moma_env.config import ConfigError
from training.train.config import TrainConfig
from training.train.envs import make_vec_env
from training.train.run import train


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario="top_observer_team4", algo="maskable_ppo", route="centralised", network="team", steps=64, envs=2, n_steps=16,
        batch_size=32, net_arch=(16, 16), max_cycles=40, checkpoint_every=10**6, eval_episodes=1, eval_max_cycles=20,
    )
    return TrainConfig(**(base | changes))


def _model(cls, policy, venv):
    return cls(policy, venv, seed=0, device="cpu", n_steps=16, batch_size=32, policy_kwargs={"n_agents": 4, "net_arch": [16, 16]})


@pytest.mark.parametrize("cls, policy", [(MaskablePPO, MaskableTeamActorCriticPolicy), (PPO, TeamActorCriticPolicy)])
def test_permuting_the_robots_permutes_their_logits_and_keeps_the_value(cls, policy):
    venv = make_vec_env(tiny(), 0)
    model = _model(cls, policy, venv).policy
    obs = torch.as_tensor(np.random.default_rng(0).normal(size=(5, venv.observation_space.shape[0])), dtype=torch.float32)
    perm = [2, 0, 3, 1]
    permuted = obs.reshape(5, 4, -1)[:, perm].reshape(5, -1)
    with torch.no_grad():
        logits = model.action_net(model.mlp_extractor.forward_actor(obs)).reshape(5, 4, 2)
        again = model.action_net(model.mlp_extractor.forward_actor(permuted)).reshape(5, 4, 2)
        value, value_permuted = model.predict_values(obs), model.predict_values(permuted)
    assert torch.allclose(again, logits[:, perm], atol=1e-6)
    assert torch.allclose(value, value_permuted, atol=1e-6)
    assert not torch.allclose(logits[:, 0], logits[:, 1])  # the robots' own observations still tell them apart
    venv.close()


def test_one_head_serves_every_robot():
    venv = make_vec_env(tiny(), 0)
    policy = _model(MaskablePPO, MaskableTeamActorCriticPolicy, venv).policy
    mlp = MaskablePPO("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs={"net_arch": [16, 16]})
    n_mlp = sum(p.numel() for p in mlp.policy.parameters())
    n_team = sum(p.numel() for p in policy.parameters())
    assert policy.action_net.linear.out_features == 2 and n_team < n_mlp
    assert sum(p.numel() for p in policy.parameters() if p.requires_grad) == sum(
        p.numel() for group in policy.optimizer.param_groups for p in group["params"])  # the optimiser holds the shared head
    venv.close()


def test_the_team_network_needs_one_discrete_action_per_robot():
    venv = make_vec_env(tiny(), 0)
    with pytest.raises(ValueError, match="n_agents"):
        MaskablePPO(MaskableTeamActorCriticPolicy, venv, seed=0, device="cpu", policy_kwargs={"n_agents": 3})
    venv.close()


class KeepModel(BaseCallback):
    def _on_step(self) -> bool:
        return True


def test_a_team_network_run_reloads_and_acts_the_same(tmp_path):
    keep = KeepModel()
    train(tiny(), tmp_path / "run", callbacks=[keep])
    loaded = LearnedPolicy.from_dir(tmp_path / "run", "top_observer_team4")
    assert isinstance(loaded.model.policy, MaskableTeamActorCriticPolicy) and loaded.model.policy.n_agents == 4
    obs = np.random.default_rng(1).normal(size=(3, keep.model.observation_space.shape[0])).astype(np.float32)
    masks = np.ones((3, 8), dtype=bool)
    a, _ = keep.model.predict(obs, deterministic=True, action_masks=masks)
    b, _ = loaded.model.predict(obs, deterministic=True, action_masks=masks)
    assert np.array_equal(a, b)


@pytest.mark.parametrize("changes", [{"route": "shared"}, {"algo": "a2c"}, {"algo": "ppo", "action_mode": "velocity"}])
def test_the_team_network_is_refused_where_it_does_not_fit(changes):
    with pytest.raises(ConfigError, match="network"):
        tiny(**changes)
