"""Seeded random configurations: always valid, boards in view, corridors clear, reproducible."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.camera import BoardView, GeometricCamera
from moma_env.config import ConfigError
from moma_env.scenarios import (
    CONFIGURATIONS,
    CaterpillarMultiConfig,
    CaterpillarSledConfig,
    Scenario,
    TopObserverConfig,
    missing_views,
    random_config,
    start_boards,
)
from moma_env.scenarios.layout import convex_polygons_distance
from moma_env.scenarios.sampling import (
    CORRIDOR_CLEARANCE_M,
    MAX_ATTEMPTS,
    Redraw,
    draw_until_valid,
    random_surroundings,
)
from moma_env.world import World
from moma_env.world.arena import box_corners, disk_overlaps_box

NAMES = tuple(CONFIGURATIONS)
SEEDS = st.integers(min_value=0, max_value=2**63 - 1)


def check_random_config(name: str, seed: int) -> None:
    config = random_config(name, np.random.default_rng(seed))
    assert type(config) is CONFIGURATIONS[name]
    scenario = config.scenario()
    assert isinstance(scenario, Scenario) and scenario.name == name

    # Every required board is seen whole at the start, by the model and by the
    # geometric camera in the reset world (zero noise).
    assert missing_views(scenario, config.required_views()) == []
    world = World(scenario.world)
    camera = dataclasses.replace(scenario.camera, noise_px=0.0)
    boards = start_boards(scenario.world)
    for camera_name, owners in config.required_views().items():
        views = [BoardView(i, boards[owner][0], world.board_transform(owner)) for i, owner in enumerate(owners)]
        found = GeometricCamera(camera_name, camera).measure(
            world.camera_transform(camera_name), views, 0.0, np.random.default_rng(0)
        )
        assert [d.marker_ids for d in found] == [boards[owner][0].marker_ids for owner in owners]

    # Ranges.
    arena = scenario.world.arena
    assert 4.0 <= arena.width <= 10.0 and 4.0 <= arena.height <= 10.0
    assert 350.0 <= scenario.camera.fx <= 600.0 and 0.0 <= scenario.camera.noise_px <= 1.0
    k1, k2, p1, p2, k3 = scenario.camera.dist
    assert abs(k1) <= 0.1 and abs(k2) <= 0.02 and p1 == p2 == k3 == 0.0
    for ugv in scenario.world.ugvs:
        start, goal = ugv.initial_pose, scenario.goals.get(ugv.name)
        assert goal is not None
        assert 1.0 - 1e-9 <= math.hypot(goal[0] - start[0], goal[1] - start[1]) <= 3.0 + 1e-9
    if isinstance(config, (TopObserverConfig, CaterpillarMultiConfig)):
        assert 2 <= config.n_ugvs <= 4
    if isinstance(config, TopObserverConfig):
        assert 1.2 <= scenario.world.uav.altitude <= 2.5
    if isinstance(config, CaterpillarSledConfig):
        assert config.min_rope <= config.rope_length <= config.max_rope

    # Obstacles: at most 4, inside the arena, clear of every start and goal and
    # of the corridor between them.
    assert len(arena.obstacles) <= 4
    xmin, ymin, xmax, ymax = arena.bounds
    disks = config.occupied_disks
    keep_out = max(r for *_, r in disks) + CORRIDOR_CLEARANCE_M
    corridor = config.corridor()
    for obstacle in arena.obstacles:
        corners = box_corners(obstacle)
        assert (corners >= (xmin, ymin)).all() and (corners <= (xmax, ymax)).all()
        for _, x, y, radius in disks:
            assert not disk_overlaps_box(x, y, radius + CORRIDOR_CLEARANCE_M, obstacle)
        assert convex_polygons_distance(corridor, corners) >= keep_out - 1e-9


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=50, deadline=None)
@given(seed=SEEDS)
def test_random_configs_are_valid_and_see_their_boards(name, seed):
    check_random_config(name, seed)


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_config_different_seeds_differ(name):
    first = [random_config(name, np.random.default_rng(seed)) for seed in range(8)]
    again = [random_config(name, np.random.default_rng(seed)) for seed in range(8)]
    assert first == again
    assert [c.scenario().world for c in first] == [c.scenario().world for c in again]
    assert len({repr(c) for c in first}) == len(first)
    # The classmethod and the registry draw the same.
    assert CONFIGURATIONS[name].random(np.random.default_rng(3)) == first[3]


@pytest.mark.parametrize("name", NAMES)
def test_random_draws_cover_the_ranges(name):
    configs = [random_config(name, np.random.default_rng(seed)) for seed in range(60)]
    counts = {len(c.obstacles) for c in configs}
    assert counts == {0, 1, 2, 3, 4}
    yaws = [c.start[2] for c in configs]
    assert min(yaws) < -2.0 and max(yaws) > 2.0
    if name in ("top_observer", "caterpillar_multi"):
        assert {c.n_ugvs for c in configs} == {2, 3, 4}
    if name == "top_observer":
        assert {c.observer for c in configs} == {"quadcopter", "handheld"}
        assert {c.formation for c in configs} == {"compact", "row"}


def test_random_config_needs_a_generator():
    with pytest.raises(TypeError, match="Generator"):
        random_config("caterpillar", 42)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="caterpillar_multi"):
        random_config("caterpilar", np.random.default_rng(0))


def test_generator_gives_up_with_a_clear_error():
    calls = []

    def never_valid(rng: np.random.Generator) -> TopObserverConfig:
        calls.append(rng.uniform())
        return TopObserverConfig(n_ugvs=1)

    with pytest.raises(RuntimeError, match=r"no valid random top_observer configuration .*n_ugvs"):
        draw_until_valid(TopObserverConfig, np.random.default_rng(0), never_valid)
    assert len(calls) == MAX_ATTEMPTS


def test_generator_rejects_draws_whose_boards_are_out_of_view():
    def too_wide(rng: np.random.Generator) -> TopObserverConfig:
        return TopObserverConfig(n_ugvs=6, formation="row", altitude=1.2)

    with pytest.raises(RuntimeError, match="markers visible"):
        draw_until_valid(TopObserverConfig, np.random.default_rng(0), too_wide)


def test_surroundings_redraw_when_the_footprints_do_not_fit():
    disks = (("a", 0.0, 0.0, 0.2), ("b", 9.8, 0.0, 0.2))
    with pytest.raises(Redraw):
        random_surroundings(np.random.default_rng(0), disks)
