"""Published policies (training/train/publish.py, agents.learned.load_published): a tiny run
published into a temporary policies folder, evaluated by name through the CLI and the
one-liner; another env version, damaged files and bad names are refused with one line.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import moma_env
from moma_env import ENV_VERSION
from agents.learned import MANIFEST, POLICIES_ENV, LearnedPolicy, TrainingDirError, load_published, policies_root
from policy_guard import episode_actions
from training.cli import main
from training.evaluation import PolicyLoadError, evaluate, load_policy
from training.train import publish as publish_module
from training.train.config import TrainConfig
from training.train.publish import PublishError, publish
from training.train.run import train

ROOT = Path(__file__).resolve().parents[1]


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario="top_observer", steps=64, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
        checkpoint_every=10**6, eval_every=64, eval_episodes=1, eval_max_cycles=10,
    )
    return TrainConfig(**(base | changes))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("train") / "run"
    train(tiny(), out)
    return out


def _actions(policy, seed: int = 3, steps: int = 12) -> list[dict]:
    return episode_actions(policy, "top_observer", policy.env_options, seed, steps)


def _one_error_line(capsys, prefix: str) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix), captured.err
    return lines[0]


def test_the_source_folder_is_recorded_as_given_not_as_the_publishers_absolute_path(run_dir, policies, monkeypatch):
    monkeypatch.chdir(run_dir.parent)
    assert publish_module.main([run_dir.name, "tiny_relative"]) == 0
    published = json.loads((policies / "tiny_relative" / MANIFEST).read_text())["published"]
    assert published["source"] == run_dir.name  # what --out would say, like the command
    assert published["command"].endswith(f"--out {run_dir.name}")


def test_publish_copies_the_final_checkpoint_with_its_manifest(run_dir, policies, capsys):
    assert publish_module.main([str(run_dir), "tiny_ppo"]) == 0
    assert "published 'tiny_ppo'" in capsys.readouterr().out
    folder = policies / "tiny_ppo"
    assert sorted(p.name for p in folder.iterdir()) == ["manifest.json", "model.zip", "vecnormalize.pkl"]
    assert not [p for p in policies.iterdir() if p.name.startswith(".")]  # no staging folder left
    manifest = json.loads((folder / MANIFEST).read_text())
    trained = json.loads((run_dir / MANIFEST).read_text())
    assert (folder / "model.zip").read_bytes() == (run_dir / trained["model"]).read_bytes()
    assert manifest["env_version"] == moma_env.ENV_VERSION and manifest["config"] == trained["config"]
    published = manifest["published"]
    assert published["name"] == "tiny_ppo" and published["seed"] == 0 and published["num_timesteps"] == 64
    assert published["wall_time_s"] == trained["wall_time_s"] > 0
    assert published["command"].startswith("moma-env train --scenario top_observer --timesteps 64 --num-envs 1 ")
    assert published["command_omits"] == {"eval_max_cycles": 10}  # no CLI option for it
    assert published["last_evaluation"]["num_timesteps"] == 64
    assert set(manifest["sha256"]) == {"model.zip", "vecnormalize.pkl"}
    assert "commit" in published["training_git"] and "commit" in published["publishing_git"]
    # publishing again under that name needs --replace
    assert publish_module.main([str(run_dir), "tiny_ppo"]) == 2
    assert "already published" in _one_error_line(capsys, "publish: ")
    assert publish_module.main([str(run_dir), "tiny_ppo", "--replace"]) == 0
    assert sorted(p.name for p in policies.iterdir()) == ["tiny_ppo"]


def test_a_published_policy_is_evaluated_by_name_through_the_cli_and_the_one_liner(run_dir, policies, tmp_path, capsys):
    publish(run_dir, "tiny_ppo")
    loaded = load_published("tiny_ppo")
    assert isinstance(loaded, LearnedPolicy) and loaded.configuration == "top_observer"
    assert _actions(loaded) == _actions(LearnedPolicy.from_dir(run_dir))  # the run's own policy
    assert load_published("tiny_ppo", root=policies).route == "shared"
    result = evaluate("top_observer", loaded, 1, 10_000, max_cycles=10, **loaded.env_options)
    assert result.summary["n_episodes"] == 1
    code = main(["evaluate", "--scenario", "top_observer", "--policy", "tiny_ppo", "--episodes", "2", "--max-cycles", "10",
                 "--out", str(tmp_path / "eval"), "--json"])
    assert code == 0
    summary = json.loads((tmp_path / "eval" / "summary.json").read_text())
    assert summary["policy"] == "tiny_ppo" and summary["n_episodes"] == 2
    capsys.readouterr()
    assert main(["evaluate", "--scenario", "caterpillar", "--policy", "tiny_ppo", "--episodes", "1"]) == 2
    assert "trained on 'top_observer', not 'caterpillar'" in _one_error_line(capsys, "moma-env evaluate: ")
    assert main(["evaluate", "--scenario", "top_observer", "--policy", "nothing_here", "--episodes", "1"]) == 2
    assert "unknown policy 'nothing_here'" in _one_error_line(capsys, "moma-env evaluate: ")
    with pytest.raises(TrainingDirError, match=r"no published policy 'nothing_here' .*\(published: tiny_ppo\)"):
        load_published("nothing_here")


def test_another_env_version_is_refused(run_dir, policies, capsys, monkeypatch, tmp_path):
    publish(run_dir, "tiny_ppo")
    path = policies / "tiny_ppo" / MANIFEST
    manifest = json.loads(path.read_text())
    path.write_text(json.dumps(manifest | {"env_version": "0"}))
    with pytest.raises(TrainingDirError, match=rf"trained on env version '0', this code's is '{ENV_VERSION}'"):
        load_published("tiny_ppo")
    assert main(["evaluate", "--scenario", "top_observer", "--policy", "tiny_ppo", "--episodes", "1",
                 "--out", str(tmp_path / "eval")]) == 2
    assert "env version '0'" in _one_error_line(capsys, "moma-env evaluate: ")
    assert not (tmp_path / "eval").exists()  # refused, not run
    # the same holds when the code's version moves on: the run itself is refused, and cannot be published
    later = ENV_VERSION + "-next"
    monkeypatch.setattr("agents.learned.ENV_VERSION", later)
    with pytest.raises(TrainingDirError, match=rf"trained on env version '{ENV_VERSION}', this code's is '{later}'"):
        LearnedPolicy.from_dir(run_dir)
    assert publish_module.main([str(run_dir), "other"]) == 2
    assert f"env version '{ENV_VERSION}'" in _one_error_line(capsys, "publish: ")


def test_a_truncated_model_zip_gives_one_line_and_exit_2(run_dir, policies, tmp_path, capsys):
    publish(run_dir, "tiny_ppo")
    model = policies / "tiny_ppo" / "model.zip"
    model.write_bytes(model.read_bytes()[: model.stat().st_size // 2])
    assert main(["evaluate", "--scenario", "top_observer", "--policy", "tiny_ppo", "--episodes", "1"]) == 2
    line = _one_error_line(capsys, "moma-env evaluate: ")
    assert "model.zip" in line and "truncated or changed" in line
    with pytest.raises(TrainingDirError, match="differs from the sha256"):
        load_published("tiny_ppo")
    # a training folder has no checksums: SB3's own error, in one line
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    manifest = json.loads((run_dir / MANIFEST).read_text())
    for name in (MANIFEST, manifest["model"], manifest["vecnormalize"]):
        (damaged / name).write_bytes((run_dir / name).read_bytes())
    (damaged / manifest["model"]).write_bytes((run_dir / manifest["model"]).read_bytes()[:100])
    with pytest.raises(TrainingDirError, match="^cannot load the model .*damaged or not an SB3 zip"):
        LearnedPolicy.from_dir(damaged)
    assert publish_module.main([str(damaged), "damaged"]) == 2
    assert "is not a whole zip" in _one_error_line(capsys, "publish: ")
    assert sorted(p.name for p in policies.iterdir()) == ["tiny_ppo"]


@pytest.mark.parametrize(
    "name, message",
    [("../escape", "not a published policy name"), ("a/b", "not a published policy name"), ("scripted", "built-in policy"),
     (".hidden", "not a published policy name")],
)
def test_bad_names_are_refused(run_dir, policies, capsys, name, message):
    assert publish_module.main([str(run_dir), name]) == 2
    assert message in _one_error_line(capsys, "publish: ")
    assert list(policies.iterdir()) == []


def test_bad_runs_and_roots_are_refused(tmp_path, policies, capsys):
    assert publish_module.main([str(tmp_path / "nowhere"), "x"]) == 2
    assert "is not a folder of a training run" in _one_error_line(capsys, "publish: ")
    assert publish_module.main([str(tmp_path), "x", "--root", str(tmp_path / "missing")]) == 2
    assert "does not exist" in _one_error_line(capsys, "publish: ")


def test_a_name_that_is_also_a_folder_here_is_ambiguous(run_dir, policies, tmp_path, monkeypatch):
    publish(run_dir, "tiny_ppo")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tiny_ppo").mkdir()
    with pytest.raises(PolicyLoadError, match=r"both a published policy .* write ./tiny_ppo"):
        load_policy("tiny_ppo", "top_observer")


def test_the_default_root_is_the_repositorys_policies_folder_which_git_keeps(monkeypatch):
    monkeypatch.delenv(POLICIES_ENV, raising=False)
    assert policies_root() == ROOT / "policies"
    assert (ROOT / "policies" / "README.md").is_file()
    for path in ("policies/some_policy/model.zip", "policies/some_policy/vecnormalize.pkl", "policies/some_policy/manifest.json"):
        ignored = subprocess.run(["git", "-C", str(ROOT), "check-ignore", "-q", path])
        assert ignored.returncode == 1, f"{path} is ignored by git"
    assert isinstance(moma_env.ENV_VERSION, str) and moma_env.ENV_VERSION
    assert sys.modules["moma_env"].ENV_VERSION == moma_env.ENV_VERSION


def test_the_recorded_command_line_remakes_the_configuration():
    import dataclasses

    from moma_env.tasks import TASKS
    from training.cli import build_parser
    from training.train.command import config_from_args, train_command
    from training.train.config import reward_overrides

    configs = [
        tiny(progress_bar=True, eval_max_cycles=None),
        TrainConfig(scenario="top_observer", steps=4000, net_arch=(8, 8), learning_rate=1e-3, normalize=False, subproc=True,
                    rewards=reward_overrides(["refused=-0.005", "progress=2"]), eval_sample_actions=True, torch_threads=2),
        TrainConfig(scenario="top_observer", envs=4, workers=2, switch_horizon_s=90.0),
        TrainConfig(scenario="top_observer_team4", algo="maskable_ppo", progress_bar=True,
                    rewards=reward_overrides(["time=-0.02"], TASKS["top_observer_team4"].options["rewards"])),
        TrainConfig(scenario="top_observer_team6", algo="maskable_ppo", route="centralised", pretrain="greedy", pretrain_rows=1000,
                    pretrain_epochs=4, dagger_rounds=1, dagger_rows=500, dagger_epochs=2, dagger_teacher="rollout", steps=0),
    ]
    for config in configs:
        argv, omitted = train_command(config, "out")
        assert argv[:2] == ["moma-env", "train"] and argv[-2:] == ["--out", "out"] and omitted == []
        assert config_from_args(build_parser().parse_args(argv[1:])) == config
    argv, omitted = train_command(dataclasses.replace(configs[0], torch_threads=2, eval_max_cycles=7), "out")
    assert omitted == ["eval_max_cycles"]


def test_every_policy_shipped_in_the_repository_loads_and_acts():
    """The policies/ folder of the repository: each published policy loads by name (its
    checksums and env version checked) and acts on a short episode of the task it was
    trained on."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "policies"
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert names, "no policy is shipped in policies/"
    for name in names:
        policy = load_published(name, root=root)
        scenario = json.loads((root / name / "manifest.json").read_text())["config"]["scenario"]
        actions = episode_actions(policy, scenario, policy.env_options, seed=5, steps=40)
        assert len(actions) == 40
