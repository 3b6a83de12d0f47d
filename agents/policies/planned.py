"""A scripted team policy that executes the MOMA navigation planner's plan in velocity mode.

:class:`PlannedPolicy` computes :func:`moma_env.planning.plan` of the episode's
scenario at ``reset`` (the robots know the map and their goals) and then runs
the plan's turns in order. In each turn

1. every device holds (mobile request -1, zero velocity) until the dwell is over
   (the observation feature ``dwell_remaining`` is 0);
2. the turn's device requests mobile until the env reports ``mobile:<device>``
   (refusals, ``dwell``, ``window`` or ``no_reference``, are simply retried);
3. a robot follows the turn's waypoints with a
   :class:`~moma_env.control.WaypointFollower` on its ESTIMATED pose
   (``infos[agent]["estimate"]``), stopping while its estimate is not
   ``localised``; a sled is reeled in (its robot holds static) until the rope,
   read from the robot's observation feature ``sled.rope``, is back to the
   sled's start length or has stopped shortening;
4. the device requests static; once the env reports ``static:<device>`` the
   next turn starts.

The UAV ``observer`` (an agent in velocity mode) is flown with a
:class:`~moma_env.control.BoardTrackingController` on the board positions in
its camera frame, rebuilt from its observation (seen, x/z, y/z, depth / 4 m).

Only estimates are read: the observation vectors and the ``infos`` keys of
:data:`~agents.policies.base.ALLOWED_INFO_KEYS`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from agents.policies.base import MOVE, REQUEST, STOP, WAIT, FeatureIndex, read_info
from moma_env.control import BoardTrackingController, WaypointFollower, WaypointFollowerConfig
from moma_env.env.parallel import MomaParallelEnv
from moma_env.planning import Plan, plan

__all__ = ["PlannedPolicy"]

#: Scale of the observer's depth feature (m): the layout stores depth / 4 m.
_DEPTH_SCALE_M = 4.0


class PlannedPolicy:
    """Follow the planner's turns in velocity action mode (see the module docstring).

    Args:
        follower: gains and tolerances of the waypoint follower; its
            ``max_speed`` must not exceed the robots' (the command is scaled by
            their limits and clipped to [-1, 1]).
        reel_stall_s: a reeled sled whose rope has not shortened by
            ``reel_stall_m`` for this long (s) ends its turn (it is stuck or the
            rope is at its minimum).
        reel_stall_m: rope shortening (m) that counts as progress.
    """

    def __init__(self, follower: WaypointFollowerConfig | None = None, reel_stall_s: float = 1.0, reel_stall_m: float = 1e-3):
        for name, value in (("reel_stall_s", reel_stall_s), ("reel_stall_m", reel_stall_m)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        self.follower = WaypointFollower(follower or WaypointFollowerConfig(max_speed=0.3, position_tolerance=0.02, yaw_tolerance=0.04))
        self.reel_stall_s = float(reel_stall_s)
        self.reel_stall_m = float(reel_stall_m)
        self._ready = False

    # ------------------------------------------------------------------ episode facts
    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Plan the episode's turns and read the robots' limits (call after ``env.reset``).

        Raises:
            ValueError: the env is not in velocity action mode.
            moma_env.planning.PlanningError: the planner found no valid plan.
        """
        if env.config.action_mode != "velocity":
            raise ValueError(f"PlannedPolicy needs action_mode='velocity', got {env.config.action_mode!r}")
        scenario = env.scenario
        world = scenario.world
        self.plan: Plan = plan(scenario)
        self.ugvs: tuple[str, ...] = tuple(a for a in env.possible_agents if a not in env.observer_agents)
        self.tows: dict[str, str] = dict(env.layout.tows)
        self._robot_of: dict[str, str] = {sled: robot for robot, sled in self.tows.items()}
        for turn in self.plan.turns:
            if turn.device not in self.ugvs and turn.device not in self._robot_of:
                raise ValueError(f"the plan moves {turn.device!r}, which no agent of this env controls")
        self._features = {a: FeatureIndex(env.layout.features[a]) for a in env.possible_agents}
        self._shapes = {a: env.action_space(a).shape for a in env.possible_agents}
        for agent in env.possible_agents:
            if not isinstance(env.action_space(agent), spaces.Box):
                raise ValueError(f"PlannedPolicy needs Box actions; {agent} has {env.action_space(agent)}")
        # Body-velocity command (m/s, m/s, rad/s) -> action scale.
        self._ugv_scale = {u.name: np.array([u.max_speed, u.max_speed, u.max_yaw_rate]) for u in world.ugvs}
        # Rope target (m) of each sled turn: the sled's start rope length; the feature is rope / max_rope.
        self._rope_target = {s.name: s.rope_length for s in getattr(world, "sleds", ())}
        self._max_rope = {s.name: s.max_rope for s in getattr(world, "sleds", ())}
        self._dt = 1.0 / world.control_hz
        # Observer agent -> (its tracking controller, as the env's, its command -> action scale); the agents follow world.uavs.
        image_size = (scenario.camera.width, scenario.camera.height)
        self._trackers = {
            agent: (
                BoardTrackingController(uav.camera_mount[:3, :3], scenario.camera.fx, image_size, env.config.tracking),
                np.array([uav.max_speed, uav.max_speed, uav.max_yaw_rate, uav.max_climb]),
            )
            for agent, uav in zip(env.observer_agents, world.uavs)
        }
        self._observer_devices = tuple(env.layout.devices)
        self.turn_index = 0
        self.device_order: list[str] = []  # devices in the order their mobile requests were granted
        self._phase = WAIT
        self._waypoint = 1
        self._shortest_rope = math.inf
        self._rope_still_s = 0.0
        self._ready = True

    @property
    def done(self) -> bool:
        """Whether every turn of the plan has been executed."""
        return self.turn_index >= len(self.plan.turns)

    # ------------------------------------------------------------------ acting
    def _current_turn(self, observations: Mapping[str, np.ndarray]) -> tuple[Any, str, str] | None:
        """(turn, device, agent) of the turn in progress, None when done or its agent is gone."""
        if self.done:
            return None
        turn = self.plan.turns[self.turn_index]
        agent = self._robot_of.get(turn.device, turn.device)
        return (turn, turn.device, agent) if agent in observations else None

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, np.ndarray]:
        """Actions of every agent in ``observations``: the turn's device moves, the others hold."""
        if not self._ready:
            raise RuntimeError("call reset(env) before act()")
        actions = {a: self._hold(a) for a in observations if a not in self._trackers}
        for agent in self._trackers:
            if agent in observations:
                actions[agent] = self._observer_action(agent, observations[agent])
        current = self._current_turn(observations)
        if current is None:
            return actions
        turn, device, agent = current
        events = read_info(infos, agent, "events") or ()
        if self._phase == REQUEST and f"mobile:{device}" in events:
            self.device_order.append(device)
            self._phase = MOVE
        if self._phase == STOP and f"static:{device}" in events:
            self._next_turn()
            current = self._current_turn(observations)
            if current is None:
                return actions
            turn, device, agent = current
        if self._phase == WAIT and self._feature(agent, observations, "dwell_remaining") <= 0.0:
            self._phase = REQUEST
        action = actions[agent]
        if self._phase == REQUEST:  # retried every step until granted
            self._request_mobile(action, device, agent)
        elif self._phase == MOVE:
            if device == agent:
                self._drive(action, agent, turn.waypoints, infos)
            else:
                self._reel(action, device, agent, observations)
        return actions

    def _hold(self, agent: str) -> np.ndarray:
        action = np.zeros(self._shapes[agent], dtype=np.float32)
        action[3] = -1.0
        if action.shape[0] == 6:
            action[5] = -1.0
        return action

    def _feature(self, agent: str, observations: Mapping[str, np.ndarray], name: str) -> float:
        return float(observations[agent][self._features[agent][name]])

    def _request_mobile(self, action: np.ndarray, device: str, agent: str) -> None:
        if device == agent:
            action[3] = 1.0
        else:
            action[5] = 1.0

    def _next_turn(self) -> None:
        self.turn_index += 1
        self._phase = WAIT
        self._waypoint = 1
        self._shortest_rope = math.inf
        self._rope_still_s = 0.0

    def _drive(self, action: np.ndarray, agent: str, waypoints: tuple, infos: Mapping[str, Mapping[str, Any]]) -> None:
        """Follow the waypoints on the estimate; at the last one request static."""
        action[3] = 1.0
        estimate = read_info(infos, agent, "estimate")
        if estimate is None or read_info(infos, agent, "status") != "localised":
            return  # wait in place until localised again
        while self._waypoint < len(waypoints) - 1 and self.follower.reached(estimate, waypoints[self._waypoint]):
            self._waypoint += 1
        target = waypoints[self._waypoint]
        if self._waypoint == len(waypoints) - 1 and self.follower.reached(estimate, target):
            action[3] = -1.0
            self._phase = STOP
            return
        command = self.follower.command(estimate, target)
        np.clip(command / self._ugv_scale[agent], -1.0, 1.0, out=command)
        action[:3] = command

    def _reel(self, action: np.ndarray, sled: str, agent: str, observations: Mapping[str, np.ndarray]) -> None:
        """Reel the sled in (robot static) until the rope is back to its start length or stops shortening."""
        rope = self._feature(agent, observations, "sled.rope") * self._max_rope[sled]
        if rope < self._shortest_rope - self.reel_stall_m:
            self._shortest_rope = rope
            self._rope_still_s = 0.0
        else:
            self._rope_still_s += self._dt
        if rope <= self._rope_target[sled] or self._rope_still_s > self.reel_stall_s:
            self._phase = STOP  # hold: action[5] stays -1 (static request), reel 0
            return
        action[4] = 1.0
        action[5] = 1.0

    def _observer_action(self, agent: str, observation: np.ndarray) -> np.ndarray:
        """Observer ``agent``'s tracking command from the board positions in its camera frame, scaled to [-1, 1]."""
        tracker, scale = self._trackers[agent]
        features = self._features[agent]
        positions = []
        for device in self._observer_devices:
            if observation[features[f"{device}.seen"]] < 0.5:
                continue
            z = float(observation[features[f"{device}.depth"]]) * _DEPTH_SCALE_M
            positions.append((float(observation[features[f"{device}.x_over_z"]]) * z, float(observation[features[f"{device}.y_over_z"]]) * z, z))
        command = tracker.command(positions)
        return np.clip(command / scale, -1.0, 1.0).astype(np.float32)
