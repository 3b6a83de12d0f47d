"""Uniformly random actions, for reference."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from moma_env.env.parallel import MomaParallelEnv

__all__ = ["RandomPolicy"]


class RandomPolicy:
    """Samples every agent's action space from its own seeded generator.

    Args:
        seed: seed of the generator; ``reset(env, seed)`` with a seed reseeds it.
    """

    def __init__(self, seed: int | None = None):
        self._rng = np.random.default_rng(seed)
        self._spaces: dict[str, spaces.Space] = {}

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Read the action spaces; reseed if ``seed`` is given."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._spaces = {a: env.action_space(a) for a in env.possible_agents}
        for agent, space in self._spaces.items():
            if not isinstance(space, (spaces.Discrete, spaces.Box)):
                raise TypeError(f"RandomPolicy samples Discrete and Box spaces; {agent} has {space}")

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        """A uniform draw per live agent (int for Discrete, float32 array for Box)."""
        actions: dict[str, Any] = {}
        for agent in observations:
            space = self._spaces[agent]
            if isinstance(space, spaces.Discrete):
                actions[agent] = int(space.start + self._rng.integers(space.n))
            else:
                actions[agent] = self._rng.uniform(space.low, space.high).astype(np.float32)
        return actions
