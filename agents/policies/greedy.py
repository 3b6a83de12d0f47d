"""Greedy parallel turn taking: as many movers at once as the motion rules allow.

The one-at-a-time baselines (:class:`~agents.policies.turns.TurnTakingPolicy`) move
one device while every other one holds. The paper's rules allow more: with three or
more robots several may move at once, as long as each mover stays observed from a
static reference (rule 1 with several markers), and a new mover may start whenever
the dwell since the last stop is over (rule 3). :class:`GreedyParallelPolicy` takes
every such chance:

* a robot that is moving keeps advancing (its leg ends by itself at the leg's end,
  ``leg_done``, or when blocked, ``leg_blocked``); one whose estimate has not changed
  by ``stall_m`` / ``stall_rad`` for ``stall_s`` (it is lost and waiting, or pushing
  against something) is stopped;
* when no dwell is running, of the static robots not yet at their goal (position
  and heading within the goal's tolerances, as estimated), the one farthest from its goal whose action mask allows ``ADVANCE`` starts a leg. One
  new mover per step: the masks judge each change alone, and the next step's masks
  judge the next one with the new mover counted.

It reads only what an agent may read: observations (goal distance, dwell), and the
non-truth infos ``static`` and ``action_mask`` (so the env needs
``action_masks=True``, which :attr:`GreedyParallelPolicy.env_options` says).
Robots towing sleds are not handled (their sleds need reeling turns).

On an env whose robots choose their leg lengths (``EnvConfig.leg_lengths``), it starts
every leg with the first length, or with ``leg_m`` when given (one of the env's
lengths): ``GreedyParallelPolicy(leg_m=1.5)``, the spec ``greedy@1.5``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from agents.policies.base import ADVANCE, HOLD, GoalReader, StallWatch, check_stall_settings, read_info
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["GreedyParallelPolicy"]


class GreedyParallelPolicy:
    """See the module docstring.

    Args:
        stall_s: a mover whose estimated pose moved less than ``stall_m`` (m) and
            turned less than ``stall_rad`` (rad) for this long (s) is stopped.
        leg_m: the leg length (m) to start legs with, one of the env's
            ``leg_lengths``; None: the first advance action (the env's first length,
            or its one leg of ``leg_length``).
    """

    #: The env options this policy needs (read by the evaluation harness).
    env_options: Mapping[str, Any] = {"action_mode": "switching", "action_masks": True}

    def __init__(self, stall_s: float = 2.0, stall_m: float = 0.02, stall_rad: float = 0.08, leg_m: float | None = None):
        check_stall_settings(stall_s=stall_s, stall_m=stall_m, stall_rad=stall_rad)
        if leg_m is not None and (isinstance(leg_m, bool) or not isinstance(leg_m, (int, float)) or not 0.0 < leg_m < math.inf):
            raise ValueError(f"leg_m must be None or a positive length (m), got {leg_m!r}")
        self.stall_s = float(stall_s)
        self.stall_m = float(stall_m)
        self.stall_rad = float(stall_rad)
        self.leg_m = None if leg_m is None else float(leg_m)
        #: The action that starts a leg (``ADVANCE`` unless ``leg_m`` picks another; set by :meth:`reset`).
        self.start_action = ADVANCE
        self._ready = False

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Read the agents, goals and normalisations; forget the last episode."""
        if not env.config.action_masks:
            raise ValueError("GreedyParallelPolicy reads the action masks: make the env with action_masks=True")
        self.ugvs = tuple(a for a in env.possible_agents if a not in env.observer_agents)
        for agent in env.possible_agents:
            if agent in env.observer_agents:
                raise ValueError("GreedyParallelPolicy cannot fly a learning observer agent; use observer_agent=False")
            space = env.action_space(agent)
            if not isinstance(space, spaces.Discrete):
                raise ValueError(f"GreedyParallelPolicy needs action_mode='switching'; {agent} has {space}")
            if agent in env.action_mode.tows:
                raise ValueError(f"GreedyParallelPolicy does not reel sleds; {agent} tows one ({space})")
        self.start_action = ADVANCE
        if self.leg_m is not None:
            lengths = env.action_mode.leg_lengths
            if lengths is None or self.leg_m not in lengths:
                offered = "one leg of the scenario's leg_length" if lengths is None else f"leg_lengths {list(lengths)}"
                raise ValueError(f"GreedyParallelPolicy(leg_m={self.leg_m}) needs an env that offers that leg length; this one has {offered}")
            self.start_action = ADVANCE + lengths.index(self.leg_m)
        self.reader = GoalReader(env, self.ugvs)
        stall_steps = max(1, int(round(self.stall_s * env.scenario.world.control_hz)))
        self._watches = {a: StallWatch(stall_steps, self.stall_m, self.stall_rad) for a in self.ugvs}
        self.stalls = 0
        self._ready = True

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, int]:
        """Movers keep advancing; the farthest static robot the masks allow starts a leg."""
        actions, startable = self.plan(observations, infos)
        if startable:
            actions[startable[0]] = self.start_action
        return actions

    def plan(
        self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]
    ) -> tuple[dict[str, int], list[str]]:
        """This step's decisions but the start: the movers' actions (``ADVANCE``, or
        ``HOLD`` for a stalled one and for every static robot), and the static robots
        not at their goal that may start a leg now, farthest from their goal first
        (empty while a dwell runs or when the masks allow none). :meth:`act` starts
        the first; a planner may start another. Counts as this step's :meth:`act`
        for the stall watches (call one of the two per step)."""
        if not self._ready:
            raise RuntimeError("call reset(env) before act()")
        reader = self.reader
        actions = {agent: HOLD for agent in observations}
        idle: list[tuple[float, int, str]] = []
        for agent in actions:
            watch = self._watches[agent]
            if read_info(infos, agent, "static") is False:
                if watch.stalled(reader.pose(agent, observations)):
                    self.stalls += 1
                    watch.clear()
                else:
                    actions[agent] = ADVANCE
                continue
            watch.clear()
            if not reader.at_goal(agent, observations):
                idle.append((-reader.goal_distance(agent, observations), self.ugvs.index(agent), agent))
        if not idle or reader.feature(idle[0][2], observations, "dwell_remaining") > 0.0:
            return actions, []
        startable = []
        for _, _, agent in sorted(idle):
            mask = read_info(infos, agent, "action_mask")
            if mask is None:
                raise ValueError(f"infos[{agent!r}] has no 'action_mask': make the env with action_masks=True")
            if mask[ADVANCE]:
                startable.append(agent)
        return actions, startable
