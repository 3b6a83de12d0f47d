"""The clone agreement check (training.clone_agreement): its table and what it counts."""

import numpy as np
import pytest

from training.clone_agreement import main, start_rows
from training.train.config import TrainConfig
from training.train.envs import env_spec
from training.train.pretrain import choice_agreement, choice_rows, collect_demonstrations


def _greedy_rows():
    config = TrainConfig(scenario="top_observer_team4_legs", algo="maskable_ppo", route="centralised", envs=2, pretrain="greedy@1.5", steps=0)
    return collect_demonstrations(env_spec(config), "greedy@1.5", 2, 2400, seed=0, route="centralised")  # both kinds of choice rows


def test_the_teachers_starts_are_the_choice_rows_where_a_free_robot_advances():
    demos = _greedy_rows()
    starts, choice = start_rows(demos), choice_rows(demos)
    per_agent = demos.masks.reshape(len(demos), 4, 5)  # hold and four leg lengths
    for r in range(len(demos)):
        free = per_agent[r].sum(axis=1) > 1
        assert starts[r] == bool((demos.actions[r][free] != 0).any())
    assert (starts & choice).any() and (choice & ~starts).any()  # the greedy starts robots and holds them
    assert not (starts & ~choice).any()  # a robot free to choose makes a choice row
    held = demos.actions.copy()
    held[starts] = 0
    assert not start_rows(demos, held).any() and start_rows(demos, demos.actions).tolist() == starts.tolist()


def test_the_agreement_of_a_selection_counts_its_choice_rows_only():
    demos = _greedy_rows()
    choice, starts = choice_rows(demos), start_rows(demos)
    other = demos.actions.copy()
    wrong = np.flatnonzero(starts)[:2]
    other[wrong] = np.where(other[wrong] == 0, 3, 0)  # a start held, a hold started
    assert choice_agreement(demos, other, starts) == pytest.approx(1 - 2 / starts.sum())
    assert choice_agreement(demos, other, choice & ~starts) == 1.0
    assert choice_agreement(demos, other) == pytest.approx(1 - 2 / choice.sum())
    assert np.isnan(choice_agreement(demos, other, np.zeros(len(demos), dtype=bool)))


def test_it_prints_the_agreement_of_a_run_with_its_teacher(tmp_path, capsys):
    from training.train.run import train

    config = TrainConfig(scenario="top_observer_team4", algo="maskable_ppo", route="centralised", envs=2, net_arch=(16,),
                         pretrain="greedy", pretrain_rows=60, pretrain_epochs=1, dagger_rounds=0, steps=0, eval_every=10**6,
                         eval_episodes=1, eval_max_cycles=20)
    train(config, tmp_path / "run")
    assert main([str(tmp_path / "run"), "--copies", "2", "--rows", "200", "--workers", "1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("greedy on top_observer_team4, 2 copies from seed 2000000: 200 rows")
    table = {line.split("|")[1].strip(): line.split("|")[2:4] for line in lines[3:6]}
    assert list(table) == ["all", "the teacher starts a robot", "the teacher starts none"]
    counts = [int(table[k][0]) for k in table]
    assert counts[0] == counts[1] + counts[2] > 0
    shares = [float(table[k][1].strip(" %")) for k in table if table[k][1].strip() != "-"]
    assert all(0.0 <= s <= 100.0 for s in shares)
    words = lines[-1].split()
    assert lines[-1].startswith("On ") and int(words[4]) == counts[1] and 0 <= int(words[1]) <= counts[1]


def test_the_teacher_drives_envs_with_the_runs_own_timer(tmp_path, capsys, monkeypatch):
    """A run trained with ``--switch-horizon`` is compared on observations with its timer."""
    import training.clone_agreement as agreement
    from training.train.run import train

    config = TrainConfig(scenario="top_observer_team4", algo="maskable_ppo", route="centralised", envs=2, net_arch=(16,),
                         pretrain="greedy", pretrain_rows=60, pretrain_epochs=1, dagger_rounds=0, steps=0, eval_every=10**6,
                         eval_episodes=1, eval_max_cycles=20,
                         switch_horizon_s=60.0)
    train(config, tmp_path / "run")
    horizons = []
    collect = agreement.time_collection

    def recorded(spec, *args, **kwargs):
        horizons.append(spec.options.get("switch_horizon_s"))
        return collect(spec, *args, **kwargs)

    monkeypatch.setattr(agreement, "time_collection", recorded)
    assert main([str(tmp_path / "run"), "--copies", "2", "--rows", "100", "--workers", "1"]) == 0
    assert horizons == [60.0]


@pytest.mark.parametrize(
    "argv, words",
    [
        (["missing_run"], "missing_run"),
        (["--teacher", "gredy"], "did you mean 'greedy'?"),
        (["--copies", "2", "--workers", "3"], "--workers must be at most --copies"),
    ],
)
def test_bad_arguments_are_named(argv, words, capsys, tmp_path):
    if argv[0].startswith("--"):
        argv = ["policies/top_observer_team4_bc", *argv]
    with pytest.raises(SystemExit):
        main(argv)
    assert words in capsys.readouterr().err
