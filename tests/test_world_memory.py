"""Memory across resets: replaced pymunk spaces do not pile up.

Each reset builds a new pymunk space, which only Python's cyclic garbage
collector can free (see ``moma_env.world.world``). With the collector disabled
nothing would ever free them; the world's own reclamation must keep at most
``RETIRED_SPACE_LIMIT`` of them alive. Counting live spaces is a cheap, exact
proxy for the ~280 KiB of native memory each one holds (the RSS is measured by
``python -m training.bench_memory``, not here).
"""

from __future__ import annotations

import gc
from collections.abc import Iterator

import pymunk
import pytest

from moma_env.markers import board_for_robot
from moma_env.world import SledConfig, UGVConfig, World, WorldConfig
from moma_env.world.world import RETIRED_SPACE_LIMIT


def config() -> WorldConfig:
    return WorldConfig(
        ugvs=(UGVConfig("a", static=False), UGVConfig("b", initial_pose=(1.0, 0.0, 0.0), board=board_for_robot(2))),
        sleds=(SledConfig("s", robot="a", initial_pose=(-0.6, 0.0, 0.0), static=False),),
    )


def live_spaces() -> int:
    return sum(type(o) is pymunk.Space for o in gc.get_objects())


@pytest.fixture
def no_automatic_gc() -> Iterator[None]:
    """Python's collector off: only what the world collects itself is freed."""
    gc.collect()
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
        gc.collect()


def drive(world: World) -> None:
    for _ in range(3):
        world.step({"a": (0.2, 0.0, 0.3)})
        world.set_reel("s", 1.0)


def test_resets_keep_at_most_the_limit_of_replaced_spaces_alive(no_automatic_gc):
    world = World(config())
    before = live_spaces()
    resets = 3 * (RETIRED_SPACE_LIMIT + 1)
    for _ in range(resets):
        drive(world)
        world.reset()
    grown = live_spaces() - before
    # Without the reclamation every replaced space would still be alive.
    assert grown <= RETIRED_SPACE_LIMIT + 1 < resets


def test_a_world_replacing_another_shares_its_reclamation(no_automatic_gc):
    world = World(config())
    before = live_spaces()
    worlds = 3 * (RETIRED_SPACE_LIMIT + 1)
    for _ in range(worlds):
        drive(world)
        world = World(config(), replaces=world)
    assert live_spaces() - before <= RETIRED_SPACE_LIMIT + 1 < worlds


def test_a_collection_runs_once_per_limit_of_replaced_spaces_even_if_it_frees_nothing(no_automatic_gc, monkeypatch):
    """Spaces that survive a collection are referenced elsewhere: they are not waited for
    again, so a collection that frees nothing is not repeated at every reset."""
    calls = []
    monkeypatch.setattr(gc, "collect", lambda *args: calls.append(args) or 0)
    world = World(config())
    kept = []  # every replaced space stays alive: nothing is garbage
    for k in range(1, 2 * (RETIRED_SPACE_LIMIT + 1) + 1):
        kept.append(World(config(), replaces=world))
        world.step()  # changed since its reset: the next reset replaces its space
        world.reset()
        assert len(calls) == (2 * k) // (RETIRED_SPACE_LIMIT + 1)


def test_replaces_must_be_a_world():
    with pytest.raises(TypeError, match="replaces must be a World"):
        World(config(), replaces=config())  # type: ignore[arg-type]
