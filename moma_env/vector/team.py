"""The centralised team as a Gymnasium ``VectorEnv``: ``num_envs`` copies of
:class:`~moma_env.env.centralised.CentralisedTeamEnv`, batched.

``gymnasium.make_vec("moma_env/TopObserver-v0", num_envs=8)`` builds a
:class:`TeamVectorEnv` for every registered id (the ``vector_entry_point``;
``vectorization_mode="sync"`` / ``"async"`` still wrap ``gymnasium.make``'s envs).
It steps a :class:`~moma_env.vector.env.MomaVectorEnv` and maps each copy with the
centralised env's own :class:`~moma_env.env.centralised.TeamLayout`, so copy ``i``
is bit for bit ``gymnasium.make(id)`` reset with seed ``s + i`` and driven with the
same actions.

Shapes (``K = num_envs``, ``D`` the team observation size, ``A`` the team action size):

* ``reset(seed=None, options=None) -> (observations (K, D) float32, infos)``;
* ``step(actions (K, A)) -> (observations (K, D) float32, rewards (K,) float64,
  terminated (K,) bool, truncated (K,) bool, infos)``; ``actions`` are integers
  (``MultiDiscrete``, switching mode) or floats in [-1, 1] (``Box``);
* ``infos``: Gymnasium's vector form, a dict of arrays over the copies: each
  copy's centralised info (agent -> that agent's info dict) batched key by key,
  every key ``k`` with its boolean mask ``"_k"`` (which copies have it);
* :meth:`TeamVectorEnv.action_masks`: ``(K, sum n)`` bool (switching mode);
* :meth:`TeamVectorEnv.reset_at`: one copy reset alone, ``(observation (D,), info)``.

Seeding: ``reset(seed=s)`` seeds copy ``i`` with ``s + i`` (or ``seed`` is a list of
``K`` seeds); ``reset()`` continues every copy's generator.

Autoreset: ``autoreset_mode`` (``gymnasium.make_vec(id, num_envs, autoreset_mode=...)``),
any of Gymnasium's modes, each as Gymnasium's ``SyncVectorEnv`` follows it (the
episodes are the same in every mode; :mod:`moma_env.vector.env`):

* ``AutoresetMode.NEXT_STEP`` (the default, as Gymnasium's own vector envs; its vector
  observation wrappers such as ``NormalizeObservation`` take no other but ``DISABLED``):
  the step after the one that ended an episode resets that copy, ignoring its actions,
  and returns reward 0 and both flags False for it.
* ``AutoresetMode.SAME_STEP``: a copy whose episode ends in a step is reset within that
  step; the step returns its new episode's first observation and infos, and the
  reward, ``terminated`` and ``truncated`` of the step that ended the episode, with
  ``infos["final_obs"]`` (an object array: the last team observation, ``(D,)``, where
  ``infos["_final_obs"]`` is True) and ``infos["final_info"]`` (the last infos, batched
  the same way).
* ``AutoresetMode.DISABLED``: a finished copy waits for ``reset(options={"reset_mask":
  mask})`` (or :meth:`TeamVectorEnv.reset_at`); stepping it first raises RuntimeError.

``reset(seed=s, options={"reset_mask": mask})`` resets only the copies of the bool mask
``(K,)`` (in every mode), copy ``i`` with seed ``s + i``, and returns every copy's
observation (the others' as last returned) and the reset copies' infos.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from moma_env.env.centralised import TeamLayout
from moma_env.vector.env import FINAL_KEYS
from moma_env.vector.make import make

__all__ = ["TeamVectorEnv"]

class TeamVectorEnv(VectorEnv):
    """``num_envs`` copies of the centralised team env (see the module docstring).

    Args:
        configuration: configuration name (``"top_observer"``, ...).
        num_envs: number of copies ``K`` >= 1.
        workers: None steps the copies in this process; ``W`` splits them over ``W``
            worker processes (:func:`moma_env.vector.make`; the same episodes).
        autoreset_mode: a ``gymnasium.vector.AutoresetMode`` or its value (see the module docstring).
        options: options of :func:`moma_env.env.factory.parallel_env` (env options
            and configuration fields), as ``gymnasium.make(id, **options)`` takes.

    Attributes:
        vector: the batched env stepped (per-agent arrays, ``state()``, ``reset_at``): a
            :class:`~moma_env.vector.env.MomaVectorEnv`, or with ``workers`` a
            :class:`~moma_env.vector.sharded.ShardedVectorEnv`. With
            ``team_action="one_start"`` step and reset the copies through this env
            (:meth:`reset_at` for one copy): the team's actions are read in the state of
            the infos it last returned.
        layout: the team layout shared with :class:`CentralisedTeamEnv`.

    Raises:
        ValueError: ``num_envs`` < 1, or an observation that is not a vector (``observer_image``).
    """

    def __init__(
        self, configuration: str, num_envs: int = 1, *, workers: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, **options: Any,
    ):
        self.vector = make(configuration, num_envs, workers=workers, autoreset_mode=autoreset_mode, **options)
        self.num_envs = self.vector.num_envs
        first = self.vector.spec_env
        self.layout = TeamLayout.of(first)
        self.single_observation_space = self.layout.observation_space
        self.single_action_space = self.layout.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = {
            "render_modes": first.metadata["render_modes"],
            "render_fps": first.metadata["render_fps"],
            "autoreset_mode": self.vector.autoreset_mode,
        }
        self.render_mode = self.vector.render_mode
        # each copy's latest PettingZoo infos (the one-start action reads which robots move)
        self._copy_infos: tuple[dict, ...] | None = None

    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every copy: ``(observations (K, D) float32, infos)``; copy ``i`` gets seed ``s + i``.
        With ``options["reset_mask"]`` (a bool array ``(K,)``, Gymnasium's partial reset) only
        those copies, with the other options (see the module docstring).

        Raises:
            ValueError: a ``reset_mask`` that is not a bool array ``(K,)`` with a True.
            RuntimeError: a partial reset before the first :meth:`reset`.
        """
        observations, copy_infos = self.vector.reset(seed=seed, options=options)
        reset = range(self.num_envs)
        if options is not None and "reset_mask" in options:  # the batch's partial reset: the others keep their infos
            reset = np.flatnonzero(options["reset_mask"]).tolist()
            chosen = set(reset)
            copy_infos = tuple(copy_infos[i] if i in chosen else old for i, old in enumerate(self._copy_infos))
        self._copy_infos = copy_infos
        infos: dict[str, Any] = {}
        for i in reset:
            infos = self._add_info(infos, dict(copy_infos[i]), i)
        return self.layout.observation(observations), infos

    def reset_at(self, index: int, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset copy ``index`` alone: its team observation ``(D,)`` float32 and its centralised
        info (agent -> info), as ``gymnasium.make(id).reset(seed=seed)`` gives them; ``seed``
        None continues the copy's generator. The next :meth:`step` and :meth:`action_masks`
        read the copy in its new episode.

        Raises:
            IndexError: ``index`` outside ``[0, num_envs)``.
            RuntimeError: before the first :meth:`reset`.
        """
        if self._copy_infos is None:
            raise RuntimeError("call reset() before reset_at()")
        observations, info = self.vector.reset_at(index, seed=seed, options=options)
        copy_infos = list(self._copy_infos)
        copy_infos[index] = info
        self._copy_infos = tuple(copy_infos)
        return self.layout.observation(observations), dict(info)

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One step of every copy with its row of ``actions`` (``(K, A)``); see the module docstring.

        Raises:
            ValueError: ``actions`` of another shape, or an entry outside an agent's
                range (naming the agent and the copy).
            RuntimeError: before the first :meth:`reset`.
        """
        observations, rewards, terminations, truncations, copy_infos = self.vector.step(self.layout.batch_actions(actions, self._copy_infos))
        self._copy_infos = copy_infos
        agents = self.layout.agents
        terminated = np.any([terminations[a] for a in agents], axis=0)
        truncated = np.any([truncations[a] for a in agents], axis=0)
        infos: dict[str, Any] = {}
        for i, info in enumerate(copy_infos):
            if "final_observation" in info:
                final = {"final_obs": self.layout.observation(info["final_observation"]), "final_info": dict(info["final_info"])}
                infos = self._add_info(infos, final, i)
            infos = self._add_info(infos, {k: v for k, v in info.items() if k not in FINAL_KEYS}, i)
        reward = np.asarray(self.layout.reward(rewards), dtype=np.float64)
        return self.layout.observation(observations), reward, terminated, truncated, infos

    def action_masks(self) -> np.ndarray:
        """``(K, sum n)`` bool: each copy's :meth:`CentralisedTeamEnv.action_masks` (switching mode).

        Raises:
            ValueError: the team action is not the switching mode's (``MultiDiscrete``, or
                ``team_action="one_start"``).
        """
        return self.layout.masks(self.vector.action_masks() if self.layout.discrete else {}, self._copy_infos)

    def render(self) -> tuple[np.ndarray | None, ...]:
        """Every copy's ``render()`` (with ``render_mode="rgb_array"``: ``(H, W, 3)`` uint8 frames)."""
        return tuple(self.vector.render(i) for i in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        """Close the copies (none if construction failed before they were made: Gymnasium's
        ``__del__`` closes a half-built env too)."""
        vector = self.__dict__.get("vector")
        if vector is not None:
            vector.close()
