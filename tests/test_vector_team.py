"""The centralised team as a Gymnasium VectorEnv (moma_env/vector/team.py): copy i of a
batch seeded s is gymnasium.make(id) seeded s + i, every output as Gymnasium's SyncVectorEnv
gives it in each autoreset mode (NEXT_STEP by default, as Gymnasium's), registered as every
id's vector_entry_point."""

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.vector.utils import batch_space
from gymnasium.wrappers.vector import DictInfoToList, NormalizeObservation, RecordEpisodeStatistics

from moma_env.config import ConfigError

from moma_env.registration import GYMNASIUM_IDS
from moma_env.scenarios import SCENARIO_SPECS
from moma_env.vector import TeamVectorEnv
from serialised import text

ID = {name: SCENARIO_SPECS[name].gymnasium_id for name in SCENARIO_SPECS}
#: (configuration, options): the MultiDiscrete and Box team actions, and a Box with discrete slots.
CASES = [
    ("top_observer", {"action_mode": "switching"}),
    ("top_observer", {"action_mode": "velocity"}),
    ("top_observer", {"action_mode": "switching", "observer_agent": True}),
    ("caterpillar_multi", {"action_mode": "switching", "random_scenarios": True}),
    ("caterpillar_sled", {"action_mode": "velocity"}),
]


def team_actions(space, steps: int, seed: int) -> list[np.ndarray]:
    space.seed(seed)
    return [space.sample() for _ in range(steps)]


@pytest.mark.parametrize("name, options", CASES)
def test_copy_i_is_gymnasium_make_seeded_s_plus_i_and_infos_are_sync_vector_envs(name, options):
    k, steps, seed = 3, 26, 7  # 26 steps of 12-step episodes: two autoresets per copy
    options = options | {"max_cycles": 12}
    envs = gymnasium.make_vec(ID[name], num_envs=k, autoreset_mode="SameStep", **options)
    assert isinstance(envs, TeamVectorEnv)
    reference = gymnasium.make_vec(ID[name], num_envs=k, vectorization_mode="sync", vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP}, **options)
    assert isinstance(reference, SyncVectorEnv)
    singles = [gymnasium.make(ID[name], **options) for _ in range(k)]
    assert envs.single_observation_space == singles[0].observation_space == reference.single_observation_space
    assert envs.single_action_space == singles[0].action_space
    assert envs.observation_space == batch_space(envs.single_observation_space, k) == reference.observation_space
    assert envs.action_space == reference.action_space

    record = [envs.reset(seed=seed)]
    assert text(record[0]) == text(reference.reset(seed=seed))
    plan = team_actions(envs.action_space, steps, seed)
    ends = 0
    for actions in plan:
        out = envs.step(actions)
        obs, rewards, terminated, truncated, infos = out
        assert obs.shape == (k, envs.single_observation_space.shape[0]) and obs.dtype == np.float32
        assert rewards.shape == terminated.shape == truncated.shape == (k,) and rewards.dtype == np.float64
        assert terminated.dtype == truncated.dtype == bool
        assert envs.observation_space.contains(obs)
        assert text(out) == text(reference.step(actions))  # infos included, key by key
        ends += int(np.sum(terminated | truncated))
        record.append(out)
    assert ends >= 2 * k
    for i in range(k):
        obs, info = singles[i].reset(seed=seed + i)
        assert text(obs) == text(record[0][0][i])
        for t, actions in enumerate(plan):
            obs, reward, term, trunc, info = singles[i].step(actions[i])
            b_obs, b_rew, b_term, b_trunc, b_info = record[t + 1]
            assert (b_rew[i], b_term[i], b_trunc[i]) == (reward, term, trunc)
            if term or trunc:
                assert b_info["_final_obs"][i] and text(b_info["final_obs"][i]) == text(obs)
                assert b_info["_final_info"][i]
                obs, info = singles[i].reset()
            else:
                assert "_final_obs" not in b_info or not b_info["_final_obs"][i]
            assert text(b_obs[i]) == text(obs), (i, t)
    envs.close()
    reference.close()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.DISABLED])
@pytest.mark.parametrize("name, options, workers", [
    ("top_observer", {"action_mode": "switching"}, None),
    ("caterpillar_sled", {"action_mode": "velocity"}, None),
    ("top_observer", {"action_mode": "switching"}, 2),
])
def test_the_other_autoreset_modes_are_sync_vector_envs_step_for_step(mode, name, options, workers):
    k, steps, seed = 3, 30, 11  # episodes of 7 to 9 steps: several ends per copy
    options = options | {"max_cycles": 7}
    envs = gymnasium.make_vec(ID[name], num_envs=k, autoreset_mode=mode.value, workers=workers, **options)
    reference = gymnasium.make_vec(ID[name], num_envs=k, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **options)
    assert envs.metadata["autoreset_mode"] is mode is reference.metadata["autoreset_mode"]
    assert text(envs.reset(seed=seed)) == text(reference.reset(seed=seed))
    ends = partial = 0
    for t, actions in enumerate(team_actions(envs.action_space, steps, seed)):
        out = envs.step(actions)
        assert text(out) == text(reference.step(actions)), t
        ended = out[2] | out[3]
        ends += int(ended.sum())
        if mode is AutoresetMode.DISABLED and ended.any():
            with pytest.raises(RuntimeError, match=rf"copies \[{np.flatnonzero(ended)[0]}.*autoreset_mode is DISABLED"):
                envs.step(actions)
            first = t + 100 * partial  # a seeded partial reset, then one continuing its generators
            seeds = first if partial % 2 == 0 else None
            partial += 1
            ours = envs.reset(seed=seeds, options={"reset_mask": ended})
            assert text(ours) == text(reference.reset(seed=seeds, options={"reset_mask": ended.copy()}))
    assert ends >= 2 * k
    assert partial >= 2 or mode is not AutoresetMode.DISABLED
    envs.close()
    reference.close()


@pytest.mark.parametrize("mode", list(AutoresetMode))
def test_partial_resets_at_random_steps_are_sync_vector_envs_in_every_mode(mode):
    """Partial resets between steps, of copies that ended and of copies that did not (clearing a
    NEXT_STEP reset due), seeded or continuing: every return as SyncVectorEnv's."""
    k, rng = 3, np.random.default_rng(len(mode.value))
    envs = gymnasium.make_vec(ID["top_observer"], num_envs=k, autoreset_mode=mode, max_cycles=5)
    reference = gymnasium.make_vec(
        ID["top_observer"], num_envs=k, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, max_cycles=5
    )
    assert text(envs.reset(seed=2)) == text(reference.reset(seed=2))
    ended, partial = np.zeros(k, dtype=bool), 0
    for t in range(30):
        if rng.random() < 0.25 or (mode is AutoresetMode.DISABLED and ended.any()):
            mask = (rng.random(k) < 0.5) | (ended if mode is AutoresetMode.DISABLED else False)
            mask[int(rng.integers(k))] = True
            seed = None if partial % 2 else int(rng.integers(1000))
            partial += 1
            ours = envs.reset(seed=seed, options={"reset_mask": mask.copy()})
            assert text(ours) == text(reference.reset(seed=seed, options={"reset_mask": mask.copy()}))
        actions = envs.action_space.sample()
        out = envs.step(actions)
        assert text(out) == text(reference.step(actions)), t
        ended = out[2] | out[3]
    assert partial >= 4
    envs.close()
    reference.close()


def test_a_partial_reset_is_checked_and_gymnasiums_observation_wrappers_take_next_step():
    envs = TeamVectorEnv("top_observer", 3, max_cycles=5)
    with pytest.raises(RuntimeError, match="call reset"):
        envs.reset(options={"reset_mask": np.array([True, False, False])})
    first, _ = envs.reset(seed=0)
    for bad, message in [([True, False, False], "numpy bool array of shape \\(3,\\), got list"),
                         (np.array([1, 0, 0]), "got ndarray int64"), (np.zeros(3, dtype=bool), "at least one copy"),
                         (np.ones(2, dtype=bool), r"shape \(3,\), got ndarray bool \(2,\)")]:
        with pytest.raises(ValueError, match=message):
            envs.reset(options={"reset_mask": bad})
    kept = first.copy()
    observations, infos = envs.reset(seed=40, options={"reset_mask": np.array([False, True, False])})
    np.testing.assert_array_equal(first, kept)  # the array returned before is not changed
    np.testing.assert_array_equal(observations[[0, 2]], first[[0, 2]])
    np.testing.assert_array_equal(observations[1], gymnasium.make(ID["top_observer"], max_cycles=5).reset(seed=41)[0])
    np.testing.assert_array_equal(infos["_ugv_0"], [False, True, False])
    with pytest.raises(ConfigError, match="autoreset_mode: must be a gymnasium.vector.AutoresetMode or one of"):
        TeamVectorEnv("top_observer", 2, autoreset_mode="Sometimes")
    # Gymnasium's own check: a bare assert up to 1.2, a ValueError naming the modes since 1.3
    with pytest.raises((AssertionError, ValueError)) as refused:
        NormalizeObservation(TeamVectorEnv("top_observer", 2, autoreset_mode=AutoresetMode.SAME_STEP))
    assert refused.type is AssertionError or "NEXT_STEP or DISABLED" in str(refused.value)
    normalised = NormalizeObservation(gymnasium.make_vec(ID["top_observer"], num_envs=2, max_cycles=5))  # the default
    normalised.reset(seed=0)
    for _ in range(12):
        observations, *_ = normalised.step(np.ones((2, 2), dtype=np.int64))
    assert observations.shape == (2, 60) and np.isfinite(observations).all()


def test_every_id_has_the_vector_entry_point_and_the_other_modes_still_work():
    for env_id, name in GYMNASIUM_IDS.items():
        assert gymnasium.spec(env_id).vector_entry_point == "moma_env.vector.team:TeamVectorEnv"
        envs = gymnasium.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", max_cycles=5)
        assert isinstance(envs, TeamVectorEnv) and envs.num_envs == 2 and envs.vector.envs[0].scenario.name == name
        # Gymnasium's own default, what vectorization_mode="sync" gives for the same id
        assert envs.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
        assert envs.spec is not None and envs.spec.id == env_id
        envs.close()
    for mode in ("sync", "async"):
        envs = gymnasium.make_vec(ID["top_observer"], num_envs=2, vectorization_mode=mode, max_cycles=5)
        assert envs.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
        try:
            obs, _ = envs.reset(seed=0)
            assert obs.shape == (2, 60)
            envs.step(envs.action_space.sample())
        finally:
            envs.close()
    single = gymnasium.make(ID["caterpillar"], max_cycles=5)
    assert single.reset(seed=0)[0].shape == single.observation_space.shape
    # the batched env's own keywords, handed to every copy by Gymnasium's own vector envs, say what to use instead
    with pytest.raises(ConfigError, match=r"autoreset_mode: is an option of the batched env .* pass vector_kwargs=\{'autoreset_mode'"):
        gymnasium.make_vec(ID["top_observer"], num_envs=2, vectorization_mode="sync", autoreset_mode="SameStep")
    with pytest.raises(ConfigError, match=r"workers: .* use vectorization_mode='async'"):
        gymnasium.make_vec(ID["top_observer"], num_envs=2, vectorization_mode="sync", workers=2)
    synced = gymnasium.make_vec(ID["top_observer"], num_envs=2, vectorization_mode="sync", vector_kwargs={"autoreset_mode": "SameStep"})
    assert synced.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    synced.close()


def test_gymnasiums_vector_wrappers_read_the_same_step_autoreset():
    envs = RecordEpisodeStatistics(TeamVectorEnv("top_observer", 2, max_cycles=6, autoreset_mode="SameStep"))
    envs.reset(seed=1)
    returns = np.zeros(2)
    for t in range(6):
        _, rewards, terminated, truncated, infos = envs.step(np.ones((2, 2), dtype=np.int64))
        returns += rewards
    assert truncated.all() and not terminated.any()
    np.testing.assert_array_equal(infos["_episode"], [True, True])
    np.testing.assert_array_equal(infos["episode"]["l"], [6, 6])
    np.testing.assert_allclose(infos["episode"]["r"], returns, rtol=1e-6)
    listed = DictInfoToList(TeamVectorEnv("caterpillar", 2, max_cycles=3, autoreset_mode="SameStep"))
    _, infos = listed.reset(seed=0)
    assert isinstance(infos, list) and len(infos) == 2 and set(infos[0]) == {"ugv_0", "ugv_1"}
    for _ in range(3):
        _, _, _, truncated, infos = listed.step(np.zeros((2, 2), dtype=np.int64))
    assert truncated.all() and infos[1]["final_obs"].shape == listed.single_observation_space.shape


def test_action_masks_are_each_copys_centralised_masks():
    envs = TeamVectorEnv("caterpillar_multi", 3)
    envs.reset(seed=4)
    singles = [gymnasium.make(ID["caterpillar_multi"]).unwrapped for _ in range(3)]
    for i, single in enumerate(singles):
        single.reset(seed=4 + i)
    rng = np.random.default_rng(0)
    for _ in range(15):
        masks = envs.action_masks()
        assert masks.shape == (3, int(envs.single_action_space.nvec.sum())) and masks.dtype == bool
        np.testing.assert_array_equal(masks, np.stack([s.action_masks() for s in singles]))
        actions = rng.integers(0, 2, size=(3, 3))
        envs.step(actions)
        for i, single in enumerate(singles):
            single.step(actions[i])
    with pytest.raises(ValueError, match="MultiDiscrete"):
        TeamVectorEnv("top_observer", 2, action_mode="velocity").action_masks()


def test_bad_actions_and_resets_are_refused_naming_the_agent():
    envs = TeamVectorEnv("top_observer", 3)
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.zeros((3, 2), dtype=np.int64))
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"team actions must have shape \(num_envs, 2\).*got \(3,\)"):
        envs.step(np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match=r"got \(3, 3\)"):
        envs.step(np.zeros((3, 3), dtype=np.int64))
    with pytest.raises(ValueError, match=r"column 1 \(agent 'ugv_1'\) must be an integer in \[0, 2\); copy 2 has 2"):
        envs.step(np.array([[0, 0], [1, 1], [0, 2]]))
    with pytest.raises(ValueError, match="must be integers, got dtype float64"):
        envs.step(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"num_envs=3 seeds, got 2"):
        envs.reset(seed=[1, 2])
    mixed = TeamVectorEnv("top_observer", 2, observer_agent=True)  # Box: UGV slots decoded by rounding
    mixed.reset(seed=0)
    nan = np.zeros((2, 6), dtype=np.float32)
    nan[1, 1] = np.nan
    with pytest.raises(ValueError, match=r"slot 1 \(agent 'ugv_1', Discrete\(2\)\) must be finite; copy 1"):
        mixed.step(nan)
    nan = np.zeros((2, 6), dtype=np.float32)
    nan[0, 4] = np.nan
    with pytest.raises(ValueError, match=r"actions of 'observer' .*copy 0 is not finite"):
        mixed.step(nan)
    with pytest.raises(ValueError, match="num_envs must be an integer >= 1"):
        TeamVectorEnv("top_observer", 0)
    with pytest.raises(ValueError, match="observer_image"):
        TeamVectorEnv("top_observer", 1, action_mode="velocity", camera_backend="rendered", observer_image=(32, 24))


def test_box_team_actions_round_into_the_discrete_agents_range():
    layout = TeamVectorEnv("top_observer", 1, observer_agent=True).layout
    column = np.array([-5.0, -1.0, -0.01, 0.0, 0.99, 1.0, 7.0], dtype=np.float32)
    actions = np.zeros((column.size, 6), dtype=np.float32)
    actions[:, 0] = column
    decoded = layout.batch_actions(actions)
    np.testing.assert_array_equal(decoded["ugv_0"], [0, 0, 0, 1, 1, 1, 1])
    assert decoded["observer"].shape == (column.size, 4)
    for row, expected in zip(actions, decoded["ugv_0"]):  # one copy's decoding is the batch's
        assert layout.agent_actions(row)["ugv_0"] == expected
