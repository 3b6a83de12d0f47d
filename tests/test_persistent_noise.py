"""Detection noise that persists over a switch window: the estimators' covariance of it.

A detection's ``persistent_covariance`` P (a part of its covariance C) is the
same draw in every frame while the camera and the board stand still; the mean
of n such frames has covariance ``P + (C - P) / n``. Without it (None) every
number is the one of independent frames, to the bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from moma_env import geometry as g
from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator
from moma_env.estimator.detection import frame_fusion_covariance
from moma_env.estimator.uncertainty import LinearError, apply_error, pose_error, window_mean_noise
from moma_env.estimator.window import SettlingWindow

BOARD = np.eye(4)
CAMERA = g.make_transform(g.R_BODY_CAM_DOWN, [0.0, 0.0, 0.0])
STD = np.array([0.003, 0.003, 0.008, 0.01, 0.01, 0.004])  # m, m, m, rad, rad, rad (camera frame)


def _random_spd(rng: np.random.Generator) -> np.ndarray:
    A = rng.normal(size=(6, 6))
    return A @ A.T


def test_window_mean_noise_without_persistence_is_todays_mean_to_the_bit() -> None:
    rng = np.random.default_rng(0)
    Q = sum(_random_spd(rng) for _ in range(7))
    assert np.array_equal(window_mean_noise(Q, None, 7), Q / 49)
    # equal samples: P + (Q - P) / n
    Q1, P1 = _random_spd(rng), 0.3 * _random_spd(rng)
    n = 25
    np.testing.assert_allclose(window_mean_noise(n * Q1, n * P1, n), P1 + (Q1 - P1) / n, rtol=1e-12)


def window_mean_error(errors: list[LinearError], joint: dict | None = None) -> LinearError:
    """The mean error a settling window of equal poses gives its samples' ``errors``."""
    window = SettlingWindow(len(errors), joint=joint)
    for e in errors:
        window.add(np.eye(4), e)
    return window.mean_error()


def test_window_mean_without_persistent_parts_equals_the_plain_mean() -> None:
    rng = np.random.default_rng(1)
    errors = [LinearError({0: rng.normal(size=(6, 6))}, _random_spd(rng)) for _ in range(9)]
    plain = LinearError.mean(errors)
    mean = window_mean_error(errors, {(0, 0): _random_spd(rng)})
    assert mean.P is None
    assert np.array_equal(mean.Q, plain.Q)
    assert np.array_equal(mean.J[0], plain.J[0])


def test_window_mean_with_persistent_parts() -> None:
    rng = np.random.default_rng(2)
    Q, P = _random_spd(rng), 0.5 * np.eye(6)
    errors = [LinearError({}, Q, P) for _ in range(4)]
    window = window_mean_error(errors)
    np.testing.assert_allclose(window.Q, P + (Q - P) / 4, rtol=1e-12)
    np.testing.assert_allclose(window.P, P, rtol=1e-12)
    independent = LinearError.mean(errors)  # different boards of one frame: their persistent parts independent
    np.testing.assert_allclose(independent.Q, Q / 4, rtol=1e-12)
    np.testing.assert_allclose(independent.P, P / 4, rtol=1e-12)


def test_plus_noise_and_transformed_carry_the_persistent_part() -> None:
    rng = np.random.default_rng(3)
    A, C = rng.normal(size=(6, 6)), _random_spd(rng)
    e = LinearError({0: np.eye(6)}).plus_noise(A, C, 0.25 * C)
    np.testing.assert_allclose(e.P, 0.25 * A @ C @ A.T, rtol=1e-12)
    B = rng.normal(size=(6, 6))
    np.testing.assert_allclose(e.transformed(B).P, B @ e.P @ B.T, rtol=1e-12)
    assert LinearError({0: np.eye(6)}).plus_noise(A, C).P is None


def test_frame_fusion_covariance() -> None:
    rng = np.random.default_rng(6)
    C = _random_spd(rng) * 1e-6
    d = Detection("down", 0, np.eye(4), np.empty((0, 2)), (), 0.0, covariance=C)
    assert frame_fusion_covariance(d, 25) is C  # no persistent part: every frame independent
    P = 0.3 * C
    d = Detection("down", 0, np.eye(4), np.empty((0, 2)), (), 0.0, covariance=C, persistent_covariance=P)
    assert frame_fusion_covariance(d, 1) is C
    # k frames fused as independent carry exactly the information of the mean of k correlated ones
    for k in (2, 5, 40):
        information = sum(np.linalg.inv(frame_fusion_covariance(d, j)) for j in range(1, k + 1))
        np.testing.assert_allclose(np.linalg.inv(information), P + (C - P) / k, rtol=1e-7)
    # a persistent part in the lateral translation only (the board shift): the rest is independent
    S = np.diag([4e-6, 4e-6, 0.0, 0.0, 0.0, 0.0])
    d = Detection("down", 0, np.eye(4), np.empty((0, 2)), (), 0.0, covariance=C + S, persistent_covariance=S)
    information = sum(np.linalg.inv(frame_fusion_covariance(d, j)) for j in range(1, 31))
    np.testing.assert_allclose(np.linalg.inv(information), S + C / 30, rtol=1e-6, atol=1e-15)


def _estimator(window: int) -> MomaEstimator:
    est = MomaEstimator(EstimatorConfig(window=window, gate=None, window_outlier_k=1e9))  # every sample an inlier
    est.add_robot("ref", boards={0: BOARD}, static=True, initial_pose=np.eye(4))
    est.add_robot("target", boards={1: BOARD}, static=True)
    est.add_robot("uav", cameras={"down": CAMERA}, static=False)
    return est


def _window_nees(rho: float | None, runs: int, window: int, seed: int) -> np.ndarray:
    """NEES (6 dof) of the target's frozen pose over ``runs`` windows whose detection noise persists
    with fraction ``rho`` of its variance; the detections declare it (``rho``) or not (None: declare 0)."""
    truth_target = g.make_transform(g.rot_z(0.4), [0.6, 0.1, 0.0])
    T_w_c = g.make_transform(g.R_BODY_CAM_DOWN, [0.3, 0.05, 2.0])
    C = np.diag(STD**2)
    true_rho = 0.8
    declared = None if rho is None else rho * C
    rng = np.random.default_rng(seed)
    nees = []
    for _ in range(runs):
        est = _estimator(window)
        persistent = {b: rng.normal(0.0, np.sqrt(true_rho) * STD) for b in (0, 1)}
        for k in range(window):
            dets = []
            for b, T_w_m in ((0, np.eye(4)), (1, truth_target)):
                e = persistent[b] + rng.normal(0.0, np.sqrt(1.0 - true_rho) * STD)
                T_c_m = apply_error(g.invert(T_w_c) @ T_w_m, e)
                dets.append(Detection("down", b, T_c_m, np.empty((0, 2)), (), 0.04 * k, covariance=C, persistent_covariance=declared))
            est.update(0.04 * (k + 1), dets)
        estimate = est.estimate("target")
        assert estimate.n_window == window and estimate.phase.name == "REFERENCE"
        e = pose_error(truth_target, estimate.T_w_b)
        nees.append(float(e @ np.linalg.solve(estimate.covariance, e)))
    return np.array(nees)


def test_moma_window_covariance_describes_persistent_noise() -> None:
    """Monte Carlo: noise 80 % persistent over the window; the declared persistence makes the frozen
    pose's NEES chi-square (6 dof), while independent frames would be over-confident by about n * 0.8."""
    runs, window = 150, 10
    declared = _window_nees(0.8, runs, window, seed=4)
    lo, hi = chi2.ppf([0.005, 0.995], 6 * runs) / runs
    assert lo < declared.mean() < hi, declared.mean()
    undeclared = _window_nees(None, runs, window, seed=4)
    assert undeclared.mean() > 4.0 * 6


def test_zero_persistent_covariance_changes_nothing() -> None:
    """A zero persistent part gives the numbers of none (the estimator's arithmetic without it)."""
    a = _window_nees(0.0, 3, 5, seed=5)
    b = _window_nees(None, 3, 5, seed=5)
    np.testing.assert_allclose(a, b, rtol=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"persistent_covariance": np.eye(5)}, "persistent_covariance must be"),
        ({"persistent_covariance": np.full((6, 6), np.nan)}, "persistent_covariance must be"),
        ({"covariance": None, "persistent_covariance": np.eye(6)}, "persistent_covariance needs a covariance"),
    ],
)
def test_bad_persistent_covariance_is_rejected(kwargs: dict, message: str) -> None:
    est = _estimator(5)
    args = {"covariance": np.eye(6), **kwargs}
    d = Detection("down", 0, g.make_transform(np.eye(3), [0.0, 0.0, 2.0]), np.empty((0, 2)), (), 0.0, **args)
    with pytest.raises(ValueError, match=message):
        est.update(0.04, [d])


def _six_frames(observe) -> tuple:
    """``(observations, book, time, detections)``: ``observe(book, by_camera)`` after each of six
    frames in which a camera sees a reference board and a target's, the target declared static
    before the third; the book, the last time (s) and the frame's detections after them."""
    from moma_env.estimator.bookkeeping import Bookkeeper

    book = Bookkeeper(EstimatorConfig(window=5, gate=None))
    book.add_robot("ref", boards={0: BOARD}, cameras=None, static=True, initial_pose=np.eye(4), time=0.0, planar=False)
    book.add_robot("target", boards={1: BOARD}, cameras=None, static=False, initial_pose=None, time=0.0, planar=False)
    book.add_robot("uav", boards=None, cameras={"down": CAMERA}, static=False, initial_pose=None, time=0.0, planar=False)
    both = [Detection("down", b, np.eye(4), np.empty((0, 2)), (), 0.0) for b in (0, 1)]
    seen = []
    t = 0.0
    for frame in range(6):
        if frame == 2:
            book.set_static("target", True, t)
        t += 0.04
        _, by_camera = book.begin_update(t, both)
        seen.append(observe(book, by_camera))
        book.end_update(t, book.measured_robots(by_camera, book.located_cameras(by_camera)))
    return seen, book, t, both


def test_still_frames_counts_the_frames_a_board_stands_still() -> None:
    seen, *_ = _six_frames(lambda book, by_camera: (book.still_frames(0), book.still_frames(1)))
    # the reference stands still from the start; the target's frames count from its static declaration
    assert seen == [(1, 1), (2, 1), (3, 1), (4, 2), (5, 3), (6, 4)]


def test_still_together_counts_the_frames_the_related_robots_stand_still_together() -> None:
    seen, book, t, both = _six_frames(lambda book, by_camera: book.still_together("down", by_camera["down"]))
    # a moving target: each frame a new scene; then the frames since it stopped beside the reference
    assert seen == [1, 1, 1, 2, 3, 4]
    only_ref = book.begin_update(t + 0.04, both[:1])[1]
    assert book.still_together("down", only_ref["down"]) == 1  # one static robot: nothing held still together


@pytest.mark.parametrize("name", ["ekf", "graph"])
def test_filters_reject_a_bad_persistent_covariance(name: str) -> None:
    from moma_env.estimator.registry import localiser_factory

    try:
        localiser = localiser_factory(name)(EstimatorConfig(window=5, gate=None))
    except ImportError:
        pytest.skip("gtsam is not installed")
    localiser.add_robot("ref", boards={0: BOARD}, static=True, initial_pose=np.eye(4))
    localiser.add_robot("uav", cameras={"down": CAMERA}, static=False)
    T = g.make_transform(np.eye(3), [0.0, 0.0, 2.0])
    bad = Detection("down", 0, T, np.empty((0, 2)), (), 0.0, covariance=np.eye(6), persistent_covariance=-np.eye(6))
    with pytest.raises(ValueError, match=r"detections\[0\].persistent_covariance"):
        localiser.update(0.04, [bad])
