"""The demonstrations benchmark (training.bench_demonstrations): what it reports, not how fast."""

import pytest

from training.bench_demonstrations import main


def test_it_prints_both_collections_rates_and_their_ratio(capsys):
    assert main(["--teacher", "greedy", "--scenario", "top_observer_team4", "--copies", "3", "--rows", "30", "--rounds", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "greedy on top_observer_team4, 3 copies, 30 rows, 2 rounds"
    rows = [line.split("|") for line in lines if line.startswith("| ") and line[2].isdigit()]
    assert [r[1].strip() for r in rows] == ["1", "2"]
    assert all(float(r[2]) > 0 and float(r[3]) > 0 for r in rows)
    assert lines[-1].startswith("2 processes / 1, per round: best ")


def test_a_runs_policy_acts_and_the_teacher_labels(tmp_path, capsys):
    from training.train.config import TrainConfig
    from training.train.run import train

    config = TrainConfig(scenario="top_observer_team4", algo="maskable_ppo", route="centralised", envs=2, net_arch=(16,),
                         pretrain="greedy", pretrain_rows=60, pretrain_epochs=1, dagger_rounds=0, steps=0, eval_every=10**6,
                         eval_episodes=1, eval_max_cycles=20)
    train(config, tmp_path / "run")
    argv = ["--teacher", "greedy", "--scenario", "top_observer_team4", "--copies", "2", "--rows", "30", "--rounds", "1"]
    assert main([*argv, "--learner", str(tmp_path / "run")]) == 0
    assert f"labelling the states of {tmp_path / 'run'}" in capsys.readouterr().out.splitlines()[0]
    with pytest.raises(SystemExit):
        main([*argv, "--learner", str(tmp_path / "missing")])
    assert "missing" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--teacher", "gredy"], "did you mean 'greedy'?"),
        (["--scenario", "nope"], "scenario"),
        (["--copies", "2", "--workers", "3"], "--workers must be at most --copies"),
        (["--workers", "1"], "worker count"),
    ],
)
def test_bad_arguments_are_named(argv, words, capsys):
    with pytest.raises(SystemExit):
        main(argv)
    assert words in capsys.readouterr().err
