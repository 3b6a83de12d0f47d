"""The camera's compiled hot path agrees with plain per-marker definitions.

Covers the kernels' projection and undistortion against the camera model, the
visibility checks against per-marker definitions (limits included), and
``GeometricCamera.measure`` on board sets that exercise every branch (hidden,
partly visible and padded boards, failed solves, occlusion), plus the
micro-benchmark's interface.
"""

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.camera import BoardView, CameraConfig, GeometricCamera, PinholeCamera, marker_visibility
from moma_env.camera.kernels import camera_parameters, project_boards, reprojection_sq, undistort_points
from moma_env.geometry import (
    R_BODY_BOARD_BACK,
    R_BODY_BOARD_UP,
    R_BODY_CAM_DOWN,
    R_BODY_CAM_FORWARD,
    invert,
    make_transform,
    rot_x,
    rot_y,
    rotation_angle,
    rotvec_to_matrix,
    se2_to_se3,
)
from moma_env.markers import BoardLayout, board_for_robot
from training.bench_camera import bench_camera

# ---------------------------------------------------------------- reference definitions


def reference_checks(camera, corners_c):
    """Checks 1-6 of each marker, one marker at a time, straight from the definitions.

    Returns (n, 6) booleans: depth, fold, image, size, incidence, range.
    """
    cfg = camera.config
    out = []
    for quad in corners_c:
        px, r2 = camera.project_with_r2(quad)
        depth = bool((quad[:, 2] > cfg.min_range_m).all())
        fold = bool((r2 < camera.fold_r2).all()) if depth else False
        image = bool(camera.in_image(px).all()) if depth else False
        sides = [np.hypot(*(px[(k + 1) % 4] - px[k])) for k in range(4)]
        size = bool(min(sides) >= cfg.min_marker_px) if depth else False
        centre = quad.mean(axis=0)
        normal = np.cross(quad[1] - quad[0], quad[3] - quad[0])  # x_M x (-y_M) = -z_M
        normal = -normal / np.linalg.norm(normal)
        cos_incidence = float(-normal @ centre) / float(np.linalg.norm(centre))
        incidence = cos_incidence >= math.cos(math.radians(cfg.max_incidence_deg))
        in_range = float(np.linalg.norm(centre)) <= cfg.max_range_m
        out.append((depth, fold, image, size, incidence, in_range))
    return np.array(out, dtype=bool)


def random_pose_c(rng):
    """A board pose in C: mostly in view and roughly facing the camera, sometimes anywhere
    (behind the camera, turned away, far ahead)."""
    if rng.uniform() < 0.7:
        z = rng.uniform(0.3, 6.0)
        R = rotvec_to_matrix(rng.normal(size=3) * 0.6) @ np.diag([1.0, -1.0, -1.0])
        t = np.array([rng.uniform(-0.9, 0.9) * z, rng.uniform(-0.7, 0.7) * z, z])
    else:
        R = rotvec_to_matrix(rng.normal(size=3) * 1.5) @ np.diag([1.0, -1.0, -1.0])
        t = np.array([rng.uniform(-2.5, 2.5), rng.uniform(-2.0, 2.0), rng.uniform(-1.0, 9.0)])
    return make_transform(R, t)


# ---------------------------------------------------------------- kernels vs the camera model


def kernel_pixels(cam, pts):
    """Pixels of camera-frame points (n, 3) through project_boards (one "marker" per 4 points)."""
    n = len(pts) // 4
    poses = np.zeros((n, 3, 4))
    poses[:, 0, 0] = poses[:, 1, 1] = poses[:, 2, 2] = 1.0
    uv = np.empty((n, 1, 4, 2))
    project_boards(
        poses, pts[: 4 * n].reshape(n, 1, 4, 3), np.ones((n, 1), bool), np.tile([0.0, 0.0, -1.0], (n, 1)),
        camera_parameters(cam), uv, np.empty((n, 1), bool), np.empty((n, 1, 3)),
    )
    return uv.reshape(-1, 2)


@settings(max_examples=60, deadline=None)
@given(
    k1=st.floats(-0.1, 0.15),
    k2=st.floats(0.0, 0.02),
    p1=st.sampled_from([0.0, 0.003]),
    k3=st.sampled_from([0.0, 0.004]),
    fy=st.sampled_from([None, 433.0]),
    seed=st.integers(0, 2**32 - 1),
)
def test_kernel_projection_and_undistortion_match_the_camera_model(k1, k2, p1, k3, fy, seed):
    cam = PinholeCamera(CameraConfig(fy=fy, dist=(k1, k2, p1, -p1, k3)))
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(-0.6, 0.6, (40, 2)), np.ones(40)]) * rng.uniform(0.2, 9.0, (40, 1))
    uv = kernel_pixels(cam, pts)
    np.testing.assert_allclose(uv, cam.project(pts), rtol=0, atol=1e-9)
    xy = np.empty_like(uv)
    undistort_points(uv, camera_parameters(cam), xy)
    np.testing.assert_allclose(xy, pts[:, :2] / pts[:, 2:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(xy, cam.undistort(uv), rtol=0, atol=1e-12)


def test_kernel_reprojection_error_is_zero_at_the_true_pose_and_grows_with_offsets():
    cam = PinholeCamera(CameraConfig())
    obj = board_for_robot(0).marker_corners.reshape(-1, 3)
    T = make_transform(np.diag([1.0, -1.0, -1.0]), [0.1, 0.05, 2.0])
    px = cam.project(obj @ T[:3, :3].T + T[:3, 3])
    p = camera_parameters(cam)
    assert reprojection_sq(T, obj, px, p) < 1e-18
    shifted = px + [0.5, 0.0]
    assert reprojection_sq(T, obj, shifted, p) == pytest.approx(len(obj) * 0.25, rel=1e-9)


# ---------------------------------------------------------------- visibility on rows


def test_marker_visibility_matches_the_reference_definitions():
    rng = np.random.default_rng(17)
    for cfg in (CameraConfig(), CameraConfig(dist=(-0.1,), max_incidence_deg=85.0), CameraConfig(min_marker_px=30.0)):
        cam = PinholeCamera(cfg)
        seen = 0
        for _ in range(300):
            T = random_pose_c(rng)
            corners = BoardLayout().marker_corners @ T[:3, :3].T + T[:3, 3]
            expected = reference_checks(cam, corners).all(axis=1)
            visible, _ = marker_visibility(cam, corners, T[:3, 2])
            np.testing.assert_array_equal(visible, expected)
            seen += int(expected.sum())
        assert seen > 60  # the sample reaches visible markers, not only hidden ones


def test_visibility_limits_are_inclusive_or_strict_as_documented():
    # fx = 512 and z = 1 make the projection exact in floats, so the limits are
    # tested exactly: a corner on the margin is inside, a side of exactly
    # min_marker_px is long enough, a marker at exactly max_range_m is in range.
    cfg = CameraConfig(dist=(), fx=512.0, min_marker_px=20.0, margin_px=5.0)
    cam = PinholeCamera(cfg)

    def visible(u, v, z=1.0):
        """Visibility of one marker facing the camera, corners at pixels (u, v) and depth z."""
        u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
        corners = np.stack([(u - cfg.cx) / cfg.fx * z, (v - cfg.cy) / cfg.fy * z, np.full(4, z)], axis=1)
        ok, px = marker_visibility(cam, corners[None], np.array([0.0, 0.0, -1.0]))
        return ok.tolist(), px[0]

    lo = cfg.margin_px - 0.5
    square_u, square_v = [lo, lo + 20.0, lo + 20.0, lo], [100.0, 100.0, 120.0, 120.0]
    ok, px = visible(square_u, square_v)
    np.testing.assert_array_equal(px, np.column_stack([square_u, square_v]))
    assert ok == [True]
    outside = lo - 2.0**-20  # a millionth of a pixel outside (exact in floats)
    assert visible([outside, lo + 20.0, lo + 20.0, outside], square_v)[0] == [False]
    short = [lo, lo + 19.75, lo + 19.75, lo]
    assert visible(short, square_v)[0] == [False]
    # A marker centred on the optical axis at exactly max_range_m is in range; beyond, not.
    r = cfg.max_range_m
    centred_u = [cfg.cx - 64.0, cfg.cx + 64.0, cfg.cx + 64.0, cfg.cx - 64.0]
    centred_v = [cfg.cy - 64.0, cfg.cy - 64.0, cfg.cy + 64.0, cfg.cy + 64.0]
    assert visible(centred_u, centred_v, z=r)[0] == [True]
    assert visible(centred_u, centred_v, z=np.nextafter(r, np.inf))[0] == [False]


# ---------------------------------------------------------------- measure on awkward board sets


def uav_camera(x, y, yaw, altitude, roll=0.0, pitch=0.0):
    return se2_to_se3(x, y, yaw, altitude) @ make_transform(rot_x(roll) @ rot_y(pitch) @ R_BODY_CAM_DOWN)


def floor_board(board_id, layout, x, y, yaw, height=0.4):
    return BoardView(board_id, layout, se2_to_se3(x, y, yaw, height) @ make_transform(R_BODY_BOARD_UP))


def assert_exact(det, T_w_c, board, atol=1e-8):
    truth = invert(T_w_c) @ board.T_w_m
    np.testing.assert_allclose(det.T_c_m[:3, 3], truth[:3, 3], rtol=0, atol=atol)
    assert rotation_angle(det.T_c_m[:3, :3].T @ truth[:3, :3]) <= 10 * atol
    np.testing.assert_array_equal(det.T_c_m[3], [0.0, 0.0, 0.0, 1.0])


def mixed_scene():
    """Hidden, partly visible, fully visible and differently sized boards under one camera."""
    T_w_c = uav_camera(0.0, 0.0, 0.3, 2.0, roll=0.04)
    single = BoardLayout(marker_ids=(20,), rows=1, cols=1, marker_size=0.2)
    big = BoardLayout(marker_ids=tuple(range(30, 39)), rows=3, cols=3, marker_size=0.1, gap=0.02)
    boards = [
        floor_board(5, board_for_robot(5), 6.0, 6.0, 0.0),  # far outside the view
        floor_board(1, board_for_robot(1), 0.3, 0.2, 0.7),
        floor_board(7, single, -0.4, 0.3, 2.0),
        floor_board(2, board_for_robot(2), 0.1, 1.52, 0.0),  # straddles the image edge
        floor_board(4, big, -0.3, -0.4, -1.0),
        floor_board(6, board_for_robot(6), 0.0, 0.0, 0.0, height=-3.0),  # beyond max_range_m, under the floor
    ]
    return T_w_c, boards


def test_mixed_board_sets_match_boards_measured_one_by_one():
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.0, max_range_m=4.0))
    T_w_c, boards = mixed_scene()
    dets = cam.measure(T_w_c, boards, 1.5, np.random.default_rng(0))
    singles = [d for b in boards for d in cam.measure(T_w_c, [b], 1.5, np.random.default_rng(0))]
    assert [d.board_id for d in dets] == [1, 7, 2, 4]
    assert [d.board_id for d in singles] == [1, 7, 2, 4]
    by_id = {b.board_id: b for b in boards}
    partial = next(d for d in dets if d.board_id == 2)
    assert 0 < partial.n_markers < 4  # the board on the image edge keeps its inner markers
    assert next(d for d in dets if d.board_id == 4).marker_ids == tuple(range(30, 39))
    for d, s in zip(dets, singles):
        assert d.marker_ids == s.marker_ids
        np.testing.assert_array_equal(d.corners_px, s.corners_px)
        assert d.corners_px.shape == (4 * d.n_markers, 2) and d.corners_px.flags.c_contiguous
        assert_exact(d, T_w_c, by_id[d.board_id])
        assert d.reprojection_error_px < 1e-6


def test_noisy_mixed_boards_are_reproducible_and_match_single_draws():
    # One draw covers all visible corners in board order, so the first board of a
    # set sees the same noise as when it is measured alone.
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.8, max_range_m=4.0))
    T_w_c, boards = mixed_scene()
    a = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(42))
    b = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(42))
    first = cam.measure(T_w_c, boards[1:2], 0.0, np.random.default_rng(42))
    assert len(a) == len(b) == 4
    for da, db in zip(a, b):
        np.testing.assert_array_equal(da.T_c_m, db.T_c_m)
        np.testing.assert_array_equal(da.corners_px, db.corners_px)
        assert da.reprojection_error_px == db.reprojection_error_px
    np.testing.assert_array_equal(a[0].corners_px, first[0].corners_px)
    np.testing.assert_array_equal(a[0].T_c_m, first[0].T_c_m)
    assert a[0].reprojection_error_px == pytest.approx(first[0].reprojection_error_px, rel=1e-12)


@pytest.mark.parametrize("failure", ["reported", "raised"])
def test_a_failed_solve_drops_only_its_board(monkeypatch, failure):
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.5, pnp_method="SQPNP"))
    T_w_c = uav_camera(0.0, 0.0, 0.0, 1.8)
    boards = [floor_board(i, board_for_robot(i), x, 0.1 * i, i) for i, x in enumerate((-0.4, 0.0, 0.4))]
    reference = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(3))
    solve_pnp = cv2.solvePnP
    calls = []

    def fail_the_middle_board(object_points, *args, **kwargs):
        # The second board solved is the middle one; fail it on every attempt.
        calls.append(object_points.copy())
        if np.array_equal(object_points, calls[min(1, len(calls) - 1)]) and len(calls) >= 2:
            if failure == "raised":
                raise cv2.error("solvePnP failed")
            return False, None, None
        return solve_pnp(object_points, *args, **kwargs)

    monkeypatch.setattr(cv2, "solvePnP", fail_the_middle_board)
    dets = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(3))
    assert [d.board_id for d in dets] == [0, 2]
    for d, r in zip(dets, (reference[0], reference[2])):
        np.testing.assert_array_equal(d.T_c_m, r.T_c_m)
        assert d.reprojection_error_px == pytest.approx(r.reprojection_error_px, rel=1e-12)


def test_occlusion_on_a_board_near_the_limits():
    # The board straddling the image edge is checked marker by marker; occlusion
    # still applies on top, and only to geometrically visible markers.
    cam = GeometricCamera("uav", CameraConfig(noise_px=0.0, max_range_m=4.0))
    T_w_c, boards = mixed_scene()
    asked = []

    def block_board_1(p_from, p_to):
        asked.append(p_to.copy())
        centre_1 = boards[1].T_w_m[:3, 3]
        return bool(np.linalg.norm(p_to[:2] - centre_1[:2]) < 0.2)

    dets = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(0), occluded=block_board_1)
    assert [d.board_id for d in dets] == [7, 2, 4]
    assert len(asked) == 4 + 1 + dets[1].n_markers + 9


def test_forward_camera_over_a_range_of_distances_is_exact():
    cam = GeometricCamera("fwd", CameraConfig(noise_px=0.0))
    T_w_c = se2_to_se3(0.0, 0.0, 0.0, 0.3) @ make_transform(R_BODY_CAM_FORWARD)
    for distance in np.linspace(0.45, 4.5, 12):
        T_w_m = se2_to_se3(distance, 0.05, 0.2, 0.3) @ make_transform(R_BODY_BOARD_BACK)
        board = BoardView(0, board_for_robot(0), T_w_m)
        (det,) = cam.measure(T_w_c, [board], 0.0, np.random.default_rng(0))
        assert_exact(det, T_w_c, board)


# ---------------------------------------------------------------- geometry cache


def test_layout_geometry_is_cached_per_layout_objects():
    cam = GeometricCamera("uav", CameraConfig())
    T_w_c = uav_camera(0.0, 0.0, 0.0, 1.8)
    layouts = [board_for_robot(0), board_for_robot(1)]
    for step in range(5):  # new views every step, same layouts: one cache entry
        boards = [floor_board(i, layouts[i], 0.2 * i, 0.01 * step, 0.0) for i in range(2)]
        cam.measure(T_w_c, boards, 0.0, np.random.default_rng(step))
    assert len(cam._geometries) == 1
    for i in range(40):  # many distinct layout objects: the cache stays small
        cam.measure(T_w_c, [floor_board(0, board_for_robot(0), 0.0, 0.0, 0.0)], 0.0, np.random.default_rng(i))
    assert 1 <= len(cam._geometries) <= 16


def test_non_planar_layout_data_is_rejected():
    class Bent(BoardLayout):
        @property
        def marker_corners(self):
            pts = super().marker_corners.copy()
            pts[0, 0, 2] = 0.01
            return pts

    cam = GeometricCamera("uav", CameraConfig())
    with pytest.raises(ValueError, match="planar"):
        cam.measure(uav_camera(0, 0, 0, 1.8), [floor_board(0, Bent(), 0, 0, 0)], 0.0, np.random.default_rng(0))


# ---------------------------------------------------------------- micro-benchmark interface


def test_bench_camera_reports_timings_for_visible_boards():
    result = bench_camera(2, 5)
    assert set(result) == {"n_boards", "iters", "pnp_method", "median_us", "mean_us", "min_us", "detections_per_call"}
    assert result["n_boards"] == 2 and result["iters"] == 5 and result["pnp_method"] == "PLANAR_LM"
    assert result["detections_per_call"] == 2.0
    assert 0.0 < result["min_us"] <= result["median_us"]
    with pytest.raises(ValueError, match="n_boards"):
        bench_camera(0, 5)
    with pytest.raises(ValueError, match="iters"):
        bench_camera(1, 0)


def test_a_failed_planar_lm_solve_drops_only_its_board(monkeypatch):
    import moma_env.camera.geometric as geometric

    cam = GeometricCamera("uav", CameraConfig(noise_px=0.5))
    assert cam.config.pnp_method == "PLANAR_LM"
    T_w_c = uav_camera(0.0, 0.0, 0.0, 1.8)
    boards = [floor_board(i, board_for_robot(i), x, 0.1 * i, i) for i, x in enumerate((-0.4, 0.0, 0.4))]
    reference = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(3))
    solve = geometric.solve_boards
    calls = []

    def fail_the_middle_board(obj, px, starts, parameters, *rest):
        # solve_boards reports a failed board with a NaN error.
        calls.append(len(starts) - 1)
        solve(obj, px, starts, parameters, *rest)
        rest[-3][1] = np.nan  # rms (then cov, status)

    monkeypatch.setattr(geometric, "solve_boards", fail_the_middle_board)
    dets = cam.measure(T_w_c, boards, 0.0, np.random.default_rng(3))
    assert calls == [3]
    assert [d.board_id for d in dets] == [0, 2]
    for d, r in zip(dets, (reference[0], reference[2])):
        np.testing.assert_array_equal(d.T_c_m, r.T_c_m)
        assert d.reprojection_error_px == pytest.approx(r.reprojection_error_px, rel=1e-12)


# ---------------------------------------------------------------- one-frame fast paths


def test_covariance_finite_keeps_a_covariance_with_only_finite_entries():
    """covariance_finite (one call for every board) and finite_or_none (one covariance) are
    the same test, every entry finite: NaN or an infinity anywhere drops the covariance, and
    finite entries whose sum would overflow keep it."""
    from moma_env.camera.geometric import finite_or_none
    from moma_env.camera.kernels import covariance_finite

    rng = np.random.default_rng(11)
    n_dropped = n_huge_kept = 0
    for trial in range(3000):
        k = int(rng.integers(1, 6))
        cov = rng.normal(size=(k, 6, 6)) * 10.0 ** rng.integers(-8, 9, size=(k, 6, 6))
        if trial % 3 == 0:  # entries near the largest float: their sum overflows, they do not
            cov[rng.random((k, 6, 6)) < 0.4] = 1.7e308
        if trial % 7 == 0:
            cov.flat[rng.integers(cov.size)] = rng.choice([np.nan, np.inf, -np.inf])
        expected = [bool(np.isfinite(c).all()) for c in cov]
        finite = np.empty(k, dtype=bool)
        covariance_finite(cov, finite)
        assert finite.tolist() == expected
        assert [finite_or_none(c) is not None for c in cov] == expected
        n_dropped += expected.count(False)
        with np.errstate(over="ignore"):
            n_huge_kept += sum(e and not np.isfinite(c.sum()) for e, c in zip(expected, cov))
    assert n_dropped > 100 and n_huge_kept > 100  # both kinds of case were exercised


def test_a_frame_seeing_every_marker_uses_the_geometry_tables():
    """A single frame that sees every marker of every board takes its corner rows, board
    starts and camera rows from its board-set geometry instead of selecting the visible
    markers: the same arrays as the selection they replace."""
    from moma_env.camera.geometric import FrameGroup
    from moma_env.camera.kernels import project_markers

    cam = GeometricCamera("uav", CameraConfig(noise_px=0.0, max_range_m=4.0))
    rng = np.random.default_rng(5)
    layouts = [board_for_robot(1), BoardLayout(marker_ids=(20,), rows=1, cols=1, marker_size=0.2), board_for_robot(2)]
    checked = 0
    for _ in range(40):
        T_w_c = uav_camera(*rng.uniform(-0.1, 0.1, 2), rng.uniform(-3, 3), rng.uniform(1.8, 2.4))
        boards = [
            floor_board(i, lay, *rng.uniform(-0.4, 0.4, 2), rng.uniform(-3, 3)) for i, lay in enumerate(layouts)
        ]
        group = FrameGroup([cam], [T_w_c], [boards], [0.0], [np.random.default_rng(0)], [None])
        # The selection of the general path (any visibility), computed here as it was.
        geo = cam._geometry(boards)
        relative = np.array([b.T_w_m[:3] for b in boards])
        relative[:, :, 3] -= T_w_c[:3, 3]
        poses = np.matmul(T_w_c[:3, :3].T, relative)
        n_markers = geo.corners_m.shape[0]
        uv, visible = np.empty((n_markers, 4, 2)), np.empty(n_markers, dtype=bool)
        centres, board_visible = np.empty((n_markers, 3)), np.empty(len(boards), dtype=np.int64)
        project_markers(
            poses, geo.board_markers, geo.corners_m, cam._parameter_rows, np.zeros(len(boards), dtype=np.int64),
            uv, visible, centres, board_visible,
        )
        assert group.all_seen == bool(visible.all())
        np.testing.assert_array_equal(group.px, uv[visible].reshape(-1, 2))
        np.testing.assert_array_equal(group.obj, geo.corners_m[visible].reshape(-1, 3))
        if not group.all_seen:
            continue
        checked += 1
        seen = [g for g in range(len(boards)) if board_visible[g]]
        bounds = [0]
        for g in seen:
            bounds.append(bounds[-1] + 4 * board_visible[g])
        assert geo.boards == seen and geo.corner_bounds == bounds
        np.testing.assert_array_equal(geo.corner_starts, bounds)
        np.testing.assert_array_equal(geo.board_zeros, np.zeros(len(seen), dtype=np.int64))
        assert group.px.flags.c_contiguous and group.obj.flags.c_contiguous and group.obj.flags.writeable
    assert checked > 5


def test_a_request_without_boards_measures_nothing():
    """measure_batch of a single geometric frame with no boards: no detections, as measure."""
    from moma_env.camera import MeasureRequest, measure_batch

    cam = GeometricCamera("uav", CameraConfig(noise_px=0.5))
    T_w_c = uav_camera(0.0, 0.0, 0.0, 1.8)
    assert measure_batch([MeasureRequest(cam, T_w_c, [], 1.0, np.random.default_rng(0))]) == [[]]
    assert cam.measure(T_w_c, [], 1.0, np.random.default_rng(0)) == []


def test_board_offsets_equal_the_numpy_code_they_replace():
    """board_offsets replaced a stack of top rows and an in-place subtraction of the camera
    positions (one frame and a batch of frames): the same bits."""
    from moma_env.camera.kernels import board_offsets

    rng = np.random.default_rng(8)
    for _ in range(500):
        n_frames = int(rng.integers(1, 5))
        sizes = rng.integers(1, 4, size=n_frames)
        cameras = [
            make_transform(rotvec_to_matrix(rng.normal(size=3)), rng.normal(size=3) * 10.0 ** rng.integers(-2, 3))
            for _ in range(n_frames)
        ]
        boards = [
            make_transform(rotvec_to_matrix(rng.normal(size=3)), rng.normal(size=3) * 10.0 ** rng.integers(-2, 3))
            for _ in range(int(sizes.sum()))
        ]
        owner = np.repeat(np.arange(n_frames), sizes)
        stack = np.array(cameras)
        reference = np.ascontiguousarray(np.array(boards)[:, :3])
        reference[:, :, 3] -= stack[owner, :3, 3]
        np.testing.assert_array_equal(board_offsets(np.array(boards), stack, owner), reference)
        # One frame: the camera's own 4x4 as a stack of one.
        first = boards[: sizes[0]]
        single = np.array([T[:3] for T in first])
        single[:, :, 3] -= cameras[0][:3, 3]
        out = board_offsets(np.array(first), cameras[0][None], np.zeros(len(first), dtype=np.int64))
        np.testing.assert_array_equal(out, single)
