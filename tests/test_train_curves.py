"""Learning curves of training runs (training/train/curves.py): written by the evaluation
callback, redrawn from run folders, several seeds overlaid; bad folders exit 2 with one line.

Runs are tiny (plumbing, not learning), as in tests/test_train.py.
"""

from __future__ import annotations

import csv
import json

import pytest

from training.train import curves
from training.train.config import TrainConfig
from training.train.run import train

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario="top_observer", steps=128, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
        checkpoint_every=10**6, eval_every=64, eval_episodes=1, eval_max_cycles=15,
    )
    return TrainConfig(**(base | changes))


def _csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("curves")
    for seed in (0, 1):
        train(tiny(seed=seed), root / f"seed{seed}")
    return root / "seed0", root / "seed1"


def test_training_writes_one_curve_row_per_evaluation_and_the_figure(two_runs):
    run = two_runs[0]
    records = json.loads((run / "evaluations.json").read_text())["records"]
    rows = _csv(run / curves.CURVES_CSV)
    assert list(rows[0]) == list(curves.CURVE_COLUMNS)
    assert [int(r["timesteps"]) for r in rows] == [r["num_timesteps"] for r in records] == [64, 128]
    # top_observer's two UGVs are two slots of one copy on the shared route: half as many env steps
    assert [int(r["env_steps"]) for r in rows] == [r["env_steps"] for r in records] == [32, 64]
    for row, record in zip(rows, records):
        assert float(row["wall_time_s"]) == pytest.approx(record["wall_time_s"])
        assert float(row["success_rate"]) == record["success_rate"]
        assert float(row["switches"]) == record["n_switches"] and float(row["refusals"]) == record["n_refused"]
        assert float(row["return"]) == pytest.approx(record["total_reward"])
        assert float(row["final_error_mean_m"]) == pytest.approx(record["e_f_m"]) or record["e_f_m"] is None
    assert (run / curves.CURVES_PNG).read_bytes().startswith(PNG_SIGNATURE)
    assert not [p.name for p in run.iterdir() if ".tmp" in p.name]  # no temporaries left


def test_redraw_one_run_and_overlay_two(two_runs, tmp_path, capsys):
    run = two_runs[0]
    (run / curves.CURVES_PNG).unlink()
    before = (run / curves.CURVES_CSV).read_text()
    assert curves.main([str(run)]) == 0
    assert (run / curves.CURVES_PNG).read_bytes().startswith(PNG_SIGNATURE)
    assert (run / curves.CURVES_CSV).read_text() == before
    out = tmp_path / "seeds.png"
    assert curves.main([str(two_runs[0]), str(two_runs[1]), "--out", str(out)]) == 0
    assert out.read_bytes().startswith(PNG_SIGNATURE)
    band = _csv(tmp_path / "seeds.csv")
    assert [int(r["env_steps"]) for r in band] == [32, 64] and {r["runs"] for r in band} == {"2"}  # 64 and 128 timesteps
    rates = [[float(r["success_rate"]) for r in _csv(folder / curves.CURVES_CSV)] for folder in two_runs]
    for k, row in enumerate(band):
        pair = [rates[0][k], rates[1][k]]
        assert float(row["success_rate_min"]) == min(pair) and float(row["success_rate_max"]) == max(pair)
        assert float(row["success_rate_mean"]) == pytest.approx(sum(pair) / 2)
    assert "png: " in capsys.readouterr().out


def test_bad_folders_exit_2_with_one_line(two_runs, tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "evaluations.json").write_text("{not json")
    cases = [
        ([str(tmp_path / "nowhere")], "is not a folder"),
        ([str(empty)], "holds no evaluations.json"),
        ([str(broken)], "cannot read"),
        ([str(two_runs[0]), str(two_runs[1])], "give --out"),
        ([str(two_runs[0]), str(two_runs[1]), "--out", str(tmp_path / "x.pdf")], "must name a .png file"),
    ]
    for args, message in cases:
        capsys.readouterr()
        assert curves.main(args) == 2
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("curves: ") and message in lines[0], (args, captured.err)
        assert captured.out == ""
    assert not (tmp_path / "x.pdf").exists()


def test_runs_on_other_held_out_episodes_are_not_averaged(two_runs, tmp_path, capsys):
    other = tmp_path / "other"
    other.mkdir()
    data = json.loads((two_runs[0] / "evaluations.json").read_text())
    (other / "evaluations.json").write_text(json.dumps(data | {"first_seed": data["first_seed"] + 1}))
    assert curves.main([str(two_runs[0]), str(other), "--out", str(tmp_path / "f.png")]) == 2
    assert "different held-out episodes" in capsys.readouterr().err
    missing = json.loads((two_runs[0] / "evaluations.json").read_text())
    del missing["records"][0]["success_rate"]
    (other / "evaluations.json").write_text(json.dumps(missing))
    assert curves.main([str(other)]) == 2
    assert "evaluation record 0 lacks 'success_rate'" in capsys.readouterr().err


def test_the_curves_are_drawn_against_env_steps_or_timesteps_for_older_records(tmp_path):
    """Records with env steps are plotted against them; a run's records from before env steps
    were recorded fall back to timesteps, with the CSV's column empty (NaN)."""
    record = {"num_timesteps": 64, "wall_time_s": 1.0, "success_rate": 0.5, "time_to_goal_s": 20.0, "e_f_m": 0.01,
              "me_m": 0.01, "n_switches": 3.0, "n_refused": 0.0, "total_reward": -1.0}
    new = [record | {"env_steps": 32}, record | {"num_timesteps": 128, "env_steps": 64}]
    old = [{k: v for k, v in r.items() if k != "env_steps"} for r in new]
    assert curves.x_column([("new", curves.curve_rows(new))]) == "env_steps"
    assert curves.x_column([("old", curves.curve_rows(old))]) == "timesteps"
    assert curves.x_column([("new", curves.curve_rows(new)), ("old", curves.curve_rows(old))]) == "timesteps"
    for name, records in (("new", new), ("old", old)):
        (tmp_path / name).mkdir()
        paths = curves.write_curves(tmp_path / name, records)
        rows = _csv(paths["csv"])
        assert [r["env_steps"] for r in rows] == (["32", "64"] if name == "new" else ["nan", "nan"])
    bad = [{k: v for k, v in record.items() if k != "me_m"}]
    with pytest.raises(curves.CurvesError, match="lacks 'me_m'"):
        curves.curve_rows(bad)
