"""The rendered camera: a synthetic image through OpenCV's ArUco detector and solvePnP."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env.camera import (
    BoardView,
    CameraConfig,
    FloorCamera,
    FloorConfig,
    FloorTexture,
    GeometricCamera,
    RenderConfig,
    RenderedCamera,
    make_camera,
)
from moma_env.camera.rays import PixelRays
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_CAM_DOWN, R_BODY_CAM_FORWARD, invert, make_transform, rotation_angle, se2_to_se3
from moma_env.markers import board_for_robot

#: Stated tolerance of a rendered detection against the geometric backend's
#: noise-free pose, for a board 1.3 m below a 720x576 camera with default noise
#: and blur: 1 cm in position, 1 degree in rotation.
POSITION_TOL_M = 0.01
ROTATION_TOL_RAD = math.radians(1.0)

LAYOUT_0 = board_for_robot(0)
LAYOUT_1 = board_for_robot(1)


def down_camera(x: float = 0.5, y: float = 0.3, z: float = 1.6) -> np.ndarray:
    return make_transform(R_BODY_CAM_DOWN, [x, y, z])


@pytest.fixture(scope="module")
def floor() -> FloorTexture:
    return FloorTexture(FloorConfig(extent=(-1.0, -1.0, 2.0, 2.0), px_per_m=200.0))


@pytest.fixture(scope="module")
def camera(floor: FloorTexture) -> RenderedCamera:
    return RenderedCamera("uav", CameraConfig(), floor=floor)


def test_rendered_board_detected_within_tolerance_of_geometric(camera: RenderedCamera) -> None:
    geometric = GeometricCamera("uav", CameraConfig(noise_px=0.0))
    rng = np.random.default_rng(3)
    T_w_c = down_camera()
    for _ in range(3):
        x, y = rng.uniform(-0.5, 0.5, 2) + (0.5, 0.3)
        boards = [BoardView(7, LAYOUT_1, se2_to_se3(x, y, rng.uniform(-math.pi, math.pi), 0.3))]
        rendered = camera.measure(T_w_c, boards, 1.5, rng)
        [truth] = geometric.measure(T_w_c, boards, 1.5, rng)
        assert len(rendered) == 1
        d = rendered[0]
        assert d.board_id == 7 and d.camera_id == "uav" and d.time == 1.5
        assert sorted(d.marker_ids) == [4, 5, 6, 7]
        assert d.corners_px.shape == (16, 2)
        assert np.linalg.norm(d.T_c_m[:3, 3] - truth.T_c_m[:3, 3]) < POSITION_TOL_M
        assert rotation_angle(d.T_c_m[:3, :3].T @ truth.T_c_m[:3, :3]) < ROTATION_TOL_RAD
        assert d.reprojection_error_px < 1.0


def test_detected_corners_follow_the_distorted_projection() -> None:
    """Strong barrel distortion: detected corners sit on the exact projection of the true corners."""
    config = CameraConfig(dist=(-0.25, 0.05), noise_px=0.0)
    camera = RenderedCamera("uav", config, RenderConfig(noise_std=0.0, blur_sigma_px=0.5))
    T_w_c = down_camera(0.0, 0.0, 1.2)
    # Near the image corner, where the distortion is largest.
    board = BoardView(0, LAYOUT_0, se2_to_se3(0.55, 0.45, 0.3, 0.2))
    [d] = camera.measure(T_w_c, [board], 0.0, np.random.default_rng(0))
    T_c_m = invert(T_w_c) @ board.T_w_m
    index = [LAYOUT_0.marker_ids.index(i) for i in d.marker_ids]
    truth = camera.camera.project(LAYOUT_0.marker_corners[index].reshape(-1, 3) @ T_c_m[:3, :3].T + T_c_m[:3, 3])
    radius = np.linalg.norm(truth - camera.camera.K[:2, 2], axis=1)
    assert radius.min() > 180.0  # far out, where the distortion moves pixels by several px
    assert np.abs(d.corners_px - truth).max() < 0.5


def test_board_outside_the_view_is_not_detected(camera: RenderedCamera) -> None:
    board = BoardView(0, LAYOUT_0, se2_to_se3(5.0, 5.0, 0.0, 0.3))
    assert camera.measure(down_camera(), [board], 0.0, np.random.default_rng(0)) == []


def test_board_too_small_is_not_detected_but_is_drawn() -> None:
    """From 6.7 m a 16 cm marker spans ~10 px (< min_marker_px = 12): drawn, not detected."""
    camera = RenderedCamera("uav", CameraConfig(), RenderConfig(noise_std=0.0))
    board = BoardView(0, LAYOUT_0, se2_to_se3(0.5, 0.3, 0.2, 0.3))
    T_w_c = down_camera(z=7.0)
    rng = np.random.default_rng(0)
    empty = camera.render(T_w_c, [], rng).copy()
    assert camera.measure(T_w_c, [board], 0.0, rng) == []
    assert np.count_nonzero(camera.last_image != empty) > 100
    near = down_camera(z=1.6)
    assert len(camera.measure(near, [board], 0.0, rng)) == 1


def test_same_seed_same_image_bit_for_bit(floor: FloorTexture) -> None:
    boards = [BoardView(0, LAYOUT_0, se2_to_se3(0.3, 0.2, 0.4, 0.3)), BoardView(1, LAYOUT_1, se2_to_se3(0.9, 0.5, -1.0, 0.3))]
    images = []
    for seed in (11, 11, 12):
        cam = RenderedCamera("uav", CameraConfig(), floor=FloorTexture(floor.config))
        images.append(cam.render(down_camera(), boards, np.random.default_rng(seed)).copy())
    assert np.array_equal(images[0], images[1])
    assert not np.array_equal(images[0], images[2])


def test_board_seen_from_behind_is_not_drawn(camera: RenderedCamera) -> None:
    upside_down = se2_to_se3(0.5, 0.3, 0.0, 0.3) @ make_transform(np.diag([1.0, -1.0, -1.0]))
    cfg = RenderConfig(noise_std=0.0)
    cam = RenderedCamera("uav", CameraConfig(), cfg, floor=camera.floor)
    rng = np.random.default_rng(0)
    empty = cam.render(down_camera(), [], rng).copy()
    image = cam.render(down_camera(), [BoardView(0, LAYOUT_0, upside_down)], rng)
    assert np.array_equal(image, empty)


def test_occluded_markers_are_painted_over_and_not_detected(camera: RenderedCamera) -> None:
    board = BoardView(0, LAYOUT_0, se2_to_se3(0.5, 0.3, 0.0, 0.3))
    rng = np.random.default_rng(0)
    assert len(camera.measure(down_camera(), [board], 0.0, rng)) == 1
    calls = []

    def blocked(p_from: np.ndarray, p_to: np.ndarray) -> bool:
        calls.append(p_to)
        return bool(p_to[0] < 0.5)  # the markers on the board's -x half

    [d] = camera.measure(down_camera(), [board], 0.0, rng, occluded=blocked)
    assert len(calls) == 4
    assert sorted(d.marker_ids) == [1, 3]  # ids 0 and 2 are the left column (x_M < 0)
    assert camera.measure(down_camera(), [board], 0.0, rng, occluded=lambda a, b: True) == []


def test_interlacing_draws_the_odd_field_one_field_earlier(floor: FloorTexture) -> None:
    render = RenderConfig(noise_std=0.0, interlaced=True)
    progressive = RenderedCamera("uav", CameraConfig(), RenderConfig(noise_std=0.0), floor=floor)
    interlaced = RenderedCamera("uav", CameraConfig(), render, floor=floor)
    board = [BoardView(0, LAYOUT_0, se2_to_se3(0.5, 0.3, 0.0, 0.3))]
    rng = np.random.default_rng(0)
    for cam in (progressive, interlaced):
        cam.render(down_camera(0.4), board, rng, time=0.0)
    # The camera moved 10 cm in 40 ms: the odd rows show it 20 ms earlier.
    a = progressive.render(down_camera(0.5), board, rng, time=0.04).copy()
    b = interlaced.render(down_camera(0.5), board, rng, time=0.04).copy()
    assert np.array_equal(a[0::2], b[0::2])
    assert np.mean(a[1::2] != b[1::2]) > 0.3
    half_way = progressive.render(down_camera(0.45), board, rng, time=1.0)
    assert np.mean(np.abs(half_way[1::2].astype(int) - b[1::2])) < 0.2 * np.mean(np.abs(a[1::2].astype(int) - b[1::2]))
    # A static scene is the same interlaced or not.
    assert np.array_equal(progressive.render(down_camera(0.5), board, rng, time=1.04), interlaced.render(down_camera(0.5), board, rng, time=0.08))


def test_plain_and_textured_floor_and_the_horizon() -> None:
    config = FloorConfig(extent=(0.0, -1.0, 4.0, 1.0), textured=((0.0, -1.0, 2.0, 1.0),), px_per_m=200.0)
    floor = FloorTexture(config)
    rays = PixelRays(RenderedCamera("c", CameraConfig(width=160, height=120, fx=100.0)).camera)
    # Looking down onto the textured half, then onto the plain half.
    textured = floor.render(rays, make_transform(R_BODY_CAM_DOWN, [1.0, 0.0, 0.5]))
    plain = floor.render(rays, make_transform(R_BODY_CAM_DOWN, [3.0, 0.0, 0.5]))
    assert textured.std() > 10.0
    assert np.all(plain == round(config.gray))
    # A forward camera 0.3 m above the floor: floor below the horizon, background above.
    forward = floor.render(rays, make_transform(R_BODY_CAM_FORWARD, [0.5, 0.0, 0.3]))
    assert np.all(forward[:50] == round(config.background_gray))
    assert forward[70:].std() > 10.0


def test_floor_camera_frames_of_a_robot(floor: FloorTexture) -> None:
    T_b_c = make_transform(R_BODY_CAM_DOWN, [0.2, 0.0, 0.3])
    cam = FloorCamera(CameraConfig(width=160, height=120, fx=120.0), T_b_c, floor, RenderConfig(noise_std=0.0))
    rng = np.random.default_rng(0)
    a = cam.frame(se2_to_se3(0.3, 0.3, 0.0), rng)
    b = cam.frame(se2_to_se3(0.3, 0.3, 0.0), rng)
    c = cam.frame(se2_to_se3(0.35, 0.3, 0.0), rng)
    assert a.shape == (120, 160) and a.dtype == np.uint8
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_configs_reject_bad_values() -> None:
    with pytest.raises(ConfigError, match="floor.extent"):
        FloorConfig(extent=(1.0, 0.0, 0.0, 1.0))
    with pytest.raises(ConfigError, match=r"floor.textured\[0\]"):
        FloorConfig(textured=((0.0, 0.0, 1.0),))
    with pytest.raises(ConfigError, match="floor.px_per_m"):
        FloorConfig(extent=(0.0, 0.0, 100.0, 100.0), px_per_m=1000.0)
    with pytest.raises(ConfigError, match="render.corner_refinement"):
        RenderConfig(corner_refinement="BEST")
    with pytest.raises(ConfigError, match="render.noise_std"):
        RenderConfig(noise_std=-1.0)
    with pytest.raises(ConfigError, match="render.paper_gray"):
        RenderConfig(paper_gray=20, ink_gray=30)
    with pytest.raises(ConfigError, match="camera.backend"):
        make_camera("c", CameraConfig(), backend="raytraced")
    with pytest.raises(ConfigError, match="camera.render"):
        make_camera("c", CameraConfig(), render=RenderConfig())
    assert isinstance(make_camera("c", CameraConfig(width=64, height=48, fx=50.0), backend="rendered"), RenderedCamera)
    cam = RenderedCamera("c", CameraConfig(width=64, height=48, fx=50.0))
    with pytest.raises(ValueError, match="unique marker ids"):
        cam.measure(np.eye(4), [BoardView(0, LAYOUT_0, np.eye(4)), BoardView(1, LAYOUT_0, np.eye(4))], 0.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="uint8"):
        cam.detect(np.zeros((48, 64), dtype=float), [], 0.0)


def test_smooth_floor_map_is_within_a_hundredth_of_a_raster_pixel() -> None:
    from moma_env.geometry import rot_x

    rays = PixelRays(RenderedCamera("c", CameraConfig()).camera)
    floor = FloorTexture(FloorConfig(extent=(-3.0, -3.0, 4.0, 4.0), px_per_m=250.0, textured=()))
    for tilt in (0.0, 0.3):
        H = floor.homography(make_transform(R_BODY_CAM_DOWN @ rot_x(tilt), [0.5, 0.3, 1.6]))
        assert np.abs(rays.smooth_map(H) - rays.sample_map(H)).max() < 0.01


def test_floor_resamples_only_the_textured_window_and_matches_the_whole_image() -> None:
    """Half-textured floor, camera over the boundary, turned: same pixels as resampling everything."""
    import cv2

    from moma_env.geometry import rot_x, rot_z

    config = FloorConfig(extent=(-2.0, -2.0, 3.0, 2.0), textured=((-2.0, -2.0, 0.6, 2.0),), px_per_m=150.0)
    floor = FloorTexture(config)
    rays = PixelRays(RenderedCamera("c", CameraConfig()).camera)
    for x, yaw in ((0.2, 0.5), (0.9, -0.3), (2.5, 0.0)):
        T_w_c = make_transform(rot_z(yaw) @ R_BODY_CAM_DOWN @ rot_x(0.1), [x, 0.1, 1.5])
        whole = cv2.remap(
            floor.raster, rays.smooth_map(floor.homography(T_w_c)), None, cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT, borderValue=round(config.gray),
        )
        image = floor.render(rays, T_w_c)
        assert np.array_equal(image, whole)
    assert np.all(image == round(config.gray))  # the last view is all plain floor


def test_blur_of_the_non_uniform_window_equals_the_whole_image_blur() -> None:
    import cv2

    from moma_env.camera.sensor import SensorModel

    for sigma in (0.7, 1.1):
        sensor = SensorModel(RenderConfig(blur_sigma_px=sigma))
        scene = np.full((60, 80), 140, dtype=np.uint8)
        scene[20:30, 35:50] = np.random.default_rng(0).integers(0, 255, (10, 15))
        scene[0:5, 0:10] = 30  # touching the image border
        ksize = int(round(6 * sigma + 1)) | 1
        whole = cv2.GaussianBlur(scene, (ksize, ksize), sigma, borderType=cv2.BORDER_REPLICATE)
        assert np.array_equal(sensor.blur(scene.copy(), (0, 0, 50, 30)), whole)
        assert not np.array_equal(whole, scene)


def test_noise_bytes_are_the_generator_bytes_and_leave_the_same_state() -> None:
    from moma_env.camera.sensor import noise_bytes

    for make, n in (
        (lambda: np.random.default_rng(3), 720 * 576),  # the fast path
        (lambda: np.random.default_rng(3), 8 * 7 + 5),  # not a multiple of 8
        (lambda: np.random.Generator(np.random.MT19937(3)), 64),  # 32-bit raw outputs
        (lambda: np.random.Generator(np.random.PCG64DXSM(3)), 64),
    ):
        for pending_half in (False, True):
            a, b = make(), make()
            if pending_half:  # a 32-bit draw leaves half of a 64-bit output pending
                a.integers(0, 7, dtype=np.int32)
                b.integers(0, 7, dtype=np.int32)
            drawn = noise_bytes(a, n)
            assert drawn.dtype == np.uint8 and drawn.shape == (n,)
            assert drawn.tobytes() == b.bytes(n)
            assert a.integers(0, 2**63, 4).tolist() == b.integers(0, 2**63, 4).tolist()


def test_read_out_equals_gain_then_saturating_float_noise() -> None:
    """The fused read-out table gives, pixel for pixel, the gain LUT then the float noise
    added with OpenCV's saturation, from the same random bytes."""
    from statistics import NormalDist

    import cv2

    from moma_env.camera.sensor import SensorModel

    quantiles = np.array([NormalDist().inv_cdf((k + 0.5) / 256.0) for k in range(256)])
    scenes = np.random.default_rng(0)
    for config in (RenderConfig(), RenderConfig(noise_std=6.0, contrast=1.3, brightness=-20.0), RenderConfig(noise_std=60.0)):
        sensor = SensorModel(config)
        gain = np.clip(np.rint(config.contrast * (np.arange(256) - 128.0) + 128.0 + config.brightness), 0, 255).astype(np.uint8)
        for shape in ((576, 720), (5, 9)):
            scene = scenes.integers(0, 256, shape, dtype=np.uint8)
            draws = np.frombuffer(np.random.default_rng(1).bytes(scene.size), dtype=np.uint8).reshape(shape)
            expected = cv2.add(cv2.LUT(scene, gain), cv2.LUT(draws, (config.noise_std * quantiles).astype(np.float32)), dtype=cv2.CV_8U)
            out = sensor.read_out(scene.copy(), np.random.default_rng(1))
            assert np.array_equal(out, expected)
            assert np.any(out != scene)
    assert np.array_equal(SensorModel(RenderConfig(noise_std=0.0)).read_out(scene.copy(), np.random.default_rng(1)), scene)


def test_nearer_boards_cover_farther_ones_and_their_occluded_markers() -> None:
    """A forward camera: a board 0.8 m ahead hides the middle of one 1.6 m ahead, listed first."""
    from moma_env.geometry import R_BODY_BOARD_BACK

    camera = RenderedCamera("cam", CameraConfig())
    geometric = GeometricCamera("cam", CameraConfig(noise_px=0.0))
    T_w_c = make_transform(R_BODY_CAM_FORWARD, [0.0, 0.0, 0.3])
    far = BoardView(0, LAYOUT_0, make_transform(R_BODY_BOARD_BACK, [1.6, 0.0, 0.3]))
    near = BoardView(1, LAYOUT_1, make_transform(R_BODY_BOARD_BACK, [0.8, 0.0, 0.3]))
    rng = np.random.default_rng(0)
    blocked = lambda p_from, p_to: bool(p_to[0] > 1.0)  # noqa: E731 - everything beyond the near board
    for occluded, order in ((None, [near, far]), (blocked, [far, near])):
        detections = camera.measure(T_w_c, order, 0.0, rng, occluded=occluded)
        assert [d.board_id for d in detections] == [1]  # the far board is hidden behind the near one
        [truth] = [d for d in geometric.measure(T_w_c, [near], 0.0, rng)]
        assert sorted(detections[0].marker_ids) == [4, 5, 6, 7]
        assert np.linalg.norm(detections[0].T_c_m[:3, 3] - truth.T_c_m[:3, 3]) < POSITION_TOL_M


def test_floor_view_is_reused_only_within_its_tolerance(floor: FloorTexture, monkeypatch: pytest.MonkeyPatch) -> None:
    texture = FloorTexture(floor.config)
    cam = RenderedCamera("uav", CameraConfig(), RenderConfig(noise_std=0.0, floor_reuse_px=0.25), floor=texture)
    exact = RenderedCamera("uav", CameraConfig(), RenderConfig(noise_std=0.0), floor=FloorTexture(floor.config))
    draws = []
    original = texture.draw
    monkeypatch.setattr(texture, "draw", lambda *args: draws.append(1) or original(*args))
    rng = np.random.default_rng(0)
    cam.render(down_camera(0.5), [], rng)
    # 0.2 mm at 1.6 m is ~0.05 px: reused; 5 mm is ~1.3 px: drawn again.
    for x, drawn in ((0.5002, 1), (0.5004, 1), (0.505, 2), (0.5051, 2)):
        image = cam.render(down_camera(x), [], rng)
        assert len(draws) == drawn
        truth = exact.render(down_camera(x), [], rng)
        assert np.mean(np.abs(image.astype(int) - truth)) < 1.0
    with pytest.raises(ConfigError, match="render.floor_reuse_px"):
        RenderConfig(floor_reuse_px=-0.1)


def test_far_floor_is_sampled_from_a_coarser_level_without_aliasing() -> None:
    """A 800 px/m texture seen from 1.6 m (3.8 mm/px, ~3 raster px per image px): sampled
    from the first pyrDown level (1.5 raster px per image px), with less aliasing."""
    import cv2

    floor = FloorTexture(FloorConfig(extent=(-1.5, -1.5, 2.5, 2.5), px_per_m=800.0, feature_size_m=0.01, contrast=0.8))
    rays = PixelRays(RenderedCamera("c", CameraConfig()).camera)
    T_w_c = down_camera(0.5, 0.3, 1.6)
    H = floor.homography(T_w_c)
    image = floor.render(rays, T_w_c)
    level_1 = cv2.remap(cv2.pyrDown(floor.raster), rays.smooth_map(np.diag([0.5, 0.5, 1.0]) @ H), None, cv2.INTER_LINEAR)
    point_sampled = cv2.remap(floor.raster, rays.smooth_map(H), None, cv2.INTER_LINEAR)
    assert np.array_equal(image, level_1)

    def fine_energy(img: np.ndarray) -> float:
        """Mean difference of neighbouring pixels: aliasing adds energy the camera cannot resolve."""
        return float(np.mean(np.abs(np.diff(img.astype(float), axis=1))))

    assert fine_energy(image) < 0.85 * fine_energy(point_sampled)
    # Close up (0.3 m, ~0.6 raster px per image px) the full raster is used.
    near = down_camera(0.5, 0.3, 0.3)
    direct = cv2.remap(floor.raster, rays.smooth_map(floor.homography(near)), None, cv2.INTER_LINEAR)
    assert np.array_equal(floor.render(rays, near), direct)
