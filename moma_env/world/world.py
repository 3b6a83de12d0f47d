"""The simulated world: ground robots, sleds and walls in pymunk, the UAVs' 2.5D states.

This is the ground truth. The camera model and the estimator sit on top of it and
are not imported here. Frames follow ``moma_env.geometry``: world W (z up),
robot body B (x forward, y left, origin on the floor at the robot's centre),
sled frame S (x towards the sled's front, origin at its footprint's centre),
board M, camera C (OpenCV). Units: metres, seconds, radians.

A *device* is anything that can be static or mobile: a robot or a sled.
``set_static``, ``is_static`` and ``board_transform`` take either kind of name;
a sled's rope and pulley are described in ``moma_env.world.sled``.

One :meth:`World.step` advances ``1/control_hz`` s with ``substeps`` pymunk
steps. Everything is deterministic: the same configuration and the same
commands give bit-identical trajectories.

Copies: ``copy.deepcopy(world)`` and ``pickle.loads(pickle.dumps(world))`` give
a world that continues bit for bit like the original. pymunk cannot copy a
space that exactly: its own copy rebuilds the constraints without their
accumulated impulses (Chipmunk's warm start, not exposed to Python), which
changes the next step by an ulp, and the solver's internal state (its spatial
index, cached contacts) only approximately. What is exact is the world's
determinism: a world records, since its last reset, every call that changed it
(steps with their checked commands, static locks, reel rates) in a compact
journal (8 bytes per number: about 90 bytes per step of a three-robot world),
and a copy is a new world of the same configuration that replays that journal
(as fast as stepping: ~40 us per step since the reset). The copy checks its
state against the original's before it is handed out. The journal is cleared
at every reset.

Memory: every reset builds a new pymunk space (a fresh solver, so that an
episode never depends on the one before). A pymunk space holds about 280 KiB of
Chipmunk's pooled buffers, outside Python's view, and sits in reference cycles
(its collision handler points back at it; every pymunk body, shape and joint
holds a cffi handle to itself), so only Python's cyclic garbage collector frees
it. A space that lived through a collection of the middle generation is freed
only by a full collection, which Python schedules by object counts, not bytes:
in a process of ~130,000 objects that took ~9,000 resets, about 7 KiB of
resident memory per reset on average. So a world keeps weak references to the
spaces it replaced and, once more than :data:`RETIRED_SPACE_LIMIT` of them are
still in memory, runs one full collection (``gc.collect()``, ~0.1 s in such a
process). A world built with ``replaces=`` an earlier one shares its record.

Physics notes: a constant robot command drives an exact arc (see
``UGVBody.drive``); the commanded velocity takes effect one substep later
(Chipmunk integrates positions before solving velocities). Contacts are
discrete: in an impact a robot may sink into what it hits by up to one
substep's travel, then settles with at most :data:`COLLISION_SLOP` of overlap.
"""

from __future__ import annotations

import gc
import math
import numbers
import struct
import weakref
from array import array
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pymunk

from moma_env.geometry import se2_to_se3, wrap_angle
from moma_env.world.arena import add_static_shapes
from moma_env.world.config import WorldConfig, unknown_name
from moma_env.world.sled import SledBody
from moma_env.world.uav import UAVDynamics, UAVState
from moma_env.world.ugv import UGVBody

__all__ = ["World", "COLLISION_SLOP", "RETIRED_SPACE_LIMIT"]

#: Overlap (m) pymunk tolerates between touching shapes before pushing them apart.
COLLISION_SLOP = 1e-3


def _uav_owner(k: int) -> int:
    """Owner index of the ``k``-th UAV's camera in the camera table (UGV cameras use the robot index >= 0)."""
    return -1 - k

#: Replaced pymunk spaces (about 280 KiB each) that may wait in memory for Python's
#: cyclic garbage collector before :meth:`World.reset` runs a full collection.
RETIRED_SPACE_LIMIT = 32

#: Journal entries (see the module's notes on copies): a step, a static lock, a reel rate.
_OP_STEP, _OP_STATIC, _OP_REEL = 0, 1, 2
#: Version of the state a world pickles (:meth:`World.__getstate__`).
_STATE_VERSION = 1

_STATIC_CATEGORY = 1
#: Bodies 0..29 (robots, then sleds) get their own shape-filter category bit
#: (1..30); later ones share bit 31, and segment queries ignoring them take a
#: slower path.
_DEDICATED_BITS = 30
_SHARED_BIT = 1 << 31
_ALL_MASKS = pymunk.ShapeFilter.ALL_MASKS()
_NO_CONTACTS: frozenset[frozenset[str]] = frozenset()
#: Most ``ignore`` name groups a world keeps the segment-query filter of (see World._segment_filter).
_SEGMENT_FILTER_LIMIT = 1024
#: Bytes of a planar pose (x, y, angle): an exact cache key.
_PACK_POSE = struct.Struct("3d").pack


def _record_contact(arbiter: pymunk.Arbiter, space: pymunk.Space, data: tuple[dict, set]) -> None:
    """pymunk pre-solve callback: note the names of two touching shapes."""
    names, contacts = data
    a, b = arbiter.shapes
    contacts.add(frozenset((names[a], names[b])))


class _RetiredSpaces:
    """Weak references to the pymunk spaces that worlds replaced, and their reclamation.

    A replaced space is garbage held only by its own reference cycles (see the
    module's notes on memory); :meth:`add` forgets the ones already freed and,
    when more than :data:`RETIRED_SPACE_LIMIT` remain, runs a full collection.
    What survives it is referenced from elsewhere, not garbage: it is forgotten
    too, so that it never triggers another collection.
    """

    __slots__ = ("_refs",)

    def __init__(self) -> None:
        self._refs: list[weakref.ref[pymunk.Space]] = []

    def add(self, space: weakref.ref[pymunk.Space]) -> None:
        """Record a replaced space, given by a weak reference (a strong one would keep it alive)."""
        refs = [ref for ref in self._refs if ref() is not None]
        refs.append(space)
        if len(refs) > RETIRED_SPACE_LIMIT:
            gc.collect()
            refs = []
        self._refs = refs


def _journal_index(value: float, count: int) -> int:
    """A device index read from a journal, checked to be one of ``count``."""
    if not (value.is_integer() and 0 <= value < count):
        raise ValueError(f"the world's journal names device {value!r} of {count}")
    return int(value)


def _category(index: int) -> int:
    return 1 << (1 + index) if index < _DEDICATED_BITS else _SHARED_BIT


def _point(name: str, value: Sequence[float]) -> tuple[float, float]:
    try:
        x, y = float(value[0]), float(value[1])
        if len(value) != 2:
            raise ValueError
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"{name} must be a point (x, y), got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x, y


def _command(owner: str, value: object, size: int, layout: str) -> list[float]:
    """A command as ``size`` finite floats, or ValueError naming its owner."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"command for {owner!r} must be {layout}, got {value!r}") from None
    if array.shape != (size,):
        raise ValueError(f"command for {owner!r} must be {layout} with shape ({size},), got shape {array.shape}")
    values = array.tolist()
    if not all(map(math.isfinite, values)):
        raise ValueError(f"command for {owner!r} must be finite, got {values}")
    return values


def _mean_body_twist(previous: Sequence[float], current: Sequence[float], dt: float) -> tuple[float, float, float]:
    """Constant body-frame twist carrying planar pose ``previous`` to ``current`` in ``dt`` s.

    The inverse of the SE(2) exponential: with ``theta`` the heading change and
    ``d`` the displacement in the starting body frame, ``d = V(theta) @ v*dt`` with
    ``V = [[sin t/t, -(1-cos t)/t], [(1-cos t)/t, sin t/t]]``. Poses are
    ``(x, y, unwrapped angle)``.
    """
    x0, y0, a0 = previous
    x1, y1, a1 = current
    theta = a1 - a0
    c, s = math.cos(a0), math.sin(a0)
    dx, dy = x1 - x0, y1 - y0
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    if theta == 0.0:
        return lx / dt, ly / dt, 0.0
    a = math.sin(theta) / theta
    b = 2.0 * math.sin(0.5 * theta) ** 2 / theta
    det = a * a + b * b
    return (a * lx + b * ly) / (det * dt), (a * ly - b * lx) / (det * dt), theta / dt


class World:
    """Ground robots, sleds, walls and obstacles in pymunk, plus the UAV's 2.5D state.

    Attributes:
        config: the world's configuration.
        dt: duration of one control step (s).
    """

    def __init__(self, config: WorldConfig, *, replaces: World | None = None):
        """Build the world of ``config`` at its initial state (:meth:`reset`).

        Args:
            config: the world's configuration.
            replaces: a world this one takes the place of (the previous
                episode's, when the layout changes): its space is retired with
                the ones this world replaces at every reset, so that their memory
                is reclaimed alike (see the module's notes on memory). The old
                world stays usable.
        """
        if not isinstance(config, WorldConfig):
            raise TypeError(f"World needs a WorldConfig, got {type(config).__name__}")
        if replaces is not None and not isinstance(replaces, World):
            raise TypeError(f"replaces must be a World or None, got {type(replaces).__name__}")
        self._build(config, replaces)

    def _build(self, config: WorldConfig, replaces: World | None) -> None:
        """Everything :meth:`__init__` does once its arguments are checked."""
        self.config = config
        self.dt = config.dt
        self._substep = config.dt / config.substeps
        self._ugv_names = config.ugv_names
        self._ugv_index = {name: i for i, name in enumerate(self._ugv_names)}
        self._boards = tuple(ugv.board_mount if ugv.board is not None else None for ugv in config.ugvs)
        self._sled_names = config.sled_names
        self._sled_index = {name: k for k, name in enumerate(self._sled_names)}
        self._sled_robots = tuple(self._ugv_index[sled.robot] for sled in config.sleds)
        cameras: dict[str, tuple[int, np.ndarray]] = {}
        for i, ugv in enumerate(config.ugvs):
            for camera in ugv.cameras:
                cameras[camera.name] = (i, camera.T_b_c)
        for k, uav in enumerate(config.uavs):
            cameras[uav.camera_name] = (_uav_owner(k), uav.camera_mount)
        self._cameras = cameras
        self._camera_names = tuple(cameras)
        self._uav_names = config.uav_names
        self._uav_index = {name: k for k, name in enumerate(self._uav_names)}
        self._uavs = tuple(UAVDynamics(uav, self.dt) for uav in config.uavs)
        # board: body index (int), camera: its name (str) -> (packed planar pose, pose @ mount): see _mounted.
        self._mounted_cache: dict[int | str, tuple[bytes, np.ndarray]] = {}
        # ignore (a tuple or frozenset of names) -> its segment-query filter: see _segment_filter.
        self._segment_filters: dict[tuple | frozenset, tuple[pymunk.ShapeFilter, tuple[int, ...] | None]] = {}
        self._space: pymunk.Space | None = None
        # The calls that changed the world since its reset (see the module's notes on copies):
        # one op per entry, and the entries' numbers in order.
        self._journal_ops = bytearray()
        self._journal_values = array("d")
        if replaces is None:
            self._retired = _RetiredSpaces()
        else:
            self._retired = replaces._retired
            if replaces._space is not None:
                self._retired.add(weakref.ref(replaces._space))
        self.reset()

    # -- simulation ----------------------------------------------------------------

    def reset(self, rng: np.random.Generator | None = None) -> None:
        """Rebuild the space with every robot and sled at its initial pose and static flag.

        Sleds start with their initial rope length and a zero reel rate.

        The world draws no random numbers (its physics is deterministic);
        ``rng`` is accepted so that callers can pass their generator uniformly.
        The space of the episode before is retired (see the module's notes on
        memory): now and then this runs a full garbage collection. A world that
        nothing changed since it was built or reset (its journal is empty: no
        step, no switch, no reel command) is at that state already, and keeps
        its space.
        """
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy Generator or None, got {type(rng).__name__}")
        if self._space is not None and not self._journal_ops:
            return
        del self._journal_ops[:]
        del self._journal_values[:]
        retired = weakref.ref(self._space) if self._space is not None else None
        space = pymunk.Space()
        space.gravity = (0.0, 0.0)
        space.collision_slop = COLLISION_SLOP
        names = add_static_shapes(space, self.config.arena, pymunk.ShapeFilter(categories=_STATIC_CATEGORY))
        self._ugvs = tuple(
            UGVBody(ugv, space, pymunk.ShapeFilter(categories=_category(i)), self._substep)
            for i, ugv in enumerate(self.config.ugvs)
        )
        first = len(self._ugvs)
        self._sleds = tuple(
            SledBody(sled, self._ugvs[robot], space, pymunk.ShapeFilter(categories=_category(first + k)))
            for k, (sled, robot) in enumerate(zip(self.config.sleds, self._sled_robots))
        )
        self._shapes = tuple(body.shape for body in self._ugvs + self._sleds)
        self._bodies = tuple(ugv.body for ugv in self._ugvs)
        for body in self._ugvs + self._sleds:
            names[body.shape] = body.config.name
        self._contacts: set[frozenset[str]] = set()
        space.on_collision(None, None, pre_solve=_record_contact, data=(names, self._contacts))
        self._space = space
        self._read_poses()
        self._previous_rows = self._rows
        self._steps = 0
        for uav in self._uavs:
            uav.reset()
        self._uav_states: tuple[UAVState, ...] | None = None
        if retired is not None:
            self._retired.add(retired)

    def step(
        self,
        ugv_commands: Mapping[str, Sequence[float] | np.ndarray] | None = None,
        uav_command: Sequence[float] | np.ndarray | Mapping[str, Sequence[float] | np.ndarray | None] | None = None,
    ) -> None:
        """Advance one control step of ``dt`` s.

        Args:
            ugv_commands: robot name -> body-frame velocity (vx forward m/s, vy left
                m/s, omega rad/s), clipped to the robot's limits. Robots left out
                get a zero command (they brake); static robots ignore theirs.
                Sleds follow their reel rate (:meth:`set_reel`).
            uav_command: (vx forward m/s, vy left m/s, yaw rate rad/s, climb m/s)
                in the UAV's yaw frame, for a world of one UAV; or UAV name -> such
                a command (any number of UAVs; UAVs left out or None hover);
                None hovers every UAV.

        Raises:
            KeyError: an unknown robot or UAV name.
            TypeError: ``ugv_commands`` is not a mapping.
            ValueError: a command of the wrong shape or not finite (naming its
                owner), a UAV command in a world without a UAV, or a single
                command in a world of several UAVs.
        """
        commands = ugv_commands if ugv_commands is not None else {}
        if not isinstance(commands, Mapping):
            raise TypeError(f"ugv_commands must map robot names to commands, got {type(commands).__name__}")
        matched = 0
        given: list[list[float] | None] = []
        for name, ugv in zip(self._ugv_names, self._ugvs):
            value = commands.get(name)
            if value is None:
                given.append(None)
                continue
            matched += 1
            checked = _command(name, value, 3, "(vx, vy, omega)")
            # A static robot ignores its command: it keeps the zero command of its lock.
            given.append(None if ugv.static else checked)
        if matched != len(commands):
            for name in commands:
                if name not in self._ugv_index:
                    raise unknown_name("ugv", name, self._ugv_names)
        self._advance(given, self._uav_commands(uav_command))

    def _uav_commands(self, uav_command: object) -> list[list[float] | None]:
        """The UAVs' checked commands, in configuration order (None: hover)."""
        flying: list[list[float] | None] = [None] * len(self._uavs)
        if uav_command is None:
            return flying
        if not self._uavs:
            raise ValueError("uav_command given but the world has no UAV (WorldConfig.uavs is empty)")
        if isinstance(uav_command, Mapping):
            for name, value in uav_command.items():
                k = self._uav_index.get(name)
                if k is None:
                    raise unknown_name("uav", name, self._uav_names)
                if value is not None:
                    flying[k] = _command(name, value, 4, "(vx, vy, yaw_rate, climb)")
            return flying
        if len(self._uavs) > 1:
            raise ValueError(
                f"uav_command: this world has {len(self._uavs)} UAVs ({', '.join(self._uav_names)}); "
                "give a mapping UAV name -> (vx, vy, yaw_rate, climb)"
            )
        flying[0] = _command(self._uav_names[0], uav_command, 4, "(vx, vy, yaw_rate, climb)")
        return flying

    def _advance(self, given: Sequence[Sequence[float] | None], flying: Sequence[Sequence[float] | None]) -> None:
        """One control step under checked commands, recorded in the journal.

        Args:
            given: per robot, in configuration order, its body-frame command
                (vx, vy, omega; unclipped), or None for a zero command.
            flying: per UAV, in configuration order, its command (vx, vy, yaw
                rate, climb), or None to hover (one None entry in a world
                without a UAV).
        """
        values = self._journal_values
        for value in given:
            if value is None:
                values.append(0.0)
            else:
                values.append(1.0)
                values.extend(value)
        for uav in flying or (None,):
            if uav is None:
                values.append(0.0)
            else:
                values.append(1.0)
                values.extend(uav)
        self._journal_ops.append(_OP_STEP)

        ugvs = self._ugvs
        for ugv, value in zip(ugvs, given):
            if value is None:
                ugv.command = (0.0, 0.0, 0.0)
            else:
                ugv.set_command(*value)
        self._contacts.clear()
        drives = [ugv.drive for ugv in ugvs if not ugv.static]
        space_step, h = self._space.step, self._substep
        if self._sleds:
            reeling = [sled for sled in self._sleds if not sled.static and sled.reel_rate != 0.0]
            paying = [sled for sled in self._sleds if sled.static and not sled.robot.static]
            for _ in range(self.config.substeps):
                for drive in drives:
                    drive()
                for sled in reeling:
                    sled.reel(h)
                space_step(h)
                for sled in paying:
                    sled.pay_out()
        else:
            for _ in range(self.config.substeps):
                for drive in drives:
                    drive()
                space_step(h)
        self._previous_rows = self._rows
        self._read_poses()
        if self._uavs:
            for dynamics, uav in zip(self._uavs, flying):
                if uav is None:
                    dynamics.step(0.0, 0.0, 0.0, 0.0)
                else:
                    dynamics.step(*uav)
            self._uav_states = None
        self._steps += 1

    def _read_poses(self) -> None:
        """Read the robots' poses once per step, as tuples of floats: ``_rows``
        (x, y, unwrapped angle) and ``_planar`` (x, y, yaw in [-pi, pi))."""
        # pymunk returns the coordinates and the angle as Python floats already.
        rows = [(*body.position, body.angle) for body in self._bodies]
        self._rows = rows
        self._planar = [(x, y, wrap_angle(angle)) for x, y, angle in rows]

    @property
    def time(self) -> float:
        """Simulated time since the last reset (s)."""
        return self._steps * self.dt

    @property
    def step_count(self) -> int:
        """Control steps since the last reset."""
        return self._steps

    # -- static lock ---------------------------------------------------------------

    def _device(self, name: str) -> UGVBody | SledBody:
        try:
            i = self._ugv_index.get(name)
            if i is not None:
                return self._ugvs[i]
            return self._sleds[self._sled_index[name]]
        except (KeyError, TypeError):
            raise self._unknown_device(name) from None

    def _unknown_device(self, name: object) -> KeyError:
        return KeyError(
            f"unknown ugv or sled {name!r}; known ugvs are {list(self._ugv_names)}, "
            f"known sleds are {list(self._sled_names)}"
        )

    def set_static(self, name: str, static: bool) -> None:
        """Lock robot or sled ``name`` in place (a static marker) or release it.

        A static device keeps a bit-identical pose whatever it is commanded and
        however it is pushed or pulled; a released one starts from rest. A
        static sled lets its rope pay out freely up to ``max_rope``; a mobile
        one follows its reel rate (which a switch keeps).
        """
        if not isinstance(static, (bool, np.bool_)):
            raise TypeError(f"static must be a bool, got {static!r}")
        device = self._device(name)
        self._journal_ops.append(_OP_STATIC)
        self._journal_values.extend((self._body_index(name), 1.0 if static else 0.0))
        device.set_static(bool(static))
        if isinstance(device, UGVBody):
            for sled in self._sleds:
                if sled.robot is device:
                    sled.sync_rope()

    def is_static(self, name: str) -> bool:
        """Whether robot or sled ``name`` is locked in place."""
        return self._device(name).static

    # -- ground robots ---------------------------------------------------------------

    def _index(self, name: str) -> int:
        try:
            return self._ugv_index[name]
        except (KeyError, TypeError):
            raise unknown_name("ugv", name, self._ugv_names) from None

    @property
    def ugv_names(self) -> tuple[str, ...]:
        """Names of the ground robots, in configuration order."""
        return self._ugv_names

    def ugv_pose(self, name: str) -> tuple[float, float, float]:
        """Planar pose ``(x, y, yaw)`` of robot ``name`` in W (m, m, rad in [-pi, pi))."""
        return self._planar[self._index(name)]

    def ugv_poses(self) -> np.ndarray:
        """(n, 3) array of ``(x, y, yaw)`` of all robots, yaw in [-pi, pi) (a copy)."""
        poses = np.array(self._rows, dtype=float).reshape(len(self._rows), 3)
        poses[:, 2] = wrap_angle(poses[:, 2])
        return poses

    def ugv_transform(self, name: str) -> np.ndarray:
        """4x4 ``T_w_b`` of robot ``name`` (body origin on the floor, z = 0)."""
        x, y, angle = self._rows[self._index(name)]
        return se2_to_se3(x, y, angle)

    def ugv_body_velocity(self, name: str) -> tuple[float, float, float]:
        """Body-frame velocity ``(vx, vy, omega)`` of robot ``name`` over the last step.

        What wheel encoders measure: the constant body-frame twist (m/s, m/s,
        rad/s) whose SE(2) exponential over ``dt`` carries the robot's pose at the
        start of the last step to its pose at the end. Zero before the first step
        and while static.
        """
        i = self._index(name)
        return _mean_body_twist(self._previous_rows[i], self._rows[i], self.dt)

    def board_transform(self, name: str) -> np.ndarray | None:
        """4x4 ``T_w_m`` of the board of robot or sled ``name``, or None for a robot without one.

        ``T_w_b @ T_b_m`` for a robot, ``T_w_s @ T_s_m`` for a sled.
        """
        i = self._body_index(name)
        n_ugvs = len(self._ugvs)
        if i >= n_ugvs:
            sled = self._sleds[i - n_ugvs]
            body = sled.body
            x, y = body.position
            return self._mounted(i, (x, y, body.angle), sled.config.board_mount)
        mount = self._boards[i]
        if mount is None:
            return None
        return self._mounted(i, self._rows[i], mount)

    def _mounted(self, key: int | str, pose: tuple[float, float, float], mount: np.ndarray) -> np.ndarray:
        """``se2_to_se3(*pose) @ mount`` (a new array), for the fixed ``mount`` named by ``key``
        (a board: its body's index; a camera: its name).

        A static device keeps its pose, so the product of the last call per key is
        kept and copied while ``pose`` is bit for bit unchanged (compared packed, as
        ``==`` on floats would confuse 0.0 and -0.0).
        """
        packed = _PACK_POSE(*pose)
        cache = self._mounted_cache
        hit = cache.get(key)
        if hit is not None and hit[0] == packed:
            return hit[1].copy()
        T = se2_to_se3(*pose) @ mount
        cache[key] = (packed, T.copy())
        return T

    def segment_blocked(
        self, p_from_xy: Sequence[float], p_to_xy: Sequence[float], ignore: Iterable[str] = ()
    ) -> bool:
        """Whether the floor segment from ``p_from_xy`` to ``p_to_xy`` (W, m) hits a wall,
        an obstacle, or a robot or sled not named in ``ignore``.

        A planar test (heights are not considered). A segment starting or ending
        inside a shape hits it.
        """
        a = _point("p_from_xy", p_from_xy)
        b = _point("p_to_xy", p_to_xy)
        shape_filter, shared = self._segment_filter(ignore)
        if shared is None:
            return self._space.segment_query_first(a, b, 0.0, shape_filter) is not None
        ignored = {self._shapes[i] for i in shared}
        hits = self._space.segment_query(a, b, 0.0, shape_filter)
        return any(hit.shape not in ignored for hit in hits)

    def _segment_filter(self, ignore: Iterable[str]) -> tuple[pymunk.ShapeFilter, tuple[int, ...] | None]:
        """The shape filter of a segment query ignoring the devices named in ``ignore``, and
        the indices of those devices if one of them shares the category bit (None if not).

        A filter depends on the names only (and the configuration): one given as a
        tuple or a frozenset of known names is kept for the world's lifetime, so that
        the names are checked and the mask is built once (the camera's occlusion
        queries repeat a few such tuples many times per step).
        """
        filters = self._segment_filters
        try:
            hit = filters.get(ignore)
        except TypeError:  # an unhashable iterable (a list, a set): no cache
            hit = None
        if hit is not None:
            return hit
        mask = _ALL_MASKS
        shared = False
        indices = [self._body_index(name) for name in ignore]
        for i in indices:
            if i >= _DEDICATED_BITS:
                shared = True
            else:
                mask &= ~_category(i)
        found = (pymunk.ShapeFilter(mask=mask), tuple(indices) if shared else None)
        if type(ignore) in (tuple, frozenset) and len(filters) < _SEGMENT_FILTER_LIMIT:
            filters[ignore] = found
        return found

    @property
    def collisions_since_last_step(self) -> frozenset[frozenset[str]]:
        """Pairs of names in contact at any substep of the last step.

        Names are robot and sled names, ``"wall"`` and ``"obstacle[k]"``; a static
        device touching only walls or other static devices makes no pair (none can
        move). A sled never touches the robot that tows it.
        """
        return frozenset(self._contacts) if self._contacts else _NO_CONTACTS

    def _body_index(self, name: str) -> int:
        """Index of robot or sled ``name`` among the bodies (robots, then sleds)."""
        i = self._ugv_index.get(name) if isinstance(name, str) else None
        if i is not None:
            return i
        try:
            return len(self._ugvs) + self._sled_index[name]
        except (KeyError, TypeError):
            raise self._unknown_device(name) from None

    # -- sleds ---------------------------------------------------------------------------

    def _sled(self, name: str) -> SledBody:
        try:
            return self._sleds[self._sled_index[name]]
        except (KeyError, TypeError):
            raise unknown_name("sled", name, self._sled_names) from None

    @property
    def sled_names(self) -> tuple[str, ...]:
        """Names of the sleds, in configuration order."""
        return self._sled_names

    def sled_pose(self, name: str) -> tuple[float, float, float]:
        """Planar pose ``(x, y, yaw)`` of sled ``name``'s frame S in W (m, m, rad in [-pi, pi))."""
        body = self._sled(name).body
        x, y = body.position
        return x, y, wrap_angle(body.angle)

    def sled_transform(self, name: str) -> np.ndarray:
        """4x4 ``T_w_s`` of sled ``name`` (origin on the floor at the footprint's centre, z = 0)."""
        body = self._sled(name).body
        x, y = body.position
        return se2_to_se3(x, y, body.angle)

    def rope_length(self, name: str) -> float:
        """Current length (m) of sled ``name``'s rope, anchor to anchor.

        The rope is slack while the anchors are closer than this and taut at it.
        """
        return self._sled(name).rope_length

    def set_reel(self, name: str, rate: float) -> None:
        """Command sled ``name``'s pulley: ``rate`` in [-1, 1], kept until changed.

        While the sled is mobile, a positive rate reels the rope in at
        ``rate * reel_speed`` m/s down to ``min_rope`` (a taut rope drags the
        sled towards the robot), a negative one lets it out up to ``max_rope``,
        and 0 holds the length. A static sled ignores the rate (its rope pays
        out freely) until it is released.

        Raises:
            KeyError: an unknown sled name.
            ValueError: ``rate`` is not a finite number in [-1, 1] (naming the sled).
        """
        sled = self._sled(name)
        if isinstance(rate, (bool, np.bool_)) or not isinstance(rate, numbers.Real):
            raise ValueError(f"reel rate for sled {name!r} must be a number in [-1, 1], got {rate!r}")
        value = float(rate)
        if not -1.0 <= value <= 1.0:  # also rejects NaN
            raise ValueError(f"reel rate for sled {name!r} must be finite and in [-1, 1], got {rate!r}")
        self._journal_ops.append(_OP_REEL)
        self._journal_values.extend((self._sled_index[name], value))
        sled.reel_rate = value

    def reel_rate(self, name: str) -> float:
        """Last reel rate commanded for sled ``name`` (0 at reset)."""
        return self._sled(name).reel_rate

    # -- cameras -----------------------------------------------------------------------

    @property
    def camera_names(self) -> tuple[str, ...]:
        """Names of every camera: the robots' cameras, then the UAVs'."""
        return self._camera_names

    def camera_transform(self, camera_name: str) -> np.ndarray:
        """4x4 ``T_w_c`` of camera ``camera_name`` (robot or UAV camera)."""
        try:
            owner, T_b_c = self._cameras[camera_name]
        except (KeyError, TypeError):
            raise unknown_name("camera", camera_name, self._camera_names) from None
        if owner < 0:
            return self._uavs[-1 - owner].body_transform() @ T_b_c
        return self._mounted(camera_name, self._rows[owner], T_b_c)

    # -- UAV -------------------------------------------------------------------------------

    @property
    def has_uav(self) -> bool:
        """Whether the world has a UAV (or hand-held observer), one or several."""
        return bool(self._uavs)

    @property
    def uav_names(self) -> tuple[str, ...]:
        """The UAVs' names, in configuration order."""
        return self._uav_names

    def _uav(self, name: str | None) -> UAVDynamics:
        """The UAV ``name``; None: the only one (LookupError without a UAV, ValueError with several)."""
        if name is None:
            if not self._uavs:
                raise LookupError("the world has no UAV (WorldConfig.uavs is empty)")
            if len(self._uavs) > 1:
                raise ValueError(f"this world has {len(self._uavs)} UAVs ({', '.join(self._uav_names)}); name one")
            return self._uavs[0]
        k = self._uav_index.get(name)
        if k is None:
            raise unknown_name("uav", name, self._uav_names)
        return self._uavs[k]

    @property
    def uav_states(self) -> tuple[UAVState, ...]:
        """Current state of every UAV, in configuration order (empty without one)."""
        if self._uav_states is None:
            self._uav_states = tuple(uav.state() for uav in self._uavs)
        return self._uav_states

    @property
    def uav_state(self) -> UAVState:
        """Current state of the only UAV (LookupError without a UAV, ValueError with several:
        read :attr:`uav_states`)."""
        self._uav(None)
        return self.uav_states[0]

    def uav_transform(self, name: str | None = None) -> np.ndarray:
        """4x4 ``T_w_b`` of UAV ``name``'s body (None: the only UAV; LookupError without
        a UAV, ValueError naming them with several, KeyError for an unknown name)."""
        return self._uav(name).body_transform()

    # -- whole state -------------------------------------------------------------------

    def state_array(self) -> np.ndarray:
        """Flat float array of the full simulated state, for comparisons and logs.

        Per robot ``x, y, angle (unwrapped), vx, vy (W), omega``; then per sled
        the same six values and its rope length; then every UAV's
        ``UAVState.as_array()``, in configuration order.
        """
        parts: list[float] = []
        for ugv in self._ugvs:
            body = ugv.body
            x, y = body.position
            vx, vy = body.velocity
            parts += (x, y, body.angle, vx, vy, body.angular_velocity)
        for sled in self._sleds:
            body = sled.body
            x, y = body.position
            vx, vy = body.velocity
            parts += (x, y, body.angle, vx, vy, body.angular_velocity, sled.rope_length)
        state = np.array(parts, dtype=float)
        if self._uavs:
            state = np.concatenate([state, *(s.as_array() for s in self.uav_states)])
        return state

    # -- copies ------------------------------------------------------------------------

    def _fingerprint(self) -> tuple[bytes, int, list[list[str]]]:
        """What a copy must reproduce exactly: the state's bytes, the step count, the contacts."""
        contacts = sorted(sorted(pair) for pair in self._contacts)
        return self.state_array().tobytes(), self._steps, contacts

    def __getstate__(self) -> dict[str, Any]:
        """The configuration and the journal since the last reset (see the module's notes
        on copies), with the state they must lead to; for :mod:`pickle` and :mod:`copy`."""
        return {
            "version": _STATE_VERSION,
            "pymunk": pymunk.version,
            "config": self.config,
            "journal": (bytes(self._journal_ops), array("d", self._journal_values)),
            "fingerprint": self._fingerprint(),
        }

    def __setstate__(self, state: Mapping[str, Any]) -> None:
        """Rebuild from :meth:`__getstate__`: a new world of the configuration replays the journal.

        Raises:
            ValueError: not a world's state, or one of another version.
            RuntimeError: the replay does not reproduce the saved state bit for bit
                (e.g. a state pickled with another pymunk version).
        """
        if not isinstance(state, Mapping) or state.get("version") != _STATE_VERSION:
            version = state.get("version") if isinstance(state, Mapping) else None
            raise ValueError(f"not the state of a World of version {_STATE_VERSION} (version {version!r})")
        config = state["config"]
        if not isinstance(config, WorldConfig):
            raise ValueError(f"the state's config is a {type(config).__name__}, not a WorldConfig")
        self._build(config, None)
        ops, values = state["journal"]
        self._replay(bytes(ops), array("d", values))
        if self._fingerprint() != tuple(state["fingerprint"]):
            raise RuntimeError(
                f"replaying the world's journal did not reproduce its state (saved with pymunk "
                f"{state.get('pymunk')}, replayed with pymunk {pymunk.version})"
            )

    def __deepcopy__(self, memo: dict[int, Any]) -> World:
        """A copy that continues bit for bit like this world; it shares the (frozen) configuration."""
        clone = World.__new__(World)
        memo[id(self)] = clone
        clone.__setstate__(self.__getstate__())
        return clone

    def _replay(self, ops: bytes, values: array) -> None:
        """Apply a journal (see :meth:`_advance`, :meth:`set_static`, :meth:`set_reel`) to this world."""
        n_ugvs = len(self._ugvs)
        devices = self._ugv_names + self._sled_names
        i = 0
        try:
            for op in ops:
                if op == _OP_STEP:
                    given: list[tuple[float, float, float] | None] = []
                    for _ in range(n_ugvs):
                        if values[i] == 0.0:
                            given.append(None)
                            i += 1
                        else:
                            given.append((values[i + 1], values[i + 2], values[i + 3]))
                            i += 4
                    flying: list[list[float] | None] = []
                    for _ in range(max(1, len(self._uavs))):
                        if values[i] == 0.0:
                            flying.append(None)
                            i += 1
                        else:
                            if not self._uavs:
                                raise ValueError("the world's journal flies a UAV the world does not have")
                            flying.append([values[i + 1], values[i + 2], values[i + 3], values[i + 4]])
                            i += 5
                    self._advance(given, flying if self._uavs else [])
                elif op == _OP_STATIC:
                    self.set_static(devices[_journal_index(values[i], len(devices))], values[i + 1] != 0.0)
                    i += 2
                elif op == _OP_REEL:
                    self.set_reel(self._sled_names[_journal_index(values[i], len(self._sled_names))], values[i + 1])
                    i += 2
                else:
                    raise ValueError(f"unknown journal entry {op}")
        except IndexError:
            raise ValueError("the world's journal is truncated") from None
        if i != len(values):
            raise ValueError(f"the world's journal has {len(values) - i} numbers left over")
