"""The minibatch size of a training run: ``--batch-size``, or by default a quarter of PPO's rollout."""

from __future__ import annotations

import argparse

import pytest

pytest.importorskip("stable_baselines3")

from moma_env.config import ConfigError
from training.cli import build_parser
from training.train.command import config_from_args, train_command
from training.train.config import DEFAULT_BATCH_SIZE, PPO_MINIBATCHES, TrainConfig
from training.train.envs import make_vec_env
from training.train.models import build_model
from training.train.rllib_command import rllib_config_from_args
from training.train.torchrl_command import torchrl_config_from_args


def parse(*argv: str) -> argparse.Namespace:
    return build_parser().parse_args(["train", "--scenario", "top_observer", "--out", "unused", *argv])


def model_batch_size(config: TrainConfig) -> tuple[int, int]:
    """``(the model's minibatch size, its venv's slots)`` of ``config``."""
    venv = make_vec_env(config, config.seed)
    try:
        return build_model(config, venv).batch_size, venv.num_envs
    finally:
        venv.close()


def test_ppo_splits_each_rollout_into_a_fixed_number_of_minibatches_by_default():
    for envs, n_steps in ((1, 64), (3, 32)):
        config = TrainConfig(scenario="top_observer", algo="ppo", envs=envs, n_steps=n_steps)
        size, slots = model_batch_size(config)
        assert slots == 2 * envs  # two UGVs a copy on the shared route
        assert size == n_steps * slots // PPO_MINIBATCHES == config.minibatch_size(n_steps * slots)


def test_a_given_batch_size_is_kept_up_to_the_rollout():
    assert model_batch_size(TrainConfig(scenario="top_observer", algo="ppo", envs=1, n_steps=64, batch_size=32))[0] == 32
    assert model_batch_size(TrainConfig(scenario="top_observer", algo="ppo", envs=1, n_steps=64, batch_size=4096))[0] == 128


def test_cloning_and_off_policy_algorithms_keep_the_fixed_default():
    config = TrainConfig(scenario="top_observer", algo="dqn", steps=1000)
    assert config.batch_size is None and config.minibatch_size() == DEFAULT_BATCH_SIZE == 256
    assert model_batch_size(config)[0] == DEFAULT_BATCH_SIZE
    assert TrainConfig(scenario="top_observer", batch_size=64).minibatch_size(8192) == 64


def test_the_command_line_default_is_none_and_other_backends_take_their_own():
    assert config_from_args(parse()).batch_size is None
    assert config_from_args(parse("--batch-size", "512")).batch_size == 512
    rllib = rllib_config_from_args(parse("--backend", "rllib"))
    torchrl = torchrl_config_from_args(parse("--backend", "torchrl", "--algo", "ppo", "--num-envs", "4"))
    assert rllib.minibatch_size == torchrl.minibatch_size == DEFAULT_BATCH_SIZE
    with pytest.raises(SystemExit):
        parse("--batch-size", "1")
    with pytest.raises(ConfigError, match="batch_size"):
        TrainConfig(scenario="top_observer", batch_size=0)


def test_a_run_made_with_the_old_default_spells_it_out_in_its_command():
    argv, omitted = train_command(TrainConfig(scenario="top_observer", batch_size=256), "out")
    assert omitted == [] and argv[argv.index("--batch-size") + 1] == "256"
    assert "--batch-size" not in train_command(TrainConfig(scenario="top_observer"), "out")[0]
