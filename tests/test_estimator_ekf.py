"""EKF cooperative localisation (``ekf``): exact without noise, consistent, MOMA's status semantics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from localiser_harness import BOARD_TOP, CAM_DOWN, NAMES, SyntheticLeapfrog, planar_nees
from moma_env import geometry as g
from moma_env.config import ConfigError
from moma_env.estimator import Detection, EstimatorConfig, Phase, Status
from moma_env.estimator.ekf import EkfConfig, EkfLocaliser
from moma_env.sim import Localiser, OdometryConsumer


def test_it_is_a_localiser_that_takes_odometry():
    ekf = EkfLocaliser(EstimatorConfig())
    assert isinstance(ekf, Localiser) and isinstance(ekf, OdometryConsumer)


@pytest.mark.parametrize("odometry", [True, False])
def test_zero_noise_is_exact(odometry):
    """Exact detections without covariances get the floor: 1e-6 m / rad here, against priors of
    centimetres, so the filter's compromise with its prior is below 1e-9 m."""
    tight = EkfConfig(detection_floor_m=1e-6, detection_floor_rad=1e-6)
    sim = SyntheticLeapfrog(lambda c: EkfLocaliser(c, tight), seed=0, exact=True, covariances=False, odometry=odometry)
    for k in range(4):
        sim.switch(k)
    for name in NAMES:
        np.testing.assert_allclose(sim.localiser.estimate(name).T_w_b, sim.truth[name], atol=1e-8)
    np.testing.assert_allclose(sim.localiser.estimate("uav").T_w_b, sim.uav_truth, atol=1e-8)


def test_nees_over_a_monte_carlo_of_a_short_run_is_inside_the_chi_square_bounds():
    runs, dof = 16, {"position": 2, "heading": 1}
    values = {"position": [], "heading": []}
    for seed in range(runs):
        sim = SyntheticLeapfrog(EkfLocaliser, seed)
        for k in range(3):
            sim.switch(k)
        assert sim.localiser.estimate("ugv_0").status is Status.LOCALISED
        position, heading = planar_nees(sim.localiser.estimate("ugv_0"), sim.truth["ugv_0"])
        values["position"].append(position)
        values["heading"].append(heading)
    for name, n in dof.items():
        total = float(np.sum(values[name]))
        low, high = chi2.ppf([0.005, 0.995], runs * n)
        assert low < total < high, (name, total / (runs * n))


def one_robot_and_a_camera():
    ekf = EkfLocaliser(EstimatorConfig(window=3, min_window=2, lost_after_s=0.5, gate=None))
    truth = g.se2_to_se3(0.0, 0.0, 0.3)
    ekf.add_robot("ugv_0", boards={0: BOARD_TOP}, static=True, initial_pose=truth, planar=True)
    ekf.add_robot("ugv_1", boards={1: BOARD_TOP}, static=True, initial_pose=g.se2_to_se3(0.0, 0.6, 0.3), planar=True)
    ekf.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    return ekf


def seen(t: float, T_w_c: np.ndarray, poses: dict[int, np.ndarray]) -> list[Detection]:
    return [Detection("down", i, g.invert(T_w_c) @ T @ BOARD_TOP, np.empty((0, 2)), (), t) for i, T in poses.items()]


def test_status_semantics_follow_moma():
    ekf = one_robot_and_a_camera()
    T_w_c = g.make_transform(np.eye(3), [0.0, 0.3, 2.0]) @ CAM_DOWN
    ugv_1 = g.se2_to_se3(0.0, 0.6, 0.3)
    assert ekf.estimate("uav").status is Status.LOST and ekf.estimate("uav").T_w_b is None
    ekf.update(0.04, seen(0.04, T_w_c, {0: g.se2_to_se3(0.0, 0.0, 0.3), 1: ugv_1}))
    assert ekf.estimate("uav").status is Status.LOCALISED
    assert ekf.estimate("ugv_0").phase is Phase.REFERENCE and ekf.window_ready("ugv_0")
    # ugv_1 moves: MOBILE, tracked while seen from the reference ugv_0, HOLDING when not, then LOST.
    ekf.set_static("ugv_1", False, 0.04)
    assert ekf.estimate("ugv_1").phase is Phase.MOBILE and not ekf.window_ready("ugv_1")
    ekf.update(0.08, seen(0.08, T_w_c, {0: g.se2_to_se3(0.0, 0.0, 0.3), 1: ugv_1}))
    assert ekf.estimate("ugv_1").status is Status.LOCALISED
    ekf.update(0.12, seen(0.12, T_w_c, {0: g.se2_to_se3(0.0, 0.0, 0.3)}))
    assert ekf.estimate("ugv_1").status is Status.HOLDING
    ekf.update(0.7, [])
    assert ekf.estimate("ugv_1").status is Status.LOST and ekf.estimate("uav").status is Status.LOST
    assert [e.kind for e in ekf.events if e.robot == "ugv_1"] == ["mobile", "lost"]
    # Declared static again: SETTLING until measured `window` times, then a REFERENCE.
    ekf.set_static("ugv_1", True, 0.7)
    for k, t in enumerate((0.74, 0.78, 0.82)):
        assert ekf.estimate("ugv_1").phase is Phase.SETTLING
        assert ekf.window_ready("ugv_1") is (k >= 2)
        ekf.update(t, seen(t, T_w_c, {0: g.se2_to_se3(0.0, 0.0, 0.3), 1: ugv_1}))
    assert ekf.estimate("ugv_1").phase is Phase.REFERENCE and ekf.estimate("ugv_1").status is Status.LOCALISED
    assert "relocalised" in [e.kind for e in ekf.events if e.robot == "ugv_1"]


def test_odometry_alone_dead_reckons_and_grows_the_covariance():
    ekf = one_robot_and_a_camera()
    ekf.set_static("ugv_1", False, 0.0)
    before = ekf.estimate("ugv_1").covariance
    for k in range(1, 11):
        ekf.odometry("ugv_1", (0.04, 0.0, 0.02), np.diag([1e-6, 1e-6, 1e-6]), 0.04 * k)
        ekf.update(0.04 * k, [])
    expected = g.se2_to_se3(0.0, 0.6, 0.3)
    for _ in range(10):
        expected = expected @ g.se2_to_se3(0.04, 0.0, 0.02)
    est = ekf.estimate("ugv_1")
    np.testing.assert_allclose(est.T_w_b, expected, atol=1e-12)
    assert est.covariance[0, 0] > before[0, 0] and est.covariance[5, 5] == pytest.approx(10e-6)
    assert est.covariance[2, 2] == 0.0  # planar: height stays known


def test_a_detection_far_outside_its_covariance_is_gated_out():
    ekf = one_robot_and_a_camera()
    T_w_c = g.make_transform(np.eye(3), [0.0, 0.3, 2.0]) @ CAM_DOWN
    ekf.update(0.04, seen(0.04, T_w_c, {0: g.se2_to_se3(0.0, 0.0, 0.3), 1: g.se2_to_se3(0.0, 0.6, 0.3)}))
    ekf.set_static("ugv_1", False, 0.04)
    wrong = seen(0.08, T_w_c, {0: g.se2_to_se3(0.0, 0.0, 0.3), 1: g.se2_to_se3(0.5, 0.6, 0.3)})
    ekf.update(0.08, wrong)
    np.testing.assert_allclose(ekf.estimate("ugv_1").T_w_b[:2, 3], [0.0, 0.6], atol=0.02)


@pytest.mark.parametrize(("field", "kwargs"), [("ekf.iterations", {"iterations": 0}), ("ekf.gate_nis", {"gate_nis": -1.0}),
                                               ("ekf.unmodelled_speed_m_s", {"unmodelled_speed_m_s": -1.0})])
def test_bad_settings_name_the_field(field, kwargs):
    with pytest.raises(ConfigError, match=field):
        EkfConfig(**kwargs)
