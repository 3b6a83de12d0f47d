"""Training with Stable-Baselines3 (training/train/): both routes, checkpoints, resume, the CLI.

Every run here is tiny (a few hundred timesteps, networks of 8 units, episodes of
a few dozen steps): these tests check the plumbing, not learning.
"""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest
from stable_baselines3.common.callbacks import BaseCallback

from agents.learned import LearnedPolicy, TrainingDirError
from moma_env.config import ConfigError
from moma_env.env.factory import parallel_env
from policy_guard import episode_actions
from training.cli import main
from training.train.checkpoint import checkpoint_files, save_checkpoint
from training.train.config import TrainConfig
from training.train.evaluation import live_policy
from training.train.run import train


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario="top_observer", steps=256, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
        checkpoint_every=10**6, eval_episodes=1, eval_max_cycles=20,
    )
    return TrainConfig(**(base | changes))


class KeepModel(BaseCallback):
    """Keeps the model at the end of training, and the step count and statistics at its start."""

    def __init__(self):
        super().__init__()
        self.start_steps = None
        self.start_obs_count = None

    def _on_training_start(self) -> None:
        self.start_steps = self.model.num_timesteps
        env = self.model.get_env()
        self.start_obs_count = float(env.obs_rms.count) if hasattr(env, "obs_rms") else None
        buffer = getattr(self.model, "replay_buffer", None)
        self.start_replay_rows = None if buffer is None else buffer.size()

    def _on_step(self) -> bool:
        return True


def _episode_actions(policy, config: TrainConfig, seed: int, steps: int) -> list[dict]:
    return episode_actions(policy, config.scenario, config.env_options, seed, steps)


@pytest.mark.parametrize(
    "route, mode", [("shared", "switching"), ("centralised", "switching"), ("shared", "velocity"), ("centralised", "velocity")]
)
def test_short_run_saves_and_reloads_with_the_same_deterministic_actions(tmp_path, route, mode):
    config = tiny(route=route, action_mode=mode)
    keep = KeepModel()
    manifest = train(config, tmp_path / "run", callbacks=[keep])
    steps = keep.model.num_timesteps
    assert steps >= config.steps and manifest["num_timesteps"] == steps
    assert manifest["route"] == route and manifest["config"]["action_mode"] == mode
    names = sorted(p.name for p in checkpoint_files(tmp_path / "run"))
    assert names == [f"model_{steps:012d}.zip", f"vecnormalize_{steps:012d}.pkl"]
    live = _episode_actions(live_policy(keep.model, config), config, seed=3, steps=30)
    loaded = _episode_actions(LearnedPolicy.from_dir(tmp_path / "run", "top_observer"), config, seed=3, steps=30)
    assert len(live) == 30 and live == loaded


def test_resume_after_a_kill_continues_from_the_checkpoint_with_its_statistics(tmp_path):
    out = tmp_path / "run"
    config = tiny(steps=512, checkpoint_every=128)  # 2 slots x 32 steps = 64 timesteps per rollout

    class Kill(BaseCallback):
        def _on_rollout_start(self) -> None:
            if self.num_timesteps >= 256:
                raise KeyboardInterrupt("killed")

        def _on_step(self) -> bool:
            return True

    with pytest.raises(KeyboardInterrupt):
        train(config, out, callbacks=[Kill()])
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["num_timesteps"] == 256
    assert sorted(p.name for p in out.iterdir()) == [".moma-run.json", "logs", "manifest.json", "model_000000000256.zip", "vecnormalize_000000000256.pkl"]
    with open(out / manifest["vecnormalize"], "rb") as f:
        saved_count = float(pickle.load(f).obs_rms.count)

    with pytest.raises(ConfigError, match="^out: .*--resume"):
        train(config, out)
    with pytest.raises(ConfigError, match="^learning_rate: "):
        train(tiny(steps=512, checkpoint_every=128, learning_rate=1e-3), out, resume=True)

    keep = KeepModel()
    final = train(config, out, resume=True, callbacks=[keep])
    assert keep.start_steps == 256
    assert saved_count > 256  # every observation so far, not a fresh VecNormalize's
    assert keep.start_obs_count == saved_count + 2  # plus the 2 slots' observations of the resumed envs' reset
    assert final["num_timesteps"] == keep.model.num_timesteps == 512
    adam = keep.model.policy.optimizer.state_dict()["state"]
    assert adam and all(float(s["step"]) > 0 for s in adam.values())  # the optimiser's moments came back
    assert final["wall_time_s"] > manifest["wall_time_s"]
    assert sorted(p.name for p in checkpoint_files(out)) == ["model_000000000512.zip", "vecnormalize_000000000512.pkl"]


def test_a_failed_save_leaves_the_previous_checkpoint_whole(tmp_path):
    out = tmp_path / "run"
    keep = KeepModel()
    config = tiny(steps=64)
    before = train(config, out, callbacks=[keep])
    files = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    model = keep.model

    def broken_save(path, *args, **kwargs):
        with open(path, "wb") as f:
            f.write(b"half a model")
        raise OSError("disk full")

    model.save = broken_save
    model.num_timesteps += 64
    with pytest.raises(OSError, match="disk full"):
        save_checkpoint(out, model, config, 1.0)
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == files
    assert json.loads((out / "manifest.json").read_text())["num_timesteps"] == before["num_timesteps"]


def test_off_policy_run_saves_and_resumes_its_replay_buffer(tmp_path):
    out = tmp_path / "sac"
    config = tiny(algo="sac", action_mode="velocity", steps=40, batch_size=16, buffer_size=1000)
    manifest = train(config, out)
    assert manifest["replay_buffer"] == f"replay_{manifest['num_timesteps']:012d}.pkl"
    keep = KeepModel()
    final = train(tiny(algo="sac", action_mode="velocity", steps=60, batch_size=16, buffer_size=1000), out, resume=True, callbacks=[keep])
    assert keep.start_steps == 40 and keep.start_replay_rows == 40 // 2  # rows of 2 slots (one env step each)
    assert final["num_timesteps"] == 60 and keep.model.replay_buffer.size() == 60 // 2


def test_evaluation_callback_writes_the_harness_metrics(tmp_path):
    out = tmp_path / "run"
    train(tiny(steps=128, eval_every=64, eval_episodes=1, progress_bar=True), out)
    records = json.loads((out / "evaluations.json").read_text())["records"]
    assert [r["num_timesteps"] for r in records] == [64, 128]
    for record in records:
        assert set(record) >= {"success_rate", "time_to_goal_s", "me_m", "e_f_m", "n_switches", "n_refused"}
        assert 0.0 <= record["success_rate"] <= 1.0


def test_evaluations_may_sample_the_actions_and_say_so(tmp_path):
    out = tmp_path / "run"
    sampled = tiny(steps=64, eval_every=64, eval_episodes=1, eval_sample_actions=True)
    train(sampled, out)
    records = json.loads((out / "evaluations.json").read_text())["records"]
    assert records and all(r["sample_actions"] is True for r in records)
    keep = KeepModel()
    train(tiny(steps=128, eval_every=64, eval_episodes=1), out, resume=True, callbacks=[keep])  # a resume may change it
    records = json.loads((out / "evaluations.json").read_text())["records"]
    assert records[0]["sample_actions"] is True and records[-1]["sample_actions"] is False
    assert not live_policy(keep.model, sampled).deterministic
    assert live_policy(keep.model, tiny()).deterministic
    with pytest.raises(ConfigError, match="eval_sample_actions"):
        tiny(eval_sample_actions="yes")


def test_evaluate_cli_runs_a_trained_policy_through_the_harness(tmp_path, capsys):
    train(tiny(steps=64), tmp_path / "run")
    code = main(["evaluate", "--scenario", "top_observer", "--policy", str(tmp_path / "run"), "--episodes", "2",
                 "--max-cycles", "15", "--out", str(tmp_path / "eval"), "--json"])
    assert code == 0
    summary = json.loads((tmp_path / "eval" / "summary.json").read_text())
    assert summary["policy"] == "run" and summary["n_episodes"] == 2 and summary["action_mode"] == "switching"
    assert all(ep["steps"] == 15 for ep in summary["episodes"])
    capsys.readouterr()
    code = main(["evaluate", "--scenario", "caterpillar", "--policy", str(tmp_path / "run"), "--episodes", "1"])
    assert code == 2 and "trained on 'top_observer', not 'caterpillar'" in capsys.readouterr().err
    code = main(["evaluate", "--scenario", "top_observer", "--policy", str(tmp_path / "run"), "--action-mode", "velocity"])
    assert code == 2 and "trained in 'switching' mode, not 'velocity'" in capsys.readouterr().err


def test_workers_are_checked_against_the_copies_the_route_and_subproc():
    assert tiny(envs=4, workers=2).workers == 2
    with pytest.raises(ConfigError, match="^workers: must be at most the number of env copies \\(2\\), got 3"):
        tiny(envs=2, workers=3)
    with pytest.raises(ConfigError, match="^workers: must be >= 1, got 0"):
        tiny(envs=2, workers=0)
    with pytest.raises(ConfigError, match="^workers: subproc runs a process per copy"):
        tiny(envs=2, workers=2, subproc=True)
    assert tiny(envs=2, workers=2, route="centralised").workers == 2


def test_learned_policy_refuses_an_env_it_does_not_fit(tmp_path):
    train(tiny(steps=64), tmp_path / "run")
    policy = LearnedPolicy.from_dir(tmp_path / "run")
    env = parallel_env("top_observer", action_mode="velocity")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="trained in 'switching' mode"):
        policy.reset(env)
    env = parallel_env("top_observer", n_ugvs=3, observer_agent=False)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="observations of shape"):
        policy.reset(env)
    with pytest.raises(TrainingDirError, match="holds no manifest.json"):
        LearnedPolicy.from_dir(tmp_path)


@pytest.mark.parametrize("mode", ["switching", "velocity"])
def test_sampled_actions_are_seeded_by_the_episode_and_leave_torch_rng_alone(tmp_path, mode):
    import torch

    config = tiny(action_mode=mode)
    train(config, tmp_path / "run")
    sampled = LearnedPolicy.from_dir(tmp_path / "run", deterministic=False)
    mode_policy = LearnedPolicy.from_dir(tmp_path / "run")
    assert not sampled.deterministic and mode_policy.deterministic
    torch.manual_seed(123)
    before = torch.get_rng_state()
    first = _episode_actions(sampled, config, seed=4, steps=30)
    assert torch.equal(torch.get_rng_state(), before)  # torch's global RNG untouched
    assert _episode_actions(sampled, config, seed=4, steps=30) == first  # same episode seed, same samples
    fresh = _episode_actions(LearnedPolicy.from_dir(tmp_path / "run", deterministic=False), config, seed=4, steps=30)
    assert fresh == first  # a fresh policy object gives the same samples for the same seed
    # Sampling differs from the distribution's mode somewhere in the episode (a freshly trained
    # network is far from deterministic), while the mode is the same every time.
    modes = _episode_actions(mode_policy, config, seed=4, steps=30)
    assert modes != first
    assert _episode_actions(mode_policy, config, seed=4, steps=30) == modes
    with pytest.raises(ValueError, match="deterministic must be a bool"):
        LearnedPolicy(sampled.model, "shared", mode, deterministic=None)


def test_evaluate_samples_only_trained_policies(tmp_path, capsys):
    from training.cli import main

    code = main(["evaluate", "--scenario", "top_observer", "--policy", "scripted", "--sample-actions", "--episodes", "1"])
    assert code == 2 and "sampling actions applies to a trained policy (a path), not 'scripted'" in capsys.readouterr().err
    train(tiny(), tmp_path / "run")
    capsys.readouterr()
    out = tmp_path / "eval"
    code = main(["evaluate", "--scenario", "top_observer", "--policy", str(tmp_path / "run"), "--sample-actions",
                 "--episodes", "1", "--max-cycles", "20", "--out", str(out), "--json"])
    assert code == 0
    assert '"policy": "run_sampled"' in capsys.readouterr().out


def test_learned_policy_runs_its_network_on_its_own_thread_count(tmp_path):
    import torch

    train(tiny(steps=64), tmp_path / "run")
    policy = LearnedPolicy.from_dir(tmp_path / "run")
    assert policy.torch_threads == 1
    seen = []
    predict = policy.model.predict
    policy.model.predict = lambda *args, **kwargs: (seen.append(torch.get_num_threads()), predict(*args, **kwargs))[1]
    env = parallel_env("top_observer", **policy.env_options)
    observations, infos = env.reset(seed=0)
    policy.reset(env)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        actions = policy.act(observations, infos)
        assert set(actions) == set(observations) and seen == [1]
        assert torch.get_num_threads() == 2  # restored
    finally:
        torch.set_num_threads(before)
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="torch_threads must be an int >= 1"):
            LearnedPolicy(policy.model, "shared", "switching", torch_threads=bad)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--scenario", "top_observer", "--algo", "sac"], "algo: sac needs continuous actions"),
        (["--scenario", "top_observer", "--algo", "dqn", "--route", "centralised"], "algo: dqn needs one discrete action"),
        (["--scenario", "top_observer", "--reward", "speed=1"], "rewards.speed: unknown field"),
        (["--scenario", "top_observer", "--reward", "time"], "rewards: expected NAME=VALUE"),
        (["--scenario", "top_observer", "--reward", "time=soon"], "rewards.time: must be a number"),
        (["--scenario", "top_observer", "--gamma", "1.5"], "gamma: must be in [0.0, 1.0]"),
        (["--scenario", "top_observer", "--resume"], "holds no manifest.json"),
    ],
)
def test_train_cli_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    (tmp_path / "out").mkdir()
    code = main(["train", *args, "--out", str(tmp_path / "out"), "--no-progress"])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]


@pytest.mark.parametrize("args", [["--num-envs", "0"], ["--timesteps", "ten"], ["--net", "64,0"], ["--route", "solo"]])
def test_train_cli_rejects_malformed_numbers_and_choices(tmp_path, capsys, args):
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--scenario", "top_observer", "--out", str(tmp_path), *args])
    assert exit_info.value.code == 2
    assert "moma-env train: error:" in capsys.readouterr().err


def test_train_cli_trains_and_reports(tmp_path, capsys):
    code = main(["train", "--scenario", "caterpillar", "--timesteps", "64", "--num-envs", "1", "--n-steps", "32", "--batch-size", "32",
                 "--net", "8", "--max-cycles", "30", "--out", str(tmp_path / "run"), "--no-progress", "--json"])
    assert code == 0
    manifest = json.loads(capsys.readouterr().out)
    assert manifest["num_timesteps"] == 64 and manifest["config"]["scenario"] == "caterpillar"
    assert LearnedPolicy.from_dir(tmp_path / "run", "caterpillar").route == "shared"


def test_compare_tables_policies_evaluated_on_the_same_episodes(tmp_path, capsys):
    from training.train import compare

    train(tiny(steps=64), tmp_path / "run")
    common = ["--scenario", "top_observer", "--episodes", "2", "--max-cycles", "10", "--json"]
    assert main(["evaluate", *common, "--policy", str(tmp_path / "run"), "--out", str(tmp_path / "learned")]) == 0
    assert main(["evaluate", *common, "--policy", "random", "--out", str(tmp_path / "random")]) == 0
    assert main(["evaluate", *common, "--policy", "random", "--seed", "5", "--out", str(tmp_path / "other")]) == 0
    capsys.readouterr()
    assert compare.main([str(tmp_path / "learned"), str(tmp_path / "random")]) == 0
    rows = capsys.readouterr().out.strip().splitlines()
    assert rows[0].startswith("| policy | success |") and len(rows) == 4
    assert rows[2].startswith("| run | 0 % | n/a |") and rows[3].startswith("| random | 0 % | n/a |")
    random_summary = json.loads((tmp_path / "random" / "summary.json").read_text())
    refused = random_summary["summary"]["n_refused"]["mean"]
    assert rows[3].split("|")[5].strip() == f"{refused:.1f}"
    assert compare.main([str(tmp_path / "random"), str(tmp_path / "other")]) == 2
    assert "differ in scenario, first seed" in capsys.readouterr().err


def test_moma_env_the_cli_and_the_worker_engine_do_not_import_sb3_or_torch():
    import subprocess
    import sys

    code = ("import sys, moma_env, agents.policies, agents.learned, training.cli, training.train.team_slots; "
            "training.cli.build_parser(); print(sorted(m for m in ('stable_baselines3', 'torch') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_sb3_metrics_go_to_one_csv_per_session_in_the_run_folder(tmp_path, monkeypatch):
    temp = tmp_path / "system_temp"
    temp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(temp))  # SB3's default logger would make SB3-<date> folders here
    out = tmp_path / "run"
    train(tiny(steps=64, eval_every=64), out)
    train(tiny(steps=128, eval_every=64), out, resume=True)
    assert list(temp.iterdir()) == []
    first, second = sorted((out / "logs").glob("progress_*.csv"))
    assert (first.name, second.name) == ("progress_000000000000.csv", "progress_000000000064.csv")
    for path, end in ((first, 64), (second, 128)):
        header, *rows = [line.split(",") for line in path.read_text().splitlines()]
        assert {"time/total_timesteps", "eval/success_rate"} <= set(header)
        assert rows and int(rows[-1][header.index("time/total_timesteps")]) == end


@pytest.mark.parametrize("route,remote_kind", [
    ("shared", {"subproc": True}), ("centralised", {"subproc": True}), ("shared", {"workers": 2}), ("centralised", {"workers": 2}),
])
def test_worker_processes_train_the_same_weights_as_one_process(tmp_path, route, remote_kind):
    import torch

    weights, rewards = [], []
    for k, kind in enumerate(({}, remote_kind)):
        keep = KeepModel()
        train(tiny(route=route, envs=2, steps=128, **kind), tmp_path / f"run_{k}", callbacks=[keep])
        weights.append([p.detach().clone() for p in keep.model.policy.parameters()])
        rewards.append(keep.model.rollout_buffer.rewards.copy())
    assert len(weights[0]) == len(weights[1]) > 0
    assert all(torch.equal(a, b) for a, b in zip(*weights))
    assert np.array_equal(rewards[0], rewards[1]) and np.abs(rewards[0]).sum() > 0


@pytest.mark.parametrize("extra, message", [
    (["--backend", "rllib", "--workers", "2"], "use --num-env-runners instead of --workers"),
    (["--backend", "torchrl", "--num-envs", "2", "--workers", "3"], "workers: must be at most the number of env copies (2)"),
    (["--num-envs", "2", "--workers", "2", "--subproc"], "workers: subproc runs a process per copy"),
    (["--backend", "rllib", "--torch-threads", "2"], "--backend rllib does not take --torch-threads"),
])
def test_train_refuses_workers_it_cannot_honour(tmp_path, capsys, extra, message):
    assert main(["train", "--scenario", "top_observer", "--timesteps", "64", *extra, "--out", str(tmp_path / "run")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_torch_threads_is_an_option_and_lands_in_the_manifest(tmp_path):
    with pytest.raises(SystemExit):
        main(["train", "--scenario", "top_observer", "--torch-threads", "0", "--out", str(tmp_path / "bad")])
    out = tmp_path / "run"
    assert main(["train", "--scenario", "top_observer", "--timesteps", "64", "--n-steps", "32", "--batch-size", "32", "--net", "8",
                 "--max-cycles", "20", "--torch-threads", "2", "--no-progress", "--out", str(out)]) == 0
    assert json.loads((out / "manifest.json").read_text())["config"]["torch_threads"] == 2
