"""A team policy network that shares its weights across robots (a deep-sets actor-critic).

On the centralised route the team's observation is every UGV's own observation side
by side, ``(N * D,)``, and the action is one switching action per UGV. A plain MLP
over the concatenation must learn the same decision once per robot position, and
rules like "the robot farthest from its goal starts next" (the greedy parallel
policy's) need a comparison across robots that it learns slowly and generalises to
new layouts badly. This network is built for that structure:

* every robot's observation goes through one shared encoder, ``e_j = psi(o_j)``;
* the team context is the element-wise max and mean of the ``e_j``;
* robot ``j``'s action logits come from one shared head on ``[e_j, max, mean]``, so
  a permutation of the robots permutes their logits (up to the order in which a
  robot's own observation lists the others);
* the value comes from the context alone (it does not depend on the robots' order).

:class:`TeamActorCriticPolicy` (for PPO) and :class:`MaskableTeamActorCriticPolicy`
(for sb3-contrib's MaskablePPO) are SB3 policies: give ``policy_kwargs={"n_agents": N,
"net_arch": [h, ...]}`` (the encoder's and the head's hidden sizes; the last is the
width of ``e_j``). A model saved with them loads with its SB3 class as any other.
"""

from __future__ import annotations

from typing import Any

import torch
from gymnasium import spaces
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
from stable_baselines3.common.policies import ActorCriticPolicy
from torch import nn

__all__ = ["TeamExtractor", "BlockwiseHead", "TeamActorCriticPolicy", "MaskableTeamActorCriticPolicy"]


def _mlp(sizes: list[int], activation: type[nn.Module]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b), activation()]
    return nn.Sequential(*layers)


class TeamExtractor(nn.Module):
    """Shared per-robot encoder, max and mean pooling, per-robot actor latents and a
    pooled critic latent (the ``mlp_extractor`` of the policies below).

    Args:
        features_dim: the team observation's size ``N * D``.
        n_agents: ``N``.
        hidden: hidden sizes; the encoder is ``D -> hidden``, the actor head
            ``3 * hidden[-1] -> hidden[-1]`` and the critic ``2 * hidden[-1] -> hidden[-1]``.
        activation_fn: the nonlinearity.

    Attributes:
        latent_dim_pi: ``N * hidden[-1]`` (robot ``j``'s latent in block ``j``).
        latent_dim_vf: ``hidden[-1]``.
    """

    def __init__(self, features_dim: int, n_agents: int, hidden: list[int], activation_fn: type[nn.Module] = nn.Tanh):
        super().__init__()
        if n_agents < 1 or features_dim % n_agents:
            raise ValueError(f"a team observation of size {features_dim} does not split into {n_agents} robots")
        if not hidden:
            raise ValueError("the team network needs at least one hidden size")
        self.n_agents = n_agents
        self.agent_dim = features_dim // n_agents
        width = hidden[-1]
        self.encoder = _mlp([self.agent_dim, *hidden], activation_fn)
        self.actor = _mlp([3 * width, width], activation_fn)
        self.critic = _mlp([2 * width, width], activation_fn)
        self.latent_dim_pi = n_agents * width
        self.latent_dim_vf = width

    def _encode(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(B, N, w)`` robot codes and ``(B, 2w)`` team context."""
        codes = self.encoder(features.reshape(features.shape[0], self.n_agents, self.agent_dim))
        context = torch.cat([codes.max(dim=1).values, codes.mean(dim=1)], dim=-1)
        return codes, context

    def _actor(self, codes: torch.Tensor, context: torch.Tensor) -> torch.Tensor:
        shared = context[:, None, :].expand(-1, self.n_agents, -1)
        return self.actor(torch.cat([codes, shared], dim=-1)).reshape(codes.shape[0], -1)

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        codes, context = self._encode(features)
        return self._actor(codes, context), self.critic(context)

    def forward_actor(self, features: torch.Tensor) -> torch.Tensor:
        return self._actor(*self._encode(features))

    def forward_critic(self, features: torch.Tensor) -> torch.Tensor:
        return self.critic(self._encode(features)[1])


class BlockwiseHead(nn.Module):
    """One linear layer applied to every robot's block of the actor latent:
    ``(B, N * w) -> (B, N * n)`` logits, robot ``j``'s in block ``j``."""

    def __init__(self, n_agents: int, width: int, n_actions: int):
        super().__init__()
        self.n_agents, self.width = n_agents, width
        self.linear = nn.Linear(width, n_actions)

    def forward(self, latent: torch.Tensor) -> torch.Tensor:
        blocks = latent.reshape(latent.shape[0], self.n_agents, self.width)
        return self.linear(blocks).reshape(latent.shape[0], -1)


class _TeamPolicy:
    """What both policies add to their SB3 base: the team extractor and the blockwise head."""

    n_agents: int

    def _team_init(self, action_space: spaces.Space, kwargs: dict[str, Any]) -> dict[str, Any]:
        n_agents = kwargs.pop("n_agents", None)
        if not isinstance(action_space, spaces.MultiDiscrete) or n_agents is None or len(action_space.nvec) != n_agents:
            raise ValueError(f"the team network needs policy_kwargs n_agents and one discrete action per robot, got {action_space} and n_agents={n_agents}")
        if len(set(int(n) for n in action_space.nvec)) != 1:
            raise ValueError(f"the team network shares its head: every robot needs the same number of actions, got {action_space.nvec}")
        self.n_agents = int(n_agents)
        return kwargs

    def _build_mlp_extractor(self) -> None:
        hidden = list(self.net_arch) if isinstance(self.net_arch, list) else list(self.net_arch.get("pi", [64]))
        self.mlp_extractor = TeamExtractor(self.features_dim, self.n_agents, hidden, self.activation_fn).to(self.device)

    def _build(self, lr_schedule) -> None:
        super()._build(lr_schedule)
        width = self.mlp_extractor.latent_dim_vf
        self.action_net = BlockwiseHead(self.n_agents, width, int(self.action_space.nvec[0])).to(self.device)
        if self.ortho_init:
            self.action_net.apply(lambda m: self.init_weights(m, gain=0.01))
        self.optimizer = self.optimizer_class(self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data["n_agents"] = self.n_agents
        return data


class TeamActorCriticPolicy(_TeamPolicy, ActorCriticPolicy):
    """PPO's actor-critic with the team network (``policy_kwargs``: ``n_agents``, ``net_arch``)."""

    def __init__(self, observation_space, action_space, lr_schedule, **kwargs):
        kwargs = self._team_init(action_space, kwargs)
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)


class MaskableTeamActorCriticPolicy(_TeamPolicy, MaskableActorCriticPolicy):
    """MaskablePPO's actor-critic with the team network (``policy_kwargs``: ``n_agents``, ``net_arch``)."""

    def __init__(self, observation_space, action_space, lr_schedule, **kwargs):
        kwargs = self._team_init(action_space, kwargs)
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)
