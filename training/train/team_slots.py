"""K MOMA env copies seen as slots (one per UGV agent): :class:`VectorSlots`.

The engine of :class:`training.train.shared_vec_env.SharedPolicyVecEnv`: one batched
env (:func:`moma_env.vector.make`, in this process or split over worker processes),
driven with the VecEnv contract of Stable-Baselines3 for its slots (slot ``k * N + j``
is UGV ``j`` of copy ``k``). It deliberately imports neither Stable-Baselines3 nor
torch, so that the worker processes stay light.

* ``step`` returns per slot the observation, the team reward, ``done``
  (terminated or truncated) and the agent's info dict (a new plain ``dict``)
  with ``"TimeLimit.truncated"`` (truncated and not terminated);
* when the episode ends, every slot's info gets ``"terminal_observation"`` (the
  episode's last observation of that slot) and ``"episode"`` (``r``: return,
  ``l``: length in steps, ``t``: simulated duration in s), and the copy resets
  itself at once, so the returned observation is the next episode's first;
* ``reset(seeds)`` reseeds each copy's generator (every later random layout comes
  from it, so a seed fixes the whole run).

In one process or several, the slots are the same bit for bit
(``tests/test_shared_vec_env.py``). :func:`env_command` is what ``get_attr``,
``set_attr`` and ``env_method`` run on a copy's parallel env, where the copy lives.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces

from moma_env.env.factory import parallel_env
from moma_env.env.parallel import MomaParallelEnv
from moma_env.vector import make

__all__ = ["EnvSpec", "VectorSlots", "slot_spaces", "slot_infos", "env_command", "control_step"]


@dataclass(frozen=True)
class EnvSpec:
    """How to build one env copy (picklable: it crosses to worker processes).

    Attributes:
        configuration: configuration name (``"top_observer"``, ...).
        options: keyword options of :func:`moma_env.env.factory.parallel_env`.
    """

    configuration: str
    options: dict[str, Any] = field(default_factory=dict)

    def make(self):
        """A new :class:`moma_env.env.parallel.MomaParallelEnv`."""
        return parallel_env(self.configuration, **self.options)


def slot_spaces(env) -> tuple[list[str], spaces.Space, spaces.Space]:
    """``(agents, observation space, action space)`` shared by every UGV slot of ``env``.

    Raises:
        ValueError: the observer is an agent (it has other spaces) or the UGVs'
            spaces differ (a shared policy needs one shape).
    """
    agents = list(env.possible_agents)
    if env.observer_agents:
        raise ValueError("the shared-policy route needs observer_agent=False (the observer's spaces differ from the UGVs')")
    obs_spaces = [env.observation_space(a) for a in agents]
    act_spaces = [env.action_space(a) for a in agents]
    first_obs, first_act = obs_spaces[0], act_spaces[0]
    for agent, o, a in zip(agents, obs_spaces, act_spaces):
        if o.shape != first_obs.shape or a != first_act:
            raise ValueError(f"agent {agent} has spaces {o}, {a}; a shared policy needs every UGV's to equal {first_obs}, {first_act}")
    low = np.min([o.low for o in obs_spaces], axis=0)
    high = np.max([o.high for o in obs_spaces], axis=0)
    return agents, spaces.Box(low, high, dtype=np.float32), first_act


def slot_infos(
    agents: Sequence[str],
    infos: Mapping[str, Mapping[str, Any]],
    terminated: bool,
    truncated: bool,
    last_observations: np.ndarray | None = None,
    episode: dict[str, float] | None = None,
) -> list[dict]:
    """One copy's step infos as its slots' SB3 infos: per agent a new plain dict of its
    info with ``"TimeLimit.truncated"`` (truncated and not terminated); at an
    episode's end (``episode`` given) also ``"terminal_observation"`` (row ``k`` of
    ``last_observations``, ``(N, D)`` float32) and ``"episode"`` (``r``, ``l``, ``t``)."""
    out = []
    for k, agent in enumerate(agents):
        info = dict(infos[agent])
        info["TimeLimit.truncated"] = bool(truncated and not terminated)
        if episode is not None:
            info["terminal_observation"] = last_observations[k].copy()
            info["episode"] = dict(episode)
        out.append(info)
    return out


def control_step(env: MomaParallelEnv) -> float:
    """The control step (s) of a parallel env's current episode (module level: it runs in
    a batch's worker process)."""
    return env.world.dt


def env_command(env: MomaParallelEnv, command: str, payload: Any) -> Any:
    """The ``getattr``, ``setattr`` and ``call`` commands of the protocol on one parallel env."""
    if command == "getattr":
        return getattr(env, payload)
    if command == "setattr":
        name, value = payload
        setattr(env, name, value)
        return None
    if command == "call":
        method, args, kwargs = payload
        return getattr(env, method)(*args, **kwargs)
    raise ValueError(f"unknown command {command!r}")


class VectorSlots:
    """K copies as ``K * N`` slots, on one batched env (in this process, or split over workers)
    (see the module docstring).

    Args:
        spec: how to build a copy (the observer must not be an agent).
        n_copies: K >= 1.
        workers: None: every copy in this process; ``W``: the copies split over ``W``
            processes, this one included (:func:`moma_env.vector.make`; the same slots
            bit for bit).
        start_method: with ``workers``, the multiprocessing start method (default
            :func:`moma_env.vector.sharded.default_start_method`).

    Attributes:
        vector: the batched env (:func:`moma_env.vector.make`).
    """

    def __init__(self, spec: EnvSpec, n_copies: int, workers: int | None = None, start_method: str | None = None):
        self.vector = make(spec.configuration, n_copies, workers=workers, start_method=start_method, **spec.options)
        self.agents, self.observation_space, self.action_space = slot_spaces(self.vector.spec_env)
        self._discrete = isinstance(self.action_space, spaces.Discrete)
        k = self.vector.num_envs
        self._returns = [0.0] * k
        self._lengths = [0] * k
        self._dt = [0.0] * k  # each copy's control step (s) in its current episode

    @property
    def n_copies(self) -> int:
        return self.vector.num_envs

    def _slots(self, per_agent: Mapping[str, np.ndarray], dtype: type = np.float32) -> np.ndarray:
        """agent -> ``(K, ...)`` arrays as ``(K * N, ...)`` rows of ``dtype``, slot ``k * N + j``."""
        stacked = np.stack([np.asarray(per_agent[a], dtype=dtype) for a in self.agents], axis=1)
        return stacked.reshape(-1, *stacked.shape[2:])

    def _episode_started(self, k: int) -> None:
        self._returns[k], self._lengths[k] = 0.0, 0
        self._dt[k] = float(self.vector.call_at(k, control_step))

    def reset(self, seeds: Sequence[int | None], options: Sequence[dict | None] | None = None) -> tuple[np.ndarray, list[dict]]:
        """Reset copy k with ``seeds[k]`` (None: its generator continues) and ``options[k]``:
        ``(observations (K * N, D) float32, infos: K * N plain dicts)``."""
        observations, infos = self.vector.reset(seed=list(seeds), options=None if options is None else list(options))
        for k in range(self.n_copies):
            self._episode_started(k)
        return self._slots(observations), [dict(info[a]) for info in infos for a in self.agents]

    def _actions(self, actions: np.ndarray) -> dict[str, np.ndarray]:
        k, n = self.n_copies, len(self.agents)
        if self._discrete:
            rows = np.asarray(actions).reshape(k, n)
        else:
            rows = np.asarray(actions, dtype=np.float32).reshape(k, n, *self.action_space.shape)
        return {agent: rows[:, j] for j, agent in enumerate(self.agents)}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        """One step of every copy with one action row per slot (``(K * N,)`` or ``(K * N, *shape)``);
        a copy whose episode ends resets (the returned observations are its next episode's first)."""
        actions = np.asarray(actions)
        if actions.shape[0] != self.n_copies * len(self.agents):
            raise ValueError(f"expected {self.n_copies * len(self.agents)} action rows (one per UGV slot), got {actions.shape[0]}")
        observations, rewards, terminations, truncations, infos = self.vector.step(self._actions(actions))
        team_rewards = np.asarray(rewards[self.agents[0]], dtype=np.float64)
        out_infos: list[dict] = []
        dones = np.zeros(self.n_copies, dtype=bool)
        for k, info in enumerate(infos):
            reward = float(team_rewards[k])
            terminated = any(bool(terminations[a][k]) for a in self.agents)
            truncated = any(bool(truncations[a][k]) for a in self.agents)
            self._returns[k] += reward
            self._lengths[k] += 1
            if terminated or truncated:
                dones[k] = True
                last = self._slots({a: np.asarray(info["final_observation"][a])[None] for a in self.agents})  # (N, D)
                # the copy has reset: its last time (s) is its step count times the control step
                episode = {"r": self._returns[k], "l": self._lengths[k], "t": float(self._lengths[k] * self._dt[k])}
                out_infos += slot_infos(self.agents, info["final_info"], terminated, truncated, last, episode)
                self._episode_started(k)
            else:
                out_infos += slot_infos(self.agents, info, terminated, truncated)
        n = len(self.agents)
        return self._slots(observations), np.repeat(team_rewards.astype(np.float32), n), np.repeat(dones, n), out_infos

    def action_masks(self) -> np.ndarray:
        """``(K * N, n_actions)`` bool, one row per slot (``MomaParallelEnv.action_mask``; switching mode)."""
        return self._slots(self.vector.action_masks(), dtype=bool)

    def command(self, k: int, command: str, payload: Any) -> Any:
        """:func:`env_command` on copy ``k``'s parallel env."""
        return self.vector.call_at(k, env_command, command, payload)

    def close(self) -> None:
        self.vector.close()
