"""``EnvConfig.info_keys``: the agents' infos keep the chosen keys, and nothing else changes."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env import vector
from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from moma_env.env.info_keys import INFO_KEYS, OBSERVER_INFO_KEYS, UGV_INFO_KEYS


def masked_actions(env, infos, rng):
    """A random granted action of every agent (its mask from the full infos)."""
    return {a: env.action_space(a).sample(mask=infos[a]["action_mask"]) for a in env.agents}


def assert_same_values(chosen_info: dict, full_info: dict, keys) -> None:
    """``chosen_info`` holds exactly the keys of ``full_info`` that are in ``keys``, in
    ``full_info``'s order, with the same values."""
    assert list(chosen_info) == [k for k in full_info if k in keys]
    for key, value in chosen_info.items():
        if isinstance(value, np.ndarray):
            assert np.array_equal(value, full_info[key])
        else:
            assert value == full_info[key]


@pytest.mark.parametrize("bad", ["static", ("static", "static"), ("static", "speed"), 3])
def test_a_bad_choice_names_the_field(bad):
    with pytest.raises(ConfigError, match="env.info_keys"):
        parallel_env("top_observer", info_keys=bad)


def test_the_keys_of_every_agent_are_known():
    assert set(OBSERVER_INFO_KEYS) <= set(UGV_INFO_KEYS) == set(INFO_KEYS)
    env = parallel_env("top_observer", action_masks=True, observer_agent=True)
    _, infos = env.reset(seed=0)
    assert list(infos["ugv_0"]) == [k for k in UGV_INFO_KEYS if not k.startswith("sled_")]
    assert list(infos["observer"]) == list(OBSERVER_INFO_KEYS)
    assert parallel_env("top_observer", info_keys=["static"]).config.info_keys == ("static",)


@pytest.mark.parametrize("keys", [("static", "action_mask"), ("action_mask",), ()])
def test_chosen_keys_carry_the_full_infos_values_and_the_episode_is_the_same(keys):
    full = parallel_env("top_observer_team4")
    chosen = parallel_env("top_observer_team4", info_keys=keys)
    _, full_infos = full.reset(seed=5)
    _, infos = chosen.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(80):
        for agent in full.agents:
            assert_same_values(infos[agent], full_infos[agent], keys)
        actions = masked_actions(full, full_infos, rng)
        full_step, step = full.step(actions), chosen.step(actions)
        for k in range(4):
            assert full_step[k].keys() == step[k].keys()
            for agent in full_step[k]:
                assert np.array_equal(full_step[k][agent], step[k][agent])
        full_infos, infos = full_step[4], step[4]
    assert chosen.switches_total == full.switches_total > 0


def test_keys_that_need_the_whole_info_observers_and_sleds():
    """A key beyond a UGV's static flag and mask (the truth, the reward terms), an observer
    agent's own keys (it has no ``"static"``), and a towing robot's sled keys."""
    for name, options, keys in (
        ("top_observer", {"action_mode": "velocity"}, ("truth", "reward_terms", "status", "static")),
        ("caterpillar_sled", {}, ("sled_truth", "localisation_error", "events")),
    ):
        full = parallel_env(name, **options)
        chosen = parallel_env(name, info_keys=keys, **options)
        _, full_infos = full.reset(seed=2)
        _, infos = chosen.reset(seed=2)
        for _ in range(30):
            for agent in full.agents:
                assert_same_values(infos[agent], full_infos[agent], keys)
            actions = {a: full.action_space(a).sample() for a in full.agents}
            _, _, _, _, full_infos = full.step(actions)
            _, _, _, _, infos = chosen.step(actions)
        if name == "caterpillar_sled":  # its one robot tows the sled
            assert list(infos["ugv_0"]) == ["localisation_error", "events", "sled_truth"]
        else:
            assert list(infos["observer"]) == ["truth", "status", "reward_terms"]


def test_a_batch_without_masks_in_its_infos_computes_them_and_ends_episodes_alike():
    full = vector.make("top_observer_team4", 3, max_cycles=40)
    chosen = vector.make("top_observer_team4", 3, max_cycles=40, info_keys=("static",))
    full.reset(seed=0)
    _, infos = chosen.reset(seed=0)
    assert all(set(info[a]) == {"static"} for info in infos for a in chosen.possible_agents)
    rng = np.random.default_rng(1)
    ended = 0
    for _ in range(45):
        masks, chosen_masks = full.action_masks(), chosen.action_masks()
        for agent in masks:
            assert np.array_equal(masks[agent], chosen_masks[agent])
        actions = {a: np.array([rng.choice(np.flatnonzero(row)) for row in rows]) for a, rows in masks.items()}
        full_step, step = full.step(actions), chosen.step(actions)
        for k in range(4):
            for agent in full_step[k]:
                assert np.array_equal(full_step[k][agent], step[k][agent])
        for info in step[4]:
            if "final_info" in info:
                ended += 1
                assert all(set(info["final_info"][a]) == {"static"} for a in chosen.possible_agents)
    assert ended == 3
