"""A batched multi-agent env: ``num_envs`` copies of one MOMA configuration stepped together.

:func:`moma_env.vector.make` returns a :class:`MomaVectorEnv` (or, with ``workers``, a
:class:`~moma_env.vector.sharded.ShardedVectorEnv` of them in worker processes). Every copy is the PettingZoo env's
own step (:class:`~moma_env.env.parallel.MomaParallelEnv` over its
:class:`~moma_env.sim.Simulation`): one implementation of the camera, the
estimator, the rules, the rewards and the observations, whatever ``num_envs`` is.
A batch step begins every copy's step (actions, rules, physics), measures the
camera requests of all copies together, then finishes every copy's step on its
detections (localiser, rewards, observations).

Arrays, per agent of ``possible_agents`` (every copy has the same agents):

* ``reset(seed=None, options=None) -> (observations, infos)`` and
  ``step(actions) -> (observations, rewards, terminations, truncations, infos)``;
* ``observations[agent]``: shape ``(num_envs, *obs_shape)`` (a dict of such arrays
  for a ``Dict`` observation space); ``actions[agent]``: shape
  ``(num_envs, *act_shape)`` (``(num_envs,)`` integers for a ``Discrete`` space);
  ``rewards[agent]``, ``terminations[agent]``, ``truncations[agent]``: ``(num_envs,)``;
* ``infos``: a tuple of ``num_envs`` dicts, copy ``i``'s PettingZoo infos (agent ->
  info dict).

Seeding (Gymnasium's vector rule): ``reset(seed=s)`` seeds copy ``i`` with ``s + i``,
so copy ``i`` behaves bit for bit like ``parallel_env(...)`` reset with ``seed=s + i``
and then driven with the same actions; ``seed`` may also be a sequence of
``num_envs`` seeds. ``reset()`` without a seed continues every copy's generator.

Autoreset (Gymnasium's ``SAME_STEP`` mode): a copy whose episode ends in a step is
reset in that step; the step returns its first observation of the new episode, its
flags and reward of the step that ended, and in ``infos[i]`` the keys
``"final_observation"`` (agent -> the last observation), ``"final_info"`` (the
last infos), ``"final_state"`` (the last ``state()``), ``"final_time"`` (the
episode's simulated duration, s) and, in switching mode, ``"final_action_masks"``.
:meth:`reset_at` resets one copy alone.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from moma_env.env.factory import parallel_env
from moma_env.env.parallel import MomaParallelEnv, checked_seed
from moma_env.vector.collection import deferred_collection
from moma_env.vector.batch_checks import checked_actions, checked_count, checked_index, copy_options, copy_seeds, random_actions
from moma_env.camera import MeasureRequest, measure_batch

__all__ = ["FINAL_KEYS", "MomaVectorEnv"]

#: The keys the autoreset adds to a copy's infos (see the module docstring).
FINAL_KEYS = ("final_observation", "final_info", "final_state", "final_time", "final_action_masks")


def _stack(values: Sequence[Any]) -> Any:
    if isinstance(values[0], dict):
        return {key: np.stack([v[key] for v in values]) for key in values[0]}
    return np.stack(values)


class MomaVectorEnv:
    """``num_envs`` copies of one configuration; see the module docstring.

    Args:
        name: configuration name (``"top_observer"``, ...).
        num_envs: number of copies (>= 1).
        options: options of :func:`moma_env.env.factory.parallel_env`.
    """

    def __init__(self, name: str, num_envs: int, **options: Any):
        self.num_envs = checked_count("num_envs", num_envs)
        self.envs: tuple[MomaParallelEnv, ...] = tuple(parallel_env(name, **options) for _ in range(self.num_envs))
        first = self.envs[0]
        self.possible_agents = list(first.possible_agents)
        self.agents = list(self.possible_agents)
        self.metadata = dict(first.metadata)
        self.render_mode = first.render_mode
        #: One copy's ``state()`` space (float32 ``(state_dim,)``).
        self.state_space: spaces.Box = first.state_space
        self._masks = first.config.action_mode == "switching"
        self._started = False
        #: The batch measurement of a step: every copy's camera requests -> that copy's
        #: detections (:func:`measure_copies`); an instance attribute, so a benchmark can
        #: time it by wrapping it.
        self.measure: Callable[[Sequence[Sequence[MeasureRequest]]], list[list[Any]]] = measure_copies

    # ------------------------------------------------------------------ spaces
    @property
    def spec_env(self) -> MomaParallelEnv:
        """A parallel env of the configuration, for its spaces and layout (copy 0: read it, do not step it)."""
        return self.envs[0]

    def single_observation_space(self, agent: str) -> spaces.Space:
        """One copy's observation space of ``agent``."""
        return self.envs[0].observation_space(agent)

    def single_action_space(self, agent: str) -> spaces.Space:
        """One copy's action space of ``agent``."""
        return self.envs[0].action_space(agent)

    # ------------------------------------------------------------------ reset
    def reset(
        self, seed: int | Sequence[int] | None = None, options: dict | Sequence[dict | None] | None = None
    ) -> tuple[dict[str, Any], tuple[dict, ...]]:
        """Reset every copy (see the module docstring for the seeds); ``options``: one dict for
        every copy or a sequence of ``num_envs``, one per copy."""
        seeds, per_copy = copy_seeds(seed, self.num_envs), copy_options(options, self.num_envs)
        results = [env.reset(seed=s, options=o) for env, s, o in zip(self.envs, seeds, per_copy)]
        self._started = True
        observations = {a: _stack([obs[a] for obs, _ in results]) for a in self.possible_agents}
        return observations, tuple(infos for _, infos in results)

    def reset_at(self, index: int, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, Any], dict]:
        """Reset copy ``index`` alone; its observations (agent -> one copy's observation) and infos."""
        return self.envs[checked_index(index, self.num_envs)].reset(seed=checked_seed(seed), options=options)

    # ------------------------------------------------------------------ step
    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, tuple[dict, ...]]:
        """Step every copy with its row of ``actions``; a copy whose episode ends resets (``SAME_STEP``)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        return self.step_checked(checked_actions(actions, self.possible_agents, self.single_action_space, self.num_envs))

    def step_checked(self, checked: Mapping[str, np.ndarray]) -> tuple[dict, dict, dict, dict, tuple[dict, ...]]:
        """:meth:`step` with actions that :func:`~moma_env.vector.batch_checks.checked_actions`
        returned for this batch (what a sharded batch's caller checked once for all shards)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        with deferred_collection():
            return self._step(checked)

    def _step(self, checked: Mapping[str, np.ndarray]) -> tuple[dict, dict, dict, dict, tuple[dict, ...]]:
        agents = self.possible_agents
        n = self.num_envs
        obs_rows: list[dict] = []
        rewards = {a: np.zeros(n, dtype=np.float64) for a in agents}
        terminations = {a: np.zeros(n, dtype=bool) for a in agents}
        truncations = {a: np.zeros(n, dtype=bool) for a in agents}
        infos: list[dict] = []
        pending = [env.begin_step({a: checked[a][i] for a in agents}) for i, env in enumerate(self.envs)]
        detections = self.measure([p.camera_requests for p in pending])
        for i, env in enumerate(self.envs):
            obs, rew, term, trunc, info = pending[i].finish(detections[i])
            for a in agents:
                rewards[a][i] = rew[a]
                terminations[a][i] = term[a]
                truncations[a][i] = trunc[a]
            if not env.agents:
                final = {"final_observation": obs, "final_info": info, "final_state": env.state(), "final_time": env.frame.time}
                if self._masks:
                    final["final_action_masks"] = env.action_masks()
                obs, info = env.reset()
                info = dict(info) | final
            obs_rows.append(obs)
            infos.append(info)
        observations = {a: _stack([row[a] for row in obs_rows]) for a in agents}
        return observations, rewards, terminations, truncations, tuple(infos)

    def sample_actions(self, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Uniform random actions of every agent for every copy, drawn from ``rng``
        (:func:`~moma_env.vector.batch_checks.random_actions`)."""
        return random_actions(self.possible_agents, self.single_action_space, self.num_envs, rng)

    # ------------------------------------------------------------------ the rest
    def action_masks(self) -> dict[str, np.ndarray]:
        """Switching mode: agent -> ``(num_envs, n)`` int8, each copy's ``action_masks()``."""
        masks = [env.action_masks() for env in self.envs]
        return {a: np.stack([m[a] for m in masks]) for a in masks[0]}

    def state(self) -> np.ndarray:
        """``(num_envs, state_dim)`` float32: each copy's ``state()``."""
        return np.stack([env.state() for env in self.envs])

    def render(self, index: int = 0) -> np.ndarray | None:
        """Copy ``index``'s ``render()``."""
        return self.envs[checked_index(index, self.num_envs)].render()

    def call_at(self, index: int, function: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """``function(env, *args, **kwargs)`` on copy ``index``'s parallel env ``env``, and its
        result (what :class:`~moma_env.vector.sharded.ShardedVectorEnv` runs in the copy's
        worker; there ``function`` must be picklable: a module-level function)."""
        return function(self.envs[checked_index(index, self.num_envs)], *args, **kwargs)

    def close(self) -> None:
        for env in self.envs:
            env.close()


def measure_copies(requests: Sequence[Sequence[MeasureRequest]]) -> list[list[Any]]:
    """Copy ``i``'s detections (one list) from its camera requests ``requests[i]``: the
    requests of all copies measured in one :func:`~moma_env.camera.measure_batch` call."""
    frames = iter(measure_batch([r for copy in requests for r in copy]))
    return [[d for _ in copy for d in next(frames)] for copy in requests]
