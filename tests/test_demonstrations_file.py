"""A cloned run keeps its teacher's demonstrations (``demonstrations.npz``) and another run
fits them instead of collecting them (``moma-env train --demonstrations RUN``): the same
weights, and refusals naming what differs."""

from __future__ import annotations

import json

import pytest
import torch

from moma_env.config import ConfigError
from training.cli import main
from training.train.command import train_command
from training.train.config import TrainConfig
from training.train.demonstrations import DEMONSTRATIONS
from training.train.run import PRETRAINING, train
from run_weights import final_weights

TASK = "top_observer_team4"


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario=TASK, algo="maskable_ppo", route="centralised", steps=0, envs=2, n_steps=16, batch_size=64, net_arch=(16,),
        max_cycles=60, checkpoint_every=10**6, eval_every=10**6, eval_episodes=1, eval_max_cycles=20, pretrain="greedy",
        pretrain_rows=240, pretrain_epochs=2, dagger_rounds=1, dagger_rows=120, dagger_epochs=2,
    )
    return TrainConfig(**(base | changes))


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    folder = tmp_path_factory.mktemp("source") / "clone"
    return folder, train(tiny(), folder)


def test_a_run_fitting_the_kept_rows_is_the_run_that_collects_them(source, tmp_path):
    folder, manifest = source
    assert (folder / DEMONSTRATIONS).is_file()
    reused = train(tiny(demonstrations=str(folder)), tmp_path / "reused")
    given, got = final_weights(folder, manifest), final_weights(tmp_path / "reused", reused)
    assert all(torch.equal(given[k], got[k]) for k in given)
    record = json.loads((tmp_path / "reused" / PRETRAINING).read_text())
    original = json.loads((folder / PRETRAINING).read_text())
    assert record["demonstrations"] == str(folder) and original["demonstrations"] is None
    assert record["rounds"] == original["rounds"] and record["teacher_episodes"] == original["teacher_episodes"]
    assert not (tmp_path / "reused" / DEMONSTRATIONS).exists()  # kept once, where they were collected


@pytest.mark.parametrize(
    "changes, field",
    [({"seed": 1}, "seed"), ({"pretrain_rows": 241}, "rows"), ({"pretrain": "greedy@1.5", "scenario": "top_observer_team4_legs"}, "teacher"),
     ({"envs": 3}, "envs"), ({"max_cycles": 61}, "env_options")],
)
def test_rows_collected_otherwise_are_refused_naming_the_setting(source, tmp_path, changes, field):
    folder, _ = source
    with pytest.raises(ConfigError, match=f"demonstrations.*{field}="):
        train(tiny(demonstrations=str(folder), **changes), tmp_path / "run")
    assert not (tmp_path / "run").exists()  # refused before the folder is claimed


def test_a_folder_without_kept_rows_and_a_run_without_a_teacher_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="demonstrations.*cannot read"):
        train(tiny(demonstrations=str(tmp_path)), tmp_path / "run")
    with pytest.raises(ConfigError, match="demonstrations.*give --pretrain"):
        tiny(pretrain=None, steps=32, demonstrations=str(tmp_path))
    with pytest.raises(ConfigError, match="demonstrations.*must be the folder"):
        tiny(demonstrations="")


def test_the_cli_takes_the_kept_rows(source, tmp_path, capsys):
    folder, _ = source
    out = tmp_path / "run"
    code = main(["train", "--scenario", TASK, "--algo", "maskable_ppo", "--route", "centralised", "--net", "16", "--num-envs", "2",
                 "--max-cycles", "60", "--timesteps", "0", "--eval-every", "0", "--pretrain", "greedy", "--pretrain-rows", "240",
                 "--pretrain-epochs", "1", "--dagger-rounds", "0", "--demonstrations", str(folder), "--no-progress", "--json",
                 "--out", str(out)])
    assert code == 0
    manifest = json.loads(capsys.readouterr().out)
    argv, missing = train_command(TrainConfig.from_dict(manifest["config"]), out)
    assert argv[argv.index("--demonstrations") + 1] == str(folder) and missing == []


@pytest.mark.parametrize("backend", ["rllib", "torchrl"])
@pytest.mark.parametrize("option, field", [(["--pretrain", "greedy"], "pretrain"), (["--dagger-teacher", "greedy"], "dagger_teacher"),
                                           (["--demonstrations", "runs/x"], "demonstrations")])
def test_the_other_backends_refuse_a_teacher(backend, option, field):
    from training.cli import build_parser
    from training.train.rllib_command import rllib_config_from_args
    from training.train.torchrl_command import torchrl_config_from_args

    scenario = "top_observer" if backend == "rllib" else "top_observer_team4"
    algo = ["--algo", "maskable_ppo"] if backend == "torchrl" else []
    args = build_parser().parse_args(["train", "--backend", backend, "--scenario", scenario, *algo, *option, "--out", "unused"])
    from_args = rllib_config_from_args if backend == "rllib" else torchrl_config_from_args
    with pytest.raises(ConfigError, match=f"{field}.*--backend {backend} does not clone a teacher"):
        from_args(args)
