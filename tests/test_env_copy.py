"""The env can be copied, pickled and shipped to other processes, and a copy continues
bit for bit like the original (SuperSuit's vector wrappers, Gymnasium's AsyncVectorEnv)."""

import copy
import pickle

import gymnasium
import numpy as np
import pytest

import moma_env  # noqa: F401 - registers the Gymnasium ids
from moma_env.env.factory import parallel_env
from moma_env.registration import GYMNASIUM_IDS
from serialised import text

CONFIGURATIONS = ("top_observer", "caterpillar", "caterpillar_sled", "caterpillar_multi")


def run(env, actions) -> str:
    """The exact text of every step's outputs and the state, for the given actions."""
    out = []
    for joint in actions:
        if not env.agents:
            out.append(text(env.reset()))
            continue
        out.append(text(env.step({a: joint[a] for a in env.agents})))
        out.append(text(env.state()))
    return "\n".join(out)


def sampled_actions(env, n, seed):
    for agent in env.possible_agents:
        env.action_space(agent).seed(seed)
    return [{a: env.action_space(a).sample() for a in env.possible_agents} for _ in range(n)]


def pickle_copy(env):
    return pickle.loads(pickle.dumps(env))


@pytest.mark.parametrize("duplicate", [copy.deepcopy, pickle_copy], ids=["deepcopy", "pickle"])
@pytest.mark.parametrize("mode", ["switching", "velocity"])
@pytest.mark.parametrize("name", CONFIGURATIONS)
def test_a_copy_continues_bit_for_bit(name, mode, duplicate):
    env = parallel_env(name, action_mode=mode, max_cycles=60)
    fresh = duplicate(env)  # before any reset
    assert text(env.reset(seed=5)) == text(fresh.reset(seed=5))
    actions = sampled_actions(env, 150, seed=5)
    run(env, actions[:40])
    run(fresh, actions[:40])
    middle = duplicate(env)  # mid-episode, with robots moving
    assert run(middle, actions[40:]) == run(env, actions[40:]) == run(fresh, actions[40:])


@pytest.mark.parametrize("duplicate", [copy.deepcopy, pickle_copy], ids=["deepcopy", "pickle"])
@pytest.mark.parametrize("estimator", ["graph", "graph_vision"])
def test_a_graph_estimator_env_copied_mid_episode_continues_bit_for_bit(estimator, duplicate):
    pytest.importorskip("gtsam")
    env = parallel_env("top_observer", action_mode="switching", max_cycles=80, localiser=estimator)
    env.reset(seed=3)
    actions = sampled_actions(env, 70, seed=3)
    run(env, actions[:30])
    assert env.simulation.localiser.size[0] > 0  # the graph holds variables: iSAM2 has state to rebuild
    middle = duplicate(env)
    assert run(middle, actions[30:]) == run(env, actions[30:])


def test_a_copy_of_a_random_layout_env_keeps_drawing_the_same_layouts():
    env = parallel_env("top_observer", random_scenarios=True, max_cycles=20)
    env.reset(seed=2)
    twin = pickle_copy(env)
    for _ in range(3):
        assert text(env.reset()) == text(twin.reset())


def test_copies_are_independent():
    env = parallel_env("top_observer", max_cycles=50)
    env.reset(seed=0)
    twin = copy.deepcopy(env)
    for _ in range(10):
        env.step({a: 1 for a in env.agents})
    assert env.steps == 10 and twin.steps == 0
    assert env.frame.truth != twin.frame.truth


def test_padding_gives_every_agent_one_observation_shape():
    env = parallel_env("top_observer", action_mode="velocity", pad_observations=True)
    observations, _ = env.reset(seed=0)
    first = env.observation_space(env.possible_agents[0])
    assert all(env.observation_space(a) == first for a in env.possible_agents)
    for agent, obs in observations.items():
        assert env.observation_space(agent).contains(obs), agent
    plain = parallel_env("top_observer", action_mode="velocity")
    unpadded, _ = plain.reset(seed=0)
    for agent, obs in unpadded.items():
        n = obs.shape[0]
        assert np.array_equal(observations[agent][:n], obs)
        assert not observations[agent][n:].any()


@pytest.mark.parametrize("num_cpus", [0, 2])
@pytest.mark.parametrize(
    "kwargs",
    [
        {"configuration": "top_observer"},
        {"configuration": "caterpillar"},
        {"configuration": "caterpillar_multi"},
        {"configuration": "top_observer", "action_mode": "velocity", "pad_observations": True},
        {"configuration": "caterpillar", "action_mode": "velocity"},
        {"configuration": "caterpillar_sled"},
        {"configuration": "caterpillar_sled", "action_mode": "velocity"},
        {"configuration": "caterpillar_multi", "action_mode": "velocity"},
    ],
    ids=lambda kw: "-".join(str(v) for v in kw.values()),
)
def test_supersuit_vector_envs(kwargs, num_cpus):
    ss = pytest.importorskip("supersuit")
    kwargs = dict(kwargs)
    env = parallel_env(kwargs.pop("configuration"), max_cycles=30, **kwargs)
    vec = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(env), 2, num_cpus=num_cpus, base_class="gymnasium")
    try:
        observations, _ = vec.reset(seed=0)
        n = vec.num_envs
        assert observations.shape[0] == n == 2 * len(env.possible_agents)
        truncated = 0
        for _ in range(40):  # past an episode's end (30 steps): the copies reset themselves
            actions = np.stack([vec.action_space.sample() for _ in range(n)])  # SuperSuit: the one-agent space
            observations, rewards, terminations, truncations, _ = vec.step(actions)
            assert observations.shape[0] == n and np.isfinite(rewards).all()
            truncated += int(np.count_nonzero(truncations))
        assert truncated == n  # every agent of every copy reached max_cycles once
    finally:
        vec.close()


def test_supersuit_copies_in_processes_match_the_in_process_ones():
    ss = pytest.importorskip("supersuit")
    results = []
    for num_cpus in (0, 2):
        vec = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(parallel_env("caterpillar", max_cycles=25)), 2, num_cpus=num_cpus)
        try:
            out = [vec.reset(seed=3)[0]]
            rng = np.random.default_rng(0)
            for _ in range(30):
                out.append(vec.step(rng.integers(0, 2, size=vec.num_envs))[0])
            results.append(np.stack(out))
        finally:
            vec.close()
    assert np.array_equal(results[0], results[1])


def test_gymnasium_async_vector_env_over_every_id():
    for env_id in GYMNASIUM_IDS:
        vec = gymnasium.vector.AsyncVectorEnv([lambda env_id=env_id: gymnasium.make(env_id, max_cycles=20)] * 2)
        try:
            observations, _ = vec.reset(seed=0)
            assert observations.shape[0] == 2
            vec.action_space.seed(0)
            for _ in range(25):
                observations, rewards, _, _, _ = vec.step(vec.action_space.sample())
            assert np.isfinite(rewards).all()
        finally:
            vec.close()


def test_a_rendered_env_copies_and_continues_bit_for_bit():
    env = parallel_env("top_observer", camera_backend="rendered", observer_agent=True, observer_image=(48, 40), max_cycles=40)
    env.reset(seed=4)
    actions = sampled_actions(env, 16, seed=4)
    run(env, actions[:6])
    twins = (copy.deepcopy(env), pickle_copy(env))
    expected = run(env, actions[6:])
    for twin in twins:
        assert run(twin, actions[6:]) == expected
