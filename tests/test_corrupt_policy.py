"""A damaged policy folder: ``moma-env evaluate --policy DIR`` answers with one line naming
the file, exit status 2, and writes nothing (no traceback from SB3, zipfile or pickle).

Each case copies a tiny trained run and damages one file: a truncated or foreign
model zip, a truncated or foreign normalisation pickle, a truncated manifest, a
manifest whose values have the wrong type.
"""

from __future__ import annotations

import json
import pickle
import shutil
import zipfile
from pathlib import Path

import pytest

from agents.learned import MANIFEST
from training.cli import main
from training.train.config import TrainConfig
from training.train.run import train

pytest.importorskip("stable_baselines3")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("train") / "run"
    config = TrainConfig(scenario="top_observer", steps=32, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=20,
                         checkpoint_every=10**6)
    train(config, out)
    return out


def _damaged(run_dir: Path, where: Path) -> tuple[Path, dict]:
    shutil.copytree(run_dir, where)
    return where, json.loads((where / MANIFEST).read_text())


def _write_zip(path: Path) -> None:
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("notes.txt", "a zip, but not a Stable-Baselines3 model")


def _damage(kind: str, folder: Path, manifest: dict) -> str:
    """Damage ``folder`` as ``kind`` says; return the file the message must name."""
    model, stats = folder / manifest["model"], folder / manifest["vecnormalize"]
    if kind == "truncated model zip":
        model.write_bytes(model.read_bytes()[:200])
        return str(model)
    if kind == "foreign model zip":
        _write_zip(model)
        return str(model)
    if kind == "model not a zip":
        model.write_text("hello")
        return str(model)
    if kind == "truncated normalisation pickle":
        stats.write_bytes(stats.read_bytes()[:50])
        return str(stats)
    if kind == "foreign normalisation pickle":
        stats.write_bytes(pickle.dumps({"mean": [0.0]}))
        return str(stats)
    path = folder / MANIFEST
    if kind == "truncated manifest":
        path.write_text(path.read_text()[:40])
        return str(path)
    changes = {
        "manifest model of wrong type": {"model": 5},
        "manifest model a path": {"model": "../elsewhere.zip"},
        "manifest config of wrong type": {"config": "ppo"},
        "manifest timesteps of wrong type": {"num_timesteps": "many"},
        "manifest class of wrong type": {"sb3_class": ["PPO"]},
        "manifest statistics of wrong type": {"vecnormalize": 7},
        "manifest action mode of wrong type": {"config": manifest["config"] | {"action_mode": 1}},
    }[kind]
    path.write_text(json.dumps(manifest | changes))
    return str(path)


KINDS = [
    "truncated model zip", "foreign model zip", "model not a zip", "truncated normalisation pickle",
    "foreign normalisation pickle", "truncated manifest", "manifest model of wrong type", "manifest model a path",
    "manifest config of wrong type", "manifest timesteps of wrong type", "manifest class of wrong type",
    "manifest statistics of wrong type", "manifest action mode of wrong type",
]


@pytest.mark.parametrize("kind", KINDS)
def test_a_damaged_policy_folder_gives_one_line_naming_the_file_and_exit_2(run_dir, tmp_path, capsys, kind):
    folder, manifest = _damaged(run_dir, tmp_path / "policy")
    named = _damage(kind, folder, manifest)
    out = tmp_path / "eval"
    code = main(["evaluate", "--scenario", "top_observer", "--policy", str(folder), "--episodes", "1", "--out", str(out)])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2 and captured.out == "", kind
    assert len(lines) == 1 and lines[0].startswith("moma-env evaluate: "), lines
    assert repr(named) in lines[0], lines[0]
    assert "Traceback" not in captured.err
    assert not out.exists()


def test_the_undamaged_copy_evaluates(run_dir, tmp_path, capsys):
    folder, _ = _damaged(run_dir, tmp_path / "policy")
    assert main(["evaluate", "--scenario", "top_observer", "--policy", str(folder), "--episodes", "1", "--max-cycles", "5",
                 "--out", str(tmp_path / "eval")]) == 0
