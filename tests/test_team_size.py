"""Large teams: the ArUco dictionary grows with the number of boards, up to a stated limit.

Robot k's board carries ids ``4k .. 4k+3`` (``markers.board_for_robot``); a team uses
the smallest 4x4 dictionary holding every id (``markers.team_dictionary``), so teams
of up to 12 boards keep DICT_4X4_50 and larger ones work end to end with both camera
backends. A team needing more ids than the largest dictionary holds is refused at
construction with an error naming ``n_ugvs``.
"""

from __future__ import annotations

import numpy as np
import pytest

from moma_env.camera import BoardView, CameraConfig, RenderedCamera
from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from moma_env.geometry import R_BODY_CAM_DOWN, make_transform, se2_to_se3
from moma_env.markers import (
    ARUCO_DICTIONARIES,
    MAX_TEAM_BOARDS,
    TEAM_DICTIONARIES,
    board_for_robot,
    team_dictionary,
)
from moma_env.scenarios import CONFIGURATIONS, CaterpillarMultiConfig, TopObserverConfig, missing_views
from moma_env.world import WorldConfig

#: A 13-robot team the observer sees whole at the start (checked below).
BIG_TEAM = {"n_ugvs": 13, "spacing": 0.5, "altitude": 2.5}


@pytest.mark.parametrize(
    ("n_boards", "dictionary"),
    [(0, "DICT_4X4_50"), (1, "DICT_4X4_50"), (12, "DICT_4X4_50"), (13, "DICT_4X4_100"), (25, "DICT_4X4_100"),
     (26, "DICT_4X4_250"), (62, "DICT_4X4_250"), (63, "DICT_4X4_1000"), (250, "DICT_4X4_1000")],
)
def test_team_dictionary_is_the_smallest_that_holds_every_id(n_boards, dictionary):
    assert team_dictionary(n_boards) == dictionary
    if n_boards:
        last = board_for_robot(n_boards - 1, dictionary=dictionary)
        assert max(last.marker_ids) == 4 * n_boards - 1 < ARUCO_DICTIONARIES[dictionary]


@pytest.mark.parametrize("bad", [MAX_TEAM_BOARDS + 1, -1, 2.0, True])
def test_team_dictionary_rejects_impossible_teams(bad):
    with pytest.raises(ValueError, match="n_boards|boards need"):
        team_dictionary(bad)


def test_team_dictionaries_are_known_and_read_only():
    assert MAX_TEAM_BOARDS == 250
    assert all(name in ARUCO_DICTIONARIES for name in TEAM_DICTIONARIES)
    with pytest.raises(TypeError):
        ARUCO_DICTIONARIES["DICT_4X4_50"] = 7  # type: ignore[index]


@pytest.mark.parametrize("name", sorted(CONFIGURATIONS))
def test_default_teams_keep_dict_4x4_50(name):
    world = CONFIGURATIONS[name]().scenario().world
    boards = [u.board for u in world.ugvs if u.board is not None] + [s.board for s in world.sleds]
    assert boards and {b.dictionary for b in boards} == {"DICT_4X4_50"}


@pytest.mark.parametrize(("n_ugvs", "dictionary"), [(12, "DICT_4X4_50"), (13, "DICT_4X4_100"), (26, "DICT_4X4_250")])
def test_top_observer_boards_share_the_team_dictionary(n_ugvs, dictionary):
    world = TopObserverConfig(n_ugvs=n_ugvs).scenario().world
    assert [u.board.marker_ids for u in world.ugvs] == [tuple(range(4 * k, 4 * k + 4)) for k in range(n_ugvs)]
    assert {u.board.dictionary for u in world.ugvs} == {dictionary}


def test_caterpillar_multi_boards_share_the_team_dictionary():
    world = CaterpillarMultiConfig(n_ugvs=14).scenario().world
    boards = [u.board for u in world.ugvs if u.board is not None]
    assert len(boards) == 13 and {b.dictionary for b in boards} == {"DICT_4X4_100"}
    assert boards[-1].marker_ids == (48, 49, 50, 51)


@pytest.mark.parametrize(
    ("name", "n_ugvs", "limit"),
    [("top_observer", MAX_TEAM_BOARDS + 1, MAX_TEAM_BOARDS), ("caterpillar_multi", MAX_TEAM_BOARDS + 2, MAX_TEAM_BOARDS + 1)],
)
def test_too_many_boards_is_refused_at_construction_naming_n_ugvs(name, n_ugvs, limit):
    with pytest.raises(ConfigError, match=rf"must be at most {limit}\b.*DICT_4X4_1000") as info:
        CONFIGURATIONS[name](n_ugvs=n_ugvs)
    assert info.value.field == f"{name}.n_ugvs"
    with pytest.raises(ConfigError, match=rf"{name}\.n_ugvs: must be at most {limit}\b"):
        parallel_env(name, n_ugvs=n_ugvs)


def test_the_largest_team_builds():
    world = TopObserverConfig(n_ugvs=MAX_TEAM_BOARDS).scenario().world
    assert world.ugvs[-1].board.marker_ids == (996, 997, 998, 999)
    assert isinstance(world, WorldConfig)


@pytest.mark.parametrize("backend", ["geometric", "rendered"])
def test_a_13_robot_team_resets_steps_and_detects_every_board(backend):
    config = TopObserverConfig(**BIG_TEAM)
    assert missing_views(config.scenario(), config.required_views()) == []
    env = parallel_env("top_observer", camera_backend=backend, max_cycles=20, **BIG_TEAM)
    env.reset(seed=0)
    assert env.agents[:13] == [f"ugv_{k}" for k in range(13)]
    for _ in range(3):
        env.step({agent: 0 for agent in env.agents})
    seen = {d.board_id: tuple(sorted(d.marker_ids)) for d in env.detections}
    # Board id k is robot k's board; the observer sees all 13 whole, ids 4k .. 4k+3.
    assert seen == {k: tuple(range(4 * k, 4 * k + 4)) for k in range(13)}
    assert all(env.board_device(k) == f"ugv_{k}" for k in seen)


@pytest.mark.parametrize("robot", [12, 61, 249])
def test_rendered_camera_detects_boards_of_every_team_dictionary(robot):
    layout = board_for_robot(robot, dictionary=team_dictionary(robot + 1))
    camera = RenderedCamera("uav", CameraConfig())
    T_w_c = make_transform(R_BODY_CAM_DOWN, [0.0, 0.0, 1.4])
    board = BoardView(robot, layout, se2_to_se3(0.05, -0.03, 0.4, 0.3))
    [detection] = camera.measure(T_w_c, [board], 0.0, np.random.default_rng(0))
    assert detection.board_id == robot
    assert sorted(detection.marker_ids) == list(range(4 * robot, 4 * robot + 4))
