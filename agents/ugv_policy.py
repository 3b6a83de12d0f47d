"""What every trained UGV team policy shares, whichever backend trained it.

The SB3 (:class:`agents.learned.LearnedPolicy`), RLlib (:class:`agents.rllib_policy.RllibPolicy`)
and TorchRL (:class:`agents.torchrl_policy.TorchRLPolicy`) policies act for every UGV
agent in the action mode they were trained in, with the UAV observer flown by its
tracking controller (``observer_agent=False``), and sample (when not deterministic)
from a numpy generator seeded by each episode's seed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from moma_env.env.config import DEFAULT_SWITCH_HORIZON_S
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["TrainedUgvPolicy"]


class TrainedUgvPolicy:
    """Base of the trained UGV team policies: :attr:`env_options` and the checks of ``reset``.

    Subclasses set ``action_mode`` (an attribute or a class attribute), and
    ``switch_horizon_s`` where the policy was trained with another than the env's
    default (``EnvConfig.switch_horizon_s``), and ``team_action`` where it acts through
    another team action than the default (``EnvConfig.team_action``).
    """

    action_mode: str
    switch_horizon_s: float | None = None
    team_action: str = "per_agent"

    @property
    def env_options(self) -> dict[str, Any]:
        """Options of ``parallel_env`` that build an env this policy fits."""
        options: dict[str, Any] = {"action_mode": self.action_mode, "observer_agent": False}
        if self.switch_horizon_s is not None:
            options["switch_horizon_s"] = self.switch_horizon_s
        if self.team_action != "per_agent":
            options["team_action"] = self.team_action
        return options

    @staticmethod
    def _env_masks(env: MomaParallelEnv, agents: Sequence[str], infos: Mapping[str, Mapping[str, Any]]) -> Mapping[str, np.ndarray]:
        """The action masks of ``agents`` in ``env``'s present state: those its infos carry
        (``EnvConfig.action_masks``), else ``env.action_masks()``, the same arrays."""
        if all("action_mask" in infos.get(a, ()) for a in agents):
            return {a: infos[a]["action_mask"] for a in agents}
        return env.action_masks()

    def _begin_episode(self, env: MomaParallelEnv, seed: int | None) -> None:
        """Seed the action sampler with ``seed`` (0 if None); refuse an env of another action
        mode or with an observer agent (ValueError, one line)."""
        self._sampler = np.random.default_rng(0 if seed is None else seed)
        if env.config.action_mode != self.action_mode:
            raise ValueError(f"the policy was trained in {self.action_mode!r} mode; the env is in {env.config.action_mode!r} mode")
        if env.observer_agents:
            raise ValueError("the policy was trained with the observer flown by its tracking controller: build the env with observer_agent=False")
        horizon = DEFAULT_SWITCH_HORIZON_S if self.switch_horizon_s is None else self.switch_horizon_s
        if env.config.switch_horizon_s != horizon:
            raise ValueError(f"the policy was trained with switch_horizon_s={horizon!r}; the env has {env.config.switch_horizon_s!r}")
