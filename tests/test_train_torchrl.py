"""``moma-env train --backend torchrl`` (MAPPO / IPPO on the batched env's TorchRL adapter):
the options it refuses, a whole run's folder, ``--resume``, determinism for a seed, the
evaluation policy (masks obeyed, envs that do not fit refused, the run's last evaluation
reproduced) and damaged or foreign folders refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

# through the adapter, which puts multiprocessing's start method back after importing torchrl
# (torchrl's import sets it to "spawn", which other tests' AsyncVectorEnv workers would inherit)
pytest.importorskip("moma_env.vector.torchrl", reason="needs the 'torchrl' extra")

import torch  # noqa: E402

from agents.learned import TrainingDirError  # noqa: E402
from agents.torchrl_policy import TorchRLPolicy, is_torchrl_run, load_checkpoint, read_torchrl_manifest  # noqa: E402
from moma_env.config import ConfigError  # noqa: E402
from moma_env.env.factory import parallel_env  # noqa: E402
from training.cli import main  # noqa: E402
from training.evaluation.harness import evaluate  # noqa: E402
from training.train.evaluation import headline  # noqa: E402
from training.train.torchrl_config import TorchRLTrainConfig  # noqa: E402
from training.train.torchrl_run import train_torchrl  # noqa: E402

ARGS = ["train", "--backend", "torchrl", "--scenario", "top_observer", "--num-envs", "2", "--n-steps", "32", "--batch-size", "16",
        "--max-cycles", "40", "--checkpoint-every", "64", "--seed", "3"]


def small_config(**changes) -> TorchRLTrainConfig:
    base = dict(scenario="top_observer", steps=128, envs=2, n_steps=32, minibatch_size=16, max_cycles=40, net_arch=(16, 16), seed=5)
    return TorchRLTrainConfig(**(base | changes))


@pytest.mark.parametrize("extra, field", [
    (["--route", "centralised"], "route"),
    (["--subproc"], "subproc"),
    (["--action-mode", "velocity"], "action_mode"),
    (["--pretrain", "greedy"], "pretrain"),
    (["--network", "team"], "network"),
    (["--algo", "a2c"], "algo"),
])
def test_options_torchrl_cannot_honour_are_refused(tmp_path, capsys, extra, field):
    assert main([*ARGS, "--timesteps", "64", *extra, "--out", str(tmp_path / "run")]) == 2
    assert field in capsys.readouterr().err
    assert not (tmp_path / "run" / "manifest.json").exists()


@pytest.mark.parametrize("changes, field", [
    ({"critic": "shared"}, "critic"),
    ({"minibatch_size": 65}, "minibatch_size"),  # a batch is n_steps x envs = 64
    ({"gae_lambda": 1.5}, "gae_lambda"),
    ({"net_arch": ()}, "net_arch"),
    ({"scenario": "nowhere"}, "scenario"),
])
def test_config_names_the_bad_field(changes, field):
    with pytest.raises(ConfigError, match=field):
        small_config(**changes)


def test_train_resume_and_evaluate(tmp_path, capsys):
    out = tmp_path / "run"
    common = [*ARGS, "--eval-every", "64", "--eval-episodes", "2", "--eval-sample-actions"]
    assert main([*common, "--timesteps", "128", "--out", str(out), "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["backend"] == "torchrl" and first["algorithm"] == "MAPPO" and first["num_timesteps"] == 128 and is_torchrl_run(out)
    assert first["collect_s"] > 0 and first["learn_s"] > 0
    assert sorted(p.name for p in out.iterdir() if p.name.startswith("checkpoint_")) == [first["checkpoint"]]

    assert main([*common, "--timesteps", "128", "--out", str(out)]) == 2  # one run per folder
    assert "already holds a training run" in capsys.readouterr().err
    assert main([*common, "--seed", "4", "--timesteps", "256", "--out", str(out), "--resume"]) == 2  # another seed
    assert "seed" in capsys.readouterr().err

    assert main([*common, "--timesteps", "256", "--out", str(out), "--resume", "--json"]) == 0
    resumed = json.loads(capsys.readouterr().out)
    assert resumed["num_timesteps"] == 256 and resumed["wall_time_s"] > first["wall_time_s"]
    assert sorted(p.name for p in out.iterdir() if p.name.startswith("checkpoint_")) == [resumed["checkpoint"]]
    records = json.loads((out / "evaluations.json").read_text())["records"]
    assert [r["num_timesteps"] for r in records] == [64, 128, 192, 256]
    assert (out / "curves.csv").is_file() and (out / "curves.png").is_file()

    # the reloaded checkpoint is the policy the run evaluated last: the same sampled episodes, the same numbers
    policy = TorchRLPolicy.from_dir(out, "top_observer", deterministic=False)
    again = headline(evaluate("top_observer", policy, 2, 10_000, random_scenarios=True, action_mode="switching", observer_agent=False).summary)
    for key in ("success_rate", "n_switches", "n_refused", "total_reward", "me_m", "e_f_m"):
        assert again[key] == pytest.approx(records[-1][key], nan_ok=True), key

    assert main(["evaluate", "--scenario", "top_observer", "--policy", str(out), "--episodes", "1", "--max-cycles", "20",
                 "--out", str(tmp_path / "eval"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_episodes"] == 1
    assert main(["evaluate", "--scenario", "caterpillar", "--policy", str(out), "--episodes", "1", "--out", str(tmp_path / "e2")]) == 2
    assert "trained on 'top_observer'" in capsys.readouterr().err


def _weights(out) -> dict[str, torch.Tensor]:
    return load_checkpoint(out / read_torchrl_manifest(out)["checkpoint"])["actor"]


def test_same_seed_same_weights_other_seed_other_weights(tmp_path):
    for name, seed in (("a", 5), ("b", 5), ("c", 6)):
        train_torchrl(small_config(seed=seed, critic="independent"), tmp_path / name)
    a, b, c = (_weights(tmp_path / name) for name in "abc")
    assert a.keys() == b.keys()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert any(not torch.equal(a[k], c[k]) for k in a)
    assert json.loads((tmp_path / "a" / "manifest.json").read_text())["algorithm"] == "IPPO"


def test_workers_train_the_same_weights_as_one_process(tmp_path):
    train_torchrl(small_config(seed=3), tmp_path / "local")
    train_torchrl(small_config(seed=3, workers=2), tmp_path / "sharded")
    a, b = _weights(tmp_path / "local"), _weights(tmp_path / "sharded")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    manifest = json.loads((tmp_path / "sharded" / "manifest.json").read_text())
    assert manifest["config"]["workers"] == 2
    with pytest.raises(ConfigError, match="workers: must be at most the number of env copies"):
        small_config(workers=small_config().envs + 1)


def test_policy_obeys_the_masks_and_refuses_envs_it_does_not_fit(tmp_path):
    out = tmp_path / "run"
    train_torchrl(small_config(steps=64), out)
    policy = TorchRLPolicy.from_dir(out, deterministic=False)
    env = parallel_env("top_observer", action_mode="switching", observer_agent=False, random_scenarios=True, max_cycles=60)
    observations, infos = env.reset(seed=11)
    policy.reset(env, seed=11)
    for _ in range(60):
        masks = env.action_masks()
        actions = policy.act(observations, infos)
        assert set(actions) == set(observations)
        assert all(masks[a][actions[a]] for a in actions), (actions, masks)
        observations, _, terminations, truncations, infos = env.step(actions)
        if not env.agents:
            break

    four = parallel_env("top_observer_team4", observer_agent=False)
    four.reset(seed=0)
    with pytest.raises(ValueError, match="trained for 2 UGVs"):
        policy.reset(four)
    velocity = parallel_env("top_observer", action_mode="velocity", observer_agent=False)
    velocity.reset(seed=0)
    with pytest.raises(ValueError, match="switching"):
        policy.reset(velocity)


def test_same_episode_seed_same_sampled_actions(tmp_path):
    out = tmp_path / "run"
    train_torchrl(small_config(steps=64), out)
    runs = []
    for _ in range(2):
        policy = TorchRLPolicy.from_dir(out, deterministic=False)
        env = parallel_env("top_observer", action_mode="switching", observer_agent=False, random_scenarios=True, max_cycles=30)
        observations, infos = env.reset(seed=4)
        policy.reset(env, seed=4)
        actions = []
        for _ in range(30):
            step = policy.act(observations, infos)
            actions.append([step[a] for a in sorted(step)])
            observations, _, _, _, infos = env.step(step)
            if not env.agents:
                break
        runs.append(np.array(actions))
    assert np.array_equal(runs[0], runs[1])


def test_damaged_or_foreign_folders_are_refused(tmp_path):
    out = tmp_path / "run"
    train_torchrl(small_config(steps=64), out)
    manifest = json.loads((out / "manifest.json").read_text())

    (out / manifest["checkpoint"]).write_bytes(b"not a checkpoint")
    with pytest.raises(TrainingDirError, match="cannot load the checkpoint"):
        TorchRLPolicy.from_dir(out)
    (out / manifest["checkpoint"]).unlink()
    with pytest.raises(TrainingDirError, match="not a file"):
        TorchRLPolicy.from_dir(out)

    (out / "manifest.json").write_text(json.dumps(manifest | {"env_version": -1}))
    with pytest.raises(TrainingDirError, match="env version"):
        read_torchrl_manifest(out)
    (out / "manifest.json").write_text(json.dumps(manifest | {"backend": "sb3"}))
    assert not is_torchrl_run(out)
    with pytest.raises(TrainingDirError, match="not the manifest of a TorchRL run"):
        read_torchrl_manifest(out)


def test_training_benchmark_row_counts_whole_batches_of_agent_steps():
    from training.train.bench import format_training, torchrl_training_fps

    row = torchrl_training_fps(1000, envs=1, scenario="top_observer")  # 2 UGVs: 1000 agent steps -> 2 batches of 256 env steps
    assert row["timesteps"] == 2 * 256 * 2
    assert row["env_steps_per_s"] == pytest.approx(row["timesteps_per_s"] / 2)
    assert row["algo"] == "mappo (torchrl)"
    assert "mappo (torchrl)" in "\n".join(format_training([row]))


def test_backend_comparison_prints_each_round_and_the_ratio(capsys):
    from training.train.bench import main as bench_main

    assert bench_main(["--steps", "512", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert "maskable_ppo" in out and "mappo (torchrl)" in out
    assert "TorchRL MAPPO / SB3 MaskablePPO env steps per second: best" in out


def test_backend_comparison_with_workers_prints_their_ratio_to_in_process(capsys):
    from training.train.bench import main as bench_main

    assert bench_main(["--steps", "256", "--rounds", "1", "--num-envs", "2", "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "maskable_ppo with 2 workers / in this process: best" in out
    assert "mappo (torchrl) with 2 workers / in this process: best" in out
    with pytest.raises(SystemExit):
        bench_main(["--num-envs", "2", "--workers", "3"])
