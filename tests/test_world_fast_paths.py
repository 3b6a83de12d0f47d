"""The world's fast paths agree bit for bit with the plain code they replaced.

``UGVBody.drive`` (clamps written as comparisons, pymunk's property setters
called directly) against its former body, and ``World.segment_blocked`` (the
shape filter of an ``ignore`` group kept per world) against the former query
that built the filter at every call; both kept here as the reference.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pymunk
import pytest

from moma_env.world import ArenaConfig, BoxObstacle, UGVConfig, World, WorldConfig
from moma_env.world.ugv import UGVBody


def _bits(*values: float) -> bytes:
    return struct.pack(f"{len(values)}d", *values)


def reference_drive(ugv: UGVBody) -> tuple[float, float, float]:
    """The former ``UGVBody.drive``: the control body's velocity (vx, vy) and angular velocity."""
    vx, vy, omega = ugv.command
    body = ugv.body
    rate = body.angular_velocity
    step = ugv.config.max_yaw_accel * ugv._substep
    next_rate = min(max(omega, rate - step), rate + step)
    half_turn = 0.5 * next_rate * ugv._substep
    angle = body.angle + rate * ugv._substep + half_turn
    chord = math.sin(half_turn) / half_turn if half_turn != 0.0 else 1.0
    c, s = chord * math.cos(angle), chord * math.sin(angle)
    return c * vx - s * vy, s * vx + c * vy, omega


def test_drive_matches_the_reference_on_random_states():
    rng = np.random.default_rng(7)
    space = pymunk.Space()
    ugv = UGVBody(UGVConfig("a", (0.0, 0.0, 0.0), static=False), space, pymunk.ShapeFilter(), 0.025)
    step = ugv.config.max_yaw_accel * 0.025
    specials = [0.0, -0.0, step, -step, 1e-300, -1e-300]
    for k in range(3000):
        rate = float(rng.normal(0.0, 2.0)) if k % 4 else float(rng.choice(specials))
        # Commands near, at and beyond the yaw-acceleration limit, and signed zeros.
        omega = rate + float(rng.choice([-1.0, 1.0])) * step * float(rng.choice([0.0, 0.5, 1.0, 1.5]))
        if k % 7 == 0:
            omega = float(rng.choice(specials))
        ugv.body.angle = float(rng.uniform(-50.0, 50.0)) if k % 5 else float(rng.choice(specials))
        ugv.body.angular_velocity = rate
        vx, vy = (float(rng.normal()), float(rng.normal())) if k % 3 else (0.0, -0.0)
        ugv.command = (vx, vy, omega)
        expected = reference_drive(ugv)
        ugv.drive()
        vx, vy = ugv.control.velocity
        assert _bits(vx, vy, ugv.control.angular_velocity) == _bits(*expected), (k, rate, omega)


def reference_segment_blocked(world: World, a, b, ignore) -> bool:
    """The former ``World.segment_blocked`` after its points were checked."""
    mask = pymunk.ShapeFilter.ALL_MASKS()
    shared = False
    indices = [world._body_index(name) for name in ignore]
    for i in indices:
        if i >= 30:
            shared = True
        else:
            mask &= ~(1 << (1 + i))
    if not shared:
        return world._space.segment_query_first(a, b, 0.0, pymunk.ShapeFilter(mask=mask)) is not None
    ignored = {world._shapes[i] for i in indices}
    hits = world._space.segment_query(a, b, 0.0, pymunk.ShapeFilter(mask=mask))
    return any(hit.shape not in ignored for hit in hits)


@pytest.mark.parametrize("n_robots", [4, 36])
def test_segment_blocked_matches_the_reference_on_random_segments(n_robots: int):
    arena = ArenaConfig(obstacles=(BoxObstacle(2.0, 2.0, 0.4, 0.4),))
    ugvs = tuple(
        UGVConfig(f"r{i}", (-1.2 + 0.46 * (i % 12), -1.0 + 0.5 * (i // 12), 0.0), static=False, board=None)
        for i in range(n_robots)
    )
    world = World(WorldConfig(arena=arena, ugvs=ugvs))
    names = world.ugv_names
    rng = np.random.default_rng(3)
    groups = [tuple(rng.choice(names, size=int(rng.integers(0, 4)))) for _ in range(12)]
    groups += [(names[-1],), (names[0], names[-1]), ()]
    for k in range(1500):
        if k == 700:
            world.reset()  # the kept filters outlive a reset (they depend on the names only)
        if k % 100 == 50:
            world.step({name: (0.5, 0.2, 0.3) for name in names})
        points = rng.uniform(-3.0, 5.0, 4)
        a, b = (points[0], points[1]), (points[2], points[3])
        group = groups[k % len(groups)]
        kinds = (tuple(group), list(group), set(group), frozenset(group), iter(group))
        ignore = kinds[k % len(kinds)]
        expected = reference_segment_blocked(world, a, b, group)
        assert world.segment_blocked(np.array(a), np.array(b), ignore=ignore) == expected, (k, a, b, group)


def test_segment_blocked_still_rejects_unknown_names_after_known_ones():
    world = World(WorldConfig(ugvs=(UGVConfig("a", (0.0, 0.0, 0.0), static=False),)))
    assert world.segment_blocked((-1.0, 0.0), (1.0, 0.0), ignore=("a",)) is False
    for bad in (("a", "c"), ("c",), (["a"],), ("a", None)):
        with pytest.raises(KeyError, match="unknown ugv or sled"):
            world.segment_blocked((-1.0, 0.0), (1.0, 0.0), ignore=bad)
    with pytest.raises(ValueError, match="p_from_xy"):
        world.segment_blocked((float("inf"), 0.0), (1.0, 0.0), ignore=("a",))
