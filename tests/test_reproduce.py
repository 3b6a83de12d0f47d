"""training.train.reproduce: two runs of one configuration are the same policy bit for bit,
another seed is not, a published policy retrains from its manifest's command into the same
weights, and bad input (unknown names, damaged zips, commands that cannot remake a run) gives
one line and exit status 2.
"""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import pytest

from agents.learned import POLICIES_ENV
from training.train.config import TrainConfig
from training.train.publish import publish
from training.train.reproduce import compare_runs, main, retrain_argv
from training.train.run import train


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario="top_observer", steps=64, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
        checkpoint_every=10**6, eval_every=64, eval_episodes=1,
    )
    return TrainConfig(**(base | changes))


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("runs")
    made = {}
    for label, config in {"a": tiny(), "again": tiny(checkpoint_every=10**7), "seed1": tiny(seed=1)}.items():
        made[label] = root / label
        train(config, made[label])
    return made


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("python -m training.train.reproduce: "), err
    return err[0]


def test_the_same_configuration_trains_the_same_policy_bit_for_bit(runs, capsys):
    comparison = compare_runs(runs["a"], runs["again"])
    assert comparison.identical and comparison.tensors > 0
    assert comparison.run_differences == []  # the checkpoint interval does not change the weights
    assert main([str(runs["a"]), str(runs["again"])]) == 0
    assert "the same policy bit for bit" in capsys.readouterr().out


def test_another_seed_is_another_policy_and_every_difference_is_named(runs, capsys):
    comparison = compare_runs(runs["a"], runs["seed1"])
    assert not comparison.identical
    assert comparison.tensor_differences and all("largest absolute difference" in what for _, what in comparison.tensor_differences)
    assert ("config.seed", 0, 1) in comparison.run_differences
    assert any(name.startswith("obs_rms.") for name, _ in comparison.statistics_differences)
    assert main([str(runs["a"]), str(runs["seed1"])]) == 1
    out = capsys.readouterr().out
    assert out.startswith("different policies") and "config.seed: 0 against 1" in out


def test_a_published_policy_retrains_from_its_command_into_the_same_weights(tmp_path, policies, capsys, monkeypatch):
    source = tmp_path / "source"
    train(tiny(), source)
    publish(source, "tiny_policy")
    argv = retrain_argv("tiny_policy", tmp_path / "again")
    assert argv[0] == "train" and argv[argv.index("--out") + 1] == str(tmp_path / "again") and "--no-progress" in argv
    assert main(["tiny_policy", "--retrain", "--out", str(tmp_path / "again")]) == 0
    assert "the same policy bit for bit" in capsys.readouterr().out
    # A folder holding the finished run is compared, not trained again.
    monkeypatch.setattr("training.cli.main", lambda argv: pytest.fail("trained again"))
    before = (tmp_path / "again" / "manifest.json").stat().st_mtime_ns
    assert main(["tiny_policy", "--retrain", "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "manifest.json").stat().st_mtime_ns == before


def test_a_policy_whose_command_cannot_remake_it_is_refused(tmp_path, policies, capsys):
    source = tmp_path / "source"
    train(tiny(eval_max_cycles=10), source)  # no command-line option sets eval_max_cycles
    publish(source, "from_python")
    assert main(["from_python", "--retrain", "--out", str(tmp_path / "again")]) == 2
    assert "eval_max_cycles" in _one_error_line(capsys)
    assert not (tmp_path / "again").exists()


def test_unknown_runs_and_damaged_checkpoints_give_one_line_and_exit_2(runs, tmp_path, policies, capsys):
    assert main(["no_such_policy", str(runs["a"])]) == 2
    line = _one_error_line(capsys)
    assert "'no_such_policy' is neither a published policy (published: none)" in line and "nor the folder of a training run" in line
    damaged = tmp_path / "damaged"
    shutil.copytree(runs["a"], damaged)
    from agents.learned import read_manifest

    model = damaged / read_manifest(damaged)["model"]
    with zipfile.ZipFile(model) as archive:
        members = {name: archive.read(name) for name in archive.namelist() if name != "policy.pth"}
    with zipfile.ZipFile(model, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    assert main([str(runs["a"]), str(damaged)]) == 2
    assert "cannot read the policy's weights" in _one_error_line(capsys)
    with pytest.raises(SystemExit):
        main([str(runs["a"])])  # one run without --retrain: argparse's usage error


def test_a_setting_missing_from_an_older_manifest_counts_as_its_default(runs, tmp_path):
    import json

    older = tmp_path / "older"
    shutil.copytree(runs["a"], older)
    manifest = json.loads((older / "manifest.json").read_text())
    del manifest["config"]["kl_to_start"]  # a run made before the setting existed
    (older / "manifest.json").write_text(json.dumps(manifest))
    assert compare_runs(runs["a"], older).run_differences == []
    manifest["config"]["team_action"] = "one_start"
    (older / "manifest.json").write_text(json.dumps(manifest))
    assert compare_runs(runs["a"], older).run_differences == [("config.team_action", "per_agent", "one_start")]


def test_a_run_records_the_library_versions_and_the_comparison_names_those_that_differ(runs, tmp_path):
    import json

    from agents.learned import read_manifest

    versions = read_manifest(runs["a"])["versions"]
    assert {"python", "machine", "cpu", "numpy", "numba", "pymunk", "opencv", "torch", "stable_baselines3"} <= set(versions)
    other = tmp_path / "other"
    shutil.copytree(runs["a"], other)
    manifest = json.loads((other / "manifest.json").read_text())
    manifest["versions"]["numpy"] = "0.0.1"
    del manifest["versions"]["pymunk"]  # an older manifest records fewer: not a difference
    (other / "manifest.json").write_text(json.dumps(manifest))
    comparison = compare_runs(runs["a"], other)
    assert comparison.run_differences == [("versions.numpy", versions["numpy"], "0.0.1")]
    assert comparison.identical  # versions explain a difference; they are not one


def test_every_shipped_policys_command_remakes_its_recorded_configuration(monkeypatch):
    """What the README's retraining runs: each policy in the repository's policies/ folder,
    retrained from its manifest's command, is configured as it was (a command-line default
    that changed since would make it train something else)."""
    import dataclasses
    import json

    from agents.learned import policies_root
    from training.cli import build_parser
    from training.train.command import config_from_args
    from training.train.config import recorded_update_threads

    monkeypatch.delenv(POLICIES_ENV, raising=False)
    root = policies_root()
    names = sorted(p.name for p in root.iterdir() if (p / "manifest.json").is_file())
    assert "top_observer_team4_legs_bc" in names
    defaults = {f.name: f.default for f in dataclasses.fields(TrainConfig) if f.default is not dataclasses.MISSING}
    for name in names:
        # As recorded; a field added since takes its default, but update_threads the run's torch_threads (what its
        # updates ran on: TrainConfig.from_dict's reading of such a record).
        recorded = recorded_update_threads(json.loads((root / name / "manifest.json").read_text())["config"])
        remade = config_from_args(build_parser().parse_args(retrain_argv(name, "out"))).to_dict()
        for key, value in remade.items():
            if key in ("progress_bar", "workers"):  # the retraining hides the bar; workers do not change the weights
                continue
            assert value == recorded.get(key, defaults.get(key)), (name, key, value, recorded.get(key))


def test_a_folder_holding_an_interrupted_run_is_refused_not_resumed(tmp_path, policies, capsys):
    source = tmp_path / "source"
    train(tiny(steps=128), source)
    publish(source, "tiny_policy")
    partial = tmp_path / "partial"
    train(tiny(), partial)  # 64 timesteps: stands for the checkpoint an interrupted retraining left
    assert main(["tiny_policy", "--retrain", "--out", str(partial)]) == 2
    line = _one_error_line(capsys)
    assert "holds a run of 64 timesteps, not the 128" in line and "empty folder" in line
