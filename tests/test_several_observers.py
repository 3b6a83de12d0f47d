"""Several observers watching one team: the world, the scenario, the env, the estimator, the experiments."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from moma_env.camera import CameraConfig
from moma_env.config import ConfigError
from moma_env.env.agent_names import is_observer_agent, observer_agent_names
from moma_env.env.factory import parallel_env
from moma_env.estimator import Status
from moma_env.scenarios.top_observer import TopObserverConfig
from moma_env.world import UAVConfig, World, WorldConfig, world_config_from_mapping
from training.cli import build_parser
from training.experiments.compare import observer_sets
from training.experiments.leapfrog_run import run_leapfrog
from training.experiments.square import SquareConfig

TWO = ("quadcopter", "handheld")


def two_uav_world() -> World:
    return World(WorldConfig(uavs=(UAVConfig(name="a", camera_name="a/cam"), UAVConfig(name="b", camera_name="b/cam", initial=(1.0, 0.0, 0.0)))))


def test_world_flies_each_uav_by_its_own_command():
    world = two_uav_world()
    for _ in range(25):
        world.step(uav_command={"a": (0.5, 0.0, 0.0, 0.0)})
    a, b = world.uav_states
    assert a.x > 0.2 and a.vx > 0.3
    assert (b.x, b.y, b.vx) == (1.0, 0.0, 0.0)  # left out: hovers
    assert world.uav_names == ("a", "b")
    assert world.camera_names == ("a/cam", "b/cam")
    assert world.camera_transform("b/cam")[0, 3] == pytest.approx(world.uav_transform("b")[0, 3] + UAVConfig().camera_mount[0, 3])
    assert world.state_array().shape == (2 * len(a.as_array()),)


def test_world_of_several_uavs_refuses_one_command_and_names_the_uavs():
    world = two_uav_world()
    with pytest.raises(ValueError, match="2 UAVs .*a, b"):
        world.step(uav_command=(0.1, 0.0, 0.0, 0.0))
    with pytest.raises(KeyError, match="c"):
        world.step(uav_command={"c": (0.1, 0.0, 0.0, 0.0)})
    with pytest.raises(ValueError, match="name one"):
        world.uav_state
    with pytest.raises(ValueError, match="uavs"):
        world.config.uav


def test_a_copy_of_a_two_uav_world_continues_bit_for_bit():
    world = two_uav_world()
    rng = np.random.default_rng(3)
    for _ in range(10):
        world.step(uav_command={"a": rng.uniform(-1, 1, 4), "b": rng.uniform(-1, 1, 4)})
    twin = copy.deepcopy(world)
    for _ in range(10):
        command = {"a": rng.uniform(-1, 1, 4), "b": rng.uniform(-1, 1, 4)}
        world.step(uav_command=command)
        twin.step(uav_command=command)
    assert world.state_array().tobytes() == twin.state_array().tobytes()


def test_world_config_names_a_duplicate_uav_and_reads_uav_lists():
    with pytest.raises(ConfigError) as excinfo:
        WorldConfig(uavs=(UAVConfig(), UAVConfig(camera_name="other")))
    assert excinfo.value.field == "uavs[1].name"
    with pytest.raises(ConfigError) as excinfo:
        WorldConfig(uavs=(UAVConfig(), UAVConfig(name="b")))
    assert excinfo.value.field == "uavs[1].camera_name"
    config = world_config_from_mapping({"uavs": [{"name": "a", "camera_name": "a/c"}, {"name": "b", "camera_name": "b/c", "kind": "handheld"}]})
    assert config.uav_names == ("a", "b") and config.uavs[1].response_time == UAVConfig.handheld().response_time
    with pytest.raises(ConfigError) as excinfo:
        world_config_from_mapping({"uav": {}, "uavs": []})
    assert excinfo.value.field == "uav"


def test_top_observer_places_one_observer_per_kind_side_by_side():
    config = TopObserverConfig(observer=TWO, observer_spacing=0.8, start=(0.0, 0.0, 0.0))
    uavs = config.scenario().world.uavs
    assert [u.name for u in uavs] == ["uav_0", "uav_1"] and [u.kind for u in uavs] == list(TWO)
    assert [u.initial[1] for u in uavs] == pytest.approx([-0.4, 0.4])
    assert set(config.required_views()) == {"uav_0/camera", "uav_1/camera"}
    single = TopObserverConfig(observer=("handheld",))
    assert single.observer == "handheld" and single.scenario().world.uav.name == "uav"


@pytest.mark.parametrize(
    "fields, field",
    [
        ({"observer": ("quadcopter", "blimp")}, "top_observer.observer[1]"),
        ({"observer": ("quadcopter",) * 5}, "top_observer.observer"),
        ({"observer": (), }, "top_observer.observer"),
        ({"observer": TWO, "observer_spacing": 0.0}, "top_observer.observer_spacing"),
    ],
)
def test_top_observer_names_a_bad_observer_field(fields, field):
    with pytest.raises(ConfigError) as excinfo:
        TopObserverConfig(**fields)
    assert excinfo.value.field == field


def test_random_layouts_refuse_several_observers():
    with pytest.raises(ConfigError) as excinfo:
        parallel_env("top_observer", observer=TWO, random_scenarios=True)
    assert excinfo.value.field == "top_observer.observer"


def test_agent_names():
    assert observer_agent_names(1) == ("observer",)
    assert observer_agent_names(3) == ("observer_0", "observer_1", "observer_2")
    assert all(map(is_observer_agent, ("observer", "observer_0", "observer_12")))
    assert not any(map(is_observer_agent, ("ugv_0", "observer_", "observer_x", "observers")))


def test_each_observer_is_an_agent_in_velocity_mode_and_flies_its_own_uav():
    env = parallel_env("top_observer", action_mode="velocity", observer=TWO, n_ugvs=3, max_cycles=60)
    observations, infos = env.reset(seed=0)
    assert env.observer_agents == ("observer_0", "observer_1")
    assert env.possible_agents == ["ugv_0", "ugv_1", "ugv_2", "observer_0", "observer_1"]
    for agent in env.observer_agents:
        assert env.action_space(agent).shape == (4,)
        assert observations[agent].shape == env.observation_space(agent).shape
    assert env.state().shape == env.state_space.shape == (5 * 3 + 7 * 2 + 4 * 3,)
    start = {name: (s.x, s.y) for name, s in env.frame.uavs.items()}
    hold = {a: np.zeros(env.action_space(a).shape, dtype=np.float32) for a in env.agents}
    for _ in range(30):
        _, _, _, _, infos = env.step(hold | {"observer_1": np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32)})
    frame = env.frame
    assert frame.uavs["uav_0"].x == pytest.approx(start["uav_0"][0], abs=1e-9)  # held still
    assert frame.uavs["uav_1"].x > start["uav_1"][0] + 0.2  # flew forward
    assert infos["observer_1"]["truth"][0] == frame.uavs["uav_1"].x
    with pytest.raises(ValueError, match="observers"):
        frame.uav
    # both cameras measure, and the estimator localises both observers from the static robots
    assert {d.camera_id for d in env.detections} == {"uav_0/camera", "uav_1/camera"}
    for agent in env.observer_agents:
        assert infos[agent]["status"] == "localised"
        assert infos[agent]["localisation_error"] < 0.05


def test_trackers_fly_both_observers_in_switching_mode_and_the_api_holds():
    env = parallel_env("top_observer", action_mode="switching", observer=("quadcopter", "quadcopter"), max_cycles=80)
    env.reset(seed=1)
    assert env.observer_agents == () and env.possible_agents == ["ugv_0", "ugv_1"]
    for _ in range(80):
        if not env.agents:
            break
        env.step({"ugv_0": 1, "ugv_1": 0})
    assert all(e.status is not Status.LOST for e in env.frame.estimates.values())
    assert np.isfinite(env.state()).all()
    parallel_api_test(parallel_env("top_observer", action_mode="velocity", observer=TWO, max_cycles=40), num_cycles=40)


def test_a_pickled_two_observer_env_continues_bit_for_bit_and_renders():
    env = parallel_env("top_observer", action_mode="velocity", observer=TWO, render_mode="rgb_array", max_cycles=50)
    env.reset(seed=4)
    rng = np.random.default_rng(0)
    actions = [{a: env.action_space(a).sample(mask=None) * 0 + rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in env.possible_agents} for _ in range(20)]
    for a in actions[:10]:
        env.step(a)
    twin = pickle.loads(pickle.dumps(env))
    for a in actions[10:]:
        o1 = env.step(a)[0]
        o2 = twin.step(a)[0]
    assert all(o1[k].tobytes() == o2[k].tobytes() for k in o1)
    assert env.render().shape[2] == 3


def test_without_camera_noise_two_observers_localise_every_robot_exactly():
    env = parallel_env("top_observer", action_mode="velocity", observer=TWO, camera=CameraConfig(noise_px=0.0), max_cycles=40)
    env.reset(seed=2)
    moving = {a: np.zeros(env.action_space(a).shape, dtype=np.float32) for a in env.agents}
    moving["ugv_0"] = np.array([0.5, 0.0, 0.2, 1.0], dtype=np.float32)  # ugv_0 drives, ugv_1 is the reference
    for _ in range(30):
        _, _, _, _, infos = env.step(moving)
    for agent in ("ugv_0", "ugv_1", "observer_0", "observer_1"):
        assert infos[agent]["localisation_error"] < 1e-6, agent


def test_two_cameras_halve_the_variance_the_estimator_reports():
    """The same static scene measured by one observer or two: the estimate from two is the
    mean of the two samples, and its reported covariance is about half (independent noise)."""
    env = parallel_env("top_observer", action_mode="switching", observer=("quadcopter", "quadcopter"), observer_spacing=0.5)
    env.reset(seed=0)
    for _ in range(40):
        env.step({"ugv_0": 0, "ugv_1": 0})
    detections = list(env.detections)
    from moma_env.estimator import MomaEstimator

    wc = env.scenario.world
    variances = []
    for cameras in ({"uav_0/camera"}, {"uav_1/camera"}, {"uav_0/camera", "uav_1/camera"}):
        est = MomaEstimator(env.scenario.estimator)
        for ugv in wc.ugvs:
            boards = {b: ugv.board_mount for device, b, _ in env.boards if device == ugv.name}
            est.add_robot(ugv.name, boards=boards, static=True, initial_pose=env.world.ugv_transform(ugv.name), planar=True)
        for uav in wc.uavs:
            est.add_robot(uav.name, cameras={uav.camera_name: uav.camera_mount}, static=False)
        est.set_static("ugv_0", False, env.world.time)  # ugv_0 mobile: measured from ugv_1, the reference
        est.update(env.world.time, [d for d in detections if d.camera_id in cameras])
        variances.append(np.diag(est.estimate("ugv_0").covariance)[[0, 1, 5]])
    one = (variances[0] + variances[1]) / 2.0
    assert np.all(variances[2] < 0.6 * one) and np.all(variances[2] > 0.4 * one)


def test_leapfrog_with_two_observers_records_both_and_checks_its_fields():
    config = SquareConfig(observer=TWO, max_time_s=8.0)
    assert config.resolved_observer_offsets == (-0.25, 0.25)
    run = run_leapfrog(config, seed=0)
    assert {"uav_0", "uav_1"} <= set(run.trajectories)
    assert run.localised["uav_1"][-1]
    with pytest.raises(ConfigError) as excinfo:
        SquareConfig(observer=TWO, observer_offsets=(0.1,))
    assert excinfo.value.field == "square.observer_offsets"
    with pytest.raises(ConfigError) as excinfo:
        SquareConfig(observer=("quadcopter", "kite"))
    assert excinfo.value.field == "square.observer[1]"


def test_compare_runs_each_observer_alone_then_together():
    sets = observer_sets(["quadcopter", "quadcopter"])
    assert [s.label for s in sets] == ["quadcopter@-0.25", "quadcopter@+0.25", "quadcopter@-0.25+quadcopter@+0.25"]
    assert observer_sets(None)[0].kinds == ()
    args = build_parser().parse_args(["experiment", "compare", "--observers", "quadcopter,quadcopter"])
    assert args.observers == ["quadcopter", "quadcopter"]
    with pytest.raises(SystemExit):
        build_parser().parse_args(["experiment", "compare", "--observers", "quadcopter,kite"])


def test_vector_copies_with_two_observers_are_the_single_env():
    from moma_env import vector

    envs = vector.make("top_observer", 3, action_mode="velocity", observer=TWO, max_cycles=30)
    single = parallel_env("top_observer", action_mode="velocity", observer=TWO, max_cycles=30)
    observations, _ = envs.reset(seed=7)
    alone, _ = single.reset(seed=8)  # copy 1 of a batch seeded 7
    rng = np.random.default_rng(1)
    for _ in range(12):
        actions = {a: rng.uniform(-1, 1, (3, *envs.single_action_space(a).shape)).astype(np.float32) for a in envs.possible_agents}
        observations, *_ = envs.step(actions)
        alone, *_ = single.step({a: actions[a][1] for a in single.possible_agents})
    for agent in single.possible_agents:
        assert observations[agent][1].tobytes() == alone[agent].tobytes()
    assert envs.state().shape == (3, *single.state_space.shape)


def test_torchrl_groups_every_observer():
    pytest.importorskip("torchrl")
    from torchrl.envs.utils import check_env_specs

    from moma_env.vector.torchrl import MomaTorchRLEnv

    env = MomaTorchRLEnv("top_observer", num_envs=2, seed=0, action_mode="velocity", observer=TWO, max_cycles=20)
    assert env.group_map["observer"] == ["observer_0", "observer_1"]
    check_env_specs(env)
    rollout = env.rollout(5, break_when_any_done=False)
    assert rollout["next", "observer", "reward"].shape == (2, 5, 2, 1)


def test_the_planned_policy_flies_two_observers_and_reaches_every_goal():
    from agents.policies.planned import PlannedPolicy
    from moma_env.planning.validate import coverage_radius

    env = parallel_env("top_observer", action_mode="velocity", observer=TWO)
    one = TopObserverConfig().scenario()
    assert coverage_radius(env.scenario) == coverage_radius(one)  # the same UAVs' ceilings: the same coverage
    observations, infos = env.reset(seed=0)
    policy = PlannedPolicy()
    policy.reset(env, seed=0)
    terminations = {}
    while env.agents:
        observations, _, terminations, _, infos = env.step(policy.act(observations, infos))
    assert all(terminations.values())  # every goal reached ends the episode
    assert infos["ugv_0"]["reached_goal"] and infos["ugv_1"]["reached_goal"]
