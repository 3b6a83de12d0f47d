"""The centralised route's VecEnv (training/train/shared_vec_env.py: TeamVecEnv) against the
centralised team env in SB3's DummyVecEnv, the route's envs before it."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.wrappers import TransformReward
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

from moma_env.env.factory import centralised_env
from training.train.shared_vec_env import TeamVecEnv
from training.train.team_slots import EnvSpec


def _reference(spec: EnvSpec, n_copies: int) -> DummyVecEnv:
    """K centralised team envs as the centralised route built them: rewards rounded to
    float32, Monitor, DummyVecEnv."""

    def one() -> Monitor:
        return Monitor(TransformReward(centralised_env(spec.configuration, **spec.options), lambda r: float(np.float32(r))))

    return DummyVecEnv([one for _ in range(n_copies)])


def _rollout(venv, seed: int, steps: int) -> list:
    """Seed, reset, ``steps`` steps of seeded random actions; every array and the end-of-episode infos."""
    venv.seed(seed)
    record = [venv.reset().copy()]
    rng = np.random.default_rng(seed)
    space = venv.action_space
    for _ in range(steps):
        if hasattr(space, "nvec"):
            actions = rng.integers(0, space.nvec, size=(venv.num_envs, len(space.nvec)))
        else:
            actions = rng.uniform(-1.0, 1.0, size=(venv.num_envs, *space.shape)).astype(np.float32)
        obs, rewards, dones, infos = venv.step(actions)
        record += [obs.copy(), rewards.copy(), dones.copy()]
        for info in infos:
            record.append(np.array([info["TimeLimit.truncated"]]))
            if "terminal_observation" in info:
                record.append(info["terminal_observation"].copy())
    return record


@pytest.mark.parametrize("options", [
    {"action_mode": "switching"},
    {"action_mode": "velocity"},
])
def test_team_slots_are_the_centralised_env_in_dummy_vec_env_bit_for_bit(options):
    spec = EnvSpec("top_observer", {"max_cycles": 12, "random_scenarios": True, "observer_agent": False, **options})
    ours, theirs = TeamVecEnv(spec, 3), _reference(spec, 3)
    try:
        assert ours.num_envs == 3 and ours.observation_space == theirs.observation_space and ours.action_space == theirs.action_space
        a, b = _rollout(ours, 7, 40), _rollout(theirs, 7, 40)  # 40 steps of 12-step episodes: three ends per copy
        dim = ours.observation_space.shape[0]
        assert len(a) == len(b) and sum(x.shape == (dim,) for x in a) == 3 * 3  # the terminal observations
        for x, y in zip(a, b):
            assert x.dtype == y.dtype and np.array_equal(x, y)
    finally:
        ours.close()
        theirs.close()


def test_team_slots_carry_the_copy_infos_and_episode_statistics():
    spec = EnvSpec("top_observer", {"max_cycles": 5, "random_scenarios": True, "observer_agent": False})
    venv = TeamVecEnv(spec, 2)
    try:
        venv.seed(3)
        obs = venv.reset()
        assert obs.shape == (2, venv.observation_space.shape[0]) and obs.dtype == np.float32
        assert set(venv.reset_infos[0]) == set(venv.agents)  # agent -> info, as the team env's
        masks = venv.action_masks()
        assert masks.shape == (2, int(venv.action_space.nvec.sum())) and masks.dtype == bool
        assert [m.tolist() for m in venv.env_method("action_masks")] == masks.tolist()
        assert venv.has_attr("action_masks") and venv.get_attr("max_cycles") == [5, 5]
        for step in range(5):
            _, rewards, dones, infos = venv.step(np.ones((2, len(venv.agents)), dtype=np.int64))
        assert rewards.dtype == np.float32 and dones.all()
        assert all(info["TimeLimit.truncated"] and info["episode"]["l"] == 5 and set(venv.agents) <= set(info) for info in infos)
        assert infos[0]["episode"]["t"] > 0.0 and infos[0]["terminal_observation"].shape == obs.shape[1:]
    finally:
        venv.close()


def test_team_slots_in_two_processes_are_the_same():
    spec = EnvSpec("top_observer", {"max_cycles": 12, "random_scenarios": True, "observer_agent": False})
    here, split = TeamVecEnv(spec, 4), TeamVecEnv(spec, 4, workers=2)
    try:
        a, b = _rollout(here, 11, 30), _rollout(split, 11, 30)
        assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    finally:
        here.close()
        split.close()
