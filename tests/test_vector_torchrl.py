"""The batched env as a TorchRL EnvBase (moma_env/vector/torchrl.py): TorchRL's spec check,
its multi-agent grouping, copy i is the PettingZoo env seeded s + i, seeding, masks."""

import importlib.util
import subprocess
import sys

import numpy as np
import pytest

if importlib.util.find_spec("torchrl") is None:  # not importorskip: importing torchrl first would set the start method
    pytest.skip("needs the torchrl extra", allow_module_level=True)

from moma_env.vector.torchrl import MomaTorchRLEnv  # noqa: E402 - first: it keeps multiprocessing's start method

import torch  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

from moma_env.config import ConfigError  # noqa: E402
from moma_env.env.factory import parallel_env  # noqa: E402

CASES = [
    ("top_observer", {"action_mode": "switching"}, {"ugv": ["ugv_0", "ugv_1"]}),
    ("top_observer", {"action_mode": "velocity"}, {"ugv": ["ugv_0", "ugv_1"], "observer": ["observer"]}),
    ("caterpillar_multi", {"action_mode": "switching", "random_scenarios": True}, {"ugv": ["ugv_0", "ugv_1", "ugv_2"]}),
]


@pytest.mark.parametrize("name, options, groups", CASES)
def test_check_env_specs_and_the_groups(name, options, groups):
    env = MomaTorchRLEnv(name, 3, seed=0, max_cycles=2, **options)  # rollouts of 3 steps cross an episode's end
    assert env.group_map == groups and env.batch_size == torch.Size([3])
    check_env_specs(env, break_when_any_done="both")
    for group, agents in groups.items():
        n = len(agents)
        assert env.full_observation_spec[group, "observation"].shape[:2] == (3, n)
        assert env.full_reward_spec[group, "reward"].shape == (3, n, 1)
        assert env.full_done_spec[group, "terminated"].shape == (3, n, 1)
        discrete = options["action_mode"] == "switching" and group == "ugv"
        assert (("action_mask" in env.full_observation_spec[group].keys()) == discrete)
        assert env.full_action_spec[group, "action"].shape == ((3, n) if discrete else (3, n, 4))
    assert env.full_done_spec["done"].shape == (3, 1) and env.full_observation_spec["state"].shape[0] == 3
    env.close()


def _actions(env, rng):
    out = {}
    for group, agents in env.group_map.items():
        spec = env.full_action_spec[group, "action"]
        if spec.dtype == torch.int64:
            out[group] = torch.as_tensor(rng.integers(0, 2, size=tuple(spec.shape)))
        else:
            out[group] = torch.as_tensor(rng.uniform(-1, 1, size=tuple(spec.shape)).astype(np.float32))
    return out


@pytest.mark.parametrize("mode", ["switching", "velocity"])
def test_copy_i_is_the_pettingzoo_env_seeded_s_plus_i_across_resets(mode):
    k, steps, seed = 3, 14, 11
    env = MomaTorchRLEnv("top_observer", k, seed=seed, max_cycles=6, action_mode=mode)
    rng = np.random.default_rng(0)
    td = env.reset()
    first = td.clone()
    record = []
    for _ in range(steps):
        actions = _actions(env, rng)
        for group, value in actions.items():
            td.set((group, "action"), value)
        stepped, td = env.step_and_maybe_reset(td)
        record.append((actions, stepped.clone(), td.clone()))
    dones = torch.stack([s["next", "done"].squeeze(-1) for _, s, _ in record])
    assert int(dones.sum()) == 2 * k  # episodes of 6 steps: two ends per copy
    for group in env.group_map:
        for _, stepped, _ in record:
            assert env.full_observation_spec[group, "observation"].is_in(stepped["next", group, "observation"])

    def rows(td, i, key="observation"):
        return {a: td[group, key][i, j].numpy() for group, agents in env.group_map.items() for j, a in enumerate(agents)}

    for i in range(k):
        single = parallel_env("top_observer", max_cycles=6, action_mode=mode)
        obs, _ = single.reset(seed=seed + i)
        assert all(np.array_equal(obs[a], o) for a, o in rows(first, i).items())
        for actions, stepped, after in record:
            joint = {a: actions[g][i, j].numpy() for g, agents in env.group_map.items() for j, a in enumerate(agents)}
            obs, rewards, terms, truncs, _ = single.step(joint)
            assert all(np.array_equal(obs[a], o) for a, o in rows(stepped["next"], i).items())
            for group, agents in env.group_map.items():
                for j, a in enumerate(agents):
                    assert stepped["next", group, "reward"][i, j, 0].item() == np.float32(rewards[a])
                    assert bool(stepped["next", group, "truncated"][i, j, 0]) == truncs[a]
            assert bool(stepped["next", "done"][i, 0]) == (not single.agents)
            assert np.array_equal(stepped["next", "state"][i].numpy(), single.state())  # a done step's state is the episode's last
            if mode == "switching":
                masks = single.action_masks()
                expected = np.stack([masks[a] for a in env.group_map["ugv"]]).astype(bool)
                assert np.array_equal(stepped["next", "ugv", "action_mask"][i].numpy(), expected)
            if not single.agents:
                obs, _ = single.reset()
                assert all(np.array_equal(obs[a], o) for a, o in rows(after, i).items())
    env.close()


def test_the_same_seed_gives_the_same_rollout_and_another_seed_another():
    def rollout(seed):
        env = MomaTorchRLEnv("caterpillar_multi", 2, max_cycles=5, random_scenarios=True)
        env.set_seed(seed)
        torch.manual_seed(0)  # the random actions
        out = env.rollout(12, break_when_any_done=False)
        env.close()
        return out

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert (a == b).all()
    assert not torch.equal(a["ugv", "observation"][:, 0], c["ugv", "observation"][:, 0])


def test_action_masks_are_the_motion_rules_and_random_actions_keep_to_them():
    env = MomaTorchRLEnv("caterpillar_multi", 2, seed=5, max_cycles=40)
    td = env.reset()
    refused = False
    for _ in range(25):
        masks = env.vector.action_masks()
        expected = np.stack([masks[a] for a in env.group_map["ugv"]], axis=1).astype(bool)
        np.testing.assert_array_equal(td["ugv", "action_mask"].numpy(), expected)
        refused |= not expected.all()
        td = env.rand_action(td)
        chosen = td["ugv", "action"].numpy()
        assert np.take_along_axis(expected, chosen[..., None], axis=-1).all()
        td = env.step(td)["next"]
    assert refused
    env.close()


def test_bad_actions_and_spaces_are_refused_naming_the_group_or_the_agent():
    env = MomaTorchRLEnv("top_observer", 2, seed=0, max_cycles=3)
    td = env.reset()
    td.set(("ugv", "action"), torch.zeros(2, 2, dtype=torch.int64))
    env.step(td)
    td.set(("ugv", "action"), torch.tensor([[0, 1], [2, 0]]))
    with pytest.raises(ValueError, match=r"actions of 'ugv_0' .* copy 1 has 2"):
        env.step(td)
    for _ in range(2):
        td.set(("ugv", "action"), torch.zeros(2, 2, dtype=torch.int64))
        out = env.step(td)
    assert out["next", "done"].all()
    with pytest.raises(RuntimeError, match=r"copies \[0, 1\] finished their episodes: reset them"):
        env.step(td)
    velocity = MomaTorchRLEnv("top_observer", 2, seed=0, action_mode="velocity")
    td = velocity.rand_action(velocity.reset())
    td.set(("observer", "action"), torch.zeros(2, 1, 3))
    with pytest.raises(ValueError, match=r"group 'observer' \(agents \['observer'\]\) must have shape \(2, 1, 4\), got \(2, 1, 3\)"):
        velocity.step(td)
    td.set(("observer", "action"), torch.full((2, 1, 4), float("nan")))
    with pytest.raises(ValueError, match=r"actions of 'observer' .* copy 0 is not finite"):
        velocity.step(td)
    with pytest.raises(ValueError, match="observer_image"):
        MomaTorchRLEnv("top_observer", 1, action_mode="velocity", camera_backend="rendered", observer_image=(32, 24))
    with pytest.raises(ConfigError, match="autoreset_mode: MomaTorchRLEnv reads the SameStep autoreset .* got 'NextStep'"):
        MomaTorchRLEnv("top_observer", 1, autoreset_mode="NextStep")


def test_importing_the_adapter_keeps_multiprocessings_start_method():
    code = (
        "import multiprocessing as mp; before = mp.get_start_method(allow_none=True); "
        "import moma_env.vector.torchrl; print(before, mp.get_start_method(allow_none=True)); "
        "import torchrl.envs; print(mp.get_start_method(allow_none=True))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["None", "None", "None"]
    bare = subprocess.run([sys.executable, "-c", "import multiprocessing as mp, torchrl; print(mp.get_start_method(allow_none=True))"],
                          capture_output=True, text=True, check=True).stdout.strip()
    assert bare == "spawn"  # what the adapter undoes


def test_the_copies_build_only_the_masks_of_their_infos_and_give_the_same_data():
    """The copies' infos are not TorchRL's data: by default they carry the masks alone
    (``info_keys=("action_mask",)``), and a rollout is the one of copies with every key."""
    lean = MomaTorchRLEnv("top_observer_team4", 2, seed=3, max_cycles=8)
    full = MomaTorchRLEnv("top_observer_team4", 2, seed=3, max_cycles=8, info_keys=None)
    assert [copy.config.info_keys for copy in lean.vector.envs] == [("action_mask",)] * 2
    assert [copy.config.info_keys for copy in full.vector.envs] == [None] * 2
    torch.manual_seed(0)
    lean_rollout = lean.rollout(20, break_when_any_done=False)
    torch.manual_seed(0)
    full_rollout = full.rollout(20, break_when_any_done=False)
    assert lean_rollout["next", "done"].any()
    assert (lean_rollout == full_rollout).all()
    lean.close()
    full.close()


def test_torchrls_pettingzoo_wrapper_takes_the_parallel_env_with_numeric_infos():
    """What docs/vector.md shows for TorchRL's own wrapper of the PettingZoo env."""
    from torchrl.envs import PettingZooWrapper

    keys = ("action_mask", "static", "localisation_error")
    env = PettingZooWrapper(env=parallel_env("top_observer", n_ugvs=3, action_masks=True, info_keys=keys, max_cycles=12),
                            use_mask=True, categorical_actions=True, seed=3)
    check_env_specs(env)
    rollout = env.rollout(30, break_when_any_done=False)
    assert rollout["ugv", "action_mask"].shape == (30, 3, 2) and rollout["next", "ugv", "reward"].shape == (30, 3, 1)
    # the masks it reads are the env's own: every action taken was allowed
    assert not rollout["ugv", "action_mask"].all()  # some starts were refused by the rules
    taken = rollout["ugv", "action"].unsqueeze(-1)
    assert rollout["ugv", "action_mask"].gather(-1, taken).all()
