"""Stable-Baselines3 ``VecEnv`` adapters over K copies of a MOMA PettingZoo parallel env.

Both step one batched env (:func:`moma_env.vector.make`, driven as slots by
:class:`training.train.team_slots.VectorSlots`): in this process (the default),
split over ``workers`` processes, or with ``subproc=True`` one copy per process
(``workers=K``). The workers import neither SB3 nor torch. All give the same
slots bit for bit.

* :class:`SharedPolicyVecEnv` (the shared route): every UGV agent of every copy is
  one slot (``num_envs = K * N`` for N UGVs), so one policy is shared by all the
  robots (parameter sharing): the observations are each robot's own (egocentric,
  from its estimates), the reward is the team's.
* :class:`TeamVecEnv` (the centralised route): every copy is one slot, the whole
  team as one agent (``num_envs = K``): slot ``k`` is bit for bit
  :class:`~moma_env.env.centralised.CentralisedTeamEnv` (``gymnasium.make(id)``)
  reset with the seed ``s + k`` and given the same actions, its rewards rounded to
  float32 as SB3's buffers keep them.

Contract (Stable-Baselines3 ``VecEnv``): ``reset()`` returns the stacked
observations ``(num_envs, D)`` and stores the infos in ``reset_infos``;
``step_wait()`` returns observations, rewards ``(num_envs,)`` float32, dones
``(num_envs,)`` bool and a list of ``num_envs`` info dicts; at an episode's end the copy
auto-resets and each of its slots' infos carries ``terminal_observation``,
``TimeLimit.truncated`` and the ``episode`` statistics (``r`` return, ``l`` length,
``t`` simulated duration in s). ``seed(s)`` (what ``PPO(seed=s)`` calls) sets slot
i's seed to ``s + i``; copy k resets with its first slot's seed at the next
``reset()`` (``s + k*N`` shared, ``s + k`` centralised), and every later layout
comes from that copy's seeded generator: same seed, same rollouts.

Action masks (switching mode): ``action_masks()`` gives one row per slot, what the
motion rules would grant at the next step (``MomaParallelEnv.action_mask``: a UGV's
row, or the team's rows side by side), and ``env_method("action_masks")`` returns
those rows, which is how sb3-contrib's ``MaskablePPO`` asks a VecEnv for them.

These adapters live in ``training/`` rather than ``moma_env/``: they subclass
SB3's ``VecEnv``, and SB3 is an optional extra that ``import moma_env`` must
not need.
"""

from __future__ import annotations

import warnings

from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from training.train.team_slots import EnvSpec, VectorSlots

__all__ = ["ACTION_MASKS", "SlotVecEnv", "SharedPolicyVecEnv", "TeamVecEnv"]

#: The method through which sb3-contrib's MaskablePPO asks a VecEnv for every slot's mask.
ACTION_MASKS = "action_masks"


class SlotVecEnv(VecEnv):
    """K copies of a parallel env as the slots of a layout (see the module docstring).

    Args:
        spec: how to build a copy (configuration and env options).
        n_copies: K >= 1.
        subproc: one process per copy (``workers=n_copies``; default: every copy
            in this process).
        start_method: multiprocessing start method of the worker processes
            (default :func:`moma_env.vector.sharded.default_start_method`).
        workers: instead of ``subproc``: the copies split over ``workers``
            processes, this one included (:func:`moma_env.vector.make`).
        slots: ``"ugv"`` (one slot per UGV agent) or ``"team"`` (one per copy)
            (:data:`training.train.team_slots.SLOT_LAYOUTS`).

    Attributes:
        env_spec: ``spec``, how a copy is built. (Not ``spec``: SB3's wrappers, ``VecMonitor``
            among them, read ``venv.spec`` as a Gymnasium ``EnvSpec``; this VecEnv has none.)
        engine: the :class:`VectorSlots` over the batched env (its ``vector``).
    """

    def __init__(
        self,
        spec: EnvSpec,
        n_copies: int,
        subproc: bool = False,
        start_method: str | None = None,
        workers: int | None = None,
        slots: str = "ugv",
    ):
        if isinstance(n_copies, bool) or not isinstance(n_copies, int) or n_copies < 1:
            raise ValueError(f"n_copies must be an integer >= 1, got {n_copies!r}")
        if subproc and workers is not None:
            raise ValueError("subproc (a process per copy) and workers (the batch split over processes) exclude each other")
        self.env_spec = spec
        self.subproc = subproc
        self.engine = VectorSlots(spec, n_copies, n_copies if subproc else workers, start_method=start_method, slots=slots)
        self._closed = False
        self.n_copies = n_copies
        self.agents = list(self.engine.agents)
        self.n_agents = len(self.agents)
        #: Slots of one copy (N UGVs, or 1 for the team).
        self.per_copy = self.engine.layout.per_copy
        super().__init__(self.engine.n_slots, self.engine.observation_space, self.engine.action_space)

    # -------------------------------------------------------------- VecEnv API
    def reset(self) -> VecEnvObs:
        """Reset every copy, copy k with its first slot's seed (``seed(s)``: ``s + k * N``); see the module docstring."""
        firsts = range(0, self.num_envs, self.per_copy)
        seeds = [self._seeds[i] for i in firsts]
        options = [self._options[i] or None for i in firsts]
        observations, infos = self.engine.reset(seeds, options)
        self.reset_infos = infos
        self._reset_seeds()
        self._reset_options()
        return observations

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if actions.shape[0] != self.num_envs:
            raise ValueError(f"expected {self.num_envs} actions (one per slot), got shape {actions.shape}")
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        return self.engine.step(self._actions)

    def close(self) -> None:
        if self._closed:
            return
        self.engine.close()
        self._closed = True

    def _per_slot(self, command: str, payload: Any, indices: VecEnvIndices) -> list[Any]:
        wanted = [i // self.per_copy for i in self._get_indices(indices)]
        values = {k: self.engine.command(k, command, payload) for k in sorted(set(wanted))}
        return [values[k] for k in wanted]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The attribute of the parallel env behind each slot."""
        return self._per_slot("getattr", attr_name, indices)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the attribute on the parallel envs behind the slots."""
        self._per_slot("setattr", (attr_name, value), indices)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        """Call a method of the parallel envs behind the slots; ``"action_masks"``
        (no arguments) gives each slot its own row of :meth:`action_masks`."""
        if method_name == ACTION_MASKS and not method_args and not method_kwargs:
            masks = self.action_masks()
            return [masks[i] for i in self._get_indices(indices)]
        return self._per_slot("call", (method_name, method_args, method_kwargs), indices)

    def has_attr(self, attr_name: str) -> bool:
        """Whether the parallel envs have ``attr_name``; ``"action_masks"`` in the switching mode."""
        if attr_name == ACTION_MASKS:
            return self.engine.layout.discrete
        return super().has_attr(attr_name)

    def action_masks(self) -> np.ndarray:
        """(num_envs, n) bool: per slot, the actions the motion rules would grant its robot
        (each robot of the team) at the next step if it were the only change (switching mode only)."""
        if not self.engine.layout.discrete:
            raise ValueError(f"action masks need the switching mode's discrete actions; the slots act in {self.action_space}")
        return self.engine.action_masks()

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        """The copies are bare parallel envs: never wrapped."""
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Each slot's frame, its copy's ``render()`` (a copy renders once; its slots share the
        frame), what SB3's ``render()`` tiles; as SB3's
        ``DummyVecEnv``, Nones with a warning unless the render mode is ``"rgb_array"``."""
        if self.render_mode != "rgb_array":
            warnings.warn(f"The render mode is {self.render_mode}, but images need render_mode='rgb_array'")
            return [None for _ in range(self.num_envs)]
        return self.env_method("render")


class SharedPolicyVecEnv(SlotVecEnv):
    """K copies, one slot per UGV agent (the shared route; see the module docstring).
    Arguments as :class:`SlotVecEnv`'s, without ``slots``; the observer must not be an agent."""

    def __init__(self, spec: EnvSpec, n_copies: int, subproc: bool = False, start_method: str | None = None, workers: int | None = None):
        super().__init__(spec, n_copies, subproc=subproc, start_method=start_method, workers=workers, slots="ugv")


class TeamVecEnv(SlotVecEnv):
    """K copies, one slot per copy: the centralised team (see the module docstring).
    Arguments as :class:`SlotVecEnv`'s, without ``slots``."""

    def __init__(self, spec: EnvSpec, n_copies: int, subproc: bool = False, start_method: str | None = None, workers: int | None = None):
        super().__init__(spec, n_copies, subproc=subproc, start_method=start_method, workers=workers, slots="team")
