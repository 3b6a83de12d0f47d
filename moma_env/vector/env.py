"""A batched multi-agent env: ``num_envs`` copies of one MOMA configuration stepped together.

:func:`moma_env.vector.make` returns a :class:`MomaVectorEnv` (or, with ``workers``, a
:class:`~moma_env.vector.sharded.ShardedVectorEnv` of them in worker processes). Every copy is the PettingZoo env's
own step (:class:`~moma_env.env.parallel.MomaParallelEnv` over its
:class:`~moma_env.sim.Simulation`): one implementation of the camera, the
estimator, the rules, the rewards and the observations, whatever ``num_envs`` is.
A batch step runs the phases of every copy's step (:class:`~moma_env.env.parallel.PendingStep`:
actions and rules, commands, physics, camera requests, then, after the camera requests of
the copies are measured together, localiser, frame, rewards, observations, infos) one
phase for every copy before the next (:func:`~moma_env.env.parallel.run_phases`), in
chunks of at most :data:`PHASE_CHUNK` copies.

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

Autoreset (``autoreset_mode``, one of Gymnasium's modes, ``gymnasium.vector.AutoresetMode``
or its value; the episodes are the same in every mode, only when a step returns what differs):

* ``SAME_STEP`` (the default): a copy whose episode ends in a step is reset in that
  step; the step returns its first observation of the new episode, its flags and reward
  of the step that ended, and in ``infos[i]`` the keys ``"final_observation"`` (agent ->
  the last observation), ``"final_info"`` (the last infos), ``"final_state"`` (the last
  ``state()``), ``"final_time"`` (the episode's simulated duration, s) and, in switching
  mode, ``"final_action_masks"``.
* ``NEXT_STEP`` (Gymnasium's default, what its vector wrappers expect): the step that ends
  an episode returns its last observation, flags, reward and infos; the next step resets
  that copy instead of stepping it (its row of actions is checked, then ignored) and
  returns its first observation and infos, reward 0 and both flags False.
* ``DISABLED``: a copy whose episode ended stays finished until :meth:`reset_at` (or
  ``reset``) resets it; a step with a finished copy raises RuntimeError naming it.

:meth:`reset_at` resets one copy alone, in every mode, and ``reset(seed=s, options={"reset_mask":
mask, ...})`` (Gymnasium's partial reset; ``mask`` a bool array ``(num_envs,)``) the copies of
``mask``, copy ``i`` with seed ``s + i`` and the other options: it returns every copy's
observations (the others' as the batch last returned them) and ``infos`` with ``{}`` for the
copies it did not reset (:func:`partial_reset`).

Action masks (switching mode): ``action_masks()`` gives every UGV's mask for the next
step. With ``EnvConfig.action_masks`` on, every UGV's infos carry that mask already, so
after a ``reset`` or ``step`` the batch returns those (:class:`LatestMasks`, read from the
infos when asked for) instead of computing them again; after :meth:`reset_at` or :meth:`call_at`, which may change a
copy, that copy's masks are computed anew.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from moma_env.env.factory import parallel_env
from moma_env.env.agent_names import is_observer_agent
from moma_env.env.parallel import STEP_PHASES, MomaParallelEnv, checked_seed, run_phases
from moma_env.vector.collection import deferred_collection
from moma_env.vector.batch_checks import (
    checked_actions, checked_autoreset_mode, checked_count, checked_index, checked_reset_mask, copy_options, copy_seeds, random_actions,
    refuse_finished_copies,
)
from moma_env.camera import MeasureRequest, measure_batch

__all__ = ["FINAL_KEYS", "LatestMasks", "MomaVectorEnv", "PHASE_CHUNK", "masks_in_infos", "partial_reset"]

#: The keys the autoreset adds to a copy's infos (see the module docstring).
FINAL_KEYS = ("final_observation", "final_info", "final_state", "final_time", "final_action_masks")

#: A batch step runs its copies in chunks of at most this many, each chunk phase by phase
#: (:func:`~moma_env.env.parallel.run_phases`) with its cameras measured together: the
#: copies' state of a chunk stays in the processor's caches from one phase to the next,
#: which that of 1,024 copies does not (docs/speed_history.md#chunks-of-64-copies).
PHASE_CHUNK = 64


def masks_in_infos(infos: Sequence[Mapping[str, Any]], agents: Sequence[str]) -> dict[str, np.ndarray] | None:
    """UGV agent -> ``(num_envs, n)`` int8: the ``"action_mask"`` each copy's infos carry for
    every UGV of ``agents`` (``EnvConfig.action_masks``), stacked; None if one is missing."""
    ugvs = [a for a in agents if not is_observer_agent(a)]
    if not ugvs or not infos:
        return None
    try:
        return {a: _stacked([info[a]["action_mask"] for info in infos]) for a in ugvs}
    except KeyError:
        return None


class LatestMasks:
    """A batch's action masks for the next step as its last reset's or step's infos carried
    them (:func:`masks_in_infos`), so that ``action_masks()`` need not compute them again.

    :meth:`take` keeps the infos (nothing is read until the masks are asked for, so a
    step pays nothing for them: a worker's shard, or a caller that never asks),
    :meth:`drop` forgets them, :meth:`stale` marks one copy's row as possibly changed
    since (a call on that copy), and :meth:`get` returns the masks, new arrays, with the
    stale rows recomputed, or None when the infos carry none. The infos' mask arrays are
    read at the first :meth:`get` after a step: changed in place before, they change it.
    """

    __slots__ = ("_infos", "_agents", "_masks", "_stale")

    def __init__(self) -> None:
        self._infos: Sequence[Mapping[str, Any]] | None = None
        self._agents: Sequence[str] = ()
        self._masks: dict[str, np.ndarray] | None = None
        self._stale: set[int] = set()

    def take(self, infos: Sequence[Mapping[str, Any]], agents: Sequence[str]) -> None:
        self._infos, self._agents, self._masks = infos, agents, None
        self._stale.clear()

    def drop(self) -> None:
        self._infos, self._masks = None, None
        self._stale.clear()

    def stale(self, index: int) -> None:
        if self._infos is not None:
            self._stale.add(index)

    def get(self, copy_masks: Callable[[int], Mapping[str, np.ndarray]]) -> dict[str, np.ndarray] | None:
        """agent -> ``(num_envs, n)`` int8 (new arrays), the stale rows from ``copy_masks(index)``."""
        if self._infos is None:
            return None
        if self._masks is None:
            self._masks = masks_in_infos(self._infos, self._agents)
            if self._masks is None:
                self.drop()
                return None
        masks = self._masks
        for index in sorted(self._stale):
            row = copy_masks(index)
            for agent, rows in masks.items():
                rows[index] = row[agent]
        self._stale.clear()
        return {agent: rows.copy() for agent, rows in masks.items()}


def _stacked(arrays: list[np.ndarray]) -> np.ndarray:
    """``np.stack(arrays)`` of equal-shaped arrays (a new array, shape ``(len(arrays), *shape)``),
    made by ``np.array``, which stacks them alike without ``np.stack``'s Python-level work (a
    third of its cost for a batch's rows); unequal shapes are a ValueError as with ``np.stack``."""
    return np.array(arrays)


def _stack(values: Sequence[Any]) -> Any:
    if isinstance(values[0], dict):
        return {key: _stacked([v[key] for v in values]) for key in values[0]}
    return _stacked(values)


class MomaVectorEnv:
    """``num_envs`` copies of one configuration; see the module docstring.

    Args:
        name: configuration name (``"top_observer"``, ...).
        num_envs: number of copies (>= 1).
        autoreset_mode: when a finished copy resets (see the module docstring).
        options: options of :func:`moma_env.env.factory.parallel_env`.

    Attributes:
        autoreset_mode: the ``gymnasium.vector.AutoresetMode`` followed.
    """

    def __init__(self, name: str, num_envs: int, *, autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP, **options: Any):
        self.num_envs = checked_count("num_envs", num_envs)
        self.autoreset_mode = checked_autoreset_mode(autoreset_mode)
        # NEXT_STEP and DISABLED: the copies whose episode ended in the last step, not reset since.
        self._ended: set[int] = set()
        # the observations last returned (agent -> batch array), for a partial reset
        self._observations: dict[str, Any] | None = None
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
        self._masks_in_infos = first.config.action_masks  # every UGV's infos carry its mask
        self._latest_masks = LatestMasks()
        # One copy's action spaces, looked up by every step's checks (they are made once per
        # env and stay the same objects across resets).
        self._action_spaces = {a: first.action_space(a) for a in self.possible_agents}
        #: The batch measurement of a step, called once per chunk of :data:`PHASE_CHUNK`
        #: copies: each copy's camera requests -> that copy's detections
        #: (:func:`measure_copies`); an instance attribute, so a benchmark or a test can wrap it.
        self.measure: Callable[[Sequence[Sequence[MeasureRequest]]], list[list[Any]]] = measure_copies
        #: None, or a dict to which every batch step adds the wall time (s) of each phase of its
        #: copies' steps (keys of :data:`~moma_env.env.parallel.STEP_PHASES`) and of the cameras'
        #: measurement (:data:`~moma_env.env.parallel.MEASUREMENT`): what ``moma-env bench
        #: --vector`` breaks a batch step into.
        self.phase_seconds: dict[str, float] | None = None

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
        every copy or a sequence of ``num_envs``, one per copy; with ``"reset_mask"`` in the dict,
        only those copies (:func:`partial_reset`)."""
        if isinstance(options, Mapping) and "reset_mask" in options:
            self._observations, infos = partial_reset(self, self._observations, seed, options)
            return self._observations, infos
        seeds, per_copy = copy_seeds(seed, self.num_envs), copy_options(options, self.num_envs)
        self._latest_masks.drop()
        results = [env.reset(seed=s, options=o) for env, s, o in zip(self.envs, seeds, per_copy)]
        self._ended = set()
        self._started = True
        observations = {a: _stack([obs[a] for obs, _ in results]) for a in self.possible_agents}
        infos = tuple(infos for _, infos in results)
        if self._masks_in_infos:
            self._latest_masks.take(infos, self.possible_agents)
        self._observations = observations
        return observations, infos

    def reset_at(self, index: int, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, Any], dict]:
        """Reset copy ``index`` alone; its observations (agent -> one copy's observation) and infos."""
        index = checked_index(index, self.num_envs)
        seed = checked_seed(seed)
        self._latest_masks.stale(index)
        result = self.envs[index].reset(seed=seed, options=options)
        self._ended.discard(index)
        return result

    # ------------------------------------------------------------------ step
    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, tuple[dict, ...]]:
        """Step every copy with its row of ``actions``; a finished copy resets as :attr:`autoreset_mode` says."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        return self.step_checked(checked_actions(actions, self.possible_agents, self._action_spaces.__getitem__, self.num_envs))

    def step_checked(self, checked: Mapping[str, np.ndarray]) -> tuple[dict, dict, dict, dict, tuple[dict, ...]]:
        """:meth:`step` with actions that :func:`~moma_env.vector.batch_checks.checked_actions`
        returned for this batch (what a sharded batch's caller checked once for all shards)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        refuse_finished_copies(self.autoreset_mode, self._ended)
        self._latest_masks.drop()
        with deferred_collection():
            out = self._step(checked)
            self._observations = out[0]
            if self._masks_in_infos:
                self._latest_masks.take(out[4], self.possible_agents)
        return out

    def _step(self, checked: Mapping[str, np.ndarray]) -> tuple[dict, dict, dict, dict, tuple[dict, ...]]:
        agents = self.possible_agents
        envs = self.envs
        # Every agent's column of actions; a Discrete agent's as Python ints (one conversion
        # for the batch, instead of a numpy scalar per copy: the same values to the copies).
        columns = []
        for a in agents:
            column = checked[a]
            columns.append((a, column.tolist() if column.ndim == 1 else column))
        seconds = self.phase_seconds
        same_step = self.autoreset_mode is AutoresetMode.SAME_STEP
        ended = self._ended
        # The copies stepped: all but, in NEXT_STEP mode, those that ended in the last step.
        indices = [i for i in range(len(envs)) if i not in ended] if ended else range(len(envs))
        stepped: list[tuple] = []
        for first in range(0, len(indices), PHASE_CHUNK):
            start = time.perf_counter() if seconds is not None else 0.0
            pending = [envs[i].begin_step({a: column[i] for a, column in columns}) for i in indices[first : first + PHASE_CHUNK]]
            if seconds is not None:
                seconds[STEP_PHASES[0]] = seconds.get(STEP_PHASES[0], 0.0) + time.perf_counter() - start
            stepped.extend(run_phases(pending, self.measure, seconds))
        # Each copy's (observations, rewards, terminations, truncations, infos).
        results: list[tuple] = []
        stepped_results = iter(stepped)
        now_ended: set[int] = set()
        for i, env in enumerate(envs):
            if i in ended:  # NEXT_STEP: the copy resets instead of stepping
                obs, info = env.reset()
                results.append((obs, dict.fromkeys(agents, 0.0), dict.fromkeys(agents, False), dict.fromkeys(agents, False), info))
                continue
            result = next(stepped_results)
            if not env.agents:
                if same_step:
                    obs, rew, term, trunc, info = result
                    final = {"final_observation": obs, "final_info": info, "final_state": env.state(), "final_time": env.frame.time}
                    if self._masks:
                        final["final_action_masks"] = env.action_masks()
                    obs, info = env.reset()
                    result = (obs, rew, term, trunc, dict(info) | final)
                else:
                    now_ended.add(i)
            results.append(result)
        self._ended = now_ended
        observations = {a: _stack([r[0][a] for r in results]) for a in agents}
        # Rewards and flags: one (agents, num_envs) array each, an agent's row its (num_envs,) array.
        rewards = np.array([[r[1][a] for r in results] for a in agents], dtype=np.float64)
        terminations = np.array([[r[2][a] for r in results] for a in agents], dtype=bool)
        truncations = np.array([[r[3][a] for r in results] for a in agents], dtype=bool)
        return (
            observations,
            dict(zip(agents, rewards)),
            dict(zip(agents, terminations)),
            dict(zip(agents, truncations)),
            tuple([r[4] for r in results]),
        )

    def sample_actions(self, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Uniform random actions of every agent for every copy, drawn from ``rng``
        (:func:`~moma_env.vector.batch_checks.random_actions`)."""
        return random_actions(self.possible_agents, self.single_action_space, self.num_envs, rng)

    # ------------------------------------------------------------------ the rest
    def action_masks(self) -> dict[str, np.ndarray]:
        """Switching mode: agent -> ``(num_envs, n)`` int8, each copy's ``action_masks()`` (the
        ones the last reset's or step's infos carried, if they did: see the module docstring)."""
        latest = self._latest_masks.get(lambda index: self.envs[index].action_masks())
        if latest is not None:
            return latest
        masks = [env.action_masks() for env in self.envs]
        return {a: _stacked([m[a] for m in masks]) for a in masks[0]}

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
        index = checked_index(index, self.num_envs)
        self._latest_masks.stale(index)
        return function(self.envs[index], *args, **kwargs)

    def close(self) -> None:
        for env in self.envs:
            env.close()


def partial_reset(
    env: Any, observations: Mapping[str, Any] | None, seed: int | Sequence[int] | None, options: Mapping[str, Any]
) -> tuple[dict[str, Any], tuple[dict, ...]]:
    """Gymnasium's partial reset of a batched env ``env`` (its ``reset_at``): the copies of
    ``options["reset_mask"]`` (:func:`~moma_env.vector.batch_checks.checked_reset_mask`), copy
    ``i`` with the seed :func:`~moma_env.vector.batch_checks.copy_seeds` gives it and the other
    options. Returns every copy's observations, new arrays (the others' rows from
    ``observations``, what the batch last returned) and the infos, ``{}`` for the copies not reset.

    Raises:
        ValueError: a bad mask. RuntimeError: before the first full reset (no ``observations``).
    """
    mask = checked_reset_mask(options["reset_mask"], env.num_envs)
    if observations is None:
        raise RuntimeError("call reset() before resetting some copies (options['reset_mask'])")
    seeds = copy_seeds(seed, env.num_envs)
    rest = {key: value for key, value in options.items() if key != "reset_mask"} or None
    out = {a: {k: v.copy() for k, v in o.items()} if isinstance(o, dict) else o.copy() for a, o in observations.items()}
    infos: list[dict] = [{} for _ in range(env.num_envs)]
    for i in np.flatnonzero(mask).tolist():
        copy_observations, infos[i] = env.reset_at(i, seed=seeds[i], options=rest)
        for a, rows in out.items():
            if isinstance(rows, dict):
                for k, column in rows.items():
                    column[i] = copy_observations[a][k]
            else:
                rows[i] = copy_observations[a]
    return out, tuple(infos)


def measure_copies(requests: Sequence[Sequence[MeasureRequest]]) -> list[list[Any]]:
    """Copy ``i``'s detections (one list) from its camera requests ``requests[i]``: the
    requests of all copies measured in one :func:`~moma_env.camera.measure_batch` call."""
    frames = iter(measure_batch([r for copy in requests for r in copy]))
    return [[d for _ in copy for d in next(frames)] for copy in requests]
