"""A training run's configuration survives its manifest: ``to_dict`` then ``from_dict`` gives the
same configuration for every backend, reward overrides included (what ``--resume`` and
``training.train.publish`` read back), and a bad reward weight name is refused naming it."""

from __future__ import annotations

import json

import pytest

from moma_env.config import ConfigError
from training.train.config import TrainConfig, reward_overrides
from training.train.rllib_config import RllibTrainConfig
from training.train.torchrl_config import TorchRLTrainConfig


@pytest.mark.parametrize("cls", [TrainConfig, RllibTrainConfig, TorchRLTrainConfig])
@pytest.mark.parametrize("rewards", [None, ["time=-0.02", "goal_bonus=3"]])
def test_round_trip_through_json(cls, rewards):
    config = cls(scenario="top_observer_team4", net_arch=(32, 16), rewards=None if rewards is None else reward_overrides(rewards))
    again = cls.from_dict(json.loads(json.dumps(config.to_dict())))
    assert again == config
    if rewards is not None:
        assert again.rewards.time == -0.02 and again.rewards.goal_bonus == 3.0


def test_an_unknown_reward_weight_is_named():
    data = TorchRLTrainConfig(scenario="top_observer").to_dict() | {"rewards": {"speed": 1.0}}
    with pytest.raises(ConfigError, match="train.rewards.speed"):
        TorchRLTrainConfig.from_dict(data)
