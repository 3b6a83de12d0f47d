"""The simulation core (moma_env.sim): Frame, Simulation, the Localiser protocol, and the
env as its adapter (reward terms, action modes, swapped localisers)."""

import dataclasses
import math

import numpy as np
import pytest

from moma_env.camera import make_camera
from moma_env.env.actions import ACTION_MODE_TYPES, SwitchingActions, VelocityActions
from moma_env.env.config import EnvConfig, RewardConfig
from moma_env.env.factory import parallel_env
from moma_env.env.parallel import MomaParallelEnv
from moma_env.env.rewards import REWARD_TERMS
from moma_env.estimator import MomaEstimator, Status
from moma_env.scenarios import make_scenario
from moma_env.sim import Commands, Localiser, Simulation


def simulation(name="top_observer", **kwargs):
    scenario = make_scenario(name)
    cameras = {c: make_camera(c, scenario.camera) for c in camera_names(scenario)}
    return Simulation(scenario, cameras, **kwargs)


def camera_names(scenario):
    wc = scenario.world
    return [c.name for u in wc.ugvs for c in u.cameras] + ([wc.uav.camera_name] if wc.uav is not None else [])


def test_the_moma_estimator_is_a_localiser():
    assert isinstance(MomaEstimator(), Localiser)
    assert not isinstance(object(), Localiser)


def test_reset_gives_a_frame_of_static_devices_at_their_start():
    sim = simulation()
    frame = sim.reset(np.random.default_rng(0))
    assert frame.time == 0.0 and frame.steps == 0
    assert frame.mobile == frozenset()
    start = {u.name: u.initial_pose for u in sim.scenario.world.ugvs}
    for device, pose in start.items():
        assert frame.truth[device] == pytest.approx(pose)
        assert frame.errors[device] == pytest.approx(0.0, abs=1e-9)
    assert {d.board_id for d in frame.detections} == {0, 1}  # the UAV sees both boards at reset


def test_frames_are_immutable_snapshots():
    sim = simulation()
    frame = sim.reset(np.random.default_rng(0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        frame.time = 1.0
    with pytest.raises(TypeError):
        frame.truth["ugv_0"] = (0.0, 0.0, 0.0)
    later = sim.step(Commands(requests={"ugv_0": True}, velocities={"ugv_0": np.array([0.2, 0.0, 0.0])}))
    assert later is not frame and frame.steps == 0 and later.steps == 1
    assert later.truth["ugv_0"][0] > frame.truth["ugv_0"][0]  # the old frame kept its truth


def test_requests_go_through_the_rules_and_are_reported():
    sim = simulation()
    sim.reset(np.random.default_rng(0))
    frame = sim.step(Commands(requests={"ugv_0": True}))
    assert [(s.device, s.kind) for s in frame.switches] == [("ugv_0", "mobile")]
    assert frame.mobile == {"ugv_0"}
    # The other robot may not move while ugv_0 is mobile: it would lose its reference.
    frame = sim.step(Commands(requests={"ugv_1": True}))
    (switch,) = frame.switches
    assert switch.kind == "refused" and switch.reason is not None
    assert frame.mobile == {"ugv_0"}


def test_without_rules_every_request_is_granted():
    sim = simulation(rules=False)
    sim.reset(np.random.default_rng(0))
    frame = sim.step(Commands(requests={"ugv_0": True, "ugv_1": True}))
    assert frame.mobile == {"ugv_0", "ugv_1"}
    assert sim.check_mobile("ugv_0") is None


def test_the_experiments_frame_at_reset_has_no_detections_without_measure_at_reset():
    sim = simulation(measure_at_reset=False)
    frame = sim.reset(np.random.default_rng(0))
    assert frame.detections == ()
    assert frame.estimates["uav"].status is Status.LOST


def test_the_simulation_refuses_use_before_reset_and_bad_input():
    sim = simulation()
    with pytest.raises(RuntimeError, match="reset"):
        sim.frame
    with pytest.raises(TypeError, match="numpy Generator"):
        sim.reset(0)
    sim.reset(np.random.default_rng(0))
    with pytest.raises(KeyError, match="unknown device 'nobody'"):
        sim.declare("nobody", static=True)
    with pytest.raises(TypeError, match="Commands"):
        sim.step({"ugv_0": True})
    with pytest.raises(ValueError, match="no camera backend"):
        Simulation(make_scenario("top_observer"), {})


class CountingLocaliser(MomaEstimator):
    """A swapped-in localiser (here the MOMA estimator counting its updates)."""

    def update(self, time, detections):
        self.updates = getattr(self, "updates", 0) + 1
        super().update(time, detections)


def test_a_localiser_is_swapped_in_by_config_without_touching_the_env():
    env = parallel_env("top_observer")
    swapped = MomaParallelEnv(make_scenario("top_observer"), EnvConfig(localiser=CountingLocaliser))
    for e in (env, swapped):
        e.reset(seed=3)
        for _ in range(20):
            e.step({a: 1 for a in e.agents})
    assert isinstance(swapped.estimator, CountingLocaliser) and swapped.estimator.updates == 21
    assert swapped.state().tobytes() == env.state().tobytes()  # the same estimator inside: the same run


def test_a_localiser_that_is_not_one_is_refused():
    env = MomaParallelEnv(make_scenario("top_observer"), EnvConfig(localiser=lambda config: object()))
    with pytest.raises(TypeError, match="not a Localiser"):
        env.reset(seed=0)
    with pytest.raises(Exception, match="env.localiser"):
        EnvConfig(localiser=3)


@pytest.mark.parametrize("mode", ["switching", "velocity"])
def test_reward_terms_are_in_infos_and_sum_to_the_reward(mode):
    env = parallel_env("caterpillar_sled", action_mode=mode)
    env.reset(seed=1)
    names = [t.name for t in REWARD_TERMS]
    for step in range(60):
        actions = {a: env.action_space(a).sample() for a in env.agents}
        _, rewards, _, _, infos = env.step(actions)
        for agent in env.possible_agents:
            terms = infos[agent]["reward_terms"]
            assert list(terms) == names
            total = 0.0
            for value in terms.values():
                total += value
            assert rewards[agent] == total
        if not env.agents:
            break


def test_every_reward_term_has_a_weight_and_a_zero_weight_silences_it():
    fields = {f.name for f in dataclasses.fields(RewardConfig)}
    assert {t.name for t in REWARD_TERMS} <= fields
    env = parallel_env("top_observer", rewards={"time": 0.0, "progress": 0.0})
    env.reset(seed=0)
    _, _, _, _, infos = env.step({a: 0 for a in env.agents})
    assert infos["ugv_0"]["reward_terms"]["time"] == 0.0
    base = parallel_env("top_observer")
    base.reset(seed=0)
    _, _, _, _, infos = base.step({a: 0 for a in base.agents})
    assert infos["ugv_0"]["reward_terms"]["time"] == RewardConfig().time


def test_action_modes_are_objects_chosen_by_config():
    assert set(ACTION_MODE_TYPES) == {"switching", "velocity"}
    assert isinstance(parallel_env("top_observer").action_mode, SwitchingActions)
    assert isinstance(parallel_env("top_observer", action_mode="velocity").action_mode, VelocityActions)


def test_the_switching_executive_owns_its_legs():
    env = parallel_env("top_observer")
    env.reset(seed=0)
    env.step({"ugv_0": 1, "ugv_1": 0})
    executive = env.action_mode
    assert set(executive.legs) == {"ugv_0"}
    leg = executive.legs["ugv_0"]
    goal = env.scenario.goals["ugv_0"]
    start = env.frame.truth["ugv_0"]
    assert math.dist(leg[:2], start[:2]) <= env.scenario.leg_length + 0.05
    assert math.dist(leg[:2], goal[:2]) < math.dist(start[:2], goal[:2])
    env.reset(seed=0)
    assert executive.legs == {}


def test_reset_forgets_the_warm_started_pnp_poses():
    """With warm-started PnP the camera remembers poses across frames; a reset must
    forget them, so an episode after reset(seed) is the fresh env's episode bit for bit."""
    import numpy as np

    from moma_env.env.factory import parallel_env

    def episode(env, seed):
        env.reset(seed=seed)
        out = []
        for _ in range(30):
            obs, *_ = env.step({a: 1 for a in env.agents})
            out.append(np.concatenate([obs[a] for a in sorted(obs)]))
        return np.array(out)

    options = {"camera": {"pnp_warm_start": True}, "max_cycles": 500}
    used = parallel_env("top_observer", **options)
    episode(used, 1)
    camera = next(iter(used.simulation.cameras.values()))
    assert camera.warm_counts[0] > 0  # the warm start did run
    np.testing.assert_array_equal(episode(used, 2), episode(parallel_env("top_observer", **options), 2))
