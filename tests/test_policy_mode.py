"""agents.policy_mode: the discrete actions of an SB3 policy, most likely or sampled, bit for
bit those of its ``predict``, and None for the policies it does not know."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gymnasium import spaces
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
from stable_baselines3.common.policies import ActorCriticPolicy

from agents.policy_mode import discrete_actions, knows
from training.evaluation.policies import load_policy

OBSERVATIONS = spaces.Box(-np.inf, np.inf, shape=(12,), dtype=np.float32)


def _policy(cls, n_actions: int = 5, seed: int = 0, action_space=None):
    torch.manual_seed(seed)
    policy = cls(OBSERVATIONS, action_space or spaces.Discrete(n_actions), lambda _: 3e-4, net_arch=[16, 16])
    policy.set_training_mode(False)
    return policy


def _batches(rng: np.random.Generator, n_features: int, n_actions: int):
    """Observations at several scales (large ones saturate the network, where the
    softmax rounds close logits together) with random masks, some refusing every action."""
    for scale in (0.01, 1.0, 30.0, 1e4):
        for _ in range(40):
            observations = (rng.standard_normal((6, n_features)) * scale).astype(np.float32)
            masks = rng.random((6, n_actions)) < 0.5
            masks[0] = False  # every action refused
            masks[1] = False
            masks[1, rng.integers(n_actions)] = True  # one allowed
            yield observations, masks


def _predict(policy, observations, masks=None):
    extra = {} if masks is None else {"action_masks": masks}
    return policy.predict(observations, deterministic=True, **extra)[0]


@pytest.mark.parametrize("seed", [0, 1])
def test_the_plain_policy_acts_as_predict(seed):
    policy = _policy(ActorCriticPolicy, seed=seed)
    for observations, _ in _batches(np.random.default_rng(seed), 12, 5):
        fast = discrete_actions(policy, observations)
        reference = _predict(policy, observations)
        assert fast.dtype == reference.dtype and np.array_equal(fast, reference)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_maskable_policy_acts_as_predict_with_and_without_masks(seed):
    policy = _policy(MaskableActorCriticPolicy, seed=seed)
    for observations, masks in _batches(np.random.default_rng(seed), 12, 5):
        for given in (masks, None):
            fast = discrete_actions(policy, observations, given)
            reference = _predict(policy, observations, given)
            assert fast.dtype == reference.dtype and np.array_equal(fast, reference)


def test_a_published_policy_acts_as_predict():
    policy = load_policy("top_observer_team4_mppo", "top_observer_team4").model.policy
    policy.set_training_mode(False)
    n_features, n_actions = policy.observation_space.shape[0], int(policy.action_space.n)
    for observations, masks in _batches(np.random.default_rng(7), n_features, n_actions):
        assert np.array_equal(discrete_actions(policy, observations, masks), _predict(policy, observations, masks))


def test_it_leaves_to_predict_what_it_does_not_know():
    training = _policy(ActorCriticPolicy)
    training.set_training_mode(True)
    assert not knows(training) and discrete_actions(training, np.zeros((1, 12), np.float32)) is None

    class Custom(ActorCriticPolicy):
        pass

    assert not knows(_policy(Custom))
    continuous = _policy(ActorCriticPolicy, action_space=spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32))
    assert not knows(continuous) and discrete_actions(continuous, np.zeros((1, 12), np.float32)) is None
    with pytest.raises(ValueError, match="takes no action masks"):
        discrete_actions(_policy(ActorCriticPolicy), np.zeros((1, 12), np.float32), np.ones((1, 5), bool))


@pytest.mark.parametrize("cls", [ActorCriticPolicy, MaskableActorCriticPolicy])
def test_near_ties_are_broken_as_predict_breaks_them(cls):
    """Logits closer than the softmax's rounding: ``predict`` takes the first of two equal
    probabilities, not the larger logit; so must :func:`discrete_actions`."""
    policy = _policy(cls, n_actions=3)
    observations = np.zeros((1, 12), dtype=np.float32)
    differs = 0
    for base in (0.0, 3.0, 17.0):
        for gap in np.logspace(-9, -5, 120, dtype=np.float32):
            bias = np.array([base, base + gap, base - 1.0], dtype=np.float32)
            with torch.no_grad():
                policy.action_net.weight.zero_()
                policy.action_net.bias.copy_(torch.as_tensor(bias))
            for masks in ([None] if cls is ActorCriticPolicy else [None, np.array([[True, True, False]]), np.array([[True, True, True]])]):
                reference = _predict(policy, observations, masks)
                assert np.array_equal(discrete_actions(policy, observations, masks), reference), (base, gap, masks)
                differs += int(reference[0] != np.argmax(bias))
    assert differs > 0  # the rounding did pick the smaller logit somewhere: the case is exercised


@pytest.mark.parametrize("cls", [ActorCriticPolicy, MaskableActorCriticPolicy])
def test_sampled_actions_are_predicts_draws_from_the_same_generator_state(cls):
    policy = _policy(cls, seed=3)
    for k, (observations, masks) in enumerate(_batches(np.random.default_rng(5), 12, 5)):
        given = masks if cls is MaskableActorCriticPolicy and k % 2 else None
        torch.manual_seed(k)
        fast = discrete_actions(policy, observations, given, deterministic=False)
        after_fast = torch.random.get_rng_state()
        torch.manual_seed(k)
        extra = {} if given is None else {"action_masks": given}
        reference = policy.predict(observations, deterministic=False, **extra)[0]
        assert fast.dtype == reference.dtype and np.array_equal(fast, reference)
        assert torch.equal(after_fast, torch.random.get_rng_state())  # the same draws consumed


@pytest.mark.parametrize("cls", [ActorCriticPolicy, MaskableActorCriticPolicy])
def test_multi_discrete_actions_are_predicts_most_likely_and_sampled(cls):
    """A centralised team's action: one choice per robot, each from its own logits."""
    space = spaces.MultiDiscrete([3, 4, 3, 2])
    policy = _policy(cls, seed=4, action_space=space)
    for k, (observations, masks) in enumerate(_batches(np.random.default_rng(9), 12, 12)):
        given = masks if cls is MaskableActorCriticPolicy and k % 2 else None
        for deterministic in (True, False):
            torch.manual_seed(k)
            fast = discrete_actions(policy, observations, given, deterministic=deterministic)
            torch.manual_seed(k)
            extra = {} if given is None else {"action_masks": given}
            reference = policy.predict(observations, deterministic=deterministic, **extra)[0]
            assert fast.shape == (6, 4) and fast.dtype == reference.dtype and np.array_equal(fast, reference)


def test_a_published_team_policy_acts_as_predict():
    policy = load_policy("top_observer_team4_bc", "top_observer_team4").model.policy
    policy.set_training_mode(False)
    assert knows(policy)
    n_features, n_actions = policy.observation_space.shape[0], int(sum(policy.action_space.nvec))
    for k, (observations, masks) in enumerate(_batches(np.random.default_rng(11), n_features, n_actions)):
        for deterministic in (True, False):
            torch.manual_seed(k)
            fast = discrete_actions(policy, observations, masks, deterministic=deterministic)
            torch.manual_seed(k)
            assert np.array_equal(fast, policy.predict(observations, deterministic=deterministic, action_masks=masks)[0])
