"""The reproducibility fingerprint tool (training/fingerprint.py)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from training.fingerprint import Case, fingerprint, main, serialise

SLED = Case("caterpillar_sled", 120, action_mode="switching", max_cycles=50)


def test_same_seed_same_hash_other_seed_other_hash():
    first, again, other = fingerprint(SLED, seed=3), fingerprint(SLED, seed=3), fingerprint(SLED, seed=4)
    assert first == again
    assert first["episodes"] == 3  # 120 steps of 50-step episodes
    assert other["sha256"] != first["sha256"]


def test_serialise_tells_apart_what_compares_equal():
    def text(value):
        out: list[str] = []
        serialise(value, out)
        return "|".join(out)

    assert text(0.1) != text(0.1 + 2**-56 * 3)  # one ulp apart
    assert text(np.zeros(2, np.float32)) != text(np.zeros(2, np.float64))
    assert text(np.zeros((2, 1))) != text(np.zeros((1, 2)))
    assert text([1]) != text((1,)) and text(1) != text(1.0) and text(True) != text(1)
    assert text({1, 2, 3}) == text({3, 2, 1})

    @dataclasses.dataclass
    class Point:
        x: float
        y: float

    assert text(Point(1.0, 2.0)) != text(Point(2.0, 1.0)) and text(Point(1.0, 2.0)) != text((1.0, 2.0))
    with pytest.raises(TypeError, match="cannot fingerprint a object"):
        text(object())


def test_check_passes_on_its_own_output_and_fails_on_a_changed_hash(tmp_path):
    out = tmp_path / "fp.json"
    lines: list[str] = []
    only = ["--only", "caterpillar_sled action_mode=switching max_cycles=250"]
    assert main([*only, "--out", str(out)], report=lines.append) == 0
    assert main([*only, "--check", str(out)], report=lines.append) == 0
    assert lines[-1].startswith("1 of 1 cases identical")
    data = json.loads(out.read_text())
    data["fingerprints"][0]["sha256"] = "0" * 64
    out.write_text(json.dumps(data))
    assert main([*only, "--check", str(out)], report=lines.append) == 1
    assert any(line.startswith("DIFFERS: caterpillar_sled") for line in lines)
    assert not any(line.startswith("note:") for line in lines)  # the same machine: nothing of it to name


def test_a_difference_names_what_of_the_machine_differs_from_the_references(tmp_path):
    from training.provenance import library_versions

    out = tmp_path / "fp.json"
    only = ["--only", "caterpillar_sled action_mode=switching max_cycles=250"]
    assert main([*only, "--out", str(out)], report=lambda line: None) == 0
    data = json.loads(out.read_text())
    assert data["machine"] == library_versions() and "cpu" in data["machine"] and "numpy" in data["machine"]
    data["machine"]["numpy"] = "0.0.1"
    out.write_text(json.dumps(data))
    lines: list[str] = []
    assert main([*only, "--check", str(out)], report=lines.append) == 0  # identical: the machine is not named
    assert not any(line.startswith("note:") for line in lines)
    data["fingerprints"][0]["sha256"] = "0" * 64
    out.write_text(json.dumps(data))
    assert main([*only, "--check", str(out)], report=lines.append) == 1
    assert f"note: the reference was made with numpy '0.0.1', this machine has {library_versions()['numpy']!r}" in lines


def test_bad_arguments_are_refused(tmp_path):
    with pytest.raises(ValueError, match="steps"):
        Case("square", 100)
    with pytest.raises(ValueError, match="steps"):
        Case("top_observer")
    with pytest.raises(SystemExit) as exit_info:
        main(["--only", "no such configuration"])
    assert exit_info.value.code == 2
    (tmp_path / "bad.json").write_text("[1, 2]")
    with pytest.raises(SystemExit):
        main(["--check", str(tmp_path / "bad.json")])


def test_an_experiment_run_is_hashed_whole_and_reproducibly():
    short = Case("line", max_time_s=8.0)
    first = fingerprint(short, seed=1)
    assert first == fingerprint(short, seed=1)
    assert first["case"] == "experiment line max_time_s=8.0"
    assert fingerprint(short, seed=2)["sha256"] != first["sha256"]
    assert fingerprint(Case("line", max_time_s=9.0), seed=1)["sha256"] != first["sha256"]


def test_a_preset_case_runs_the_experiment_under_that_preset():
    from moma_env.config import ConfigError

    plain = fingerprint(Case("line", max_time_s=8.0), seed=1)["sha256"]
    assert fingerprint(Case("line", preset="default", max_time_s=8.0), seed=1)["sha256"] == plain  # default: the same run
    with pytest.raises(ConfigError, match="unknown preset 'lab'"):
        fingerprint(Case("line", preset="lab", max_time_s=8.0), seed=1)
