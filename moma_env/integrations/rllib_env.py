"""The env side of the RLlib integration: the PettingZoo parallel env of an ``env_config``,
with the switching mode's action masks in the UGVs' observations (no Ray import).

``env_config`` holds keyword options of :func:`moma_env.env.factory.parallel_env`
(``action_mode``, ``observer_agent``, ``max_cycles``, ``random_scenarios``,
configuration fields), ``masks`` (default True) and, optionally, ``configuration``
(ignored here: the caller names the configuration).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from moma_env.env.agent_names import is_observer_agent
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["MaskedObservations", "masked_parallel_env", "MASK_KEY", "OBS_KEY"]

#: Keys of a masked observation.
MASK_KEY = "action_mask"
OBS_KEY = "observations"


class MaskedObservations:
    """A PettingZoo parallel env whose masked agents observe ``{"observations", "action_mask"}``.

    The masked agents are those :meth:`MomaParallelEnv.action_masks` covers (the UGVs in
    switching mode); the mask is float32 0/1 over the agent's ``Discrete`` actions. Every
    other agent, and everything but the observations, passes through unchanged.

    Args:
        env: a switching-mode :class:`MomaParallelEnv`.
    """

    def __init__(self, env: MomaParallelEnv):
        if env.config.action_mode != "switching":
            raise ValueError(f"action masks need the switching mode, the env is in {env.config.action_mode!r} mode")
        self.env = env
        self.possible_agents = list(env.possible_agents)
        self.metadata = env.metadata
        self.render_mode = env.render_mode
        self._masked = [a for a in self.possible_agents if not is_observer_agent(a)]
        self._spaces = {}
        for agent in self.possible_agents:
            inner = env.observation_space(agent)
            if agent in self._masked:
                n = env.action_space(agent).n
                self._spaces[agent] = spaces.Dict({OBS_KEY: inner, MASK_KEY: spaces.Box(0.0, 1.0, (n,), np.float32)})
            else:
                self._spaces[agent] = inner

    @property
    def agents(self) -> list[str]:
        return self.env.agents

    @property
    def unwrapped(self) -> MomaParallelEnv:
        return self.env

    def observation_space(self, agent: str) -> spaces.Space:
        return self._spaces[agent]

    def action_space(self, agent: str) -> spaces.Space:
        return self.env.action_space(agent)

    def observe(self, observations: Mapping[str, Any], infos: Mapping[str, Mapping[str, Any]] | None = None) -> dict[str, Any]:
        """``observations`` of the wrapped env with the masked agents' current masks added:
        those ``infos`` (the same step's) carry (``EnvConfig.action_masks``), else computed."""
        masks = None if infos is None else _masks_in(infos, [a for a in observations if a in self._masked])
        if masks is None:
            masks = self.env.action_masks()
        return {a: {OBS_KEY: o, MASK_KEY: masks[a].astype(np.float32)} if a in self._masked else o for a, o in observations.items()}

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self.env.reset(seed=seed, options=options)
        return self.observe(observations, infos), infos

    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        observations, rewards, terminations, truncations, infos = self.env.step(actions)
        return self.observe(observations, infos), rewards, terminations, truncations, infos

    def render(self) -> Any:
        return self.env.render()

    def state(self) -> np.ndarray:
        return self.env.state()

    def close(self) -> None:
        self.env.close()


def _masks_in(infos: Mapping[str, Mapping[str, Any]], agents: list[str]) -> dict[str, np.ndarray] | None:
    """Each of ``agents``' ``"action_mask"`` in ``infos``; None if one has none."""
    masks = {}
    for agent in agents:
        mask = infos.get(agent, {}).get("action_mask")  # the info key (EnvConfig.action_masks), not the observation's
        if mask is None:
            return None
        masks[agent] = mask
    return masks


def _split_options(configuration: str, env_config: Mapping[str, Any]) -> tuple[dict[str, Any], bool]:
    options = dict(env_config)
    masks = options.pop("masks", True)
    if not isinstance(masks, bool):
        raise ConfigError("env_config.masks", f"must be a bool, got {masks!r}")
    options.pop("configuration", None)
    return options, masks


def masked_parallel_env(configuration: str, env_config: Mapping[str, Any]) -> MomaParallelEnv | MaskedObservations:
    """The PettingZoo parallel env of ``env_config`` (masks added in switching mode when asked)."""
    options, masks = _split_options(configuration, env_config)
    env = parallel_env(configuration, **options)
    return MaskedObservations(env) if masks and env.config.action_mode == "switching" else env


