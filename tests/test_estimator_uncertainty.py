"""Covariance through MOMA's chain: Jacobians against finite differences, and the
estimator's covariances against Monte Carlo errors (consistency)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.estimator import Status
from moma_env.estimator.uncertainty import (
    LinearError,
    apply_error,
    compose_jacobians,
    inverse_jacobian,
    pose_error,
    upright_projection_jacobian,
)
from training.experiments.covariance_growth import SyntheticLeapfrog, growth
from training.experiments.covariance_growth import main as covariance_growth_main

perturb = apply_error
error_of = pose_error


def random_pose(rng: np.random.Generator) -> np.ndarray:
    return g.make_transform(g.rotvec_to_matrix(rng.uniform(-2, 2, 3)), rng.uniform(-2, 2, 3))


def numeric_jacobian(f, T: np.ndarray, h: float = 1e-6) -> np.ndarray:
    J = np.empty((6, 6))
    base = f(T)
    for k in range(6):
        e = np.zeros(6)
        e[k] = h
        J[:, k] = (error_of(f(perturb(T, e)), base) - error_of(f(perturb(T, -e)), base)) / (2 * h)
    return J


@pytest.mark.parametrize("seed", range(5))
def test_compose_and_inverse_jacobians_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    A, B = random_pose(rng), random_pose(rng)
    J_A, J_B = compose_jacobians(A, B)
    np.testing.assert_allclose(J_A, numeric_jacobian(lambda X: X @ B, A), atol=1e-6)
    np.testing.assert_allclose(J_B, numeric_jacobian(lambda X: A @ X, B), atol=1e-6)
    np.testing.assert_allclose(inverse_jacobian(A), numeric_jacobian(g.invert, A), atol=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_upright_projection_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    T_b_x = g.make_transform(g.R_BODY_BOARD_UP @ g.rot_z(rng.uniform(-1, 1)), rng.uniform(-0.3, 0.3, 3))
    T_w_b = g.se2_to_se3(*rng.uniform(-2, 2, 2), rng.uniform(-3, 3), z=0.0)
    tilt = g.make_transform(g.rotvec_to_matrix(rng.normal(0, 0.05, 3)))
    T_w_x = tilt @ T_w_b @ T_b_x
    J = upright_projection_jacobian(T_w_x, T_b_x)
    numeric = numeric_jacobian(lambda X: g.upright_body_from_mount(X, T_b_x, 0.0), T_w_x)
    np.testing.assert_allclose(J, numeric, atol=1e-6)
    assert not J[2:5].any()


def test_linear_error_mean_keeps_the_shared_reference_and_averages_fresh_noise():
    Q = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    errors = [LinearError({0: np.eye(6)}, Q) for _ in range(4)]
    mean = LinearError.mean(errors)
    P = {(0, 0): 2.0 * np.eye(6)}
    np.testing.assert_allclose(mean.covariance(P), 2.0 * np.eye(6) + Q / 4)
    np.testing.assert_allclose(mean.cross(P, 0), 2.0 * np.eye(6))


# --------------------------------------------------------------------------- the estimator
def nees(sim: SyntheticLeapfrog, name: str, planar: bool) -> tuple[float, float, int]:
    """Position NEES, heading NEES and position dimension of ``name``'s current estimate."""
    e = sim.estimator.estimate(name)
    err = error_of(e.T_w_b, sim.truth[name])
    d = 2 if planar else 3
    P = e.covariance
    pos = float(err[:d] @ np.linalg.solve(P[:d, :d], err[:d]))
    heading = float(err[5] ** 2 / P[5, 5])
    return pos, heading, d


@pytest.mark.parametrize("planar", [False, True])
def test_covariance_is_consistent_over_monte_carlo_runs(planar):
    """ANEES of position and heading of a robot after 6 switches, over 150 runs, inside 99 % chi-square bounds."""
    runs = 150
    pos, head = [], []
    for seed in range(runs):
        sim = SyntheticLeapfrog(seed, travel=True, planar=planar)
        for k in range(6):
            sim.switch(k)
        assert sim.estimator.estimate("ugv_1").status is Status.LOCALISED
        p, h, d = nees(sim, "ugv_1", planar)
        pos.append(p)
        head.append(h)
    for values, dof in ((pos, d), (head, 1)):
        anees = float(np.mean(values)) / dof
        # chi2(runs * dof) / (runs * dof): mean 1, sd sqrt(2 / (runs dof)); 99 % ~ 2.6 sd.
        half_width = 2.6 * math.sqrt(2.0 / (runs * dof))
        assert abs(anees - 1.0) < half_width, (anees, dof)


def test_covariance_grows_faster_for_a_travelling_team_than_for_one_that_stays():
    """Heading error becomes lateral error as the team travels: predicted and realised
    position errors grow as n^0.5 in place and faster when travelling, and agree."""
    stays = growth(switches=16, runs=12, seed=0, travel=False)
    travels = growth(switches=16, runs=12, seed=0, travel=True)
    assert 0.4 < stays["predicted_exponent"] < 0.6, stays["predicted_exponent"]
    assert travels["predicted_exponent"] > 0.8, travels["predicted_exponent"]
    # The Monte Carlo errors follow the prediction (12 runs: a loose band).
    for team in (stays, travels):
        ratio = np.array(team["rms_error_m"][4:]) / np.array(team["predicted_std_m"][4:])
        assert 0.5 < float(np.median(ratio)) < 1.6, ratio


def test_covariance_growth_command_prints_both_teams(capsys):
    assert covariance_growth_main(["--switches", "6", "--runs", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [t["travel"] for t in out["teams"]] == [False, True]
    assert all(len(t["predicted_std_m"]) == 6 for t in out["teams"])
    with pytest.raises(SystemExit):
        covariance_growth_main(["--switches", "2"])


def test_apply_error_and_pose_error_are_inverse():
    rng = np.random.default_rng(3)
    T = random_pose(rng)
    e = rng.normal(0.0, 0.3, 6)
    np.testing.assert_allclose(pose_error(apply_error(T, e), T), e, atol=1e-12)


def test_initial_references_have_zero_covariance_and_mobile_robots_positive():
    sim = SyntheticLeapfrog(1, travel=True, planar=False)
    assert not sim.estimator.estimate("ugv_0").covariance.any()
    sim.switch(0)
    sim.frame()
    cov = sim.estimator.estimate("uav").covariance
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    e = sim.estimator.estimate("ugv_1")
    assert e.position_std_m == pytest.approx(math.sqrt(np.trace(e.covariance[:3, :3])))
    assert e.heading_std_rad == pytest.approx(math.sqrt(e.covariance[5, 5]))
