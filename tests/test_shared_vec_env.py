"""The shared-policy VecEnv adapter over the PettingZoo parallel env (training/train/shared_vec_env.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecFrameStack, VecMonitor

from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from moma_env.vector import MomaVectorEnv
from training.fingerprint import serialise
from training.train.models import training_logger
from training.train.shared_vec_env import SharedPolicyVecEnv, TeamVecEnv
from training.train.team_slots import EnvSpec

SPEC = EnvSpec("top_observer", {"max_cycles": 12, "random_scenarios": True, "observer_agent": False})


def _rollout(venv: SharedPolicyVecEnv, seed: int, steps: int) -> list:
    """Seed, reset, then ``steps`` steps of seeded random actions; everything returned."""
    venv.seed(seed)
    record = [venv.reset().copy()]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, rewards, dones, infos = venv.step(rng.integers(0, 2, size=venv.num_envs))
        record += [obs.copy(), rewards.copy(), dones.copy()]
    return record


def _same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


def test_slots_are_the_ugvs_of_every_copy():
    venv = SharedPolicyVecEnv(SPEC, 3)
    try:
        assert venv.agents == ["ugv_0", "ugv_1"] and venv.num_envs == 6
        assert venv.observation_space.shape == (30,) and venv.action_space == spaces.Discrete(2)
        obs = venv.reset()
        assert obs.shape == (6, 30) and obs.dtype == np.float32
        assert len(venv.reset_infos) == 6 and all("status" in info for info in venv.reset_infos)
        assert venv.get_attr("max_cycles") == [12] * 6
        assert venv.env_method("state", indices=[2])[0].dtype == np.float32
    finally:
        venv.close()


def test_same_seed_same_first_rollout_and_another_seed_another():
    a, b = SharedPolicyVecEnv(SPEC, 2), SharedPolicyVecEnv(SPEC, 2)
    try:
        first = _rollout(a, 5, 30)  # 30 steps over 12-step episodes: two auto-resets on new random layouts
        assert _same(first, _rollout(b, 5, 30))
        other = _rollout(b, 6, 30)
        assert not np.array_equal(first[0], other[0])
    finally:
        a.close()
        b.close()


#: The two ways of running copies in worker processes: one per copy, or the batch split in two.
REMOTE = [{"subproc": True}, {"workers": 2}]


@pytest.mark.parametrize("remote_kind", REMOTE)
def test_worker_processes_give_the_same_rollout_as_in_process(remote_kind):
    local, remote = SharedPolicyVecEnv(SPEC, 2), SharedPolicyVecEnv(SPEC, 2, **remote_kind)
    try:
        assert _same(_rollout(local, 11, 15), _rollout(remote, 11, 15))
        assert remote.get_attr("max_cycles", indices=[3]) == [12]
        assert np.array_equal(remote.env_method("action_masks", indices=[0, 3]), local.env_method("action_masks", indices=[0, 3]))
    finally:
        local.close()
        remote.close()


def _text(value) -> str:
    out: list[str] = []
    serialise(value, out)
    return "|".join(out)


@pytest.mark.parametrize("remote_kind", REMOTE)
@pytest.mark.parametrize("mode", ["switching", "velocity"])
def test_the_in_process_engine_is_the_vector_env_and_gives_the_workers_slots_infos_included(mode, remote_kind):
    spec = EnvSpec("caterpillar_multi", {"max_cycles": 9, "random_scenarios": True, "action_mode": mode})
    local, remote = SharedPolicyVecEnv(spec, 2), SharedPolicyVecEnv(spec, 2, **remote_kind)
    try:
        assert isinstance(local.engine.vector, MomaVectorEnv) and local.engine.vector.num_envs == 2
        records = []
        for venv in (local, remote):
            venv.seed(3)
            record = [venv.reset(), venv.reset_infos]
            rng = np.random.default_rng(2)
            for _ in range(20):  # two auto-resets per copy
                if mode == "switching":
                    actions = rng.integers(0, venv.action_space.n, venv.num_envs)
                else:
                    actions = rng.uniform(-1, 1, (venv.num_envs, *venv.action_space.shape)).astype(np.float32)
                record.append(venv.step(actions))
            records.append(record)
        ends = [info for _, _, dones, infos in records[0][2:] for info in infos if "episode" in info]
        assert len(ends) == 2 * 6 and all(info["episode"]["l"] == 9 for info in ends)
        assert all(info["episode"]["t"] > 0 for info in ends)
        assert _text(records[0]) == _text(records[1])  # terminal observations, episode statistics and all
    finally:
        local.close()
        remote.close()


def test_copy_k_resets_with_its_first_slots_seed():
    spec = EnvSpec("top_observer", {"max_cycles": 12})
    venv = SharedPolicyVecEnv(spec, 3)
    try:
        venv.seed(20)
        obs = venv.reset()
        for k in range(3):
            single, _ = parallel_env("top_observer", max_cycles=12).reset(seed=20 + 2 * k)
            np.testing.assert_array_equal(obs[2 * k : 2 * k + 2], np.stack([single["ugv_0"], single["ugv_1"]]))
        venv.set_options([{"a": 1}] * 2 + [None] * 4)  # one options dict per copy (the env reads none)
        assert venv.reset().shape == (6, *venv.observation_space.shape)
    finally:
        venv.close()


def test_a_bad_action_is_refused_naming_the_robot_and_a_worker_error_comes_back_with_its_traceback():
    remote = SharedPolicyVecEnv(SPEC, 2, subproc=True)
    try:
        remote.reset()
        with pytest.raises(ValueError, match=r"actions of 'ugv_1' must be an array of shape \(2,\) of integers in \[0, 2\).*copy 1 has 7"):
            remote.step(np.array([0, 0, 0, 7]))
        with pytest.raises(AttributeError, match="no_such_method") as raised:
            remote.env_method("no_such_method", indices=[3])
        assert any("worker 1 (copies 1..1)" in note for note in raised.value.__notes__)
    finally:
        remote.close()


def test_infos_and_episode_ends_follow_the_vecenv_contract():
    venv = SharedPolicyVecEnv(SPEC, 2)
    try:
        venv.seed(0)
        venv.reset()
        hold = np.zeros(venv.num_envs, dtype=np.int64)
        for step in range(1, 13):
            obs, rewards, dones, infos = venv.step(hold)
            assert isinstance(infos, list) and len(infos) == 4 and all(type(i) is dict for i in infos)
            assert rewards.dtype == np.float32 and rewards.shape == (4,) and dones.dtype == bool
            assert rewards[0] == rewards[1] and rewards[2] == rewards[3]  # the team reward, per copy
            if step < 12:
                assert not dones.any() and not any("terminal_observation" in i for i in infos)
        assert dones.all()  # max_cycles reached: truncated, auto-reset
        for k, info in enumerate(infos):
            assert info["TimeLimit.truncated"] is True
            assert info["terminal_observation"].shape == (30,)
            assert info["episode"]["l"] == 12 and info["episode"]["r"] == pytest.approx(12 * float(rewards[k]), abs=1.0)
            assert not np.array_equal(info["terminal_observation"], obs[k])  # obs is the next episode's first
        obs, _, dones, infos = venv.step(hold)
        assert not dones.any() and "terminal_observation" not in infos[0]
    finally:
        venv.close()


@pytest.mark.parametrize("vec_env", [SharedPolicyVecEnv, TeamVecEnv])
def test_sb3s_vec_wrappers_take_the_adapters(vec_env):
    """VecMonitor reads ``venv.spec.id`` when ``venv.spec`` is set, as a Gymnasium EnvSpec: the
    adapters keep how a copy is built as ``env_spec``. VecFrameStack stacks the terminal observations."""
    venv = vec_env(SPEC, 2)
    assert venv.env_spec is SPEC and getattr(venv, "spec", None) is None
    wrapped = VecFrameStack(VecMonitor(venv), 2)
    try:
        obs = wrapped.reset()
        assert obs.shape == (venv.num_envs, 2 * venv.observation_space.shape[0])
        hold = np.zeros((venv.num_envs, *venv.action_space.shape), dtype=np.int64)
        for _ in range(12):
            obs, rewards, dones, infos = wrapped.step(hold)
        assert dones.all() and all(info["episode"]["l"] == 12 for info in infos)
        assert infos[0]["terminal_observation"].shape == obs.shape[1:]
    finally:
        wrapped.close()


@pytest.mark.parametrize("workers", [None, 2])
def test_sb3s_render_tiles_each_slots_copy_frame(workers):
    venv = SharedPolicyVecEnv(EnvSpec("top_observer", {"render_mode": "rgb_array", "max_cycles": 5}), 3, workers=workers)
    try:
        venv.reset()
        venv.step(np.ones(venv.num_envs, dtype=np.int64))
        images = venv.get_images()
        assert len(images) == venv.num_envs == 6
        for slot, image in enumerate(images):  # slots 2k and 2k + 1 are copy k's two UGVs
            np.testing.assert_array_equal(image, venv.engine.vector.render(slot // 2))
        assert not np.array_equal(images[0], images[2])  # another copy, another scene
        tiled = venv.render()  # SB3 tiles the six frames in a grid
        assert tiled.shape[0] * tiled.shape[1] == 6 * images[0].shape[0] * images[0].shape[1] and tiled.shape[2] == 3
    finally:
        venv.close()
    plain = SharedPolicyVecEnv(SPEC, 1)
    try:
        with pytest.warns(UserWarning, match="render_mode='rgb_array'"):
            assert plain.get_images() == [None, None]
    finally:
        plain.close()


def test_the_observer_agent_and_bad_sizes_are_refused():
    with pytest.raises(ValueError, match="observer_agent=False"):
        SharedPolicyVecEnv(EnvSpec("top_observer", {"action_mode": "velocity"}), 1)
    with pytest.raises(ValueError, match="n_copies"):
        SharedPolicyVecEnv(SPEC, 0)
    with pytest.raises(ConfigError, match="autoreset_mode: the Stable-Baselines3 VecEnv reads the SameStep autoreset"):
        SharedPolicyVecEnv(EnvSpec("top_observer", {"autoreset_mode": "Disabled"}), 1)
    venv = SharedPolicyVecEnv(SPEC, 1)
    try:
        venv.reset()
        with pytest.raises(ValueError, match="expected 2 actions"):
            venv.step(np.zeros(3, dtype=np.int64))
    finally:
        venv.close()


@pytest.fixture
def one_torch_thread():
    """Tiny networks: one thread is fastest and does not contend with other processes."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_ppo_with_a_seed_trains_reproducibly_on_the_adapter(one_torch_thread):
    def learn(seed: int) -> list:
        venv = SharedPolicyVecEnv(SPEC, 1)
        try:
            model = PPO("MlpPolicy", venv, seed=seed, n_steps=16, batch_size=16, n_epochs=1, device="cpu",
                        policy_kwargs={"net_arch": [8]})
            model.set_logger(training_logger(None))  # SB3's default would leave a folder in /tmp
            model.learn(64)
            assert model.num_timesteps == 64
            return [p.detach().clone() for p in model.policy.parameters()]
        finally:
            venv.close()

    first, again, other = learn(3), learn(3), learn(4)
    assert all(np.array_equal(a.numpy(), b.numpy()) for a, b in zip(first, again))
    assert not all(np.array_equal(a.numpy(), b.numpy()) for a, b in zip(first, other))


def test_subproc_and_workers_exclude_each_other():
    with pytest.raises(ValueError, match="exclude each other"):
        SharedPolicyVecEnv(SPEC, 2, subproc=True, workers=2)
