"""Named tasks: a configuration with its study options, accepted wherever a configuration is."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env import vector
from moma_env.config import ConfigError
from moma_env.env.config import SWITCHING_ONLY_OPTIONS, EnvConfig
from moma_env.env.factory import parallel_env
from moma_env.scenarios.top_observer import MAX_GOAL_SPREAD, TopObserverConfig
from moma_env.tasks import TASKS, task_options


@pytest.mark.parametrize("name", sorted(TASKS))
def test_every_task_builds_with_its_team_and_options(name):
    task = TASKS[name]
    env = parallel_env(name)
    observations, infos = env.reset(seed=1)
    ugvs = [a for a in env.possible_agents if a != "observer"]
    assert len(ugvs) == task.options["n_ugvs"]
    assert env.config.action_mode == task.options["action_mode"]
    assert all("action_mask" in infos[a] for a in ugvs) == task.options["action_masks"]
    assert env.scenario.name == task.configuration


def test_task_keywords_override_the_task_options():
    env = parallel_env("top_observer_team4", action_mode="velocity", action_masks=False, commit_legs=False)
    assert env.config.action_mode == "velocity"
    configuration, options = task_options("top_observer_team4", n_ugvs=5)
    assert configuration == "top_observer" and options["n_ugvs"] == 5 and options["goal_spread"] == 2.0


@pytest.mark.parametrize("name", sorted(TASKS))
def test_another_action_mode_names_every_switching_option_of_the_task_at_once(name):
    own = [key for key in SWITCHING_ONLY_OPTIONS if TASKS[name].options.get(key) not in (None, False)]
    assert own  # every task runs in switching mode with the masks and committed legs
    with pytest.raises(ConfigError, match="action_mode: task") as error:
        parallel_env(name, action_mode="velocity")
    for key in own:
        assert key in str(error.value)
    off = {key: (False if isinstance(TASKS[name].options[key], bool) else None) for key in own}
    # what the message says to pass is enough: the env builds in the other mode
    assert parallel_env(name, action_mode="velocity", **off).config.action_mode == "velocity"
    with pytest.raises(ConfigError, match="action_mode: task") as partial:
        parallel_env(name, action_mode="velocity", **dict(list(off.items())[:1]))
    assert own[0] not in str(partial.value).split("pass")[1]


@pytest.mark.parametrize("key", SWITCHING_ONLY_OPTIONS)
def test_each_switching_only_option_is_refused_in_velocity_mode(key):
    on = {"action_masks": True, "commit_legs": True, "leg_lengths": (0.5, 1.0), "follower_hold_m": 0.2}[key]
    EnvConfig(action_mode="switching", **{key: on})
    with pytest.raises(ConfigError, match=f"env.{key}"):
        EnvConfig(action_mode="velocity", **{key: on})


def test_unknown_task_is_named():
    with pytest.raises(ConfigError, match="task: unknown task 'nope'"):
        task_options("nope")


def test_a_task_vector_env_steps():
    envs = vector.make("top_observer_team4", 3)
    observations, _ = envs.reset(seed=0)
    assert observations["ugv_3"].shape[0] == 3
    masks = envs.action_masks()
    assert masks["ugv_0"].shape == (3, 2)


def test_goal_spread_spreads_the_team_about_the_formation_centre():
    base = TopObserverConfig(n_ugvs=4, goal_offset=(1.0, 0.5, 0.0))
    spread = TopObserverConfig(n_ugvs=4, goal_offset=(1.0, 0.5, 0.0), goal_spread=2.5)
    starts = {u.name: u.initial_pose for u in base.scenario().world.ugvs}
    kept, spread_goals = base.scenario().goals, spread.scenario().goals
    centre = np.mean([g[:2] for g in kept.values()], axis=0)
    centre_spread = np.mean([g[:2] for g in spread_goals.values()], axis=0)
    np.testing.assert_allclose(centre, centre_spread, atol=1e-12)
    for name, start in starts.items():
        np.testing.assert_allclose(np.subtract(spread_goals[name][:2], centre), 2.5 * np.subtract(kept[name][:2], centre), atol=1e-12)
        assert math.isclose(spread_goals[name][2], kept[name][2])


def test_random_layouts_keep_the_goal_spread_and_default_draws_are_unchanged():
    a = TopObserverConfig.random(np.random.default_rng(7), n_ugvs=3)
    b = TopObserverConfig.random(np.random.default_rng(7), n_ugvs=3, goal_spread=1.0)
    assert a == b
    c = TopObserverConfig.random(np.random.default_rng(7), n_ugvs=3, goal_spread=2.0)
    assert c.goal_spread == 2.0 and c.n_ugvs == 3


@pytest.mark.parametrize("value", [0.5, MAX_GOAL_SPREAD + 0.1, float("nan"), "2"])
def test_bad_goal_spread_is_named(value):
    with pytest.raises(ConfigError, match="top_observer.goal_spread"):
        TopObserverConfig.random(np.random.default_rng(0), goal_spread=value)
    with pytest.raises(ConfigError, match="top_observer.goal_spread"):
        TopObserverConfig(goal_spread=value)


def test_team_count_stays_an_integer():
    with pytest.raises(ConfigError, match="top_observer.n_ugvs"):
        TopObserverConfig.random(np.random.default_rng(0), n_ugvs=2.5)


def test_final_error_term_charges_the_mean_error_once_when_the_team_arrives():
    from agents.policies import GreedyParallelPolicy
    from moma_env.tasks import TEAM_REWARDS

    env = parallel_env("top_observer_team4")
    observations, infos = env.reset(seed=3)
    policy = GreedyParallelPolicy()
    policy.reset(env)
    charged = []
    terminations: dict[str, bool] = {}
    while env.agents:
        observations, _, terminations, _, infos = env.step(policy.act(observations, infos))
        charged.append(infos["ugv_0"]["reward_terms"]["final_error"])
    assert all(terminations.values())
    assert all(value == 0.0 for value in charged[:-1])
    errors = [infos[a]["localisation_error"] for a in infos]
    assert charged[-1] == pytest.approx(TEAM_REWARDS["final_error"] * sum(errors) / len(errors), rel=1e-12)
    assert charged[-1] < 0.0


def test_training_config_takes_a_task_and_its_objective():
    from training.train.command_common import scenario_rewards
    from training.train.config import TrainConfig
    from moma_env.tasks import TEAM_REWARDS

    config = TrainConfig(scenario="top_observer_team4")
    assert "rewards" not in config.env_options  # the task's own weights apply
    env = parallel_env(config.scenario, **config.env_options)
    assert env.config.rewards.final_error == TEAM_REWARDS["final_error"]
    assert scenario_rewards("top_observer_team4", []) is None
    changed = scenario_rewards("top_observer_team4", ["time=-0.02"])
    assert changed.time == -0.02 and changed.final_error == TEAM_REWARDS["final_error"]
    assert scenario_rewards("top_observer", ["time=-0.02"]).final_error == 0.0
    with pytest.raises(ConfigError, match="scenario"):
        TrainConfig(scenario="top_observer_team5")


def test_built_in_policies_load_for_a_task():
    from training.evaluation import load_policy
    from agents.policies import TopObserverLeapfrog

    assert isinstance(load_policy("scripted", "top_observer_team4"), TopObserverLeapfrog)


def test_tasks_have_gymnasium_ids():
    import gymnasium

    import moma_env  # noqa: F401  (registers the ids)

    team = gymnasium.make("moma_env/TopObserverTeam4-v0")
    observation, info = team.reset(seed=0)
    assert team.unwrapped.parallel_env.scenario.name == "top_observer"
    assert len([a for a in team.unwrapped.parallel_env.possible_agents if a.startswith("ugv")]) == 4
    envs = gymnasium.make_vec("moma_env/TopObserverTeam6-v0", num_envs=2)
    observations, _ = envs.reset(seed=0)
    assert observations.shape[0] == 2
    envs.close()
