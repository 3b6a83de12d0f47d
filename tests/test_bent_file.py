"""The bent file: a caterpillar_multi jog around a wall, and routes in the switching executive."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env.config import ConfigError
from moma_env.control.route import Route
from moma_env.env.factory import parallel_env
from moma_env.planning.paths import box_distances
from moma_env.scenarios import Scenario
from moma_env.scenarios.caterpillar_multi import MAX_BEND_M, MIN_BEND_M, CaterpillarMultiConfig
from moma_env.scenarios.trail import JOG_ANGLE_RAD, JOG_START_M, jog_length, trail_pose
from moma_env.world import WorldConfig


def _trail_length(points):
    return sum(math.dist(a[:2], b[:2]) for a, b in zip(points, points[1:]))


@pytest.mark.parametrize("bend", [1.0, -0.7])
@pytest.mark.parametrize("heading", [0.0, 2.0])
def test_every_robot_follows_the_trail_for_goal_distance(bend, heading):
    config = CaterpillarMultiConfig(n_ugvs=4, bend=bend, goal_distance=3.5, start=(0.3, -0.2, heading))
    scenario = config.scenario()
    radius = scenario.world.ugvs[0].radius
    for ugv in scenario.world.ugvs:
        route = scenario.routes.get(ugv.name, ())
        way = [ugv.initial_pose, *route, scenario.goals[ugv.name]]
        assert _trail_length(way) == pytest.approx(config.goal_distance, abs=1e-9)
        # the heading of each via pose is the heading of the segment that arrives there
        for a, b in zip(way, way[1:]):
            if math.dist(a[:2], b[:2]) > 1e-9 and b is not way[-1]:
                assert math.atan2(b[1] - a[1], b[0] - a[0]) == pytest.approx(b[2], abs=1e-9)
    # the leader passes both corners; the wall blocks the straight way but no robot's way
    leader = scenario.routes["ugv_0"]
    assert len(leader) == 2
    assert leader[1][2] == pytest.approx(heading + math.copysign(JOG_ANGLE_RAD, bend))
    (wall,) = scenario.world.arena.obstacles
    straight = np.array([(math.cos(heading) * d + 0.3, math.sin(heading) * d - 0.2) for d in np.linspace(0, 3.5, 200)])
    assert box_distances(straight, wall).min() < radius
    for ugv in scenario.world.ugvs:
        way = [ugv.initial_pose, *scenario.routes.get(ugv.name, ()), scenario.goals[ugv.name]]
        samples = np.concatenate([np.linspace(a[:2], b[:2], 50) for a, b in zip(way, way[1:])])
        assert box_distances(samples, wall).min() > radius


def test_trail_pose_is_continuous_and_turns_at_the_corners():
    start = (0.0, 0.0, 0.0)
    s1, s2 = JOG_START_M, JOG_START_M + jog_length(1.0)
    assert trail_pose(start, 1.0, s1) == pytest.approx((s1, 0.0, 0.0))
    end_of_jog = trail_pose(start, 1.0, s2)
    assert end_of_jog[1] == pytest.approx(1.0)
    assert trail_pose(start, 1.0, s2 + 1.0) == pytest.approx((end_of_jog[0] + 1.0, 1.0, 0.0))
    assert trail_pose(start, 1.0, -0.8) == pytest.approx((-0.8, 0.0, 0.0))


def test_a_straight_file_has_no_route_and_no_wall():
    scenario = CaterpillarMultiConfig(n_ugvs=4).scenario()
    assert scenario.routes == {}
    assert scenario.world.arena.obstacles == ()


@pytest.mark.parametrize("bend", [0.2, -0.3, MAX_BEND_M + 0.1, math.nan])
def test_bad_bend_is_named(bend):
    with pytest.raises(ConfigError, match=r"caterpillar_multi\.bend"):
        CaterpillarMultiConfig(n_ugvs=3, bend=bend, goal_distance=5.0)


def test_a_goal_short_of_the_jog_is_named():
    with pytest.raises(ConfigError, match=r"caterpillar_multi\.goal_distance.*past the jog"):
        CaterpillarMultiConfig(n_ugvs=3, bend=1.0, goal_distance=2.0)


def test_random_layouts_keep_the_bend_and_straight_draws_are_unchanged():
    for seed in range(3):
        bent = CaterpillarMultiConfig.random(np.random.default_rng(seed), n_ugvs=4, bend=MIN_BEND_M)
        assert bent.bend == MIN_BEND_M and bent.n_ugvs == 4
        assert bent.goal_distance > JOG_START_M + jog_length(MIN_BEND_M)
        assert bent.scenario().routes
        straight = CaterpillarMultiConfig.random(np.random.default_rng(seed), n_ugvs=3)
        assert straight == CaterpillarMultiConfig.random(np.random.default_rng(seed), n_ugvs=3, bend=0.0)
        assert straight.bend == 0.0
    with pytest.raises(ConfigError, match=r"caterpillar_multi\.bend"):
        CaterpillarMultiConfig.random(np.random.default_rng(0), bend=0.1)


def test_a_route_is_measured_by_arc_length():
    route = Route((0.0, 0.0), ((1.0, 0.0, 0.0), (1.0, 2.0, 1.5), (3.0, 2.0, 0.0)))
    assert route.length == pytest.approx(5.0)
    assert route.pose_at(0.5) == pytest.approx((0.5, 0.0, 0.0))
    assert route.pose_at(1.5) == pytest.approx((1.0, 0.5, 1.5))  # past the corner, with the next segment's heading
    assert route.pose_at(7.0) == (3.0, 2.0, 0.0)
    assert route.project(0.9, 1.0) == pytest.approx(2.0)
    assert route.project(0.2, 0.1) == pytest.approx(0.2)
    assert route.project(0.2, 0.1, not_before=1.2) == pytest.approx(1.2)  # never behind the progress made
    with pytest.raises(ValueError, match="goal"):
        Route((0.0, 0.0), ())


def test_scenario_routes_are_checked():
    world = CaterpillarMultiConfig(n_ugvs=2).scenario().world
    assert isinstance(world, WorldConfig)
    goals = {"ugv_0": (1.0, 0.0, 0.0)}
    with pytest.raises(ConfigError, match=r"scenario\.routes\['ugv_9'\]"):
        Scenario("x", world, goals=goals, routes={"ugv_9": ((0.5, 0.0, 0.0),)})
    with pytest.raises(ConfigError, match=r"scenario\.routes\['ugv_0'\]\[0\]"):
        Scenario("x", world, goals=goals, routes={"ugv_0": ((0.5, 0.0),)})
    with pytest.raises(ConfigError, match=r"scenario\.routes\['ugv_0'\]\[1\]"):
        Scenario("x", world, goals=goals, routes={"ugv_0": ((0.5, 0.0, 0.0), (math.inf, 0.0, 0.0))})


def test_advance_drives_to_the_corners_first_with_the_segment_heading():
    env = parallel_env("caterpillar_multi", n_ugvs=2, bend=1.0, goal_distance=3.0, action_mode="switching")
    env.reset(seed=0)
    simulation = env.simulation
    ends = []
    for _ in range(400):
        _, _, terminations, truncations, infos = env.step({"ugv_0": 1, "ugv_1": 0})
        if "leg_done:ugv_0" in infos["ugv_0"]["events"]:
            ends.append(simulation.device_pose("ugv_0"))
            if len(ends) == 2:
                break
        assert not any(terminations.values()) and not any(truncations.values())
    assert len(ends) == 2
    tolerance = 0.03  # the executive's position tolerance plus the estimate's error
    assert ends[0][:2] == pytest.approx((JOG_START_M, 0.0), abs=tolerance)  # the first corner, not 0.5 m towards the goal
    assert ends[0][2] == pytest.approx(0.0, abs=0.05)
    # the next leg: leg_length further along the trail, on the diagonal (the first leg's end
    # is within the tolerance of the corner, so the second's within twice of its place)
    expected = trail_pose((0.0, 0.0, 0.0), 1.0, JOG_START_M + simulation.scenario.leg_length)
    assert ends[1][:2] == pytest.approx(expected[:2], abs=2 * tolerance)
    # turned to the diagonal's heading, within the executive's yaw tolerance (0.04 rad) and the estimate's error
    assert ends[1][2] == pytest.approx(JOG_ANGLE_RAD, abs=0.07)
