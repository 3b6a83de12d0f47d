"""``reset(options={"scenario": s})`` lays out a given scenario: the same episode as an env
made on that scenario alone, the generator's later resets unchanged, the same through the
batch (one dict per copy, in this process or over workers). Bad options (not a mapping,
a scenario of another configuration or team) are refused by name, changing nothing;
other keys are ignored with a warning naming them."""

import warnings

import numpy as np
import pytest

from moma_env import vector
from moma_env.env.factory import parallel_env
from moma_env.env.parallel import MomaParallelEnv
from moma_env.scenarios import TopObserverConfig, make_scenario, random_config
from serialised import text


def episode(env, seed, steps=25, options=None) -> str:
    """The exact text of a reset and ``steps`` steps of fixed, seeded actions."""
    out = [text(env.reset(seed=seed, options=options))]
    rng = np.random.default_rng(7)
    for _ in range(steps):
        if not env.agents:
            break
        out.append(text(env.step({a: int(rng.integers(2)) for a in env.agents})))
    return "\n".join(out)


def drawn_scenario(seed=3):
    """A random layout of the default team (2 UGVs)."""
    return TopObserverConfig.random(np.random.default_rng(seed), n_ugvs=2).scenario()


@pytest.mark.parametrize("random_scenarios", [False, True])
def test_a_given_scenario_runs_as_an_env_made_on_it(random_scenarios):
    scenario = drawn_scenario()
    env = parallel_env("top_observer", action_mode="switching", random_scenarios=random_scenarios)
    alone = MomaParallelEnv(scenario, env.config)
    given = episode(env, 11, options={"scenario": scenario})
    assert env.scenario is scenario
    assert given == episode(alone, 11)
    # and not the env's own layout of that seed
    assert given != episode(parallel_env("top_observer", action_mode="switching", random_scenarios=random_scenarios), 11)


def test_the_resets_after_a_given_scenario_are_as_without_it():
    scenario = drawn_scenario()
    plain = parallel_env("top_observer", action_mode="switching", random_scenarios=True)
    with_given = parallel_env("top_observer", action_mode="switching", random_scenarios=True)
    plain.reset(seed=5)
    with_given.reset(seed=5, options={"scenario": scenario})
    assert [episode(plain, None, 5) for _ in range(2)] == [episode(with_given, None, 5) for _ in range(2)]


def test_other_options_are_ignored_with_a_warning_naming_them():
    """PettingZoo's API test resets with made-up options and expects them taken."""
    a = parallel_env("top_observer", action_mode="switching", random_scenarios=True)
    b = parallel_env("top_observer", action_mode="switching", random_scenarios=True)
    c = parallel_env("top_observer", action_mode="switching", random_scenarios=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        reference = episode(a, 4)
        assert episode(b, 4, options={}) == reference
    with pytest.warns(UserWarning, match=r"^reset options 'layout', 'goals' are not this env's and are ignored; its reset takes 'scenario'$"):
        assert episode(c, 4, options={"layout": 1, "goals": 2}) == reference


def steps(env, n, rng) -> str:
    return "\n".join(text(env.step({a: int(rng.integers(2)) for a in env.agents})) for _ in range(n))


def test_bad_reset_options_are_refused_by_name_and_change_nothing():
    env = parallel_env("top_observer", action_mode="switching")
    reference = parallel_env("top_observer", action_mode="switching")
    env.reset(seed=2)
    reference.reset(seed=2)
    rng, reference_rng = np.random.default_rng(1), np.random.default_rng(1)
    assert steps(env, 3, rng) == steps(reference, 3, reference_rng)
    with pytest.raises(TypeError, match="options must be None or a mapping, got list"):
        env.reset(seed=9, options=[("scenario", None)])
    with pytest.raises(TypeError, match=r"options\['scenario'\] must be a Scenario .*got TopObserverConfig"):
        env.reset(seed=9, options={"scenario": random_config("top_observer", np.random.default_rng(0))})
    with pytest.raises(ValueError, match=r"options\['scenario'\]: a 'caterpillar' scenario; this env lays out 'top_observer' scenarios"):
        env.reset(seed=9, options={"scenario": make_scenario("caterpillar")})
    with pytest.raises(ValueError, match=r"options\['scenario'\]: its robots must be this env's: UGVs \['ugv_0', 'ugv_1', 'ugv_2'\]"):
        env.reset(seed=9, options={"scenario": make_scenario("top_observer", n_ugvs=3)})
    # the refused resets neither reset nor reseeded anything: the episode goes on as the reference's
    assert steps(env, 5, rng) + text(env.state()) == steps(reference, 5, reference_rng) + text(reference.state())
    assert text(env.reset()) == text(reference.reset())


@pytest.mark.parametrize("workers", [None, 2])
def test_the_batch_gives_each_copy_its_own_options(workers):
    scenario = drawn_scenario(8)
    envs = vector.make("top_observer", 3, action_mode="switching", random_scenarios=True, workers=workers)
    try:
        observations, _ = envs.reset(seed=20, options=[None, {"scenario": scenario}, None])
        for i, seed in enumerate((20, 21, 22)):
            single = parallel_env("top_observer", action_mode="switching", random_scenarios=True)
            expected, _ = single.reset(seed=seed, options={"scenario": scenario} if i == 1 else None)
            for agent in envs.agents:
                np.testing.assert_array_equal(observations[agent][i], expected[agent])
        with pytest.warns(UserWarning, match="reset options 'scenery' are not this env's and are ignored; its reset takes 'scenario'"):
            envs.reset_at(0, seed=20, options={"scenery": scenario})
    finally:
        envs.close()


def test_the_gymnasium_team_env_and_its_vector_env_take_the_scenario():
    import gymnasium

    import moma_env  # noqa: F401 - registers the Gymnasium ids

    scenario = drawn_scenario(5)
    team = gymnasium.make("moma_env/TopObserver-v0", action_mode="switching")
    observation, _ = team.reset(seed=1, options={"scenario": scenario})
    assert team.unwrapped.parallel_env.scenario is scenario
    envs = gymnasium.make_vec("moma_env/TopObserver-v0", num_envs=2, action_mode="switching")
    observations, _ = envs.reset(seed=[1, 1], options={"scenario": scenario})
    np.testing.assert_array_equal(observations[0], observation)
    np.testing.assert_array_equal(observations[1], observation)
    plain, _ = gymnasium.make("moma_env/TopObserver-v0", action_mode="switching").reset(seed=1)
    assert not np.array_equal(plain, observation)
    envs.close()
