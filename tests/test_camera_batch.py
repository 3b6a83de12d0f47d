"""Batched measurement (moma_env.camera.batch.measure_batch): bit for bit the per-request measure."""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest

from moma_env.camera import BoardView, CameraConfig, GeometricCamera, RenderConfig, RenderedCamera, up_in_board
from moma_env.camera.batch import MeasureRequest, measure_batch
from moma_env.geometry import R_BODY_BOARD_BACK, R_BODY_BOARD_UP, R_BODY_CAM_DOWN, make_transform, rot_x, rot_y, se2_to_se3
from moma_env.markers import BoardLayout, board_for_robot

LAYOUTS = [board_for_robot(i) for i in range(4)] + [
    BoardLayout(marker_ids=(40,), rows=1, cols=1, marker_size=0.12, gap=0.02),
    BoardLayout(marker_ids=tuple(range(30, 39)), rows=3, cols=3, marker_size=0.1, gap=0.02),
]


def random_frame(rng: np.random.Generator, n_boards: int) -> tuple[np.ndarray, list[BoardView]]:
    """A tilted downward camera 1.2-3 m up and ``n_boards`` boards around it (face-up or upright)."""
    x, y = rng.uniform(-0.3, 0.3, 2)
    roll, pitch = rng.uniform(-0.1, 0.1, 2)
    T_w_c = (
        se2_to_se3(x, y, rng.uniform(-math.pi, math.pi), rng.uniform(1.2, 3.0))
        @ make_transform(rot_x(roll) @ rot_y(pitch))
        @ make_transform(R_BODY_CAM_DOWN)
    )
    boards = []
    for i in range(n_boards):
        mount = make_transform(R_BODY_BOARD_UP if rng.random() < 0.7 else R_BODY_BOARD_BACK)
        T_w_m = se2_to_se3(*rng.uniform(-1.2, 1.2, 2), rng.uniform(-3.0, 3.0), 0.4) @ mount
        up = up_in_board(mount) if rng.random() < 0.8 else None
        boards.append(BoardView(i, LAYOUTS[int(rng.integers(len(LAYOUTS)))], T_w_m, up))
    return T_w_c, boards


def assert_same(a, b) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert (x.camera_id, x.board_id, x.marker_ids, x.time) == (y.camera_id, y.board_id, y.marker_ids, y.time)
        np.testing.assert_array_equal(x.T_c_m, y.T_c_m)
        np.testing.assert_array_equal(x.corners_px, y.corners_px)
        assert x.reprojection_error_px == y.reprojection_error_px
        assert (x.covariance is None) == (y.covariance is None)
        if x.covariance is not None:
            np.testing.assert_array_equal(x.covariance, y.covariance)


def block_right_half(p_from: np.ndarray, p_to: np.ndarray) -> bool:
    return bool(p_to[0] > 0.3)


CONFIGS = [
    CameraConfig(),
    CameraConfig(noise_px=0.0),
    CameraConfig(attitude_noise_deg=2.0),
    CameraConfig(pnp_sigma_source="residuals", noise_px=0.8),
    CameraConfig(pnp_method="SQPNP"),
    CameraConfig(pnp_warm_start=True),
]


@pytest.mark.parametrize("warm", [False, True])
def test_batch_equals_per_request_measure_bit_for_bit(warm: bool) -> None:
    scene_rng = np.random.default_rng(11)
    n = 24
    configs = [CONFIGS[i % len(CONFIGS)] for i in range(n)]
    if warm:
        configs = [dataclasses.replace(c, pnp_warm_start=True) for c in configs]
    batch_cams = [GeometricCamera(f"c{i}", cfg) for i, cfg in enumerate(configs)]
    loop_cams = copy.deepcopy(batch_cams)
    batch_rngs = [np.random.default_rng([5, i]) for i in range(n)]
    loop_rngs = copy.deepcopy(batch_rngs)
    scenes = [random_frame(scene_rng, int(scene_rng.integers(0, 6))) for _ in range(n)]
    for step in range(4):  # the cameras drift 1 cm a step: later steps warm-start from the earlier ones
        frames = [(se2_to_se3(0.01 * step, 0.0, 0.0, 0.0) @ T, boards) for T, boards in scenes]
        occluded = [block_right_half if i % 5 == 2 else None for i in range(n)]
        time = 0.04 * step
        requests = [
            MeasureRequest(batch_cams[i], frames[i][0], frames[i][1], time, batch_rngs[i], occluded[i]) for i in range(n)
        ]
        batched = measure_batch(requests)
        looped = [
            loop_cams[i].measure(frames[i][0], frames[i][1], time, loop_rngs[i], occluded[i]) for i in range(n)
        ]
        assert sum(map(len, looped)) > n // 2  # the frames do see boards
        for a, b in zip(batched, looped):
            assert_same(a, b)
        for a, b in zip(batch_rngs, loop_rngs):
            assert a.bit_generator.state == b.bit_generator.state
    assert [c.warm_counts for c in batch_cams] == [c.warm_counts for c in loop_cams]
    if warm:
        assert sum(c.warm_counts[0] for c in batch_cams) > n


@pytest.mark.parametrize("pnp_method", ["PLANAR_LM", "SQPNP"])
def test_cameras_of_different_intrinsics_and_noise_are_measured_in_one_group(monkeypatch, pnp_method: str) -> None:
    """The copies of a random-scenario vector env each draw their camera: one group, one
    projection and one solve, still bit for bit each camera's own measure."""
    import moma_env.camera.batch as batch_module

    groups = []

    class CountedGroup(batch_module.FrameGroup):
        def __init__(self, *args, **kwargs):
            groups.append(len(args[0]))
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(batch_module, "FrameGroup", CountedGroup)
    scene_rng = np.random.default_rng(3)
    n = 12
    configs = [
        CameraConfig(
            fx=float(scene_rng.uniform(300.0, 600.0)),
            dist=(float(scene_rng.uniform(-0.1, 0.05)), float(scene_rng.uniform(0.0, 0.02)), 0.0, 0.0, 0.0),
            noise_px=float(scene_rng.uniform(0.2, 1.0)),
            attitude_noise_deg=float(scene_rng.choice([0.0, 1.5])),
            pnp_sigma_source=str(scene_rng.choice(["auto", "residuals"])),
            max_range_m=float(scene_rng.uniform(3.0, 8.0)),
            pnp_method=pnp_method,
        )
        for _ in range(n)
    ]
    batch_cams = [GeometricCamera(f"c{i}", cfg) for i, cfg in enumerate(configs)]
    loop_cams = copy.deepcopy(batch_cams)
    batch_rngs = [np.random.default_rng([9, i]) for i in range(n)]
    loop_rngs = copy.deepcopy(batch_rngs)
    scenes = [random_frame(scene_rng, int(scene_rng.integers(1, 6))) for _ in range(n)]
    requests = [MeasureRequest(batch_cams[i], T, boards, 0.0, batch_rngs[i]) for i, (T, boards) in enumerate(scenes)]
    batched = measure_batch(requests)
    looped = [loop_cams[i].measure(T, boards, 0.0, loop_rngs[i]) for i, (T, boards) in enumerate(scenes)]
    assert sum(map(len, looped)) > n // 2
    for a, b in zip(batched, looped):
        assert_same(a, b)
    assert groups.count(n) == 1 and len([g for g in groups if g > 1]) == 1


def test_shared_generator_and_repeated_camera_follow_request_order() -> None:
    # Two cameras share one generator, and one camera takes two frames (warm starts
    # of its second frame come from its first): the batch is the sequential calls.
    scene_rng = np.random.default_rng(3)
    frames = [random_frame(scene_rng, 4) for _ in range(5)]
    cfg = CameraConfig(pnp_warm_start=True, attitude_noise_deg=1.0)
    a, b = GeometricCamera("a", cfg), GeometricCamera("b", cfg)
    a2, b2 = copy.deepcopy(a), copy.deepcopy(b)
    for cams, rng in (((a, b), np.random.default_rng(1)), ((a2, b2), np.random.default_rng(1))):
        cams[0].measure(frames[0][0], frames[0][1], 0.0, rng)  # memory for the next frame
    shared, shared2 = np.random.default_rng(9), np.random.default_rng(9)
    order = [(0, 1, 0.04), (1, 2, 0.04), (0, 3, 0.08), (1, 4, 0.08)]
    batched = measure_batch([MeasureRequest((a, b)[c], frames[f][0], frames[f][1], t, shared) for c, f, t in order])
    looped = [(a2, b2)[c].measure(frames[f][0], frames[f][1], t, shared2) for c, f, t in order]
    for x, y in zip(batched, looped):
        assert_same(x, y)
    assert shared.bit_generator.state == shared2.bit_generator.state


def test_batch_detections_do_not_share_arrays_across_frames() -> None:
    scene_rng = np.random.default_rng(4)
    cams = [GeometricCamera("c", CameraConfig()) for _ in range(3)]
    frames = [random_frame(scene_rng, 5) for _ in range(3)]
    results = measure_batch([MeasureRequest(c, T, b, 0.0, np.random.default_rng(0)) for c, (T, b) in zip(cams, frames)])
    assert sum(1 for r in results if r) >= 2
    bases = [{id(d.T_c_m.base), id(d.corners_px.base)} for r in results for d in r]
    frame_of = [f for f, r in enumerate(results) for _ in r]
    for i in range(len(bases)):
        for j in range(len(bases)):
            if frame_of[i] != frame_of[j]:
                assert not bases[i] & bases[j]  # a kept detection keeps only its frame's arrays alive
    for r in results:
        for d in r:
            assert d.T_c_m.base.shape[0] == len(r) and d.corners_px.base.shape[0] == sum(len(x.corners_px) for x in r)


def test_rendered_requests_fall_back_to_their_own_measure() -> None:
    cfg = CameraConfig(width=320, height=240, fx=190.0)
    render = RenderConfig(noise_std=2.0)
    T_w_c = se2_to_se3(0.1, -0.05, 0.3, 1.6) @ make_transform(R_BODY_CAM_DOWN)
    boards = [
        BoardView(i, board_for_robot(i), se2_to_se3(x, y, 0.4 * i, 0.4) @ make_transform(R_BODY_BOARD_UP))
        for i, (x, y) in enumerate(((0.3, 0.1), (-0.2, -0.25)))
    ]
    rendered, rendered2 = RenderedCamera("r", cfg, render), RenderedCamera("r", cfg, render)
    geometric, geometric2 = GeometricCamera("g", cfg), GeometricCamera("g", cfg)
    shared, shared2 = np.random.default_rng(2), np.random.default_rng(2)  # one generator for both cameras
    batched = measure_batch(
        [MeasureRequest(geometric, T_w_c, boards, 0.0, shared), MeasureRequest(rendered, T_w_c, boards, 0.0, shared),
         MeasureRequest(geometric, T_w_c, boards, 0.04, shared)]
    )
    looped = [
        geometric2.measure(T_w_c, boards, 0.0, shared2),
        rendered2.measure(T_w_c, boards, 0.0, shared2),
        geometric2.measure(T_w_c, boards, 0.04, shared2),
    ]
    assert [len(r) for r in batched] == [2, 2, 2]
    for x, y in zip(batched, looped):
        assert_same(x, y)
    assert shared.bit_generator.state == shared2.bit_generator.state


def test_bad_requests_are_named() -> None:
    cam = GeometricCamera("c", CameraConfig())
    T_w_c, boards = random_frame(np.random.default_rng(0), 2)
    good = MeasureRequest(cam, T_w_c, boards, 0.0, np.random.default_rng(0))
    with pytest.raises(TypeError, match=r"requests\[1\] must be a MeasureRequest"):
        measure_batch([good, (cam, T_w_c, boards, 0.0, None)])
    with pytest.raises(ValueError, match=r"requests\[1\]: T_w_c must be a 4x4 pose"):
        measure_batch([good, MeasureRequest(cam, np.eye(3), boards, 0.0, np.random.default_rng(0))])
    with pytest.raises(ValueError, match=r"requests\[0\]: time must be finite"):
        measure_batch([MeasureRequest(cam, T_w_c, boards, math.nan, np.random.default_rng(0))])
    with pytest.raises(TypeError, match=r"requests\[0\]: rng must be a numpy.random.Generator"):
        measure_batch([MeasureRequest(cam, T_w_c, boards, 0.0, 7)])
    rng = np.random.default_rng(5)
    state = rng.bit_generator.state
    with pytest.raises(ValueError, match=r"requests\[1\]"):
        measure_batch([MeasureRequest(cam, T_w_c, boards, 0.0, rng), MeasureRequest(cam, T_w_c, boards, math.inf, rng)])
    assert rng.bit_generator.state == state  # validated before anything is drawn
    assert measure_batch([]) == []


def test_board_view_rejects_what_it_did_and_converts_the_rest() -> None:
    layout, T = LAYOUTS[0], np.eye(4)
    view = BoardView(np.int64(3), layout, T.tolist(), [0, 0, 1])
    assert type(view.board_id) is int and view.board_id == 3
    assert view.T_w_m.dtype == np.float64 and view.T_w_m.shape == (4, 4)
    assert view.up_m.dtype == np.float64 and not view.up_m.flags.writeable
    up = np.array([0.0, 1.0, 0.0])
    view = BoardView(True, layout, T, up)
    assert view.board_id == 1 and view.T_w_m is T and view.up_m is not up
    up[1] = 0.5  # the view keeps its own copy
    assert view.up_m[1] == 1.0
    bad = [
        ((1.5, layout, T, None), TypeError, "board_id must be an integer"),
        ((0, "layout", T, None), TypeError, "layout must be a BoardLayout"),
        ((0, layout, np.eye(3), None), ValueError, "T_w_m must be a 4x4 pose"),
        ((0, layout, np.full((4, 4), np.nan), None), ValueError, "T_w_m must be finite"),
        ((0, layout, np.where(np.eye(4) > 0, np.inf, 0.0), None), ValueError, "T_w_m must be finite"),
        ((0, layout, np.full((4, 4), np.inf, dtype=np.float32), None), ValueError, "T_w_m must be finite"),
        ((0, layout, T, [0.0, 0.0]), ValueError, "up_m must be a finite 3-vector"),
        ((0, layout, T, [0.0, np.nan, 1.0]), ValueError, "up_m must be a finite 3-vector"),
        ((0, layout, T, np.array([np.inf, 0.0, 0.0])), ValueError, "up_m must be a finite 3-vector"),
        ((0, layout, T, [0.0, 0.0, 1.01]), ValueError, "up_m must be a unit vector"),
    ]
    for args, error, message in bad:
        with pytest.raises(error, match=message):
            BoardView(*args)
    # A pose of huge but finite entries whose sum overflows is still accepted.
    huge = np.eye(4)
    huge[:3, 3] = 1e308
    assert BoardView(0, layout, huge).T_w_m is huge
