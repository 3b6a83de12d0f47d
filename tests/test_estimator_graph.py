"""Pose-graph MOMA (``graph``, GTSAM's iSAM2): exact without noise, consistent, MOMA's status semantics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

gtsam = pytest.importorskip("gtsam")

from localiser_harness import BOARD_TOP, CAM_DOWN, NAMES, SyntheticLeapfrog, planar_nees  # noqa: E402
from moma_env import geometry as g  # noqa: E402
from moma_env.config import ConfigError  # noqa: E402
from moma_env.estimator import Detection, EstimatorConfig, Phase, Status  # noqa: E402
from moma_env.estimator.graph import GraphConfig, GraphLocaliser, gtsam_from_ros, ros_from_gtsam  # noqa: E402
from moma_env.estimator.uncertainty import apply_error, pose_error  # noqa: E402
from moma_env.sim import Localiser  # noqa: E402


def test_it_is_a_localiser():
    assert isinstance(GraphLocaliser(EstimatorConfig()), Localiser)


def test_covariance_conventions_convert_both_ways_and_match_a_perturbation():
    rng = np.random.default_rng(0)
    T = g.make_transform(g.rotvec_to_matrix(rng.normal(size=3)), rng.normal(size=3))
    xi = 1e-6 * rng.normal(size=6)  # GTSAM: rotation first, T Exp(xi)
    perturbed = T @ gtsam.Pose3.Expmap(xi).matrix()
    e = pose_error(perturbed, T)  # ours: translation first, on the left
    B = ros_from_gtsam(T, np.outer(xi, xi))
    np.testing.assert_allclose(B, np.outer(e, e), atol=1e-15)
    A = rng.normal(size=(6, 6))
    C = A @ A.T
    np.testing.assert_allclose(gtsam_from_ros(T, ros_from_gtsam(T, C)), C, atol=1e-12)
    np.testing.assert_allclose(apply_error(T, e), perturbed, atol=1e-12)


def test_zero_noise_is_exact():
    tight = GraphConfig(detection_floor_m=1e-6, detection_floor_rad=1e-6)
    sim = SyntheticLeapfrog(lambda c: GraphLocaliser(c, tight), seed=0, exact=True, covariances=False)
    for k in range(4):
        sim.switch(k)
    for name in NAMES:
        np.testing.assert_allclose(sim.localiser.estimate(name).T_w_b, sim.truth[name], atol=1e-8)
    np.testing.assert_allclose(sim.localiser.estimate("uav").T_w_b, sim.uav_truth, atol=1e-8)
    variables, factors = sim.localiser.size
    assert variables > 0 and factors > variables


def test_nees_over_a_monte_carlo_of_a_short_run_is_inside_the_chi_square_bounds():
    runs, dof = 12, {"position": 2, "heading": 1}
    values = {"position": [], "heading": []}
    for seed in range(runs):
        sim = SyntheticLeapfrog(GraphLocaliser, seed)
        for k in range(3):
            sim.switch(k)
        est = sim.localiser.estimate("ugv_0")
        assert est.status is Status.LOCALISED
        position, heading = planar_nees(est, sim.truth["ugv_0"])
        values["position"].append(position)
        values["heading"].append(heading)
    for name, n in dof.items():
        total = float(np.sum(values[name]))
        low, high = chi2.ppf([0.005, 0.995], runs * n)
        assert low < total < high, (name, total / (runs * n))


def seen(t: float, T_w_c: np.ndarray, poses: dict[int, np.ndarray]) -> list[Detection]:
    return [Detection("down", i, g.invert(T_w_c) @ T @ BOARD_TOP, np.empty((0, 2)), (), t) for i, T in poses.items()]


def test_status_semantics_follow_moma_and_a_static_phase_keeps_improving():
    graph = GraphLocaliser(EstimatorConfig(window=3, min_window=2, lost_after_s=0.5, gate=None))
    ugv_0, ugv_1 = g.se2_to_se3(0.0, 0.0, 0.3), g.se2_to_se3(0.0, 0.6, 0.3)
    graph.add_robot("ugv_0", boards={0: BOARD_TOP}, static=True, initial_pose=ugv_0, planar=True)
    graph.add_robot("ugv_1", boards={1: BOARD_TOP}, static=True, initial_pose=ugv_1, planar=True)
    graph.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    T_w_c = g.make_transform(np.eye(3), [0.0, 0.3, 2.0]) @ CAM_DOWN
    assert graph.estimate("uav").status is Status.LOST and graph.estimate("uav").T_w_b is None
    graph.update(0.04, seen(0.04, T_w_c, {0: ugv_0, 1: ugv_1}))
    assert graph.estimate("uav").status is Status.LOCALISED
    graph.set_static("ugv_1", False, 0.04)
    assert graph.estimate("ugv_1").phase is Phase.MOBILE and not graph.window_ready("ugv_1")
    graph.update(0.08, seen(0.08, T_w_c, {0: ugv_0, 1: ugv_1}))
    assert graph.estimate("ugv_1").status is Status.LOCALISED
    graph.update(0.12, seen(0.12, T_w_c, {0: ugv_0}))
    assert graph.estimate("ugv_1").status is Status.HOLDING
    graph.update(0.7, [])
    assert graph.estimate("ugv_1").status is Status.LOST and graph.estimate("uav").status is Status.LOST
    graph.set_static("ugv_1", True, 0.7)
    stds = []
    for k, t in enumerate((0.74, 0.78, 0.82, 0.86, 0.9)):
        assert graph.estimate("ugv_1").phase is (Phase.SETTLING if k < 3 else Phase.REFERENCE)
        graph.update(t, seen(t, T_w_c, {0: ugv_0, 1: ugv_1}))
        stds.append(graph.estimate("ugv_1").position_std_m)
    # One variable for the static phase: every frame adds to it, so its uncertainty keeps shrinking.
    assert all(b < a for a, b in zip(stds, stds[1:])), stds
    assert [e.kind for e in graph.events if e.robot == "ugv_1"] == ["mobile", "lost", "static", "relocalised", "frozen"]


@pytest.mark.parametrize("field", ["detection_floor_m", "anchor_sigma", "relinearize_threshold"])
def test_bad_settings_name_the_field(field):
    with pytest.raises(ConfigError, match=f"graph.{field}"):
        GraphConfig(**{field: 0.0})


def test_wheel_odometry_factors_lower_the_error_of_the_detection_graph():
    from moma_env.estimator.graph import graph_vision

    errors = {}
    for name, factory in (("odometry", GraphLocaliser), ("vision", graph_vision)):
        squared = []
        for seed in range(12):
            sim = SyntheticLeapfrog(factory, seed)
            for k in range(3):
                sim.switch(k)
            est = sim.localiser.estimate("ugv_0")
            squared.append(float(np.sum((est.T_w_b[:2, 3] - sim.truth["ugv_0"][:2, 3]) ** 2)))
        errors[name] = float(np.sqrt(np.mean(squared)))
    assert errors["odometry"] < errors["vision"], errors
