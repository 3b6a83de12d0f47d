"""K MOMA env copies seen as slots: :class:`VectorSlots`.

The engine of the training VecEnvs (:mod:`training.train.shared_vec_env`): one batched
env (:func:`moma_env.vector.make`, in this process or split over worker processes),
driven with the VecEnv contract of Stable-Baselines3 for its slots. A slot layout
says what a slot is:

* :class:`UGVSlots` (the shared route): one slot per UGV agent, slot ``k * N + j``
  UGV ``j`` of copy ``k``, its own observation and action;
* :class:`TeamSlot` (the centralised route): one slot per copy, the whole team as
  one agent through :class:`moma_env.env.centralised.TeamLayout`, as
  :class:`~moma_env.env.centralised.CentralisedTeamEnv` sees it.

It deliberately imports neither Stable-Baselines3 nor torch, so that the worker
processes stay light.

* ``step`` returns per slot the observation, the team reward, ``done``
  (terminated or truncated) and an info dict (a new plain ``dict``: the UGV's own
  info, or the copy's, agent -> info, for the team) with ``"TimeLimit.truncated"``
  (truncated and not terminated);
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

from moma_env.env.centralised import TeamLayout
from moma_env.env.factory import parallel_env
from moma_env.env.parallel import MomaParallelEnv
from moma_env.vector import make
from moma_env.vector.batch_checks import require_same_step

__all__ = [
    "EnvSpec", "SLOT_LAYOUTS", "SLOT_INFO_KEYS", "TeamSlot", "UGVSlots", "VectorSlots", "slot_spaces", "slot_infos", "env_command",
    "control_step",
]

#: The info keys the slots read of a copy's infos (``EnvConfig.info_keys``): each UGV's
#: action mask (the masked algorithms' masks come from the infos) and whether it is static
#: (the centralised route's ``one_start`` team action). A training run's envs carry only
#: these (:func:`training.train.envs.make_vec_env`): PPO reads nothing else of them.
SLOT_INFO_KEYS = ("static", "action_mask")


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


class UGVSlots:
    """One slot per UGV agent of a copy (the shared route); see the module docstring.

    Args:
        env: a parallel env of the run (the observer must not be an agent).
    """

    def __init__(self, env: MomaParallelEnv):
        self.agents, self.observation_space, self.action_space = slot_spaces(env)
        #: Slots of one copy.
        self.per_copy = len(self.agents)
        #: Whether the slots' actions are the switching mode's (masks exist).
        self.discrete = isinstance(self.action_space, spaces.Discrete)

    def rows(self, per_agent: Mapping[str, np.ndarray], dtype: type = np.float32) -> np.ndarray:
        """agent -> ``(K, ...)`` arrays as ``(K * N, ...)`` rows of ``dtype``, slot ``k * N + j``."""
        stacked = np.stack([np.asarray(per_agent[a], dtype=dtype) for a in self.agents], axis=1)
        return stacked.reshape(-1, *stacked.shape[2:])

    def agent_actions(self, actions: np.ndarray, infos: Sequence[Mapping[str, Any]] | None = None) -> dict[str, np.ndarray]:
        """One action row per slot (``(K * N,)`` or ``(K * N, *shape)``) as agent -> its ``K``
        actions (``infos``, the copies' latest, unread)."""
        n = self.per_copy
        k = actions.shape[0] // n
        if self.discrete:
            rows = np.asarray(actions).reshape(k, n)
        else:
            rows = np.asarray(actions, dtype=np.float32).reshape(k, n, *self.action_space.shape)
        return {agent: rows[:, j] for j, agent in enumerate(self.agents)}

    def slot_actions(self, actions: Mapping[str, np.ndarray], infos: Sequence[Mapping[str, Any]] | None = None) -> np.ndarray:
        """agent -> ``(K,)`` switching actions as ``(K * N,)`` int64, slot ``k * N + j``
        (the inverse of :meth:`agent_actions`; ``infos`` unread)."""
        return self.rows(actions, dtype=np.int64)

    def mask_rows(self, masks: Mapping[str, np.ndarray], infos: Sequence[Mapping[str, Any]] | None = None) -> np.ndarray:
        """agent -> ``(K, n)`` masks as ``(K * N, n)`` bool rows (``infos`` unread)."""
        return self.rows(masks, dtype=bool)

    def payloads(self, infos: Mapping[str, Mapping[str, Any]]) -> list[Mapping[str, Any]]:
        """One copy's infos (agent -> info) as its slots' infos: each UGV's own."""
        return [infos[a] for a in self.agents]


class TeamSlot:
    """One slot per copy: the whole team as one agent (the centralised route), mapped with
    the :class:`~moma_env.env.centralised.TeamLayout` of
    :class:`~moma_env.env.centralised.CentralisedTeamEnv`; see the module docstring.

    Args:
        env: a parallel env of the run.
    """

    per_copy = 1

    def __init__(self, env: MomaParallelEnv):
        self.layout = TeamLayout.of(env)
        self.agents = list(self.layout.agents)
        self.observation_space = self.layout.observation_space
        self.action_space = self.layout.action_space
        self.discrete = self.layout.discrete

    def rows(self, per_agent: Mapping[str, np.ndarray]) -> np.ndarray:
        """agent -> ``(K, D_agent)`` arrays as ``(K, D)`` float32 team observations."""
        return self.layout.observation(per_agent)

    def agent_actions(self, actions: np.ndarray, infos: Sequence[Mapping[str, Any]] | None = None) -> dict[str, np.ndarray]:
        """``(K, A)`` (or ``(K,)`` one-start) team actions as agent -> its ``K`` actions, in the
        state of the copies' latest ``infos`` (:meth:`TeamLayout.batch_actions`)."""
        return self.layout.batch_actions(actions, infos)

    def slot_actions(self, actions: Mapping[str, np.ndarray], infos: Sequence[Mapping[str, Any]] | None = None) -> np.ndarray:
        """agent -> ``(K,)`` switching actions, chosen on the copies' ``infos``, as the
        copies' team actions (:meth:`TeamLayout.team_actions`)."""
        return self.layout.team_actions(actions, infos)

    def mask_rows(self, masks: Mapping[str, np.ndarray], infos: Sequence[Mapping[str, Any]] | None = None) -> np.ndarray:
        """agent -> ``(K, n)`` masks as the ``(K, M)`` bool team masks, in the state of the
        copies' latest ``infos`` (:meth:`TeamLayout.masks`)."""
        return self.layout.masks(masks, infos)

    def payloads(self, infos: Mapping[str, Mapping[str, Any]]) -> list[Mapping[str, Any]]:
        """One copy's infos as its one slot's info: agent -> info, as the team env's."""
        return [infos]


#: Slot layouts by name: what :class:`VectorSlots` takes.
SLOT_LAYOUTS = {"ugv": UGVSlots, "team": TeamSlot}


def slot_infos(
    payloads: Sequence[Mapping[str, Any]],
    terminated: bool,
    truncated: bool,
    last_observations: np.ndarray | None = None,
    episode: dict[str, float] | None = None,
) -> list[dict]:
    """One copy's step infos as its slots' SB3 infos: per slot a new plain dict of its
    payload (a layout's :meth:`~UGVSlots.payloads`) with ``"TimeLimit.truncated"``
    (truncated and not terminated); at an episode's end (``episode`` given) also
    ``"terminal_observation"`` (row ``j`` of ``last_observations``, ``(per_copy, D)``
    float32) and ``"episode"`` (``r``, ``l``, ``t``)."""
    out = []
    for j, payload in enumerate(payloads):
        info = dict(payload)
        info["TimeLimit.truncated"] = bool(truncated and not terminated)
        if episode is not None:
            info["terminal_observation"] = last_observations[j].copy()
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
    """K copies as slots of a layout, on one batched env (in this process, or split over
    workers) (see the module docstring).

    Args:
        spec: how to build a copy.
        n_copies: K >= 1.
        workers: None: every copy in this process; ``W``: the copies split over ``W``
            processes, this one included (:func:`moma_env.vector.make`; the same slots
            bit for bit).
        start_method: with ``workers``, the multiprocessing start method (default
            :func:`moma_env.vector.sharded.default_start_method`).
        slots: a key of :data:`SLOT_LAYOUTS`: ``"ugv"`` (default, one slot per UGV;
            the observer must not be an agent) or ``"team"`` (one per copy).

    Attributes:
        vector: the batched env (:func:`moma_env.vector.make`).
        layout: the slot layout (:class:`UGVSlots` or :class:`TeamSlot`).
    """

    def __init__(self, spec: EnvSpec, n_copies: int, workers: int | None = None, start_method: str | None = None, slots: str = "ugv"):
        if slots not in SLOT_LAYOUTS:
            raise ValueError(f"slots must be one of {sorted(SLOT_LAYOUTS)}, got {slots!r}")
        require_same_step(spec.options, "the Stable-Baselines3 VecEnv")
        self.vector = make(spec.configuration, n_copies, workers=workers, start_method=start_method, **spec.options)
        self.layout = SLOT_LAYOUTS[slots](self.vector.spec_env)
        self.agents = self.layout.agents
        self.observation_space, self.action_space = self.layout.observation_space, self.layout.action_space
        k = self.vector.num_envs
        self._returns = [0.0] * k
        self._lengths = [0] * k
        self._dt = [0.0] * k  # each copy's control step (s) in its current episode
        self._infos: Sequence[Mapping[str, Any]] | None = None  # each copy's latest PettingZoo infos

    @property
    def n_copies(self) -> int:
        return self.vector.num_envs

    @property
    def n_slots(self) -> int:
        """Slots of every copy: ``K * per_copy``."""
        return self.n_copies * self.layout.per_copy

    def _episode_started(self, k: int) -> None:
        self._returns[k], self._lengths[k] = 0.0, 0
        self._dt[k] = float(self.vector.call_at(k, control_step))

    def reset(self, seeds: Sequence[int | None], options: Sequence[dict | None] | None = None) -> tuple[np.ndarray, list[dict]]:
        """Reset copy k with ``seeds[k]`` (None: its generator continues) and ``options[k]``:
        ``(observations (K * per_copy, D) float32, infos: one plain dict per slot)``."""
        observations, infos = self.vector.reset(seed=list(seeds), options=None if options is None else list(options))
        self._infos = infos
        for k in range(self.n_copies):
            self._episode_started(k)
        payloads = self.layout.payloads
        return self.layout.rows(observations), [dict(p) for info in infos for p in payloads(info)]

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        """One step of every copy with one action row per slot (``(K * per_copy, ...)``);
        a copy whose episode ends resets (the returned observations are its next episode's first)."""
        actions = np.asarray(actions)
        if actions.shape[0] != self.n_slots:
            raise ValueError(f"expected {self.n_slots} action rows (one per slot), got {actions.shape[0]}")
        layout = self.layout
        agents = self.agents
        observations, rewards, terminations, truncations, infos = self.vector.step(layout.agent_actions(actions, self._infos))
        self._infos = infos
        team_rewards = np.asarray(rewards[agents[0]], dtype=np.float64)
        out_infos: list[dict] = []
        dones = np.zeros(self.n_copies, dtype=bool)
        for k, info in enumerate(infos):
            reward = float(team_rewards[k])
            terminated = any(bool(terminations[a][k]) for a in agents)
            truncated = any(bool(truncations[a][k]) for a in agents)
            self._returns[k] += reward
            self._lengths[k] += 1
            if terminated or truncated:
                dones[k] = True
                last = layout.rows({a: np.asarray(info["final_observation"][a])[None] for a in agents})  # (per_copy, D)
                # the copy has reset: its last time (s) is its step count times the control step
                episode = {"r": self._returns[k], "l": self._lengths[k], "t": float(self._lengths[k] * self._dt[k])}
                out_infos += slot_infos(layout.payloads(info["final_info"]), terminated, truncated, last, episode)
                self._episode_started(k)
            else:
                out_infos += slot_infos(layout.payloads(info), terminated, truncated)
        n = layout.per_copy
        return layout.rows(observations), np.repeat(team_rewards.astype(np.float32), n), np.repeat(dones, n), out_infos

    def action_masks(self) -> np.ndarray:
        """``(K * per_copy, n)`` bool, one row per slot (``MomaParallelEnv.action_mask``; switching mode)."""
        return self.layout.mask_rows(self.vector.action_masks(), self._infos)

    def command(self, k: int, command: str, payload: Any) -> Any:
        """:func:`env_command` on copy ``k``'s parallel env."""
        return self.vector.call_at(k, env_command, command, payload)

    def close(self) -> None:
        self.vector.close()
