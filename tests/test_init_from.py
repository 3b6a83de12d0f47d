"""``moma-env train --init-from RUN``: a run that starts from another run's networks and
normalisation statistics (training/train/init_from.py).

The runs are tiny (networks of 8 units, a few hundred timesteps): the plumbing, not learning.
"""

from __future__ import annotations

import json
import pickle
import re

import pytest
import torch
from stable_baselines3.common.callbacks import BaseCallback

from agents.learned import file_sha256
from moma_env.config import ConfigError
from training.cli import main
from training.train.command import train_command
from training.train.config import TrainConfig
from training.train.run import train


def tiny(**changes) -> TrainConfig:
    base = dict(scenario="top_observer", steps=256, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
                checkpoint_every=10**6, eval_episodes=1, eval_max_cycles=20)
    return TrainConfig(**(base | changes))


class AtStart(BaseCallback):
    """Keeps the weights, the optimiser's state and the statistics' count as learning starts,
    and the model at its end."""

    def _on_training_start(self) -> None:
        self.weights = {k: v.clone() for k, v in self.model.policy.state_dict().items()}
        self.adam = self.model.policy.optimizer.state_dict()["state"]
        self.obs_count = float(self.model.get_env().obs_rms.count)

    def _on_step(self) -> bool:
        return True


def _weights(model_zip) -> dict[str, torch.Tensor]:
    from stable_baselines3 import PPO

    return PPO.load(model_zip, device="cpu").policy.state_dict()


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    folder = tmp_path_factory.mktemp("source") / "run"
    return folder, train(tiny(seed=5), folder)


def test_a_run_starts_from_the_sources_networks_and_statistics_with_a_fresh_optimiser(source, tmp_path):
    folder, manifest = source
    start = AtStart()
    final = train(tiny(init_from=str(folder), learning_rate=1e-4, eval_every=10**6), tmp_path / "run", callbacks=[start])
    given = _weights(folder / manifest["model"])
    assert start.weights.keys() == given.keys()
    assert all(torch.equal(start.weights[k], given[k]) for k in given)
    assert start.adam == {}  # no moments carried over: the run's own optimiser at its own learning rate
    with open(folder / manifest["vecnormalize"], "rb") as f:
        count = float(pickle.load(f).obs_rms.count)
    assert start.obs_count == count + 2  # the source's statistics, plus the two slots' first observations
    record = json.loads((tmp_path / "run" / "init_from.json").read_text())
    assert record["run"] == str(folder) and record["num_timesteps"] == manifest["num_timesteps"]
    assert record["model_sha256"] == file_sha256(folder / manifest["model"])
    assert final["config"]["init_from"] == str(folder) and final["num_timesteps"] == 256
    learned = _weights(tmp_path / "run" / final["model"])
    assert any(not torch.equal(learned[k], given[k]) for k in given)  # and it learned from there
    evaluations = json.loads((tmp_path / "run" / "evaluations.json").read_text())["records"]
    assert evaluations[0]["num_timesteps"] == 0  # the curves start where the given policy is


def test_the_same_source_and_seed_give_the_same_weights(source, tmp_path):
    folder, _ = source
    finals = [train(tiny(init_from=str(folder), seed=3), tmp_path / name) for name in ("a", "b")]
    a, b = (_weights(tmp_path / name / f["model"]) for name, f in zip("ab", finals))
    assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"net_arch": (16,)}, "net_arch=[8], this run has [16]"),
        ({"route": "centralised"}, "route='shared', this run has 'centralised'"),
        ({"action_mode": "velocity"}, "action_mode='switching', this run has 'velocity'"),
        ({"scenario": "caterpillar"}, "scenario='top_observer', this run has 'caterpillar'"),
    ],
)
def test_a_source_of_another_task_or_network_is_refused_before_the_folder_is_claimed(source, tmp_path, changes, message):
    folder, _ = source
    with pytest.raises(ConfigError, match=f"^init_from: .*{re.escape(message)}"):
        train(tiny(init_from=str(folder), **changes), tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_a_folder_without_a_finished_run_is_refused_naming_the_field(tmp_path):
    (tmp_path / "empty").mkdir()
    for where, message in ((tmp_path / "empty", "holds no manifest.json"), (tmp_path / "missing", "is not a folder of a training run")):
        with pytest.raises(ConfigError, match=f"^init_from: .*{message}"):
            train(tiny(init_from=str(where)), tmp_path / "run")


@pytest.mark.parametrize(
    "changes, message",
    [({"init_from": ""}, "must be the folder of a finished training run"),
     ({"init_from": "runs/x", "pretrain": "greedy", "algo": "maskable_ppo", "scenario": "top_observer_team4"}, "give one")],
)
def test_bad_init_from_settings_are_refused_naming_the_field(changes, message):
    with pytest.raises(ConfigError, match=f"^init_from: .*{message}"):
        tiny(**changes)


def test_the_cli_starts_from_a_run_and_its_command_line_says_so(source, tmp_path, capsys):
    folder, _ = source
    out = tmp_path / "run"
    code = main(["train", "--scenario", "top_observer", "--timesteps", "64", "--num-envs", "1", "--n-steps", "32", "--batch-size", "32",
                 "--net", "8", "--max-cycles", "40", "--init-from", str(folder), "--out", str(out), "--no-progress", "--json"])
    assert code == 0
    manifest = json.loads(capsys.readouterr().out)
    assert manifest["config"]["init_from"] == str(folder)
    argv, missing = train_command(TrainConfig.from_dict(manifest["config"]), out)
    assert argv[argv.index("--init-from") + 1] == str(folder) and missing == []
    code = main(["train", "--scenario", "top_observer", "--net", "16", "--init-from", str(folder), "--out", str(tmp_path / "bad"), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "init_from" in err[0] and "net_arch" in err[0]
