"""Evaluation sweeps without Ray (training/sweep, ``moma-env sweep --backend local``):
the spec's validation, one folder per sweep (lock, refusal), the table's layout, and a
sweep killed mid-run that resumes without redoing its finished cells."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("pyarrow", reason="the sweep's Parquet table needs the 'ray' extra")

from moma_env.config import ConfigError
from moma_env.io import RunFolderError
from training.cli import main
from training.sweep.backends import LocalBackend
from training.sweep.cells import run_cell
from training.sweep.folder import CELLS_DIR, SweepFolder
from training.sweep.run import sweep
from training.sweep.spec import Cell, SweepSpec, parse_seeds

REPO = Path(__file__).resolve().parents[1]
SPEC = SweepSpec(scenarios=("top_observer", "caterpillar"), policies=("scripted", "random"), seeds=(0, 1), max_cycles=25)


def test_seed_ranges_and_bad_specs_name_the_field():
    assert parse_seeds("0:4") == (0, 1, 2, 3)
    assert parse_seeds("7,3") == (7, 3)
    for text, field in (("4:4", "seeds"), ("a:b", "seeds"), ("-1:2", "seeds"), ("1,1", "seeds")):
        with pytest.raises(ConfigError) as err:
            parse_seeds(text)
        assert err.value.field == field
    with pytest.raises(ConfigError) as err:
        SweepSpec(scenarios=("top_observer", "nowhere"), policies=("scripted",), seeds=(0,))
    assert err.value.field == "scenarios[1]"
    with pytest.raises(ConfigError) as err:
        SweepSpec(scenarios=("top_observer",), policies=("scripted",), seeds=(0,), max_cycles=0)
    assert err.value.field == "max_cycles"


def test_cli_rejects_bad_input_in_one_line(tmp_path, capsys):
    assert main(["sweep", "--scenarios", "top_observer", "--policies", "scripted", "--seeds", "5:2", "--out", str(tmp_path / "a"),
                 "--backend", "local"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("moma-env sweep:") and "seeds" in err and "\n" not in err
    assert main(["sweep", "--scenarios", "top_observer", "--policies", "no_such_policy", "--seeds", "0:1", "--out", str(tmp_path / "b"),
                 "--backend", "local", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "no_such_policy" in err and "\n" not in err
    assert not (tmp_path / "b").exists()  # refused before the folder was made


def test_a_cell_is_one_harness_episode_and_the_table_is_in_spec_order(tmp_path):
    report = sweep(SPEC, tmp_path / "s", LocalBackend(1), cells_per_task=3)
    assert (report.n_cells, report.n_run) == (8, 8)
    lines = (tmp_path / "s" / "results.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert header[:4] == ["scenario", "policy", "seed", "success"]
    keys = [tuple(line.split(",")[:3]) for line in lines[1:]]
    assert keys == [(c.scenario, c.policy, str(c.seed)) for c in SPEC.cells()]
    # the row is run_cell's, which is the harness's episode
    row = run_cell(Cell("caterpillar", "random", 1), SPEC.options)
    with SweepFolder(tmp_path / "s", SPEC, resume=True) as folder:
        stored = folder.stored()[Cell("caterpillar", "random", 1)]
    assert json.dumps(stored) == json.dumps(row)  # NaN != NaN, so compare the text
    assert len(list((tmp_path / "s" / CELLS_DIR).glob("*.json"))) == 3  # one file per task of 3 cells
    summary = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert [(g["scenario"], g["policy"], g["n_episodes"]) for g in summary["groups"]] == [
        ("top_observer", "scripted", 2), ("top_observer", "random", 2), ("caterpillar", "scripted", 2), ("caterpillar", "random", 2)]
    assert (tmp_path / "s" / "sweep.png").stat().st_size > 0


def test_one_folder_holds_one_sweep(tmp_path):
    out = tmp_path / "s"
    with SweepFolder(out, SPEC):
        with pytest.raises(ConfigError, match="another sweep is running"):
            sweep(SPEC, out, LocalBackend(1), resume=True)
    other = SweepSpec(scenarios=("top_observer",), policies=("scripted",), seeds=(0,))
    with pytest.raises(ConfigError, match="already holds a sweep"):
        sweep(other, out, LocalBackend(1))
    with pytest.raises(ConfigError) as err:
        sweep(other, out, LocalBackend(1), resume=True)
    assert err.value.field == "scenarios"
    elsewhere = tmp_path / "evaluation"
    elsewhere.mkdir()
    (elsewhere / "summary.json").write_text("{}")
    with pytest.raises(RunFolderError, match="not a moma-env sweep run"):
        sweep(other, elsewhere, LocalBackend(1))
    assert sorted(p.name for p in elsewhere.iterdir()) == ["summary.json"]  # untouched


def _cell_files(out: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in (out / CELLS_DIR).glob("[0-9]*.json")}


def test_a_killed_sweep_resumes_without_redoing_finished_cells(tmp_path):
    spec = SweepSpec(scenarios=("top_observer",), policies=("scripted", "random"), seeds=tuple(range(6)), max_cycles=120)
    out = tmp_path / "killed"
    env = dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "training.cli", "sweep", "--scenarios", "top_observer", "--policies", "scripted,random", "--seeds", "0:6",
         "--max-cycles", "120", "--backend", "local", "--jobs", "1", "--cells-per-task", "1", "--no-progress", "--out", str(out)],
        cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 60
    try:
        while len(list((out / CELLS_DIR).glob("[0-9]*.json")) if (out / CELLS_DIR).is_dir() else []) < 3:
            assert proc.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() < deadline
            time.sleep(0.02)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    assert not (out / "results.csv").exists()
    before = _cell_files(out)
    assert 3 <= len(before) < 12
    with pytest.raises(ConfigError, match="already holds a sweep"):
        sweep(spec, out, LocalBackend(1))
    report = sweep(spec, out, LocalBackend(2), resume=True)
    assert report.n_run == 12 - len(before)
    after = _cell_files(out)
    assert {name: after[name] for name in before} == before  # finished cells untouched
    assert sorted(p.name for p in (out / CELLS_DIR).iterdir()) == sorted(after)  # no half-written file left
    fresh = sweep(spec, tmp_path / "fresh", LocalBackend(1), cells_per_task=5)
    assert fresh.n_run == 12
    for name in ("results.csv", "results.parquet", "summary.json"):
        assert (out / name).read_bytes() == (tmp_path / "fresh" / name).read_bytes(), name


def test_a_damaged_result_file_is_refused_naming_it(tmp_path):
    spec = SweepSpec(scenarios=("top_observer",), policies=("random",), seeds=(0, 1), max_cycles=5)
    out = tmp_path / "s"
    sweep(spec, out, LocalBackend(1))
    damaged = sorted((out / CELLS_DIR).glob("*.json"))[0]
    damaged.write_text('[{"scenario": "top_observer", "policy"')
    with pytest.raises(ConfigError, match=damaged.name):
        sweep(spec, out, LocalBackend(1), resume=True)


def test_sampling_applies_to_trained_policies_and_is_seeded():
    # the published team-of-four policy samples its actions; the greedy policy ignores the flag
    spec = SweepSpec(scenarios=("top_observer_team4",), policies=("greedy", "top_observer_team4_mppo"), seeds=(4,), max_cycles=200,
                     sample_actions=True)
    assert SweepSpec.from_dict(spec.to_dict()) == spec
    sampled = [run_cell(Cell("top_observer_team4", "top_observer_team4_mppo", 4), spec.options) for _ in range(2)]
    assert json.dumps(sampled[0]) == json.dumps(sampled[1])
    deterministic = run_cell(Cell("top_observer_team4", "top_observer_team4_mppo", 4), spec.options | {"sample_actions": False})
    assert json.dumps(deterministic) != json.dumps(sampled[0])
    greedy = run_cell(Cell("top_observer_team4", "greedy", 4), spec.options | {"max_cycles": 60})
    assert json.dumps(greedy) == json.dumps(run_cell(Cell("top_observer_team4", "greedy", 4), spec.options | {"max_cycles": 60, "sample_actions": False}))


def test_the_local_pool_does_not_fork_the_driver(monkeypatch):
    """Forked from a driver that ran torch with two threads (loading a trained policy does),
    a worker hangs at its first parallel torch operation (OpenMP's threads are not copied
    by a fork); the pool's workers start from a clean server process instead."""
    import moma_env.vector.parent_watch as parent_watch

    contexts = []

    class Recording(parent_watch.WorkerPool):
        def __init__(self, max_workers, context):
            contexts.append(context)
            super().__init__(max_workers, context)

    monkeypatch.setattr(parent_watch, "WorkerPool", Recording)
    spec = SweepSpec(scenarios=("top_observer",), policies=("random",), seeds=(0, 1), max_cycles=5)
    rows = []
    LocalBackend(2).run([[cell] for cell in spec.cells()], spec.options, lambda cells, out: rows.extend(out))
    assert len(rows) == 2
    assert len(contexts) == 1 and contexts[0] is not None and contexts[0].get_start_method() != "fork"
