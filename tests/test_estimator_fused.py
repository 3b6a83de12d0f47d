"""Information-weighted fusion (``EstimatorConfig(fusion="information")``, the ``fused`` estimator)."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.config import ConfigError
from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator
from moma_env.estimator.fusion import information_fusion, information_weights
from moma_env.estimator.registry import fused_estimator
from moma_env.estimator.uncertainty import LinearError
from localiser_harness import BOARD_TOP, CAM_DOWN, NAMES, SyntheticLeapfrog

NO_CORNERS = np.empty((0, 2))


def test_weights_of_two_isotropic_covariances_are_the_inverse_variance_weights():
    s1, s2 = 0.01, 0.03
    W1, W2 = information_weights([s1**2 * np.eye(6), s2**2 * np.eye(6)])
    # 1/s1^2 / (1/s1^2 + 1/s2^2) = 9 / 10 by hand.
    np.testing.assert_allclose(W1, 0.9 * np.eye(6), atol=1e-9)
    np.testing.assert_allclose(W2, 0.1 * np.eye(6), atol=1e-9)


def test_fusion_of_two_positions_is_the_inverse_variance_mean_with_its_variance():
    T1 = g.make_transform(np.eye(3), [1.0, 0.0, 0.0])
    T2 = g.make_transform(np.eye(3), [2.0, 1.0, 0.0])
    e1 = LinearError(Q=np.diag([1e-4, 1e-4, 1e-4, 0.0, 0.0, 0.0]))
    e2 = LinearError(Q=np.diag([4e-4, 4e-4, 4e-4, 0.0, 0.0, 0.0]))
    T, error = information_fusion([T1, T2], [e1, e2], {})
    # Weights 4/5 and 1/5: x = 0.8 * 1 + 0.2 * 2 = 1.2, y = 0.2; variance 1 / (1e4 + 2.5e3) = 8e-5.
    np.testing.assert_allclose(T[:3, 3], [1.2, 0.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.diag(error.covariance({}))[:3], [8e-5] * 3, rtol=1e-6)


def test_fusion_keeps_the_dependence_on_a_shared_reference():
    T = g.make_transform(np.eye(3), [0.0, 0.0, 0.0])
    P = {(0, 0): 1e-4 * np.eye(6)}
    a = LinearError({0: np.eye(6)}, 1e-4 * np.eye(6))
    b = LinearError({0: np.eye(6)}, 1e-4 * np.eye(6))
    _, fused = information_fusion([T, T], [a, b], P)
    # The shared reference's error does not average down; the fresh noise halves.
    np.testing.assert_allclose(fused.covariance(P), 1e-4 * np.eye(6) + 0.5e-4 * np.eye(6), rtol=1e-6)


def two_references_and_a_camera(fusion: str) -> tuple[MomaEstimator, np.ndarray, np.ndarray]:
    """Two reference UGVs (known poses) seen by one camera whose detections are off by
    known translations with covariances 0.01^2 and 0.03^2 m^2 (no rotation error)."""
    est = MomaEstimator(EstimatorConfig(gate=None, fusion=fusion))
    truth = {"ugv_0": g.se2_to_se3(0.0, 0.0, 0.3), "ugv_1": g.se2_to_se3(0.0, 0.6, 0.3)}
    for i, name in enumerate(NAMES):
        est.add_robot(name, boards={i: BOARD_TOP}, static=True, initial_pose=truth[name], planar=True)
    est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    T_w_c = g.make_transform(g.rot_z(0.4), [0.1, 0.3, 2.0]) @ CAM_DOWN
    offsets = (np.array([0.01, 0.0, 0.0]), np.array([0.0, 0.02, 0.0]))
    detections = []
    for i, (name, std, delta) in enumerate(zip(NAMES, (0.01, 0.03), offsets)):
        T_c_m = g.invert(T_w_c) @ truth[name] @ BOARD_TOP
        T_c_m[:3, 3] += delta
        cov = np.diag([std**2] * 3 + [0.0] * 3)
        detections.append(Detection("down", i, T_c_m, NO_CORNERS, (), 0.04, covariance=cov))
    est.update(0.04, detections)
    # A camera from a board measured delta too far in C sits R_w_c @ delta off the other way.
    candidates = [T_w_c[:3, 3] - T_w_c[:3, :3] @ delta for delta in offsets]
    return est, candidates, T_w_c


def test_two_references_with_different_covariances_weight_the_camera_pose_by_hand():
    est, (p1, p2), _ = two_references_and_a_camera("information")
    np.testing.assert_allclose(est.camera_pose("down")[:3, 3], 0.9 * p1 + 0.1 * p2, atol=1e-9)
    cov = est.camera_covariance("down")
    np.testing.assert_allclose(np.diag(cov)[:3], [1.0 / (1e4 + 1e4 / 9.0)] * 3, rtol=1e-5)


def test_the_paper_mean_stays_the_default_and_unweighted():
    assert EstimatorConfig().fusion == "mean"
    est, (p1, p2), _ = two_references_and_a_camera("mean")
    np.testing.assert_allclose(est.camera_pose("down")[:3, 3], 0.5 * p1 + 0.5 * p2, atol=1e-9)


def test_fused_estimator_is_exact_without_noise():
    sim = SyntheticLeapfrog(fused_estimator, seed=0, exact=True)
    for k in range(4):
        sim.switch(k)
    for name in NAMES:
        np.testing.assert_allclose(sim.localiser.estimate(name).T_w_b, sim.truth[name], atol=1e-9)
    assert sim.localiser.config.fusion == "information"


def test_unknown_fusion_names_the_field():
    with pytest.raises(ConfigError, match="estimator.fusion"):
        EstimatorConfig(fusion="median")
