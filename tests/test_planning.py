"""MOMA navigation planner: plans for every configuration, and the rule checker catching violations."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.planning import Plan, PlanningError, Turn, coverage_radius, plan, shortest_path, validate
from moma_env.planning.paths import box_distances, polyline_length
from moma_env.planning.validate import CLEARANCE_M, PRACTICAL_MAX_RANGE_M, enclosing_circle, sample_polyline
from moma_env.scenarios import CONFIGURATIONS, CaterpillarConfig, TopObserverConfig, make_scenario
from moma_env.world import ArenaConfig, BoxObstacle

NAMES = sorted(CONFIGURATIONS)
SEEDS = range(10)


def _goals_reached(scenario, result: Plan) -> bool:
    final = result.final_poses
    for name, goal in scenario.goals.items():
        x, y, yaw = final[name]
        if math.hypot(x - goal[0], y - goal[1]) > scenario.goal_tolerance_m:
            return False
        if abs(math.remainder(yaw - goal[2], 2.0 * math.pi)) > scenario.goal_tolerance_rad:
            return False
    return True


def _check_turns_follow_rules(scenario, result: Plan) -> None:
    """Structural rules checked independently of validate(): one mover, continuity, leg bound."""
    poses = dict(result.start)
    for turn in result.turns:
        assert turn.device in poses
        assert np.allclose(turn.waypoints[0], poses[turn.device])
        assert turn.length <= scenario.leg_length + 1e-9
        poses[turn.device] = turn.goal


# -- plans ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_default_scenario_has_a_valid_plan(name):
    scenario = make_scenario(name)
    result = plan(scenario)
    assert result.scenario_name == name
    assert validate(scenario, result) == []
    assert _goals_reached(scenario, result)
    _check_turns_follow_rules(scenario, result)
    moved = {turn.device for turn in result.turns}
    assert set(scenario.goals) <= moved


@pytest.mark.parametrize("name", NAMES)
def test_random_scenarios_plans_are_valid_and_found(name):
    found = 0
    for seed in SEEDS:
        scenario = CONFIGURATIONS[name].random(np.random.default_rng(seed)).scenario()
        try:
            result = plan(scenario)
        except PlanningError:
            continue
        assert validate(scenario, result) == [], f"seed {seed}"
        assert _goals_reached(scenario, result), f"seed {seed}"
        _check_turns_follow_rules(scenario, result)
        found += 1
    assert found >= 9, f"{name}: only {found}/10 plans found"


def test_plan_is_deterministic():
    scenario = TopObserverConfig.random(np.random.default_rng(3)).scenario()
    assert plan(scenario) == plan(scenario)


def test_caterpillar_leader_never_outruns_its_follower():
    scenario = make_scenario("caterpillar", goal_distance=3.0)
    result = plan(scenario)
    for k in range(len(result.turns)):
        poses = result.poses_after(k)
        gap = math.dist(poses["ugv_0"][:2], poses["ugv_1"][:2])
        assert 0.8 - 1e-9 <= gap <= 0.8 + PRACTICAL_MAX_RANGE_M - 0.539 + 1e-9


def test_sled_turns_alternate_and_reel_the_sled_in():
    scenario = make_scenario("caterpillar_sled")
    result = plan(scenario)
    devices = [turn.device for turn in result.turns]
    assert devices == ["ugv_0", "sled"] * (len(devices) // 2)
    sled = scenario.world.sleds[0]
    final = result.final_poses
    assert sled.anchor_distance(final["ugv_0"], final["sled"]) == pytest.approx(sled.rope_length)


def test_obstacle_between_start_and_goal_is_driven_around():
    box = BoxObstacle(x=1.5, y=0.0, width=0.4, height=0.4)
    scenario = TopObserverConfig(formation="row", goal_offset=(3.0, 0.0, 0.5), obstacles=(box,)).scenario()
    result = plan(scenario)
    assert validate(scenario, result) == []
    for name in scenario.goals:
        assert result.path_length[name] > 3.0 + 1e-3
        samples = np.concatenate([sample_polyline(t.waypoints, 0.01) for t in result.turns if t.device == name])
        assert box_distances(samples[:, :2], box).min() >= scenario.world.ugv(name).radius + CLEARANCE_M


def test_caterpillar_blocked_file_raises_or_plans_validly():
    scenario = CaterpillarConfig(goal_distance=3.0, obstacles=(BoxObstacle(1.5, 0.0, 0.4, 0.4),)).scenario()
    try:
        result = plan(scenario)
    except PlanningError as error:
        assert "caterpillar" in str(error)
    else:
        assert validate(scenario, result) == []


def test_unsupported_configuration_raises():
    scenario = dataclasses.replace(make_scenario("caterpillar"), name="custom")
    with pytest.raises(PlanningError, match="not supported yet"):
        plan(scenario)


def test_too_few_turns_raise():
    with pytest.raises(PlanningError, match="max_turns"):
        plan(make_scenario("caterpillar"), max_turns=3)


def test_bad_arguments_raise():
    with pytest.raises(TypeError):
        plan("caterpillar")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_turns"):
        plan(make_scenario("caterpillar"), max_turns=0)
    with pytest.raises(ValueError, match="at least 2"):
        Turn("ugv_0", ((0.0, 0.0, 0.0),))
    with pytest.raises(ValueError, match="finite"):
        Turn("ugv_0", ((0.0, 0.0, 0.0), (math.nan, 0.0, 0.0)))


def test_poses_after_tracks_the_movers():
    scenario = make_scenario("caterpillar")
    result = plan(scenario)
    assert result.poses_after(-1) == dict(result.start)
    after0 = result.poses_after(0)
    assert after0[result.turns[0].device] == result.turns[0].goal
    others = set(after0) - {result.turns[0].device}
    assert all(after0[n] == result.start[n] for n in others)
    with pytest.raises(IndexError):
        result.poses_after(len(result.turns))


# -- planted violations -----------------------------------------------------------------


def _straight_turns(device, start, goal, leg):
    """Turns of ``device`` from ``start`` to ``goal`` in straight legs of at most ``leg`` m."""
    n = max(1, math.ceil(math.dist(start[:2], goal[:2]) / leg - 1e-9))
    points = [tuple(float(a + (b - a) * k / n) for a, b in zip(start, goal)) for k in range(n + 1)]
    return [Turn(device, (p, q)) for p, q in zip(points, points[1:])]


def test_two_movers_in_one_turn_are_caught():
    scenario = make_scenario("caterpillar")
    good = plan(scenario)
    turns = list(good.turns)
    # ugv_1's second turn starts 0.1 m ahead of where its first turn left it:
    # it crept forward during ugv_0's turn.
    k = [i for i, t in enumerate(turns) if t.device == "ugv_1"][1]
    x, y, yaw = turns[k].waypoints[0]
    turns[k] = Turn("ugv_1", ((x + 0.1, y, yaw),) + turns[k].waypoints[1:])
    violations = validate(scenario, dataclasses.replace(good, turns=tuple(turns)))
    assert any(v.startswith(f"turn {k} (ugv_1): move in turns") for v in violations), violations
    unknown = dataclasses.replace(good, turns=(Turn("ugv_0+ugv_1", ((0.0, 0.0, 0.0), (0.1, 0.0, 0.0))),))
    assert any("move in turns: unknown device" in v for v in validate(scenario, unknown))


def test_leg_through_an_obstacle_is_caught():
    box = BoxObstacle(x=1.5, y=0.0, width=0.4, height=0.4)
    scenario = TopObserverConfig(formation="row", goal_offset=(3.0, 0.0, 0.0), obstacles=(box,)).scenario()
    start = {u.name: u.initial_pose for u in scenario.world.ugvs}
    turns = []
    for name in ("ugv_0", "ugv_1"):
        turns += _straight_turns(name, start[name], scenario.goals[name], scenario.leg_length)
    straight = Plan("top_observer", start, tuple(turns))
    violations = validate(scenario, straight)
    assert violations
    assert all("collision" in v and "obstacle[0]" in v for v in violations), violations
    assert {v.split(":")[0] for v in violations} >= {"turn 2 (ugv_0)", "turn 8 (ugv_1)"}


def test_leg_too_long_is_caught():
    scenario = make_scenario("top_observer")
    start = {u.name: u.initial_pose for u in scenario.world.ugvs}
    turns = [Turn(n, (start[n], scenario.goals[n])) for n in ("ugv_0", "ugv_1")]
    violations = validate(scenario, Plan("top_observer", start, tuple(turns)))
    assert violations == [
        f"turn {k} ({n}): leg length 2.000 m exceeds leg_length 0.5 m" for k, n in enumerate(("ugv_0", "ugv_1"))
    ]


def test_leader_running_away_breaks_observability():
    scenario = make_scenario("caterpillar")
    start = {u.name: u.initial_pose for u in scenario.world.ugvs}
    turns = _straight_turns("ugv_0", start["ugv_0"], scenario.goals["ugv_0"], scenario.leg_length)
    violations = validate(scenario, Plan("caterpillar", start, tuple(turns)))
    # range = standoff 0.539 + advance: beyond 2.0 m only in the third leg (1.0 -> 1.5 m)
    observability = [v for v in violations if "observability" in v]
    assert len(observability) == 2 and observability[0].startswith("turn 2 (ugv_0)"), violations
    assert "range" in observability[0]


def test_sideways_leader_breaks_the_bearing():
    scenario = make_scenario("caterpillar")
    start = {u.name: u.initial_pose for u in scenario.world.ugvs}
    turn = Turn("ugv_0", (start["ugv_0"], (0.0, 0.5, 0.0)))
    violations = validate(scenario, Plan("caterpillar", start, (turn,)))
    assert any("observability" in v and "horizontal bearing" in v for v in violations), violations


def test_team_spread_beyond_the_coverage_is_caught():
    scenario = TopObserverConfig(formation="row", arena=(12.0, 12.0)).scenario()
    reach = coverage_radius(scenario)
    start = {u.name: u.initial_pose for u in scenario.world.ugvs}
    x, y, yaw = start["ugv_1"]
    far = (x, y + 2.0 * reach, yaw)  # ugv_1 runs off to the left, ugv_0 stays
    turns = _straight_turns("ugv_1", start["ugv_1"], far, scenario.leg_length)
    violations = validate(scenario, Plan("top_observer", start, tuple(turns)))
    assert any("observability" in v and "coverage" in v for v in violations), violations
    first_bad = min(int(v.split()[1]) for v in violations if "coverage" in v)
    # every turn before the first bad one keeps the spread coverable
    spread_ok = 0.5 * (0.6 + first_bad * scenario.leg_length) + 0.5 * math.hypot(0.34, 0.34)
    assert spread_ok <= reach + 1e-9


def test_sled_rope_leash_is_caught():
    scenario = make_scenario("caterpillar_sled")
    start = {"ugv_0": scenario.world.ugvs[0].initial_pose, "sled": scenario.world.sleds[0].initial_pose}
    turns = _straight_turns("ugv_0", start["ugv_0"], scenario.goals["ugv_0"], scenario.leg_length)
    violations = validate(scenario, Plan("caterpillar_sled", start, tuple(turns)))
    assert any("rope of sled" in v for v in violations), violations


def test_plan_stopping_short_is_caught():
    scenario = make_scenario("caterpillar_multi")
    good = plan(scenario)
    short = dataclasses.replace(good, turns=good.turns[:-1])
    last = good.turns[-1].device
    violations = validate(scenario, short)
    assert len(violations) == 1 and violations[0].startswith(f"goal: {last} ends"), violations


def test_wrong_start_is_caught():
    scenario = make_scenario("caterpillar")
    good = plan(scenario)
    moved = dict(good.start, ugv_1=(-1.0, 0.0, 0.0))
    violations = validate(scenario, dataclasses.replace(good, start=moved))
    assert any("start pose of ugv_1" in v for v in violations)


# -- helpers ----------------------------------------------------------------------------

coordinate = st.floats(-5.0, 5.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(coordinate, coordinate), min_size=1, max_size=6))
def test_enclosing_circle_is_tight(points):
    pts = np.array(points)
    cx, cy, r = enclosing_circle(pts)
    assert np.all(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy) <= r + 1e-6)
    diameter = max(math.dist(a, b) for a in points for b in points)
    assert diameter / 2.0 - 1e-9 <= r <= diameter / math.sqrt(3.0) + 1e-6  # Jung's theorem


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(coordinate, coordinate, st.floats(-4.0, 4.0)), min_size=2, max_size=5),
       st.floats(0.01, 0.5))
def test_samples_cover_the_polyline(waypoints, step):
    samples = sample_polyline(waypoints, step)
    assert np.allclose(samples[0], waypoints[0])
    assert np.allclose(samples[-1, :2], waypoints[-1][:2])
    assert math.remainder(samples[-1, 2] - waypoints[-1][2], 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    gaps = np.hypot(*np.diff(samples[:, :2], axis=0).T)
    assert gaps.max() <= step + 1e-9
    assert gaps.sum() == pytest.approx(polyline_length([w[:2] for w in waypoints]))


@settings(max_examples=30, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(0.2, 1.0), st.floats(0.2, 1.0), st.floats(-math.pi, math.pi))
def test_shortest_path_clears_a_box_in_the_way(y, width, height, yaw):
    box = BoxObstacle(0.0, y, width, height, yaw)
    arena = ArenaConfig(width=8.0, height=8.0, origin=(-4.0, -4.0), obstacles=(box,))
    clearance = 0.3
    path = shortest_path((-3.0, 0.0), (3.0, 0.0), clearance, arena)
    assert path[0] == (-3.0, 0.0) and path[-1] == (3.0, 0.0)
    dense = sample_polyline([(*p, 0.0) for p in path], 0.005)[:, :2]
    assert box_distances(dense, arena.obstacles[0]).min() >= clearance - 1e-9
    assert polyline_length(path) >= 6.0 - 1e-9


@pytest.mark.parametrize("n_ugvs, max_altitude", [(2, None), (4, None), (3, 2.6)])
def test_top_observer_switch_points_keep_the_team_away_from_the_image_border(n_ugvs, max_altitude):
    import dataclasses

    from moma_env.planning.planner import PREFERRED_COVERAGE_FRACTION, team_spread
    from moma_env.planning.validate import RuleChecker, coverage_radius
    from moma_env.scenarios import TopObserverConfig

    scenario = TopObserverConfig(n_ugvs=n_ugvs, goal_offset=(3.0, 0.0, 0.0)).scenario()
    if max_altitude is not None:
        # A lower ceiling: without the preference, 3 robots' legs would reach 75 % of the coverage.
        uav = dataclasses.replace(scenario.world.uav, max_altitude=max_altitude)
        scenario = dataclasses.replace(scenario, world=dataclasses.replace(scenario.world, uavs=(uav,)))
    result = plan(scenario)
    assert validate(scenario, result) == []
    checker = RuleChecker(scenario)
    limit = PREFERRED_COVERAGE_FRACTION * coverage_radius(scenario)
    assert team_spread(checker, result.poses_after(-1)) <= limit  # the start meets the preference
    for k in range(len(result.turns)):
        assert team_spread(checker, result.poses_after(k)) <= limit + 1e-9, k
