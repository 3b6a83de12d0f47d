"""``EnvConfig.team_action="one_start"``: the centralised team's action as one choice a
step (no start, or one static robot's advance), its masks, its decoding and encoding,
and how a training run, its policy and its evaluations carry it."""

from __future__ import annotations

import json
import numpy as np
import pytest
from gymnasium import spaces

from agents.learned import LearnedPolicy
from moma_env.config import ConfigError
from moma_env.env.centralised import CentralisedTeamEnv, TeamLayout
from moma_env.env.factory import parallel_env
from moma_env.tasks import task_options
from moma_env.vector.team import TeamVectorEnv
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


def infos_of(layout: TeamLayout, static: list[list[bool]]) -> list[dict]:
    """Copies' infos saying which robots are static (row per copy, column per agent)."""
    return [{agent: {"static": flag} for agent, flag in zip(layout.agents, row)} for row in static]


def test_the_one_start_action_is_no_start_or_one_static_robots_advance_and_the_others_keep_their_state():
    env = one_start_env()
    per_agent = CentralisedTeamEnv(task_env())
    n_ugvs, n_advances = len(per_agent.layout.agents), int(per_agent.action_space.nvec[0]) - 1
    assert isinstance(per_agent.action_space, spaces.MultiDiscrete)  # the default is the old action
    assert env.action_space == spaces.Discrete(1 + n_ugvs * n_advances)
    assert env.layout.starts == tuple((agent, a) for agent in env.layout.agents for a in range(1, n_advances + 1))
    _, infos = env.reset(seed=0)
    assert all(infos[a]["static"] for a in env.layout.agents)
    # Team action s sends start s's action to its robot, hold (0) to every other; 0 holds all.
    for index in range(env.action_space.n):
        actions = env.agent_actions(np.int64(index))
        expected = {agent: 0 for agent in env.layout.agents}
        if index:
            agent, action = env.layout.starts[index - 1]
            expected[agent] = action
        assert actions == expected
    everyone_static = [dict(infos)] * env.action_space.n
    batch = env.layout.batch_actions(np.arange(env.action_space.n), everyone_static)
    for k in range(env.action_space.n):
        assert {a: int(batch[a][k]) for a in env.layout.agents} == env.agent_actions(k)
    # A mobile robot keeps advancing (1) whatever is chosen, a start of it included.
    layout = env.layout
    ugv_1_moves = infos_of(layout, [[True, False, True, True]] * 3)
    chosen = np.array([0, layout.starts.index(("ugv_1", 3)) + 1, layout.starts.index(("ugv_2", 4)) + 1])
    batch = layout.batch_actions(chosen, ugv_1_moves)
    assert [[int(batch[a][k]) for a in layout.agents] for k in range(3)] == [[0, 1, 0, 0], [0, 1, 0, 0], [0, 1, 4, 0]]


def test_its_masks_allow_no_start_always_and_a_start_only_of_a_static_robot_its_mask_allows():
    env = one_start_env()
    _, infos = env.reset(seed=4)
    seen_moving = seen_startable = False
    rng = np.random.default_rng(0)
    for _ in range(120):
        agent_masks = env.parallel_env.action_masks()
        mask = env.action_masks()
        assert mask.shape == (env.action_space.n,) and mask.dtype == bool and mask[0]
        for s, (agent, action) in enumerate(env.layout.starts, start=1):
            static = infos[agent]["static"]
            seen_moving |= not static
            seen_startable |= bool(static and agent_masks[agent][action])
            assert mask[s] == (static and bool(agent_masks[agent][action]))
        _, _, _, _, infos = env.step(rng.choice(np.flatnonzero(mask)))
    assert seen_moving and seen_startable  # the walk met moving robots and static ones free to start


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
        actions = teacher.act(observations, infos)
        team = one_start.layout.team_actions({a: np.array([v]) for a, v in actions.items()}, [infos])
        assert team.shape == (1,) and one_start.action_masks()[team[0]]
        starts += int(team[0] != 0)
        observations, rewards, terminations, truncations, infos = per_agent.step(actions)
        team_obs, reward, terminated, truncated, _ = one_start.step(team[0])
        assert np.array_equal(team_obs, one_start.layout.observation(observations))
        assert reward == float(rewards[per_agent.possible_agents[0]])
        assert terminated == any(terminations.values()) and truncated == any(truncations.values())
    assert starts > 0 and terminated  # robots were started, and every goal reached
    assert teacher.stalls == 0  # a stop of a stalled mobile robot has no one-start action: none here


def test_two_starts_in_one_step_cannot_be_encoded_and_the_error_names_them():
    layout = one_start_env().layout
    agents = layout.agents
    infos = infos_of(layout, [[True, True, False, True]] * 2)  # ugv_2 drives a leg in both copies
    # copy 0: ugv_1 starts a 1 m leg, ugv_2 advances on its leg; copy 1: two robots start
    actions = {agents[0]: np.array([0, 3]), agents[1]: np.array([2, 0]), agents[2]: np.array([1, 1]), agents[3]: np.array([0, 4])}
    with pytest.raises(ValueError, match=rf"copy 1: agents \['{agents[0]}', '{agents[3]}'\] start in the same step"):
        layout.team_actions(actions, infos)
    actions[agents[3]] = np.array([0, 0])
    encoded = layout.team_actions(actions, infos)
    assert [layout.starts[i - 1] for i in encoded] == [(agents[1], 2), (agents[0], 3)]
    # A mobile robot's stop is not a start: it is left out.
    actions[agents[2]] = np.array([0, 0])
    assert np.array_equal(layout.team_actions(actions, infos), encoded)


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
    layout = one_start_env().layout
    with pytest.raises(ValueError, match=message):
        layout.batch_actions(bad, infos_of(layout, [[True] * 4] * len(bad)))


def test_the_one_start_action_needs_the_copies_infos():
    layout = one_start_env().layout
    with pytest.raises(ValueError, match="give the copies' latest infos"):
        layout.batch_actions(np.array([0, 1]))
    with pytest.raises(ValueError, match="reads infos\\[agent\\]\\['static'\\]"):
        layout.batch_actions(np.array([0]), [{"ugv_0": {}}])
    with pytest.raises(ValueError, match="infos of 1 copies for 2 team actions"):
        layout.batch_actions(np.array([0, 1]), infos_of(layout, [[True] * 4]))


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


@pytest.mark.parametrize("workers", [None, 2])  # copy 1 in this process, or in the second worker
def test_a_copy_reset_alone_is_read_in_its_new_episode(workers):
    envs = TeamVectorEnv(TASK, 2, workers=workers, **task_options(TASK, team_action="one_start")[1])
    with pytest.raises(RuntimeError, match="reset\\(\\) before reset_at"):
        envs.reset_at(0)
    envs.reset(seed=3)
    singles = [one_start_env() for _ in range(2)]
    singles[0].reset(seed=3)
    rng = np.random.default_rng(2)
    for _ in range(15):  # copy 1's robots start moving, so its new episode's infos differ
        actions = np.array([rng.choice(np.flatnonzero(m)) for m in envs.action_masks()])
        envs.step(actions)
        singles[0].step(actions[0])
    obs, info = envs.reset_at(1, seed=41)
    single_obs, single_info = singles[1].reset(seed=41)
    assert np.array_equal(obs, single_obs) and obs.dtype == np.float32
    assert info.keys() == single_info.keys()
    for _ in range(25):
        masks = envs.action_masks()
        assert np.array_equal(masks, np.stack([s.action_masks() for s in singles]))
        actions = np.array([rng.choice(np.flatnonzero(m)) for m in masks])
        observations, rewards, *_ = envs.step(actions)
        for i, single in enumerate(singles):
            single_obs, reward, *_ = single.step(actions[i])
            assert np.array_equal(observations[i], single_obs) and rewards[i] == reward
    with pytest.raises(IndexError, match=r"copy index must be an integer in \[0, 2\), got 2"):
        envs.reset_at(2)
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
        checkpoint_every=10**6, max_cycles=60, eval_every=1, eval_episodes=1, eval_max_cycles=20,
    )
    assert config.env_options["team_action"] == "one_start"
    assert "team_action" not in TrainConfig(scenario=TASK, algo="maskable_ppo", route="centralised").env_options
    manifest = train(config, tmp_path / "run")
    assert manifest["config"]["team_action"] == "one_start"
    # The evaluation during training (of the clone, eval_every=1) ran on one-start envs.
    assert len(json.loads((tmp_path / "run" / "evaluations.json").read_text())["records"]) == 1
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
