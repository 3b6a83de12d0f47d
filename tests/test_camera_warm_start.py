"""Warm-started PnP (CameraConfig.pnp_warm_start): against the full solve, fallbacks, reset, copies.

Tolerance against the full solve: both solves end at a Levenberg-Marquardt
stop on the same cost, which stops once a step lowers the cost by at most
1e-7 of itself; that leaves a pose within about sqrt(1e-7 chi^2) ~ 2e-3 of
its own standard deviation from the exact minimum (chi^2 ~ 26 for a 16-corner
board). So when both reach the same minimum they differ by a few 1e-3 in the
full solve's whitened units (measured: at most 3.4e-4 over 12,000 detections
at 0.5 px); the test allows 1e-2, a hundredth of the pose's noise.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import pickle

import numpy as np
import pytest

from moma_env.camera import BoardView, CameraConfig, GeometricCamera, up_in_board
from moma_env.camera.kernels import SOLVED_FULL, SOLVED_WARM, WARM_REJECTED
from moma_env.config import ConfigError
from moma_env.geometry import (
    R_BODY_BOARD_UP,
    R_BODY_CAM_DOWN,
    invert,
    make_transform,
    matrix_to_rotvec,
    rot_x,
    rot_y,
    rotation_angle,
    se2_to_se3,
)
from moma_env.markers import board_for_robot

#: Largest warm - full difference, in the full solve's whitened units (see the module docstring).
WHITENED_TOL = 1e-2
MOUNT = make_transform(R_BODY_BOARD_UP)
UP_M = up_in_board(MOUNT)
LAYOUTS = [board_for_robot(i) for i in range(4)]


def sequence(seed: int, n_frames: int, dt: float = 0.1):
    """Frames ``(time, T_w_c, boards)`` of a hovering, tilting UAV camera over 4 face-up boards
    driving at up to 0.3 m/s (they wrap around the view now and then: jumps)."""
    rng = np.random.default_rng(seed)
    starts = [(rng.uniform(-0.8, 0.8), rng.uniform(-0.6, 0.6), rng.uniform(-3, 3)) for _ in range(4)]
    speeds = [(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.5, 0.5)) for _ in range(4)]
    for k in range(n_frames):
        t = k * dt
        tilt = make_transform(rot_x(0.05 * math.sin(t)) @ rot_y(0.05 * math.cos(1.3 * t)))
        T_w_c = se2_to_se3(0.2 * math.sin(0.3 * t), 0.2 * math.cos(0.2 * t), 0.1 * t, 1.8) @ tilt @ make_transform(R_BODY_CAM_DOWN)
        boards = []
        for i, ((x, y, yaw), (vx, vy, w)) in enumerate(zip(starts, speeds)):
            X = (x + vx * t + 1.0) % 2.0 - 1.0
            Y = (y + vy * t + 0.8) % 1.6 - 0.8
            boards.append(BoardView(i, LAYOUTS[i], se2_to_se3(X, Y, yaw + w * t, 0.4) @ MOUNT, UP_M))
        yield t, T_w_c, boards


def pose_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(dt, dtheta) of ``b`` relative to ``a`` in the detection covariance's convention."""
    return np.concatenate([b[:3, 3] - a[:3, 3], matrix_to_rotvec(b[:3, :3] @ a[:3, :3].T)])


def assert_same(x, y) -> None:
    np.testing.assert_array_equal(x.T_c_m, y.T_c_m)
    np.testing.assert_array_equal(x.covariance, y.covariance)
    assert x.reprojection_error_px == y.reprojection_error_px


@pytest.mark.parametrize("config", [CameraConfig(), CameraConfig(noise_px=1.0, attitude_noise_deg=2.0),
                                    CameraConfig(pose_disambiguation="min_cost"),
                                    CameraConfig(pnp_sigma_source="residuals")])
def test_warm_start_stays_within_a_hundredth_of_a_sigma_of_the_full_solve(config: CameraConfig) -> None:
    full = GeometricCamera("c", config)
    warm = GeometricCamera("c", dataclasses.replace(config, pnp_warm_start=True))
    worst = 0.0
    for seed in range(3):
        full.reset(), warm.reset()
        rng_full, rng_warm = np.random.default_rng([seed, 1]), np.random.default_rng([seed, 1])
        for t, T_w_c, boards in sequence(seed, 120):
            a = full.measure(T_w_c, boards, t, rng_full)
            b = warm.measure(T_w_c, boards, t, rng_warm)
            assert [d.board_id for d in a] == [d.board_id for d in b]
            for x, y in zip(a, b):
                d = pose_difference(x.T_c_m, y.T_c_m)
                worst = max(worst, math.sqrt(d @ np.linalg.solve(x.covariance, d)))
                assert np.abs(d[:3]).max() < 1e-5  # m
                np.testing.assert_array_equal(x.corners_px, y.corners_px)  # the same draws
    accepted, rejected = warm.warm_counts
    assert accepted > 5 * rejected > 0  # mostly warm; the jumps (and ambiguous views) fall back
    assert worst < WHITENED_TOL


def test_noise_free_warm_start_is_exact() -> None:
    warm = GeometricCamera("c", CameraConfig(noise_px=0.0, pnp_warm_start=True))
    full = GeometricCamera("c", CameraConfig(noise_px=0.0))
    worst = {warm: [0.0, 0.0], full: [0.0, 0.0]}
    for t, T_w_c, boards in sequence(4, 80):
        for cam in (warm, full):
            for det in cam.measure(T_w_c, boards, t, np.random.default_rng(0)):
                truth = invert(T_w_c) @ boards[det.board_id].T_w_m
                d = pose_difference(truth, det.T_c_m)
                worst[cam][0] = max(worst[cam][0], float(np.abs(d[:3]).max()))
                worst[cam][1] = max(worst[cam][1], float(np.linalg.norm(d[3:])))
                assert det.reprojection_error_px < 1e-6
    assert warm.warm_counts[0] > 200 and warm.warm_counts[1] == 0
    assert max(worst[warm]) < 1e-8 and max(worst[full]) < 1e-8  # m, rad


def test_a_jump_falls_back_to_the_full_solve_bit_for_bit() -> None:
    config = CameraConfig(pnp_warm_start=True)
    warm, full = GeometricCamera("c", config), GeometricCamera("c", dataclasses.replace(config, pnp_warm_start=False))
    T_w_c = se2_to_se3(0.0, 0.0, 0.0, 1.8) @ make_transform(R_BODY_CAM_DOWN)
    near = [BoardView(0, LAYOUTS[0], se2_to_se3(0.3, 0.1, 0.2, 0.4) @ MOUNT, UP_M)]
    warm.measure(T_w_c, near, 0.0, np.random.default_rng(1))
    # The board jumps 0.9 m and turns by 170 degrees: the warm start lands far off and is rejected.
    jumped = [BoardView(0, LAYOUTS[0], se2_to_se3(-0.6, -0.3, 0.2 + math.radians(170), 0.4) @ MOUNT, UP_M)]
    (a,) = warm.measure(T_w_c, jumped, 0.1, np.random.default_rng(2))
    (b,) = full.measure(T_w_c, jumped, 0.1, np.random.default_rng(2))
    assert warm.warm_counts == [0, 1]
    assert_same(a, b)


def test_boards_not_seen_in_the_last_frame_and_reset_solve_from_scratch() -> None:
    config = CameraConfig(pnp_warm_start=True)
    warm, full = GeometricCamera("c", config), GeometricCamera("c", dataclasses.replace(config, pnp_warm_start=False))
    frames = list(sequence(2, 4))
    (t0, T0, boards0), (t1, T1, boards1), (t2, T2, boards2), (t3, T3, boards3) = frames
    warm.measure(T0, boards0[:2], t0, np.random.default_rng(0))  # boards 0 and 1 remembered
    warm.measure(T1, boards1[2:], t1, np.random.default_rng(0))  # now only 2 and 3
    counts = list(warm.warm_counts)
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    for a, b in zip(warm.measure(T2, boards2[:2], t2, rng_a), full.measure(T2, boards2[:2], t2, rng_b)):
        assert_same(a, b)  # 0 and 1 were not seen in the last frame
    assert warm.warm_counts == counts
    warm.reset()
    for a, b in zip(warm.measure(T3, boards3[:2], t3, rng_a), full.measure(T3, boards3[:2], t3, rng_b)):
        assert_same(a, b)  # forgotten
    assert warm.warm_counts == counts
    # A frame at a time not after the last one does not warm-start either (a new sequence).
    for a, b in zip(warm.measure(T3, boards3[:2], t3, rng_a), full.measure(T3, boards3[:2], t3, rng_b)):
        assert_same(a, b)
    assert warm.warm_counts == counts
    (a, *_), (b, *_) = warm.measure(T3, boards3[:2], t3 + 0.1, rng_a), full.measure(T3, boards3[:2], t3 + 0.1, rng_b)
    assert warm.warm_counts[0] == counts[0] + 2


def mirrored(T_c_m: np.ndarray) -> np.ndarray:
    """The other pose of the planar ambiguity: the board normal mirrored about the line of sight."""
    t = T_c_m[:3, 3] / np.linalg.norm(T_c_m[:3, 3])
    n = T_c_m[:3, 2]
    m = 2.0 * (n @ t) * t - n
    axis = np.cross(n, m)
    angle = math.atan2(np.linalg.norm(axis), n @ m)
    from moma_env.geometry import rotvec_to_matrix

    out = T_c_m.copy()
    out[:3, :3] = rotvec_to_matrix(axis / np.linalg.norm(axis) * angle) @ T_c_m[:3, :3]
    return out


@pytest.mark.parametrize("tilt_deg", [5.0, 10.0, 20.0])
def test_a_warm_start_from_the_mirror_pose_does_not_lock_onto_it(tilt_deg: float) -> None:
    # A small board 3 m away, tilted from the line of sight, 1 px noise: its two poses
    # compete (docs/pnp.md). Started from the wrong one, the warm solve must end where
    # the full solve does: it falls back, or reaches the same pose.
    config = CameraConfig(noise_px=1.0, pnp_warm_start=True)
    full = GeometricCamera("c", dataclasses.replace(config, pnp_warm_start=False))
    T_w_c = make_transform(R_BODY_CAM_DOWN, [0.0, 0.0, 3.4])
    flips = 0
    statuses = []
    for k in range(40):
        yaw = 0.37 * k
        mount = make_transform(rot_x(math.radians(tilt_deg)))
        board = BoardView(0, LAYOUTS[0], se2_to_se3(0.1, -0.05, yaw, 0.4) @ mount, up_in_board(mount))
        truth = invert(T_w_c) @ board.T_w_m
        warm = GeometricCamera("c", config)
        warm._warm_poses, warm._warm_time = {0: mirrored(truth)}, -1.0
        (a,) = warm.measure(T_w_c, [board], 0.0, np.random.default_rng(k))
        (b,) = full.measure(T_w_c, [board], 0.0, np.random.default_rng(k))
        statuses.append(tuple(warm.warm_counts))
        d = pose_difference(b.T_c_m, a.T_c_m)
        assert math.sqrt(d @ np.linalg.solve(b.covariance, d)) < WHITENED_TOL
        flips += rotation_angle(a.T_c_m[:3, :3].T @ truth[:3, :3]) > math.radians(tilt_deg)
    assert flips == 0
    assert (0, 1) in statuses  # the mirror test did fall back


def test_copies_continue_the_sequence_bit_for_bit() -> None:
    cam = GeometricCamera("c", CameraConfig(pnp_warm_start=True))
    rng = np.random.default_rng(3)
    frames = list(sequence(5, 12))
    for t, T_w_c, boards in frames[:6]:
        cam.measure(T_w_c, boards, t, rng)
    clones = [(copy.deepcopy(cam), copy.deepcopy(rng)), pickle.loads(pickle.dumps((cam, rng)))]
    for t, T_w_c, boards in frames[6:]:
        reference = cam.measure(T_w_c, boards, t, rng)
        for clone, clone_rng in clones:
            for a, b in zip(reference, clone.measure(T_w_c, boards, t, clone_rng)):
                assert_same(a, b)
    assert cam.warm_counts[0] > 0


def test_opencv_methods_never_warm_start() -> None:
    cam = GeometricCamera("c", CameraConfig(pnp_method="SQPNP", pnp_warm_start=True))
    rng = np.random.default_rng(0)
    for t, T_w_c, boards in sequence(1, 5):
        cam.measure(T_w_c, boards, t, rng)
    assert cam.warm_counts == [0, 0]


def test_kernel_status_values_are_distinct() -> None:
    assert len({SOLVED_FULL, SOLVED_WARM, WARM_REJECTED}) == 3 and SOLVED_FULL == 0


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"pnp_warm_start": 1}, "camera.pnp_warm_start.*True or False"),
        ({"pnp_warm_max_rms_px": 0.0}, "camera.pnp_warm_max_rms_px.*> 0"),
        ({"pnp_warm_max_rms_px": math.nan}, "camera.pnp_warm_max_rms_px"),
        ({"pnp_warm_max_rms_px": 0.3, "noise_px": 0.5}, "camera.pnp_warm_max_rms_px.*at least noise_px"),
    ],
)
def test_warm_start_config_is_validated(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        CameraConfig(**kwargs)


def test_warm_threshold_default_follows_the_noise() -> None:
    assert CameraConfig(noise_px=0.5).warm_max_rms_px == 1.5
    assert CameraConfig(noise_px=0.0).warm_max_rms_px == pytest.approx(0.3)  # 3 x pnp_sigma_floor_px
    assert CameraConfig(pnp_warm_max_rms_px=2).warm_max_rms_px == 2.0
