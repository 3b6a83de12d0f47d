"""The PettingZoo ParallelEnv of every MOMA configuration.

One step: the agents' state requests go through the paper's motion rules
(:mod:`moma_env.env.rules`); granted ones lock or release devices in the world
and are declared to the estimator; the world advances one control step; every
camera measures the boards it sees; the MOMA estimator updates; observations are
built from the estimates only (:mod:`moma_env.env.observations`).

Agents: the UGVs (``ugv_0``, ``ugv_1``, ...) and, when it is a learning agent,
the UAV ``observer``. A sled is a device without an agent: the robot that tows it
commands its state and its reel.

Actions (chosen by ``EnvConfig.action_mode``):

* ``velocity``: a UGV sends ``Box(-1, 1, (4,))``: body velocities vx, vy (times
  its max speed), yaw rate (times its max yaw rate), and a mobile request (> 0:
  be mobile, <= 0: be static). A robot towing a sled sends two more values: the
  reel rate (> 0 reels in) and the sled's mobile request: ``Box(-1, 1, (6,))``.
  The observer sends ``Box(-1, 1, (4,))``: vx, vy, yaw rate, climb rate (times
  its limits).
* ``switching``: a UGV sends ``Discrete(2)``: 0 hold (be static), 1 advance (be
  mobile and drive the next leg towards its goal with the built-in controller;
  at the leg's end the robot stops and is declared static, event
  ``leg_done:<robot>``; a robot that comes no closer to the leg's end for 1 s,
  blocked by a static robot, an obstacle or a wall, stops there and is declared
  static, event ``leg_blocked:<robot>``). A robot towing a
  sled has ``Discrete(3)``: 2 holds the robot and reels the sled in (sled
  mobile until the rope is at its minimum or the sled is stuck, then static). The observer, if an agent, keeps the velocity
  Box; otherwise its tracking controller flies it. With ``EnvConfig.action_masks``
  every UGV's ``infos`` carry ``"action_mask"`` (:meth:`MomaParallelEnv.action_mask`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from moma_env.camera import BoardView, up_in_board
from moma_env.config import all_finite
from moma_env.control import BoardTrackingController, WaypointFollower, WaypointFollowerConfig
from moma_env.env.cameras import build_cameras, floor_for
from moma_env.env.config import EnvConfig
from moma_env.env.observations import DeviceSnapshot, ObservationLayout
from moma_env.env.pixels import observation_spaces, observer_observation
from moma_env.env.rules import MotionRules
from moma_env.estimator import MomaEstimator, Phase, Status
from moma_env.geometry import se3_to_se2, wrap_angle
from moma_env.scenarios import Scenario
from moma_env.world import World

__all__ = ["MomaParallelEnv", "OBSERVER"]

#: Name of the observer agent.
OBSERVER = "observer"
#: A reeled sled whose rope has not shortened for this long (s) is declared static.
_REEL_STALL_S = 1.0
#: A leg of the switching mode whose robot has come no closer to the leg's end for this
#: long (s), while localised, is blocked (by a static robot, an obstacle, a wall): the
#: robot stops and is declared static. The controller's speed floor (2 cm/s) makes a
#: free robot close in by far more than the thresholds below in that time.
_LEG_STALL_S = 1.0
#: Closer by more than this (m) in position, or (rad) in heading, counts as progress.
_LEG_PROGRESS_M = 0.005
_LEG_PROGRESS_RAD = 0.01

ScenarioFactory = Callable[[np.random.Generator | None], Scenario]


def _none_if_nan(value: float) -> float | None:
    """Infos carry None, not NaN, for a missing value (NaN != NaN breaks equality checks)."""
    return None if math.isnan(value) else value


class MomaParallelEnv(ParallelEnv):
    """MOMA multi-robot localisation as a PettingZoo parallel environment.

    Args:
        scenario: a :class:`Scenario`, or a factory ``f(rng) -> Scenario`` called
            at every reset (random scenarios); every scenario it returns must
            have the same robots.
        config: action mode, observer agent, rewards, episode length.
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        name: the environment's name in ``metadata``.
    """

    metadata = {"name": "moma_v0", "render_modes": ["rgb_array", "human"], "render_fps": 25, "is_parallelizable": True}

    def __init__(
        self,
        scenario: Scenario | ScenarioFactory,
        config: EnvConfig | None = None,
        render_mode: str | None = None,
        name: str | None = None,
    ):
        self.config = config or EnvConfig()
        if not isinstance(self.config, EnvConfig):
            raise TypeError(f"config must be an EnvConfig, got {type(self.config).__name__}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        if isinstance(scenario, Scenario):
            self._factory: ScenarioFactory = lambda rng, s=scenario: s
        elif callable(scenario):
            self._factory = scenario
        else:
            raise TypeError(f"scenario must be a Scenario or a callable rng -> Scenario, got {type(scenario).__name__}")
        self.metadata = dict(self.metadata)
        first = self._factory(None)
        if not isinstance(first, Scenario):
            raise TypeError(f"the scenario factory returned {type(first).__name__}, not a Scenario")
        self.metadata["name"] = name or f"{first.name}_v0"
        self.metadata["render_fps"] = int(round(first.world.control_hz))
        self._signature = self._robots_signature(first)
        self._setup(first)
        self._np_random = np.random.default_rng()
        self._seeded = False
        self._window = None

    # ------------------------------------------------------------------ set-up
    @staticmethod
    def _robots_signature(s: Scenario) -> tuple:
        sleds = tuple((sled.name, sled.robot) for sled in getattr(s.world, "sleds", ()))
        return (s.world.ugv_names, sleds, s.world.uav is not None, tuple(sorted(s.goals)))

    def _setup(self, scenario: Scenario) -> None:
        """Build the episode's world, cameras, estimator, rules and layouts."""
        self.scenario = scenario
        wc = scenario.world
        self.world = World(wc)
        self._ugvs = wc.ugv_names
        sleds = tuple(getattr(wc, "sleds", ()))
        self._sleds = tuple(s.name for s in sleds)
        self._tows = {s.robot: s.name for s in sleds}
        self._towed_by: dict[str, str] = {}  # sled -> the robot towing it (the first, if several)
        for robot, sled in self._tows.items():
            self._towed_by.setdefault(sled, robot)
        self._devices = self._ugvs + self._sleds
        self._has_uav = wc.uav is not None
        agents = list(self._ugvs)
        self._observer_agent = self._has_uav and self.config.observer_is_agent
        if self._observer_agent:
            agents.append(OBSERVER)
        self.possible_agents = agents
        self.agents = []

        # Boards and cameras, as the estimator and the cameras see them.
        self._boards: list[tuple[str, int, Any]] = []  # (device, board id, layout)
        board_owner: dict[int, str] = {}
        for index, ugv in enumerate(wc.ugvs):
            if ugv.board is not None:
                self._boards.append((ugv.name, index, ugv.board))
                board_owner[index] = ugv.name
        for k, sled in enumerate(sleds):
            board_id = len(wc.ugvs) + k
            self._boards.append((sled.name, board_id, sled.board))
            board_owner[board_id] = sled.name
        self._board_up = {d.name: up_in_board(d.board_mount) for d in (*wc.ugvs, *sleds)}  # world up in M, from the mounts
        camera_owner: dict[str, str] = {}
        for ugv in wc.ugvs:
            for cam in ugv.cameras:
                camera_owner[cam.name] = ugv.name
        if self._has_uav:
            camera_owner[wc.uav.camera_name] = wc.uav.name
        self._camera_owner = camera_owner
        self._board_owner = board_owner
        self._floor = floor_for(self.config, wc.arena.bounds, getattr(self, "_floor", None))
        self._cameras = build_cameras(camera_owner, scenario.camera, self.config, self._floor)
        # Ground cameras look across the floor: robots and obstacles can hide boards.
        # The UAV looks down over everything.
        uav_camera = wc.uav.camera_name if self._has_uav else None
        self._occlusions = {name: self._occlusion_query(owner) for name, owner in camera_owner.items() if name != uav_camera}
        self.rules = MotionRules(board_owner, camera_owner, scenario.dwell_s)
        self._max_cycles = self.config.max_cycles or scenario.max_cycles

        arena = wc.arena
        xmin, ymin, xmax, ymax = arena.bounds
        centre = ((xmin + xmax) / 2.0, (ymin + ymax) / 2.0)
        self._half_diag = 0.5 * math.hypot(xmax - xmin, ymax - ymin)
        self.layout = ObservationLayout(
            self._devices, self._ugvs, self._tows, self._observer_agent, centre, self._half_diag, scenario.dwell_s
        )
        self._observation_spaces = observation_spaces(self.layout.spaces, OBSERVER, self.config.observer_image)
        self._action_spaces = {a: self._make_action_space(a) for a in self.possible_agents}
        self._follower = WaypointFollower(WaypointFollowerConfig(max_speed=0.3, position_tolerance=0.02, yaw_tolerance=0.04))
        if self._has_uav:
            uav = wc.uav
            self._tracker = BoardTrackingController(uav.camera_mount[:3, :3], scenario.camera.fx, (scenario.camera.width, scenario.camera.height))
        n_state = 5 * len(self._devices) + (7 if self._has_uav else 0) + 4 * len(self._ugvs)
        self.state_space = spaces.Box(-np.inf, np.inf, shape=(n_state,), dtype=np.float32)

    def _make_action_space(self, agent: str) -> spaces.Space:
        if agent == OBSERVER:
            return spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        if self.config.action_mode == "switching":
            return spaces.Discrete(3 if agent in self._tows else 2)
        return spaces.Box(-1.0, 1.0, shape=(6 if agent in self._tows else 4,), dtype=np.float32)

    @property
    def max_cycles(self) -> int:
        """Episode length in steps (truncation); settable, as in PettingZoo's own envs."""
        return self._max_cycles

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"max_cycles must be an integer >= 1, got {value!r}")
        self._max_cycles = value

    # ------------------------------------------------------------------ spaces
    @functools.lru_cache(maxsize=None)  # noqa: B019 - spaces are fixed per instance
    def observation_space(self, agent: str) -> spaces.Space:
        return self._observation_spaces[self._checked_agent(agent)]

    @functools.lru_cache(maxsize=None)  # noqa: B019
    def action_space(self, agent: str) -> spaces.Space:
        return self._action_spaces[self._checked_agent(agent)]

    def _checked_agent(self, agent: str) -> str:
        if agent not in self.possible_agents:
            raise KeyError(f"unknown agent {agent!r}; agents are {self.possible_agents}")
        return agent

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None:
            self._np_random = np.random.default_rng(seed)
            self._seeded = True
        rng_scenario, self._rng_camera = self._np_random.spawn(2)
        scenario = self._factory(rng_scenario)
        if self._robots_signature(scenario) != self._signature:
            raise ValueError("the scenario factory changed the set of robots between resets; agents must stay fixed")
        if scenario is not self.scenario:
            self._setup(scenario)
        else:
            self.world.reset()
        self.agents = list(self.possible_agents)
        self.rules.reset()
        self._steps = 0
        self._last_switch_time = 0.0
        self._mobile: set[str] = set()
        self._legs: dict[str, tuple[float, float, float]] = {}
        self._reeling: set[str] = set()
        self._reel_progress: dict[str, tuple[float, float]] = {}  # sled -> (shortest rope m, when s)
        self._leg_progress: dict[str, tuple[float, float, float]] = {}  # robot -> (closest m, rad, when s)
        self._reached_goal: set[str] = set()
        self._refused_total = 0
        self._switches_total = 0

        est = MomaEstimator(self.scenario.estimator)
        wc = self.scenario.world
        boards_of: dict[str, dict[int, np.ndarray]] = {}
        for device, board_id, _ in self._boards:
            boards_of.setdefault(device, {})[board_id] = self._board_mount(device)
        for ugv in wc.ugvs:
            est.add_robot(
                ugv.name,
                boards=boards_of.get(ugv.name, {}),
                cameras={c.name: c.T_b_c for c in ugv.cameras},
                static=True,
                initial_pose=self.world.ugv_transform(ugv.name),
                time=0.0,
                planar=True,
            )
        for sled in self._sleds:
            est.add_robot(sled, boards=boards_of.get(sled, {}), static=True, initial_pose=self._device_transform(sled), time=0.0, planar=True)
        if self._has_uav:
            est.add_robot(wc.uav.name, cameras={wc.uav.camera_name: wc.uav.camera_mount}, static=False, time=0.0)
        self.estimator = est
        self._detections = self._measure()
        est.update(self.world.time, self._detections)
        self._est = est.estimates()
        self._read_truth()
        self._prev_goal_distance = self._goal_distances()
        self._prev_contacts: frozenset = frozenset()
        observations = self._observations()
        infos = self._infos({}, 0.0)
        return observations, infos

    def _board_mount(self, device: str) -> np.ndarray:
        wc = self.scenario.world
        if device in self._sleds:
            return wc.sled(device).board_mount
        return wc.ugv(device).board_mount

    def _device_transform(self, device: str) -> np.ndarray:
        if device in self._sleds:
            return self.world.sled_transform(device)
        return self.world.ugv_transform(device)

    def _device_pose(self, device: str) -> tuple[float, float, float]:
        if device in self._sleds:
            return self.world.sled_pose(device)
        return self.world.ugv_pose(device)

    def _read_truth(self) -> None:
        """Per device, once the step's world and estimates are final: ``_truth`` (true
        planar pose), ``_est_planar`` (planar pose of the estimate, None without one)
        and ``_errors`` (:meth:`localisation_error`), for the reward, observations and infos."""
        truth = {d: self._device_pose(d) for d in self._devices}
        est_planar: dict[str, tuple[float, float, float] | None] = {}
        errors: dict[str, float] = {}
        for device, (x, y, _) in truth.items():
            T = self._est[device].T_w_b
            if T is None:
                est_planar[device] = None
                errors[device] = math.nan
            else:
                est_planar[device] = se3_to_se2(T)
                errors[device] = math.hypot(T[0, 3] - x, T[1, 3] - y)
        self._truth = truth
        self._est_planar = est_planar
        self._errors = errors

    # ------------------------------------------------------------------ step
    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        if not isinstance(actions, Mapping):
            raise TypeError(f"actions must be a mapping agent -> action, got {type(actions).__name__}")
        for agent in actions:
            if agent not in self.agents:
                if agent in self.possible_agents:
                    raise ValueError(f"action for finished agent {agent!r}")
                raise KeyError(f"action for unknown agent {agent!r}; agents are {self.agents}")
        parsed = {a: self._parse_action(a, actions.get(a)) for a in self.agents}
        t = self.world.time
        events: dict[str, list[str]] = {a: [] for a in self.agents}
        n_switch, n_refused = 0, 0

        # 1. State requests: static first (always granted), then mobile (rules).
        wants = self._requests(parsed)
        for device, want_mobile in wants.items():
            if not want_mobile and device in self._mobile:
                self._make_static(device, t)
                n_switch += 1
                events[self._agent_of(device)].append(f"static:{device}")
        # The references as of the last update: making a device static this step
        # only starts its settling, so no device became a reference since.
        references = settling = None
        for device, want_mobile in wants.items():
            if want_mobile and device not in self._mobile:
                if references is None:
                    references, settling = self._reference_devices()
                reason = self.rules.check_mobile(device, t, self._mobile, references, self._detections, settling)
                agent = self._agent_of(device)
                if reason is None:
                    self._make_mobile(device, t)
                    references.discard(device)
                    n_switch += 1
                    events[agent].append(f"mobile:{device}")
                else:
                    n_refused += 1
                    events[agent].append(f"refused:{device}:{reason}")

        # 2. Commands.
        ugv_commands = self._ugv_commands(parsed, events)
        uav_command = self._uav_command(parsed)

        # 3. Physics, cameras, estimator.
        self.world.step(ugv_commands, uav_command)
        self._steps += 1
        self._detections = self._measure()
        self.estimator.update(self.world.time, self._detections)
        self._est = self.estimator.estimates()
        if self._auto_static_sleds(events):
            self._est = self.estimator.estimates()
        self._read_truth()

        # 4. Rewards, terminations, observations.
        reward, newly_reached, collisions = self._reward(n_switch, n_refused)
        for device in newly_reached:
            events[self._agent_of(device)].append(f"goal:{device}")
        self._switches_total += n_switch
        self._refused_total += n_refused
        done = bool(self.scenario.goals) and len(self._reached_goal) == len(self.scenario.goals)
        truncate = self._steps >= self._max_cycles
        observations = self._observations()
        rewards = {a: reward for a in self.agents}
        terminations = {a: done for a in self.agents}
        truncations = {a: truncate and not done for a in self.agents}
        infos = self._infos(events, reward, collisions)
        if done or truncate:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def _reference_devices(self) -> tuple[set[str], set[str]]:
        """Static devices as the rules see them, as of the estimator's last update (new sets):
        those whose pose others may rely on after a switch (frozen references and ready
        switch windows), and those still collecting their window."""
        ready: set[str] = set()
        settling: set[str] = set()
        for device in self._devices:
            phase = self._est[device].phase
            if phase is Phase.REFERENCE:
                ready.add(device)
            elif phase is Phase.SETTLING:
                (ready if self.estimator.window_ready(device) else settling).add(device)
        return ready, settling

    def _agent_of(self, device: str) -> str:
        return self._towed_by.get(device, device)

    def _parse_action(self, agent: str, action: Any) -> Any:
        """Validated action: an int for Discrete, a list of floats clipped to [-1, 1] for Box."""
        space = self._action_spaces[agent]
        if action is None:
            return 0 if isinstance(space, spaces.Discrete) else [0.0] * space.shape[0]
        if isinstance(space, spaces.Discrete):
            try:
                value = int(action)
            except (TypeError, ValueError):
                raise ValueError(f"action of {agent!r} must be an integer in [0, {space.n}), got {action!r}") from None
            if value != action or not 0 <= value < space.n:
                raise ValueError(f"action of {agent!r} must be an integer in [0, {space.n}), got {action!r}")
            return value
        a = np.asarray(action, dtype=np.float64)
        if a.shape != space.shape:
            raise ValueError(f"action of {agent!r} must have shape {space.shape}, got {a.shape}")
        values = a.tolist()
        if not all_finite(a):
            raise ValueError(f"action of {agent!r} must be finite, got {values}")
        # Plain floats: a handful of values, where numpy calls cost more than the arithmetic.
        return [-1.0 if v < -1.0 else (1.0 if v > 1.0 else v) for v in values]

    def _requests(self, parsed: Mapping[str, Any]) -> dict[str, bool]:
        """Device -> wants to be mobile, from this step's actions."""
        wants: dict[str, bool] = {}
        switching = self.config.action_mode == "switching"
        for agent, action in parsed.items():
            if agent == OBSERVER:
                continue
            sled = self._tows.get(agent)
            if switching:
                if action == 1:
                    wants[agent] = True
                elif agent in self._mobile:  # hold, or reel (the camera must be static)
                    wants[agent] = False
                if sled is not None and action == 2 and sled not in self._mobile:
                    wants[sled] = True
            else:
                wants[agent] = bool(action[3] > 0.0)
                if sled is not None:
                    wants[sled] = bool(action[5] > 0.0)
        return wants

    def _make_static(self, device: str, t: float) -> None:
        self.world.set_static(device, True)
        self.estimator.set_static(device, True, t)
        self._mobile.discard(device)
        self._legs.pop(device, None)
        self._leg_progress.pop(device, None)
        if device in self._sleds:
            self.world.set_reel(device, 0.0)
            self._reeling.discard(device)
        self.rules.note_static(t)
        self._last_switch_time = t

    def _make_mobile(self, device: str, t: float) -> None:
        self.world.set_static(device, False)
        self.estimator.set_static(device, False, t)
        self._mobile.add(device)
        self._last_switch_time = t
        if self.config.action_mode == "switching":
            if device in self._sleds:
                self._reeling.add(device)
                self._reel_progress[device] = (math.inf, t)
                self.world.set_reel(device, 1.0)
            else:
                self._legs[device] = self._next_leg(device)
                self._leg_progress[device] = (math.inf, math.inf, t)

    def _leg_blocked(self, device: str, pose: tuple[float, float, float], leg: tuple[float, float, float], t: float) -> bool:
        """Note how far ``device`` (localised at ``pose``) is from the end of its ``leg`` at
        time ``t`` (s); True if it has come no closer for ``_LEG_STALL_S``."""
        distance = math.hypot(leg[0] - pose[0], leg[1] - pose[1])
        heading = abs(wrap_angle(leg[2] - pose[2]))
        closest, aligned, since = self._leg_progress[device]
        if distance < closest - _LEG_PROGRESS_M or heading < aligned - _LEG_PROGRESS_RAD:
            closest, aligned, since = min(distance, closest), min(heading, aligned), t
            self._leg_progress[device] = (closest, aligned, since)
        return t - since > _LEG_STALL_S

    def _next_leg(self, device: str) -> tuple[float, float, float]:
        """Target of the next advance: at most ``leg_length`` towards the goal, from the estimate."""
        goal = self.scenario.goals.get(device)
        pose = self._estimated_pose(device)
        if pose is None:
            pose = self._device_pose(device)  # never used for control: a static device has a frozen estimate
        if goal is None:
            return pose
        x, y, yaw = pose
        dx, dy = goal[0] - x, goal[1] - y
        dist = math.hypot(dx, dy)
        if dist <= self.scenario.leg_length:
            return goal
        f = self.scenario.leg_length / dist
        return (x + f * dx, y + f * dy, yaw)

    def _estimated_pose(self, device: str) -> tuple[float, float, float] | None:
        e = self._est[device]
        if e.T_w_b is None or e.status is Status.LOST:
            return None
        return se3_to_se2(e.T_w_b)

    def _ugv_commands(self, parsed: Mapping[str, Any], events: dict[str, list[str]]) -> dict[str, np.ndarray]:
        commands: dict[str, np.ndarray] = {}
        wc = self.scenario.world
        t = self.world.time
        if self.config.action_mode == "velocity":
            for agent, a in parsed.items():
                if agent == OBSERVER:
                    continue
                u = wc.ugv(agent)
                commands[agent] = np.array([a[0] * u.max_speed, a[1] * u.max_speed, a[2] * u.max_yaw_rate])
                sled = self._tows.get(agent)
                if sled is not None and sled in self._mobile:
                    self.world.set_reel(sled, float(a[4]))
            return commands
        for device, leg in list(self._legs.items()):
            pose = self._estimated_pose(device)
            e = self._est[device]
            if pose is None or e.status is not Status.LOCALISED:
                commands[device] = np.zeros(3)  # wait where it is until it is localised again
                closest, aligned, _ = self._leg_progress[device]
                self._leg_progress[device] = (closest, aligned, t)  # waiting is not being blocked
                continue
            if self._follower.reached(pose, leg):
                self._make_static(device, t)
                events[self._agent_of(device)].append(f"leg_done:{device}")
                commands[device] = np.zeros(3)
            elif self._leg_blocked(device, pose, leg, t):
                self._make_static(device, t)
                events[self._agent_of(device)].append(f"leg_blocked:{device}")
                commands[device] = np.zeros(3)
            else:
                commands[device] = self._follower.command(pose, leg)
        return commands

    def _auto_static_sleds(self, events: dict[str, list[str]]) -> bool:
        """In switching mode a reeled sled becomes static once the rope is at its minimum,
        or when it has not shortened for a second (the sled is stuck). True if one did."""
        t = self.world.time
        changed = False
        for sled in list(self._reeling):
            cfg = self.scenario.world.sled(sled)
            rope = self.world.rope_length(sled)
            shortest, since = self._reel_progress.get(sled, (math.inf, t))
            if rope < shortest - 1e-4:
                self._reel_progress[sled] = (rope, t)
                since = t
            stalled = t - since > _REEL_STALL_S
            if rope <= cfg.min_rope + 1e-6 or stalled:
                self._reel_progress.pop(sled, None)
                changed = True
                self._make_static(sled, self.world.time)
                agent = self._agent_of(sled)
                if agent in events:
                    events[agent].append(f"leg_done:{sled}")
        return changed

    def _uav_command(self, parsed: Mapping[str, Any]) -> np.ndarray | None:
        if not self._has_uav:
            return None
        uav = self.scenario.world.uav
        if self._observer_agent:
            a = parsed[OBSERVER]
            return np.array([a[0] * uav.max_speed, a[1] * uav.max_speed, a[2] * uav.max_yaw_rate, a[3] * uav.max_climb])
        positions = [d.T_c_m[:3, 3].tolist() for d in self._detections if d.camera_id == uav.camera_name]
        return self._tracker.command(positions)

    def _measure(self) -> list:
        views = self.board_views()
        if self._occlusions:
            # Device positions for the occlusion queries, once per frame.
            self._device_xy = [(d, self._device_pose(d)[:2]) for d in self._devices]
        detections = []
        for name, camera in self._cameras.items():
            occluded = self._occlusions.get(name)
            detections += camera.measure(self.world.camera_transform(name), views, self.world.time, self._rng_camera, occluded)
        return detections

    def _occlusion_query(self, camera_owner: str):
        """Line-of-sight test for a ground camera: walls, obstacles and robots other than
        the camera's owner and the device carrying the marker (the one nearest the marker,
        among the positions :meth:`_measure` takes once per frame)."""
        world = self.world

        def occluded(p_from: np.ndarray, p_to: np.ndarray) -> bool:
            x, y = float(p_to[0]), float(p_to[1])
            nearest = min(self._device_xy, key=lambda item: (item[1][0] - x) ** 2 + (item[1][1] - y) ** 2)[0]
            return world.segment_blocked(p_from[:2], p_to[:2], ignore=(camera_owner, nearest))

        return occluded

    # ------------------------------------------------------------------ reward
    def _goal_distances(self) -> dict[str, float]:
        out = {}
        truth = self._truth
        for device, goal in self.scenario.goals.items():
            x, y, _ = truth[device]
            out[device] = math.hypot(goal[0] - x, goal[1] - y)
        return out

    def _reward(self, n_switch: int, n_refused: int) -> tuple[float, list[str], int]:
        w = self.config.rewards
        dist = self._goal_distances()
        progress = sum(self._prev_goal_distance[d] - dist[d] for d in dist)
        self._prev_goal_distance = dist
        errors, n_lost = [], 0
        for device in self._ugvs:
            err = self._errors[device]
            if math.isnan(err):
                errors.append(w.lost_error_m)
            else:
                errors.append(err)
            if self._est[device].status is Status.LOST:
                n_lost += 1
        newly = []
        for device, goal in self.scenario.goals.items():
            if device in self._reached_goal:
                continue
            yaw = self._truth[device][2]
            if dist[device] <= self.scenario.goal_tolerance_m and abs(wrap_angle(goal[2] - yaw)) <= self.scenario.goal_tolerance_rad:
                self._reached_goal.add(device)
                newly.append(device)
        contacts = self.world.collisions_since_last_step
        new_contacts = contacts - self._prev_contacts
        self._prev_contacts = contacts
        reward = (
            w.progress * progress
            + w.localisation_error * (sum(errors) / max(1, len(errors)))
            + w.switch * n_switch
            + w.refused * n_refused
            + w.collision * len(new_contacts)
            + w.lost * n_lost
            + w.goal_bonus * len(newly)
            + w.time
        )
        return float(reward), newly, len(new_contacts)

    @property
    def devices(self) -> tuple[str, ...]:
        """The devices (UGVs, then sleds) in their fixed order."""
        return self._devices

    @property
    def sleds(self) -> tuple[str, ...]:
        """The sleds among the devices."""
        return self._sleds

    @property
    def boards(self) -> tuple[tuple[str, int, Any], ...]:
        """Every board as ``(device, board id, layout)``."""
        return tuple(self._boards)

    @property
    def cameras(self) -> Mapping[str, Any]:
        """The camera backends by camera name (world camera names; read-only)."""
        return MappingProxyType(self._cameras)

    @property
    def steps(self) -> int:
        """Steps since the last ``reset``."""
        return self._steps

    @property
    def mobile_devices(self) -> frozenset[str]:
        """The devices declared mobile now."""
        return frozenset(self._mobile)

    @property
    def switches_total(self) -> int:
        """Granted state changes since the last ``reset``."""
        return self._switches_total

    @property
    def refused_total(self) -> int:
        """Refused mobile requests since the last ``reset``."""
        return self._refused_total

    def board_views(self) -> list[BoardView]:
        """The boards as the cameras are shown them now: true pose and the mount's up direction."""
        return [
            BoardView(board_id, layout, self.world.board_transform(device), self._board_up[device])
            for device, board_id, layout in self._boards
        ]

    @property
    def detections(self) -> tuple:
        """The latest camera frame: every camera's ``Detection``s of the last ``reset``
        or ``step`` (camera ids are the world's camera names)."""
        return tuple(self._detections)

    def board_device(self, board_id: int) -> str:
        """The device (UGV or sled) that carries board ``board_id``; KeyError naming the known ids otherwise."""
        try:
            return self._board_owner[board_id]
        except KeyError:
            raise KeyError(f"unknown board id {board_id!r}; known: {sorted(self._board_owner)}") from None

    def localisation_error(self, device: str) -> float:
        """Planar position error (m) of a device's MOMA estimate, NaN without one
        (as of the last ``reset`` or ``step``; see :meth:`_read_truth`)."""
        return self._errors[device]

    # ------------------------------------------------------------------ observations
    def _snapshots(self) -> dict[str, DeviceSnapshot]:
        seen: set[str] = set()
        for d in self._detections:
            seen.add(self._board_owner[d.board_id])
            seen.add(self._camera_owner[d.camera_id])
        lost_after = self.scenario.estimator.lost_after_s
        t = self.world.time
        snaps = {}
        for device in self._devices:
            e = self._est[device]
            pose = None if e.status is Status.LOST else self._est_planar[device]
            age = 1.0 if e.last_fresh_time is None else min(1.0, (t - e.last_fresh_time) / lost_after)
            snaps[device] = DeviceSnapshot(
                pose, e.status, device not in self._mobile, age, e.position_std_m, e.heading_std_rad, device in seen
            )
        return snaps

    def _observations(self) -> dict[str, np.ndarray]:
        if not self.agents:
            return {}
        snaps = self._snapshots()
        t = self.world.time
        since = t - self._last_switch_time
        dwell_left = self.rules.dwell_remaining(t)
        obs = {}
        for agent in self.agents:
            if agent == OBSERVER:
                continue
            rope = None
            sled = self._tows.get(agent)
            if sled is not None:
                cfg = self.scenario.world.sled(sled)
                rope = self.world.rope_length(sled) / cfg.max_rope
            obs[agent] = self.layout.ugv(agent, snaps, self.scenario.goals.get(agent), since, dwell_left, rope)
        if self._observer_agent and OBSERVER in self.agents:
            uav = self.scenario.world.uav
            e = self._est[uav.name]
            pose = None if e.T_w_b is None or e.status is Status.LOST else se3_to_se2(e.T_w_b)
            altitude = None if pose is None else float(e.T_w_b[2, 3])
            in_cam = {self._board_owner[d.board_id]: d.T_c_m[:3, 3] for d in self._detections if d.camera_id == uav.camera_name}
            std = (e.position_std_m, e.heading_std_rad)
            obs[OBSERVER] = self.layout.observer(pose, altitude, e.status, std, in_cam, since, dwell_left)
            if self.config.observer_image is not None:
                image = self._cameras[uav.camera_name].last_image
                obs[OBSERVER] = observer_observation(obs[OBSERVER], image, self.config.observer_image)
        return obs

    def _info(self, agent: str, events: list[str], reward: float, collisions: int = 0) -> dict:
        if agent == OBSERVER:
            uav = self.scenario.world.uav
            s = self.world.uav_state
            e = self._est[uav.name]
            if e.T_w_b is None:
                err = None
            else:
                d = e.T_w_b[:3, 3] - np.array([s.x, s.y, s.z])
                err = math.sqrt(d.dot(d))  # what np.linalg.norm computes for a vector
            return {
                "truth": (s.x, s.y, s.yaw, s.z),
                "status": e.status.name.lower(),
                "covariance": e.covariance,
                "localisation_error": err,
                "events": events,
            }
        e = self._est[agent]
        info = {
            "truth": self._truth[agent],
            "estimate": self._est_planar[agent],
            "covariance": e.covariance,
            "localisation_error": _none_if_nan(self._errors[agent]),
            "status": e.status.name.lower(),
            "static": agent not in self._mobile,
            "events": events,
            "refused": [ev.split(":", 2)[2] for ev in events if ev.startswith("refused:")],
            "reached_goal": agent in self._reached_goal,
            "collisions": collisions,
            "switches_total": self._switches_total,
        }
        sled = self._tows.get(agent)
        if sled is not None:
            info["sled_truth"] = self._truth[sled]
            info["sled_localisation_error"] = _none_if_nan(self._errors[sled])
        return info

    def _infos(self, events: Mapping[str, list[str]], reward: float, collisions: int = 0) -> dict[str, dict]:
        """Every agent's info (:meth:`_info`; ``events`` by agent, none if left out), with
        the UGVs' action masks when ``EnvConfig.action_masks`` is on."""
        infos = {a: self._info(a, events.get(a, []), reward, collisions) for a in self.agents}
        if self.config.action_masks:
            masks = self.action_masks()
            for agent in self.agents:
                if agent != OBSERVER:
                    infos[agent]["action_mask"] = masks[agent]
        return infos

    def action_masks(self) -> dict[str, np.ndarray]:
        """:meth:`action_mask` of every UGV agent of ``possible_agents`` (switching mode),
        the estimator's reference set read once for all of them."""
        if self.config.action_mode != "switching":
            raise ValueError(f"action masks are for the switching mode's actions; this env is in {self.config.action_mode!r} mode")
        references, settling = self._reference_devices()
        return {a: self._action_mask(a, references, settling) for a in self.possible_agents if a != OBSERVER}

    def action_mask(self, agent: str) -> np.ndarray:
        """Which switching actions of UGV ``agent`` the motion rules would grant at the next step.

        An ``int8`` array over the agent's ``Discrete`` actions (the form
        ``Discrete.sample(mask=...)`` takes), 1 where the action's requests would
        all be granted if it were the only change requested (every other agent
        keeping its current state), as of the last ``reset`` or ``step``:

        * 0, hold: always 1 (becoming static is always granted);
        * 1, advance: 1 if the robot is mobile already, else if
          :meth:`MotionRules.check_mobile` grants it (dwell time over, every
          mover still localisable from a static reference in the latest frame);
        * 2, reel the towed sled in: 1 if the sled is mobile already, else if the
          robot is static and the rules grant the sled; from a mobile robot it is
          0 (the robot stops first, which restarts the dwell).

        A mask, not a rule: masked actions may still be sent, and are refused
        and reported in ``infos`` as usual.
        """
        space = self._action_spaces[self._checked_agent(agent)]
        if not isinstance(space, spaces.Discrete) or agent == OBSERVER:
            raise ValueError(f"action masks are for the UGVs' switching actions; {agent!r} has {space}")
        return self._action_mask(agent, *self._reference_devices())

    def _action_mask(self, agent: str, references: set[str], settling: set[str]) -> np.ndarray:
        """:meth:`action_mask` of a UGV agent, given :meth:`_reference_devices`."""
        mask = np.ones(self._action_spaces[agent].n, dtype=np.int8)
        t = self.world.time
        check = self.rules.check_mobile
        if agent not in self._mobile:
            mask[1] = check(agent, t, self._mobile, references, self._detections, settling) is None
        sled = self._tows.get(agent)
        if sled is not None and sled not in self._mobile:
            if agent not in self._mobile:
                mask[2] = check(sled, t, self._mobile, references, self._detections, settling) is None
            elif self.rules.dwell_s <= 0.0:  # no dwell: the robot stops, then the sled is judged
                mask[2] = check(sled, t, self._mobile - {agent}, references, self._detections, settling) is None
            else:
                mask[2] = 0
        return mask

    # ------------------------------------------------------------------ state, render
    def state(self) -> np.ndarray:
        """Global truth for centralised critics: device poses, UAV pose, goals."""
        out: list[float] = []
        for device in self._devices:
            x, y, yaw = self._device_pose(device)
            out += [x, y, math.cos(yaw), math.sin(yaw), 0.0 if device in self._mobile else 1.0]
        if self._has_uav:
            s = self.world.uav_state
            out += [s.x, s.y, s.z, math.cos(s.yaw), math.sin(s.yaw), s.roll, s.pitch]
        for ugv in self._ugvs:
            goal = self.scenario.goals.get(ugv)
            out += [0.0, 0.0, 0.0, 0.0] if goal is None else [goal[0], goal[1], math.cos(goal[2]), math.sin(goal[2])]
        return np.asarray(out, dtype=np.float32)

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the frame, (H, W, 3) uint8; ``human``: shows it in a window and returns None."""
        if self.render_mode is None:
            return None
        from moma_env.env.rendering import HumanWindow, render_env

        frame = render_env(self)
        if self.render_mode == "human":
            if self._window is None:
                self._window = HumanWindow(self.metadata["name"], self.metadata["render_fps"])
            self._window.show(frame)
            return None
        return frame

    def close(self) -> None:
        if self._window is not None:
            self._window.close()
            self._window = None
