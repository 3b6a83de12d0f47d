"""DAgger from a finished run's policy (``moma-env train --init-from RUN --dagger-teacher T``):
the run's policy acts, T labels the states it reaches, and the policy is fitted to those
rows (and T's kept demonstrations, given ``--demonstrations``), before any PPO update.

Runs are tiny (networks of 16 units, a few hundred rows): the plumbing and the direction
of the fit, not its final quality.
"""

from __future__ import annotations

import json
from dataclasses import replace

import pytest
import torch

from moma_env.config import ConfigError
from training import clone_agreement
from training.cli import main
from training.train.command import train_command
from training.train.config import TrainConfig
from training.train.demonstrations import DEMONSTRATIONS, read_demonstrations
from training.train.run import PRETRAINING, train
from run_weights import final_weights

TASK = "top_observer_team4_legs"  # leg lengths: a teacher of 1.5 m legs corrects a clone of 0.5 m ones


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario=TASK, algo="maskable_ppo", route="centralised", steps=0, envs=2, n_steps=16, batch_size=64, net_arch=(16,),
        max_cycles=60, checkpoint_every=10**6, eval_every=10**6, eval_episodes=1, eval_max_cycles=20,
    )
    return TrainConfig(**(base | changes))


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A clone of the 0.5 m greedy policy: it never starts a 1.5 m leg."""
    folder = tmp_path_factory.mktemp("source") / "clone"
    manifest = train(tiny(pretrain="greedy@0.5", pretrain_rows=240, pretrain_epochs=3, dagger_rounds=0), folder)
    return folder, final_weights(folder, manifest)


def test_the_runs_policy_is_corrected_by_the_teacher_on_its_own_states(source, tmp_path):
    folder, start = source
    finals = []
    for name in ("a", "b"):
        config = tiny(init_from=str(folder), dagger_teacher="greedy@1.5", dagger_rounds=2, dagger_rows=200, dagger_epochs=3)
        finals.append(final_weights(tmp_path / name, train(config, tmp_path / name)))
    assert all(torch.equal(finals[0][k], finals[1][k]) for k in start)  # the same source and seed: the same weights
    assert not all(torch.equal(finals[0][k], start[k]) for k in start)
    record = json.loads((tmp_path / "a" / PRETRAINING).read_text())
    assert record["teacher"] is None and record["dagger_teacher"] == "greedy@1.5"
    rows = [r["rows"] for r in record["rounds"]]
    assert rows[0] == 0 and rows[1] >= 200 and rows[2] >= 2 * 200 and rows[2] > rows[1]  # the rounds' rows alone
    agreement = [r["learner_choice_agreement"] for r in record["rounds"][:2]]
    # the source never starts 1.5 m legs, which the teacher starts wherever a robot may start
    assert agreement[0] == 0.0 and 0.0 <= agreement[1] <= 1.0
    for fit in (record["rounds"][1]["epochs"], record["rounds"][2]["epochs"]):
        assert len(fit) == 3 and fit[-1]["policy_loss"] < fit[0]["policy_loss"]  # each round fits the teacher's labels


def test_without_the_teacher_a_run_from_another_runs_weights_runs_no_dagger(source, tmp_path):
    folder, _ = source
    train(tiny(init_from=str(folder), dagger_rounds=2, steps=32), tmp_path / "run")
    assert not (tmp_path / "run" / PRETRAINING).exists()
    with pytest.raises(ConfigError, match="steps: must be >= 1"):  # nothing to train without PPO or DAgger
        tiny(init_from=str(folder))


def test_dagger_from_a_run_fits_kept_demonstrations_of_its_teacher_beside_its_rounds(source, tmp_path):
    folder, start = source
    teacher = tmp_path / "teacher"  # a cloning of the labeller keeps its rows: other rows and seed than the DAgger run's
    train(tiny(pretrain="greedy@1.5", pretrain_rows=120, pretrain_epochs=1, dagger_rounds=0, seed=5), teacher)
    kept = read_demonstrations(tiny(pretrain="greedy@1.5", pretrain_rows=120, dagger_rounds=0, seed=5, demonstrations=str(teacher)))
    config = tiny(init_from=str(folder), dagger_teacher="greedy@1.5", dagger_rounds=1, dagger_rows=200, dagger_epochs=3)
    alone = final_weights(tmp_path / "alone", train(config, tmp_path / "alone"))
    both = final_weights(tmp_path / "both", train(replace(config, demonstrations=str(teacher)), tmp_path / "both"))
    assert not all(torch.equal(alone[k], both[k]) for k in start)
    record = json.loads((tmp_path / "both" / PRETRAINING).read_text())
    alone_record = json.loads((tmp_path / "alone" / PRETRAINING).read_text())
    assert record["demonstrations"] == str(teacher) and alone_record["demonstrations"] is None
    assert record["rounds"][0]["rows"] == len(kept) == 120
    assert record["rounds"][1]["rows"] == len(kept) + alone_record["rounds"][1]["rows"]  # the kept rows and the round's
    assert not (tmp_path / "both" / DEMONSTRATIONS).exists()  # DAgger keeps no teacher rows of its own


def test_dagger_from_a_run_refuses_another_teachers_rows_or_none_to_label(source, tmp_path):
    folder, _ = source  # a clone of greedy@0.5: its folder keeps greedy@0.5's rows
    config = tiny(init_from=str(folder), dagger_teacher="greedy@1.5", dagger_rounds=1, dagger_rows=100, demonstrations=str(folder))
    with pytest.raises(ConfigError, match="demonstrations.*teacher='greedy@0.5'.*teacher='greedy@1.5'"):
        train(config, tmp_path / "run")
    assert not (tmp_path / "run").exists()  # refused before the folder is claimed
    with pytest.raises(ConfigError, match="demonstrations.*or --init-from with --dagger-teacher"):
        tiny(init_from=str(folder), steps=32, demonstrations=str(folder))


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"dagger_teacher": "greedy@1.5"}, "give --pretrain or --init-from"),
        ({"dagger_teacher": "greedy@1.5", "init_from": "runs/x", "dagger_rounds": 0}, "--dagger-rounds of 1 or more"),
        ({"dagger_teacher": "greedy@1.5", "init_from": "runs/x", "algo": "a2c", "route": "shared"}, "DAgger fits PPO's actor"),
        ({"dagger_teacher": "greedy@1.5", "init_from": "runs/x", "action_mode": "velocity"}, "switching action mode"),
    ],
)
def test_dagger_without_a_policy_to_correct_is_refused_naming_the_field(changes, message):
    with pytest.raises(ConfigError, match=f"dagger_teacher.*{message}"):
        tiny(**changes)


def test_the_cli_passes_the_teacher_with_init_from(source, tmp_path, capsys):
    folder, _ = source
    out = tmp_path / "run"
    code = main(["train", "--scenario", TASK, "--algo", "maskable_ppo", "--route", "centralised", "--net", "16", "--num-envs", "2",
                 "--max-cycles", "60", "--timesteps", "0", "--eval-every", "0", "--init-from", str(folder),
                 "--dagger-teacher", "greedy@1.5", "--dagger-rounds", "1", "--dagger-rows", "100", "--dagger-epochs", "1",
                 "--no-progress", "--json", "--out", str(out)])
    assert code == 0
    manifest = json.loads(capsys.readouterr().out)
    record = json.loads((out / PRETRAINING).read_text())
    assert record["dagger_teacher"] == "greedy@1.5" and len(record["rounds"]) == 2
    argv, missing = train_command(TrainConfig.from_dict(manifest["config"]), out)
    assert argv[argv.index("--dagger-teacher") + 1] == "greedy@1.5" and argv[argv.index("--init-from") + 1] == str(folder)
    assert missing == []
    # the agreement command's teacher is the run's --dagger-teacher when it has no --pretrain
    assert clone_agreement.main([str(out), "--copies", "2", "--rows", "60", "--workers", "1"]) == 0
    assert capsys.readouterr().out.startswith(f"greedy@1.5 on {TASK}, 2 copies from seed 2000000: 60 rows")
