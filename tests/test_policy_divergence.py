"""``python -m training.policy_divergence RUN START``: the KL divergence of one trained
centralised policy from another along the first's actions (training/policy_divergence.py)."""

from __future__ import annotations

import numpy as np
import pytest

from agents.learned import LearnedPolicy
from training.policy_divergence import divergences, main
from training.train.config import TrainConfig
from training.train.envs import env_spec
from training.train.run import train


def tiny(**changes) -> TrainConfig:
    base = dict(scenario="top_observer", route="centralised", steps=64, envs=1, n_steps=32, batch_size=32, net_arch=(8,),
                max_cycles=40, checkpoint_every=10**6)
    return TrainConfig(**(base | changes))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    for name, seed, algo in (("a", 1, "maskable_ppo"), ("b", 2, "maskable_ppo"), ("plain", 4, "ppo")):
        train(tiny(seed=seed, algo=algo), root / name)
    train(tiny(seed=3, route="shared"), root / "shared")
    return root


def test_a_policy_is_at_no_divergence_from_itself_and_at_some_from_another(runs):
    a, b = (LearnedPolicy.from_dir(runs / name) for name in "ab")
    spec = env_spec(tiny())
    same, choice = divergences(a, a, spec, copies=2, steps=10, seed=7, sample=True)
    assert same.shape == choice.shape == (20,) and np.all(same == 0)
    other, choice_again = divergences(a, b, spec, copies=2, steps=10, seed=7, sample=True)
    assert np.array_equal(choice, choice_again)  # the same states: a acts, with the same seed
    assert np.all(other >= 0) and other.mean() > 0
    again, _ = divergences(a, b, spec, copies=2, steps=10, seed=7, sample=True)
    assert np.array_equal(other, again)
    plain = LearnedPolicy.from_dir(runs / "plain")  # PPO without masks: its distribution over every action
    assert divergences(plain, a, spec, copies=1, steps=5, seed=7, sample=False)[0].mean() > 0


def test_the_command_prints_the_divergence_and_refuses_a_shared_route_run(runs, capsys):
    assert main([str(runs / "a"), str(runs / "b"), "--copies", "1", "--steps", "5"]) == 0
    out = capsys.readouterr().out
    assert "5 rows" in out and "nats" in out
    with pytest.raises(SystemExit) as exit_info:
        main([str(runs / "shared"), str(runs / "a")])
    assert exit_info.value.code == 2 and "shared route" in capsys.readouterr().err
