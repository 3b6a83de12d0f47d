"""The batched MOMA env as a TorchRL ``EnvBase``, grouped as TorchRL's multi-agent envs are.

Needs the ``torchrl`` extra (``pip install "moma_env[torchrl]"``); ``import moma_env``
never imports this module. Importing ``torchrl`` sets multiprocessing's global start
method to ``"spawn"`` when none was set; this module puts it back as it was, so that
importing the adapter does not change how other code (e.g. Gymnasium's
``AsyncVectorEnv`` over a registered id) starts processes. TorchRL's own components
choose their start method explicitly and are not affected.

>>> from moma_env.vector.torchrl import MomaTorchRLEnv          # doctest: +SKIP
>>> env = MomaTorchRLEnv("top_observer", num_envs=8, seed=0)
>>> rollout = env.rollout(100, break_when_any_done=False)      # batch (8, 100)

Layout (``B = num_envs``; TorchRL's multi-agent convention, as its ``PettingZooWrapper``
and ``VmasEnv`` give it): the agents are split in groups, each group a sub-tensordict
of batch ``(B, n_agents)`` whose agents are stacked along dim 1:

* group ``"ugv"``: every UGV agent (``ugv_0``, ``ugv_1``, ...; they share their
  spaces, which is checked); group ``"observer"``: the observers, when they are
  agents (``observer``, or ``observer_0``, ``observer_1``, ... with several). :attr:`MomaTorchRLEnv.group_map` names them (the grouping by name prefix
  that TorchRL's ``PettingZooWrapper`` makes by default, and BenchMARL reads);
* ``(group, "observation")``: ``(B, n, D)`` float32; ``(group, "action")``: ``(B, n)``
  int64 for a ``Discrete`` agent (categorical encoding, switching mode) or
  ``(B, n, *shape)`` float32 in [-1, 1]; ``(group, "reward")``: ``(B, n, 1)`` float32
  (the team reward, rounded to float32); ``(group, "done" | "terminated" |
  "truncated")``: ``(B, n, 1)`` bool;
* ``(group, "action_mask")``: ``(B, n, n_actions)`` bool for a group of discrete
  agents (the motion rules' masks, ``MomaParallelEnv.action_masks``); the group's
  action spec carries the same mask, so ``rand_action`` samples granted actions.
  TorchRL's key ``"mask"`` is for agents that no longer act; every MOMA agent acts
  every step, so there is none;
* root ``"done"``, ``"terminated"``, ``"truncated"``: ``(B, 1)`` bool (any agent);
  root ``"state"``: ``(B, S)`` float32, the global state (``MomaParallelEnv.state``).

Seeding: ``set_seed(s)`` resets copy ``i`` with seed ``s + i`` at once (the next
``reset()`` returns those first observations), so copy ``i`` is the PettingZoo env
reset with ``seed=s + i``; every later reset continues each copy's generator.

Resets: the underlying :class:`~moma_env.vector.MomaVectorEnv` resets a copy in the
step that ends its episode. This env returns that step's last observations, state
and action masks (from ``final_observation``, ``final_state`` and
``final_action_masks``) and keeps the new episode's first ones until TorchRL resets
the copy (``_reset`` mask, or a full ``reset()``), so the data is TorchRL's: a done
step's ``"next"`` holds the episode's end.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

#: multiprocessing's global start method before torchrl's import (None: not set).
_START_METHOD_BEFORE = multiprocessing.get_start_method(allow_none=True)
try:
    import torch
    from tensordict import TensorDict, TensorDictBase
    from torchrl.data import Bounded, Categorical, Composite, Unbounded
    from torchrl.envs import EnvBase
except ImportError as err:  # pragma: no cover - depends on the installed extras
    # ModuleNotFoundError, as for the missing module itself: pytest.importorskip skips on it
    raise ModuleNotFoundError(
        f"moma_env.vector.torchrl needs the 'torchrl' extra (pip install 'moma_env[torchrl]'): {err}", name=err.name
    ) from err
if multiprocessing.get_start_method(allow_none=True) != _START_METHOD_BEFORE:
    multiprocessing.set_start_method(_START_METHOD_BEFORE, force=True)

from moma_env.env.agent_names import is_observer_agent
from moma_env.vector.batch_checks import require_same_step
from moma_env.vector.make import BatchedEnv, make

__all__ = ["MomaTorchRLEnv", "UGV_GROUP", "OBSERVER_GROUP"]

#: Group name of the UGV agents.
UGV_GROUP = "ugv"
#: Group name of the observer, when it is an agent.
OBSERVER_GROUP = "observer"
#: The info keys the env builds by default (``EnvConfig.info_keys``): the action masks it reads.
MASKS_ONLY = ("action_mask",)


def _group_specs(vector: BatchedEnv, agents: list[str], batch: torch.Size) -> tuple[Composite, Composite, bool]:
    """``(observation spec, action spec, discrete)`` of one group of agents with equal spaces.

    Raises:
        ValueError: an agent's spaces differ from the group's first agent's, or an
            observation is not a vector (``observer_image``).
    """
    obs_spaces = [vector.single_observation_space(a) for a in agents]
    act_spaces = [vector.single_action_space(a) for a in agents]
    for agent, o, a in zip(agents, obs_spaces, act_spaces):
        if not isinstance(o, spaces.Box):
            raise ValueError(f"agent {agent!r} observes {o}; the TorchRL adapter takes vector observations (no observer_image)")
        if o.shape != obs_spaces[0].shape or a != act_spaces[0]:
            raise ValueError(f"agent {agent!r} has spaces {o}, {a}; its group {agents} needs the spaces of {agents[0]!r}: {obs_spaces[0]}, {act_spaces[0]}")
    n = len(agents)
    shape = (*batch, n, *obs_spaces[0].shape)
    low = np.broadcast_to(np.stack([o.low for o in obs_spaces]), shape)
    high = np.broadcast_to(np.stack([o.high for o in obs_spaces]), shape)
    if np.isfinite(low).all() and np.isfinite(high).all():
        observation: Bounded | Unbounded = Bounded(torch.as_tensor(low.copy()), torch.as_tensor(high.copy()), shape=shape, dtype=torch.float32)
    else:
        observation = Unbounded(shape=shape, dtype=torch.float32)
    space = act_spaces[0]
    group_shape = (*batch, n)
    observation_spec = Composite({"observation": observation}, shape=group_shape)
    if isinstance(space, spaces.Discrete):
        action: Categorical | Bounded = Categorical(int(space.n), shape=group_shape, dtype=torch.int64)
        observation_spec["action_mask"] = Categorical(2, shape=(*group_shape, int(space.n)), dtype=torch.bool)
    else:
        action = Bounded(float(space.low.min()), float(space.high.max()), shape=(*group_shape, *space.shape), dtype=torch.float32)
        if not (np.all(space.low == space.low.min()) and np.all(space.high == space.high.max())):
            raise ValueError(f"agent {agents[0]!r} acts in {space}; the TorchRL adapter takes a Box with one low and one high")
    return observation_spec, Composite({"action": action}, shape=group_shape), isinstance(space, spaces.Discrete)


def _done_spec(shape: tuple[int, ...]) -> dict[str, Categorical]:
    return {key: Categorical(2, shape=(*shape, 1), dtype=torch.bool) for key in ("done", "terminated", "truncated")}


class MomaTorchRLEnv(EnvBase):
    """``num_envs`` copies of a MOMA configuration as one TorchRL env of batch size
    ``(num_envs,)`` (see the module docstring for the keys and shapes).

    Args:
        configuration: configuration name (``"top_observer"``, ...).
        num_envs: number of copies ``B`` >= 1.
        seed: if given, :meth:`set_seed` with it.
        device: the tensors' device.
        workers: None steps the copies in this process; ``W`` splits them over ``W``
            worker processes (:func:`moma_env.vector.make`; the same episodes).
        options: options of :func:`moma_env.env.factory.parallel_env`. The copies'
            infos are not part of TorchRL's data, so unless ``info_keys`` is given
            they are built with ``info_keys=("action_mask",)`` (the masks this env
            reads; ``EnvConfig.info_keys``): the same episodes, without the truth,
            estimates and reward terms no one reads.

    Attributes:
        vector: the batched env stepped (:func:`moma_env.vector.make`).
        group_map: group name -> its agents (``possible_agents`` order).

    Raises:
        ValueError: the UGVs' spaces differ, or an observation is not a vector.
    """

    def __init__(
        self,
        configuration: str,
        num_envs: int,
        *,
        seed: int | None = None,
        device: str | torch.device = "cpu",
        workers: int | None = None,
        **options: Any,
    ):
        options.setdefault("info_keys", MASKS_ONLY)
        require_same_step(options, "MomaTorchRLEnv")
        self.vector = make(configuration, num_envs, workers=workers, **options)
        super().__init__(device=device, batch_size=torch.Size([self.vector.num_envs]))
        agents = self.vector.possible_agents
        self.group_map: dict[str, list[str]] = {UGV_GROUP: [a for a in agents if not is_observer_agent(a)]}
        observers = [a for a in agents if is_observer_agent(a)]
        if observers:
            self.group_map[OBSERVER_GROUP] = observers
        batch = self.batch_size
        observation_spec = Composite(shape=batch)
        action_spec = Composite(shape=batch)
        reward_spec = Composite(shape=batch)
        done_spec = Composite(_done_spec(tuple(batch)), shape=batch)
        self._masked: list[str] = []
        for group, members in self.group_map.items():
            group_shape = (*batch, len(members))
            observations, actions, discrete = _group_specs(self.vector, members, batch)
            observation_spec[group] = observations
            action_spec[group] = actions
            reward_spec[group] = Composite({"reward": Unbounded(shape=(*group_shape, 1), dtype=torch.float32)}, shape=group_shape)
            done_spec[group] = Composite(_done_spec(group_shape), shape=group_shape)
            if discrete:
                self._masked.append(group)
        state_shape = self.vector.state_space.shape
        observation_spec["state"] = Unbounded(shape=(*batch, *state_shape), dtype=torch.float32)
        self.observation_spec = observation_spec
        self.action_spec = action_spec
        self.reward_spec = reward_spec
        self.done_spec = done_spec
        b = self.vector.num_envs
        self._started = False
        self._observations: dict[str, np.ndarray] = {}  # agent -> (B, D): what the last call returned
        self._masks: dict[str, np.ndarray] = {}  # agent -> (B, n) of the masked groups' agents
        self._state = np.zeros((b, *state_shape), dtype=np.float32)
        self._waiting = np.zeros(b, dtype=bool)  # copies reset by the batched env, not yet by TorchRL
        self._next_observations: dict[str, np.ndarray] = {}
        self._next_masks: dict[str, np.ndarray] = {}
        self._next_state = np.zeros_like(self._state)
        if seed is not None:
            self.set_seed(seed)

    # ------------------------------------------------------------------ output
    def _masked_agents(self) -> list[str]:
        return [a for group in self._masked for a in self.group_map[group]]

    def _read_masks(self) -> dict[str, np.ndarray]:
        if not self._masked:
            return {}
        masks = self.vector.action_masks()
        return {a: masks[a].astype(bool) for a in self._masked_agents()}

    def _tensordict(self, rewards: Mapping[str, np.ndarray] | None = None, terminations: Mapping[str, np.ndarray] | None = None,
                    truncations: Mapping[str, np.ndarray] | None = None) -> TensorDictBase:
        """The current observations, masks and state (with a step's rewards and flags) as a tensordict."""
        b = self.vector.num_envs
        zeros = np.zeros(b, dtype=bool)
        source: dict[str, Any] = {}
        any_terminated = np.zeros(b, dtype=bool)
        any_truncated = np.zeros(b, dtype=bool)
        for group, members in self.group_map.items():
            term = np.stack([terminations[a] if terminations is not None else zeros for a in members], axis=1)[..., None]
            trunc = np.stack([truncations[a] if truncations is not None else zeros for a in members], axis=1)[..., None]
            any_terminated |= term.any(axis=(1, 2))
            any_truncated |= trunc.any(axis=(1, 2))
            fields: dict[str, Any] = {
                "observation": torch.as_tensor(np.stack([self._observations[a] for a in members], axis=1), dtype=torch.float32),
                "terminated": torch.as_tensor(term),
                "truncated": torch.as_tensor(trunc),
                "done": torch.as_tensor(term | trunc),
            }
            if rewards is not None:
                fields["reward"] = torch.as_tensor(np.stack([rewards[a] for a in members], axis=1)[..., None], dtype=torch.float32)
            if group in self._masked:
                mask = torch.as_tensor(np.stack([self._masks[a] for a in members], axis=1))
                fields["action_mask"] = mask
                self.full_action_spec[group, "action"].update_mask(mask.clone())
            source[group] = TensorDict(fields, batch_size=(b, len(members)), device=self.device)
        source["terminated"] = torch.as_tensor(any_terminated[:, None])
        source["truncated"] = torch.as_tensor(any_truncated[:, None])
        source["done"] = torch.as_tensor((any_terminated | any_truncated)[:, None])
        source["state"] = torch.as_tensor(self._state.copy())  # a copy: a later reset of a copy rewrites self._state in place
        return TensorDict(source, batch_size=self.batch_size, device=self.device)

    # ------------------------------------------------------------------ reset
    def _reset_rows(self, tensordict: TensorDictBase | None) -> np.ndarray:
        """The copies to reset: the root ``"_reset"`` (``(B, 1)``), else any agent's group
        ``"_reset"``, else every copy."""
        b = self.vector.num_envs
        if tensordict is None:
            return np.ones(b, dtype=bool)
        reset = tensordict.get("_reset", None)
        if reset is not None:
            return reset.reshape(b, -1).any(-1).cpu().numpy()
        rows = np.zeros(b, dtype=bool)
        found = False
        for group in self.group_map:
            group_reset = tensordict.get((group, "_reset"), None)
            if group_reset is not None:
                found = True
                rows |= group_reset.reshape(b, -1).any(-1).cpu().numpy()
        return rows if found else np.ones(b, dtype=bool)

    def _start(self, seed: int | None) -> None:
        """Reset every copy of the batched env (copy ``i`` with ``seed + i``) and keep the
        first observations as the copies' next episode."""
        observations, _ = self.vector.reset(seed=seed)
        self._started = True
        self._next_observations = {a: np.array(o, dtype=np.float32) for a, o in observations.items()}
        self._next_masks = self._read_masks()
        self._next_state = self.vector.state()
        self._observations = {a: o.copy() for a, o in self._next_observations.items()}
        self._masks = {a: m.copy() for a, m in self._next_masks.items()}
        self._state = self._next_state.copy()
        self._waiting[:] = True

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        rows = self._reset_rows(tensordict)
        if not self._started:
            self._start(None)
        fresh = np.flatnonzero(rows & ~self._waiting)
        for i in fresh:  # copies mid-episode: a new episode from each one's generator
            observations, _ = self.vector.reset_at(int(i))
            for agent, o in observations.items():
                self._next_observations[agent][i] = o
        if fresh.size:
            masks = self._read_masks()
            state = self.vector.state()
            for agent in masks:
                self._next_masks[agent][fresh] = masks[agent][fresh]
            self._next_state[fresh] = state[fresh]
        for agent in self._observations:
            self._observations[agent][rows] = self._next_observations[agent][rows]
        for agent in self._masks:
            self._masks[agent][rows] = self._next_masks[agent][rows]
        self._state[rows] = self._next_state[rows]
        self._waiting[rows] = False
        return self._tensordict()

    # ------------------------------------------------------------------ step
    def _agent_actions(self, tensordict: TensorDictBase) -> dict[str, np.ndarray]:
        """The groups' actions as agent -> ``(B,)`` integers or ``(B, *shape)`` floats."""
        out = {}
        for group, members in self.group_map.items():
            spec = self.full_action_spec[group, "action"]
            action = tensordict.get((group, "action"))
            if tuple(action.shape) != tuple(spec.shape):
                raise ValueError(f"actions of group {group!r} (agents {members}) must have shape {tuple(spec.shape)}, got {tuple(action.shape)}")
            values = action.detach().cpu().numpy()
            for j, agent in enumerate(members):
                out[agent] = values[:, j]
        return out

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        if self._waiting.any():
            waiting = [int(i) for i in np.flatnonzero(self._waiting)]
            raise RuntimeError(f"copies {waiting} finished their episodes: reset them (step_and_maybe_reset, or reset()) before stepping")
        observations, rewards, terminations, truncations, infos = self.vector.step(self._agent_actions(tensordict))
        done = np.array(["final_observation" in info for info in infos], dtype=bool)  # reset by the batched env
        masks = self._read_masks()
        state = self.vector.state()
        for agent, o in observations.items():
            self._observations[agent] = np.array(o, dtype=np.float32)
            if done.any():
                self._next_observations[agent][done] = self._observations[agent][done]
        for i in np.flatnonzero(done):  # the step's data is the episode's end
            for agent, o in infos[i]["final_observation"].items():
                self._observations[agent][i] = o
        if done.any():
            for agent in masks:
                self._next_masks[agent][done] = masks[agent][done]
            self._next_state[done] = state[done]
            self._waiting |= done
            for i in np.flatnonzero(done):  # the step's state and masks are the episode's last ones
                state[i] = infos[i]["final_state"]
                for agent, mask in infos[i].get("final_action_masks", {}).items():
                    if agent in masks:
                        masks[agent][i] = mask.astype(bool)
        self._masks = masks
        self._state = state
        return self._tensordict(rewards, terminations, truncations)

    def _set_seed(self, seed: int | None) -> None:
        """Reset copy ``i`` with seed ``seed + i`` (the next ``reset()`` returns it); None: nothing."""
        if seed is not None:
            self._start(seed)

    def close(self, *, raise_if_closed: bool = True) -> None:
        self.vector.close()
        super().close(raise_if_closed=raise_if_closed)
