"""The action modes, as objects chosen by ``EnvConfig.action_mode``.

An action mode says what the UGV agents send and turns it into the
simulation's inputs: state requests, velocity commands and reel rates. The
``switching`` mode is an executive with state of its own (legs, reels, blocked
legs); the ``velocity`` mode passes the agents' commands through. The observer,
when it is an agent, sends a velocity ``Box(-1, 1, (4,))`` in both modes.

A mode is used in this order every step (see :class:`ActionMode`): ``parse``
each agent's action, ``requests`` for the simulation's request phase,
``granted`` with what it granted, ``commands`` (the executive may declare
devices static at the end of their legs), the physics, then ``after_step``.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping
from numbers import Integral
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from moma_env.config import all_finite
from moma_env.control import WaypointFollower, WaypointFollowerConfig
from moma_env.control.route import Route
from moma_env.estimator import Status
from moma_env.geometry import wrap_angle
from moma_env.sim import Frame, Simulation, Switch

__all__ = ["ACTION_MODE_TYPES", "ActionMode", "EventLog", "LEG_POSITION_TOLERANCE_M", "SwitchingActions", "VelocityActions", "action_mode"]

#: How close (m) a switching-mode robot's estimate must come to the end of its leg for the
#: leg's position to count as reached (``EnvConfig.follower_hold_m`` is at least this).
LEG_POSITION_TOLERANCE_M = 0.02
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

#: ``note(device, event)``: record an event of a device for the agent that commands it.
EventLog = Callable[[str, str], None]

_BOX_KINDS = "iuf"  # numpy dtype kinds of real numbers (bool, complex, strings, objects are refused)


def parse_box(agent: str, action: Any, space: spaces.Box) -> list[float]:
    """A Box action as a list of floats clipped to [-1, 1]; ValueError naming ``agent`` and ``space`` otherwise."""

    def refuse(requirement: str, got: str) -> ValueError:
        expected = f"{space.shape[0]} finite real numbers, the space {space}"
        return ValueError(f"action of {agent!r} must {requirement} ({expected}), got {got}")

    try:
        a = np.asarray(action)
    except Exception:  # noqa: BLE001 - whatever numpy refuses, the message says what was expected
        raise refuse("be a sequence of real numbers", repr(action)) from None
    if a.dtype.kind not in _BOX_KINDS:
        raise refuse("be a sequence of real numbers", repr(action))
    if a.shape != space.shape:
        raise refuse(f"have shape {space.shape}", f"shape {a.shape}: {action!r}")
    a = a.astype(np.float64)
    if not all_finite(a):
        raise refuse("be finite", repr(a.tolist()))
    values = a.tolist()
    # Plain floats: a handful of values, where numpy calls cost more than the arithmetic.
    return [-1.0 if v < -1.0 else (1.0 if v > 1.0 else v) for v in values]


def parse_discrete(agent: str, action: Any, space: spaces.Discrete) -> int:
    """A Discrete action as an int; ValueError naming ``agent`` and ``space`` otherwise.

    Integers (Python or numpy, also as a one-element integer array) are accepted;
    bools, floats, strings and everything else are refused.
    """
    value = action
    if type(value) is int and 0 <= value < space.n:  # the common case, checked first
        return value
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "iu":
        value = value.reshape(()).item()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Integral) or not 0 <= int(value) < space.n:
        raise ValueError(f"action of {agent!r} must be an integer in [0, {space.n}) (the space {space}), got {action!r}")
    return int(value)


class ActionMode(ABC):
    """What the UGV agents send, and how it drives the simulation.

    Args:
        tows: robot -> the sled it tows.
        max_speeds: UGV -> ``(max speed m/s, max yaw rate rad/s)``.
    """

    #: The ``EnvConfig.action_mode`` value that selects this mode.
    name: ClassVar[str]

    def __init__(self, tows: Mapping[str, str], max_speeds: Mapping[str, tuple[float, float]]):
        self.tows = dict(tows)
        self.max_speeds = dict(max_speeds)

    @abstractmethod
    def space(self, agent: str) -> spaces.Space:
        """The action space of UGV ``agent``."""

    def parse(self, agent: str, action: Any, space: spaces.Space) -> Any:
        """The validated action of ``agent`` in ``space``; None is the neutral action (hold, or zeros)."""
        if isinstance(space, spaces.Discrete):
            return 0 if action is None else parse_discrete(agent, action, space)
        return [0.0] * space.shape[0] if action is None else parse_box(agent, action, space)

    def reset(self, simulation: Simulation) -> None:
        """Forget the last episode."""

    @abstractmethod
    def requests(self, actions: Mapping[str, Any], mobile: frozenset[str]) -> dict[str, bool]:
        """Device -> wants to be mobile, from the UGV agents' parsed actions."""

    def granted(self, simulation: Simulation, switches: Iterable[Switch]) -> None:
        """What the simulation's request phase granted (or refused) this step."""

    @abstractmethod
    def commands(self, actions: Mapping[str, Any], simulation: Simulation, note: EventLog) -> dict[str, np.ndarray]:
        """UGV -> body velocity command of this step (m/s, rad/s); may set reels and declare devices static."""

    def after_step(self, simulation: Simulation, note: EventLog) -> bool:
        """After the physics and the update; True if it declared a state change (the frame is then refreshed)."""
        return False


class VelocityActions(ActionMode):
    """``velocity``: a UGV sends ``Box(-1, 1, (4,))``: vx, vy (times its max speed), yaw
    rate (times its max yaw rate), and a mobile request (> 0: be mobile, <= 0: be
    static). A robot towing a sled sends two more: the reel rate (> 0 reels in) and
    the sled's mobile request: ``Box(-1, 1, (6,))``."""

    name = "velocity"

    def space(self, agent: str) -> spaces.Space:
        return spaces.Box(-1.0, 1.0, shape=(6 if agent in self.tows else 4,), dtype=np.float32)

    def requests(self, actions: Mapping[str, Any], mobile: frozenset[str]) -> dict[str, bool]:
        wants: dict[str, bool] = {}
        for agent, action in actions.items():
            wants[agent] = bool(action[3] > 0.0)
            sled = self.tows.get(agent)
            if sled is not None:
                wants[sled] = bool(action[5] > 0.0)
        return wants

    def commands(self, actions: Mapping[str, Any], simulation: Simulation, note: EventLog) -> dict[str, np.ndarray]:
        commands: dict[str, np.ndarray] = {}
        mobile = simulation.mobile
        for agent, a in actions.items():
            speed, yaw_rate = self.max_speeds[agent]
            commands[agent] = np.array([a[0] * speed, a[1] * speed, a[2] * yaw_rate])
            sled = self.tows.get(agent)
            if sled is not None and sled in mobile:
                simulation.set_reel(sled, float(a[4]))
        return commands


class SwitchingActions(ActionMode):
    """``switching``: a UGV sends ``Discrete(2)``: 0 hold (be static), 1 advance (be
    mobile and drive the next leg towards its goal with the built-in controller; at
    the leg's end the robot stops and is declared static, event ``leg_done:<robot>``;
    a robot that comes no closer to the leg's end for 1 s, blocked by a static
    robot, an obstacle or a wall, stops there and is declared static, event
    ``leg_blocked:<robot>``). A robot towing a sled has ``Discrete(3)``: 2 holds the
    robot and reels the sled in (sled mobile until the rope is at its minimum or the
    sled is stuck, then static).

    On a scenario with ``routes``, a robot advances along the polyline from its
    start through its via poses to its goal (:class:`~moma_env.control.route.Route`),
    ``leg_length`` metres of arc a leg from where its estimate projects on the
    route, each leg ending with the heading of the segment it ends on; robots on
    one trail so keep their spacing along it.

    With ``commit_legs``, a leg once started runs to its end: ``hold`` (and ``reel``)
    from a robot driving a leg with a localised estimate is ignored, and its mask
    allows only ``advance``; a robot whose estimate is not localised (it waits for
    it) can still be held. The leg still ends early when it is blocked.

    With ``follower_hold_m`` (``EnvConfig.follower_hold_m``, m), a robot whose estimate
    has come within the leg's position tolerance turns in place to the leg's heading
    while its estimate stays within that distance of the leg's end, instead of driving
    back whenever the estimate's noise carries it out of the tolerance
    (:attr:`~moma_env.control.WaypointFollowerConfig.hold_m`); the leg ends when the
    heading is reached with the position so held.

    With ``leg_lengths`` (``EnvConfig.leg_lengths``, K lengths in m), a UGV chooses how
    far each leg goes: ``Discrete(1 + K)``, 0 holds and ``k`` (1 to K) advances a leg of
    ``leg_lengths[k - 1]`` m instead of the scenario's ``leg_length``; a towing robot's
    reel is ``1 + K``. Every advance action of one robot has the same mask (the rules
    do not depend on how far a leg goes); a committed robot's mask allows ``1`` only,
    and any advance action continues its leg. Without it, K is 1 and the one leg is the
    scenario's ``leg_length``.

    The executive owns its state: the legs being driven, the sleds being reeled in,
    and the progress that tells a blocked leg or a stuck sled.
    """

    name = "switching"
    HOLD, ADVANCE, REEL = 0, 1, 2

    def __init__(
        self,
        tows: Mapping[str, str],
        max_speeds: Mapping[str, tuple[float, float]],
        commit_legs: bool = False,
        leg_lengths: tuple[float, ...] | None = None,
        follower_hold_m: float | None = None,
    ):
        super().__init__(tows, max_speeds)
        self.commit_legs = commit_legs
        #: The leg lengths (m) the advance actions ``1..K`` choose from; None: the scenario's ``leg_length``.
        self.leg_lengths = None if leg_lengths is None else tuple(float(x) for x in leg_lengths)
        #: K, how many advance actions a UGV has (1 without ``leg_lengths``).
        self.n_advances = 1 if self.leg_lengths is None else len(self.leg_lengths)
        #: The reel action of a towing robot (2 without ``leg_lengths``).
        self.reel = 1 + self.n_advances
        self._chosen: dict[str, float] = {}  # robot -> leg length (m) of the advance it asked for this step
        self.committed: set[str] = set()  # with commit_legs: robots driving a leg on a localised estimate
        self.follower = WaypointFollower(
            WaypointFollowerConfig(max_speed=0.3, position_tolerance=LEG_POSITION_TOLERANCE_M, yaw_tolerance=0.04, hold_m=follower_hold_m)
        )
        self.legs: dict[str, tuple[float, float, float]] = {}
        self.held: set[str] = set()  # with follower_hold_m: robots whose leg's position was reached
        self.reeling: set[str] = set()
        self._reel_progress: dict[str, tuple[float, float]] = {}  # sled -> (shortest rope m, when s)
        self._leg_progress: dict[str, tuple[float, float, float]] = {}  # robot -> (closest m, rad, when s)
        self._routes: dict[str, Route] = {}  # robot -> its route, if the scenario gives one
        self._route_s: dict[str, float] = {}  # robot -> arc length (m) of its last leg's start on its route
        self._mask_templates: dict[str, dict] = {}  # UGV -> its masks by outcome (see _templates)

    def space(self, agent: str) -> spaces.Space:
        return spaces.Discrete(self.n_actions(agent))

    def n_actions(self, agent: str) -> int:
        """How many actions UGV ``agent`` has: hold, the advances, and reel when it tows a sled."""
        return 1 + self.n_advances + (1 if agent in self.tows else 0)

    def reset(self, simulation: Simulation) -> None:
        self.legs = {}
        self.reeling = set()
        self.committed = set()
        self.held = set()
        self._reel_progress = {}
        self._leg_progress = {}
        scenario = simulation.scenario
        self._routes = {
            ugv.name: Route(ugv.initial_pose, (*scenario.routes[ugv.name], scenario.goals[ugv.name]))
            for ugv in scenario.world.ugvs
            if ugv.name in scenario.routes
        }
        self._route_s = {name: 0.0 for name in self._routes}

    def requests(self, actions: Mapping[str, Any], mobile: frozenset[str]) -> dict[str, bool]:
        wants: dict[str, bool] = {}
        lengths = self.leg_lengths
        if lengths is not None:
            self._chosen = {}  # without leg lengths it stays empty: no allocation per step
        last_advance = self.n_advances
        for agent, action in actions.items():
            advance = 1 <= action <= last_advance
            if not advance and agent in self.committed:
                continue  # the leg runs to its end
            if advance:
                wants[agent] = True
                if lengths is not None:
                    self._chosen[agent] = lengths[action - 1]
            elif agent in mobile:  # hold, or reel (the camera must be static)
                wants[agent] = False
            sled = self.tows.get(agent)
            if sled is not None and action == self.reel and sled not in mobile:
                wants[sled] = True
        return wants

    def granted(self, simulation: Simulation, switches: Iterable[Switch]) -> None:
        t = simulation.time
        for switch in switches:
            if switch.kind == "static":
                self._stopped(switch.device)
            elif switch.kind == "mobile":
                device = switch.device
                if device in simulation.sleds:
                    self.reeling.add(device)
                    self._reel_progress[device] = (math.inf, t)
                    simulation.set_reel(device, 1.0)
                else:
                    length = self._chosen.get(device, simulation.scenario.leg_length)
                    self.legs[device] = self._next_leg(device, simulation, length)
                    self.held.discard(device)
                    self._leg_progress[device] = (math.inf, math.inf, t)

    def _stopped(self, device: str) -> None:
        self.committed.discard(device)
        self.held.discard(device)
        self.legs.pop(device, None)
        self._leg_progress.pop(device, None)
        self.reeling.discard(device)

    def _declare_static(self, device: str, simulation: Simulation) -> None:
        simulation.declare(device, static=True)
        self._stopped(device)

    def _next_leg(self, device: str, simulation: Simulation, length: float) -> tuple[float, float, float]:
        """Target of the next advance: at most ``length`` (m) towards the next via pose
        of the route or the goal, from the estimate."""
        scenario = simulation.scenario
        goal = scenario.goals.get(device)
        pose = simulation.frame.usable_pose(device)
        if pose is None:
            pose = simulation.device_pose(device)  # never used for control: a static device has a frozen estimate
        if goal is None:
            return pose
        x, y, yaw = pose
        route = self._routes.get(device)
        if route is not None:
            s = route.project(x, y, not_before=self._route_s[device] - scenario.leg_length)
            self._route_s[device] = s
            return route.pose_at(s + length)
        dx, dy = goal[0] - x, goal[1] - y
        dist = math.hypot(dx, dy)
        if dist <= length:
            return goal
        f = length / dist
        return (x + f * dx, y + f * dy, yaw)

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

    def commands(self, actions: Mapping[str, Any], simulation: Simulation, note: EventLog) -> dict[str, np.ndarray]:
        commands: dict[str, np.ndarray] = {}
        frame: Frame = simulation.frame
        t = simulation.time
        follower = self.follower
        holds = follower.config.hold_m is not None
        for device, leg in list(self.legs.items()):
            pose = frame.usable_pose(device)
            if pose is None or frame.estimates[device].status is not Status.LOCALISED:
                self.committed.discard(device)  # a robot waiting for its estimate can be held
                commands[device] = np.zeros(3)  # wait where it is until it is localised again
                closest, aligned, _ = self._leg_progress[device]
                self._leg_progress[device] = (closest, aligned, t)  # waiting is not being blocked
                continue
            held = holds and device in self.held
            if follower.reached(pose, leg, held):
                self._declare_static(device, simulation)
                note(device, f"leg_done:{device}")
                commands[device] = np.zeros(3)
            elif self._leg_blocked(device, pose, leg, t):
                self._declare_static(device, simulation)
                note(device, f"leg_blocked:{device}")
                commands[device] = np.zeros(3)
            else:
                if self.commit_legs:
                    self.committed.add(device)
                commands[device] = follower.command(pose, leg, held)
                if holds:
                    if follower.position_reached(pose, leg, held):
                        self.held.add(device)
                    else:
                        self.held.discard(device)
        return commands

    def after_step(self, simulation: Simulation, note: EventLog) -> bool:
        """A reeled sled becomes static once the rope is at its minimum, or when it has
        not shortened for a second (the sled is stuck). True if one did."""
        t = simulation.time
        changed = False
        world = simulation.world
        for sled in list(self.reeling):
            cfg = simulation.scenario.world.sled(sled)
            rope = world.rope_length(sled)
            shortest, since = self._reel_progress.get(sled, (math.inf, t))
            if rope < shortest - 1e-4:
                self._reel_progress[sled] = (rope, t)
                since = t
            stalled = t - since > _REEL_STALL_S
            if rope <= cfg.min_rope + 1e-6 or stalled:
                self._reel_progress.pop(sled, None)
                changed = True
                self._declare_static(sled, simulation)
                note(sled, f"leg_done:{sled}")
        return changed

    def masks(self, agents: Iterable[str], simulation: Simulation) -> dict[str, np.ndarray]:
        """:meth:`mask` of each agent, the localiser's reference set and the mobile devices read once for all."""
        references = simulation.reference_devices()
        mobile = simulation.mobile
        return {agent: self._mask(agent, simulation, references, mobile) for agent in agents}

    def mask(self, agent: str, simulation: Simulation, references: tuple[set[str], set[str]] | None = None) -> np.ndarray:
        """Which actions of UGV ``agent`` the rules would grant at the next step, if it
        were the only change requested (see ``MomaParallelEnv.action_mask``)."""
        if references is None:
            references = simulation.reference_devices()
        return self._mask(agent, simulation, references, simulation.mobile)

    def _mask(self, agent: str, simulation: Simulation, references: tuple[set[str], set[str]], mobile: frozenset[str]) -> np.ndarray:
        """:meth:`mask` given the reference set and the devices mobile now; a new array (a copy of
        the agent's template for the outcome, which is cheaper than building one)."""
        templates = self._mask_templates.get(agent)
        if templates is None:
            templates = self._mask_templates[agent] = self._templates(agent)
        if agent in self.committed:
            return templates[None].copy()  # the leg runs to its end: advance only
        check = simulation.check_mobile
        advance = agent in mobile or check(agent, mobile, references) is None
        reel = True
        sled = self.tows.get(agent)
        if sled is not None and sled not in mobile:
            if agent not in mobile:
                reel = check(sled, mobile, references) is None
            elif simulation.rules is None or simulation.rules.dwell_s <= 0.0:  # no dwell: the robot stops, then the sled is judged
                reel = check(sled, mobile - {agent}, references) is None
            else:
                reel = False
        return templates[advance, reel].copy()

    def _templates(self, agent: str) -> dict[tuple[bool, bool] | None, np.ndarray]:
        """The masks of UGV ``agent``, int8 over its actions: ``(advance granted, reel granted)``
        -> hold 1, every advance action and the reel (when it tows) as granted; ``None`` -> the
        mask of a committed leg (advance only). Not to be handed out: :meth:`_mask` copies them."""
        n = self.n_actions(agent)
        out: dict[tuple[bool, bool] | None, np.ndarray] = {}
        for advance in (False, True):
            for reel in (False, True):
                mask = np.ones(n, dtype=np.int8)
                mask[self.ADVANCE : self.ADVANCE + self.n_advances] = advance
                if agent in self.tows:
                    mask[self.reel] = reel
                out[advance, reel] = mask
        committed = np.zeros(n, dtype=np.int8)
        committed[self.ADVANCE] = 1
        out[None] = committed
        return out


#: ``EnvConfig.action_mode`` -> its class.
ACTION_MODE_TYPES: Mapping[str, type[ActionMode]] = MappingProxyType({cls.name: cls for cls in (VelocityActions, SwitchingActions)})


def action_mode(
    name: str,
    tows: Mapping[str, str],
    max_speeds: Mapping[str, tuple[float, float]],
    commit_legs: bool = False,
    leg_lengths: tuple[float, ...] | None = None,
    follower_hold_m: float | None = None,
) -> ActionMode:
    """The action mode called ``name`` (one of :data:`ACTION_MODE_TYPES`); ``commit_legs``,
    ``leg_lengths`` and ``follower_hold_m`` are :class:`SwitchingActions`'s (switching mode only)."""
    try:
        cls = ACTION_MODE_TYPES[name]
    except KeyError:
        raise ValueError(f"unknown action mode {name!r}; known: {sorted(ACTION_MODE_TYPES)}") from None
    if cls is SwitchingActions:
        return SwitchingActions(tows, max_speeds, commit_legs=commit_legs, leg_lengths=leg_lengths, follower_hold_m=follower_hold_m)
    if commit_legs or leg_lengths is not None or follower_hold_m is not None:
        raise ValueError(f"commit_legs, leg_lengths and follower_hold_m exist only in switching mode, not {name!r}")
    return cls(tows, max_speeds)
