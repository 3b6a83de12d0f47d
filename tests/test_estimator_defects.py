"""The estimator's correctness at switches and at its boundary: a stale pose never
becomes a reference, a window needs enough samples, and bad measurements are refused."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env import geometry as g
from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator, Phase, Status

DT = 0.04
BOARD_TOP = g.make_transform(g.R_BODY_BOARD_UP, [0.0, 0.0, 0.30])
CAM_DOWN = g.make_transform(g.R_BODY_CAM_DOWN, [0.0, 0.0, -0.05])
NO_CORNERS = np.empty((0, 2))
T_W_C = g.make_transform(g.rot_z(0.3), [0.3, 0.0, 2.5]) @ CAM_DOWN


def seen(board_id: int, T_w_b: np.ndarray, t: float) -> Detection:
    return Detection("down", board_id, g.invert(T_W_C) @ T_w_b @ BOARD_TOP, NO_CORNERS, (), t)


def team(n: int) -> tuple[MomaEstimator, dict[str, np.ndarray]]:
    est = MomaEstimator(EstimatorConfig())
    truth = {}
    for i, name in enumerate("abc"[:n]):
        truth[name] = g.se2_to_se3(0.6 * i, 0.1 * i, 0.2 * i)
        est.add_robot(name, boards={i: BOARD_TOP}, static=True, initial_pose=truth[name])
    est.add_robot("uav", cameras={"down": CAM_DOWN}, static=False)
    return est, truth


def position_error(est: MomaEstimator, name: str, truth: dict[str, np.ndarray]) -> float:
    return float(np.linalg.norm(est.estimate(name).T_w_b[:3, 3] - truth[name][:3, 3]))


def drive_a_unseen(est: MomaEstimator, truth: dict[str, np.ndarray], others: str) -> float:
    """Robot a drives 0.30 m for 3 s while its board is not seen (HOLDING, then LOST)."""
    t = 0.0
    for _ in range(5):
        t += DT
        est.update(t, [seen(i, truth[n], t) for i, n in enumerate("abc") if n in truth])
    est.set_static("a", False, t)
    start = truth["a"].copy()
    steps = round(3.0 / DT)
    for k in range(1, steps + 1):
        t = round(t + DT, 10)
        truth["a"] = start @ g.se2_to_se3(0.30 * k / steps, 0.0, 0.0)
        est.update(t, [seen(i, truth[n], t) for i, n in enumerate("abc") if n in others])
    assert est.estimate("a").status is Status.LOST
    return t


def test_stale_freeze_a_lost_robot_never_becomes_a_reference():
    """Two boards under a downward camera: robot a driven unseen until LOST, declared static, then b mobile."""
    est, truth = team(2)
    t = drive_a_unseen(est, truth, others="b")
    est.set_static("a", True, t)
    est.set_static("b", False, t)
    a = est.estimate("a")
    assert a.phase is not Phase.REFERENCE and a.status is Status.LOST
    assert not est.window_ready("a")
    # b is never reported fresh from a's stale pose: with no reference it is not measured at all.
    for k in range(1, 40):
        t = round(t + DT, 10)
        est.update(t, [seen(0, truth["a"], t), seen(1, truth["b"], t)])
        b = est.estimate("b")
        if b.status is Status.LOCALISED:
            assert position_error(est, "b", truth) < 1e-9
    assert est.estimate("a").status is Status.LOST and est.estimate("b").status is not Status.LOCALISED


def test_stale_freeze_with_three_robots_relocalises_from_a_static_reference():
    est, truth = team(3)
    t = drive_a_unseen(est, truth, others="bc")
    est.set_static("a", True, t)
    est.set_static("b", False, t)  # c stays a reference
    assert est.estimate("a").phase is Phase.SETTLING and est.estimate("a").status is Status.LOST
    # b is measured through c, correctly, while a is not yet seen.
    t = round(t + DT, 10)
    est.update(t, [seen(1, truth["b"], t), seen(2, truth["c"], t)])
    assert est.estimate("b").status is Status.LOCALISED and position_error(est, "b", truth) < 1e-9
    # Once c's camera sees a again, a settles from fresh samples and is frozen at its true pose.
    for _ in range(est.config.window + est.config.gate.start_samples - 1):  # the gate restarts on a
        t = round(t + DT, 10)
        est.update(t, [seen(i, truth[n], t) for i, n in enumerate("abc")])
    a = est.estimate("a")
    assert (a.phase, a.status) == (Phase.REFERENCE, Status.LOCALISED)
    assert position_error(est, "a", truth) < 1e-9
    assert [e.kind for e in est.events if e.robot == "a"][-2:] == ["relocalised", "frozen"]


# --------------------------------------------------------------------------- the boundary
def fresh() -> MomaEstimator:
    est, _ = team(2)
    return est


@pytest.mark.parametrize(
    ("T", "match"),
    [
        (np.diag([3.0, 3.0, 3.0, 1.0]), "rigid transform.*determinant 27"),
        (g.make_transform(np.diag([1.0, 1.0, -1.0])), "rigid transform"),  # a reflection
        (g.make_transform(g.rot_x(0.1) + 1e-3), "rigid transform"),
        (np.vstack([np.eye(4)[:3], [0.0, 0.0, 0.5, 1.0]]), "rigid transform"),
    ],
)
def test_a_detection_whose_rotation_is_not_a_rotation_is_refused(T, match):
    est = fresh()
    T = T.copy()
    T[2, 3] = 2.0
    with pytest.raises(ValueError, match=f"board 0 by camera 'down'.*{match}"):
        est.update(0.04, [Detection("down", 0, T, NO_CORNERS, (), 0.04)])
    assert est.time == 0.0 and est.camera_pose("down") is None


def test_a_board_detected_twice_by_one_camera_in_one_frame_is_refused():
    est, truth = team(2)
    d = seen(1, truth["b"], 0.04)
    with pytest.raises(ValueError, match="board 1 .*detected twice"):
        est.update(0.04, [seen(0, truth["a"], 0.04), d, d])
    assert est.time == 0.0


@pytest.mark.parametrize(
    ("detections", "error", "match"),
    [
        (None, TypeError, "detections must be an iterable of Detection, got NoneType"),
        (42, TypeError, "detections must be an iterable of Detection, got int"),
        (["a detection"], TypeError, r"detections\[0\] must be a Detection, got str"),
    ],
)
def test_update_refuses_what_is_not_detections(detections, error, match):
    with pytest.raises(error, match=match):
        fresh().update(0.04, detections)


@pytest.mark.parametrize("time", ["0.04", None, True, float("nan")])
def test_update_refuses_a_time_that_is_not_a_finite_number(time):
    with pytest.raises(ValueError, match="time must be"):
        fresh().update(time, [])


@pytest.mark.parametrize(
    "cov",
    [np.eye(5), np.full((6, 6), np.nan), -np.eye(6), np.triu(np.ones((6, 6)))],
)
def test_a_bad_detection_covariance_is_refused(cov):
    est, truth = team(2)
    d = seen(0, truth["a"], 0.04)
    bad = Detection(d.camera_id, d.board_id, d.T_c_m, d.corners_px, d.marker_ids, d.time, covariance=cov)
    with pytest.raises(ValueError, match="covariance must be a finite symmetric 6x6"):
        est.update(0.04, [bad])


def test_min_window_config_is_checked_against_the_window():
    from moma_env.config import ConfigError

    assert EstimatorConfig(window=4).min_window == 4
    assert EstimatorConfig().min_window == 10
    with pytest.raises(ConfigError, match="estimator.min_window"):
        EstimatorConfig(window=5, min_window=6)
    with pytest.raises(ConfigError, match="estimator.window_outlier_k"):
        EstimatorConfig(window_outlier_k=0.0)
