"""What every trained UGV team policy shares, whichever backend trained it.

The SB3 (:class:`agents.learned.LearnedPolicy`), RLlib (:class:`agents.rllib_policy.RllibPolicy`)
and TorchRL (:class:`agents.torchrl_policy.TorchRLPolicy`) policies act for every UGV
agent in the action mode they were trained in, with the UAV observer flown by its
tracking controller (``observer_agent=False``), and sample (when not deterministic)
from a numpy generator seeded by each episode's seed.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from moma_env.env.parallel import MomaParallelEnv

__all__ = ["TrainedUgvPolicy"]


class TrainedUgvPolicy:
    """Base of the trained UGV team policies: :attr:`env_options` and the checks of ``reset``.

    Subclasses set ``action_mode`` (an attribute or a class attribute).
    """

    action_mode: str

    @property
    def env_options(self) -> dict[str, Any]:
        """Options of ``parallel_env`` that build an env this policy fits."""
        return {"action_mode": self.action_mode, "observer_agent": False}

    def _begin_episode(self, env: MomaParallelEnv, seed: int | None) -> None:
        """Seed the action sampler with ``seed`` (0 if None); refuse an env of another action
        mode or with an observer agent (ValueError, one line)."""
        self._sampler = np.random.default_rng(0 if seed is None else seed)
        if env.config.action_mode != self.action_mode:
            raise ValueError(f"the policy was trained in {self.action_mode!r} mode; the env is in {env.config.action_mode!r} mode")
        if env.observer_agents:
            raise ValueError("the policy was trained with the observer flown by its tracking controller: build the env with observer_agent=False")
