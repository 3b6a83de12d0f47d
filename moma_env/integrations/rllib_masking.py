"""An RLlib PPO module (new API stack) that acts only among the actions the motion rules would grant.

With masks, a UGV's observation is ``{"observations": Box, "action_mask": Box(0, 1, (n,))}``
(:class:`moma_env.integrations.rllib_env.MaskedObservations`): the networks see the
observation only; the logits of masked actions get ``log(0)`` (clamped to the float
minimum), so their probability is zero in exploration, inference and the loss alike.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import torch
from ray.rllib.algorithms.ppo.torch.ppo_torch_rl_module import PPOTorchRLModule
from ray.rllib.core.columns import Columns

from moma_env.integrations.rllib_env import MASK_KEY, OBS_KEY

__all__ = ["MaskedPPOTorchRLModule", "MASK_KEY", "OBS_KEY"]


def _split(batch: dict[str, Any]) -> tuple[dict[str, Any], Any]:
    """``batch`` with the plain observations under ``Columns.OBS``, and the mask."""
    obs = batch[Columns.OBS]
    if isinstance(obs, dict):
        inner = dict(batch)
        inner[Columns.OBS] = obs[OBS_KEY]
        return inner, obs[MASK_KEY]
    return batch, batch[MASK_KEY]


def _apply_mask(out: dict[str, Any], mask: Any) -> dict[str, Any]:
    logits = out[Columns.ACTION_DIST_INPUTS]
    out[Columns.ACTION_DIST_INPUTS] = logits + torch.clamp(torch.log(mask.to(logits.dtype)), min=torch.finfo(logits.dtype).min)
    return out


class MaskedPPOTorchRLModule(PPOTorchRLModule):
    """RLlib's default PPO module on the ``observations`` part of a masked observation,
    its action logits masked by the ``action_mask`` part."""

    def __init__(self, *, observation_space: gym.spaces.Dict | None = None, **kwargs: Any):
        if not isinstance(observation_space, gym.spaces.Dict) or set(observation_space.spaces) != {OBS_KEY, MASK_KEY}:
            raise ValueError(f"MaskedPPOTorchRLModule needs a Dict observation space with keys {OBS_KEY!r} and {MASK_KEY!r}, got {observation_space}")
        self._masked_space = observation_space
        super().__init__(observation_space=observation_space[OBS_KEY], **kwargs)

    def setup(self) -> None:
        super().setup()  # the networks are built for the plain observations
        self.observation_space = self._masked_space

    def _forward_inference(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        inner, mask = _split(batch)
        return _apply_mask(super()._forward_inference(inner, **kwargs), mask)

    def _forward_exploration(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        inner, mask = _split(batch)
        return _apply_mask(super()._forward_exploration(inner, **kwargs), mask)

    def _forward_train(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        inner, mask = _split(batch)
        return _apply_mask(super()._forward_train(inner, **kwargs), mask)

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> Any:
        if isinstance(batch[Columns.OBS], dict):
            inner, _ = _split(batch)
            return super().compute_values(inner, embeddings)
        return super().compute_values(batch, embeddings)
