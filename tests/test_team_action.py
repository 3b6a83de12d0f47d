"""``EnvConfig.team_action="one_start"``: the centralised team's action as one choice a
step (no start, or one static robot's advance), its masks, its decoding and encoding,
and how a training run, its policy and its evaluations carry it."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces

from agents.learned import LearnedPolicy
from moma_env.config import ConfigError
from moma_env.env.centralised import CentralisedTeamEnv, TeamLayout
from moma_env.env.factory import parallel_env
from moma_env.tasks import task_options
from moma_env.vector.team import TeamVectorEnv
from training.cli import build_parser
from training.evaluation import evaluate
from training.evaluation.policies import load_policy
from training.train.config import TrainConfig
from training.train.run import train

TASK = "top_observer_team4_legs"


def task_env(**options):
    configuration, task = task_options(TASK, **options)
    return parallel_env(configuration, **task)


def one_start_env() -> CentralisedTeamEnv:
    return CentralisedTeamEnv(task_env(team_action="one_start"))


def test_the_one_start_action_is_no_start_or_one_robots_advance():
    env = one_start_env()
    per_agent = CentralisedTeamEnv(task_env())
    n_ugvs, n_advances = len(per_agent.layout.agents), int(per_agent.action_space.nvec[0]) - 1
    assert isinstance(per_agent.action_space, spaces.MultiDiscrete)  # the default is the old action
    assert env.action_space == spaces.Discrete(1 + n_ugvs * n_advances)
    assert env.layout.starts == tuple((agent, a) for agent in env.layout.agents for a in range(1, n_advances + 1))
    env.reset(seed=0)
    # Team action s sends start s's action to its robot, hold (0) to every other; 0 holds all.
    for index in range(env.action_space.n):
        actions = env.agent_actions(np.int64(index))
        expected = {agent: 0 for agent in env.layout.agents}
        if index:
            agent, action = env.layout.starts[index - 1]
            expected[agent] = action
        assert actions == expected
    batch = env.layout.batch_actions(np.arange(env.action_space.n))
    for k in range(env.action_space.n):
        assert {a: int(batch[a][k]) for a in env.layout.agents} == env.agent_actions(k)


def test_its_masks_allow_no_start_always_and_a_start_only_where_the_robot_has_a_choice():
    env = one_start_env()
    env.reset(seed=4)
    seen_committed = seen_free = False
    rng = np.random.default_rng(0)
    for _ in range(120):
        agent_masks = env.parallel_env.action_masks()
        mask = env.action_masks()
        assert mask.shape == (env.action_space.n,) and mask.dtype == bool and mask[0]
        for s, (agent, action) in enumerate(env.layout.starts, start=1):
            free = agent_masks[agent].sum() > 1
            seen_committed |= not free and bool(agent_masks[agent][1])
            seen_free |= free
            assert mask[s] == (free and bool(agent_masks[agent][action]))
        env.step(rng.choice(np.flatnonzero(mask)))
    assert seen_committed and seen_free  # the walk met robots driving committed legs, and free ones


@pytest.mark.parametrize("seed", [3, 11])
def test_a_teachers_episode_through_the_encoding_is_the_same_episode_bit_for_bit(seed):
    per_agent = task_env()
    one_start = one_start_env()
    teacher = load_policy("greedy@1.5", TASK)
    observations, infos = per_agent.reset(seed=seed)
    team_obs, _ = one_start.reset(seed=seed)
    teacher.reset(per_agent, seed=seed)
    starts = 0
    while per_agent.agents:
        masks = per_agent.action_masks()
        actions = teacher.act(observations, infos)
        team = one_start.layout.team_actions({a: np.array([v]) for a, v in actions.items()}, {a: m[None] for a, m in masks.items()})
        assert team.shape == (1,) and one_start.action_masks()[team[0]]
        starts += int(team[0] != 0)
        observations, rewards, terminations, truncations, infos = per_agent.step(actions)
        team_obs, reward, terminated, truncated, _ = one_start.step(team[0])
        assert np.array_equal(team_obs, one_start.layout.observation(observations))
        assert reward == float(rewards[per_agent.possible_agents[0]])
        assert terminated == any(terminations.values()) and truncated == any(truncations.values())
    assert starts > 0 and terminated  # robots were started, and every goal reached


def test_two_starts_in_one_step_cannot_be_encoded_and_the_error_names_them():
    layout = one_start_env().layout
    agents = layout.agents
    free = np.ones((2, 5), dtype=bool)
    committed = np.array([[False, True, False, False, False]] * 2)
    masks = {agents[0]: free, agents[1]: free, agents[2]: committed, agents[3]: free}
    # copy 0: ugv_1 starts a 1 m leg, ugv_2 drives its committed leg; copy 1: two robots start
    actions = {agents[0]: np.array([0, 3]), agents[1]: np.array([2, 0]), agents[2]: np.array([1, 1]), agents[3]: np.array([0, 4])}
    with pytest.raises(ValueError, match=rf"copy 1: agents \['{agents[0]}', '{agents[3]}'\] start in the same step"):
        layout.team_actions(actions, masks)
    actions[agents[3]] = np.array([0, 0])
    encoded = layout.team_actions(actions, masks)
    assert [layout.starts[i - 1] for i in encoded] == [(agents[1], 2), (agents[0], 3)]


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.array([[1], [2]]), r"shape \(num_envs,\)"),
        (np.array([1.0, 2.0]), "must be integers"),
        (np.array([0, 17]), r"copy 1 must be an integer in \[0, 17\)"),
        (np.array([-1, 0]), r"copy 0 must be an integer in \[0, 17\)"),
    ],
)
def test_bad_team_actions_are_refused_naming_the_copy_or_the_shape(bad, message):
    with pytest.raises(ValueError, match=message):
        one_start_env().layout.batch_actions(bad)


def test_one_team_action_must_be_one_integer():
    env = one_start_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="must be one integer"):
        env.step(np.array([1, 2]))


@pytest.mark.parametrize(
    "options, message",
    [
        ({"team_action": "both"}, "env.team_action.*one of"),
        ({"team_action": "one_start", "commit_legs": False}, "env.team_action.*commit_legs=True"),
        ({"team_action": "one_start", "observer_agent": True}, "env.team_action.*observer_agent=False"),
    ],
)
def test_an_env_that_cannot_take_the_team_action_is_refused_naming_the_field(options, message):
    with pytest.raises(ConfigError, match=message):
        task_env(**options)


def test_a_layout_of_box_actions_cannot_be_one_start():
    with pytest.raises(ValueError, match="needs every agent's actions Discrete"):
        TeamLayout(["ugv_0"], [spaces.Box(-1, 1, (3,))], [spaces.Box(-1, 1, (3,))], "one_start")


def test_the_batched_team_env_is_each_copys_centralised_env():
    envs = TeamVectorEnv(TASK, 3, **task_options(TASK, team_action="one_start")[1])
    singles = [one_start_env() for _ in range(3)]
    assert envs.single_action_space == singles[0].action_space
    observations, _ = envs.reset(seed=7)
    for i, single in enumerate(singles):
        obs, _ = single.reset(seed=7 + i)
        assert np.array_equal(observations[i], obs)
    rng = np.random.default_rng(1)
    for _ in range(40):
        masks = envs.action_masks()
        assert np.array_equal(masks, np.stack([s.action_masks() for s in singles]))
        actions = np.array([rng.choice(np.flatnonzero(m)) for m in masks])
        observations, rewards, terminated, truncated, _ = envs.step(actions)
        for i, single in enumerate(singles):
            obs, reward, *_ = single.step(actions[i])
            assert np.array_equal(observations[i], obs) and rewards[i] == reward
    envs.close()


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"route": "shared"}, "--route centralised"),
        ({"network": "team"}, "--network mlp"),
        ({"scenario": "top_observer"}, "needs a task with committed legs"),
    ],
)
def test_a_run_that_cannot_take_the_team_action_is_refused_naming_the_field(fields, message):
    base = {"scenario": TASK, "algo": "maskable_ppo", "route": "centralised", "team_action": "one_start"}
    with pytest.raises(ConfigError, match=f"team_action.*{message}"):
        TrainConfig(**{**base, **fields})


def test_a_cloned_run_records_the_team_action_and_its_policy_fits_only_envs_with_it(tmp_path):
    config = TrainConfig(
        scenario=TASK, algo="maskable_ppo", route="centralised", team_action="one_start", steps=0, envs=2, net_arch=(16,),
        pretrain="greedy@1.5", pretrain_rows=600, pretrain_epochs=2, dagger_rounds=1, dagger_rows=100, dagger_epochs=1,
        checkpoint_every=10**6, max_cycles=60,
    )
    assert config.env_options["team_action"] == "one_start"
    assert "team_action" not in TrainConfig(scenario=TASK, algo="maskable_ppo", route="centralised").env_options
    manifest = train(config, tmp_path / "run")
    assert manifest["config"]["team_action"] == "one_start"
    policy = LearnedPolicy.from_dir(tmp_path / "run")
    assert policy.env_options["team_action"] == "one_start"
    assert isinstance(policy.model.action_space, spaces.Discrete)
    per_agent = task_env(observer_agent=False)
    per_agent.reset(seed=0)
    with pytest.raises(ValueError, match="team_action='one_start'; the env has 'per_agent'"):
        policy.reset(per_agent)
    # The evaluation builds the env the policy fits, and the policy's actions are the env's.
    options = {k: v for k, v in policy.env_options.items() if k != "action_mode"}
    result = evaluate(TASK, policy, 1, 10000, max_cycles=30, **options)
    assert len(result.episodes) == 1


@pytest.mark.parametrize("backend", ["rllib", "torchrl"])
def test_the_other_backends_refuse_the_team_action(backend):
    from training.train.rllib_command import rllib_config_from_args
    from training.train.torchrl_command import torchrl_config_from_args

    scenario = "top_observer" if backend == "rllib" else "top_observer_team4"
    algo = ["--algo", "maskable_ppo"] if backend == "torchrl" else []
    args = build_parser().parse_args(
        ["train", "--backend", backend, "--scenario", scenario, *algo, "--team-action", "one_start", "--out", "unused"]
    )
    from_args = rllib_config_from_args if backend == "rllib" else torchrl_config_from_args
    with pytest.raises(ConfigError, match="team_action.*drop --team-action"):
        from_args(args)
