"""Copies of the world (copy.deepcopy, pickle) continue bit for bit like the original.

pymunk cannot copy the world's space exactly (a copied constraint loses its
accumulated impulse, Chipmunk's warm start); the world replays its journal
instead. These tests copy a world before any step, after a reset and in the
middle of a run where robots drive, one robot is static, a sled reels in and
shapes touch, then step the original, the copy and a twin that was never copied
with the same calls and compare everything the world reports, exactly.
"""

from __future__ import annotations

import copy
import math
import pickle
from array import array
from collections.abc import Callable

import numpy as np
import pytest

from moma_env.markers import board_for_robot
from moma_env.world import ArenaConfig, BoxObstacle, SledConfig, UAVConfig, UGVConfig, World, WorldConfig

#: A small walled arena: robot "a" tows sled "s" towards static robot "b"; robot "c"
#: drives into the north wall; the UAV flies. Boards avoid the sled's ids (4..7).
CONFIG = WorldConfig(
    arena=ArenaConfig(width=3.0, height=2.0, origin=(-1.5, -1.0), obstacles=(BoxObstacle(-1.0, 0.7, 0.3, 0.3, 0.4),)),
    ugvs=(
        UGVConfig("a", (0.0, 0.0, 0.0), static=False, board=board_for_robot(0)),
        UGVConfig("b", (0.75, 0.05, 0.0), static=True, board=board_for_robot(2)),
        UGVConfig("c", (0.0, 0.6, 1.2), static=False, board=board_for_robot(3)),
    ),
    sleds=(SledConfig("s", "a", initial_pose=(-0.65, 0.0, 0.0), static=False),),
    uavs=(UAVConfig(),),
)

COPIES: dict[str, Callable[[World], World]] = {
    "deepcopy": copy.deepcopy,
    "pickle": lambda world: pickle.loads(pickle.dumps(world)),
}


def act(world: World, k: int) -> None:
    """The calls of step ``k`` of the schedule: commands that change every step, a
    static lock and release, reel rates in and out, a UAV that flies and hovers."""
    if k % 40 == 25:
        world.set_static("c", True)
    if k % 40 == 35:
        world.set_static("c", False)
    if k % 30 == 0:
        world.set_reel("s", 1.0 if (k // 30) % 2 == 0 else -0.5)
    commands = {
        "a": (0.45, 0.05 * math.sin(k / 5.0), 0.4 * math.sin(k / 9.0)),
        "c": (0.3 * math.cos(k / 7.0), 0.35, 0.8),
    }
    if k % 11 == 0:
        del commands["c"]  # left out: a zero command
    uav = None if k % 13 == 0 else (0.3, 0.2 * math.sin(k / 4.0), 0.5, 0.1 * math.cos(k / 6.0))
    world.step(commands, uav)


def observed(world: World) -> tuple:
    """Everything the world reports, as exactly comparable values."""
    return (
        world.state_array().tobytes(),
        world.ugv_poses().tobytes(),
        world.collisions_since_last_step,
        tuple(world.ugv_body_velocity(name) for name in world.ugv_names),
        tuple(world.is_static(name) for name in world.ugv_names + world.sled_names),
        world.sled_pose("s"),
        world.rope_length("s"),
        world.reel_rate("s"),
        world.uav_state,
        world.uav_transform().tobytes(),
        tuple(world.board_transform(name).tobytes() for name in world.ugv_names + world.sled_names),
        tuple(world.camera_transform(name).tobytes() for name in world.camera_names),
        world.step_count,
        world.time,
        world.segment_blocked((-1.4, -0.9), (1.4, 0.9)),
    )


def run(world: World, start: int, steps: int) -> None:
    for k in range(start, start + steps):
        act(world, k)


def prepared(moment: str) -> tuple[World, int]:
    """A world at ``moment`` (``fresh``, ``reset``, ``mid-run``) and the schedule step it is at."""
    world = World(CONFIG)
    if moment == "fresh":
        return world, 0
    run(world, 0, 60)
    if moment == "reset":
        world.reset()
        return world, 0
    return world, 60


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize("moment", ["fresh", "reset", "mid-run"])
def test_a_copy_continues_bit_for_bit_like_the_original(moment, how):
    world, k = prepared(moment)
    twin, _ = prepared(moment)  # never copied
    if moment == "mid-run":
        # What the copy must carry over: moving robots, a static one, a reeling sled, contacts.
        assert world.collisions_since_last_step
        assert world.is_static("b") and not world.is_static("a") and not world.is_static("s")
        assert world.reel_rate("s") != 0.0
        assert any(v != 0.0 for v in world.ugv_body_velocity("a"))
    clone = COPIES[how](world)
    assert clone is not world
    assert observed(clone) == observed(world) == observed(twin)
    contacts = 0
    for step in range(k, k + 150):
        act(world, step)
        act(clone, step)
        act(twin, step)
        assert observed(clone) == observed(world) == observed(twin), f"step {step}"
        contacts += bool(clone.collisions_since_last_step)
    assert contacts > 10  # the run did test the copy's collision handler


@pytest.mark.parametrize("how", sorted(COPIES))
def test_the_copy_records_contacts_in_its_own_containers(how):
    world, k = prepared("mid-run")
    while world.collisions_since_last_step:  # drive out of contact first
        world.step({"a": (-0.3, 0.0, 0.0), "c": (0.0, -0.3, 0.0)})
    assert not world.collisions_since_last_step
    before = observed(world)
    clone = COPIES[how](world)
    touched = False
    for _ in range(100):  # drive the copy alone into robot b
        clone.step({"a": (0.5, 0.0, 0.0)})
        touched = touched or frozenset(("a", "b")) in clone.collisions_since_last_step
    assert touched
    assert observed(world) == before  # the original neither moved nor saw a contact
    world.step({"a": (-0.3, 0.0, 0.0)})
    assert not world.collisions_since_last_step


def test_copies_of_copies_and_the_original_stay_independent():
    world, k = prepared("mid-run")
    first = copy.deepcopy(world)
    run(first, k, 20)
    second = pickle.loads(pickle.dumps(first))
    third = copy.deepcopy(second)
    run(world, k, 20)
    assert observed(first) == observed(world)
    for clone in (second, third):
        run(clone, k + 20, 40)
    run(world, k + 20, 40)
    assert observed(second) == observed(third) == observed(world)
    assert observed(first) != observed(world)  # first stayed 40 steps behind


def test_a_deep_copy_shares_the_frozen_configuration_and_a_pickle_rebuilds_an_equal_one():
    world, _ = prepared("mid-run")
    assert copy.deepcopy(world).config is world.config
    assert pickle.loads(pickle.dumps(world)).config == world.config


def test_the_journal_starts_again_at_every_reset():
    world, _ = prepared("mid-run")
    long_run = len(pickle.dumps(world))
    world.reset()
    fresh = len(pickle.dumps(World(CONFIG)))
    assert len(pickle.dumps(world)) == fresh < long_run
    ops, values = world.__getstate__()["journal"]
    assert len(ops) == 0 and len(values) == 0


@pytest.mark.parametrize("moment", ["fresh", "reset"])
def test_a_reset_of_an_unchanged_world_keeps_its_space_and_runs_like_a_fresh_one(moment):
    world, _ = prepared(moment)
    space = world._space
    world.reset()
    world.reset(np.random.default_rng(0))
    assert world._space is space
    twin = World(CONFIG)
    assert observed(world) == observed(twin)
    run(world, 0, 60)
    run(twin, 0, 60)
    assert observed(world) == observed(twin)


@pytest.mark.parametrize("change", ["step", "set_static", "set_reel"])
def test_any_change_makes_the_next_reset_rebuild_the_space(change):
    world = World(CONFIG)
    space = world._space
    {"step": lambda: world.step(), "set_static": lambda: world.set_static("a", True), "set_reel": lambda: world.set_reel("s", 0.5)}[change]()
    world.reset()
    assert world._space is not space
    assert observed(world) == observed(World(CONFIG))


def test_a_state_that_does_not_replay_to_its_fingerprint_is_refused():
    world, _ = prepared("mid-run")
    state = world.__getstate__()
    data, steps, contacts = state["fingerprint"]
    state["fingerprint"] = (data, steps + 1, contacts)
    with pytest.raises(RuntimeError, match="did not reproduce its state"):
        World.__new__(World).__setstate__(state)


@pytest.mark.parametrize(
    "change, error",
    [
        (lambda state: state.update(version=99), "not the state of a World"),
        (lambda state: state.update(config="config"), "not a WorldConfig"),
        (lambda state: state.update(journal=(state["journal"][0] + b"\x00", state["journal"][1])), "truncated"),
        (lambda state: state.update(journal=(state["journal"][0] + b"\x07", state["journal"][1])), "unknown journal entry"),
        (lambda state: state.update(journal=(state["journal"][0][:-1], state["journal"][1])), "left over"),
        (lambda state: state.update(journal=(b"\x02", array("d", [5.0, 0.5]))), "names device 5.0 of 1"),
        (lambda state: state.update(journal=(b"\x00", array("d", [0.0, 0.0, 0.0, 1.0, 0.1]))), "truncated"),
    ],
)
def test_a_malformed_state_is_refused_with_a_clear_error(change, error):
    world, _ = prepared("mid-run")
    state = world.__getstate__()
    change(state)
    with pytest.raises(ValueError, match=error):
        World.__new__(World).__setstate__(state)


def test_failed_steps_change_nothing_and_are_not_recorded():
    world, k = prepared("mid-run")
    twin, _ = prepared("mid-run")
    with pytest.raises(KeyError):
        world.step({"a": (1.0, 0.0, 0.0), "nobody": (0.0, 0.0, 0.0)})
    with pytest.raises(ValueError):
        world.step({"a": (1.0, 0.0, 0.0), "c": (math.nan, 0.0, 0.0)})
    with pytest.raises(ValueError):
        world.set_reel("s", 2.0)
    assert world.__getstate__()["journal"][0] == twin.__getstate__()["journal"][0]
    clone = copy.deepcopy(world)
    run(world, k, 50)
    run(twin, k, 50)
    run(clone, k, 50)
    assert observed(world) == observed(twin) == observed(clone)
    np.testing.assert_array_equal(world.state_array(), clone.state_array())
