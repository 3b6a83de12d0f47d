"""An output folder holds one run (``moma_env.io.run_folder``).

A run writes into a temporary sibling folder that replaces the target whole at the
end; a failed or killed run leaves the previous results as they were; the
temporaries of a killed run are removed by the next run; a folder holding another
kind of run, or files that are not a run, is refused with one line.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from extras import installed
from moma_env.io import RUN_MARKER, RunFolderError, claim_run_folder, run_folder, run_kind, write_json
from training.cli import main

#: Whether Stable-Baselines3 (the train extra) is installed: not in make test-base.
HAS_TRAIN_EXTRA = installed("train")


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_second_run_replaces_the_first_whole(tmp_path):
    target = tmp_path / "out"
    with run_folder(target, "demo") as run:
        assert run.path.parent == tmp_path and run.path != target and not target.exists()
        write_json(run.path / "a.json", {"run": 1})
        (run.path / "sub").mkdir()
        (run.path / "sub" / "b.txt").write_text("first")
    assert run_kind(target) == "demo" and json.loads((target / "a.json").read_text()) == {"run": 1}
    with run_folder(target, "demo") as run:
        write_json(run.path / "c.json", {"run": 2})
        assert run.final(run.path / "c.json") == target / "c.json"
        assert run.final({"x": [run.path / "c.json"], "y": 3}) == {"x": [target / "c.json"], "y": 3}
    assert sorted(_files(target)) == [RUN_MARKER, "c.json"]  # nothing of the first run beside the second
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("interruption", [RuntimeError("figure failed"), KeyboardInterrupt()])
def test_a_failed_run_leaves_the_previous_results_and_no_temporary(tmp_path, interruption):
    target = tmp_path / "out"
    with run_folder(target, "demo") as run:
        (run.path / "summary.json").write_text("previous")
    before = _files(target)
    with pytest.raises(type(interruption)):
        with run_folder(target, "demo") as run:
            (run.path / "episodes.csv").write_text("new")
            raise interruption
    assert _files(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_the_temporaries_of_a_killed_run_are_removed_by_the_next(tmp_path):
    target = tmp_path / "out"
    killed = tmp_path / f".out.run-{_dead_pid()}-{'a' * 12}"  # a run killed half-way: a partial temporary folder
    (killed / "tum").mkdir(parents=True)
    (killed / "episodes.csv").write_text("partial")
    swapped = tmp_path / f".out.old-{_dead_pid()}-{'b' * 12}"  # killed between the two renames
    swapped.mkdir()
    alive = tmp_path / f".out.run-{os.getppid()}-{'c' * 12}"  # another live process's run: left alone
    alive.mkdir()
    other = tmp_path / f".elsewhere.run-{_dead_pid()}-{'d' * 12}"  # another target's: left alone
    other.mkdir()
    with run_folder(target, "demo") as run:
        (run.path / "summary.json").write_text("{}")
    assert not killed.exists() and not swapped.exists()
    assert alive.exists() and other.exists() and (target / "summary.json").is_file()


def test_a_folder_of_another_kind_or_of_other_files_is_refused(tmp_path):
    with run_folder(tmp_path / "square", "experiment square") as run:
        (run.path / "summary.json").write_text("{}")
    with pytest.raises(RunFolderError, match=r"holds a experiment square run's results, not a evaluate run's"):
        with run_folder(tmp_path / "square", "evaluate"):
            pytest.fail("the block must not run")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("do not delete")
    with pytest.raises(RunFolderError, match="holds files that are not a moma-env evaluate run"):
        with run_folder(mine, "evaluate"):
            pytest.fail("the block must not run")
    assert (mine / "thesis.tex").read_text() == "do not delete"
    (tmp_path / "file").write_text("x")
    with pytest.raises(RunFolderError, match="is a file"):
        with run_folder(tmp_path / "file", "evaluate"):
            pytest.fail("the block must not run")
    (tmp_path / "empty").mkdir()
    with run_folder(tmp_path / "empty", "evaluate") as run:
        (run.path / "x").write_text("1")
    assert run_kind(tmp_path / "empty") == "evaluate"
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / RUN_MARKER).write_text("[]")
    with pytest.raises(RunFolderError, match="is not a run marker"):
        run_kind(tmp_path / "bad")


def test_the_current_folder_or_one_holding_it_is_refused(tmp_path, monkeypatch):
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    for target in (".", "..", str(here), str(tmp_path)):
        with pytest.raises(RunFolderError, match="is the current folder or holds it"):
            with run_folder(target, "demo"):
                pytest.fail("the block must not run")
    with run_folder("sub", "demo") as run:  # a folder inside the current one is fine
        (run.path / "x.txt").write_text("1")
    assert (here / "sub" / "x.txt").read_text() == "1" and sorted(p.name for p in here.iterdir()) == ["sub"]


def test_claim_marks_a_folder_written_in_place(tmp_path):
    assert claim_run_folder(tmp_path / "train", "train") == tmp_path / "train"
    assert run_kind(tmp_path / "train") == "train"
    assert claim_run_folder(tmp_path / "train", "train") == tmp_path / "train"  # the same kind again: fine
    with pytest.raises(RunFolderError, match="holds a train run's results"):
        claim_run_folder(tmp_path / "train", "evaluate")
    legacy = tmp_path / "legacy"
    legacy.mkdir()
    (legacy / "manifest.json").write_text("{}")
    with pytest.raises(RunFolderError, match="not a moma-env train run"):
        claim_run_folder(legacy, "train")
    assert claim_run_folder(legacy, "train", unmarked_ok=True) == legacy and run_kind(legacy) == "train"


def _one_line_exit_2(argv, capsys) -> str:
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert captured.out == "" and len(lines) == 1
    return lines[0]


def test_the_commands_refuse_another_kind_of_run(tmp_path, capsys):
    square = tmp_path / "square"
    assert main(["experiment", "square", "--runs", "1", "--max-time", "1", "--out", str(square)]) == 1
    before = _files(square)
    capsys.readouterr()
    line = _one_line_exit_2(["evaluate", "--scenario", "caterpillar", "--policy", "random", "--episodes", "1", "--out", str(square)], capsys)
    assert str(square) in line and "experiment square" in line
    line = _one_line_exit_2(["experiment", "line", "--runs", "1", "--out", str(square)], capsys)
    assert "experiment square run's results, not a experiment line run's" in line
    line = _one_line_exit_2(["train", "--scenario", "caterpillar", "--timesteps", "8", "--out", str(square), "--no-progress"], capsys)
    # without the train extra (make test-base) the command stops before the folder, naming the extra
    assert "not a train run's" in line if HAS_TRAIN_EXTRA else "needs the 'train' extra" in line
    assert _files(square) == before


def test_an_evaluation_replaces_its_previous_results_whole(tmp_path, capsys):
    out = tmp_path / "eval"
    common = ["evaluate", "--scenario", "caterpillar", "--policy", "random", "--max-cycles", "5", "--out", str(out)]
    assert main([*common, "--episodes", "2"]) == 0
    assert (out / "tum" / "ep_001").is_dir()
    capsys.readouterr()
    assert main([*common, "--episodes", "1", "--json"]) == 0
    files = json.loads(capsys.readouterr().out)["files"]
    assert files["summary"] == str(out / "summary.json") and all(Path(path).exists() for path in files.values())
    assert not (out / "tum" / "ep_001").exists()  # the first run's second episode is gone with it
    assert json.loads((out / "summary.json").read_text())["summary"]["n_episodes"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["eval"]


def test_a_training_run_killed_before_its_first_checkpoint_is_cleaned_by_the_next(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    out = claim_run_folder(tmp_path / "train", "train")  # what the killed run had made
    stale = out / ".model_000000000032.0123456789ab.tmp.zip"
    stale.write_bytes(b"half a zip")
    argv = ["train", "--scenario", "caterpillar", "--timesteps", "32", "--num-envs", "1", "--n-steps", "32", "--batch-size", "32",
            "--net", "8", "--max-cycles", "20", "--out", str(out), "--no-progress", "--json"]
    assert main(argv) == 0
    assert not stale.exists()
    assert json.loads(capsys.readouterr().out)["num_timesteps"] >= 32  # a whole rollout of every slot
    assert run_kind(out) == "train"
