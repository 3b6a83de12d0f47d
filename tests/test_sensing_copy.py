"""Copies of the cameras, the floor texture and the MOMA estimator continue like the originals.

A small pipeline (the world, every camera, the estimator and the camera noise's
generator, as the environment wires them) runs a leapfrog schedule; it is copied
with ``copy.deepcopy`` or ``pickle`` in the middle of the run, then the original,
the copy and a twin that was never copied run on with the same calls and must
produce the same images, detections and estimates, bit for bit. Both camera
backends are covered: the geometric one, and the rendered one with a textured
floor, interlacing and floor-view reuse (state carried from frame to frame),
ground cameras with occlusion queries included.
"""

from __future__ import annotations

import copy
import math
import pickle
from collections.abc import Callable

import numpy as np
import pytest

from moma_env.camera import BoardView, FloorConfig, FloorTexture, GeometricCamera, RenderConfig, RenderedCamera, up_in_board
from moma_env.estimator import MomaEstimator
from moma_env.scenarios import CONFIGURATIONS
from moma_env.world import World

COPIES: dict[str, Callable[[object], object]] = {
    "deepcopy": copy.deepcopy,
    "pickle": lambda thing: pickle.loads(pickle.dumps(thing)),
}


class Pipeline:
    """World, cameras and estimator of one configuration, stepped by a fixed schedule."""

    def __init__(self, configuration: str, backend: str, seed: int = 0) -> None:
        scenario = CONFIGURATIONS[configuration]().scenario()
        wc = scenario.world
        self.world = World(wc)
        self.rng = np.random.default_rng(seed)
        self.devices = wc.ugv_names + wc.sled_names
        self.mounts = {d.name: d.board_mount for d in (*wc.ugvs, *wc.sleds)}
        self.layouts = {ugv.name: (i, ugv.board) for i, ugv in enumerate(wc.ugvs) if ugv.board is not None}
        self.layouts.update({sled.name: (len(wc.ugvs) + k, sled.board) for k, sled in enumerate(wc.sleds)})
        owners = {cam.name: ugv.name for ugv in wc.ugvs for cam in ugv.cameras}
        if wc.uav is not None:
            owners[wc.uav.camera_name] = wc.uav.name
        self.owners = owners
        self.uav_camera = wc.uav.camera_name if wc.uav is not None else None
        if backend == "geometric":
            self.cameras = {name: GeometricCamera(name, scenario.camera) for name in owners}
        else:
            x0, y0, x1, y1 = wc.arena.bounds
            floor = FloorTexture(FloorConfig(extent=(x0 - 0.5, y0 - 0.5, x1 + 0.5, y1 + 0.5), px_per_m=120.0))
            render = RenderConfig(interlaced=True, floor_reuse_px=0.25, noise_std=6.0, blur_sigma_px=1.0)
            self.cameras = {name: RenderedCamera(name, scenario.camera, render, floor) for name in owners}
        est = MomaEstimator(scenario.estimator)
        for ugv in wc.ugvs:
            boards = {self.layouts[ugv.name][0]: ugv.board_mount} if ugv.name in self.layouts else {}
            est.add_robot(
                ugv.name,
                boards=boards,
                cameras={c.name: c.T_b_c for c in ugv.cameras},
                static=True,
                initial_pose=self.world.ugv_transform(ugv.name),
                time=0.0,
                planar=True,
            )
        for sled in wc.sleds:
            est.add_robot(
                sled.name,
                boards={self.layouts[sled.name][0]: sled.board_mount},
                static=True,
                initial_pose=self.world.sled_transform(sled.name),
                time=0.0,
                planar=True,
            )
        if wc.uav is not None:
            est.add_robot(wc.uav.name, cameras={wc.uav.camera_name: wc.uav.camera_mount}, static=False, time=0.0)
        self.estimator = est
        self.mobile = wc.ugv_names[0]
        self.detections: list = []

    def occluded(self, camera: str, p_from: np.ndarray, p_to: np.ndarray) -> bool:
        """Line of sight of a ground camera: anything but its owner and the nearest device blocks it."""
        x, y = float(p_to[0]), float(p_to[1])
        poses = {d: self.world.sled_pose(d) if d in self.world.sled_names else self.world.ugv_pose(d) for d in self.devices}
        nearest = min(poses, key=lambda d: (poses[d][0] - x) ** 2 + (poses[d][1] - y) ** 2)
        return self.world.segment_blocked(p_from[:2], p_to[:2], ignore=(self.owners[camera], nearest))

    def views(self) -> list[BoardView]:
        return [
            BoardView(board_id, layout, self.world.board_transform(device), up_in_board(self.mounts[device]))
            for device, (board_id, layout) in self.layouts.items()
        ]

    def frame(self, k: int) -> None:
        """Step ``k`` of the schedule: a robot is released, driven and locked again in turn."""
        world, est = self.world, self.estimator
        if k % 40 == 10:
            world.set_static(self.mobile, False)
            est.set_static(self.mobile, False, world.time)
        if k % 40 == 30:
            world.set_static(self.mobile, True)
            est.set_static(self.mobile, True, world.time)
            names = world.ugv_names
            self.mobile = names[(names.index(self.mobile) + 1) % len(names)]
        for sled in world.sled_names:
            world.set_reel(sled, 0.5 if k % 40 < 20 else -0.5)
        command = {self.mobile: (0.15, 0.0, 0.3 * math.sin(k / 6.0))}
        uav = (0.1 * math.cos(k / 8.0), 0.1 * math.sin(k / 8.0), 0.2, 0.0) if world.has_uav else None
        world.step(command, uav)
        views = self.views()
        detections = []
        for name, camera in self.cameras.items():
            query = None if name == self.uav_camera else (lambda a, b, name=name: self.occluded(name, a, b))
            detections += camera.measure(world.camera_transform(name), views, world.time, self.rng, query)
        est.update(world.time, detections)
        self.detections = detections

    def observed(self) -> tuple:
        """The frame's images, detections and estimates, as exactly comparable values."""
        images = tuple(
            None if getattr(c, "last_image", None) is None else c.last_image.tobytes() for c in self.cameras.values()
        )
        detections = tuple(
            (d.camera_id, d.board_id, d.T_c_m.tobytes(), d.corners_px.tobytes(), d.marker_ids, d.time,
             d.reprojection_error_px, None if d.covariance is None else d.covariance.tobytes())
            for d in self.detections
        )
        estimates = tuple(
            (e.name, None if e.T_w_b is None else e.T_w_b.tobytes(), e.status, e.phase, e.last_fresh_time, e.n_window,
             None if e.covariance is None else e.covariance.tobytes())
            for e in self.estimator.estimates().values()
        )
        located = tuple(
            (name, None if (T := self.estimator.camera_pose(name)) is None else T.tobytes()) for name in self.cameras
        )
        return images, detections, estimates, located, self.estimator.events, self.world.state_array().tobytes()


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize(
    "configuration, backend, before, after",
    [
        ("top_observer", "geometric", 45, 100),
        ("caterpillar_sled", "geometric", 45, 100),
        ("top_observer", "rendered", 15, 15),
        ("caterpillar", "rendered", 15, 12),
    ],
)
def test_a_copied_pipeline_continues_like_the_original(configuration, backend, before, after, how):
    pipeline, twin = Pipeline(configuration, backend), Pipeline(configuration, backend)
    for k in range(before):
        pipeline.frame(k)
        twin.frame(k)
    assert pipeline.detections  # the cameras see boards
    clone = COPIES[how](pipeline)
    assert clone.world is not pipeline.world and clone.estimator is not pipeline.estimator
    assert observed_equal(clone, pipeline, twin)
    detected = 0
    for k in range(before, before + after):
        for p in (pipeline, clone, twin):
            p.frame(k)
        assert observed_equal(clone, pipeline, twin), f"frame {k}"
        detected += len(clone.detections)
    assert detected >= after // 2  # the frames do detect boards
    assert len(clone.estimator.events) > 0  # the copy switched robots


def observed_equal(*pipelines: Pipeline) -> bool:
    first = pipelines[0].observed()
    return all(p.observed() == first for p in pipelines[1:])


@pytest.mark.parametrize("how", sorted(COPIES))
def test_copied_cameras_share_a_floor_texture_as_the_originals_do(how):
    pipeline = Pipeline("caterpillar_multi", "rendered")
    floors = {id(c.floor) for c in pipeline.cameras.values()}
    assert len(pipeline.cameras) > 1 and len(floors) == 1
    clone = COPIES[how](pipeline)
    assert len({id(c.floor) for c in clone.cameras.values()}) == 1
    assert next(iter(clone.cameras.values())).floor is not next(iter(pipeline.cameras.values())).floor


@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_camera_copied_alone_measures_like_the_original_with_its_own_caches(how):
    """A camera copied after use, then shown boards whose layouts are new (equal) objects."""
    pipeline = Pipeline("top_observer", "rendered")
    for k in range(5):
        pipeline.frame(k)
    name = pipeline.uav_camera
    camera = pipeline.cameras[name]
    clone = COPIES[how](camera)
    views = pipeline.views()
    new_views = [BoardView(v.board_id, copy.deepcopy(v.layout), v.T_w_m, v.up_m) for v in views]
    T_w_c = pipeline.world.camera_transform(name)
    rng_a, rng_b = np.random.default_rng(7), np.random.default_rng(7)
    a = camera.measure(T_w_c, views, 1.0, rng_a)
    b = clone.measure(T_w_c, new_views, 1.0, rng_b)
    assert a and [d.T_c_m.tobytes() for d in a] == [d.T_c_m.tobytes() for d in b]
    assert np.array_equal(camera.last_image, clone.last_image)


@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_floor_texture_copy_draws_the_same_floor(how):
    floor = FloorTexture(FloorConfig(extent=(-1.0, -1.0, 1.0, 1.0), px_per_m=100.0))
    pipeline = Pipeline("top_observer", "geometric")
    camera = GeometricCamera("probe", CONFIGURATIONS["top_observer"]().scenario().camera).camera
    T_w_c = pipeline.world.camera_transform(pipeline.uav_camera)
    rendered = RenderedCamera("probe", camera.config, None, floor)
    clone = COPIES[how](rendered)
    image_a = rendered.render(T_w_c, [], np.random.default_rng(1))
    image_b = clone.render(T_w_c, [], np.random.default_rng(1))
    assert np.array_equal(image_a, image_b) and image_a.std() > 1.0  # a textured floor, drawn alike
