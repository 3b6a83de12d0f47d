"""The physics-layout benchmark (training.bench_physics): what it builds and reports, not how fast."""

import numpy as np
import pytest

from training.bench_physics import (
    CASES,
    LAYOUTS,
    PerCopySpaces,
    SharedSpace,
    WorldLayout,
    format_physics_bench,
    grid_offsets,
    main,
    run_physics_bench,
    world_config,
)


def test_the_table_has_a_row_per_case_and_size_with_every_layout():
    rows = run_physics_bench([1, 3], steps=3, rounds=2)
    assert [(r["case"], r["num_envs"]) for r in rows] == [(c, n) for c in CASES for n in (1, 3)]
    for row in rows:
        assert set(row["rates"]) == set(LAYOUTS)
        assert all(len(v) == 2 and min(v) > 0 for v in row["rates"].values())
        # The per-copy replica of World's physics is World's, bit for bit; the two shared layouts agree.
        assert row["replica"]["exact"] == row["num_envs"]
        assert row["batch vs loop"]["exact"] == row["num_envs"]
        assert row["shared batch"]["copy0_exact"]
    text = format_physics_bench(rows)
    lines = text.splitlines()
    assert sum(line.startswith("top_observer 8 UGVs") for line in lines) == 2
    assert lines[-1].startswith("verdict: ")


def test_the_shared_space_keeps_copies_apart_and_poses_finite():
    config = world_config("top_observer", {"n_ugvs": 8})
    n, steps = 6, 40
    offsets = grid_offsets(config, n)
    # Walls of neighbouring copies never overlap: the pitch exceeds the walled arena.
    walled = config.arena.width + 2 * config.arena.wall_thickness
    assert np.diff(np.unique(offsets[:, 0])).min() > walled
    shared = SharedSpace(config, range(n))
    shared.run(steps)
    poses = shared.poses
    assert poses.shape == (n, 8, 3) and np.isfinite(poses).all()
    # Every robot still inside its own copy's arena (poses are relative to the copy's offset).
    xmin, ymin, xmax, ymax = config.arena.bounds
    assert (poses[..., 0] > xmin).all() and (poses[..., 0] < xmax).all()
    assert (poses[..., 1] > ymin).all() and (poses[..., 1] < ymax).all()
    # The robots did move: the commands are not all zero.
    start = np.array([u.initial_pose for u in config.ugvs])
    assert np.abs(poses - start).max() > 0.1
    # Copy k alone in the space at the same offset: no other copy touches it (bounded
    # difference: the solver's order of contacts may change the last bits, which a
    # crowded arena amplifies).
    for k in (0, n - 1):
        alone = SharedSpace(config, [k], grid=n)
        alone.run(steps)
        assert np.abs(alone.poses[0] - poses[k]).max() < 1e-3


def test_a_copy_of_two_robots_is_bit_identical_alone_or_shared_and_to_world():
    config = world_config("top_observer")
    n, steps = 5, 30
    shared = SharedSpace(config, range(n))
    shared.run(steps)
    world = WorldLayout(config, range(n))
    world.run(steps)
    per_copy = PerCopySpaces(config, range(n))
    per_copy.run(steps)
    assert world.unwrapped_poses().tobytes() == per_copy.poses.tobytes()
    assert shared.poses[0].tobytes() == per_copy.poses[0].tobytes()  # copy 0 sits at the origin
    for k in range(n):
        alone = PerCopySpaces(config, [k], grid=n)
        alone.run(steps)
        assert alone.poses[0].tobytes() == shared.poses[k].tobytes()


def test_sleds_step_alike_in_every_layout():
    config = world_config("caterpillar_sled")
    assert config.sleds
    world, per_copy, shared = WorldLayout(config, range(2)), PerCopySpaces(config, range(2)), SharedSpace(config, range(2))
    for layout in (world, per_copy, shared):
        layout.run(20)
    assert world.unwrapped_poses().tobytes() == per_copy.poses.tobytes()
    assert per_copy.poses.shape == shared.poses.shape == (2, len(config.ugvs) + len(config.sleds), 3)
    assert np.abs(per_copy.poses - shared.poses).max() < 1e-6


def test_the_command_line_refuses_bad_sizes():
    with pytest.raises(SystemExit):
        main(["--num-envs", "0"])
    with pytest.raises(SystemExit):
        main(["--cases", "nope"])
    with pytest.raises(ValueError, match="num_envs >= 1"):
        run_physics_bench([0])
