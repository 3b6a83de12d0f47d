"""MOMA env copies seen as slots (one per UGV agent), in this process or in a worker.

These are the engines of :class:`training.train.shared_vec_env.SharedPolicyVecEnv`
and deliberately import neither Stable-Baselines3 nor torch, so that worker
processes stay light. :class:`VectorSlots` runs K copies in this process on one
:class:`moma_env.vector.MomaVectorEnv` (the default); :class:`TeamSlots` runs one
copy, in a worker process. Both implement the VecEnv contract of
Stable-Baselines3 for their slots (slot ``k * N + j`` is UGV ``j`` of copy ``k``):

* ``step`` returns per slot the observation, the team reward, ``done``
  (terminated or truncated) and the agent's info dict (a new plain ``dict``)
  with ``"TimeLimit.truncated"`` (truncated and not terminated);
* when the episode ends, every slot's info gets ``"terminal_observation"`` (the
  episode's last observation of that slot) and ``"episode"`` (``r``: return,
  ``l``: length in steps, ``t``: simulated duration in s), and the copy resets
  itself at once, so the returned observation is the next episode's first;
* ``reset(seed)`` reseeds the env's generator (every later random layout comes
  from it, so a seed fixes the whole run).

The two engines give the same slots bit for bit (``tests/test_shared_vec_env.py``).

Worker protocol (:func:`worker`, over a ``multiprocessing`` pipe): the parent
sends ``(command, payload)`` tuples and receives ``("ok", result)`` or
``("error", traceback text)``:

=============  ==========================  ===========================================
command        payload                     result
=============  ==========================  ===========================================
``reset``      ``(seed, options)``         ``(observations, infos)``
``step``       actions, one row per slot   ``(observations, rewards, dones, infos)``
``getattr``    attribute name              that attribute of the parallel env
``setattr``    ``(name, value)``           None
``call``       ``(method, args, kwargs)``  the parallel env method's return value
``masks``      None                        :meth:`TeamSlots.action_masks`
``close``      None                        None; then the worker exits
=============  ==========================  ===========================================
"""

from __future__ import annotations

import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces

from moma_env.env.factory import parallel_env
from moma_env.env.parallel import MomaParallelEnv
from moma_env.vector import make

__all__ = ["EnvSpec", "TeamSlots", "VectorSlots", "worker", "slot_spaces", "slot_infos", "env_command"]


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


class TeamSlots:
    """One env copy as ``len(agents)`` slots with auto-reset (see the module docstring)."""

    def __init__(self, spec: EnvSpec):
        self.env = spec.make()
        self.agents, self.observation_space, self.action_space = slot_spaces(self.env)
        self._discrete = isinstance(self.action_space, spaces.Discrete)
        self._return = 0.0
        self._length = 0

    @property
    def n_slots(self) -> int:
        return len(self.agents)

    def _stack(self, observations: dict[str, np.ndarray]) -> np.ndarray:
        return np.stack([np.asarray(observations[a], dtype=np.float32) for a in self.agents])

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, list[dict]]:
        """Reset the copy: ``(observations (N, D) float32, infos: N plain dicts)``."""
        observations, infos = self.env.reset(seed=seed, options=options or None)
        self._return, self._length = 0.0, 0
        return self._stack(observations), [dict(infos[a]) for a in self.agents]

    def _action(self, row: Any) -> Any:
        if self._discrete:
            return int(np.asarray(row).reshape(()))
        return np.asarray(row, dtype=np.float32).reshape(self.action_space.shape)

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        """One env step with one action row per slot (auto-reset at the episode's end)."""
        actions = np.asarray(actions)
        if actions.shape[0] != self.n_slots:
            raise ValueError(f"expected {self.n_slots} action rows (one per UGV slot), got {actions.shape[0]}")
        observations, rewards, terminations, truncations, infos = self.env.step(
            {agent: self._action(actions[k]) for k, agent in enumerate(self.agents)}
        )
        obs = self._stack(observations)
        reward = float(rewards[self.agents[0]])
        terminated = any(terminations.values())
        truncated = any(truncations.values())
        done = terminated or truncated
        self._return += reward
        self._length += 1
        episode = {"r": self._return, "l": self._length, "t": float(self.env.frame.time)} if done else None
        out_infos = slot_infos(self.agents, infos, terminated, truncated, obs, episode)
        if done:
            obs, _ = self.reset()
        rewards_out = np.full(self.n_slots, reward, dtype=np.float32)
        dones = np.full(self.n_slots, done, dtype=bool)
        return obs, rewards_out, dones, out_infos

    def action_masks(self) -> np.ndarray:
        """(N, n_actions) bool, one row per slot: the actions the motion rules would
        grant its robot at the next step (``MomaParallelEnv.action_mask``; switching mode)."""
        masks = self.env.action_masks()
        return np.stack([masks[agent] for agent in self.agents]).astype(bool)

    def handle(self, command: str, payload: Any) -> Any:
        """Execute one protocol command (see the module docstring)."""
        if command == "step":
            return self.step(payload)
        if command == "reset":
            seed, options = payload
            return self.reset(seed, options)
        if command == "masks":
            return self.action_masks()
        if command == "close":
            self.env.close()
            return None
        return env_command(self.env, command, payload)


class VectorSlots:
    """K copies as ``K * N`` slots, on one batched env (in this process, or split over workers)
    (see the module docstring; the same slots as K :class:`TeamSlots`).

    Args:
        spec: how to build a copy (the observer must not be an agent).
        n_copies: K >= 1.
        workers: None: every copy in this process; ``W``: the copies split over ``W``
            worker processes (:func:`moma_env.vector.make`; the same slots bit for bit).

    Attributes:
        vector: the batched env (:func:`moma_env.vector.make`).
    """

    def __init__(self, spec: EnvSpec, n_copies: int, workers: int | None = None):
        self.vector = make(spec.configuration, n_copies, workers=workers, **spec.options)
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

    def reset(self, seeds: Sequence[int | None], options: dict | None = None) -> tuple[np.ndarray, list[dict]]:
        """Reset copy k with ``seeds[k]`` (None: its generator continues): ``(observations
        (K * N, D) float32, infos: K * N plain dicts)``."""
        observations, infos = self.vector.reset(seed=list(seeds), options=options or None)
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


def worker(connection, spec: EnvSpec) -> None:
    """Worker process main loop: build the copy, then serve commands until ``close``."""
    try:
        slots = TeamSlots(spec)
        connection.send(("ok", (slots.agents, slots.observation_space, slots.action_space)))
    except Exception:  # the parent raises it with the traceback
        connection.send(("error", traceback.format_exc()))
        connection.close()
        return
    while True:
        try:
            command, payload = connection.recv()
        except (EOFError, KeyboardInterrupt):
            break
        try:
            result = slots.handle(command, payload)
            connection.send(("ok", result))
        except Exception:
            connection.send(("error", traceback.format_exc()))
        if command == "close":
            break
    connection.close()
