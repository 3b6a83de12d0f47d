"""Bad input gets a clear error naming the problem, at the boundary."""

import numpy as np
import pytest

from moma_env import caterpillar_sled_v0, top_observer_v0
from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env


@pytest.fixture
def velocity_env():
    env = top_observer_v0.parallel_env(action_mode="velocity")
    env.reset(seed=0)
    return env


def ok_actions(env):
    return {a: np.zeros(env.action_space(a).shape, dtype=np.float32) for a in env.agents}


@pytest.mark.parametrize("bad", [np.array([np.nan, 0, 0, 0]), np.array([0, np.inf, 0, 0])])
def test_non_finite_action_is_rejected(velocity_env, bad):
    actions = ok_actions(velocity_env) | {"ugv_0": bad}
    with pytest.raises(ValueError, match="action of 'ugv_0' must be finite"):
        velocity_env.step(actions)


def test_wrong_shape_action_is_rejected(velocity_env):
    with pytest.raises(ValueError, match=r"action of 'observer' must have shape \(4,\)"):
        velocity_env.step(ok_actions(velocity_env) | {"observer": np.zeros(3)})


def test_out_of_range_velocity_is_clipped_not_rejected(velocity_env):
    velocity_env.step(ok_actions(velocity_env) | {"ugv_0": np.array([5.0, 0.0, 0.0, 1.0])})


@pytest.mark.parametrize("bad", [2, -1, 0.5, "advance", None])
def test_bad_discrete_action_is_rejected(bad):
    env = top_observer_v0.parallel_env()
    env.reset(seed=0)
    if bad is None:  # a missing action means "hold"
        env.step({"ugv_0": None, "ugv_1": 0})
        return
    with pytest.raises(ValueError, match=r"action of 'ugv_0' must be an integer in \[0, 2\)"):
        env.step({"ugv_0": bad, "ugv_1": 0})


def test_sled_robot_has_a_reel_action():
    env = caterpillar_sled_v0.parallel_env()
    env.reset(seed=0)
    assert env.action_space("ugv_0").n == 3
    with pytest.raises(ValueError, match=r"\[0, 3\)"):
        env.step({"ugv_0": 3})


def test_unknown_and_finished_agents_are_rejected(velocity_env):
    with pytest.raises(KeyError, match="unknown agent 'ugv_9'"):
        velocity_env.step(ok_actions(velocity_env) | {"ugv_9": np.zeros(4)})
    env = top_observer_v0.parallel_env(max_cycles=1)
    env.reset(seed=0)
    env.step({"ugv_0": 0, "ugv_1": 0})
    assert env.agents == []
    with pytest.raises(RuntimeError, match="finished episode"):
        env.step({"ugv_0": 0})
    with pytest.raises(KeyError, match="unknown agent"):
        env.observation_space("pilot")


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"action_mode": "teleport"}, "env.action_mode"),
        ({"max_cycles": 0}, "env.max_cycles"),
        ({"n_ugvs": 1}, "top_observer.n_ugvs"),
        ({"camera": {"fx": 0.0}}, "camera.fx"),
        ({"rewards": {"progres": 1.0}}, "rewards.progres"),
        ({"altitude": -1.0}, "top_observer.altitude"),
        ({"colour": "red"}, "top_observer.colour"),
    ],
)
def test_invalid_configs_name_the_field(kwargs, field):
    with pytest.raises(ConfigError) as err:
        parallel_env("top_observer", **kwargs)
    assert field in str(err.value)


def test_unknown_configuration_and_render_mode():
    with pytest.raises(ConfigError, match="unknown configuration 'kite'"):
        parallel_env("kite")
    with pytest.raises(ValueError, match="render_mode"):
        top_observer_v0.parallel_env(render_mode="ascii")


def test_refused_request_is_reported_not_raised():
    # Both robots ask to move at once: one is granted, the other refused (rule 2).
    env = top_observer_v0.parallel_env()
    env.reset(seed=0)
    _, rewards, _, _, infos = env.step({"ugv_0": 1, "ugv_1": 1})
    events = infos["ugv_0"]["events"] + infos["ugv_1"]["events"]
    assert sum(ev.startswith("mobile:") for ev in events) == 1
    refused = infos["ugv_0"]["refused"] + infos["ugv_1"]["refused"]
    assert refused == ["no_reference"]


# -- actions that numpy would coerce: each refused, naming the agent and the space ----------------


@pytest.mark.parametrize("bad", [float("inf"), float("nan"), True, np.bool_(True), "1", 1.0, 1 + 0j, [1]])
def test_switching_actions_must_be_integers_of_the_space(bad):
    env = top_observer_v0.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action of 'ugv_0' must be an integer in \[0, 2\) \(the space Discrete\(2\)\)"):
        env.step({"ugv_0": bad, "ugv_1": 0})


@pytest.mark.parametrize("good", [1, np.int64(1), np.array(1), np.array([1], dtype=np.int32)])
def test_switching_actions_accept_python_and_numpy_integers(good):
    env = top_observer_v0.parallel_env()
    env.reset(seed=0)
    _, _, _, _, infos = env.step({"ugv_0": good, "ugv_1": 0})
    assert "mobile:ugv_0" in infos["ugv_0"]["events"]


@pytest.mark.parametrize(
    "bad",
    ["abc", {"vx": 1}, ["1", "0", "0", "0"], [1 + 0j, 0, 0, 0], [True, False, False, True], object(), None.__class__],
)
def test_velocity_actions_must_be_real_numbers(velocity_env, bad):
    with pytest.raises(ValueError, match=r"action of 'ugv_0' must .*Box\(-1\.0, 1\.0, \(4,\), float32\)"):
        velocity_env.step(ok_actions(velocity_env) | {"ugv_0": bad})


@pytest.mark.parametrize("call", ["state", "action_masks", "render"])
def test_using_the_env_before_reset_is_a_clear_error(call):
    env = top_observer_v0.parallel_env(render_mode="rgb_array")
    with pytest.raises(RuntimeError, match=r"call reset\(\) before"):
        getattr(env, call)()
    env.reset(seed=0)
    getattr(env, call)()


@pytest.mark.parametrize("seed", [-1, True, 1.5, "0", np.float64(2.0)])
def test_bad_seeds_name_the_seed(seed):
    env = top_observer_v0.parallel_env()
    with pytest.raises(ValueError, match="seed must be None or a non-negative integer"):
        env.reset(seed=seed)


def test_large_and_numpy_seeds_follow_gymnasium():
    env = top_observer_v0.parallel_env()
    a = env.reset(seed=2**64)[0]
    b = env.reset(seed=np.uint64(7))[0]
    c = env.reset(seed=7)[0]
    assert all(np.array_equal(b[k], c[k]) for k in c)
    assert set(a) == set(c)


def test_max_cycles_set_on_the_env_survives_random_layouts():
    env = parallel_env("top_observer", random_scenarios=True)
    env.max_cycles = 7
    for seed in range(3):
        env.reset(seed=seed)
        steps = 0
        while env.agents:
            env.step({a: 0 for a in env.agents})
            steps += 1
        assert steps == 7 and env.max_cycles == 7


@pytest.mark.parametrize("value", [np.int64(50), np.int32(3), 5])
def test_numpy_integers_are_integers_for_max_cycles(value):
    env = parallel_env("top_observer", max_cycles=value)
    assert env.max_cycles == int(value) and type(env.config.max_cycles) is int
    env.max_cycles = value
    assert env.max_cycles == int(value)


@pytest.mark.parametrize("value", [0, -3, 2.5, True, "50"])
def test_bad_max_cycles_is_refused_naming_it(value):
    with pytest.raises(ConfigError, match="max_cycles"):
        parallel_env("top_observer", max_cycles=value)
    env = parallel_env("top_observer")
    with pytest.raises(ConfigError, match="max_cycles"):
        env.max_cycles = value
