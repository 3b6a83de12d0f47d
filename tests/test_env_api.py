"""PettingZoo's and Gymnasium's own checkers, for every configuration and action mode."""

import types

import gymnasium
import numpy as np
import pytest
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test

import moma_env
from moma_env import caterpillar_multi_v0, caterpillar_sled_v0, caterpillar_v0, top_observer_v0
from moma_env.registration import GYMNASIUM_IDS

MODULES = {
    "top_observer": top_observer_v0,
    "caterpillar": caterpillar_v0,
    "caterpillar_sled": caterpillar_sled_v0,
    "caterpillar_multi": caterpillar_multi_v0,
}
MODES = ("switching", "velocity")
CASES = [(name, mode) for name in MODULES for mode in MODES]


def module_for(name: str, mode: str) -> types.SimpleNamespace:
    """A module-like object whose constructors use ``mode`` (for the checkers that take a module)."""
    mod = MODULES[name]
    return types.SimpleNamespace(
        parallel_env=lambda **kw: mod.parallel_env(action_mode=mode, **kw),
        env=lambda **kw: mod.env(action_mode=mode, **kw),
    )


@pytest.mark.parametrize("name, mode", CASES)
def test_parallel_api(name, mode):
    parallel_api_test(module_for(name, mode).parallel_env(), num_cycles=60)


@pytest.mark.parametrize("name, mode", CASES)
def test_aec_api(name, mode):
    api_test(module_for(name, mode).env(), num_cycles=30)


@pytest.mark.parametrize("name, mode", CASES)
def test_parallel_seed(name, mode):
    parallel_seed_test(module_for(name, mode).parallel_env, num_cycles=40)


@pytest.mark.parametrize("name, mode", CASES)
def test_render(name, mode):
    render_test(lambda render_mode=None: module_for(name, mode).env(render_mode=render_mode, max_cycles=5))


@pytest.mark.parametrize("name, mode", CASES)
def test_max_cycles(name, mode):
    max_cycles_test(module_for(name, mode))


@pytest.mark.parametrize("env_id", sorted(GYMNASIUM_IDS))
def test_gymnasium_checkers(env_id):
    from gymnasium.utils.env_checker import check_env as gym_check_env

    sb3_check_env = pytest.importorskip("stable_baselines3.common.env_checker", reason="needs the 'train' extra").check_env

    env = gymnasium.make(env_id, max_cycles=50)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert isinstance(reward, float) and set(info) == set(env.unwrapped.parallel_env.possible_agents)
    env.close()


def test_gymnasium_velocity_mode_and_render():
    env = gymnasium.make("moma_env/TopObserver-v0", action_mode="velocity", render_mode="rgb_array", max_cycles=5)
    env.reset(seed=0)
    assert isinstance(env.action_space, gymnasium.spaces.Box)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    env.close()


def test_pettingzoo_registry():
    import pettingzoo

    if not hasattr(pettingzoo, "register"):
        pytest.skip("this PettingZoo has no registry")
    env = pettingzoo.make("parallel", "moma_env/top_observer-v0")
    assert env.possible_agents == ["ugv_0", "ugv_1"]
    assert moma_env.__version__


def test_metadata_and_cached_spaces():
    env = top_observer_v0.parallel_env(action_mode="velocity")
    assert env.metadata["name"] == "top_observer_v0"
    assert env.metadata["is_parallelizable"] is True
    assert set(env.metadata["render_modes"]) >= {"rgb_array"}
    assert env.metadata["render_fps"] == 25
    assert env.possible_agents == ["ugv_0", "ugv_1", "observer"]
    assert env.observation_space("ugv_0") is env.observation_space("ugv_0")
    assert env.action_space("observer") is env.action_space("observer")
