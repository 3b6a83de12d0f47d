"""A centralised Gymnasium view of a MOMA team: the whole team as one agent.

Observation: the agents' observations concatenated in ``possible_agents`` order
(a ``Box``). Action: the agents' actions side by side: a ``MultiDiscrete`` when
every agent is discrete (``switching`` mode), else a ``Box`` in [-1, 1] where a
discrete agent's slot is decoded by rounding into its range. Reward: the team
reward. The episode ends when the team's episode ends. ``info`` holds each
agent's info under its name.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from moma_env.env.parallel import MomaParallelEnv

__all__ = ["CentralisedTeamEnv"]


class CentralisedTeamEnv(gym.Env):
    """Wrap a :class:`MomaParallelEnv` as a single-agent ``gymnasium.Env``."""

    def __init__(self, parallel_env: MomaParallelEnv):
        if not isinstance(parallel_env, MomaParallelEnv):
            raise TypeError(f"expected a MomaParallelEnv, got {type(parallel_env).__name__}")
        self.parallel_env = parallel_env
        self.metadata = {"render_modes": parallel_env.metadata["render_modes"], "render_fps": parallel_env.metadata["render_fps"]}
        self.render_mode = parallel_env.render_mode
        self._agents = list(parallel_env.possible_agents)
        obs_spaces = [parallel_env.observation_space(a) for a in self._agents]
        if not all(isinstance(s, spaces.Box) for s in obs_spaces):
            raise ValueError("the centralised env concatenates vector observations; it cannot take observer_image (a Dict)")
        self.observation_space = spaces.Box(
            low=np.concatenate([s.low for s in obs_spaces]),
            high=np.concatenate([s.high for s in obs_spaces]),
            dtype=np.float32,
        )
        act_spaces = [parallel_env.action_space(a) for a in self._agents]
        self._act_spaces = act_spaces
        if all(isinstance(s, spaces.Discrete) for s in act_spaces):
            self.action_space = spaces.MultiDiscrete([int(s.n) for s in act_spaces])
            self._discrete = True
        else:
            size = sum(1 if isinstance(s, spaces.Discrete) else int(np.prod(s.shape)) for s in act_spaces)
            self.action_space = spaces.Box(-1.0, 1.0, shape=(size,), dtype=np.float32)
            self._discrete = False

    def team_observation(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The agents' observations concatenated in ``possible_agents`` order (float32)."""
        return np.concatenate([obs[a] for a in self._agents]).astype(np.float32, copy=False)

    def agent_actions(self, action: Any) -> dict[str, Any]:
        """The team action split into the agents' actions (what ``step`` sends to the parallel env)."""
        a = np.asarray(action)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        if self._discrete:
            return {agent: int(a[i]) for i, agent in enumerate(self._agents)}
        out: dict[str, Any] = {}
        k = 0
        for agent, space in zip(self._agents, self._act_spaces):
            if isinstance(space, spaces.Discrete):
                value = float(np.clip(a[k], -1.0, 1.0))
                out[agent] = int(min(space.n - 1, np.floor((value + 1.0) / 2.0 * space.n)))
                k += 1
            else:
                n = int(np.prod(space.shape))
                out[agent] = a[k : k + n].reshape(space.shape)
                k += n
        return out

    def action_masks(self) -> np.ndarray:
        """Flat boolean mask over the ``MultiDiscrete`` team action (switching mode): the
        agents' :meth:`MomaParallelEnv.action_mask` side by side in ``possible_agents``
        order, the one-dimensional form sb3-contrib's ``MaskablePPO`` asks an env for.
        Each agent's part assumes the other agents keep their state."""
        if not self._discrete:
            raise ValueError("action masks need the MultiDiscrete team action of action_mode='switching'")
        masks = self.parallel_env.action_masks()
        return np.concatenate([masks[a] for a in self._agents]).astype(bool)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        obs, infos = self.parallel_env.reset(seed=seed, options=options)
        return self.team_observation(obs), dict(infos)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, rewards, terms, truncs, infos = self.parallel_env.step(self.agent_actions(action))
        reward = float(next(iter(rewards.values())))
        return self.team_observation(obs), reward, any(terms.values()), any(truncs.values()), dict(infos)

    def render(self) -> np.ndarray | None:
        return self.parallel_env.render()

    def close(self) -> None:
        self.parallel_env.close()
