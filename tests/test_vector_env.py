"""The batched env (moma_env.vector): copy i of a batch seeded s is the single env seeded s + i."""

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from moma_env import vector
from moma_env.vector.env import FINAL_KEYS
from moma_env.env.factory import parallel_env
from serialised import text

CASES = [(name, mode) for name in ("top_observer", "caterpillar", "caterpillar_sled", "caterpillar_multi") for mode in ("switching", "velocity")]


def batch_actions(envs, steps, seed):
    rng = np.random.default_rng(seed)
    return [envs.sample_actions(rng) for _ in range(steps)]


@pytest.mark.parametrize("num_envs", [1, 7, 64])
@pytest.mark.parametrize("name,mode", CASES)
def test_copy_i_is_the_single_env_seeded_s_plus_i(name, mode, num_envs):
    assert_copies_are_single_envs(name, {"action_mode": mode}, num_envs, steps=30 if num_envs == 64 else 70)


@pytest.mark.parametrize("task", ["top_observer_team4", "caterpillar_multi_bend4", "top_observer_team4_legs"])
def test_a_tasks_copies_are_its_single_envs(task):
    """The coordination tasks (random layouts, masks, committed legs, their rewards) batch as
    the configurations do."""
    assert_copies_are_single_envs(task, {}, 7, steps=40)


def assert_copies_are_single_envs(name, options, num_envs, steps):
    """Copies 0, the middle one and the last of a batch seeded 11 are the single env seeded 11 + i,
    bit for bit, over ``steps`` steps of random actions (with the autoresets of 25-step episodes)."""
    mode = options.get("action_mode")
    envs = vector.make(name, num_envs, max_cycles=25, **options)
    observations, infos = envs.reset(seed=11)
    plan = batch_actions(envs, steps, seed=num_envs)
    record = [(observations, infos)]
    for joint in plan:
        record.append(envs.step(joint))
    for i in sorted({0, num_envs // 2, num_envs - 1}):
        single = parallel_env(name, max_cycles=25, **options)
        obs, info = single.reset(seed=11 + i)
        assert text({a: o[i] for a, o in record[0][0].items()}) == text(obs)
        assert text(record[0][1][i]) == text(info)
        for k, joint in enumerate(plan):
            obs, rew, term, trunc, info = single.step({a: joint[a][i] for a in single.agents})
            b_obs, b_rew, b_term, b_trunc, b_info = record[k + 1]
            assert all(b_rew[a][i] == rew[a] and b_term[a][i] == term[a] and b_trunc[a][i] == trunc[a] for a in rew)
            if not single.agents:  # the batch reset this copy in the same step
                assert text(b_info[i]["final_observation"]) == text(obs)
                assert b_info[i]["final_state"].tobytes() == single.state().tobytes()
                assert b_info[i]["final_time"] == single.frame.time
                if mode != "velocity":
                    assert text(b_info[i]["final_action_masks"]) == text(single.action_masks())
                assert text({a: v for a, v in b_info[i]["final_info"].items()}) == text(info)
                obs, info = single.reset()
            assert text({a: o[i] for a, o in b_obs.items()}) == text(obs), (i, k)


def test_shapes_masks_state_and_reset_at():
    envs = vector.make("caterpillar_sled", 5, max_cycles=20)
    observations, infos = envs.reset(seed=0)
    for agent in envs.agents:
        assert observations[agent].shape == (5, *envs.single_observation_space(agent).shape)
    masks = envs.action_masks()
    assert masks["ugv_0"].shape == (5, envs.single_action_space("ugv_0").n) and masks["ugv_0"].dtype == np.int8
    assert envs.state().shape == (5, envs.envs[0].state_space.shape[0])
    obs, info = envs.reset_at(3, seed=9)
    single = parallel_env("caterpillar_sled", max_cycles=20)
    assert text(obs) == text(single.reset(seed=9)[0])
    with pytest.raises(IndexError, match=r"copy index must be an integer in \[0, 5\)"):
        envs.reset_at(5)


def test_bad_batched_actions_name_the_agent_and_the_shape():
    envs = vector.make("top_observer", 3)
    with pytest.raises(RuntimeError, match="reset"):
        envs.step({})
    envs.reset(seed=0)
    good = {"ugv_0": np.zeros(3, dtype=int), "ugv_1": np.zeros(3, dtype=int)}
    envs.step(good)
    with pytest.raises(ValueError, match=r"actions of 'ugv_0' must be an array of shape \(3,\)"):
        envs.step(good | {"ugv_0": np.zeros(4, dtype=int)})
    with pytest.raises(ValueError, match=r"actions of 'ugv_1' .* copy 2 has 2"):
        envs.step(good | {"ugv_1": np.array([0, 1, 2])})
    with pytest.raises(ValueError, match="got dtype float64"):
        envs.step(good | {"ugv_1": np.array([0.0, 1.0, 1.0])})
    with pytest.raises(KeyError, match="no action for agent 'ugv_1'"):
        envs.step({"ugv_0": good["ugv_0"]})
    velocity = vector.make("top_observer", 2, action_mode="velocity")
    velocity.reset(seed=0)
    ok = {a: np.zeros((2, 4), dtype=np.float32) for a in velocity.agents}
    nan = np.zeros((2, 4))
    nan[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"actions of 'observer' .*shape \(2, 4\).*copy 1 is not finite"):
        velocity.step(ok | {"observer": nan})
    with pytest.raises(ValueError, match="num_envs must be an integer >= 1"):
        vector.make("top_observer", 0)
    # a Box agent's actions: the dtype's error names the agent, the shape and the dtype
    with pytest.raises(ValueError, match=r"actions of 'ugv_1' must be an array of shape \(2, 4\) of finite real numbers.*got dtype <U1"):
        velocity.step(ok | {"ugv_1": np.full((2, 4), "x")})
    with pytest.raises(ValueError, match=r"actions of 'ugv_0' must be an array of shape \(2, 4\) .*got dtype bool"):
        velocity.step(ok | {"ugv_0": np.zeros((2, 4), dtype=bool)})
    velocity.step(ok | {"ugv_0": np.zeros((2, 4), dtype=np.int64)})  # integers are real numbers


@pytest.mark.parametrize("workers", [None, 2])
def test_render_index_is_that_copys_frame(workers):
    """``render(index)`` is copy ``index``'s own ``render()``; an index that names no copy is refused."""
    envs = vector.make("top_observer", 3, render_mode="rgb_array", max_cycles=20, workers=workers)
    try:
        envs.reset(seed=4)
        actions = envs.sample_actions(np.random.default_rng(0))
        envs.step(actions)
        frames = [envs.render(i) for i in range(3)]
        np.testing.assert_array_equal(envs.render(), frames[0])
        single = parallel_env("top_observer", render_mode="rgb_array", max_cycles=20)
        single.reset(seed=4 + 2)
        single.step({a: actions[a][2] for a in single.agents})
        np.testing.assert_array_equal(frames[2], single.render())
        assert frames[2].dtype == np.uint8 and frames[2].ndim == 3
        assert not np.array_equal(frames[0], frames[2])  # copies 0 and 2 lay out different scenarios
        for bad in (3, -1, 1.0, True):
            with pytest.raises(IndexError, match=r"copy index must be an integer in \[0, 3\)"):
                envs.render(bad)
    finally:
        envs.close()


@pytest.mark.parametrize("workers", [None, 2])
def test_next_step_autoreset_resets_a_copy_the_step_after_its_end_and_keeps_its_episodes(workers):
    k, steps, seed, cycles = 3, 40, 21, 9
    envs = vector.make("top_observer", k, max_cycles=cycles, autoreset_mode="NextStep", workers=workers)
    singles = [parallel_env("top_observer", max_cycles=cycles) for _ in range(k)]
    observations, infos = envs.reset(seed=seed)
    for i, single in enumerate(singles):
        assert text(single.reset(seed=seed + i)) == text(({a: o[i] for a, o in observations.items()}, infos[i]))
    envs.reset_at(1, seed=99)  # copy 1's episodes end three steps after the others'
    singles[1].reset(seed=99)
    plan = batch_actions(envs, steps, seed=4)
    resets = 0
    for t, joint in enumerate(plan):
        if t == 2:
            envs.reset_at(1, seed=99)
            singles[1].reset(seed=99)
        b_obs, b_rew, b_term, b_trunc, b_info = envs.step(joint)
        for i, single in enumerate(singles):
            if not single.agents:  # ended in the last step: this step resets it, its actions ignored
                obs, info = single.reset()
                rew = term = trunc = dict.fromkeys(single.possible_agents, 0)
                resets += 1
            else:
                obs, rew, term, trunc, info = single.step({a: joint[a][i] for a in single.agents})
                assert not any(key in b_info[i] for key in FINAL_KEYS)
            assert text(({a: o[i] for a, o in b_obs.items()}, b_info[i])) == text((obs, info)), (t, i)
            assert all(b_rew[a][i] == rew[a] and b_term[a][i] == term[a] and b_trunc[a][i] == trunc[a] for a in single.possible_agents)
    assert resets >= 2 * k
    envs.close()


@pytest.mark.parametrize("workers", [None, 2])
def test_disabled_autoreset_refuses_a_step_until_the_finished_copies_are_reset(workers):
    envs = vector.make("top_observer", 3, max_cycles=4, autoreset_mode=AutoresetMode.DISABLED, workers=workers)
    assert envs.autoreset_mode is AutoresetMode.DISABLED
    envs.reset(seed=0)
    joint = {a: np.ones(3, dtype=np.int64) for a in envs.agents}
    envs.step(joint)
    envs.reset_at(0)  # copies 0 and 1 end one step after copy 2 (the worker's, with two workers)
    envs.reset_at(1)
    for _ in range(3):
        envs.step(joint)
    with pytest.raises(RuntimeError, match=r"copies \[2\] ended their episodes and autoreset_mode is DISABLED"):
        envs.step(joint)
    envs.reset_at(2)
    _, _, _, truncations, infos = envs.step(joint)
    np.testing.assert_array_equal(truncations["ugv_0"], [True, True, False])
    assert not any(key in info for info in infos for key in FINAL_KEYS)
    with pytest.raises(RuntimeError, match=r"copies \[0, 1\]"):
        envs.step(joint)
    envs.reset()
    envs.step(joint)
    envs.close()


DICT_OBSERVATIONS = {"action_mode": "velocity", "camera_backend": "rendered", "observer_image": (16, 12)}  # the observer's: a Dict


@pytest.mark.parametrize("workers, options", [(None, {}), (2, {}), (None, DICT_OBSERVATIONS)])
def test_a_partial_reset_resets_the_masked_copies_with_their_seeds_and_keeps_the_others(workers, options):
    envs = vector.make("top_observer", 3, random_scenarios=True, workers=workers, **options)
    with pytest.raises(RuntimeError, match="call reset"):
        envs.reset(options={"reset_mask": np.array([True, False, False])})
    envs.reset(seed=0)
    before, _, _, _, _ = envs.step(envs.sample_actions(np.random.default_rng(0)))
    kept = text(before)
    observations, infos = envs.reset(seed=50, options={"reset_mask": np.array([False, True, True])})
    assert text(before) == kept  # what the batch returned before is not changed
    assert infos[0] == {} and all(infos[i] for i in (1, 2))
    for i in range(3):
        row = {a: ({k: v[i] for k, v in o.items()} if isinstance(o, dict) else o[i]) for a, o in observations.items()}
        old = {a: ({k: v[i] for k, v in o.items()} if isinstance(o, dict) else o[i]) for a, o in before.items()}
        if i == 0:
            assert text(row) == text(old)
        else:  # as the single env reset with the seed copy i gets, 50 + i
            single = parallel_env("top_observer", random_scenarios=True, **options)
            obs, info = single.reset(seed=50 + i)
            assert text(row) == text(obs) and text(infos[i]) == text(info)
    with pytest.raises(ValueError, match=r"reset_mask'\] must be a numpy bool array of shape \(3,\)"):
        envs.reset(options={"reset_mask": [True, True, True]})
    envs.close()
