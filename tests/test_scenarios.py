"""The four configurations: defaults, layouts, start views, validation and the registry."""

from __future__ import annotations

import copy
import dataclasses
import math
import pickle

import numpy as np
import pytest

from moma_env.camera import BoardView, GeometricCamera
from moma_env.config import ConfigError
from moma_env.geometry import R_BODY_BOARD_BACK, R_BODY_CAM_BACKWARD, R_BODY_CAM_FORWARD, invert
from moma_env.markers import board_for_robot
from moma_env.scenarios import (
    CONFIGURATIONS,
    CaterpillarConfig,
    CaterpillarMultiConfig,
    CaterpillarSledConfig,
    Scenario,
    TopObserverConfig,
    make_config,
    make_scenario,
    missing_views,
    start_boards,
    start_camera_poses,
)
from moma_env.world import BoxObstacle, World, board_on_top

NAMES = ("top_observer", "caterpillar", "caterpillar_sled", "caterpillar_multi")


def detections(scenario: Scenario, camera: str, owner: str, occlusion_ignore: tuple[str, ...] | None = None):
    """Zero-noise detections of ``owner``'s board by ``camera`` in the reset World.

    With ``occlusion_ignore`` the line of sight is checked against the world's
    bodies, ignoring the named ones.
    """
    world = World(scenario.world)
    layout = start_boards(scenario.world)[owner][0]
    view = BoardView(7, layout, world.board_transform(owner))
    occluded = None
    if occlusion_ignore is not None:

        def occluded(a: np.ndarray, b: np.ndarray) -> bool:
            return world.segment_blocked(a[:2], b[:2], ignore=occlusion_ignore)

    backend = GeometricCamera(camera, dataclasses.replace(scenario.camera, noise_px=0.0))
    found = backend.measure(world.camera_transform(camera), [view], 0.0, np.random.default_rng(0), occluded)
    return found, world


def assert_sees_whole_board(scenario: Scenario, camera: str, owner: str) -> None:
    found, world = detections(scenario, camera, owner)
    assert len(found) == 1
    layout = start_boards(scenario.world)[owner][0]
    assert found[0].marker_ids == layout.marker_ids
    T_c_m = invert(world.camera_transform(camera)) @ world.board_transform(owner)
    np.testing.assert_allclose(found[0].T_c_m, T_c_m, atol=1e-6)


# -- every configuration ------------------------------------------------------------------


def test_registry_holds_the_four_configurations():
    assert set(CONFIGURATIONS) == set(NAMES)
    assert CONFIGURATIONS["top_observer"] is TopObserverConfig
    assert CONFIGURATIONS["caterpillar"] is CaterpillarConfig
    assert CONFIGURATIONS["caterpillar_sled"] is CaterpillarSledConfig
    assert CONFIGURATIONS["caterpillar_multi"] is CaterpillarMultiConfig


@pytest.mark.parametrize("name", NAMES)
def test_defaults_build_a_valid_scenario(name):
    config = CONFIGURATIONS[name]()
    scenario = config.scenario()
    assert isinstance(scenario, Scenario)
    assert scenario.name == name
    assert scenario.camera == config.camera
    assert scenario.estimator == config.estimator
    assert scenario.max_cycles > 25 * 10  # more than the start budget
    assert set(scenario.goals) == set(scenario.world.ugv_names) == {f"ugv_{i}" for i in range(len(scenario.world.ugvs))}
    assert all(ugv.static for ugv in scenario.world.ugvs)
    # Building is deterministic and the World accepts it.
    again = config.scenario()
    assert again.world == scenario.world and dict(again.goals) == dict(scenario.goals)
    World(scenario.world)


@pytest.mark.parametrize("name", NAMES)
def test_defaults_see_the_required_boards(name):
    config = CONFIGURATIONS[name]()
    scenario = config.scenario()
    assert config.required_views()
    assert missing_views(scenario, config.required_views()) == []
    for camera, owners in config.required_views().items():
        for owner in owners:
            assert_sees_whole_board(scenario, camera, owner)


@pytest.mark.parametrize("name", NAMES)
def test_start_poses_match_the_reset_world(name):
    scenario = make_scenario(name)
    world = World(scenario.world)
    cameras = start_camera_poses(scenario.world)
    assert set(cameras) == set(world.camera_names)
    for camera, T_w_c in cameras.items():
        np.testing.assert_allclose(world.camera_transform(camera), T_w_c, atol=1e-12)
    for owner, (_, T_w_m) in start_boards(scenario.world).items():
        np.testing.assert_allclose(world.board_transform(owner), T_w_m, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_arena_fits_start_and_goals_with_margin(name):
    config = CONFIGURATIONS[name]()
    xmin, ymin, xmax, ymax = config.scenario().world.arena.bounds
    assert xmax - xmin >= 4.0 and ymax - ymin >= 4.0
    for _, x, y, radius in config.occupied_disks:
        assert xmin + radius + 1.0 - 1e-9 <= x <= xmax - radius - 1.0 + 1e-9
        assert ymin + radius + 1.0 - 1e-9 <= y <= ymax - radius - 1.0 + 1e-9


@pytest.mark.parametrize("name", NAMES)
def test_max_cycles_explicit_or_derived(name):
    cls = CONFIGURATIONS[name]
    assert cls(max_cycles=123).scenario().max_cycles == 123
    short = cls(goal_distance=1.0) if name != "top_observer" else cls(goal_offset=(1.0, 0.0, 0.0))
    long = cls(goal_distance=3.0) if name != "top_observer" else cls(goal_offset=(3.0, 0.0, 0.0))
    assert long.scenario().max_cycles > short.scenario().max_cycles


@pytest.mark.parametrize("name", NAMES)
def test_configs_compare_and_hash_by_value(name):
    cls = CONFIGURATIONS[name]
    a = cls(arena=[7, 6.5], obstacles=[{"x": 2.0, "y": 2.0, "width": 0.3, "height": 0.3}])
    b = cls(arena=(7.0, 6.5), obstacles=(BoxObstacle(2.0, 2.0, 0.3, 0.3),))
    assert a == b and hash(a) == hash(b)
    assert a != cls(arena=(7.0, 6.0))
    assert a.scenario().world.arena.obstacles == (BoxObstacle(2.0, 2.0, 0.3, 0.3),)


@pytest.mark.parametrize("name", NAMES)
def test_every_scenario_call_gives_a_new_scenario_equal_to_the_first(name):
    """The constructor's scenario is handed out once; later calls build their own (a caller
    may change its scenario's goals without changing another's)."""
    config = CONFIGURATIONS[name]()
    first, second, third = config.scenario(), config.scenario(), config.scenario()
    assert first is not second and second is not third and first.goals is not second.goals
    assert first == second == third
    first.goals.clear()
    assert config.scenario() == second and config.scenario().goals == second.goals != {}
    assert config.occupied_disks == config.layout.disks
    assert dataclasses.replace(config) == config and repr(config) == repr(dataclasses.replace(config))
    fresh = CONFIGURATIONS[name]()
    older = object.__new__(type(fresh))  # as unpickled from a version that kept neither
    older.__dict__.update({k: v for k, v in fresh.__getstate__().items() if k not in ("_layout", "_unclaimed")})
    assert older.layout == fresh.layout and older.scenario() == second and older.occupied_disks == fresh.occupied_disks
    for twin in (copy.copy(fresh), copy.deepcopy(fresh), pickle.loads(pickle.dumps(fresh))):
        assert twin == fresh and twin.layout == fresh.layout
        assert twin.scenario() is not fresh.scenario() and twin.scenario() == second


# -- top observer ----------------------------------------------------------------------------


def test_top_observer_defaults_follow_the_square_experiment():
    config = TopObserverConfig()
    scenario = config.scenario()
    ugv_0, ugv_1 = scenario.world.ugvs
    assert (ugv_0.name, ugv_1.name) == ("ugv_0", "ugv_1")
    assert ugv_0.board == board_for_robot(0) and ugv_1.board == board_for_robot(1)
    np.testing.assert_array_equal(ugv_0.board_mount, board_on_top())
    assert ugv_0.cameras == () and ugv_1.cameras == ()
    # Side by side 0.6 m apart, ugv_1 on ugv_0's left, centred on the start.
    np.testing.assert_allclose(ugv_0.initial_pose, (0.0, -0.3, 0.0), atol=1e-12)
    np.testing.assert_allclose(ugv_1.initial_pose, (0.0, 0.3, 0.0), atol=1e-12)
    assert scenario.goals["ugv_0"] == pytest.approx((2.0, -0.3, 0.0))
    assert scenario.goals["ugv_1"] == pytest.approx((2.0, 0.3, 0.0))
    uav = scenario.world.uav
    assert uav is not None and uav.kind == "quadcopter"
    assert uav.initial == (0.0, 0.0, 0.0) and uav.altitude == 1.6
    assert config.required_views() == {"uav/camera": ("ugv_0", "ugv_1")}


@pytest.mark.parametrize("formation", ["compact", "row"])
@pytest.mark.parametrize("n_ugvs", [2, 3, 4, 6])
def test_top_observer_formation_is_centred_and_spaced(formation, n_ugvs):
    config = TopObserverConfig(n_ugvs=n_ugvs, formation=formation, spacing=0.7, start=(1.0, -0.5, 0.4))
    ugvs = config.scenario().world.ugvs
    assert [u.name for u in ugvs] == [f"ugv_{i}" for i in range(n_ugvs)]
    assert [u.board.marker_ids for u in ugvs] == [board_for_robot(i).marker_ids for i in range(n_ugvs)]
    xy = np.array([u.initial_pose[:2] for u in ugvs])
    gaps = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(n_ugvs) * 1e9
    assert gaps.min() == pytest.approx(0.7)
    # Centred on the start: the bounding box (in the start's frame) has its centre there.
    c, s = math.cos(0.4), math.sin(0.4)
    local = (xy - (1.0, -0.5)) @ np.array([[c, -s], [s, c]])
    np.testing.assert_allclose(local.min(axis=0) + local.max(axis=0), 0.0, atol=1e-12)
    assert all(u.initial_pose[2] == pytest.approx(0.4) for u in ugvs)
    if formation == "row":
        np.testing.assert_allclose(local[:, 0], 0.0, atol=1e-12)
        assert np.all(np.diff(local[:, 1]) > 0)  # each robot left of the previous


@pytest.mark.parametrize("n_ugvs", [2, 3, 4])
@pytest.mark.parametrize("observer", ["quadcopter", "handheld"])
def test_top_observer_sees_every_board_at_the_start(n_ugvs, observer):
    config = TopObserverConfig(n_ugvs=n_ugvs, observer=observer)
    scenario = config.scenario()
    assert scenario.world.uav.kind == observer
    for i in range(n_ugvs):
        assert_sees_whole_board(scenario, "uav/camera", f"ugv_{i}")


def test_top_observer_goals_shift_every_start():
    config = TopObserverConfig(n_ugvs=3, start=(0.5, 0.5, 1.0), goal_offset=(-1.0, 1.5, 0.5))
    scenario = config.scenario()
    for ugv in scenario.world.ugvs:
        x, y, yaw = ugv.initial_pose
        assert scenario.goals[ugv.name] == pytest.approx((x - 1.0, y + 1.5, yaw + 0.5))


def test_top_observer_reports_a_row_too_wide_for_the_camera():
    config = TopObserverConfig(n_ugvs=5, formation="row", altitude=1.2)
    assert missing_views(config.scenario(), config.required_views())


# -- caterpillar -------------------------------------------------------------------------------


def test_caterpillar_layout():
    config = CaterpillarConfig(start=(1.0, 2.0, math.pi / 2))
    scenario = config.scenario()
    assert scenario.world.uav is None
    leader, follower = scenario.world.ugvs
    assert (leader.name, follower.name) == ("ugv_0", "ugv_1")
    assert leader.board == board_for_robot(0) and follower.board is None
    np.testing.assert_allclose(leader.board_mount[:3, :3], R_BODY_BOARD_BACK)
    assert leader.cameras == ()
    (camera,) = follower.cameras
    assert camera.name == "ugv_1/camera"
    np.testing.assert_allclose(camera.T_b_c[:3, :3], R_BODY_CAM_FORWARD)
    # In a file along the heading (+y here), 0.8 m apart centre to centre.
    np.testing.assert_allclose(leader.initial_pose, (1.0, 2.0, math.pi / 2), atol=1e-12)
    np.testing.assert_allclose(follower.initial_pose, (1.0, 1.2, math.pi / 2), atol=1e-12)
    assert scenario.goals["ugv_0"] == pytest.approx((1.0, 4.0, math.pi / 2))
    assert scenario.goals["ugv_1"] == pytest.approx((1.0, 3.2, math.pi / 2))
    assert config.required_views() == {"ugv_1/camera": ("ugv_0",)}


@pytest.mark.parametrize(("distance", "standoff"), [(0.8, 0.539), (1.2, 0.6), (0.6, 0.5)])
def test_caterpillar_camera_starts_at_the_standoff_facing_the_board(distance, standoff):
    scenario = CaterpillarConfig(distance=distance, standoff=standoff).scenario()
    world = World(scenario.world)
    T_c_m = invert(world.camera_transform("ugv_1/camera")) @ world.board_transform("ugv_0")
    np.testing.assert_allclose(T_c_m[:3, 3], (0.0, 0.0, standoff), atol=1e-12)  # straight ahead
    np.testing.assert_allclose(T_c_m[:3, 2], (0.0, 0.0, -1.0), atol=1e-12)  # face-on
    assert_sees_whole_board(scenario, "ugv_1/camera", "ugv_0")


# -- multi-robot caterpillar ----------------------------------------------------------------


@pytest.mark.parametrize("n_ugvs", [2, 3, 5])
def test_caterpillar_multi_layout(n_ugvs):
    config = CaterpillarMultiConfig(n_ugvs=n_ugvs)
    scenario = config.scenario()
    ugvs = scenario.world.ugvs
    assert [u.name for u in ugvs] == [f"ugv_{k}" for k in range(n_ugvs)]
    assert ugvs[0].cameras == ()
    for k, ugv in enumerate(ugvs):
        assert ugv.initial_pose == pytest.approx((-0.8 * k, 0.0, 0.0))
        assert scenario.goals[ugv.name] == pytest.approx((2.0 - 0.8 * k, 0.0, 0.0))
        if k < n_ugvs - 1:
            assert ugv.board == board_for_robot(k)
            np.testing.assert_allclose(ugv.board_mount[:3, :3], R_BODY_BOARD_BACK)
        else:
            assert ugv.board is None
        if k > 0:
            assert [c.name for c in ugv.cameras] == [f"ugv_{k}/camera"]
    assert config.required_views() == {f"ugv_{k}/camera": (f"ugv_{k - 1}",) for k in range(1, n_ugvs)}
    for camera, (owner,) in config.required_views().items():
        assert_sees_whole_board(scenario, camera, owner)


def test_caterpillar_multi_robot_ahead_hides_the_boards_beyond_it():
    scenario = CaterpillarMultiConfig(n_ugvs=3).scenario()
    seen, _ = detections(scenario, "ugv_2/camera", "ugv_1", occlusion_ignore=("ugv_2", "ugv_1"))
    hidden, _ = detections(scenario, "ugv_2/camera", "ugv_0", occlusion_ignore=("ugv_2", "ugv_0"))
    assert len(seen) == 1 and hidden == []


def test_caterpillar_is_a_two_robot_file():
    two = CaterpillarMultiConfig(n_ugvs=2).scenario()
    one = CaterpillarConfig().scenario()
    assert two.world == one.world and dict(two.goals) == dict(one.goals)


# -- sled ------------------------------------------------------------------------------------------


def test_caterpillar_sled_layout():
    config = CaterpillarSledConfig(start=(0.5, -0.5, math.pi), rope_length=0.8)
    scenario = config.scenario()
    assert scenario.world.uav is None
    (robot,) = scenario.world.ugvs
    assert robot.name == "ugv_0" and robot.board is None
    (camera,) = robot.cameras
    assert camera.name == "ugv_0/camera"
    np.testing.assert_allclose(camera.T_b_c[:3, :3], R_BODY_CAM_BACKWARD)
    (sled,) = scenario.world.sleds
    assert (sled.name, sled.robot) == ("sled", "ugv_0")
    assert sled.board == board_for_robot(1)
    assert sled.rope_length == 0.8
    # Straight behind the robot (heading -x), the rope just taut.
    assert sled.initial_pose[1] == pytest.approx(-0.5) and sled.initial_pose[0] > 0.5
    assert sled.anchor_distance(robot.initial_pose) == pytest.approx(0.8)
    assert World(scenario.world).rope_length("sled") == pytest.approx(0.8)
    assert set(scenario.goals) == {"ugv_0"}
    assert scenario.goals["ugv_0"] == pytest.approx((-1.5, -0.5, -math.pi))  # yaw wrapped to [-pi, pi)
    assert config.required_views() == {"ugv_0/camera": ("sled",)}


@pytest.mark.parametrize("rope_length", [0.35, 0.6, 1.5])
def test_caterpillar_sled_camera_sees_the_sled_board(rope_length):
    scenario = CaterpillarSledConfig(rope_length=rope_length).scenario()
    world = World(scenario.world)
    T_c_m = invert(world.camera_transform("ugv_0/camera")) @ world.board_transform("sled")
    assert T_c_m[2, 3] > 0.0 and abs(T_c_m[0, 3]) < 1e-12 and abs(T_c_m[1, 3]) < 1e-12
    np.testing.assert_allclose(T_c_m[:3, 2], (0.0, 0.0, -1.0), atol=1e-12)
    assert_sees_whole_board(scenario, "ugv_0/camera", "sled")


# -- validation --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "overrides", "field"),
    [
        ("top_observer", {"n_ugvs": 1}, "top_observer.n_ugvs"),
        ("top_observer", {"n_ugvs": 2.0}, "top_observer.n_ugvs"),
        ("top_observer", {"spacing": -0.6}, "top_observer.spacing"),
        ("top_observer", {"spacing": 0.4}, "top_observer.spacing"),
        ("top_observer", {"formation": "circle"}, "top_observer.formation"),
        ("top_observer", {"observer": "blimp"}, "top_observer.observer"),
        ("top_observer", {"altitude": 0.3}, "top_observer.altitude"),
        ("top_observer", {"goal_offset": (1.0, 2.0)}, "top_observer.goal_offset"),
        ("top_observer", {"start": (0.0, math.nan, 0.0)}, "top_observer.start.y"),
        ("caterpillar", {"distance": -0.8}, "caterpillar.distance"),
        ("caterpillar", {"distance": 0.4}, "caterpillar.distance"),
        ("caterpillar", {"standoff": 0.8}, "caterpillar.standoff"),
        ("caterpillar", {"standoff": 0.9}, "caterpillar.standoff"),
        ("caterpillar", {"standoff": 0.0}, "caterpillar.standoff"),
        ("caterpillar", {"goal_distance": 0.0}, "caterpillar.goal_distance"),
        ("caterpillar_multi", {"n_ugvs": 1}, "caterpillar_multi.n_ugvs"),
        ("caterpillar_multi", {"standoff": 1.0}, "caterpillar_multi.standoff"),
        ("caterpillar_sled", {"rope_length": 2.0}, "caterpillar_sled.rope_length"),
        ("caterpillar_sled", {"min_rope": -0.1}, "caterpillar_sled.min_rope"),
        ("caterpillar_sled", {"max_rope": 0.3}, "caterpillar_sled.max_rope"),
        ("caterpillar_sled", {"reel_speed": 0.0}, "caterpillar_sled.reel_speed"),
        ("caterpillar_sled", {"goal_distance": -1.0}, "caterpillar_sled.goal_distance"),
        ("caterpillar", {"arena": (2.0, 2.0)}, "caterpillar.arena"),
        ("caterpillar", {"arena": (-5.0, 5.0)}, "caterpillar.arena.width"),
        ("top_observer", {"arena": (6.0, 6.0), "arena_origin": (0.0, 0.0)}, "top_observer.arena"),
        ("top_observer", {"arena_origin": (0.0,)}, "top_observer.arena_origin"),
        ("caterpillar", {"leg_length": 0.0}, "caterpillar.leg_length"),
        ("caterpillar", {"dwell_s": -1.0}, "caterpillar.dwell_s"),
        ("caterpillar", {"goal_tolerance_m": 0.0}, "caterpillar.goal_tolerance_m"),
        ("caterpillar", {"max_cycles": 0}, "caterpillar.max_cycles"),
        ("caterpillar", {"camera": "pal"}, "caterpillar.camera"),
        ("caterpillar", {"estimator": None}, "caterpillar.estimator"),
        ("caterpillar", {"obstacles": BoxObstacle(3.0, 3.0, 0.2, 0.2)}, "caterpillar.obstacles"),
        ("caterpillar", {"obstacles": [(3.0, 3.0, 0.2, 0.2)]}, "caterpillar.obstacles[0]"),
        ("caterpillar", {"obstacles": [{"x": 3.0, "y": 3.0, "width": -1, "height": 1}]}, "caterpillar.obstacles[0]"),
        (
            "caterpillar",
            {"obstacles": [{"x": 3.0, "y": 3.0, "width": 1, "height": 1, "z": 0}]},
            "caterpillar.obstacles[0]",
        ),
        ("caterpillar", {"obstacles": [BoxObstacle(0.0, 0.3, 0.5, 0.2)]}, "caterpillar.obstacles[0]"),  # on a start
        ("caterpillar", {"obstacles": [BoxObstacle(1.2, 0.0, 0.2, 0.2)]}, "caterpillar.obstacles[0]"),  # on a goal
        ("caterpillar_sled", {"obstacles": [BoxObstacle(-0.97, 0.0, 0.2, 0.2)]}, "caterpillar_sled.obstacles[0]"),
    ],
)
def test_config_errors_name_the_field(name, overrides, field):
    with pytest.raises(ConfigError) as info:
        CONFIGURATIONS[name](**overrides)
    assert info.value.field == field


def test_obstacle_error_says_what_it_covers():
    with pytest.raises(ConfigError, match="covers the ugv_1 goal"):
        CaterpillarConfig(obstacles=(BoxObstacle(1.2, 0.0, 0.2, 0.2),))


def test_configs_are_keyword_only_and_frozen():
    with pytest.raises(TypeError):
        TopObserverConfig(3)  # type: ignore[misc]
    config = TopObserverConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.n_ugvs = 3  # type: ignore[misc]


# -- registry --------------------------------------------------------------------------------


def test_make_scenario_applies_overrides_and_nested_mappings():
    scenario = make_scenario("caterpillar_multi", n_ugvs=4, camera={"fx": 500.0, "noise_px": 0.0}, dwell_s=1.5)
    assert len(scenario.world.ugvs) == 4
    assert scenario.camera.fx == 500.0 and scenario.camera.noise_px == 0.0
    assert scenario.dwell_s == 1.5
    assert make_config("caterpillar_multi", n_ugvs=4) == CaterpillarMultiConfig(n_ugvs=4)


def test_make_scenario_rejects_an_unknown_name_listing_the_known_ones():
    with pytest.raises(ConfigError) as info:
        make_scenario("square")
    for name in NAMES:
        assert name in str(info.value)


def test_make_scenario_rejects_unknown_overrides_naming_them():
    with pytest.raises(ConfigError) as info:
        make_scenario("top_observer", n_robots=3, hight=2.0)
    assert info.value.field == "top_observer.hight"
    assert "'hight'" in str(info.value) and "'n_robots'" in str(info.value)
    with pytest.raises(ConfigError) as info:
        make_scenario("caterpillar", camera={"focal": 400.0})
    assert "focal" in str(info.value)


def test_make_scenario_reports_bad_values_by_field():
    with pytest.raises(ConfigError) as info:
        make_scenario("caterpillar", standoff=1.0)
    assert info.value.field == "caterpillar.standoff"
