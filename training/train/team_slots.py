"""One MOMA env copy seen as N slots (one per UGV agent), in-process or in a worker.

This is the engine of :class:`training.train.shared_vec_env.SharedPolicyVecEnv`
and deliberately imports neither Stable-Baselines3 nor torch, so that worker
processes stay light. A copy implements the VecEnv contract of
Stable-Baselines3 for its slots:

* ``step`` returns per slot the observation, the team reward, ``done``
  (terminated or truncated) and the agent's info dict (a new plain ``dict``)
  with ``"TimeLimit.truncated"`` (truncated and not terminated);
* when the episode ends, every slot's info gets ``"terminal_observation"`` (the
  episode's last observation of that slot) and ``"episode"`` (``r``: return,
  ``l``: length in steps, ``t``: simulated duration in s), and the copy resets
  itself at once, so the returned observation is the next episode's first;
* ``reset(seed)`` reseeds the env's generator (every later random layout comes
  from it, so a seed fixes the whole run).

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
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces

from moma_env.env.factory import parallel_env
from moma_env.env.parallel import OBSERVER

__all__ = ["EnvSpec", "TeamSlots", "worker", "slot_spaces"]


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
    if OBSERVER in agents:
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
        out_infos = []
        for k, agent in enumerate(self.agents):
            info = dict(infos[agent])
            info["TimeLimit.truncated"] = bool(truncated and not terminated)
            if done:
                info["terminal_observation"] = obs[k].copy()
                info["episode"] = {"r": self._return, "l": self._length, "t": float(self.env.frame.time)}
            out_infos.append(info)
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
        if command == "getattr":
            return getattr(self.env, payload)
        if command == "setattr":
            name, value = payload
            setattr(self.env, name, value)
            return None
        if command == "call":
            method, args, kwargs = payload
            return getattr(self.env, method)(*args, **kwargs)
        if command == "masks":
            return self.action_masks()
        if command == "close":
            self.env.close()
            return None
        raise ValueError(f"unknown command {command!r}")


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
