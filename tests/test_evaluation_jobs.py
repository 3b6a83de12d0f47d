"""An evaluation's episodes split over worker processes (training/evaluation/runner.py):
the same episodes as in one process, for built-in, random and learned policies, during
training too; and the boundary's errors."""

from __future__ import annotations

import json
import multiprocessing
import pickle
import random

import numpy as np
import pytest
import torch

from agents.learned import LearnedPolicy
from moma_env.config import ConfigError
from training.cli import main
from training.evaluation.harness import episode_dict, evaluate
from training.evaluation.policies import load_policy
from training.evaluation.runner import RANGES_PER_JOB, PolicyNotPortableError, episode_ranges
from training.train.config import TrainConfig, eval_jobs, usable_cores
from training.train.run import train

SHORT = {"max_cycles": 40}


def _episodes(result) -> str:
    """Everything the harness recorded of every episode, and the summary, as one text."""
    return json.dumps({"episodes": [episode_dict(ep) for ep in result.episodes], "summary": result.summary,
                       "robots": result.robots}, sort_keys=True, default=repr)


@pytest.mark.parametrize("episodes, jobs", [(1, 1), (1, 4), (5, 1), (5, 2), (10, 2), (100, 2), (9, 3)])
def test_episode_ranges_cover_the_episodes_in_order(episodes, jobs):
    ranges = episode_ranges(episodes, jobs)
    assert len(ranges) == min(episodes, RANGES_PER_JOB * jobs)
    assert [r.first for r in ranges] == list(np.cumsum([0] + [r.count for r in ranges[:-1]]))
    assert sum(r.count for r in ranges) == episodes
    assert max(r.count for r in ranges) - min(r.count for r in ranges) <= 1 and min(r.count for r in ranges) >= 1


@pytest.mark.parametrize("configuration, spec", [("top_observer_team4", "greedy"), ("top_observer", "random"), ("caterpillar_multi", "scripted")])
def test_split_episodes_equal_one_process(configuration, spec):
    alone = evaluate(configuration, spec, 5, 70, **SHORT)
    split = evaluate(configuration, spec, 5, 70, jobs=2, **SHORT)
    assert [ep.index for ep in split.episodes] == list(range(5)) and [ep.seed for ep in split.episodes] == list(range(70, 75))
    assert _episodes(split) == _episodes(alone)
    assert split.policy == alone.policy


def test_a_learned_policy_object_evaluates_the_same_in_workers():
    policy = load_policy("top_observer_team4_mppo", "top_observer_team4")
    alone = evaluate("top_observer_team4", policy, 4, 1_000_000, max_cycles=120)
    finished = []
    split = evaluate("top_observer_team4", policy, 4, 1_000_000, max_cycles=120, jobs=2, progress=finished.append)
    assert _episodes(split) == _episodes(alone)
    assert sorted(ep.index for ep in finished) == [0, 1, 2, 3]


def test_detection_logs_come_back_in_episode_order():
    alone: list[str] = []
    split: list[str] = []
    evaluate("top_observer", "scripted", 3, 5, detection_logs=alone, max_cycles=25)
    evaluate("top_observer", "scripted", 3, 5, detection_logs=split, jobs=2, max_cycles=25)
    assert len(alone) == 3 and split == alone
    assert len(set(alone)) == 3  # three different episodes, not one log thrice


def test_a_learned_policy_pickles_as_its_model_and_leaves_the_global_generators_alone():
    policy = load_policy("top_observer_team4_mppo", "top_observer_team4")
    blob = pickle.dumps(policy)
    random.seed(11)
    np.random.seed(11)
    torch.manual_seed(11)
    states = random.getstate(), np.random.get_state()[1].copy(), torch.random.get_rng_state().clone()
    copy = pickle.loads(blob)
    assert random.getstate() == states[0]
    assert np.array_equal(np.random.get_state()[1], states[1])
    assert torch.equal(torch.random.get_rng_state(), states[2])
    assert isinstance(copy, LearnedPolicy) and copy.model is not policy.model
    assert (copy.route, copy.action_mode, copy.deterministic, copy.team_action) == (policy.route, policy.action_mode, True, policy.team_action)
    for name, tensor in policy.model.policy.state_dict().items():
        assert torch.equal(copy.model.policy.state_dict()[name], tensor), name
    assert np.array_equal(copy.normalise.mean, policy.normalise.mean) and np.array_equal(copy.normalise.var, policy.normalise.var)


class _Unpicklable:
    """A policy holding a lambda: it acts, but cannot go to a worker."""

    def __init__(self):
        self.pick = lambda infos: 0

    def reset(self, env, seed=None):
        pass

    def act(self, observations, infos):
        return {agent: self.pick(infos) for agent in observations}


def test_bad_jobs_and_unportable_policies_are_refused():
    for jobs in (0, -1, True, 2.0, "2"):
        with pytest.raises(ValueError, match="jobs must be an integer >= 1"):
            evaluate("top_observer", "scripted", 2, 0, jobs=jobs)
    with pytest.raises(ValueError, match="recording frames .* jobs=1"):
        evaluate("top_observer", "scripted", 2, 0, jobs=2, frame_sink=lambda frame: None)
    with pytest.raises(PolicyNotPortableError, match="_Unpicklable cannot be sent to worker processes"):
        evaluate("top_observer", _Unpicklable(), 2, 0, jobs=2, max_cycles=5)
    assert len(evaluate("top_observer", _Unpicklable(), 2, 0, jobs=1, max_cycles=5).episodes) == 2


def test_evaluate_cli_splits_episodes_and_refuses_a_video_with_jobs(tmp_path, capsys):
    args = ["evaluate", "--scenario", "top_observer", "--policy", "scripted", "--episodes", "3", "--max-cycles", "20", "--json"]
    assert main([*args, "--out", str(tmp_path / "one")]) == 0
    assert main([*args, "--jobs", "2", "--out", str(tmp_path / "two")]) == 0
    one, two = (json.loads((tmp_path / name / "summary.json").read_text()) for name in ("one", "two"))
    assert one["episodes"] == two["episodes"] and one["summary"] == two["summary"]
    capsys.readouterr()
    assert main([*args, "--jobs", "2", "--video", "--out", str(tmp_path / "video")]) == 2
    assert "--video records the first episode in this process: give --jobs 1" in capsys.readouterr().err
    assert not (tmp_path / "video").exists()


def test_eval_jobs_is_checked_and_resolved():
    with pytest.raises(ConfigError, match="eval_jobs"):
        TrainConfig(scenario="top_observer", eval_jobs=0)
    assert eval_jobs(TrainConfig(scenario="top_observer", eval_jobs=3, eval_episodes=10)) == 3
    assert eval_jobs(TrainConfig(scenario="top_observer", eval_jobs=3, eval_episodes=2)) == 2
    assert eval_jobs(TrainConfig(scenario="top_observer", eval_episodes=10)) == min(usable_cores(), 10)
    assert eval_jobs(TrainConfig(scenario="top_observer", eval_episodes=1)) == 1


@pytest.mark.parametrize("backend", ["rllib", "torchrl"])
def test_other_backends_refuse_eval_jobs(tmp_path, capsys, backend):
    code = main(["train", "--scenario", "top_observer", "--backend", backend, "--timesteps", "64", "--eval-jobs", "2",
                 "--out", str(tmp_path / "run")])
    assert code == 2
    assert "eval_jobs" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_training_evaluates_the_same_with_a_worker_pool(tmp_path):
    base = dict(scenario="top_observer", steps=128, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
                checkpoint_every=10**6, eval_every=64, eval_episodes=3, eval_max_cycles=20)
    records = []
    for jobs in (1, 2):
        out = tmp_path / f"jobs{jobs}"
        train(TrainConfig(**base, eval_jobs=jobs), out)
        records.append([{k: v for k, v in r.items() if k not in ("wall_time_s", "eval_seconds")}
                        for r in json.loads((out / "evaluations.json").read_text())["records"]])
    assert [r["num_timesteps"] for r in records[0]] == [64, 128]
    assert records[1] == records[0]
    assert not multiprocessing.active_children()  # the run's evaluation workers ended with it
    with pytest.raises(SystemExit) as exit_:
        main(["train", "--scenario", "top_observer", "--timesteps", "0", "--eval-jobs", "0", "--out", str(tmp_path / "x")])
    assert exit_.value.code == 2


def test_the_evaluation_benchmark_prints_its_three_ways(capsys):
    from training.bench_evaluation import WAYS, main as bench

    assert bench(["--policy", "greedy", "--episodes", "2", "--max-cycles", "10", "--rounds", "1"]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[0].startswith("greedy on top_observer_team4, 2 episodes from seed 100000, 2 workers, 1 rounds")
    rows = [line for line in table if line.startswith("| ") and not line.startswith("| evaluation")]
    assert [row.split(" | ")[0].lstrip("| ") for row in rows] == list(WAYS)
    assert rows[0].endswith("| 1.00x | 1.00x |")


def test_a_policy_refusing_the_env_in_a_worker_fails_the_evaluation_as_in_one_process():
    from training.evaluation.policies import PolicyEnvError

    messages = []
    for jobs in (1, 2):
        with pytest.raises(PolicyEnvError) as refused:
            evaluate("top_observer", "pipeline", 4, 0, jobs=jobs, max_cycles=10)
        messages.append(str(refused.value))
    assert messages[0] == messages[1] and "cannot act in this env" in messages[0]
    assert not multiprocessing.active_children()  # the pool's workers ended with the failure
