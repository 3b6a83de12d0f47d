"""A centralised Gymnasium view of a MOMA team: the whole team as one agent.

Observation: the agents' observations concatenated in ``possible_agents`` order
(a ``Box``). Action (``EnvConfig.team_action``): by default the agents' actions side
by side, a ``MultiDiscrete`` when every agent is discrete (``switching`` mode), else
a ``Box`` in [-1, 1] where a discrete agent's slot is decoded by rounding into its
range; with ``team_action="one_start"`` one ``Discrete`` choice of which static robot
starts which leg, if any. Reward: the team reward. The episode ends when the team's
episode ends. ``info`` holds each agent's info under its name.

:class:`TeamLayout` holds that mapping (spaces, observation concatenation,
action decoding, masks) for one copy or a batch of copies; it is shared by
:class:`CentralisedTeamEnv` and the batched :class:`moma_env.vector.team.TeamVectorEnv`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from moma_env.env.config import TEAM_ACTIONS
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["CentralisedTeamEnv", "TeamLayout"]


class TeamLayout:
    """How a team of agents is one agent: the team's spaces and the (de)composition.

    Args:
        agents: the agents in team order (``possible_agents``).
        observation_spaces: each agent's observation space (``Box`` only).
        action_spaces: each agent's action space (``Discrete`` or ``Box``).
        team_action: one of :data:`moma_env.env.config.TEAM_ACTIONS` (``EnvConfig.team_action``).

    Attributes:
        agents: the agents in team order.
        observation_space: ``Box`` of shape ``(D,)`` float32, ``D`` the sum of the
            agents' observation sizes.
        action_space: with ``team_action="per_agent"``, ``MultiDiscrete`` of the agents'
            ``n`` when every agent is discrete (``switching`` mode), else ``Box(-1, 1, (A,))``
            float32 with one slot per discrete agent and ``prod(shape)`` slots per ``Box``
            agent. With ``"one_start"``, ``Discrete(1 + S)``: 0 starts no robot, and
            ``1 .. S`` are the agents' advance actions in team order (agent ``j``'s actions
            ``1 .. n_j - 1``, then the next agent's; :attr:`starts`): the chosen robot,
            if static, sends that action, and every other robot keeps its state (a
            mobile robot advances, a static one holds).
        discrete: whether ``action_space`` is discrete with action masks (``MultiDiscrete``
            or the ``one_start`` ``Discrete``).
        team_action: the team action's kind.
        starts: with ``"one_start"``, ``(agent, action)`` of team actions ``1 .. S``; empty otherwise.

    Raises:
        ValueError: an observation space is not a ``Box`` (e.g. ``observer_image``'s
            ``Dict``); an unknown ``team_action``; ``"one_start"`` with an agent whose
            actions are not ``Discrete``.

    What the ``one_start`` action means depends on which robots move, so its methods
    take the copies' latest PettingZoo infos (``infos``: agent -> info for one copy, or a
    sequence of ``K`` such, as the env's ``reset`` and ``step`` return them), whose
    ``"static"`` says it; the ``per_agent`` action ignores them.
    """

    def __init__(
        self,
        agents: Sequence[str],
        observation_spaces: Sequence[spaces.Space],
        action_spaces: Sequence[spaces.Space],
        team_action: str = "per_agent",
    ):
        self.agents: tuple[str, ...] = tuple(agents)
        if not all(isinstance(s, spaces.Box) for s in observation_spaces):
            raise ValueError("the centralised env concatenates vector observations; it cannot take observer_image (a Dict)")
        if team_action not in TEAM_ACTIONS:
            raise ValueError(f"team_action must be one of {TEAM_ACTIONS}, got {team_action!r}")
        self.observation_space = spaces.Box(
            low=np.concatenate([s.low for s in observation_spaces]),
            high=np.concatenate([s.high for s in observation_spaces]),
            dtype=np.float32,
        )
        self._act_spaces: tuple[spaces.Space, ...] = tuple(action_spaces)
        self.team_action = team_action
        self.discrete = all(isinstance(s, spaces.Discrete) for s in action_spaces)
        self.action_space: spaces.MultiDiscrete | spaces.Box | spaces.Discrete
        self.starts: tuple[tuple[str, int], ...] = ()
        if team_action == "one_start":
            if not self.discrete:
                raise ValueError("team_action='one_start' needs every agent's actions Discrete (switching mode, the observer not an agent)")
            self.starts = tuple((agent, a) for agent, space in zip(self.agents, action_spaces) for a in range(1, int(space.n)))
            # team action -> (the agent's position, its action); 0 starts none
            self._start_agent = np.array([-1] + [self.agents.index(agent) for agent, _ in self.starts], dtype=np.int64)
            self._start_action = np.array([0] + [a for _, a in self.starts], dtype=np.int64)
            # agent j's action a is team action offsets[j] + a
            sizes = [int(space.n) - 1 for space in action_spaces]
            self._offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
            self.action_space = spaces.Discrete(1 + len(self.starts))
        elif self.discrete:
            self.action_space = spaces.MultiDiscrete([int(s.n) for s in action_spaces])
        else:
            size = sum(1 if isinstance(s, spaces.Discrete) else int(np.prod(s.shape)) for s in action_spaces)
            self.action_space = spaces.Box(-1.0, 1.0, shape=(size,), dtype=np.float32)

    @property
    def one_start(self) -> bool:
        """Whether the team action is the ``one_start`` ``Discrete``."""
        return self.team_action == "one_start"

    @classmethod
    def of(cls, parallel_env: MomaParallelEnv) -> TeamLayout:
        """The layout of ``parallel_env``'s ``possible_agents``, with its ``EnvConfig.team_action``."""
        agents = list(parallel_env.possible_agents)
        return cls(
            agents,
            [parallel_env.observation_space(a) for a in agents],
            [parallel_env.action_space(a) for a in agents],
            parallel_env.config.team_action,
        )

    def observation(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """The agents' observations concatenated along the last axis, in team order (float32):
        ``(D,)`` for one copy's observations, ``(K, D)`` for ``(K, D_agent)`` arrays."""
        return np.concatenate([observations[a] for a in self.agents], axis=-1).astype(np.float32, copy=False)

    def moving(self, infos: Any) -> np.ndarray:
        """``(K, N)`` bool: agent ``j`` of copy ``k`` is mobile, from the copies' latest infos
        (a sequence of ``K`` mappings agent -> info, or one copy's mapping: ``K`` = 1).

        Raises:
            ValueError: ``infos`` is None or an agent's info has no ``"static"``.
        """
        if infos is None:
            raise ValueError("team_action='one_start' acts on which robots move: give the copies' latest infos (their 'static')")
        copies = [infos] if isinstance(infos, Mapping) else list(infos)
        try:
            return np.array([[not info[agent]["static"] for agent in self.agents] for info in copies], dtype=bool).reshape(len(copies), len(self.agents))
        except (KeyError, TypeError):
            raise ValueError(f"team_action='one_start' reads infos[agent]['static'] of every agent {list(self.agents)}") from None

    def batch_actions(self, actions: Any, infos: Any = None) -> dict[str, np.ndarray]:
        """``K`` team actions, shape ``(K, A)``, split into agent -> the agent's ``K`` actions.

        A discrete agent gets ``(K,)`` integers: in the ``MultiDiscrete`` mode its
        column, checked in range; in the ``Box`` mode its slot in [-1, 1] decoded by
        rounding into ``[0, n)`` (``floor((clip(x, -1, 1) + 1) / 2 * n)``, ``n - 1`` at
        ``x = 1``). A ``Box`` agent gets its slots reshaped to ``(K, *shape)``.

        With ``team_action="one_start"`` the team actions have shape ``(K,)`` and
        ``infos`` are the copies' latest (see the class): copy ``k``'s chosen robot, if
        static, gets its start's action; every other robot, and a chosen one that is
        mobile already, keeps its state (``ADVANCE``, 1, if mobile, else ``HOLD``, 0).

        Raises:
            ValueError: wrong shape, a non-integer or out-of-range ``MultiDiscrete``
                entry, or a non-finite slot of a discrete agent; naming the agent
                and the copy.
        """
        if self.one_start:
            return self._one_start_actions(actions, self.moving(infos))
        a = np.asarray(actions)
        expected = (a.shape[0] if a.ndim else 0, *self.action_space.shape)
        if a.ndim != 2 or a.shape != expected:
            raise ValueError(f"team actions must have shape (num_envs, {self.action_space.shape[0]}) for {self.action_space}, got {a.shape}")
        out: dict[str, np.ndarray] = {}
        if self.discrete:
            if a.dtype.kind not in "iu":
                raise ValueError(f"team actions of {self.action_space} must be integers, got dtype {a.dtype}")
            for i, (agent, space) in enumerate(zip(self.agents, self._act_spaces)):
                column = a[:, i]
                bad = np.flatnonzero((column < 0) | (column >= space.n))
                if bad.size:
                    raise ValueError(
                        f"team action column {i} (agent {agent!r}) must be an integer in [0, {space.n}); copy {int(bad[0])} has {column[bad[0]].item()!r}"
                    )
                out[agent] = column
            return out
        k = 0
        for agent, space in zip(self.agents, self._act_spaces):
            if isinstance(space, spaces.Discrete):
                value = a[:, k].astype(np.float64)
                finite = np.isfinite(value)
                if not finite.all():
                    raise ValueError(f"team action slot {k} (agent {agent!r}, {space}) must be finite; copy {int(np.flatnonzero(~finite)[0])} is not")
                value = np.clip(value, -1.0, 1.0)
                out[agent] = np.minimum(space.n - 1, np.floor((value + 1.0) / 2.0 * space.n)).astype(np.int64)
                k += 1
            else:
                n = int(np.prod(space.shape))
                out[agent] = a[:, k : k + n].reshape(a.shape[0], *space.shape)
                k += n
        return out

    def _one_start_actions(self, actions: Any, moving: np.ndarray) -> dict[str, np.ndarray]:
        a = np.asarray(actions)
        n = int(self.action_space.n)
        if a.ndim != 1:
            raise ValueError(f"team actions must have shape (num_envs,) for {self.action_space} (team_action='one_start'), got {a.shape}")
        if a.dtype.kind not in "iu":
            raise ValueError(f"team actions of {self.action_space} must be integers, got dtype {a.dtype}")
        bad = np.flatnonzero((a < 0) | (a >= n))
        if bad.size:
            raise ValueError(f"team action of copy {int(bad[0])} must be an integer in [0, {n}) (team_action='one_start'), got {a[bad[0]].item()!r}")
        if moving.shape != (a.shape[0], len(self.agents)):
            raise ValueError(f"infos of {moving.shape[0]} copies for {a.shape[0]} team actions")
        index = a.astype(np.int64)
        agent_of, action_of = self._start_agent[index], self._start_action[index]
        return {
            agent: np.where(moving[:, j], 1, np.where(agent_of == j, action_of, 0)).astype(np.int64)
            for j, agent in enumerate(self.agents)
        }

    def team_actions(self, actions: Mapping[str, np.ndarray], infos: Any = None) -> np.ndarray:
        """``K`` copies' agent actions (agent -> ``(K,)`` integers, switching mode) as the team
        actions that stand for them: ``(K, N)`` int64 side by side (``"per_agent"``), or
        ``(K,)`` int64 (``"one_start"``, given the copies' ``infos`` the actions were chosen
        on): the start of the one static robot that takes an action other than 0 (hold),
        0 if none does. A mobile robot's action is left to the decoding, which keeps it
        moving: a scripted policy's stop of a mobile robot (a stalled one that is not
        driving a committed leg) has no one-start action and is left out. A start the
        masks would refuse is a start all the same.

        Raises:
            ValueError: the team action is a ``Box``; with ``"one_start"``, two static
                robots start in the same step of a copy (naming them and the copy).
        """
        if not self.discrete:
            raise ValueError("team actions of agents' actions exist for the discrete actions of action_mode='switching'")
        if not self.one_start:
            return np.stack([np.asarray(actions[a], dtype=np.int64) for a in self.agents], axis=1)
        moving = self.moving(infos)
        chosen = np.stack([np.asarray(actions[a], dtype=np.int64) for a in self.agents], axis=1)  # (K, N)
        if moving.shape != chosen.shape:
            raise ValueError(f"infos of {moving.shape[0]} copies for {chosen.shape[0]} copies' actions")
        starts = ~moving & (chosen != 0)
        crowded = np.flatnonzero(starts.sum(axis=1) > 1)
        if crowded.size:
            k = int(crowded[0])
            names = [self.agents[j] for j in np.flatnonzero(starts[k])]
            raise ValueError(f"copy {k}: agents {names} start in the same step; team_action='one_start' starts one robot a step")
        out = np.zeros(chosen.shape[0], dtype=np.int64)
        k, j = np.nonzero(starts)
        out[k] = self._offsets[j] + chosen[k, j]
        return out

    def agent_actions(self, action: Any, infos: Any = None) -> dict[str, Any]:
        """One team action, shape ``(A,)`` (one integer with ``"one_start"``, given the copy's
        latest ``infos``, agent -> info), split into the agents' actions (a discrete
        agent's as a Python ``int``, a ``Box`` agent's as an array of its shape)."""
        a = np.asarray(action)
        if self.one_start:
            if a.shape != ():
                raise ValueError(f"action must be one integer for {self.action_space} (team_action='one_start'), got shape {a.shape}")
            batch = self._one_start_actions(a[None], self.moving(infos))
            return {agent: int(batch[agent][0]) for agent in self.agents}
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        if self.discrete:  # any number: int() of it, as the parallel env's parser expects
            return {agent: int(a[i]) for i, agent in enumerate(self.agents)}
        batch = self.batch_actions(a[None])
        return {
            agent: int(batch[agent][0]) if isinstance(space, spaces.Discrete) else batch[agent][0]
            for agent, space in zip(self.agents, self._act_spaces)
        }

    def reward(self, rewards: Mapping[str, Any]) -> Any:
        """The team reward: every agent gets it, read from the first agent's (a float,
        or a ``(K,)`` array from the batched rewards)."""
        return rewards[self.agents[0]]

    def masks(self, agent_masks: Mapping[str, np.ndarray], infos: Any = None) -> np.ndarray:
        """The agents' action masks side by side along the last axis (bool): ``(sum n,)``
        from one copy's ``action_masks()``, ``(K, sum n)`` from ``(K, n)`` arrays.

        With ``team_action="one_start"``, given the copies' latest ``infos``: ``(1 + S,)``
        or ``(K, 1 + S)``; starting none is always allowed, and start ``(agent, a)``
        where the robot is static and its mask allows ``a``.

        Raises:
            ValueError: the team action is not discrete (switching mode).
        """
        if not self.discrete:
            raise ValueError("action masks need the discrete team action of action_mode='switching' (the MultiDiscrete, or team_action='one_start')")
        if not self.one_start:
            return np.concatenate([agent_masks[a] for a in self.agents], axis=-1).astype(bool)
        every = [np.asarray(agent_masks[a], dtype=bool) for a in self.agents]
        lead = every[0].shape[:-1]
        moving = self.moving(infos)
        if moving.shape[0] != (lead[0] if lead else 1):
            raise ValueError(f"infos of {moving.shape[0]} copies for masks of shape {every[0].shape}")
        columns = [np.ones((*lead, 1), dtype=bool)]
        for j, mask in enumerate(every):
            static = ~moving[:, j]
            columns.append(mask[..., 1:] & (static[:, None] if lead else static[0]))
        return np.concatenate(columns, axis=-1)


class CentralisedTeamEnv(gym.Env):
    """Wrap a :class:`MomaParallelEnv` as a single-agent ``gymnasium.Env`` (see the module docstring)."""

    def __init__(self, parallel_env: MomaParallelEnv):
        if not isinstance(parallel_env, MomaParallelEnv):
            raise TypeError(f"expected a MomaParallelEnv, got {type(parallel_env).__name__}")
        self.parallel_env = parallel_env
        self.metadata = {"render_modes": parallel_env.metadata["render_modes"], "render_fps": parallel_env.metadata["render_fps"]}
        self.render_mode = parallel_env.render_mode
        self.layout = TeamLayout.of(parallel_env)
        self.observation_space = self.layout.observation_space
        self.action_space = self.layout.action_space
        self._infos: Mapping[str, Any] | None = None  # the parallel env's latest infos (the one-start action reads them)

    def team_observation(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        """The agents' observations concatenated in ``possible_agents`` order (float32)."""
        return self.layout.observation(obs)

    def agent_actions(self, action: Any) -> dict[str, Any]:
        """The team action split into the agents' actions (what ``step`` sends to the parallel
        env), in the state of the latest ``reset`` or ``step``."""
        return self.layout.agent_actions(action, self._infos)

    def action_masks(self) -> np.ndarray:
        """Flat boolean mask over the discrete team action (switching mode): the agents'
        :meth:`MomaParallelEnv.action_mask` side by side in ``possible_agents`` order
        (or the ``one_start`` starts, :meth:`TeamLayout.masks`), the one-dimensional form
        sb3-contrib's ``MaskablePPO`` asks an env for. Each agent's part assumes the
        other agents keep their state."""
        return self.layout.masks(self.parallel_env.action_masks() if self.layout.discrete else {}, self._infos)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        obs, infos = self.parallel_env.reset(seed=seed, options=options)
        self._infos = infos
        return self.team_observation(obs), dict(infos)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, rewards, terms, truncs, infos = self.parallel_env.step(self.agent_actions(action))
        self._infos = infos
        reward = float(self.layout.reward(rewards))
        return self.team_observation(obs), reward, any(terms.values()), any(truncs.values()), dict(infos)

    def render(self) -> np.ndarray | None:
        return self.parallel_env.render()

    def close(self) -> None:
        self.parallel_env.close()
