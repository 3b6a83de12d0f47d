"""The discrete actions of a Stable-Baselines3 policy, the most likely or sampled,
computed as its ``predict`` computes them, without that call's overhead.

``predict`` puts the network in evaluation mode (a walk over every module), converts
and checks the observations, and builds two or three torch ``Categorical``
distributions, each validating its arguments, to take the argmax of their
probabilities: about 300 us a call on this project's 64x64 networks, several times the
network's own arithmetic. :func:`discrete_actions` runs the same torch operations on the
same tensors in the same order, so it returns the same actions bit for bit
(``tests/test_policy_mode.py`` holds it to ``predict``):

* the features extractor on the preprocessed observations, the actor's layers and the
  action head: the logits ``l``;
* SB3's ``Categorical``: ``l - logsumexp(l)``; sb3-contrib's ``MaskableCategorical``
  normalises once more, and with masks it sets the normalised logits of the refused
  actions to -1e8 and normalises that;
* the argmax of the softmax of the last logits (not of the logits themselves: the
  softmax can round two close logits to one probability, and the argmax then takes the
  first); or, sampled, torch's ``multinomial`` draw from those probabilities, one per
  row, from torch's global generator as ``Categorical.sample`` draws (the caller seeds it).

It knows Stable-Baselines3's ``ActorCriticPolicy`` (PPO, A2C) and sb3-contrib's
``MaskableActorCriticPolicy`` (MaskablePPO), exactly those classes, on ``Box``
observations and a ``Discrete`` or ``MultiDiscrete`` action space (each action's logits
apart, as SB3 splits them), in evaluation mode; for any other policy
it returns None and the caller uses ``predict``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["discrete_actions", "knows"]

#: The logit sb3-contrib gives a refused action (``MaskableCategorical.apply_masking``).
REFUSED_LOGIT = -1e8


def _policy_classes() -> tuple[type, type | None]:
    from stable_baselines3.common.policies import ActorCriticPolicy

    try:
        from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
    except ImportError:  # pragma: no cover - sb3-contrib is in the train extra
        MaskableActorCriticPolicy = None
    return ActorCriticPolicy, MaskableActorCriticPolicy


def knows(policy: Any) -> bool:
    """Whether :func:`discrete_actions` computes ``policy``'s actions (else it returns None)."""
    from gymnasium import spaces

    plain, maskable = _policy_classes()
    space = policy.action_space
    return (
        type(policy) in (plain, maskable)
        and (isinstance(space, spaces.Discrete) or (isinstance(space, spaces.MultiDiscrete) and space.nvec.ndim == 1))
        and isinstance(policy.observation_space, spaces.Box)
        and not policy.training
    )


def _action_sizes(space: Any) -> list[int]:
    """The choices of each action of a ``Discrete`` (one) or ``MultiDiscrete`` space."""
    return [int(space.n)] if space.shape == () else [int(n) for n in space.nvec]


def discrete_actions(policy: Any, observations: np.ndarray, masks: np.ndarray | None = None, deterministic: bool = True) -> np.ndarray | None:
    """``policy.predict(observations, deterministic=deterministic, [action_masks=masks])[0]``
    bit for bit (sampled: with torch's global generator in the same state), or None for a
    policy it does not know (:func:`knows`).

    Args:
        policy: a Stable-Baselines3 policy (``model.policy``).
        observations: a batch ``(N, *observation_shape)`` as the policy takes it (the
            normalised observations).
        masks: ``(N, n_actions)`` booleans of the allowed actions (of a
            ``MultiDiscrete`` space, every action's side by side), or None; only for a
            maskable policy.
        deterministic: the most likely actions, else a sample of each row (of a
            ``MultiDiscrete`` space, one action after the other, as sb3-contrib and
            SB3 draw them).

    Returns:
        ``(N,)`` actions of a ``Discrete`` space, ``(N, len(nvec))`` of a
        ``MultiDiscrete`` one, int64; or None.

    Raises:
        ValueError: masks for a policy that does not take them.
    """
    if not knows(policy):
        return None
    import torch as th
    from stable_baselines3.common.preprocessing import preprocess_obs

    _, maskable = _policy_classes()
    masked_policy = maskable is not None and type(policy) is maskable
    if masks is not None and not masked_policy:
        raise ValueError(f"{type(policy).__name__} takes no action masks")
    batch = np.asarray(observations).reshape((-1, *policy.observation_space.shape))
    device = policy.action_net.weight.device  # where the network is (SB3's policy.device walks every module to say)
    with th.no_grad():
        tensor = th.as_tensor(batch, device=device)
        features = policy.pi_features_extractor(preprocess_obs(tensor, policy.observation_space, normalize_images=policy.normalize_images))
        sizes = _action_sizes(policy.action_space)
        logits = policy.action_net(policy.mlp_extractor.forward_actor(features)).view(-1, sum(sizes))
        allowed = [None] * len(sizes)
        if masks is not None:
            allowed = th.split(th.as_tensor(masks).reshape(-1, sum(sizes)), sizes, dim=1)
        chosen = []
        for part, mask in zip(th.split(logits, sizes, dim=1), allowed):
            part = part - part.logsumexp(dim=-1, keepdim=True)
            if masked_policy:
                if mask is not None:
                    mask = th.as_tensor(mask, dtype=th.bool, device=part.device).reshape(part.shape)
                    part = th.where(mask, part, th.tensor(REFUSED_LOGIT, dtype=part.dtype, device=part.device))
                part = part - part.logsumexp(dim=-1, keepdim=True)
            probabilities = th.softmax(part, dim=-1)
            chosen.append(th.argmax(probabilities, dim=1) if deterministic else th.multinomial(probabilities, 1, True).T.reshape(-1))
        actions = chosen[0] if policy.action_space.shape == () else th.stack(chosen, dim=1)
    return actions.cpu().numpy().reshape((-1, *policy.action_space.shape))
