"""Tests of moma_env.env.render: top-down map, camera view inset, composition."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.camera import BoardView, CameraConfig, PinholeCamera
from moma_env.estimator.results import Status
from moma_env.env.render import (
    DETECTED_COLOUR,
    INSET_CORNERS,
    STATUS_COLOURS,
    RobotView,
    SceneView,
    TopDownMapping,
    compose,
    inset_size,
    render_camera_view,
    render_top_down,
)
from moma_env.geometry import R_BODY_CAM_DOWN, make_transform, rot_x, se2_to_se3
from moma_env.markers import BoardLayout, board_for_robot

BOUNDS = (0.0, 0.0, 4.0, 4.0)
SIZE = (400, 400)


def robot(x: float = 1.0, y: float = 3.0, est=None, status: str = "localised", **kw) -> RobotView:
    return RobotView(name="ugv_0", true_pose=(x, y, 0.0), est_pose=est, radius=0.225, static=False,
                     status=status, **kw)


def full_scene() -> SceneView:
    board = np.array([[1.17, 3.17], [0.83, 3.17], [0.83, 2.83], [1.17, 2.83]])
    return SceneView(
        bounds=(-1.0, -0.5, 3.0, 2.5),
        obstacles=(np.array([[2.0, 1.0], [2.5, 1.0], [2.5, 1.5], [2.0, 1.5]]),),
        robots=(
            robot(0.0, 0.0, est=(0.05, 0.0, 0.1), board_corners_w=board - [1.0, 3.0]),
            RobotView("sled", (1.0, 0.5, 0.3), (1.1, 0.5, 0.2), 0.2, True, Status.HOLDING, shape="box",
                      size=(0.4, 0.3)),
        ),
        goals={"ugv_0": (1.0, 1.0, math.pi / 2)},
        observer_true=(0.5, 0.2, 0.3, 1.5),
        observer_est=(0.52, 0.21, 0.3),
        footprints=(np.array([[0.0, 0.0], [1.0, 0.0], [np.nan, np.nan], [0.0, 0.8]]),),
        ropes=(((0.0, 0.0), (1.0, 0.5)),),
        time=3.25,
        info_lines=("step 81", "switches 2"),
    )


def changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Boolean (H, W) mask of pixels that differ between two images."""
    return (a != b).any(axis=2)


def has_colour(img: np.ndarray, colour) -> bool:
    return bool((img == np.array(colour, dtype=np.uint8)).all(axis=2).any())


# ------------------------------------------------------------------ top-down
def test_top_down_shape_dtype_and_determinism():
    scene = full_scene()
    img = render_top_down(scene, size=(320, 200))
    assert img.shape == (200, 320, 3) and img.dtype == np.uint8
    assert np.array_equal(img, render_top_down(full_scene(), size=(320, 200)))
    assert render_top_down(scene).shape == (640, 640, 3)


def test_mapping_matches_hand_computation():
    m = TopDownMapping.fit(BOUNDS, SIZE)
    # 3 % margin of 400 px -> 12 px each side, 376 px for 4 m.
    assert m.scale == pytest.approx(94.0)
    assert m.to_pixels(np.array([1.0, 3.0])) == pytest.approx([105.5, 105.5])
    assert m.to_pixels(np.array([2.0, 2.0])) == pytest.approx([199.5, 199.5])  # centre of the image


@settings(max_examples=60, deadline=None)
@given(
    xmin=st.floats(-50, 50), ymin=st.floats(-50, 50), dx=st.floats(0.1, 40), dy=st.floats(0.1, 40),
    w=st.integers(16, 2000), h=st.integers(16, 2000),
)
def test_mapping_letterboxes_and_inverts(xmin, ymin, dx, dy, w, h):
    m = TopDownMapping.fit((xmin, ymin, xmin + dx, ymin + dy), (w, h))
    corners = np.array([[xmin, ymin + dy], [xmin + dx, ymin]])  # top-left, bottom-right
    (u0, v0), (u1, v1) = m.to_pixels(corners)
    # inside the image (edges of the pixel grid are at -0.5 and size - 0.5) and centred
    eps = 1e-9  # floating-point rounding of the affine map, in pixels
    assert -0.5 - eps <= u0 < u1 <= w - 0.5 + eps and -0.5 - eps <= v0 < v1 <= h - 0.5 + eps
    assert (u0 + u1) / 2 == pytest.approx((w - 1) / 2) and (v0 + v1) / 2 == pytest.approx((h - 1) / 2)
    # one side fills the area inside the margins: the aspect ratio is kept, nothing is wasted
    pad = math.floor(0.03 * min(w, h))
    assert max((u1 - u0) / (w - 2 * pad), (v1 - v0) / (h - 2 * pad)) == pytest.approx(1.0)
    p = np.array([[xmin + 0.3 * dx, ymin + 0.7 * dy]])
    assert m.to_world(m.to_pixels(p)) == pytest.approx(p)
    # world y up -> image v down
    assert m.to_pixels(p + [0.0, 0.05])[0, 1] < m.to_pixels(p)[0, 1]


def test_robot_drawn_at_expected_pixel_with_y_up():
    empty = render_top_down(SceneView(BOUNDS), SIZE, legend=False)
    img = render_top_down(SceneView(BOUNDS, robots=(robot(1.0, 3.0),)), SIZE, legend=False)
    # the disk covers the pixel of its centre, (1, 3) m -> (105.5, 105.5) px
    assert (img[104:108, 104:108] != empty[104:108, 104:108]).any(axis=2).all()
    rows, cols = np.nonzero(changed(img, empty))
    assert abs(np.median(cols) - 105.5) < 15 and abs(np.median(rows) - 105.5) < 15
    # the same robot at y = 1 m lands in the lower half
    low = render_top_down(SceneView(BOUNDS, robots=(robot(1.0, 1.0),)), SIZE, legend=False)
    rows_low, _ = np.nonzero(changed(low, empty))
    assert np.median(rows_low) > 250 > np.median(rows)


def estimate_region(img: np.ndarray) -> np.ndarray:
    # estimate at (3, 1) m -> (293.5, 293.5) px, radius 21 px: its ring lies within +-35 px
    return img[255:335, 255:335]


@pytest.mark.parametrize("status", ["localised", "holding", "lost"])
def test_estimate_outline_coloured_by_status(status):
    img = render_top_down(SceneView(BOUNDS, robots=(robot(est=(3.0, 1.0, 0.0), status=status),)), SIZE,
                          legend=False)
    region = estimate_region(img)
    assert has_colour(region, STATUS_COLOURS[status])
    for other, colour in STATUS_COLOURS.items():
        if other != status:
            assert not has_colour(img, colour)
    # the ring passes through (3, 1 + radius): 21 px above the centre pixel
    assert tuple(img[293 - 21, 293]) == STATUS_COLOURS[status]


def test_no_estimate_draws_nothing_at_the_estimate():
    empty = render_top_down(SceneView(BOUNDS), SIZE, legend=False)
    none = render_top_down(SceneView(BOUNDS, robots=(robot(est=None),)), SIZE, legend=False)
    some = render_top_down(SceneView(BOUNDS, robots=(robot(est=(3.0, 1.0, 0.0)),)), SIZE, legend=False)
    assert np.array_equal(estimate_region(none), estimate_region(empty))
    assert changed(estimate_region(some), estimate_region(empty)).any()
    for colour in STATUS_COLOURS.values():
        assert not has_colour(none, colour)


def test_static_and_mobile_truth_differ():
    def img(static: bool) -> np.ndarray:
        r = RobotView("r", (2.0, 2.0, 0.0), None, 0.3, static, "lost")
        return render_top_down(SceneView(BOUNDS, robots=(r,)), SIZE, legend=False)

    assert not np.array_equal(img(True)[185:195, 185:195], img(False)[185:195, 185:195])


def test_footprint_nan_rows_skipped_and_translucent():
    empty = render_top_down(SceneView(BOUNDS), SIZE, legend=False)
    tri = np.array([[1.0, 1.0], [3.0, 1.0], [np.nan, np.nan], [1.0, 3.0]])
    img = render_top_down(SceneView(BOUNDS, footprints=(tri,)), SIZE, legend=False)
    m = TopDownMapping.fit(BOUNDS, SIZE)
    inside = np.round(m.to_pixels(np.array([1.5, 1.5]))).astype(int)
    outside = np.round(m.to_pixels(np.array([2.7, 2.7]))).astype(int)  # beyond the hypotenuse
    pix, base = img[inside[1], inside[0]].astype(int), empty[inside[1], inside[0]].astype(int)
    assert (pix != base).any() and (pix > 40).all()  # tinted, floor still showing through
    assert np.array_equal(img[outside[1], outside[0]], empty[outside[1], outside[0]])
    all_nan = np.full((4, 2), np.nan)
    assert np.array_equal(render_top_down(SceneView(BOUNDS, footprints=(all_nan,)), SIZE, legend=False), empty)


@settings(max_examples=25, deadline=None)
@given(
    poses=st.lists(st.tuples(st.floats(-1e6, 1e6), st.floats(-1e6, 1e6), st.floats(-10, 10)), min_size=1,
                   max_size=4),
    w=st.integers(1, 300), h=st.integers(1, 300),
)
def test_any_finite_poses_render(poses, w, h):
    robots = tuple(RobotView(f"r{i}", p, p, 0.2, i % 2 == 0, "holding") for i, p in enumerate(poses))
    x, y, yaw = poses[0]
    scene = SceneView(BOUNDS, robots=robots, goals={"g": poses[0]}, observer_true=(x, y, yaw, 1.0),
                      observer_est=poses[0], ropes=(((0.0, 0.0), (x, y)),))
    assert render_top_down(scene, (w, h)).shape == (h, w, 3)


@pytest.mark.parametrize("size", [(0, 100), (100, -1), (100,), (1.5, 100), (True, 100), "ab", None])
def test_bad_sizes_raise(size):
    with pytest.raises(ValueError, match="size"):
        render_top_down(SceneView(BOUNDS), size)


@pytest.mark.parametrize("bounds", [(1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 1.0, 1.0), (0.0, 0.0, 1.0), (0, 0, np.inf, 1)])
def test_bad_bounds_raise(bounds):
    with pytest.raises(ValueError, match="bounds"):
        SceneView(bounds)


def test_bad_robot_and_scene_fields_raise():
    with pytest.raises(ValueError, match="status"):
        robot(status="confused")
    with pytest.raises(ValueError, match="size"):
        robot(shape="box")
    with pytest.raises(ValueError, match="shape"):
        robot(shape="triangle")
    with pytest.raises(ValueError, match="radius"):
        RobotView("r", (0, 0, 0), None, 0.0, True, "lost")
    with pytest.raises(ValueError, match="est_pose"):
        robot(est=(0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match="obstacles"):
        SceneView(BOUNDS, obstacles=(np.zeros((2, 2)),))
    with pytest.raises(ValueError, match="footprints"):
        SceneView(BOUNDS, footprints=(np.array([[0.0, np.inf], [1, 1], [2, 2]]),))
    with pytest.raises(ValueError, match="goals"):
        SceneView(BOUNDS, goals={"a": (0.0, 1.0)})
    with pytest.raises(TypeError, match="robots"):
        SceneView(BOUNDS, robots=("ugv_0",))
    with pytest.raises(TypeError, match="SceneView"):
        render_top_down(BOUNDS)


# --------------------------------------------------------------- camera view
CAMERA = PinholeCamera(CameraConfig())  # 720x576, fx 420, mild barrel distortion
CAM_HEIGHT = 1.5
T_W_C_DOWN = make_transform(R_BODY_CAM_DOWN, [0.0, 0.0, CAM_HEIGHT])  # looking straight down from 1.5 m


def board(x: float, y: float, z: float = 0.3, yaw: float = 0.0, board_id: int = 0, face_down: bool = False):
    T = se2_to_se3(x, y, yaw, z)
    if face_down:
        T = T @ make_transform(rot_x(math.pi))
    return BoardView(board_id, board_for_robot(board_id), T)


def empty_view(size=None) -> np.ndarray:
    return render_camera_view(CAMERA, T_W_C_DOWN, [], size=size)


def test_camera_view_board_below_shows_markers_at_centre():
    img = render_camera_view(CAMERA, T_W_C_DOWN, [board(0.0, 0.0)])
    assert img.shape == (576, 720, 3) and img.dtype == np.uint8
    cu, cv = 359, 287
    centre = img[cv - 25:cv + 26, cu - 25:cu + 26]
    assert (centre == 0).all(axis=2).sum() > 500  # black marker squares around the centre
    assert (centre == 255).all(axis=2).any()  # the white gaps between them
    assert np.array_equal(img, render_camera_view(CAMERA, T_W_C_DOWN, [board(0.0, 0.0)]))


def test_camera_view_marker_centres_where_the_camera_projects_them():
    b = board(0.6, -0.4, yaw=0.4)  # off-centre: distortion matters
    img = render_camera_view(CAMERA, T_W_C_DOWN, [b])
    centres_m = b.layout.marker_corners.mean(axis=1)
    T_c_m = np.linalg.inv(T_W_C_DOWN) @ b.T_w_m
    px = CAMERA.project(centres_m @ T_c_m[:3, :3].T + T_c_m[:3, 3])
    for u, v in np.round(px).astype(int):
        assert (img[v - 2:v + 3, u - 2:u + 3] == 0).all()


def test_camera_view_resized():
    img = render_camera_view(CAMERA, T_W_C_DOWN, [board(0.0, 0.0)], size=(360, 288))
    assert img.shape == (288, 360, 3)
    centre = img[143 - 12:143 + 13, 179 - 12:179 + 13]
    assert (centre == 0).all(axis=2).sum() > 100


@pytest.mark.parametrize(
    "b",
    [
        board(0.0, 0.0, z=2.5, face_down=True),  # above the camera, facing it: behind the image plane
        board(0.0, 0.0, face_down=True),  # below, printed face turned away
    ],
    ids=["behind", "facing-away"],
)
def test_camera_view_hidden_board_draws_nothing(b):
    assert np.array_equal(render_camera_view(CAMERA, T_W_C_DOWN, [b], detected_ids={0}), empty_view())


def test_camera_view_detected_outline():
    boards = [board(-0.3, 0.0, board_id=0), board(0.3, 0.0, board_id=1)]
    plain = render_camera_view(CAMERA, T_W_C_DOWN, boards)
    assert not has_colour(plain, DETECTED_COLOUR)
    marked = render_camera_view(CAMERA, T_W_C_DOWN, boards, detected_ids={1})
    assert has_colour(marked, DETECTED_COLOUR)
    # the outline sits on board 1 only: image rows above the centre (board at +x is image-up)
    rows, _ = np.nonzero((marked == np.array(DETECTED_COLOUR, np.uint8)).all(axis=2))
    assert rows.max() < 287


def test_camera_view_bad_input():
    with pytest.raises(ValueError, match="size"):
        render_camera_view(CAMERA, T_W_C_DOWN, [], size=(0, 10))
    with pytest.raises(ValueError, match="T_w_c"):
        render_camera_view(CAMERA, np.eye(3), [])
    with pytest.raises(TypeError, match="PinholeCamera"):
        render_camera_view(CameraConfig(), T_W_C_DOWN, [])
    with pytest.raises(TypeError, match="BoardView"):
        render_camera_view(CAMERA, T_W_C_DOWN, [BoardLayout()])


# ------------------------------------------------------------------- compose
@pytest.mark.parametrize("corner", INSET_CORNERS)
def test_compose_places_inset_in_corner(corner):
    top = np.zeros((400, 600, 3), np.uint8)
    inset = np.full((576, 720, 3), (255, 0, 0), np.uint8)
    out = compose(top, inset, corner=corner, scale=0.25)
    assert out.shape == top.shape and out.dtype == np.uint8
    rows, cols = np.nonzero((out == [255, 0, 0]).all(axis=2))
    tw, th = inset_size((600, 400), (720, 576), 0.25)
    assert (tw, th) == (150, 120)
    assert out.any(axis=2).sum() == len(rows) == tw * th  # a solid rectangle, the rest of top untouched
    assert cols.max() - cols.min() + 1 == tw and rows.max() - rows.min() + 1 == th
    margin = 6  # 1.5 % of 400 px
    assert (cols.min() == margin) if corner.endswith("left") else (cols.max() == 600 - 1 - margin)
    assert (rows.min() == margin) if corner.startswith("top") else (rows.max() == 400 - 1 - margin)
    assert not top.any()  # input not modified


def test_compose_exact_size_inset_pasted_unchanged_and_none_copies():
    top = render_top_down(full_scene(), (320, 240))
    inset = render_camera_view(CAMERA, T_W_C_DOWN, [board(0.0, 0.0)], size=inset_size((320, 240), (720, 576)))
    out = compose(top, inset)
    th, tw = inset.shape[:2]
    margin = 4  # 1.5 % of 240 px
    assert np.array_equal(out[margin:margin + th, 320 - margin - tw:320 - margin], inset)
    copy = compose(top, None)
    assert np.array_equal(copy, top) and copy is not top


def test_compose_tall_inset_shrinks_to_fit():
    # 1.0 * 400 px wide would be 2000 px tall: shrunk to the 96 px between 2 px margins
    assert inset_size((400, 100), (100, 500), 1.0) == (19, 96)
    out = compose(np.zeros((100, 400, 3), np.uint8), np.full((500, 100, 3), 200, np.uint8), scale=1.0)
    rows, cols = np.nonzero(out.any(axis=2))
    assert (rows.min(), rows.max(), cols.min(), cols.max()) == (2, 97, 400 - 2 - 19, 400 - 3)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"scale": 0.0}, "scale"),
        ({"scale": 1.5}, "scale"),
        ({"corner": "middle"}, "corner"),
        ({"inset": np.zeros((10, 10), np.uint8)}, "inset"),
        ({"inset": np.zeros((10, 10, 3), np.float32)}, "inset"),
        ({"top": np.zeros((0, 10, 3), np.uint8)}, "top"),
    ],
)
def test_compose_bad_input_raises(kwargs, match):
    args = {"top": np.zeros((50, 50, 3), np.uint8), "inset": np.zeros((10, 10, 3), np.uint8)} | kwargs
    with pytest.raises(ValueError, match=match):
        compose(**args)


def test_overlapping_footprints_fill_their_union():
    """Two overlapping footprints tint their overlap too (one fill per polygon, not the
    even-odd fill of one call, which leaves the overlap empty)."""
    empty = render_top_down(SceneView(BOUNDS), SIZE, legend=False)
    a = np.array([[0.5, 0.5], [3.0, 0.5], [3.0, 3.0], [0.5, 3.0]])
    b = a + 0.5
    one = render_top_down(SceneView(BOUNDS, footprints=(a,)), SIZE, legend=False)
    both = render_top_down(SceneView(BOUNDS, footprints=(a, b)), SIZE, legend=False)
    m = TopDownMapping.fit(BOUNDS, SIZE)
    u, v = np.round(m.to_pixels(np.array([2.0, 2.0]))).astype(int)  # inside both
    assert not np.array_equal(both[v, u], empty[v, u])
    assert np.array_equal(both[v, u], one[v, u])  # the union is tinted once, not twice
