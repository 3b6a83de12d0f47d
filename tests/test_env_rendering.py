"""The scene an environment hands to the renderer (moma_env.env.rendering.scene_of)."""

import numpy as np
import pytest

from moma_env.env.factory import parallel_env
from moma_env.env.rendering import scene_of


@pytest.mark.parametrize("name", ["caterpillar", "caterpillar_sled", "caterpillar_multi"])
def test_ground_cameras_show_their_view_inside_the_arena(name):
    env = parallel_env(name)
    env.reset(seed=0)
    scene = scene_of(env.simulation)
    world = env.world
    assert len(scene.footprints) == len(world.camera_names) >= 1
    xmin, ymin, xmax, ymax = env.scenario.world.arena.bounds
    for camera_name, polygon in zip(world.camera_names, scene.footprints):
        assert len(polygon) >= 3 and np.isfinite(polygon).all()
        tol = 1e-4  # the clip to the arena runs in float32
        assert (polygon[:, 0] >= xmin - tol).all() and (polygon[:, 0] <= xmax + tol).all()
        assert (polygon[:, 1] >= ymin - tol).all() and (polygon[:, 1] <= ymax + tol).all()
        # The camera sits at a vertex of its view, which opens along its optical axis.
        T_w_c = world.camera_transform(camera_name)
        apex = T_w_c[:2, 3]
        assert np.min(np.hypot(*(polygon - apex).T)) < 1e-4
        axis = T_w_c[:2, 2] / np.hypot(*T_w_c[:2, 2])
        centroid = polygon.mean(axis=0)
        assert float((centroid - apex) @ axis) > 0.5


def test_the_uav_shows_its_ground_footprint_only():
    env = parallel_env("top_observer")
    env.reset(seed=0)
    scene = scene_of(env.simulation)
    assert len(scene.footprints) == 1
    footprint = scene.footprints[0]
    assert footprint.shape == (4, 2) and np.isfinite(footprint).all()
    s = env.world.uav_state
    assert footprint[:, 0].min() < s.x < footprint[:, 0].max() and footprint[:, 1].min() < s.y < footprint[:, 1].max()
