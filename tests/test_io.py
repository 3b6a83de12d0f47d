"""Atomic result writing: files appear whole or not at all."""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moma_env.io import (
    atomic_path,
    atomic_write_bytes,
    atomic_write_text,
    to_jsonable,
    write_csv,
    write_json,
)


class Boom(RuntimeError):
    pass


def test_atomic_write_text_writes_exact_content(tmp_path: Path) -> None:
    target = tmp_path / "a.txt"
    atomic_write_text(target, "line 1\r\nline 2\n\u00e9")
    assert target.read_bytes() == "line 1\r\nline 2\n\u00e9".encode()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_atomic_write_bytes_replaces_existing_file(tmp_path: Path) -> None:
    target = tmp_path / "b.bin"
    target.write_bytes(b"old content that is longer")
    atomic_write_bytes(target, b"\x00\x01new")
    assert target.read_bytes() == b"\x00\x01new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bin"]


def test_atomic_write_rejects_wrong_types(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="bytes"):
        atomic_write_bytes(tmp_path / "x", "text")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="str"):
        atomic_write_text(tmp_path / "x", b"bytes")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


def test_exception_mid_write_leaves_no_file_and_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "result.json"
    with pytest.raises(Boom):
        with atomic_path(target) as tmp:
            assert tmp.parent == tmp_path
            tmp.write_text('{"half": ')
            raise Boom("writer crashed")
    assert list(tmp_path.iterdir()) == []


def test_failed_rewrite_keeps_existing_file_intact(tmp_path: Path) -> None:
    target = tmp_path / "result.csv"
    target.write_text("a,b\n1,2\n")
    with pytest.raises(Boom):
        with atomic_path(target) as tmp:
            tmp.write_text("a,b\n3,")
            raise Boom("writer crashed")
    assert target.read_text() == "a,b\n1,2\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.csv"]


def test_keyboard_interrupt_also_cleans_up(tmp_path: Path) -> None:
    target = tmp_path / "r.txt"
    target.write_text("kept")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_text("partial")
            raise KeyboardInterrupt
    assert target.read_text() == "kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.txt"]


def test_write_json_failure_keeps_existing_file(tmp_path: Path) -> None:
    target = tmp_path / "r.json"
    write_json(target, {"ok": 1})
    before = target.read_text()
    with pytest.raises(TypeError, match=r"\$\.runs\[1\]"):
        write_json(target, {"runs": [1, object()]})
    assert target.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


def test_temp_path_keeps_suffix_so_savefig_infers_format(tmp_path: Path) -> None:
    from matplotlib.figure import Figure

    target = tmp_path / "figure.png"
    fig = Figure(figsize=(1, 1))
    fig.add_subplot().plot([0, 1], [0, 1])
    with atomic_path(target) as tmp:
        assert tmp.suffix == ".png"
        assert tmp != target
        fig.savefig(tmp)
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figure.png"]


def test_file_mode_follows_umask_like_open(tmp_path: Path) -> None:
    reference = tmp_path / "plain.txt"
    reference.write_text("x")
    target = tmp_path / "atomic.txt"
    atomic_write_text(target, "x")
    assert (target.stat().st_mode & 0o777) == (reference.stat().st_mode & 0o777)


def test_missing_folder_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="does not exist"):
        atomic_write_text(tmp_path / "no_such_dir" / "a.txt", "x")


def test_directory_target_is_rejected(tmp_path: Path) -> None:
    (tmp_path / "d").mkdir()
    with pytest.raises(IsADirectoryError):
        atomic_write_text(tmp_path / "d", "x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_write_json_sorted_indented_numpy_and_nan(tmp_path: Path) -> None:
    target = tmp_path / "m.json"
    obj = {
        "b": np.float64(1.5),
        "a": np.array([1.0, np.nan, np.inf]),
        "c": {"z": np.int64(3), "y": (np.bool_(True), None)},
        7: float("nan"),
    }
    write_json(target, obj)
    text = target.read_text()
    assert text.endswith("\n")
    assert text == json.dumps(
        {"7": None, "a": [1.0, None, None], "b": 1.5, "c": {"y": [True, None], "z": 3}},
        sort_keys=True,
        indent=2,
    ) + "\n"


def test_to_jsonable_uses_to_dict_and_paths() -> None:
    class HasDict:
        def to_dict(self) -> dict[str, float]:
            return {"x": np.float32(0.25)}

    assert to_jsonable({"m": HasDict(), "p": Path("a/b")}) == {"m": {"x": 0.25}, "p": "a/b"}


def test_to_jsonable_rejects_bad_keys() -> None:
    with pytest.raises(TypeError, match="keys"):
        to_jsonable({(1, 2): 3})


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=8))
def test_to_jsonable_floats_round_trip_or_null(values: list[float]) -> None:
    out = json.loads(json.dumps(to_jsonable(np.array(values, dtype=float)), allow_nan=False))
    assert len(out) == len(values)
    for v, o in zip(values, out):
        if math.isfinite(v):
            assert o == v
        else:
            assert o is None


def test_write_csv_header_is_union_in_first_seen_order(tmp_path: Path) -> None:
    target = tmp_path / "t.csv"
    rows = [{"run": 0, "me": np.float64(0.0197)}, {"run": 1, "ef": 0.1, "me": float("nan")}, {"note": "x,y"}]
    write_csv(target, rows)
    with open(target, newline="") as f:
        table = list(csv.reader(f))
    assert table == [
        ["run", "me", "ef", "note"],
        ["0", "0.0197", "", ""],
        ["1", "nan", "0.1", ""],
        ["", "", "", "x,y"],
    ]


def test_write_csv_explicit_fieldnames(tmp_path: Path) -> None:
    target = tmp_path / "t.csv"
    write_csv(target, [], fieldnames=["a", "b"])
    assert target.read_text() == "a,b\n"
    with pytest.raises(ValueError, match="'c'"):
        write_csv(target, [{"a": 1, "c": 2}], fieldnames=["a", "b"])
    assert target.read_text() == "a,b\n"


def test_write_csv_without_rows_or_fieldnames_fails(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="at least one row"):
        write_csv(tmp_path / "t.csv", [])
    with pytest.raises(TypeError, match="row 0"):
        write_csv(tmp_path / "t.csv", [[1, 2]])  # type: ignore[list-item]
    assert list(tmp_path.iterdir()) == []


def test_no_temp_files_left_after_many_writes(tmp_path: Path) -> None:
    target = tmp_path / "r.txt"
    for i in range(20):
        atomic_write_text(target, str(i))
    assert target.read_text() == "19"
    assert os.listdir(tmp_path) == ["r.txt"]


def test_read_json_in_names_what_is_wrong(tmp_path):
    import pytest

    from moma_env.io import read_json_in

    class Bad(ValueError):
        pass

    with pytest.raises(Bad, match="is not a run folder"):
        read_json_in(tmp_path / "nope", "a.json", Bad, "a run folder")
    with pytest.raises(Bad, match=r"holds no a\.json \(train first\)"):
        read_json_in(tmp_path, "a.json", Bad, hint="train first")
    (tmp_path / "a.json").write_text("{", encoding="utf-8")
    with pytest.raises(Bad, match="cannot read"):
        read_json_in(tmp_path, "a.json", Bad)
    (tmp_path / "a.json").write_text('{"k": 1}', encoding="utf-8")
    path, data = read_json_in(tmp_path, "a.json", Bad)
    assert path == tmp_path / "a.json" and data == {"k": 1}
