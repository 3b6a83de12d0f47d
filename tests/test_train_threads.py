"""torch's threads in training: the rollouts on ``torch_threads``, the on-policy updates on
``update_threads`` (docs/training.md, "Threads").

The updates run on the update count and the rollouts (and the callbacks at a rollout's start)
on the other; the manifest records the count; the default networks and minibatches train the
same weights on one update thread as on two; bad counts and algorithms that update between env
steps are refused naming the field; a run recorded before the field existed reads back with the
count its updates ran on.
"""

from __future__ import annotations

import json

import pytest
import torch
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.save_util import load_from_zip_file

from agents.learned import read_manifest
from moma_env.config import ConfigError
from training.cli import main
from training.train.config import TrainConfig
from training.train.models import algorithm_class
from training.train.run import train


class _ThreadProbe(BaseCallback):
    """Records torch's thread count at every rollout step and rollout start."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[int] = set()

    def _on_rollout_start(self) -> None:
        self.seen.add(torch.get_num_threads())

    def _on_step(self) -> bool:
        self.seen.add(torch.get_num_threads())
        return True


def _config(**changes) -> TrainConfig:
    base = dict(scenario="top_observer", algo="ppo", steps=768, envs=2, n_steps=64,  # 3 rollouts of 256 agent steps net_arch=(8,), max_cycles=40,
                checkpoint_every=10**6, torch_threads=1)
    return TrainConfig(**(base | changes))


@pytest.mark.parametrize("algo", ["ppo", "maskable_ppo", "a2c"])
def test_updates_run_on_their_threads_and_rollouts_on_theirs(tmp_path, monkeypatch, algo):
    cls = algorithm_class(algo)
    update_counts: list[int] = []
    original = cls.train

    def recording_train(self):
        update_counts.append(torch.get_num_threads())
        return original(self)

    monkeypatch.setattr(cls, "train", recording_train)
    probe = _ThreadProbe()
    before = torch.get_num_threads()
    train(_config(algo=algo, update_threads=3), tmp_path / "run", callbacks=[probe])
    assert len(update_counts) == 3 and set(update_counts) == {3}  # every update of the 3 rollouts
    assert probe.seen == {1}  # every rollout step and rollout start, after the first update too
    assert torch.get_num_threads() == before  # restored when the run ends
    assert json.loads((tmp_path / "run" / "manifest.json").read_text())["update_threads"] == 3


def test_update_threads_default_to_the_usable_cores(tmp_path, monkeypatch):
    import training.train.config as config_module

    monkeypatch.setattr(config_module, "usable_cores", lambda: 5)
    config = _config()
    assert config.update_threads is None and config_module.update_threads(config) == 5
    train(config, tmp_path / "run")
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert manifest["update_threads"] == 5 and manifest["config"]["update_threads"] is None


def _weights(out) -> dict[str, torch.Tensor]:
    _, params, _ = load_from_zip_file(out / read_manifest(out)["model"], device="cpu")
    return params["policy"]


def test_default_networks_train_the_same_weights_on_one_or_two_update_threads(tmp_path):
    # The default 64x64 networks and minibatches (a quarter of the rollout) of the four-UGV task.
    config = dict(scenario="top_observer_team4", algo="maskable_ppo", steps=4096, envs=4, n_steps=128, max_cycles=80,
                  checkpoint_every=10**6, torch_threads=1)
    runs = {}
    for threads in (1, 2):
        train(TrainConfig(**config, update_threads=threads), tmp_path / f"t{threads}")
        runs[threads] = _weights(tmp_path / f"t{threads}")
    assert len(runs[1]) > 0 and runs[1].keys() == runs[2].keys()
    assert all(torch.equal(runs[1][k], runs[2][k]) for k in runs[1])
    train(TrainConfig(**config, update_threads=2, seed=1), tmp_path / "other_seed")
    other = _weights(tmp_path / "other_seed")
    assert not all(torch.equal(runs[2][k], other[k]) for k in runs[2])  # the comparison above can fail


@pytest.mark.parametrize("changes, message", [
    (dict(update_threads=0), "update_threads"),
    (dict(update_threads=1.5), "update_threads"),
    (dict(algo="sac", action_mode="velocity", update_threads=2), "update_threads: sac updates between env steps"),
    (dict(algo="dqn", update_threads=1), "update_threads: dqn updates between env steps"),
])
def test_bad_update_threads_are_refused_naming_the_field(changes, message):
    with pytest.raises(ConfigError, match=message):
        _config(**changes)


def test_off_policy_runs_take_the_default():
    assert _config(algo="dqn").update_threads is None


def test_a_run_recorded_before_update_threads_reads_back_with_its_torch_threads():
    recorded = _config(algo="maskable_ppo", torch_threads=2).to_dict()
    del recorded["update_threads"]
    assert TrainConfig.from_dict(recorded).update_threads == 2
    recorded_off_policy = _config(algo="dqn").to_dict()
    del recorded_off_policy["update_threads"]
    assert TrainConfig.from_dict(recorded_off_policy).update_threads is None
    assert TrainConfig.from_dict(_config(update_threads=3).to_dict()).update_threads == 3


@pytest.mark.parametrize("extra, message", [
    (["--update-threads", "0"], None),
    (["--backend", "rllib", "--update-threads", "2"], "--backend rllib does not take --update-threads"),
    (["--algo", "dqn", "--update-threads", "2"], "update_threads: dqn updates between env steps"),
])
def test_the_cli_refuses_update_threads_it_cannot_honour(tmp_path, capsys, extra, message):
    argv = ["train", "--scenario", "top_observer", "--timesteps", "64", *extra, "--out", str(tmp_path / "run")]
    if message is None:
        with pytest.raises(SystemExit):
            main(argv)
    else:
        assert main(argv) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_the_cli_option_lands_in_the_config(tmp_path):
    out = tmp_path / "run"
    assert main(["train", "--scenario", "top_observer", "--timesteps", "64", "--n-steps", "32", "--batch-size", "32", "--net", "8",
                 "--max-cycles", "20", "--update-threads", "2", "--no-progress", "--out", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["update_threads"] == 2 and manifest["update_threads"] == 2


def test_torchrl_updates_run_on_their_threads(tmp_path, monkeypatch):
    pytest.importorskip("torchrl")
    from training.train import torchrl_run
    from training.train.torchrl_config import TorchRLTrainConfig

    update_counts: list[int] = []
    original = torchrl_run._Learner.update

    def recording_update(self, batch):
        update_counts.append(torch.get_num_threads())
        return original(self, batch)

    monkeypatch.setattr(torchrl_run._Learner, "update", recording_update)
    config = TorchRLTrainConfig(scenario="top_observer", steps=192, envs=2, n_steps=32, minibatch_size=32, num_epochs=1,
                                net_arch=(8,), max_cycles=40, checkpoint_every=10**6, torch_threads=1, update_threads=3)
    before = torch.get_num_threads()
    torchrl_run.train_torchrl(config, tmp_path / "run")
    assert len(update_counts) == 3 and set(update_counts) == {3}  # 3 batches of 64 env steps
    assert torch.get_num_threads() == before
    assert json.loads((tmp_path / "run" / "manifest.json").read_text())["update_threads"] == 3
    recorded = config.to_dict()
    del recorded["update_threads"]
    assert TorchRLTrainConfig.from_dict(recorded).update_threads == 1  # recorded before the field: its torch_threads


def test_the_torchrl_cli_passes_update_threads():
    from training.cli import build_parser
    from training.train.torchrl_command import torchrl_config_from_args

    parser = build_parser()
    base = ["train", "--backend", "torchrl", "--scenario", "top_observer", "--out", "unused"]
    assert torchrl_config_from_args(parser.parse_args([*base, "--update-threads", "2"])).update_threads == 2
    assert torchrl_config_from_args(parser.parse_args(base)).update_threads is None
