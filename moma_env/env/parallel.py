"""The PettingZoo ParallelEnv of every MOMA configuration: an adapter of the simulation core.

One step: the action mode (:mod:`moma_env.env.actions`) turns the agents'
actions into state requests, which the simulation (:class:`moma_env.sim.Simulation`)
grants or refuses by the paper's motion rules, and into commands; the world
advances one control step, every camera measures the boards it sees, the
localiser updates; the reward (:mod:`moma_env.env.rewards`) and the
observations (:mod:`moma_env.env.observations`) are built from the step's
:class:`~moma_env.sim.Frame`, observations from the estimates only.

Agents: the UGVs (``ugv_0``, ``ugv_1``, ...) and, when they are learning agents,
the observers: the UAV ``observer``, or ``observer_0``, ``observer_1``, ... when
several watch the team (:mod:`moma_env.env.agent_names`). A sled is a device without an agent: the robot that tows it
commands its state and its reel.

Actions (chosen by ``EnvConfig.action_mode``; see :mod:`moma_env.env.actions`):

* ``velocity``: a UGV sends ``Box(-1, 1, (4,))``: body velocities vx, vy (times
  its max speed), yaw rate (times its max yaw rate), and a mobile request (> 0:
  be mobile, <= 0: be static). A robot towing a sled sends two more values: the
  reel rate (> 0 reels in) and the sled's mobile request: ``Box(-1, 1, (6,))``.
  An observer sends ``Box(-1, 1, (4,))``: vx, vy, yaw rate, climb rate (times
  its limits).
* ``switching``: a UGV sends ``Discrete(2)``: 0 hold (be static), 1 advance (be
  mobile and drive the next leg towards its goal with the built-in controller;
  at the leg's end the robot stops and is declared static, event
  ``leg_done:<robot>``; a robot that comes no closer to the leg's end for 1 s,
  blocked by a static robot, an obstacle or a wall, stops there and is declared
  static, event ``leg_blocked:<robot>``). A robot towing a
  sled has ``Discrete(3)``: 2 holds the robot and reels the sled in (sled
  mobile until the rope is at its minimum or the sled is stuck, then static). An observer, if an agent, keeps the velocity
  Box; otherwise its own tracking controller flies it. With ``EnvConfig.action_masks``
  every UGV's ``infos`` carry ``"action_mask"`` (:meth:`MomaParallelEnv.action_mask`).

Seeds follow Gymnasium: ``reset(seed=None)`` or a non-negative integer.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Generator, Iterator, Mapping, Sequence
from numbers import Integral
from types import MappingProxyType
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from moma_env.camera import BoardView
from moma_env.control import BoardTrackingController
from moma_env.env.actions import ActionMode, SwitchingActions, action_mode, parse_box
from moma_env.env.agent_names import OBSERVER, observer_agent_names
from moma_env.env.cameras import build_cameras, floor_for
from moma_env.env.config import EnvConfig, checked_max_cycles
from moma_env.env.info_keys import InfoChoice
from moma_env.env.observations import ObservationLayout, device_table, padded
from moma_env.env.pixels import observation_spaces, observer_observation
from moma_env.env.rewards import TeamReward
from moma_env.estimator import Status
from moma_env.geometry import se3_to_se2
from moma_env.scenarios import Scenario
from moma_env.sim import Frame, Simulation, measured

__all__ = [
    "MEASUREMENT", "MomaParallelEnv", "OBSERVER", "FixedScenario", "PendingStep", "RESET_OPTIONS", "STEP_PHASES",
    "checked_reset_options", "run_phases",
]

#: Status -> its name in infos (``"localised"``, ...): read from a table, not from the enum's ``name`` each time.
_STATUS_NAMES: Mapping[Status, str] = MappingProxyType({status: status.name.lower() for status in Status})

ScenarioFactory = Callable[[np.random.Generator | None], Scenario]


class FixedScenario:
    """The scenario factory of an env without random layouts: the same :class:`Scenario` at every reset."""

    def __init__(self, scenario: Scenario):
        self.scenario = scenario

    def __call__(self, rng: np.random.Generator | None) -> Scenario:
        return self.scenario


def checked_seed(seed: object) -> int | None:
    """``seed`` if it is None or a non-negative integer (Python or numpy; Gymnasium's
    convention), else ValueError naming ``seed``."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, Integral) or seed < 0:
        raise ValueError(f"seed must be None or a non-negative integer (Gymnasium's convention), got {seed!r}")
    return int(seed)


#: The keys :meth:`MomaParallelEnv.reset` takes in ``options``.
RESET_OPTIONS = ("scenario",)


def checked_reset_options(options: object) -> Scenario | None:
    """The scenario ``options`` asks a reset to lay out (``options["scenario"]``), or None
    for a reset that draws its own.

    ``options`` is None or a mapping (TypeError otherwise). Keys other than those of
    :data:`RESET_OPTIONS` are ignored with a warning naming them: PettingZoo's API test
    resets with made-up options and expects them taken, so they cannot be refused, but a
    misspelt option must not pass unseen. An empty mapping, as Gymnasium's vector envs
    pass, asks nothing.
    """
    if options is None:
        return None
    if not isinstance(options, Mapping):
        raise TypeError(f"options must be None or a mapping, got {type(options).__name__}")
    if not options:
        return None
    unknown = [key for key in options if key not in RESET_OPTIONS]
    if unknown:
        warnings.warn(
            f"reset options {', '.join(map(repr, unknown))} are not this env's and are ignored; "
            f"its reset takes {', '.join(map(repr, RESET_OPTIONS))}",
            UserWarning,
            stacklevel=3,
        )
    scenario = options.get("scenario")
    if scenario is not None and not isinstance(scenario, Scenario):
        raise TypeError(f"options['scenario'] must be a Scenario (e.g. a configuration's .scenario()), got {type(scenario).__name__}")
    return scenario


class PendingStep:
    """An env step run in phases (:meth:`MomaParallelEnv.begin_step`), so that a batch can run
    each phase for every copy before the next phase (:func:`run_phases`).

    The phases, in order (:data:`STEP_PHASES`): the actions checked and applied with the
    state requests (run by ``begin_step``); the robots' commands; the observers' commands;
    the world's control step; the camera requests of the new scene (then the step awaits
    their detections); the localiser's update; the step's frame; the rewards; the
    observations; the infos. Every step of an env has the same phases.

    Attributes:
        camera_requests: what the cameras are asked to measure in the moved scene
            (:class:`~moma_env.camera.MeasureRequest`), in the order of their detections;
            None until the step reaches its cameras.
        result: ``(observations, rewards, terminations, truncations, infos)`` once the step
            has finished, else None.
    """

    __slots__ = ("camera_requests", "result", "_phases", "_detections", "_state")

    def __init__(self, phases: Generator):
        self.camera_requests: tuple | None = None
        self.result: tuple[dict, dict, dict, dict, dict] | None = None
        self._phases = phases
        self._detections: Sequence[Any] | None = None
        self._state = _RUNNING

    def advance(self) -> bool:
        """Run the step's next phase. True if another phase can run now; False once the step
        awaits the detections of its :attr:`camera_requests` (:meth:`detected`) or has
        finished (:attr:`result`)."""
        state = self._state
        if state is not _RUNNING:
            raise RuntimeError(
                "this step is finished already" if state is _DONE
                else "the step awaits the detections of its camera requests; pass them to detected() first"
            )
        detections, self._detections = self._detections, None
        try:
            value = self._phases.send(detections)  # None except in the phase after the cameras
        except StopIteration as done:
            self._state = _DONE
            self.result = done.value
            return False
        except BaseException:
            self._state = _DONE
            raise
        if value is not None:
            self.camera_requests = value
            self._state = _AWAITING
            return False
        return True

    def detected(self, detections: Sequence[Any]) -> None:
        """Hand the step the detections of its :attr:`camera_requests` (all of them, in order,
        in one sequence); the next :meth:`advance` runs the localiser on them."""
        if self._state is not _AWAITING:
            raise RuntimeError(
                "this step is finished already" if self._state is _DONE
                else "the step has not reached its cameras; run its phases first (to_cameras())"
            )
        self._detections = detections
        self._state = _RUNNING

    def to_cameras(self) -> tuple:
        """Run the phases up to the cameras; the :attr:`camera_requests`. (:meth:`advance`
        until it returns False, in one loop: the single env's step.)"""
        state = self._state
        if state is _AWAITING:
            return self.camera_requests
        if state is _DONE:
            raise RuntimeError("this step is finished already")
        phases = self._phases
        self._state = _DONE  # until the cameras are reached (an error ends the step)
        requests = None
        try:
            while requests is None:
                requests = next(phases)  # the step's phases before the cameras yield None
        except StopIteration:  # pragma: no cover - every step has cameras
            raise RuntimeError("the env's step ended before its cameras") from None
        self.camera_requests = requests
        self._state = _AWAITING
        return requests

    def finish(self, detections: Sequence[Any]) -> tuple[dict, dict, dict, dict, dict]:
        """The step's ``(observations, rewards, terminations, truncations, infos)`` given the
        detections of :attr:`camera_requests` (all of them, in order, in one sequence): the
        phases after the cameras, run to the end (:meth:`detected`, then :meth:`advance`
        until it returns False, in one loop)."""
        if self._state is not _AWAITING:
            self.detected(detections)  # raises the state's error
        phases = self._phases
        self._state = _DONE
        try:
            phases.send(detections)
            while True:
                next(phases)
        except StopIteration as done:
            self.result = done.value
        return self.result


#: The states of a :class:`PendingStep`.
_RUNNING, _AWAITING, _DONE = "running", "awaiting detections", "done"

#: The phases of an env's step, in order (:class:`PendingStep`); the first is run by
#: :meth:`MomaParallelEnv.begin_step`, the fifth ends with the camera requests.
STEP_PHASES = (
    "actions", "commands", "observer commands", "physics", "camera requests",
    "localiser", "frame", "rewards", "observations", "infos",
)
#: The key of the cameras' measurement in :func:`run_phases`'s ``seconds``.
MEASUREMENT = "camera measurement"


def run_phases(
    steps: Sequence[PendingStep],
    measure: Callable[[list[tuple]], Sequence[Sequence[Any]]],
    seconds: dict[str, float] | None = None,
) -> list[tuple]:
    """Finish ``steps`` (begun by :meth:`MomaParallelEnv.begin_step`, one per env) phase by
    phase: every step runs a phase before any runs the next, and the camera requests of all
    of them are measured together, ``measure(requests)`` -> each step's detections.

    Each env runs the same code on its own state as in its own :meth:`~MomaParallelEnv.step`
    (envs share nothing), so the results are those of stepping the envs one after the other,
    bit for bit. Running a phase for every env in turn keeps that phase's code and data in
    the processor's caches, which running each env's whole step in turn does not
    (docs/vector.md measures it). Returns each step's :attr:`PendingStep.result`, in order.

    ``seconds``: if given, the wall time of each phase after the first (for all the steps,
    keys of :data:`STEP_PHASES`) and of the measurement (:data:`MEASUREMENT`) is added to it.
    """
    if seconds is None and len(steps) == 1:  # the same order of phases, run in PendingStep's own loops
        step = steps[0]
        (found,) = measure([step.to_cameras()])
        return [step.finish(found)]
    phases = iter(STEP_PHASES[1:])
    _advance_all(steps, phases, seconds)
    start = time.perf_counter() if seconds is not None else 0.0
    detections = measure([step.camera_requests for step in steps])
    if seconds is not None:
        _add(seconds, MEASUREMENT, time.perf_counter() - start)
    for step, found in zip(steps, detections, strict=True):
        step.detected(found)
    _advance_all(steps, phases, seconds)
    return [step.result for step in steps]


def _advance_all(steps: Sequence[PendingStep], phases: Iterator[str], seconds: dict[str, float] | None) -> None:
    """Run every step's phases, each phase for every step before the next, until each awaits
    its detections or has finished; with ``seconds``, each phase's time under its name, the
    next of ``phases``."""
    running = list(steps)
    while running:
        start = time.perf_counter() if seconds is not None else 0.0
        running = [step for step in running if step.advance()]
        if seconds is not None:
            _add(seconds, next(phases), time.perf_counter() - start)


def _add(seconds: dict[str, float], key: str, value: float) -> None:
    seconds[key] = seconds.get(key, 0.0) + value


class MomaParallelEnv(ParallelEnv):
    """MOMA multi-robot localisation as a PettingZoo parallel environment.

    Args:
        scenario: a :class:`Scenario`, or a factory ``f(rng) -> Scenario`` called
            at every reset (random scenarios); every scenario it returns must
            have the same robots. A factory must be picklable for the env to be
            (a class instance, not a local function).
        config: action mode, observer agent, rewards, episode length.
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        name: the environment's name in ``metadata``.

    The simulation core is :attr:`simulation`; its latest snapshot is :attr:`frame`.
    The env can be copied (``copy.deepcopy``) and pickled at any time; a copy
    continues bit for bit like the original.
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
        #: The cameras' measurement of a step: camera requests -> detections (:func:`moma_env.sim.measured`);
        #: an instance attribute, so a benchmark can time it by wrapping it.
        self.measure: Callable[[Sequence[Any]], list[Any]] = measured
        if isinstance(scenario, Scenario):
            self._factory: ScenarioFactory = FixedScenario(scenario)
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
        self._max_cycles_set: int | None = None
        self._floor = None
        self._setup(first)
        self._np_random = np.random.default_rng()
        self._seeded = False
        self._window = None
        self._info_choice: InfoChoice | None = None  # EnvConfig.info_keys worked out (_infos)

    # ------------------------------------------------------------------ set-up
    @staticmethod
    def _robots_signature(s: Scenario) -> tuple:
        sleds = tuple((sled.name, sled.robot) for sled in s.world.sleds)
        return (s.world.ugv_names, sleds, s.world.uav_names, tuple(sorted(s.goals)))

    def _check_given_scenario(self, scenario: Scenario) -> None:
        """ValueError naming ``options['scenario']`` if it is not of this env's configuration
        or has other robots (its agents and spaces would not be this env's)."""
        if scenario.name != self.scenario.name:
            raise ValueError(
                f"options['scenario']: a {scenario.name!r} scenario; this env lays out {self.scenario.name!r} scenarios"
            )
        if self._robots_signature(scenario) != self._signature:
            ugvs, sleds, uavs, goals = self._robots_signature(scenario)
            want_ugvs, want_sleds, want_uavs, want_goals = self._signature
            raise ValueError(
                "options['scenario']: its robots must be this env's: "
                f"UGVs {list(ugvs)}, sleds {list(sleds)}, UAVs {list(uavs)}, goals of {list(goals)}; "
                f"this env's: UGVs {list(want_ugvs)}, sleds {list(want_sleds)}, UAVs {list(want_uavs)}, goals of {list(want_goals)}"
            )

    def _setup(self, scenario: Scenario) -> None:
        """Build the episode's simulation, action mode, observation layout and spaces."""
        self.scenario = scenario
        wc = scenario.world
        self._ugvs = wc.ugv_names
        self._tows = {s.robot: s.name for s in wc.sleds}
        #: Towing robot -> (its sled, the sled's maximum rope length (m)), for the rope feature.
        self._max_ropes = {robot: (sled, wc.sled(sled).max_rope) for robot, sled in self._tows.items()}
        self._towed_by: dict[str, str] = {}  # sled -> the robot towing it (the first, if several)
        for robot, sled in self._tows.items():
            self._towed_by.setdefault(sled, robot)
        self._uavs = wc.uavs
        agents = list(self._ugvs)
        # Observer agent -> its UAV, and the UAV's name -> its agent (empty when the trackers fly them).
        self._observers = dict(zip(observer_agent_names(len(wc.uavs)), wc.uavs)) if self.config.observer_is_agent else {}
        self._observer_of = {uav.name: agent for agent, uav in self._observers.items()}
        agents += self._observers
        self.possible_agents = agents
        self.agents = []

        camera_names = [c.name for u in wc.ugvs for c in u.cameras] + [uav.camera_name for uav in wc.uavs]
        self._floor = floor_for(self.config, wc.arena.bounds, self._floor)
        cameras = build_cameras(camera_names, scenario.camera, self.config, self._floor)
        localiser = {} if self.config.localiser is None else {"localiser": self.config.localiser_factory}
        self.simulation = Simulation(scenario, cameras, replaces=getattr(self, "simulation", None), **localiser)
        self._mode: ActionMode = action_mode(
            self.config.action_mode,
            self._tows,
            {u.name: (u.max_speed, u.max_yaw_rate) for u in wc.ugvs},
            commit_legs=self.config.commit_legs,
            leg_lengths=self.config.leg_lengths,
            follower_hold_m=self.config.follower_hold_m,
        )
        self._reward = TeamReward(scenario, self._ugvs, self.config.rewards)
        self._max_cycles = self._max_cycles_set or self.config.max_cycles or scenario.max_cycles

        xmin, ymin, xmax, ymax = wc.arena.bounds
        centre = ((xmin + xmax) / 2.0, (ymin + ymax) / 2.0)
        half_diag = 0.5 * math.hypot(xmax - xmin, ymax - ymin)
        devices = self.simulation.devices
        self.layout = ObservationLayout(
            devices, self._ugvs, self._tows, tuple(self._observers), centre, half_diag, scenario.dwell_s, self.config.switch_horizon_s,
            goals=scenario.goals, previous=getattr(self, "layout", None),
        )
        if not hasattr(self, "_action_spaces"):
            # The spaces are made once: every scenario of the env has the same robots, and a
            # space object (with its sampling generator) stays the same across resets.
            vector_spaces = self.layout.spaces
            self._pad = None
            if self.config.pad_observations:
                # One Box for every agent: zeros appended, bounds the union of the agents'.
                self._pad = max(space.shape[0] for space in vector_spaces.values())
                grown = [padded(space, self._pad) for space in vector_spaces.values()]
                low = np.minimum.reduce([space.low for space in grown])
                high = np.maximum.reduce([space.high for space in grown])
                vector_spaces = {a: spaces.Box(low=low, high=high, dtype=np.float32) for a in vector_spaces}
            self._observation_spaces = observation_spaces(vector_spaces, tuple(self._observers), self.config.observer_image)
            self._action_spaces = {a: self._make_action_space(a) for a in self.possible_agents}
        image_size = (scenario.camera.width, scenario.camera.height)
        self._trackers = {uav.name: BoardTrackingController(uav.camera_mount[:3, :3], scenario.camera.fx, image_size, self.config.tracking)
                           for uav in wc.uavs}
        n_state = 5 * len(devices) + 7 * len(wc.uavs) + 4 * len(self._ugvs)
        if getattr(self, "state_space", None) is None or self.state_space.shape != (n_state,):
            self.state_space = spaces.Box(-np.inf, np.inf, shape=(n_state,), dtype=np.float32)

    def _make_action_space(self, agent: str) -> spaces.Space:
        if agent in self._observers:
            return spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        return self._mode.space(agent)

    @property
    def max_cycles(self) -> int:
        """Episode length in steps (truncation). Setting it overrides the configuration's
        and the scenarios' (random layouts included) from the next step on."""
        return self._max_cycles

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        self._max_cycles = self._max_cycles_set = checked_max_cycles("max_cycles", value)

    # ------------------------------------------------------------------ read-only views
    @property
    def world(self):
        """The simulation's :class:`~moma_env.world.World` (truth; for readers, not for agents)."""
        return self.simulation.world

    @property
    def estimator(self):
        """This episode's localiser (the MOMA estimator by default)."""
        return self.simulation.localiser

    @property
    def frame(self) -> Frame:
        """The latest :class:`~moma_env.sim.Frame` (RuntimeError before ``reset``)."""
        return self.simulation.frame

    @property
    def action_mode(self) -> ActionMode:
        """The action mode object (``EnvConfig.action_mode``)."""
        return self._mode

    @property
    def observer_agents(self) -> tuple[str, ...]:
        """The observers among ``possible_agents`` (none when their trackers fly them)."""
        return tuple(self._observers)

    @property
    def devices(self) -> tuple[str, ...]:
        """The devices (UGVs, then sleds) in their fixed order."""
        return self.simulation.devices

    @property
    def sleds(self) -> tuple[str, ...]:
        """The sleds among the devices."""
        return self.simulation.sleds

    @property
    def boards(self) -> tuple[tuple[str, int, Any], ...]:
        """Every board as ``(device, board id, layout)``."""
        return self.simulation.boards

    @property
    def cameras(self) -> Mapping[str, Any]:
        """The camera backends by camera name (world camera names; read-only)."""
        return self.simulation.cameras

    @property
    def steps(self) -> int:
        """Steps since the last ``reset``."""
        return self._require_reset().steps

    @property
    def mobile_devices(self) -> frozenset[str]:
        """The devices declared mobile now."""
        return self.simulation.mobile

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
        return self.simulation.board_views()

    @property
    def detections(self) -> tuple:
        """The latest camera frame: every camera's ``Detection``s of the last ``reset``
        or ``step`` (camera ids are the world's camera names)."""
        return self._require_reset().detections

    def board_device(self, board_id: int) -> str:
        """The device (UGV or sled) that carries board ``board_id``; KeyError naming the known ids otherwise."""
        return self.simulation.board_device(board_id)

    def localisation_error(self, device: str) -> float:
        """Planar position error (m) of a device's estimate, NaN without one (as of the last ``reset`` or ``step``)."""
        return self._require_reset().errors[device]

    def _require_reset(self) -> Frame:
        if not self.simulation.started:
            raise RuntimeError(f"{self.metadata['name']}: call reset() before using the environment")
        return self.simulation.frame

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: str) -> spaces.Space:
        return self._observation_spaces[self._checked_agent(agent)]

    def action_space(self, agent: str) -> spaces.Space:
        return self._action_spaces[self._checked_agent(agent)]

    def _checked_agent(self, agent: str) -> str:
        if agent not in self.possible_agents:
            raise KeyError(f"unknown agent {agent!r}; agents are {self.possible_agents}")
        return agent

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """Start an episode; ``seed`` (None or a non-negative integer) reseeds the env.

        ``options`` (None or a mapping): ``{"scenario": s}`` lays out the
        :class:`~moma_env.scenarios.Scenario` ``s`` (of this env's configuration, with
        its robots and goals' robots, e.g. ``TopObserverConfig(...).scenario()``)
        instead of drawing one; the cameras' noise still comes from the seed, and the
        env's generator advances as in any reset, so the resets after it are the same
        either way. Other keys are ignored with a warning (:func:`checked_reset_options`).
        """
        seed = checked_seed(seed)
        given = checked_reset_options(options)
        if given is not None:
            self._check_given_scenario(given)
        if seed is not None:
            self._np_random = np.random.default_rng(seed)
            self._seeded = True
        rng_scenario, rng_camera = self._np_random.spawn(2)
        scenario = self._factory(rng_scenario) if given is None else given
        if given is None and self._robots_signature(scenario) != self._signature:
            raise ValueError("the scenario factory changed the set of robots between resets; agents must stay fixed")
        if scenario is not self.scenario:
            self._setup(scenario)
        self.agents = list(self.possible_agents)
        self._refused_total = 0
        self._switches_total = 0
        frame = self.simulation.reset(rng_camera)
        self._mode.reset(self.simulation)
        self._reward.reset(frame)
        observations = self._observations(frame)
        infos = self._infos(frame, {}, {})
        return observations, infos

    # ------------------------------------------------------------------ step
    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        pending = self.begin_step(actions)
        return pending.finish(self.measure(pending.to_cameras()))

    def begin_step(self, actions: Mapping[str, Any]) -> PendingStep:
        """:meth:`step` in phases: the actions are checked and applied (the first phase, run
        now: a bad action raises here); the returned :class:`PendingStep` runs the others.
        ``step(a)`` is ``p = begin_step(a)``, ``p.finish(<p.to_cameras() measured>)``; a vector
        env runs each phase of every copy's step before the next (:func:`run_phases`) and
        measures the camera requests of all its copies in one batch."""
        pending = PendingStep(self._stages(actions))
        pending.advance()
        return pending

    def _stages(self, actions: Mapping[str, Any]) -> Generator[tuple | None, Sequence[Any] | None, tuple[dict, dict, dict, dict, dict]]:
        """The step's phases (:class:`PendingStep`): yields None at the end of each, and the camera
        requests at the end of the fifth (send their detections back); returns the step's result."""
        agents = self.agents  # the step's agents (the list is replaced, not changed, when the episode ends)
        if not agents:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        if not isinstance(actions, Mapping):
            raise TypeError(f"actions must be a mapping agent -> action, got {type(actions).__name__}")
        for agent in actions:
            if agent not in agents:
                if agent in self.possible_agents:
                    raise ValueError(f"action for finished agent {agent!r}")
                raise KeyError(f"action for unknown agent {agent!r}; agents are {agents}")
        mode = self._mode
        sim = self.simulation
        observers = self._observers
        action_spaces = self._action_spaces
        parse, get = mode.parse, actions.get
        parsed = {a: parse(a, get(a), action_spaces[a]) for a in agents if a not in observers}
        observer_actions = {
            a: [0.0] * 4 if get(a) is None else parse_box(a, actions[a], action_spaces[a]) for a in agents if a in observers
        } if observers else {}
        events: dict[str, list[str]] = {a: [] for a in agents}
        towed_by = self._towed_by

        def note(device: str, event: str) -> None:
            agent = towed_by.get(device, device)
            if agent in events:
                events[agent].append(event)

        # 1. State requests: static first (always granted), then mobile (rules).
        n_switch = n_refused = 0
        switches = sim.request(mode.requests(parsed, sim.mobile))
        for switch in switches:
            if switch.kind == "refused":
                n_refused += 1
                note(switch.device, f"refused:{switch.device}:{switch.reason}")
            else:
                n_switch += 1
                note(switch.device, f"{switch.kind}:{switch.device}")
        mode.granted(sim, switches)
        yield None  # the phases of PendingStep's docstring; each ``yield None`` ends one

        # 2. Commands, 3. physics, cameras, localiser.
        velocities = mode.commands(parsed, sim, note)
        yield None
        uav_command = self._uav_command(observer_actions)
        yield None
        frame = yield from sim.phases(velocities, uav_command)  # yields the camera requests
        if mode.after_step(sim, note):
            frame = sim.refresh()
        yield None

        # 4. Rewards, terminations, observations.
        reward = self._reward.step(frame, n_switch, n_refused)
        for device in reward.newly_reached:
            note(device, f"goal:{device}")
        self._switches_total += n_switch
        self._refused_total += n_refused
        done = self._reward.done
        truncate = frame.steps >= self._max_cycles
        yield None
        observations = self._observations(frame)
        yield None
        rewards = dict.fromkeys(agents, reward.total)
        terminations = dict.fromkeys(agents, done)
        truncations = dict.fromkeys(agents, truncate and not done)
        infos = self._infos(frame, events, reward.terms, reward.collisions)
        if done or truncate:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def _uav_command(self, observer_actions: Mapping[str, list[float]]) -> dict[str, np.ndarray] | None:
        """UAV name -> its command: its agent's action scaled to its limits, else its tracker's
        command from its camera's last detections (None without a UAV)."""
        if not self._uavs:
            return None
        commands = {}
        detections = None
        for uav in self._uavs:
            agent = self._observer_of.get(uav.name)
            a = None if agent is None else observer_actions.get(agent)
            if a is not None:
                commands[uav.name] = np.array([a[0] * uav.max_speed, a[1] * uav.max_speed, a[2] * uav.max_yaw_rate, a[3] * uav.max_climb])
            else:
                if detections is None:
                    detections = self.simulation.frame.detections
                camera = uav.camera_name
                positions = [d.T_c_m[:3, 3].tolist() for d in detections if d.camera_id == camera]
                commands[uav.name] = self._trackers[uav.name].command(positions)
        return commands

    # ------------------------------------------------------------------ observations
    def _observations(self, frame: Frame) -> dict[str, np.ndarray]:
        if not self.agents:
            return {}
        sim = self.simulation
        table = device_table(frame, self.layout.devices, sim.board_device, sim.camera_owner, self.scenario.estimator.lost_after_s)
        since = frame.time - frame.last_switch_time
        dwell_left = frame.dwell_remaining
        observers = self._observers
        frame_ropes = frame.ropes
        ropes = {agent: frame_ropes[sled] / max_rope for agent, (sled, max_rope) in self._max_ropes.items()}
        obs = self.layout.ugvs(table, since, dwell_left, ropes)  # in UGV order, as the agents are (a new dict)
        for agent, uav in observers.items():
            if agent in self.agents:
                e = frame.estimates[uav.name]
                pose = None if e.T_w_b is None or e.status is Status.LOST else se3_to_se2(e.T_w_b)
                altitude = None if pose is None else float(e.T_w_b[2, 3])
                in_cam = {sim.board_device(d.board_id): d.T_c_m[:3, 3] for d in frame.detections if d.camera_id == uav.camera_name}
                std = (e.position_std_m, e.heading_std_rad)
                obs[agent] = self.layout.observer(agent, pose, altitude, e.status, std, in_cam, since, dwell_left)
        if self._pad is not None:
            obs = {a: padded(o, self._pad) for a, o in obs.items()}
        if self.config.observer_image is not None:
            for agent, uav in observers.items():
                if agent in obs:
                    image = sim.cameras[uav.camera_name].last_image
                    obs[agent] = observer_observation(obs[agent], image, self.config.observer_image)
        return obs

    def _observer_info(self, frame: Frame, uav: Any, events: list[str], terms: dict[str, float]) -> dict:
        """The info of the observer agent flying ``uav`` (its UAV's configuration)."""
        s = frame.uavs[uav.name]
        e = frame.estimates[uav.name]
        if e.T_w_b is None:
            err = None
        else:
            d = e.T_w_b[:3, 3] - np.array([s.x, s.y, s.z])
            err = math.sqrt(d.dot(d))  # what np.linalg.norm computes for a vector
        return {
            "truth": (s.x, s.y, s.yaw, s.z),
            "status": _STATUS_NAMES[e.status],
            "covariance": e.covariance,
            "localisation_error": err,
            "events": events,
            "reward_terms": terms,
        }

    def _infos(self, frame: Frame, events: Mapping[str, list[str]], terms: Mapping[str, float], collisions: int = 0) -> dict[str, dict]:
        """Every agent's info (``events`` by agent, none if left out; ``terms``: the step's
        weighted reward terms, none at reset), with the UGVs' action masks when
        ``EnvConfig.action_masks`` is on; only the keys of ``EnvConfig.info_keys`` when it
        chooses some (:meth:`_chosen_infos`)."""
        chosen = self.config.info_keys
        observers = self._observers
        infos: dict[str, dict] = {}
        if chosen is None:
            for agent in self.agents:
                agent_events = events.get(agent, [])
                uav = observers.get(agent)
                if uav is not None:
                    infos[agent] = self._observer_info(frame, uav, agent_events, dict(terms))
                else:
                    infos[agent] = self._ugv_info(frame, agent, agent_events, terms, collisions)
            masks_wanted = True
        else:
            choice = self._info_choice
            if choice is None or choice.keys is not chosen:  # worked out once per choice
                choice = self._info_choice = InfoChoice.of(chosen)
            infos = self._chosen_infos(frame, events, terms, collisions, choice)
            masks_wanted = choice.masks
        if masks_wanted and self.config.action_masks:
            masks = self.action_masks()
            for agent in self.agents:
                if agent not in observers:
                    infos[agent]["action_mask"] = masks[agent]
        return infos

    def _ugv_info(self, frame: Frame, agent: str, events: list[str], terms: Mapping[str, float], collisions: int) -> dict:
        """The info of UGV ``agent`` but its action mask (:data:`~moma_env.env.info_keys.UGV_INFO_KEYS`)."""
        e = frame.estimates[agent]
        info = {
            "truth": frame.truth[agent],
            "estimate": frame.estimated[agent],
            "covariance": e.covariance,
            "localisation_error": frame.error(agent),
            "status": _STATUS_NAMES[e.status],
            "static": agent not in frame.mobile,
            "events": events,
            "refused": [ev.split(":", 2)[2] for ev in events if ev.startswith("refused:")] if events else [],
            "reached_goal": agent in self._reward.reached,
            "collisions": collisions,
            "switches_total": self._switches_total,
            "reward_terms": dict(terms),
        }
        sled = self._tows.get(agent)
        if sled is not None:
            info["sled_truth"] = frame.truth[sled]
            info["sled_localisation_error"] = frame.error(sled)
        return info

    def _chosen_infos(
        self, frame: Frame, events: Mapping[str, list[str]], terms: Mapping[str, float], collisions: int, choice: InfoChoice
    ) -> dict[str, dict]:
        """Every agent's info but its action mask, with only the keys of ``choice``
        (``EnvConfig.info_keys``) that the agent has, in their usual order; what no chosen
        key needs is not built (a UGV's whole info only for a key other than ``"static"``
        and ``"action_mask"``)."""
        observers = self._observers
        observer_keys, keep = choice.observer_keys, choice.keep
        mobile = frame.mobile
        infos: dict[str, dict] = {}
        for agent in self.agents:
            uav = observers.get(agent)
            if uav is not None:
                if observer_keys:
                    info = self._observer_info(frame, uav, events.get(agent, []), dict(terms))
                    infos[agent] = {key: info[key] for key in observer_keys}
                else:
                    infos[agent] = {}
            elif choice.whole_ugv:
                info = self._ugv_info(frame, agent, events.get(agent, []), terms, collisions)
                infos[agent] = {key: value for key, value in info.items() if key in keep}
            else:
                infos[agent] = {"static": agent not in mobile} if choice.static else {}
        return infos

    # ------------------------------------------------------------------ masks
    def _switching(self) -> SwitchingActions:
        if not isinstance(self._mode, SwitchingActions):
            raise ValueError(f"action masks are for the switching mode's actions; this env is in {self.config.action_mode!r} mode")
        self._require_reset()
        return self._mode

    def action_masks(self) -> dict[str, np.ndarray]:
        """:meth:`action_mask` of every UGV agent of ``possible_agents`` (switching mode),
        the localiser's reference set read once for all of them."""
        return self._switching().masks(self._ugvs, self.simulation)

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
        if not isinstance(space, spaces.Discrete) or agent in self._observers:
            raise ValueError(f"action masks are for the UGVs' switching actions; {agent!r} has {space}")
        return self._switching().mask(agent, self.simulation)

    # ------------------------------------------------------------------ state, render
    def state(self) -> np.ndarray:
        """Global truth for centralised critics: device poses, the UAVs' poses, goals."""
        frame = self._require_reset()
        out: list[float] = []
        for device in self.simulation.devices:
            x, y, yaw = frame.truth[device]
            out += [x, y, math.cos(yaw), math.sin(yaw), 0.0 if device in frame.mobile else 1.0]
        for s in frame.uavs.values():
            out += [s.x, s.y, s.z, math.cos(s.yaw), math.sin(s.yaw), s.roll, s.pitch]
        for ugv in self._ugvs:
            goal = self.scenario.goals.get(ugv)
            out += [0.0, 0.0, 0.0, 0.0] if goal is None else [goal[0], goal[1], math.cos(goal[2]), math.sin(goal[2])]
        return np.asarray(out, dtype=np.float32)

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the frame, (H, W, 3) uint8; ``human``: shows it in a window and returns None."""
        if self.render_mode is None:
            return None
        self._require_reset()
        from moma_env.env.rendering import HumanWindow, render_simulation

        lines = (
            f"step {self.steps}",
            f"mobile: {', '.join(sorted(self.mobile_devices)) or '-'}",
            f"switches {self._switches_total}  refused {self._refused_total}",
        )
        frame = render_simulation(self.simulation, lines)
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

    # ------------------------------------------------------------------ copy, pickle
    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_window"] = None  # a window belongs to the process that opened it
        return state
