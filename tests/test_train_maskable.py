"""Masked PPO (sb3-contrib's MaskablePPO) on the switching task: the masks the VecEnvs
hand it, training on both routes, and a trained policy that acts only among the
actions the motion rules would grant.

Runs are tiny, as in tests/test_train.py: plumbing, not learning.
"""

from __future__ import annotations

import numpy as np
import pytest
from sb3_contrib import MaskablePPO
from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported
from stable_baselines3.common.callbacks import BaseCallback

from agents.learned import LearnedPolicy
from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from policy_guard import guarded
from training.train.config import TrainConfig
from training.train.envs import make_vec_env, wrap_normalisation
from training.train.evaluation import live_policy
from training.train.run import train
from training.train.shared_vec_env import SharedPolicyVecEnv
from training.train.team_slots import EnvSpec


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario="top_observer", algo="maskable_ppo", steps=256, envs=1, n_steps=32, batch_size=32, net_arch=(8,),
        max_cycles=40, checkpoint_every=10**6, eval_episodes=1, eval_max_cycles=20,
    )
    return TrainConfig(**(base | changes))


def _copy_masks(venv: SharedPolicyVecEnv) -> np.ndarray:
    """Every slot's mask read from the parallel env behind it (its ``action_mask``), in slot order."""
    rows = []
    for first in range(0, venv.num_envs, venv.n_agents):
        rows += [venv.env_method("action_mask", agent, indices=[first])[0] for agent in venv.agents]
    return np.array(rows, dtype=bool)


def test_shared_vec_env_gives_each_slot_its_robots_mask():
    venv = SharedPolicyVecEnv(EnvSpec("caterpillar_multi", {"random_scenarios": True, "max_cycles": 30}), n_copies=2)
    venv.seed(4)
    venv.reset()
    rng = np.random.default_rng(0)
    seen_refusal = False
    for _ in range(40):
        masks = venv.action_masks()
        assert masks.dtype == bool and masks.shape == (venv.num_envs, venv.action_space.n)
        np.testing.assert_array_equal(masks, _copy_masks(venv))
        # What MaskablePPO calls: env_method("action_masks"), one row per slot, also through VecNormalize.
        np.testing.assert_array_equal(get_action_masks(venv), masks)
        np.testing.assert_array_equal(np.stack(venv.env_method("action_masks", indices=[1, 4])), masks[[1, 4]])
        seen_refusal |= not masks.all()
        venv.step(rng.integers(0, venv.action_space.n, venv.num_envs))
    assert seen_refusal  # the rules refuse something in 40 random steps: the masks are not all ones
    assert is_masking_supported(venv) and is_masking_supported(wrap_normalisation(venv, tiny()))
    venv.close()


@pytest.mark.parametrize("remote_kind", [{"subproc": True}, {"workers": 2}])
def test_worker_processes_give_the_same_masks(remote_kind):
    spec = EnvSpec("top_observer", {"random_scenarios": True, "max_cycles": 30})
    local, remote = SharedPolicyVecEnv(spec, 2), SharedPolicyVecEnv(spec, 2, **remote_kind)
    try:
        for venv in (local, remote):
            venv.seed(7)
            venv.reset()
        rng = np.random.default_rng(1)
        for _ in range(15):
            np.testing.assert_array_equal(remote.action_masks(), local.action_masks())
            actions = rng.integers(0, local.action_space.n, local.num_envs)
            local.step(actions)
            remote.step(actions)
    finally:
        local.close()
        remote.close()


def test_velocity_slots_have_no_masks():
    venv = SharedPolicyVecEnv(EnvSpec("top_observer", {"action_mode": "velocity", "observer_agent": False}), n_copies=1)
    try:
        assert not venv.has_attr("action_masks") and not is_masking_supported(venv)
        with pytest.raises(ValueError, match="switching"):
            venv.action_masks()
    finally:
        venv.close()


def test_maskable_ppo_needs_the_switching_mode():
    with pytest.raises(ConfigError, match="algo.*switching"):
        tiny(action_mode="velocity")


class KeepModel(BaseCallback):
    def _on_step(self) -> bool:
        return True


def _masked_episode(policy, config: TrainConfig, seed: int, steps: int) -> tuple[list[dict], int]:
    """The policy's actions over one episode, and how many of them its masks forbade."""
    env = parallel_env(config.scenario, **(config.env_options | {"max_cycles": steps}))
    observations, infos = env.reset(seed=seed)
    policy.reset(env, seed=seed)
    actions_seen, forbidden = [], 0
    while env.agents:
        masks = {a: env.action_mask(a) for a in env.agents}
        actions = policy.act(observations, guarded(infos))
        forbidden += sum(int(masks[a][actions[a]] == 0) for a in actions)
        actions_seen.append({a: int(v) for a, v in actions.items()})
        observations, _, _, _, infos = env.step(actions)
    return actions_seen, forbidden


@pytest.mark.parametrize("route", ["shared", "centralised"])
def test_masked_run_reloads_and_acts_only_among_granted_actions(tmp_path, route):
    config = tiny(route=route)
    keep = KeepModel()
    manifest = train(config, tmp_path / "run", callbacks=[keep])
    assert manifest["sb3_class"] == "MaskablePPO" and isinstance(keep.model, MaskablePPO)
    loaded = LearnedPolicy.from_dir(tmp_path / "run", "top_observer")
    assert isinstance(loaded.model, MaskablePPO)
    live, n_live = _masked_episode(live_policy(keep.model, config), config, seed=3, steps=30)
    again, n_again = _masked_episode(loaded, config, seed=3, steps=30)
    assert len(live) == 30 and live == again and n_live == n_again == 0
    sampling = LearnedPolicy.from_dir(tmp_path / "run", "top_observer", deterministic=False)
    first, n_first = _masked_episode(sampling, config, seed=5, steps=30)
    second, _ = _masked_episode(sampling, config, seed=5, steps=30)
    assert first == second and n_first == 0


def test_masks_change_what_the_policy_does():
    # The same network without its masks chooses, at some step, an action the rules would refuse.
    config = tiny(route="shared")
    venv = wrap_normalisation(make_vec_env(config, seed=0), config)
    model = MaskablePPO("MlpPolicy", venv, seed=0, device="cpu", n_steps=32, batch_size=32, policy_kwargs={"net_arch": [8]})
    env = parallel_env("top_observer", **(config.env_options | {"max_cycles": 60}))
    observations, _ = env.reset(seed=2)
    rng = np.random.default_rng(3)
    unmasked_forbidden = 0
    while env.agents:
        agents = list(env.agents)
        batch = np.stack([observations[a] for a in agents])
        masks = np.stack([env.action_mask(a) for a in agents]).astype(bool)
        free, _ = model.predict(batch, deterministic=False)
        masked, _ = model.predict(batch, deterministic=False, action_masks=masks)
        unmasked_forbidden += int((~masks[np.arange(len(agents)), free]).sum())
        assert masks[np.arange(len(agents)), masked].all()
        observations, *_ = env.step({a: int(rng.integers(0, env.action_space(a).n)) for a in agents})
    assert unmasked_forbidden > 0
    venv.close()


def test_masked_training_is_reproducible(tmp_path):
    # Same settings, same weights bit for bit (the masks come from the seeded envs).
    import torch

    weights = []
    for name in ("a", "b"):
        keep = KeepModel()
        train(tiny(steps=128), tmp_path / name, callbacks=[keep])
        weights.append(keep.model.policy.state_dict())
    assert weights[0].keys() == weights[1].keys()
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])
    keep = KeepModel()
    train(tiny(steps=128, seed=1), tmp_path / "c", callbacks=[keep])
    assert not all(torch.equal(weights[0][k], keep.model.policy.state_dict()[k]) for k in weights[0])


def test_algorithm_classes_come_from_sb3_then_sb3_contrib():
    from stable_baselines3 import PPO

    from agents.learned import TrainingDirError, sb3_class
    from training.train.models import algorithm_class

    assert sb3_class("PPO") is PPO and sb3_class("MaskablePPO") is MaskablePPO
    assert algorithm_class("maskable_ppo") is MaskablePPO and algorithm_class("ppo") is PPO
    with pytest.raises(TrainingDirError, match="'NoSuchPPO'"):
        sb3_class("NoSuchPPO")
