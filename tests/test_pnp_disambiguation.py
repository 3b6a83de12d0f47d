"""Choosing between the two poses of the planar ambiguity: the upright prior, and the flip-rate command."""

from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pytest

from moma_env.camera import BoardView, CameraConfig, GeometricCamera, up_in_board
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_BOARD_BACK, invert, make_transform, rot_x, rot_y, rotvec_to_matrix
from moma_env.markers import board_for_robot
from training.cli import main
from training.experiments.flip_rate import FlipConfig, flip_rates, is_flipped, random_view

UP = np.array([0.0, 0.0, 1.0])


def mirrored(T_c_m: np.ndarray) -> np.ndarray:
    """The other pose of the ambiguity: the normal mirrored about the line of sight (same centre)."""
    n = T_c_m[:3, 2]
    v = T_c_m[:3, 3] / np.linalg.norm(T_c_m[:3, 3])
    m = 2.0 * (n @ v) * v - n
    axis = np.cross(n, m)
    angle = math.atan2(np.linalg.norm(axis), n @ m)
    R = rotvec_to_matrix(axis / np.linalg.norm(axis) * angle) @ T_c_m[:3, :3]
    return make_transform(R, T_c_m[:3, 3])


def ambiguous_corners(camera: GeometricCamera, T_c_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Board corners (n, 3) in M and pixels halfway between their images under ``T_c_m`` and its mirror:
    corners both poses explain equally well."""
    obj = board_for_robot(0).marker_corners.reshape(-1, 3)
    images = [camera.camera.project(obj @ T[:3, :3].T + T[:3, 3]) for T in (T_c_m, mirrored(T_c_m))]
    return obj, 0.5 * (images[0] + images[1])


@pytest.mark.parametrize("seed", range(6))
def test_upright_prior_picks_the_pose_whose_normal_matches_up(seed):
    """On corners halfway between the two poses, the prior alone decides: declare either
    pose's normal as up and that pose comes out."""
    cfg = CameraConfig(noise_px=0.5)
    camera = GeometricCamera("uav", cfg)
    T_c_m = random_view(cfg, math.radians(6.0), 3.0, np.random.default_rng(seed))
    obj, px = ambiguous_corners(camera, T_c_m)
    starts = np.array([0, len(px)])
    for T_up in (T_c_m, mirrored(T_c_m)):
        up_c = T_up[:3, 2]  # world up in C: this pose's normal (the board lies face-up)
        T, rms, cov = camera.solve_boards(obj, px, starts, UP[None, :], up_c)
        assert math.isfinite(rms[0]) and np.all(np.isfinite(cov[0]))
        assert is_flipped(T_c_m, T[0]) == (T_up is not T_c_m)


def test_min_cost_ignores_the_prior():
    cfg = CameraConfig(noise_px=0.5, pose_disambiguation="min_cost")
    camera = GeometricCamera("uav", cfg)
    T_c_m = random_view(cfg, math.radians(6.0), 3.0, np.random.default_rng(0))
    obj, px = ambiguous_corners(camera, T_c_m)
    starts = np.array([0, len(px)])
    results = [camera.solve_boards(obj, px, starts, UP[None, :], T[:3, 2])[0][0] for T in (T_c_m, mirrored(T_c_m))]
    np.testing.assert_array_equal(results[0], results[1])


def test_where_gravity_cannot_tell_the_poses_apart_the_lower_cost_decides():
    """A vertical board tilted about the vertical, seen by a level camera: both poses
    predict the same up direction, so the choice is the lower cost's."""
    layout = board_for_robot(0)
    up_m = up_in_board(make_transform(R_BODY_BOARD_BACK))
    rules = {rule: GeometricCamera("ugv", CameraConfig(noise_px=1.0, pose_disambiguation=rule)) for rule in ("upright", "min_cost")}
    sides = []
    for seed in range(100):
        # Camera level, looking along +x_W; the board's face turned 6 deg about the vertical from facing it.
        R_w_c = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        T_w_c = make_transform(R_w_c, (0.0, 0.0, 0.4))
        T_w_m = make_transform(
            rotvec_to_matrix([0.0, 0.0, math.radians(6.0)]) @ R_BODY_BOARD_BACK, (2.5, 0.0, 0.4)
        )
        T_c_m = invert(T_w_c) @ T_w_m
        board = BoardView(0, layout, T_w_m, up_m=up_m)
        flips = [
            is_flipped(T_c_m, cam.measure(T_w_c, [board], 0.0, np.random.default_rng(seed))[0].T_c_m) for cam in rules.values()
        ]
        sides.append(flips)
    upright, min_cost = np.array(sides).T
    assert 0 < min_cost.sum() < len(min_cost)  # the corners really were ambiguous
    # The prior does not take sides: as many flips as the lower cost gives, and mostly the same views.
    assert abs(int(upright.sum()) - int(min_cost.sum())) <= 0.1 * len(sides)
    assert np.mean(upright == min_cost) >= 0.8


def test_upright_flips_less_than_min_cost_on_a_seeded_sample():
    result = flip_rates(FlipConfig(views=60, seed=3, tilts_deg=(5.0,)), rules=("PLANAR_LM min_cost", "PLANAR_LM upright"))
    old = result["rules"]["PLANAR_LM min_cost"]["flip_rate"][0]
    new = result["rules"]["PLANAR_LM upright"]["flip_rate"][0]
    assert new < old


def test_flips_command_prints_json_with_every_rule_and_tilt():
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["experiment", "flips", "--views", "20", "--seed", "1", "--json"]) == 0
    data = json.loads(out.getvalue())
    assert data["views"] == 20 and data["seed"] == 1
    tilts = data["tilts_deg"]
    assert tilts == [5.0, 10.0, 20.0, 30.0]
    assert {"PLANAR_LM min_cost", "PLANAR_LM upright", "IPPE min_cost", "SQPNP min_cost"} <= set(data["rules"])
    for rule in data["rules"].values():
        assert len(rule["flip_rate"]) == len(rule["flips"]) == len(rule["lost"]) == len(tilts)
        assert all(0.0 <= r <= 1.0 for r in rule["flip_rate"])
        assert all(f == round(r * (data["views"] - m)) for f, r, m in zip(rule["flips"], rule["flip_rate"], rule["lost"]))


def test_flips_command_prints_a_table():
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["experiment", "flips", "--views", "5"]) == 0
    text = out.getvalue()
    assert "| PLANAR_LM upright |" in text and "| 5 deg |" in text


def test_flips_command_rejects_bad_arguments(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["experiment", "flips", "--views", "0"])
    assert exit_info.value.code == 2
    assert "view count" in capsys.readouterr().err


def test_flip_config_rejects_bad_values():
    with pytest.raises(ValueError, match="views"):
        FlipConfig(views=0)
    with pytest.raises(ValueError, match="tilts_deg"):
        FlipConfig(tilts_deg=(95.0,))
    with pytest.raises(ValueError, match="distance_m"):
        FlipConfig(distance_m=-1.0)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"pose_disambiguation": "gravity"}, "camera.pose_disambiguation"),
        ({"upright_prior_deg": 0.0}, "camera.upright_prior_deg"),
        ({"upright_prior_deg": float("nan")}, "camera.upright_prior_deg"),
        ({"attitude_noise_deg": -1.0}, "camera.attitude_noise_deg"),
        ({"pnp_sigma_source": "guess"}, "camera.pnp_sigma_source"),
        ({"pnp_sigma_floor_px": -0.1}, "camera.pnp_sigma_floor_px"),
    ],
)
def test_bad_pose_settings_name_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        CameraConfig(**kwargs)


def test_board_view_up_m_is_validated():
    layout = board_for_robot(0)
    with pytest.raises(ValueError, match="up_m"):
        BoardView(0, layout, np.eye(4), up_m=np.array([0.0, 0.0, 2.0]))
    with pytest.raises(ValueError, match="up_m"):
        BoardView(0, layout, np.eye(4), up_m=np.array([0.0, 1.0]))
    view = BoardView(0, layout, np.eye(4), up_m=up_in_board(make_transform(rot_x(0.1)[:3, :3] @ rot_y(0.2)[:3, :3])))
    assert not view.up_m.flags.writeable


def test_attitude_noise_draws_three_numbers_after_the_corner_noise():
    T_c_m = random_view(CameraConfig(), 0.3, 2.0, np.random.default_rng(0))
    board = BoardView(0, board_for_robot(0), np.eye(4), up_m=UP)
    states = []
    for attitude in (0.0, 2.0):
        rng = np.random.default_rng(5)
        GeometricCamera("uav", CameraConfig(attitude_noise_deg=attitude)).measure(invert(T_c_m), [board], 0.0, rng)
        states.append(rng)
    states[0].standard_normal(3)
    assert states[0].bit_generator.state == states[1].bit_generator.state


def test_env_board_normal_errors_are_measured_from_the_env_public_frame():
    from training.experiments.board_normals import format_normal_table, normal_errors

    result = normal_errors("caterpillar", episodes=1, seed=0)
    assert result["detections"] > 100
    assert 0.0 <= result["median_deg"] <= result["p99_deg"] <= result["max_deg"] < 90.0
    assert 0.0 <= result["over_5_deg"] <= 1.0
    table = format_normal_table([result])
    assert "| caterpillar |" in table and "1 random layouts" in table
    with pytest.raises(ValueError, match="episodes"):
        normal_errors("caterpillar", episodes=0)


def test_env_exposes_the_latest_detections_and_board_devices():
    from moma_env.top_observer_v0 import parallel_env

    env = parallel_env()
    env.reset(seed=0)
    core = env.unwrapped
    assert core.detections and all(core.board_device(d.board_id).startswith("ugv_") for d in core.detections)
    with pytest.raises(KeyError, match="unknown board id 99"):
        core.board_device(99)
