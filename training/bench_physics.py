"""Physics of a batched env: one pymunk space per copy against one space shared by every copy.

``python -m training.bench_physics [--num-envs 64,256,1024] [--steps N] [--rounds R]``
times, for ``top_observer`` (2 UGVs), ``top_observer`` with 8 UGVs and
``caterpillar_multi`` (3 UGVs) at each ``num_envs``, in interleaved rounds of one
run, what a vector env needs from the physics at every control step of every
copy: set the robots' commands, step the space :attr:`WorldConfig.substeps`
times with the robots' velocity control (``UGVBody.drive`` before every
substep, as :class:`~moma_env.world.World` does), and read back the position
(m) and angle (rad) of every robot and sled. Four ways to hold the copies:

* ``World.step``: a :class:`~moma_env.world.World` per copy, stepped with a
  command dict and read with ``ugv_poses`` and ``sled_pose`` (what the env
  does today: its checks, journal and pose cache included);
* ``per-copy``: a pymunk space per copy built from the world's public pieces
  (:func:`~moma_env.world.arena.add_static_shapes`,
  :class:`~moma_env.world.ugv.UGVBody`, :class:`~moma_env.world.sled.SledBody`)
  and stepped by ``World``'s loop, without its checks and journal;
* ``shared loop``: every copy in one space, copies on a grid far apart and
  shape-filtered, stepped by the same per-body Python loop (the layout alone);
* ``shared batch``: the same shared space, bodies read and written with
  :mod:`pymunk.batch` (one call per substep for every copy's velocities,
  the drive law vectorised with numpy, one call for the poses).

An env-step is one control step of one copy. Every layout gets the same
commands (drawn before the clock starts, per copy, held ``HOLD_STEPS`` steps,
within the robots' limits so the clipping is a no-op) and runs the same number
of steps, so their final poses are compared: ``per-copy`` against ``World``
(the replica of World's physics must be bit-identical), ``shared batch``
against ``shared loop`` (the vectorised drive law must be bit-identical),
``shared`` against a few copies (:data:`CHECK_COPIES` and the last) run alone in
their own spaces at the same offsets (a difference is the solver's order of
contacts in the bigger space), and ``shared`` minus its offsets against
``per-copy`` at the origin (copy 0 sits at the origin; the other copies also
carry the rounding of their offset, up to ~200 m at 1,024 copies).

Left out of every layout alike: the UAV (not pymunk: ``uav`` is dropped from
the configuration), the static locks (every robot and sled is mobile), the
cameras and the estimator. The contacts are recorded in every layout by a
pre-solve callback, as ``World`` does for ``collisions_since_last_step``.
Private pieces of :mod:`moma_env.world.world` are replicated here: its shape
filter categories (static shapes bit 0, body ``i`` bit ``1 + i``) and its
contact callback. A measurement, not an assertion.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pymunk
import pymunk.batch as pbatch

from moma_env.world import COLLISION_SLOP, World, WorldConfig
from moma_env.world.arena import add_static_shapes
from moma_env.world.sled import SledBody
from moma_env.world.ugv import UGVBody
from training.cli_args import int_list

__all__ = [
    "CASES",
    "LAYOUTS",
    "HOLD_STEPS",
    "world_config",
    "grid_offsets",
    "command_pool",
    "WorldLayout",
    "PerCopySpaces",
    "SharedSpace",
    "compare_poses",
    "run_physics_bench",
    "format_physics_bench",
    "main",
]

#: The rows: label -> (configuration, options of ``make_scenario``).
CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "top_observer": ("top_observer", {}),
    "top_observer 8 UGVs": ("top_observer", {"n_ugvs": 8}),
    "caterpillar_multi": ("caterpillar_multi", {}),
}
#: The layouts timed, in the table's order.
LAYOUTS = ("World.step", "per-copy", "shared loop", "shared batch")
#: Control steps a drawn command is held (0.4 s at 25 Hz): long enough to cross into walls and robots.
HOLD_STEPS = 10
#: Distinct commands per copy, used in turn.
POOL = 16
#: Copies (the first ones and the last) also run alone at their shared-space offsets, to compare.
CHECK_COPIES = 16
#: Free floor (m) between two copies' walls in the shared space (more than any rope or robot).
GAP = 2.0
_STATIC_CATEGORY = 1  # World's: static shapes on bit 0, body i on bit 1 + i
_FIELDS_DRIVE = pbatch.BodyFields.ANGLE | pbatch.BodyFields.VELOCITY | pbatch.BodyFields.ANGULAR_VELOCITY
_FIELDS_SET = pbatch.BodyFields.VELOCITY | pbatch.BodyFields.ANGULAR_VELOCITY
_FIELDS_POSE = pbatch.BodyFields.POSITION | pbatch.BodyFields.ANGLE


def world_config(name: str, options: dict[str, Any] | None = None) -> WorldConfig:
    """The world of configuration ``name``'s default scenario, physics only: no UAV,
    every robot and sled mobile (the env locks and releases them; this times the motion)."""
    from moma_env.scenarios.registry import make_scenario

    config = make_scenario(name, **(options or {})).world
    return dataclasses.replace(
        config,
        uavs=(),
        ugvs=tuple(dataclasses.replace(u, static=False) for u in config.ugvs),
        sleds=tuple(dataclasses.replace(s, static=False) for s in config.sleds),
    )


def shifted_config(config: WorldConfig, dx: float, dy: float) -> WorldConfig:
    """``config`` translated by ``(dx, dy)`` m (arena, obstacles, initial poses); itself for (0, 0)."""
    if dx == 0.0 and dy == 0.0:
        return config
    arena = config.arena
    ox, oy = arena.origin
    moved = dataclasses.replace(
        arena,
        origin=(ox + dx, oy + dy),
        obstacles=tuple(dataclasses.replace(o, x=o.x + dx, y=o.y + dy) for o in arena.obstacles),
    )

    def pose(p: tuple[float, float, float]) -> tuple[float, float, float]:
        return (p[0] + dx, p[1] + dy, p[2])

    return dataclasses.replace(
        config,
        arena=moved,
        ugvs=tuple(dataclasses.replace(u, initial_pose=pose(u.initial_pose)) for u in config.ugvs),
        sleds=tuple(dataclasses.replace(s, initial_pose=pose(s.initial_pose)) for s in config.sleds),
    )


def grid_offsets(config: WorldConfig, n: int) -> np.ndarray:
    """(n, 2) offsets (m) of ``n`` copies on a square grid, copy 0 at the origin, copies
    ``GAP`` m apart wall to wall (row-major: copy ``k`` in column ``k % side``)."""
    arena = config.arena
    pitch_x = arena.width + 2.0 * arena.wall_thickness + GAP
    pitch_y = arena.height + 2.0 * arena.wall_thickness + GAP
    side = max(1, math.ceil(math.sqrt(n)))
    k = np.arange(n)
    return np.stack([(k % side) * pitch_x, (k // side) * pitch_y], axis=1).astype(float)


def _color(offset_index: int, side: int) -> int:
    """Shape-filter bit of copy ``offset_index`` on a grid ``side`` wide: four colours in 2x2
    tiles, so neighbouring copies (sides and corners) never share one. Bits 27..30."""
    col, row = offset_index % side, offset_index // side
    return 1 << (27 + (col % 2) + 2 * (row % 2))


def command_pool(config: WorldConfig, copies: Sequence[int], seed: int = 0) -> np.ndarray:
    """(POOL, len(copies), n_ugvs, 3) body-frame commands (vx m/s, vy m/s, omega rad/s).

    Copy ``k``'s commands come from its own generator (seeded ``(seed, k)``), so they
    do not depend on which other copies run. Speeds up to 0.95 of ``max_speed`` and
    yaw rates up to 0.95 of ``max_yaw_rate``: ``UGVBody.set_command`` clips nothing.
    """
    out = np.empty((POOL, len(copies), len(config.ugvs), 3))
    for j, k in enumerate(copies):
        rng = np.random.default_rng([seed, int(k)])
        for i, ugv in enumerate(config.ugvs):
            speed = ugv.max_speed * 0.95 * np.sqrt(rng.uniform(size=POOL))
            heading = rng.uniform(-math.pi, math.pi, size=POOL)
            out[:, j, i, 0] = speed * np.cos(heading)
            out[:, j, i, 1] = speed * np.sin(heading)
            out[:, j, i, 2] = rng.uniform(-0.95, 0.95, size=POOL) * ugv.max_yaw_rate
    return out


def _reel_rates(config: WorldConfig, k: int, seed: int) -> list[float]:
    """Copy ``k``'s constant reel rate per sled, in [-1, 1]."""
    rng = np.random.default_rng([seed, int(k), 1])
    return [float(r) for r in rng.uniform(-1.0, 1.0, size=len(config.sleds))]


def _record_contact(arbiter: pymunk.Arbiter, space: pymunk.Space, data: tuple[dict, set]) -> None:
    """pymunk pre-solve callback (World's): note ``(copy, {name, name})`` of two touching shapes."""
    names, contacts = data
    a, b = arbiter.shapes
    (copy, name_a), (_, name_b) = names[a], names[b]
    contacts.add((copy, frozenset((name_a, name_b))))



def run_substeps(space, h: float, substeps: int, ugvs, reeling, paying) -> None:
    """World's inner loop (``World._advance``), replicated because it is private: per
    substep of ``h`` s, drive the UGVs, reel the reeling sleds in, step ``space``, pay the
    paying sleds' ropes out."""
    for _ in range(substeps):
        for ugv in ugvs:
            ugv.drive()
        for sled in reeling:
            sled.reel(h)
        space.step(h)
        for sled in paying:
            sled.pay_out()

class _Copy:
    """One copy's static shapes, robots and sleds added to a space (World's ``reset``)."""

    __slots__ = ("ugvs", "sleds", "bodies", "reeling", "paying")

    def __init__(self, config: WorldConfig, space: pymunk.Space, index: int, names: dict, color: int = 0):
        # color 0: World's filters (every mask open); else copy-private categories and masks.
        mask = color if color else pymunk.ShapeFilter.ALL_MASKS()

        def shape_filter(category: int) -> pymunk.ShapeFilter:
            return pymunk.ShapeFilter(categories=category | color, mask=mask)

        substep = config.dt / config.substeps
        for shape, name in add_static_shapes(space, config.arena, shape_filter(_STATIC_CATEGORY)).items():
            names[shape] = (index, name)
        self.ugvs = tuple(UGVBody(u, space, shape_filter(1 << (1 + i)), substep) for i, u in enumerate(config.ugvs))
        first = len(self.ugvs)
        self.sleds = tuple(
            SledBody(s, self.ugvs[config.ugv_names.index(s.robot)], space, shape_filter(1 << (1 + first + k)))
            for k, s in enumerate(config.sleds)
        )
        for device in self.ugvs + self.sleds:
            names[device.shape] = (index, device.config.name)
        self.bodies = tuple(device.body for device in self.ugvs + self.sleds)
        self.reeling: list[SledBody] = []
        self.paying: list[SledBody] = []

    def set_reels(self, rates: Sequence[float]) -> None:
        for sled, rate in zip(self.sleds, rates):
            sled.reel_rate = rate
        self.reeling = [s for s in self.sleds if not s.static and s.reel_rate != 0.0]
        self.paying = [s for s in self.sleds if s.static and not s.robot.static]


def _new_space() -> pymunk.Space:
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    space.collision_slop = COLLISION_SLOP
    return space


def _check_layout(config: WorldConfig) -> None:
    if len(config.ugvs) + len(config.sleds) > 26:
        raise ValueError("the shared space keeps bits 27..30 for its copies: at most 26 robots and sleds")


class _Layout:
    """What every layout shares: the commands, the step counter, the poses read."""

    config: WorldConfig
    n: int
    poses: np.ndarray  # (n, bodies, 3): x (m), y (m), unwrapped angle (rad) of robots, then sleds

    def _setup(self, config: WorldConfig, copies: Sequence[int], seed: int) -> None:
        self.config = config
        self.n = len(copies)
        self.copies = list(copies)
        self.commands = command_pool(config, copies, seed)
        self.steps = 0
        self.substeps = config.substeps
        self.h = config.dt / config.substeps

    def current(self) -> np.ndarray:
        """(n, n_ugvs, 3) commands of the coming step."""
        return self.commands[(self.steps // HOLD_STEPS) % POOL]

    def run(self, steps: int) -> dict[str, float]:
        """``steps`` control steps of every copy; ``steps_per_s`` is env-steps per second."""
        start = time.perf_counter()
        for _ in range(steps):
            self.step()
        return {"steps_per_s": steps * self.n / (time.perf_counter() - start)}

    def step(self) -> None:
        raise NotImplementedError


class WorldLayout(_Layout):
    """A :class:`World` per copy, at the origin (what the env does today)."""

    def __init__(self, config: WorldConfig, copies: Sequence[int], seed: int = 0):
        self._setup(config, copies, seed)
        self.worlds = [World(config) for _ in copies]
        for world, k in zip(self.worlds, copies):
            for name, rate in zip(config.sled_names, _reel_rates(config, k, seed)):
                world.set_reel(name, rate)
        self._names = config.ugv_names
        self._sleds = config.sled_names
        self.poses = np.zeros((self.n, len(self._names) + len(self._sleds), 3))

    def step(self) -> None:
        names, sleds = self._names, self._sleds
        rows = []
        for world, command in zip(self.worlds, self.current().tolist()):
            world.step(dict(zip(names, command)))
            rows.append(world.ugv_poses())
            if sleds:
                rows.append(np.array([world.sled_pose(s) for s in sleds]))
        self.poses = np.concatenate(rows).reshape(self.poses.shape)
        self.steps += 1

    def unwrapped_poses(self) -> np.ndarray:
        """(n, bodies, 3) poses with unwrapped angles (from ``state_array``), to compare."""
        nu, ns = len(self._names), len(self._sleds)
        out = []
        for world in self.worlds:
            state = world.state_array()
            ugv = state[: 6 * nu].reshape(nu, 6)[:, :3]
            sled = state[6 * nu : 6 * nu + 7 * ns].reshape(ns, 7)[:, :3]
            out.append(np.concatenate([ugv, sled]))
        return np.array(out)


class PerCopySpaces(_Layout):
    """A pymunk space per copy stepped by World's loop (no checks, no journal).

    Every copy at the origin (as today), or with ``grid`` at its offset in a
    :class:`SharedSpace` laid out for ``grid`` copies (poses then relative to it):
    the same floating-point inputs as the shared space, to tell the solver's order
    from the rounding of the offsets.
    """

    def __init__(self, config: WorldConfig, copies: Sequence[int], seed: int = 0, *, grid: int | None = None):
        self._setup(config, copies, seed)
        self.spaces, self.parts, self.contacts = [], [], []
        offsets = np.zeros((self.n, 2)) if grid is None else grid_offsets(config, grid)[list(copies)]
        self._offsets_3 = None if grid is None else np.concatenate([offsets, np.zeros((self.n, 1))], axis=1)[:, None, :]
        for j, k in enumerate(copies):
            space = _new_space()
            names: dict = {}
            part = _Copy(shifted_config(config, float(offsets[j, 0]), float(offsets[j, 1])), space, j, names)
            part.set_reels(_reel_rates(config, k, seed))
            contacts: set = set()
            space.on_collision(None, None, pre_solve=_record_contact, data=(names, contacts))
            self.spaces.append(space)
            self.parts.append(part)
            self.contacts.append(contacts)
        self.poses = np.zeros((self.n, len(self.parts[0].bodies), 3))

    def step(self) -> None:
        h, substeps = self.h, self.substeps
        rows: list[float] = []
        for space, part, contacts, command in zip(self.spaces, self.parts, self.contacts, self.current().tolist()):
            ugvs = part.ugvs
            for ugv, value in zip(ugvs, command):
                ugv.set_command(*value)
            contacts.clear()
            run_substeps(space, h, substeps, ugvs, part.reeling, part.paying)
            for body in part.bodies:
                x, y = body.position
                rows += (x, y, body.angle)
        self.poses = np.array(rows).reshape(self.poses.shape)
        if self._offsets_3 is not None:
            self.poses -= self._offsets_3
        self.steps += 1



class SharedSpace(_Layout):
    """One pymunk space holding every copy, ``grid_offsets`` apart, copy-private shape filters.

    Args:
        config: the world of one copy (at the origin).
        copies: the copies' indices: grid cells (offsets) and command streams.
            ``copies=[k]`` runs copy ``k`` alone at its usual offset.
        batch: drive and read with :mod:`pymunk.batch` (else World's per-body loop).
        grid: number of copies the grid is laid out for (default ``max(copies) + 1``).
    """

    def __init__(self, config: WorldConfig, copies: Sequence[int], seed: int = 0, *, batch: bool = True, grid: int | None = None):
        _check_layout(config)
        self._setup(config, copies, seed)
        cells = max(copies) + 1 if grid is None else grid
        side = max(1, math.ceil(math.sqrt(cells)))
        self.offsets = grid_offsets(config, cells)[list(copies)]
        self.space = space = _new_space()
        self.batch = batch
        names: dict = {}
        self.parts = []
        for j, k in enumerate(copies):
            dx, dy = self.offsets[j]
            part = _Copy(shifted_config(config, float(dx), float(dy)), space, j, names, _color(k, side))
            part.set_reels(_reel_rates(config, k, seed))
            self.parts.append(part)
        self.contacts: set = set()
        space.on_collision(None, None, pre_solve=_record_contact, data=(names, self.contacts))
        self.ugvs = [ugv for part in self.parts for ugv in part.ugvs]
        self.reeling = [s for part in self.parts for s in part.reeling]
        self.paying = [s for part in self.parts for s in part.paying]
        nb = len(self.parts[0].bodies)
        self.poses = np.zeros((self.n, nb, 3))
        # Rows of the batch buffers: bodies in the space's order, found by id.
        ids = pbatch.Buffer()
        pbatch.get_space_bodies(space, pbatch.BodyFields.BODY_ID, ids)
        row = {int(i): r for r, i in enumerate(np.frombuffer(ids.int_buf(), dtype=np.uintp))}
        self._robot_rows = np.array([row[u.body.id] for u in self.ugvs])
        self._control_rows = np.array([row[u.control.id] for u in self.ugvs])
        self._body_rows = np.array([[row[b.id] for b in part.bodies] for part in self.parts])
        self._n_rows = len(row)
        cfg = config.ugvs
        n = self.n
        self._max_speed = np.tile([u.max_speed for u in cfg], n)
        self._max_yaw_rate = np.tile([u.max_yaw_rate for u in cfg], n)
        self._max_yaw_step = np.tile([u.max_yaw_accel * self.h for u in cfg], n)
        self._get = pbatch.Buffer()
        self._set_values = np.zeros((self._n_rows, 3))
        self._set = pbatch.Buffer()
        self._set.set_float_buf(self._set_values.reshape(-1))
        self._pose_buffer = pbatch.Buffer()
        self._offsets_3 = np.concatenate([self.offsets, np.zeros((n, 1))], axis=1)[:, None, :]

    def step(self) -> None:
        if self.batch:
            self._step_batch()
        else:
            self._step_loop()
        self.steps += 1

    def _step_loop(self) -> None:
        """World's loop over every copy's bodies, one ``space.step`` per substep."""
        h, space = self.h, self.space
        for ugv, value in zip(self.ugvs, self.current().reshape(-1, 3).tolist()):
            ugv.set_command(*value)
        self.contacts.clear()
        run_substeps(space, h, self.substeps, self.ugvs, self.reeling, self.paying)
        rows: list[float] = []
        for part in self.parts:
            for body in part.bodies:
                x, y = body.position
                rows += (x, y, body.angle)
        self.poses = np.array(rows).reshape(self.poses.shape) - self._offsets_3

    def _step_batch(self) -> None:
        """``UGVBody.set_command`` and ``drive`` vectorised, bodies through :mod:`pymunk.batch`."""
        h, space = self.h, self.space
        command = self.current().reshape(-1, 3)
        vx, vy, omega = command[:, 0].copy(), command[:, 1].copy(), command[:, 2]
        speed = np.hypot(vx, vy)
        over = speed > self._max_speed
        if over.any():
            vx[over] *= self._max_speed[over] / speed[over]
            vy[over] *= self._max_speed[over] / speed[over]
        omega = np.minimum(np.maximum(omega, -self._max_yaw_rate), self._max_yaw_rate)
        self.contacts.clear()
        get, values = self._get, self._set_values
        robots, controls, step = self._robot_rows, self._control_rows, self._max_yaw_step
        for _ in range(self.substeps):
            get.clear()
            pbatch.get_space_bodies(space, _FIELDS_DRIVE, get)
            state = np.frombuffer(get.float_buf()).reshape(-1, 4)  # angle, vx, vy, omega
            values[:] = state[:, 1:]
            rate = state[robots, 3]
            next_rate = np.minimum(np.maximum(omega, rate - step), rate + step)
            half_turn = 0.5 * next_rate * h
            angle = state[robots, 0] + rate * h + half_turn
            turning = half_turn != 0.0
            chord = np.ones_like(half_turn)
            chord[turning] = np.sin(half_turn[turning]) / half_turn[turning]
            c, s = chord * np.cos(angle), chord * np.sin(angle)
            values[controls, 0] = c * vx - s * vy
            values[controls, 1] = s * vx + c * vy
            values[controls, 2] = omega
            pbatch.set_space_bodies(space, _FIELDS_SET, self._set)
            for sled in self.reeling:
                sled.reel(h)
            space.step(h)
            for sled in self.paying:
                sled.pay_out()
        buffer = self._pose_buffer
        buffer.clear()
        pbatch.get_space_bodies(space, _FIELDS_POSE, buffer)
        self.poses = np.frombuffer(buffer.float_buf()).reshape(-1, 3)[self._body_rows] - self._offsets_3



def compare_poses(reference: np.ndarray, other: np.ndarray) -> dict[str, Any]:
    """How far ``other`` (n, bodies, 3) is from ``reference``: copies bit-identical, copy 0
    bit-identical, largest position difference (m) and angle difference (rad)."""
    same = [a.tobytes() == b.tobytes() for a, b in zip(reference, other)]
    diff = np.abs(np.asarray(other) - np.asarray(reference))
    return {
        "exact": sum(same),
        "copies": len(same),
        "copy0_exact": bool(same[0]),
        "max_position_m": float(diff[..., :2].max()) if diff.size else 0.0,
        "max_angle_rad": float(diff[..., 2].max()) if diff.size else 0.0,
    }


def build_layouts(config: WorldConfig, n: int, seed: int = 0) -> dict[str, _Layout]:
    """The four layouts (:data:`LAYOUTS`) of ``n`` copies of ``config``."""
    copies = range(n)
    return {
        "World.step": WorldLayout(config, copies, seed),
        "per-copy": PerCopySpaces(config, copies, seed),
        "shared loop": SharedSpace(config, copies, seed, batch=False),
        "shared batch": SharedSpace(config, copies, seed, batch=True),
    }


def run_physics_bench(
    num_envs: Sequence[int] = (64, 256, 1024),
    steps: int = 20,
    rounds: int = 3,
    cases: Sequence[str] | None = None,
    seed: int = 0,
) -> list[dict[str, Any]]:
    """One row per case and ``num_envs``: every layout's env-steps/s over ``rounds``
    interleaved rounds of ``steps`` control steps (after one warm-up step), and the
    comparisons of the final poses (see the module docstring)."""
    from training.bench_common import best_of_rounds

    if rounds < 1 or steps < 1 or not num_envs or min(num_envs) < 1:
        raise ValueError(f"need rounds >= 1, steps >= 1 and num_envs >= 1, got {rounds}, {steps}, {list(num_envs)}")
    rows = []
    for label in cases if cases is not None else CASES:
        name, options = CASES[label]
        config = world_config(name, options)
        for n in num_envs:
            start = time.perf_counter()
            layouts = build_layouts(config, n, seed)
            build_s = time.perf_counter() - start
            for layout in layouts.values():
                layout.run(1)
            measures: list[Callable[[], dict]] = [lambda layout=layout: layout.run(steps) for layout in layouts.values()]
            best = best_of_rounds(measures, rounds)
            rates = {key: row["rounds_steps_per_s"] for key, row in zip(layouts, best)}
            world, per_copy, shared = layouts["World.step"], layouts["per-copy"], layouts["shared batch"]
            # A few copies alone in their own spaces at their shared-space offsets, stepped alike.
            check = sorted(set(range(min(n, CHECK_COPIES))) | {n - 1})
            alone = PerCopySpaces(config, check, seed, grid=n)
            alone.run(per_copy.steps)
            rows.append({
                "case": label,
                "num_envs": n,
                "steps": steps,
                "rounds": rounds,
                "build_s": build_s,
                "rates": rates,
                "replica": compare_poses(world.unwrapped_poses(), per_copy.poses),
                "shared loop": compare_poses(per_copy.poses, layouts["shared loop"].poses),
                "shared batch": compare_poses(per_copy.poses, shared.poses),
                "batch vs loop": compare_poses(layouts["shared loop"].poses, shared.poses),
                "at offsets": compare_poses(alone.poses, shared.poses[check]),
            })
            del layouts, measures, alone
    return rows


def _exact(result: dict[str, Any]) -> str:
    return f"{result['exact']}/{result['copies']}"


def _alone(result: dict[str, Any]) -> str:
    if result["exact"] == result["copies"]:
        return _exact(result)
    return f"{_exact(result)} ({result['max_position_m']:.0e})"


def format_physics_bench(rows: Sequence[dict[str, Any]]) -> str:
    """The table of :func:`run_physics_bench`'s rows, with a one-line verdict.

    Trajectory columns (final poses, copies bit-identical / compared): ``=World``
    per-copy against World.step; ``batch=loop`` the two shared layouts;
    ``=alone`` shared copies against the same copies alone in their own spaces at
    the same offsets; ``vs origin`` shared (minus offset) against per-copy at the
    origin: whether copy 0 (at the origin) is identical, and the largest position
    difference (m) over all copies.
    """
    head = (
        f"{'configuration':<21}{'N':>5}" + "".join(f"{key:>15}" for key in LAYOUTS)
        + f"{'batch/per-copy':>16}{'=World':>9}{'batch=loop':>11}{'=alone (max m)':>17}  vs origin"
    )
    lines = [head, f"{'':<26}" + "".join(f"{'best/median':>15}" for _ in LAYOUTS) + f"{'best/median':>16}", "-" * (len(head) + 14)]
    ratios = []
    for row in rows:
        rates = row["rates"]
        cells = "".join(f"{max(rates[k]):>9.0f}/{statistics.median(rates[k]):<5.0f}" for k in LAYOUTS)
        best = max(rates["shared batch"]) / max(rates["per-copy"])
        med = statistics.median(rates["shared batch"]) / statistics.median(rates["per-copy"])
        ratios.append(med)
        origin = row["shared batch"]
        lines.append(
            f"{row['case']:<21}{row['num_envs']:>5}{cells}{best:>10.2f}/{med:<5.2f}"
            f"{_exact(row['replica']):>9}{_exact(row['batch vs loop']):>11}{_alone(row['at offsets']):>17}  "
            f"copy0 {'exact' if origin['copy0_exact'] else 'DIFFERS'}, max {origin['max_position_m']:.1e} m"
        )
    if rows:
        first = rows[0]
        lines.append(
            f"(env-steps/s: set the commands, step the substeps, read every body's pose; {first['steps']} control steps "
            f"per layout and round, best/median of {first['rounds']} interleaved rounds; trajectories: copies with "
            "bit-identical final poses / copies compared)"
        )
        low, high = min(ratios), max(ratios)
        word = "faster" if low > 1.0 else ("slower" if high < 1.0 else "neither faster nor slower throughout")
        lines.append(
            f"verdict: one shared space with pymunk.batch runs the physics at {low:.2f}x to {high:.2f}x the median rate "
            f"of one space per copy ({word})"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Per-copy pymunk spaces against one shared space for a batched env.")
    parser.add_argument("--num-envs", type=int_list("copy count", 1), default=[64, 256, 1024], help="copies, comma-separated (default 64,256,1024)")
    parser.add_argument("--steps", type=int, default=20, help="control steps per layout and round (default 20)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (default 3)")
    parser.add_argument("--cases", default=",".join(CASES), help=f"comma-separated rows of {list(CASES)}")
    args = parser.parse_args(argv)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if args.steps < 1 or args.rounds < 1 or unknown or not cases:
        parser.error(f"--steps and --rounds must be >= 1 and --cases among {list(CASES)}")
    print(f"pymunk {pymunk.version}, numpy {np.__version__}, {time.strftime('%Y-%m-%d %H:%M')}")
    print(format_physics_bench(run_physics_bench(args.num_envs, args.steps, args.rounds, cases)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
