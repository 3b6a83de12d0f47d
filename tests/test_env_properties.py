"""Random scenarios x random actions: invariants that must hold at every step."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from moma_env.env.factory import parallel_env
from moma_env.scenarios import CONFIGURATIONS

CASES = [(name, mode) for name in CONFIGURATIONS for mode in ("switching", "velocity")]


@pytest.mark.parametrize("name, mode", CASES)
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1))
def test_random_scenarios_and_actions_keep_the_invariants(name, mode, seed):
    env = parallel_env(name, action_mode=mode, random_scenarios=True, max_cycles=150)
    obs, infos = env.reset(seed=seed)
    for agent in env.possible_agents:
        env.action_space(agent).seed(seed)
    assert env.agents == env.possible_agents and set(obs) == set(env.agents) == set(infos)
    devices = env.devices
    steps = 0
    while env.agents:
        before = {d: env.simulation.device_pose(d) for d in devices if env.world.is_static(d)}
        alive = list(env.agents)
        actions = {a: env.action_space(a).sample() for a in alive}
        obs, rewards, terms, truncs, infos = env.step(actions)
        steps += 1
        assert set(obs) == set(rewards) == set(terms) == set(truncs) == set(infos) == set(alive)
        for agent, o in obs.items():
            space = env.observation_space(agent)
            assert o.shape == space.shape and o.dtype == space.dtype
            assert np.isfinite(o).all(), (agent, o)
            assert space.contains(o), (agent, o)
            assert np.isfinite(rewards[agent])
        released = {ev.split(":")[1] for info in infos.values() for ev in info["events"] if ev.startswith("mobile:")}
        for device, pose in before.items():
            if device not in released:
                assert env.simulation.device_pose(device) == pose, f"static {device} moved"
        ids = {d.board_id for d in env.detections}
        assert ids <= {board_id for _, board_id, _ in env.boards}
    assert steps <= 150
    assert env.agents == []


def test_switching_team_reaches_its_goal_with_a_simple_alternation():
    """Advancing the robots in turns is enough for the built-in controller to finish."""
    env = parallel_env("top_observer", action_mode="switching")
    env.reset(seed=0)
    turn, reached = 0, False
    while env.agents:
        agents = env.agents
        mover = agents[turn % len(agents)]
        obs, rewards, terms, truncs, infos = env.step({a: int(a == mover) for a in agents})
        if any(ev.startswith("leg_done") for ev in infos[mover]["events"]):
            turn += 1
        reached = all(terms.values())
    assert reached
    assert all(info["reached_goal"] for info in infos.values())
    assert all(info["localisation_error"] < 0.05 for info in infos.values())
