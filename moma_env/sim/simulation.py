"""The simulation core: one MOMA rig (world, cameras, localiser, motion rules) stepped in time.

A :class:`Simulation` is built from a :class:`~moma_env.scenarios.Scenario` and
the camera backends of its cameras. Each episode starts with :meth:`reset`; a
step is

1. state changes at the current time: :meth:`request` (mobile requests go
   through the paper's motion rules, :mod:`moma_env.sim.rules`; static ones are
   always granted) and :meth:`declare` (an executive's own declarations, e.g. a
   robot that reached the end of its leg);
2. :meth:`advance`: the world moves one control step with the given commands,
   every camera measures the boards it sees, the localiser updates, and a
   :class:`~moma_env.sim.frame.Frame` of the step is returned.

:meth:`step` does both for callers that only send requests and commands. The
PettingZoo env, the paper's experiments and the benchmarks all drive this
class; nothing else wires world, cameras and estimator together.

Frames and units: world frame W (x, y on the floor, z up), metres, radians,
seconds; the localiser's world frame is fixed by the UGVs' initial poses.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from moma_env.camera import BoardView, CameraBackend, MeasureRequest, measure_batch, up_in_board
from moma_env.estimator import MomaEstimator, Phase
from moma_env.geometry import se3_to_se2
from moma_env.scenarios import Scenario
from moma_env.sim.frame import Frame, Pose2D, Switch
from moma_env.sim.localiser import Localiser, LocaliserFactory
from moma_env.sim.rules import MotionRules
from moma_env.world import World

__all__ = ["Commands", "Simulation"]


@dataclass(frozen=True)
class Commands:
    """One step's input to :meth:`Simulation.step`.

    Attributes:
        requests: device -> wants to be mobile (True) or static (False); devices
            left out keep their state. Static requests are handled first.
        velocities: UGV -> body velocity command ``(vx, vy, yaw rate)`` (m/s,
            rad/s); UGVs left out are commanded to stop.
        reels: sled -> reel rate in [-1, 1] (> 0 reels in), set before the physics.
        uav: the observer's command ``(vx, vy, yaw rate, climb rate)`` (m/s,
            rad/s), or UAV name -> such a command with several observers
            (:meth:`moma_env.world.World.step`); None hovers (or without an observer).
    """

    requests: Mapping[str, bool] = field(default_factory=dict)
    velocities: Mapping[str, Any] = field(default_factory=dict)
    reels: Mapping[str, float] = field(default_factory=dict)
    uav: Any = None


class _LineOfSight:
    """Occlusion query of a ground camera (:data:`moma_env.camera.backend.OcclusionQuery`):
    walls, obstacles and robots other than the camera's owner and the device carrying the
    marker (the one nearest the marker, among :attr:`Simulation.device_positions`)."""

    def __init__(self, simulation: Simulation, camera_owner: str):
        self.simulation = simulation
        self.camera_owner = camera_owner

    def __call__(self, p_from: np.ndarray, p_to: np.ndarray) -> bool:
        x, y = float(p_to[0]), float(p_to[1])
        simulation = self.simulation
        # The nearest device by squared distance, the first of equal ones: min() over
        # the positions with that key, in a plain loop (no key function call per device).
        positions = iter(simulation.device_positions)
        nearest, (px, py) = next(positions)
        best = (px - x) ** 2 + (py - y) ** 2
        for device, (px, py) in positions:
            distance = (px - x) ** 2 + (py - y) ** 2
            if distance < best:
                nearest, best = device, distance
        # The floor points as float pairs (the world reads x and y of each).
        return simulation.world.segment_blocked((float(p_from[0]), float(p_from[1])), (x, y), ignore=(self.camera_owner, nearest))


class Simulation:
    """One MOMA rig stepped in time; see the module docstring for a step's phases.

    Args:
        scenario: the layout (world, camera intrinsics, estimator settings, dwell).
        cameras: a backend per camera of the world (the world's camera names).
        localiser: builds an episode's localiser from ``scenario.estimator``
            (default :class:`~moma_env.estimator.MomaEstimator`).
        rules: enforce the motion rules on mobile requests (default). Without
            them every request is granted: for callers whose schedule is the
            authority, such as the paper's experiments.
        planar_ugvs: tell the localiser the UGVs and sleds move upright on the
            floor (``add_robot(planar=...)``).
        measure_at_reset: take a camera frame at time 0 in :meth:`reset` (the
            envs do, so that the first observation holds detections); the
            paper's experiments start with the first step.
        replaces: a simulation this one takes the place of (an env's previous
            layout): the new world shares the old one's record of retired physics
            spaces, so that memory stays flat across layouts (``World(replaces=...)``).
    """

    def __init__(
        self,
        scenario: Scenario,
        cameras: Mapping[str, CameraBackend],
        *,
        localiser: LocaliserFactory = MomaEstimator,
        rules: bool = True,
        planar_ugvs: bool = True,
        measure_at_reset: bool = True,
        replaces: Simulation | None = None,
    ):
        if not isinstance(scenario, Scenario):
            raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
        if not callable(localiser):
            raise TypeError(f"localiser must be a callable EstimatorConfig -> Localiser, got {type(localiser).__name__}")
        self.scenario = scenario
        wc = scenario.world
        if replaces is not None and not isinstance(replaces, Simulation):
            raise TypeError(f"replaces must be a Simulation or None, got {type(replaces).__name__}")
        self.world = World(wc, replaces=None if replaces is None else replaces.world)
        self._ugvs = wc.ugv_names
        sleds = tuple(wc.sleds)
        self._sleds = tuple(s.name for s in sleds)
        self._devices = self._ugvs + self._sleds
        self._is_sled = frozenset(self._sleds)
        #: Per device, in order: (name, the world's planar pose getter of its kind): the one
        #: UGV/sled dispatch of device_pose, chosen once (the per-step reads call the getters).
        self._pose_readers = tuple((d, self.world.sled_pose if d in self._is_sled else self.world.ugv_pose) for d in self._devices)
        self._pose_reader = dict(self._pose_readers)
        boards: list[tuple[str, int, Any]] = []
        for index, ugv in enumerate(wc.ugvs):
            if ugv.board is not None:
                boards.append((ugv.name, index, ugv.board))
        for k, sled in enumerate(sleds):
            boards.append((sled.name, len(wc.ugvs) + k, sled.board))
        self._boards = tuple(boards)
        self._board_owner = {board_id: device for device, board_id, _ in boards}
        board_up = {d.name: up_in_board(d.board_mount) for d in (*wc.ugvs, *sleds)}  # world up in M, from the mounts
        for up in board_up.values():
            up.setflags(write=False)  # shared by every view of the board
        #: Per board, what its views take besides the pose: (device, board id, layout, world up in M).
        self._view_parts = tuple((device, board_id, layout, board_up[device]) for device, board_id, layout in boards)
        camera_owner: dict[str, str] = {}
        for ugv in wc.ugvs:
            for cam in ugv.cameras:
                camera_owner[cam.name] = ugv.name
        for uav in wc.uavs:
            camera_owner[uav.camera_name] = uav.name
        self._camera_owner = camera_owner
        missing = sorted(set(camera_owner) - set(cameras))
        if missing:
            raise ValueError(f"no camera backend for the world's camera(s) {missing}; given {sorted(cameras)}")
        self._cameras = {name: cameras[name] for name in camera_owner}
        # Ground cameras look across the floor: robots and obstacles can hide boards.
        # The UAVs look down over everything.
        uav_cameras = {uav.camera_name for uav in wc.uavs}
        self._occlusions = {name: _LineOfSight(self, owner) for name, owner in camera_owner.items() if name not in uav_cameras}
        #: Per camera, in the order of its requests: (name, backend, occlusion query or None).
        self._camera_parts = tuple((name, camera, self._occlusions.get(name)) for name, camera in self._cameras.items())
        self.rules = MotionRules(self._board_owner, camera_owner, scenario.dwell_s) if rules else None
        self._localiser_factory = localiser
        self._planar_ugvs = bool(planar_ugvs)
        self._measure_at_reset = bool(measure_at_reset)
        self.device_positions: list[tuple[str, tuple[float, float]]] = []
        self._localiser: Localiser | None = None
        self._frame: Frame | None = None
        self._stepping = False  # between the world's move and the localiser's update of a step
        self._localising: Generator | None = None  # the phases move() began, for localise()
        self._references: tuple[frozenset[str], frozenset[str]] | None = None

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a copy (:mod:`copy`, :mod:`pickle`), with the up vectors its board views
        share read-only again (numpy's copies of arrays are writeable)."""
        self.__dict__.update(state)
        for *_, up in self._view_parts:
            up.setflags(write=False)

    # ------------------------------------------------------------------ layout
    @property
    def devices(self) -> tuple[str, ...]:
        """The devices (UGVs, then sleds) in their fixed order."""
        return self._devices

    @property
    def ugvs(self) -> tuple[str, ...]:
        """The UGVs' names."""
        return self._ugvs

    @property
    def sleds(self) -> tuple[str, ...]:
        """The sleds' names."""
        return self._sleds

    @property
    def boards(self) -> tuple[tuple[str, int, Any], ...]:
        """Every board as ``(device, board id, layout)``."""
        return self._boards

    @property
    def camera_owner(self) -> Mapping[str, str]:
        """Camera name -> the robot carrying it (a UAV's name for an observer's camera)."""
        return MappingProxyType(self._camera_owner)

    @property
    def cameras(self) -> Mapping[str, CameraBackend]:
        """The camera backends by camera name (read-only)."""
        return MappingProxyType(self._cameras)

    def board_device(self, board_id: int) -> str:
        """The device (UGV or sled) that carries board ``board_id``; KeyError naming the known ids otherwise."""
        try:
            return self._board_owner[board_id]
        except KeyError:
            raise KeyError(f"unknown board id {board_id!r}; known: {sorted(self._board_owner)}") from None

    # ------------------------------------------------------------------ state
    @property
    def started(self) -> bool:
        """True once :meth:`reset` has been called."""
        return self._frame is not None

    def _require_started(self) -> Frame:
        if self._frame is None:
            raise RuntimeError("the simulation has not been reset; call reset() first")
        return self._frame

    @property
    def frame(self) -> Frame:
        """The latest :class:`Frame` (RuntimeError before :meth:`reset`)."""
        return self._require_started()

    @property
    def localiser(self) -> Localiser:
        """This episode's localiser (RuntimeError before :meth:`reset`)."""
        self._require_started()
        assert self._localiser is not None
        return self._localiser

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self.world.time

    @property
    def mobile(self) -> frozenset[str]:
        """The devices declared mobile now."""
        return self._mobile  # a frozenset, replaced at every switch

    def device_pose(self, device: str) -> Pose2D:
        """True planar pose ``(x, y, yaw)`` of a UGV or sled (m, rad)."""
        return self._pose_reader.get(device, self.world.ugv_pose)(device)  # an unknown name: the world's error

    def device_transform(self, device: str) -> np.ndarray:
        """True 4x4 ``T_w_b`` of a UGV or sled (m)."""
        if device in self._is_sled:
            return self.world.sled_transform(device)
        return self.world.ugv_transform(device)

    def board_views(self) -> list[BoardView]:
        """The boards as the cameras are shown them now: true pose and the mount's up direction."""
        # Views of the world's own poses (new float 4x4 arrays) and of the up vectors checked at
        # construction: made without the constructor's checks (a view per board per frame).
        board_transform = self.world.board_transform
        view = BoardView.trusted
        return [view(board_id, layout, board_transform(device), up) for device, board_id, layout, up in self._view_parts]

    # ------------------------------------------------------------------ reset
    def reset(self, rng: np.random.Generator) -> Frame:
        """Start an episode: every device static at its initial pose, a fresh localiser.

        Args:
            rng: the cameras' generator for the episode (every measurement noise
                draw comes from it).
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy Generator, got {type(rng).__name__}")
        self.world.reset()
        for camera in self._cameras.values():
            forget = getattr(camera, "reset", None)  # a backend with memory across frames (warm-started PnP)
            if forget is not None:
                forget()
        if self.rules is not None:
            self.rules.reset()
        self._rng = rng
        self._mobile: frozenset[str] = frozenset()
        self._last_switch_time = 0.0
        self._steps = 0
        self._switches: list[Switch] = []
        self._localiser = self._new_localiser()
        self._stepping = False
        self._localising = None
        if self._measure_at_reset:
            self._detections = measured(self._camera_requests())
            self._localiser.update(self.world.time, self._detections)
        else:
            self._detections = []
        self._frame = self._snapshot()
        return self._frame

    def _new_localiser(self) -> Localiser:
        localiser = self._localiser_factory(self.scenario.estimator)
        if not isinstance(localiser, Localiser):
            raise TypeError(f"the localiser factory returned {type(localiser).__name__}, which is not a Localiser")
        wc = self.scenario.world
        boards_of: dict[str, dict[int, np.ndarray]] = {}
        for device, board_id, _ in self._boards:
            mount = wc.sled(device).board_mount if device in self._is_sled else wc.ugv(device).board_mount
            boards_of.setdefault(device, {})[board_id] = mount
        t = self.world.time
        for ugv in wc.ugvs:
            localiser.add_robot(
                ugv.name,
                boards=boards_of.get(ugv.name, {}),
                cameras={c.name: c.T_b_c for c in ugv.cameras},
                static=True,
                initial_pose=self.world.ugv_transform(ugv.name),
                time=t,
                planar=self._planar_ugvs,
            )
        for sled in self._sleds:
            localiser.add_robot(
                sled, boards=boards_of.get(sled, {}), static=True, initial_pose=self.world.sled_transform(sled), time=t, planar=self._planar_ugvs
            )
        for uav in wc.uavs:
            localiser.add_robot(uav.name, cameras={uav.camera_name: uav.camera_mount}, static=False, time=t)
        return localiser

    # ------------------------------------------------------------------ state changes
    def reference_devices(self) -> tuple[set[str], set[str]]:
        """Static devices as the rules see them, as of the localiser's last update (new sets):
        those whose pose others may rely on after a switch (frozen references and ready
        switch windows), and those still collecting their window."""
        estimates = self._require_started().estimates
        # Kept until the frame is replaced or a switch is made (the localiser changes only
        # through this simulation's updates and switches); every call returns new sets.
        cached = self._references
        if cached is None:
            window_ready = self._localiser.window_ready
            ready: list[str] = []
            settling: list[str] = []
            for device in self._devices:
                phase = estimates[device].phase
                if phase is Phase.REFERENCE:
                    ready.append(device)
                elif phase is Phase.SETTLING:
                    (ready if window_ready(device) else settling).append(device)
            cached = self._references = (frozenset(ready), frozenset(settling))
        return set(cached[0]), set(cached[1])

    def check_mobile(
        self, device: str, mobile: Iterable[str] | None = None, references: tuple[set[str], set[str]] | None = None
    ) -> str | None:
        """None if ``device`` may become mobile now, else the refusal reason (the rules').

        ``mobile`` replaces the set of mobile devices (to ask "what if"), and
        ``references`` a precomputed :meth:`reference_devices`.
        """
        frame = self._require_started()
        if self.rules is None:
            return None
        ready, settling = references if references is not None else self.reference_devices()
        movers = self._mobile if mobile is None else mobile  # the rules read it into a new set
        return self.rules.check_mobile(device, frame.time, movers, ready, frame.detections, settling)

    def request(self, wants: Mapping[str, bool]) -> list[Switch]:
        """Handle state requests at the current time: static ones first (always granted),
        then mobile ones through the rules, in the mapping's order; requests for the
        state a device has already are ignored. Returns what was granted or refused."""
        frame = self._require_started()
        t = self.world.time
        handled: list[Switch] = []
        for device, want_mobile in wants.items():
            if not want_mobile and device in self._mobile:
                handled.append(self._set_static(device, t))
        # The references as of the last update: making a device static this step
        # only starts its settling, so no device became a reference since.
        references = settling = None
        for device, want_mobile in wants.items():
            if want_mobile and device not in self._mobile:
                reason = None
                if self.rules is not None:
                    if references is None:
                        references, settling = self.reference_devices()
                    reason = self.rules.check_mobile(device, t, self._mobile, references, frame.detections, settling)
                if reason is None:
                    handled.append(self._set_mobile(device, t))
                    if references is not None:
                        references.discard(device)
                else:
                    switch = Switch(device, "refused", reason)
                    self._switches.append(switch)
                    handled.append(switch)
        return handled

    def declare(self, device: str, static: bool) -> Switch | None:
        """An owner's declaration, granted without the rules (e.g. a robot stopping at
        the end of its leg, or a schedule that is the authority); None if ``device``
        is in that state already."""
        self._require_started()
        if device not in self._devices:
            raise KeyError(f"unknown device {device!r}; devices are {self._devices}")
        t = self.world.time
        if static:
            return self._set_static(device, t) if device in self._mobile else None
        return self._set_mobile(device, t) if device not in self._mobile else None

    def set_reel(self, sled: str, rate: float) -> None:
        """Reel rate of a sled's winch in [-1, 1] (> 0 reels in); see ``World.set_reel``."""
        self.world.set_reel(sled, rate)

    def _set_static(self, device: str, t: float) -> Switch:
        self.world.set_static(device, True)
        self._localiser.set_static(device, True, t)
        self._mobile = self._mobile - {device}
        self._references = None
        if device in self._is_sled:
            self.world.set_reel(device, 0.0)
        if self.rules is not None:
            self.rules.note_static(t)
        self._last_switch_time = t
        switch = Switch(device, "static")
        self._switches.append(switch)
        return switch

    def _set_mobile(self, device: str, t: float) -> Switch:
        self.world.set_static(device, False)
        self._localiser.set_static(device, False, t)
        self._mobile = self._mobile | {device}
        self._references = None
        self._last_switch_time = t
        switch = Switch(device, "mobile")
        self._switches.append(switch)
        return switch

    # ------------------------------------------------------------------ time
    def advance(self, velocities: Mapping[str, Any], uav: Any = None) -> Frame:
        """Move the world one control step, measure, update the localiser; the step's :class:`Frame`.

        Args:
            velocities: UGV -> ``(vx, vy, yaw rate)`` body velocity command (m/s, rad/s).
            uav: the observer's ``(vx, vy, yaw rate, climb rate)`` command, UAV name ->
                such a command with several observers, or None.
        """
        return self.localise(measured(self.move(velocities, uav)))

    def phases(self, velocities: Mapping[str, Any], uav: Any = None) -> Generator[tuple[MeasureRequest, ...] | None, Sequence[Any] | None, Frame]:
        """:meth:`advance` as a generator of its phases, for a caller that steps many
        simulations phase by phase (:func:`moma_env.env.parallel.run_phases`).

        Each resumption runs one phase: the world moves one control step (then the
        generator yields None); the camera requests of the new scene are made (it yields
        them: send their detections back, in their order, as :meth:`localise` takes them);
        the localiser updates on them (it yields None); the step's :class:`Frame` is made
        (returned as the generator's value). :meth:`move` and :meth:`localise` are its
        first two and last two phases.
        """
        self._require_started()
        if self._stepping:
            raise RuntimeError("move() called twice; localise() the measured requests first")
        self.world.step(velocities, uav)
        self._steps += 1
        self._stepping = True
        yield None
        detections = yield self._camera_requests()
        self._stepping = False
        self._detections = list(detections)
        self._localiser.update(self.world.time, self._detections)
        yield None
        self._frame = self._snapshot()
        return self._frame

    def move(self, velocities: Mapping[str, Any], uav: Any = None) -> tuple[MeasureRequest, ...]:
        """The first half of :meth:`advance`: the world moves one control step; returns what
        the cameras are asked to measure in the new scene, for :meth:`localise`.

        A caller stepping many simulations measures all their requests at once
        (:func:`moma_env.camera.measure_batch`) and hands each its detections.
        """
        phases = self.phases(velocities, uav)
        next(phases)
        requests = next(phases)
        self._localising = phases
        return requests

    def localise(self, detections: Sequence[Any]) -> Frame:
        """The second half of :meth:`advance`: the localiser updates on ``detections`` (those
        of the requests :meth:`move` returned, in their order); the step's :class:`Frame`."""
        phases = self._localising
        if phases is None:
            raise RuntimeError("localise() without move(): no camera requests are awaiting detections")
        self._localising = None
        phases.send(detections)
        try:
            next(phases)
        except StopIteration as done:
            return done.value
        raise RuntimeError("the simulation's step did not end after the localiser")  # pragma: no cover - three yields

    def step(self, commands: Commands) -> Frame:
        """:meth:`request`, the reels, then :meth:`advance`: one step of a caller without an executive."""
        if not isinstance(commands, Commands):
            raise TypeError(f"commands must be a Commands, got {type(commands).__name__}")
        self.request(commands.requests)
        for sled, rate in commands.reels.items():
            self.set_reel(sled, rate)
        return self.advance(commands.velocities, commands.uav)

    def refresh(self) -> Frame:
        """The latest frame with the localiser's estimates and the declared states re-read,
        after declarations made since it (its switches are kept and the new ones added)."""
        previous = self._require_started()
        frame = self._snapshot(previous.switches)
        self._frame = frame
        return frame

    # ------------------------------------------------------------------ internals
    def _camera_requests(self) -> tuple[MeasureRequest, ...]:
        views = self.board_views()
        if self._occlusions:
            # Device positions for the occlusion queries, once per frame.
            self.device_positions = [(d, pose_of(d)[:2]) for d, pose_of in self._pose_readers]
        world = self.world
        camera_transform, t, rng = world.camera_transform, world.time, self._rng
        return tuple([MeasureRequest(camera, camera_transform(name), views, t, rng, occluded) for name, camera, occluded in self._camera_parts])

    def _snapshot(self, earlier: Sequence[Switch] = ()) -> Frame:
        estimates = self._localiser.estimates()
        self._references = None  # of the frame this one replaces
        truth: dict[str, Pose2D] = {}
        estimated: dict[str, Pose2D | None] = {}
        errors: dict[str, float] = {}
        for device, pose_of in self._pose_readers:  # device_pose of each device
            true_pose = truth[device] = pose_of(device)
            T = estimates[device].T_w_b
            if T is None:
                estimated[device] = None
                errors[device] = math.nan
            else:
                pose = estimated[device] = se3_to_se2(T)  # x, y: T[0, 3], T[1, 3] as floats
                errors[device] = math.hypot(pose[0] - true_pose[0], pose[1] - true_pose[1])
        world = self.world
        t = world.time
        switches = (*earlier, *self._switches)
        self._switches = []
        return Frame(
            time=t,
            steps=self._steps,
            truth=MappingProxyType(truth),
            uavs=MappingProxyType(dict(zip(world.uav_names, world.uav_states))),
            estimates=MappingProxyType(estimates),
            estimated=MappingProxyType(estimated),
            errors=MappingProxyType(errors),
            detections=tuple(self._detections),
            mobile=self._mobile,
            switches=switches,
            contacts=world.collisions_since_last_step,
            ropes=MappingProxyType({s: world.rope_length(s) for s in self._sleds}),
            last_switch_time=self._last_switch_time,
            dwell_remaining=self.rules.dwell_remaining(t) if self.rules is not None else 0.0,
        )


def measured(requests: Sequence[MeasureRequest]) -> list[Any]:
    """The detections of ``requests`` (:func:`~moma_env.camera.measure_batch`), in one list."""
    return [d for frame in measure_batch(requests) for d in frame]
