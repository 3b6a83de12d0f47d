"""The sharded batch (moma_env.vector.make(..., workers=W)): the in-process batch's episodes,
bit for bit, with its copies stepped in worker processes; errors at the boundary and from
the workers."""

import numpy as np
import pytest

from moma_env import vector
from moma_env.vector.sharded import shard_sizes
from serialised import text


def copy_dt(env, scale):
    """A picklable function for call_at: the copy's control step times ``scale``."""
    return env.world.dt * scale


def failing(env):
    raise KeyError("no such thing in this copy")


def test_shard_sizes_are_contiguous_and_balanced():
    assert shard_sizes(7, 3) == [3, 2, 2]
    assert shard_sizes(64, 2) == [32, 32]
    assert shard_sizes(5, 5) == [1] * 5
    assert sum(shard_sizes(1024, 7)) == 1024


@pytest.mark.parametrize("name,mode,num_envs,workers", [("top_observer", "switching", 7, 3), ("caterpillar_multi", "velocity", 4, 2)])
def test_sharded_batch_is_the_in_process_batch(name, mode, num_envs, workers):
    local = vector.make(name, num_envs, action_mode=mode, max_cycles=20)
    sharded = vector.make(name, num_envs, workers=workers, action_mode=mode, max_cycles=20)
    try:
        assert isinstance(sharded, vector.ShardedVectorEnv) and sharded.workers == workers
        assert sharded.possible_agents == local.possible_agents and sharded.state_space == local.state_space
        assert text(sharded.reset(seed=5)) == text(local.reset(seed=5))
        rng = np.random.default_rng(1)
        for _ in range(45):  # past every copy's first episode: autoresets included
            actions = local.sample_actions(rng)
            assert text(sharded.step(actions)) == text(local.step(actions))
        assert sharded.state().tobytes() == local.state().tobytes()
        if mode == "switching":
            assert text(sharded.action_masks()) == text(local.action_masks())
        # a reset without a seed continues each copy's generator, in both
        assert text(sharded.reset()) == text(local.reset())
        assert text(sharded.reset_at(num_envs - 1, seed=99)) == text(local.reset_at(num_envs - 1, seed=99))
        actions = local.sample_actions(rng)
        assert text(sharded.step(actions)) == text(local.step(actions))
        assert sharded.call_at(num_envs - 1, copy_dt, 2.0) == local.call_at(num_envs - 1, copy_dt, 2.0)
    finally:
        sharded.close()
        local.close()


def test_bad_input_is_refused_before_the_workers_and_their_errors_come_back():
    envs = vector.make("top_observer", 3, workers=2, action_mode="switching", max_cycles=20)
    try:
        with pytest.raises(RuntimeError, match="reset"):
            envs.step({a: np.zeros(3, dtype=np.int64) for a in envs.agents})
        envs.reset(seed=0)
        with pytest.raises(ValueError, match=r"actions of 'ugv_0' must be an array of shape \(3,\)"):
            envs.step({a: np.zeros(2, dtype=np.int64) for a in envs.agents})
        with pytest.raises(ValueError, match=r"actions of 'ugv_1'.*got dtype float64"):
            envs.step({"ugv_0": np.zeros(3, dtype=np.int64), "ugv_1": np.zeros(3)})
        with pytest.raises(IndexError, match=r"copy index must be an integer in \[0, 3\), got 3"):
            envs.reset_at(3)
        with pytest.raises(ValueError, match="seed must be None or a non-negative integer"):
            envs.reset_at(0, seed=-1)
        with pytest.raises(ValueError, match="a sequence must hold num_envs=3 seeds"):
            envs.reset(seed=[1, 2])
        with pytest.raises(ValueError, match=r"options: a sequence must hold num_envs=3 entries \(one per copy\), got 2"):
            envs.reset(seed=0, options=[None, None])
        with pytest.raises(TypeError, match="options\\[1\\] must be None or a mapping, got int"):
            envs.reset(seed=0, options=[None, 1, None])
        # an error raised in a worker comes back with its own type and the worker named
        with pytest.raises(KeyError, match="no such thing") as raised:
            envs.call_at(2, failing)
        assert any("worker 1 (copies 2..2)" in note for note in raised.value.__notes__)
        # the workers still serve after an error
        observations, _ = envs.reset(seed=0)
        assert observations["ugv_0"].shape == (3, *envs.single_observation_space("ugv_0").shape)
    finally:
        envs.close()
    envs.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        envs.reset(seed=0)


def test_one_worker_is_this_process_alone_and_its_errors_say_so():
    import multiprocessing

    before = len(multiprocessing.active_children())
    envs = vector.make("top_observer", 2, workers=1, max_cycles=20)
    try:
        assert len(multiprocessing.active_children()) == before  # no worker process
        local = vector.make("top_observer", 2, max_cycles=20)
        assert text(envs.reset(seed=8)) == text(local.reset(seed=8))
        with pytest.raises(KeyError, match="no such thing") as raised:
            envs.call_at(1, failing)
        assert any("this process (copies 0..1)" in note for note in raised.value.__notes__)
    finally:
        envs.close()


def test_bad_workers_and_options_are_refused_without_starting_workers():
    with pytest.raises(ValueError, match="workers must be an integer >= 1, got 0"):
        vector.make("top_observer", 4, workers=0)
    with pytest.raises(ValueError, match="workers must be at most num_envs=2, got 3"):
        vector.make("top_observer", 2, workers=3)
    with pytest.raises(Exception, match="max_cycles"):
        vector.make("top_observer", 2, workers=2, max_cycles=-1)


def test_gymnasium_make_vec_with_workers_gives_the_same_batches():
    import gymnasium

    import moma_env  # noqa: F401 - registers the ids

    local = gymnasium.make_vec("moma_env/TopObserver-v0", num_envs=4, max_cycles=15)
    sharded = gymnasium.make_vec("moma_env/TopObserver-v0", num_envs=4, workers=2, max_cycles=15)
    try:
        assert isinstance(sharded.unwrapped.vector, vector.ShardedVectorEnv)
        assert text(sharded.reset(seed=3)) == text(local.reset(seed=3))
        local.action_space.seed(0)
        for _ in range(20):
            actions = local.action_space.sample()
            assert text(sharded.step(actions)) == text(local.step(actions))
        assert np.array_equal(sharded.unwrapped.action_masks(), local.unwrapped.action_masks())
    finally:
        sharded.close()
        local.close()


def test_torchrl_adapter_with_workers_passes_the_spec_check_and_rolls_out_the_same():
    pytest.importorskip("torchrl")
    import torch
    from torchrl.envs.utils import check_env_specs

    from moma_env.vector.torchrl import MomaTorchRLEnv

    local = MomaTorchRLEnv("top_observer", 3, seed=4, max_cycles=12)
    sharded = MomaTorchRLEnv("top_observer", 3, seed=4, workers=2, max_cycles=12)
    try:
        check_env_specs(sharded)
        rollouts = []
        for env in (local, sharded):
            env.set_seed(4)
            torch.manual_seed(0)  # the random actions of rollout()
            rollouts.append(env.rollout(30, break_when_any_done=False))
        assert bool(rollouts[0]["next", "done"].any())  # an episode ended inside the rollout
        assert bool((rollouts[0] == rollouts[1]).all())
    finally:
        sharded.close()
        local.close()


def interrupt_next_step(env):
    """For call_at on a copy in this process: its next step raises KeyboardInterrupt (Ctrl-C)."""

    def interrupted(actions):
        raise KeyboardInterrupt

    env.begin_step = interrupted


def restore_step(env):
    del env.begin_step


def test_a_call_interrupted_by_ctrl_c_leaves_no_stale_reply_behind():
    envs = vector.make("top_observer", 4, workers=2, max_cycles=20)
    local = vector.make("top_observer", 4, max_cycles=20)
    try:
        envs.reset(seed=1)
        envs.call_at(0, interrupt_next_step)  # copy 0 is stepped in this process
        with pytest.raises(KeyboardInterrupt):
            envs.step(envs.sample_actions(np.random.default_rng(0)))  # the worker's reply is left unread
        envs.call_at(0, restore_step)
        assert text(envs.reset(seed=2)) == text(local.reset(seed=2))
        actions = local.sample_actions(np.random.default_rng(1))
        assert text(envs.step(actions)) == text(local.step(actions))
    finally:
        envs.close()
        local.close()
