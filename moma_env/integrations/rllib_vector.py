"""The batched env as RLlib's multi-agent vector env (the ``"vector"`` route of
:mod:`moma_env.integrations.rllib`).

RLlib's ``MultiAgentEnvRunner`` builds its env with ``make_vec``, which only stacks
copies of a ``MultiAgentEnv`` and steps them one after the other
(``SyncVectorMultiAgentEnv``); it has no hook for an env that steps its copies
together. :class:`MomaVectorEnvRunner` (``PPOConfig().env_runners(env_runner_cls=...)``)
builds :class:`BatchedMultiAgentEnv` instead: ``num_envs_per_env_runner`` copies of
the configuration's parallel env whose step runs the phases of every copy's step
(:meth:`MomaParallelEnv.begin_step`) one phase for every copy before the next, with all
copies' camera requests measured in one call (:func:`moma_env.env.parallel.run_phases`
with :func:`moma_env.vector.env.measure_copies`, as :class:`moma_env.vector.MomaVectorEnv`
does). It follows RLlib's vector contract: per-copy dicts of
agents, ``"__all__"`` in the done flags, and ``next_step`` autoreset (a copy whose
episode ended is reset at the next step, with zero rewards, instead of stepped). Copy
``i`` of a ``reset(seed=s)`` is reset with ``s + i``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from ray.rllib.callbacks.utils import make_callback
from ray.rllib.env.multi_agent_env import MultiAgentEnv
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.env.vector.vector_multi_agent_env import VectorMultiAgentEnv

from moma_env.config import ConfigError, check_count
from moma_env.env.parallel import MomaParallelEnv, run_phases
from moma_env.integrations.rllib_env import MaskedObservations, masked_parallel_env
from moma_env.vector.env import measure_copies

__all__ = ["BatchedMultiAgentEnv", "MomaVectorEnvRunner", "CopyView"]


class CopyView(MultiAgentEnv):
    """What RLlib reads of one copy: its agents and spaces (it is stepped by the batch)."""

    def __init__(self, env: MomaParallelEnv | MaskedObservations):
        super().__init__()
        self.copy = env
        self.possible_agents = list(env.possible_agents)
        self.agents = list(env.possible_agents)
        self.observation_spaces = {a: env.observation_space(a) for a in self.possible_agents}
        self.action_spaces = {a: env.action_space(a) for a in self.possible_agents}
        self.observation_space = spaces.Dict(self.observation_spaces)
        self.action_space = spaces.Dict(self.action_spaces)


def _done(flags: Mapping[str, bool]) -> dict[str, bool]:
    out = {a: bool(v) for a, v in flags.items()}
    out["__all__"] = bool(out) and all(out.values())
    return out


class BatchedMultiAgentEnv(VectorMultiAgentEnv):
    """``num_envs`` copies of ``configuration`` stepped together (see the module).

    Args:
        configuration: a configuration or task name.
        env_config: the options of :func:`moma_env.integrations.rllib_env.masked_parallel_env`.
        num_envs: copies (>= 1).
    """

    def __init__(self, configuration: str, env_config: Mapping[str, Any], num_envs: int):
        super().__init__()
        check_count("num_envs", num_envs, 1)
        self.copies = [masked_parallel_env(configuration, env_config) for _ in range(num_envs)]
        self.envs = [CopyView(c) for c in self.copies]
        self.num_envs = num_envs
        self.metadata = {"autoreset_mode": "next_step"}
        self.render_mode = None
        self.single_observation_spaces = dict(self.envs[0].observation_spaces)
        self.single_action_spaces = dict(self.envs[0].action_spaces)
        self.single_observation_space = spaces.Dict(self.single_observation_spaces)
        self.single_action_space = spaces.Dict(self.single_action_spaces)
        self._needs_reset = np.zeros(num_envs, dtype=bool)

    @staticmethod
    def _raw(copy: MomaParallelEnv | MaskedObservations) -> MomaParallelEnv:
        return copy.env if isinstance(copy, MaskedObservations) else copy

    @staticmethod
    def _observe(copy: MomaParallelEnv | MaskedObservations, observations: Mapping[str, Any], infos: Mapping[str, Any]) -> dict[str, Any]:
        return copy.observe(observations, infos) if isinstance(copy, MaskedObservations) else dict(observations)

    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict | None = None) -> tuple[list[dict], list[dict]]:
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ConfigError("seed", f"needs {self.num_envs} seeds, got {len(seeds)}")
        self._needs_reset[:] = False
        observations, infos = [], []
        for copy, s in zip(self.copies, seeds):
            obs, info = copy.reset(seed=s, options=options)
            observations.append(obs)
            infos.append(info)
        return observations, infos

    def step(self, actions: Sequence[Mapping[str, Any]]) -> tuple[list[dict], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = self.num_envs
        observations: list[dict] = [{} for _ in range(n)]
        rewards: list[dict] = [{} for _ in range(n)]
        terminateds: list[dict] = [{} for _ in range(n)]
        truncateds: list[dict] = [{} for _ in range(n)]
        infos: list[dict] = [{} for _ in range(n)]
        stepping, pending = [], []
        for i, copy in enumerate(self.copies):
            if self._needs_reset[i]:
                observations[i], infos[i] = copy.reset()
                agents = copy.possible_agents
                rewards[i] = dict.fromkeys(agents, 0.0)
                terminateds[i] = _done(dict.fromkeys(agents, False))
                truncateds[i] = _done(dict.fromkeys(agents, False))
            else:
                stepping.append(i)
                pending.append(self._raw(copy).begin_step(actions[i]))
        for i, (obs, rew, term, trunc, info) in zip(stepping, run_phases(pending, measure_copies), strict=True):
            observations[i] = self._observe(self.copies[i], obs, info)
            rewards[i] = dict(rew)
            terminateds[i] = _done(term)
            truncateds[i] = _done(trunc)
            infos[i] = info
        self._needs_reset = np.array([t["__all__"] or u["__all__"] for t, u in zip(terminateds, truncateds)])
        return observations, np.array(rewards, dtype=object), np.array(terminateds, dtype=object), np.array(truncateds, dtype=object), np.array(infos, dtype=object)

    def render(self) -> tuple[Any, ...]:
        return tuple(c.render() for c in self.copies)

    def close_extras(self, **kwargs: Any) -> None:
        for copy in self.copies:
            copy.close()


class MomaVectorEnvRunner(MultiAgentEnvRunner):
    """RLlib's multi-agent env runner with :class:`BatchedMultiAgentEnv` as its env; the
    configuration is ``env_config["configuration"]`` (set by :func:`moma_env.integrations.rllib.ppo_config`)."""

    def make_env(self) -> None:
        if self.env is not None:
            self.env.close()
        env_config = dict(self.config.env_config)
        configuration = env_config.get("configuration")
        if configuration is None:
            raise ConfigError("env_config.configuration", "the vector route needs the configuration's name in env_config")
        self.env = BatchedMultiAgentEnv(configuration, env_config, self.config.num_envs_per_env_runner)
        self.num_envs = self.env.num_envs
        self._needs_initial_reset = True
        make_callback(
            "on_environment_created",
            callbacks_objects=self._callbacks,
            callbacks_functions=self.config.callbacks_on_environment_created,
            kwargs=dict(env_runner=self, metrics_logger=self.metrics, env=self.env.unwrapped, env_context=self.config.env_config),
        )
