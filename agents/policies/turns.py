"""Turn taking in switching mode: one device moves at a time, the others hold.

:class:`TurnTakingPolicy` runs the cycle every scripted baseline shares, on the
env's events only: pick a *move* (an agent and the action that moves one
device: ``advance`` moves the robot, ``reel`` the sled it tows), hold until the
dwell is over, request it until the env reports ``mobile:<device>``, keep it
until ``leg_done:<device>``, then pick the next move. Subclasses only say which
move comes next (:meth:`TurnTakingPolicy._next_moves`).

Refusals never deadlock the cycle: a ``dwell`` or ``window`` refusal is retried; a move
refused with ``no_reference`` for longer than ``give_up_s`` is set aside and the
next candidate is tried; when every candidate is set aside, they are all
retried. A leg that stalls (the mover's estimated pose has not changed by
``stall_m`` / ``stall_rad`` for ``stall_s``: it is pushing against another
robot or an obstacle on its straight path, or it is lost and waits) is ended by
holding, and the turn passes, so the robot in the way can move on; so is a leg
the env ends as blocked (``leg_blocked:<device>``, after 1 s without progress).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from agents.policies.base import HOLD, GoalReader, StallWatch, check_stall_settings
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["Move", "TurnTakingPolicy"]



@dataclass(frozen=True)
class Move:
    """``agent`` sends ``action`` to make ``device`` mobile for one leg."""

    agent: str
    action: int
    device: str


class TurnTakingPolicy:
    """Base of the switching-mode scripted policies (see the module docstring).

    Args:
        give_up_s: a move refused for lack of a reference for this long (s) is
            set aside for another candidate.
        stall_s: a mover whose estimated pose moved less than ``stall_m`` (m)
            and turned less than ``stall_rad`` (rad) for this long (s) is stopped.
    """

    def __init__(self, give_up_s: float = 2.0, stall_s: float = 2.0, stall_m: float = 0.02, stall_rad: float = 0.08):
        check_stall_settings(give_up_s=give_up_s, stall_s=stall_s, stall_m=stall_m, stall_rad=stall_rad)
        self.give_up_s = float(give_up_s)
        self.stall_s = float(stall_s)
        self.stall_m = float(stall_m)
        self.stall_rad = float(stall_rad)
        self._env_ready = False

    # ------------------------------------------------------------------ episode facts
    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Read agents, layouts, goals and switching parameters; forget the last episode."""
        self.ugvs: tuple[str, ...] = tuple(a for a in env.possible_agents if a in env.layout.features and a not in env.observer_agents)
        for agent in env.possible_agents:
            if agent in self.ugvs and not isinstance(env.action_space(agent), spaces.Discrete):
                raise ValueError(f"{type(self).__name__} needs action_mode='switching'; {agent} has {env.action_space(agent)}")
            if agent not in self.ugvs:
                raise ValueError(f"{type(self).__name__} cannot fly a learning observer agent ({agent!r}); use observer_agent=False")
        self.reader = GoalReader(env, self.ugvs)
        self.goals = self.reader.goals
        self.tows: dict[str, str] = dict(env.layout.tows)
        control_hz = env.scenario.world.control_hz
        self._give_up_steps = max(1, int(round(self.give_up_s * control_hz)))
        self._watch = StallWatch(max(1, int(round(self.stall_s * control_hz))), self.stall_m, self.stall_rad)
        self.stalls = 0
        self._turn: Move | None = None
        self._moving = False
        self._refused_no_ref = 0
        self._set_aside: set[Move] = set()
        self.last_move: Move | None = None
        self.legs_done = 0
        self._env_ready = True

    # ------------------------------------------------------------------ observation helpers
    def feature(self, agent: str, observations: Mapping[str, np.ndarray], name: str) -> float:
        """One named feature of ``agent``'s observation."""
        return self.reader.feature(agent, observations, name)

    def goal_distance(self, agent: str, observations: Mapping[str, np.ndarray]) -> float:
        """Estimated distance (m) from ``agent`` to its goal; inf if unknown, 0 without a goal."""
        return self.reader.goal_distance(agent, observations)

    def at_goal(self, agent: str, observations: Mapping[str, np.ndarray]) -> bool:
        """Whether ``agent``'s estimate is within its goal's position and heading tolerances."""
        return self.reader.at_goal(agent, observations)

    # ------------------------------------------------------------------ what subclasses decide
    def _next_moves(self, observations: Mapping[str, np.ndarray]) -> Sequence[Move]:
        """Candidate moves, best first; empty when nothing needs to move."""
        raise NotImplementedError

    # ------------------------------------------------------------------ the cycle
    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, int]:
        """Hold for everyone but the mover, whose action depends on the turn's phase."""
        if not self._env_ready:
            raise RuntimeError("call reset(env) before act()")
        if self._turn is not None:
            self._follow_turn(infos)
        if self._turn is None:
            self._start_turn(observations)
        actions = {agent: HOLD for agent in observations}
        turn = self._turn
        if turn is not None and turn.agent in actions:
            waiting = not self._moving and self.feature(turn.agent, observations, "dwell_remaining") > 0.0
            actions[turn.agent] = HOLD if waiting else turn.action
            if self._moving and self._stalled(turn, observations):
                actions[turn.agent] = HOLD  # blocked or lost: stop it and pass the turn
                self.stalls += 1
                self._end_turn(done=False)
        return actions

    def _stalled(self, turn: Move, observations: Mapping[str, np.ndarray]) -> bool:
        """Whether the mover has not moved for ``stall_s`` (robots only: the env ends a
        stuck reel itself when the rope stops shortening)."""
        if turn.device != turn.agent:
            return False
        return self._watch.stalled(self.reader.pose(turn.agent, observations))

    def _follow_turn(self, infos: Mapping[str, Mapping[str, Any]]) -> None:
        turn = self._turn
        assert turn is not None
        info = infos.get(turn.agent)
        events = () if info is None else info["events"]
        if not self._moving:
            if f"mobile:{turn.device}" in events:
                self._moving = True
            else:
                refused = () if info is None else info["refused"]
                if "no_reference" in refused:
                    self._refused_no_ref += 1
                    if self._refused_no_ref >= self._give_up_steps:
                        self._set_aside.add(turn)
                        self._end_turn(done=False)
                        return
        if self._moving and (f"leg_done:{turn.device}" in events or f"static:{turn.device}" in events):
            self._end_turn(done=True)
        elif self._moving and f"leg_blocked:{turn.device}" in events:
            self.stalls += 1  # the env stopped it (blocked): the turn passes, as after a stall seen here
            self._end_turn(done=False)

    def _end_turn(self, done: bool) -> None:
        if done:
            self.legs_done += 1
            self._set_aside.clear()
        self.last_move = self._turn
        self._turn = None
        self._moving = False
        self._refused_no_ref = 0
        self._watch.clear()

    def _start_turn(self, observations: Mapping[str, np.ndarray]) -> None:
        candidates = [m for m in self._next_moves(observations) if m.agent in observations]
        if not candidates:
            return
        fresh = [m for m in candidates if m not in self._set_aside]
        if not fresh:  # every candidate was refused: retry them all rather than wait forever
            self._set_aside.clear()
            fresh = candidates
        self._turn = fresh[0]
