"""Result files written whole or not at all.

Every writer here goes through :func:`atomic_path`: the content is written to a
temporary file in the destination's folder, flushed to disk (``fsync``) and then
renamed over the destination with :func:`os.replace`, which is atomic on POSIX and
Windows when both paths are on the same file system. A crash or an exception
half-way leaves the previous file (if any) untouched and no temporary file behind,
so a figure, a JSON summary or a CSV table is never half written.

A whole run's folder follows the same rule (:func:`run_folder`): a command writes
its results into a temporary sibling folder and only then replaces the target
folder whole, so an output folder holds one run, never a new file beside an old
one; a folder holding another kind of run (or files that are not a run) is refused
with one line (:class:`RunFolderError`), and the temporary folders of a killed run
are removed by the next run into the same folder. Each run folder holds a marker,
:data:`RUN_MARKER`, naming its kind.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import math
import os
import re
import shutil
import uuid
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "RUN_MARKER",
    "RunFolder",
    "RunFolderError",
    "run_folder",
    "claim_run_folder",
    "read_json_in",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_text",
    "to_jsonable",
    "write_json",
    "write_csv",
]

PathLike = str | os.PathLike[str]


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(directory: Path) -> None:
    """Persist a rename in ``directory`` (POSIX only; best effort elsewhere)."""
    if os.name != "posix":
        return
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _create_temp_beside(path: Path) -> Path:
    """Create an empty, uniquely named file next to ``path``; return its path.

    The temporary name keeps the destination's suffix (``.fig.3f2a...tmp.png``)
    so that writers inferring the format from the extension (matplotlib's
    ``savefig``) still do. The file is created with mode 0o666 filtered by the
    process umask, like a file opened with ``open(path, "w")``.
    """
    while True:
        tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}.tmp{path.suffix}")
        try:
            fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
        except FileExistsError:  # pragma: no cover - 48-bit random name collision
            continue
        os.close(fd)
        return tmp


@contextlib.contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """Context manager yielding a temporary path to write ``path`` through.

    Write the whole content to the yielded path inside the ``with`` block. On a
    normal exit the temporary file is fsynced and renamed over ``path``; if the
    block raises (any exception, including ``KeyboardInterrupt``), the temporary
    file is deleted, ``path`` is left as it was, and the exception propagates.

    The temporary file lives in the destination's folder (same file system, so
    the rename is atomic) and keeps the destination's suffix::

        with atomic_path("results/figure.png") as tmp:
            fig.savefig(tmp)

    Raises:
        FileNotFoundError: the destination's folder does not exist.
        IsADirectoryError: ``path`` is an existing directory.
    """
    target = Path(path)
    parent = target.parent
    if not parent.is_dir():
        raise FileNotFoundError(f"cannot write {str(target)!r}: folder {str(parent)!r} does not exist")
    if target.is_dir():
        raise IsADirectoryError(f"cannot write {str(target)!r}: it is a directory")
    tmp = _create_temp_beside(target)
    try:
        yield tmp
        _fsync_file(tmp)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    _fsync_dir(parent)


def atomic_write_bytes(path: PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"atomic_write_bytes needs bytes, got {type(data).__name__}")
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)


def atomic_write_text(path: PathLike, text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically, byte for byte (no newline translation)."""
    if not isinstance(text, str):
        raise TypeError(f"atomic_write_text needs a str, got {type(text).__name__}")
    atomic_write_bytes(path, text.encode(encoding))


def to_jsonable(obj: Any, _where: str = "$") -> Any:
    """Convert ``obj`` to plain JSON types.

    numpy scalars become Python numbers, arrays and tuples become lists,
    non-finite floats (NaN, +-inf) become ``None`` (JSON ``null``), paths become
    strings, objects with a ``to_dict()`` method and dataclasses become mappings.
    Mapping keys must be strings or integers (integers are written as strings).

    Raises:
        TypeError: a value or key of an unsupported type, with its location
            (``$.runs[3].name``).
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if math.isfinite(value) else None
    if isinstance(obj, np.ndarray):
        return [to_jsonable(v, f"{_where}[{i}]") for i, v in enumerate(obj.tolist())]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if hasattr(obj, "to_dict") and callable(obj.to_dict):
        return to_jsonable(obj.to_dict(), _where)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_jsonable(dataclasses.asdict(obj), _where)
    if isinstance(obj, Mapping):
        out: dict[str, Any] = {}
        for key, value in obj.items():
            if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
                key = str(int(key))
            elif not isinstance(key, str):
                raise TypeError(f"{_where}: JSON keys must be str or int, got {type(key).__name__} {key!r}")
            out[key] = to_jsonable(value, f"{_where}.{key}")
        return out
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v, f"{_where}[{i}]") for i, v in enumerate(obj)]
    raise TypeError(f"{_where}: cannot convert {type(obj).__name__} to JSON")


def write_json(path: PathLike, obj: Any) -> None:
    """Write ``obj`` as JSON (sorted keys, indent 2, trailing newline), atomically.

    Values are converted with :func:`to_jsonable` (numpy types, NaN -> null).
    """
    text = json.dumps(to_jsonable(obj), sort_keys=True, indent=2, allow_nan=False)
    atomic_write_text(path, text + "\n")


def read_json_in(folder: PathLike, name: str, error: type[Exception], folder_kind: str = "a folder", hint: str = "") -> tuple[Path, Any]:
    """``(path, parsed JSON)`` of the file ``name`` in ``folder``.

    Raises:
        error: one line naming what is wrong: ``folder`` is not ``folder_kind`` (not a
            folder), holds no ``name`` (with ``hint`` in brackets), or the file cannot be
            read or parsed.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise error(f"{str(folder)!r} is not {folder_kind}")
    path = folder / name
    if not path.is_file():
        raise error(f"{str(folder)!r} holds no {name}" + (f" ({hint})" if hint else ""))
    try:
        return path, json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise error(f"cannot read {str(path)!r}: {err}") from None


def write_csv(
    path: PathLike,
    rows: Sequence[Mapping[str, Any]],
    fieldnames: Sequence[str] | None = None,
) -> None:
    """Write ``rows`` (mappings) as CSV with a header row, atomically.

    The header is ``fieldnames`` if given (a row key outside it raises
    ``ValueError``), else every key of every row in order of first appearance
    (the first row's keys in its order, then new keys of later rows). A row
    lacking a key gets an empty cell. numpy scalars are written as Python numbers
    (floats with ``repr`` precision, NaN as ``nan``).

    Raises:
        ValueError: no rows and no ``fieldnames`` (no header to write), or a row
            key not in ``fieldnames``.
        TypeError: a row is not a mapping, or a key is not a string.
    """
    rows = list(rows)
    for i, row in enumerate(rows):
        if not isinstance(row, Mapping):
            raise TypeError(f"row {i} is a {type(row).__name__}, not a mapping")
    if fieldnames is None:
        if not rows:
            raise ValueError("write_csv needs at least one row or explicit fieldnames")
        header: dict[str, None] = {}
        for row in rows:
            for key in row:
                header.setdefault(key, None)
        fields = list(header)
    else:
        fields = list(fieldnames)
        known = set(fields)
        for i, row in enumerate(rows):
            extra = [k for k in row if k not in known]
            if extra:
                raise ValueError(f"row {i} has key {extra[0]!r} not in fieldnames {fields}")
    for key in fields:
        if not isinstance(key, str):
            raise TypeError(f"CSV column names must be str, got {type(key).__name__} {key!r}")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(fields)
    for row in rows:
        writer.writerow([_csv_cell(row[k]) if k in row else "" for k in fields])
    atomic_write_text(path, buffer.getvalue())


def _csv_cell(value: Any) -> Any:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return repr(value)
    return value


#: The marker file of a run folder: ``{"kind": "<command>", "format": 1}``.
RUN_MARKER = ".moma-run.json"
_RUN_MARKER_FORMAT = 1


class RunFolderError(ValueError):
    """An output folder that a run may not write into (one line naming the folder)."""


def run_kind(folder: PathLike) -> str | None:
    """The kind recorded by ``folder``'s :data:`RUN_MARKER`, or None without a marker.

    Raises:
        RunFolderError: the marker cannot be read or is not a run marker.
    """
    path = Path(folder) / RUN_MARKER
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise RunFolderError(f"cannot read the run marker {str(path)!r}: {err}") from None
    if not isinstance(data, dict) or not isinstance(data.get("kind"), str):
        raise RunFolderError(f"{str(path)!r} is not a run marker (no 'kind')")
    return data["kind"]


def _check_target(target: Path, kind: str, unmarked_ok: bool = False) -> bool:
    """Whether ``target`` exists as a folder a ``kind`` run may take over (False: it does
    not exist); :class:`RunFolderError` if it may not."""
    if not target.exists():
        return False
    if not target.is_dir():
        raise RunFolderError(f"output folder {str(target)!r} is a file, not a folder")
    found = run_kind(target)
    if found is None:
        if unmarked_ok or not any(target.iterdir()):
            return True
        raise RunFolderError(
            f"output folder {str(target)!r} holds files that are not a moma-env {kind} run: choose a new or empty folder"
        )
    if found != kind:
        raise RunFolderError(
            f"output folder {str(target)!r} holds a {found} run's results, not a {kind} run's: choose another folder or delete it"
        )
    return True


def _write_marker(folder: Path, kind: str) -> None:
    write_json(folder / RUN_MARKER, {"format": _RUN_MARKER_FORMAT, "kind": kind})


def _process_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # exists, owned by someone else (or cannot tell): leave its folder alone
    return True


def _sibling_pattern(target: Path) -> re.Pattern[str]:
    return re.compile(rf"^\.{re.escape(target.name)}\.(run|old)-(\d+)-[0-9a-f]{{12}}$")


def remove_stale_run_folders(target: PathLike) -> list[Path]:
    """Remove the temporary sibling folders of ``target`` left by killed runs (their
    process is gone); return what was removed. Folders of live processes stay."""
    target = Path(target)
    if not target.parent.is_dir():
        return []
    pattern = _sibling_pattern(target)
    removed = []
    for path in sorted(target.parent.iterdir()):
        match = pattern.match(path.name)
        if match and path.is_dir() and not _process_alive(int(match[2])):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def _sibling(target: Path, what: str) -> Path:
    return target.with_name(f".{target.name}.{what}-{os.getpid()}-{uuid.uuid4().hex[:12]}")


@dataclasses.dataclass(frozen=True)
class RunFolder:
    """A run being written: ``path`` is the temporary folder to write into, ``target``
    the folder it becomes when the run finishes."""

    path: Path
    target: Path

    def final(self, obj: Any) -> Any:
        """``obj`` (a path, or mappings and lists of paths) with every path under
        :attr:`path` moved under :attr:`target`: where the files will be."""
        if isinstance(obj, Path):
            try:
                return self.target / obj.relative_to(self.path)
            except ValueError:
                return obj
        if isinstance(obj, Mapping):
            return {key: self.final(value) for key, value in obj.items()}
        if isinstance(obj, list):
            return [self.final(value) for value in obj]
        return obj


@contextlib.contextmanager
def run_folder(target: PathLike, kind: str) -> Iterator[RunFolder]:
    """Write one ``kind`` run's results into ``target``, replacing what it held whole.

    Checks ``target`` first (before anything runs): it may be missing, empty, or hold a
    run of the same ``kind`` (its :data:`RUN_MARKER`); anything else raises
    :class:`RunFolderError`. Removes the temporary folders killed runs left beside it,
    then yields a :class:`RunFolder` whose ``path`` is a new temporary sibling folder
    (marked with ``kind``). On a normal exit the old ``target`` is moved aside, the
    temporary folder renamed to ``target`` and the old one deleted; if the block raises
    (including ``KeyboardInterrupt``), the temporary folder is deleted and ``target``
    keeps its previous results::

        with run_folder("runs/square", "experiment square") as run:
            write_json(run.path / "summary.json", summary)

    Raises:
        RunFolderError: ``target`` is a file, holds another kind of run, or holds files
            that are not a run (checked again before the replacement), or is the current
            folder or one holding it (which the replacement would pull away).
    """
    target = Path(target)
    if not isinstance(kind, str) or not kind:
        raise ValueError(f"kind must be a non-empty str, got {kind!r}")
    here = Path.cwd().resolve()
    if target.resolve() in (here, *here.parents):
        raise RunFolderError(f"output folder {str(target)!r} is the current folder or holds it: it would be replaced, choose a folder for the run")
    _check_target(target, kind)
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_run_folders(target)
    tmp = _sibling(target, "run")
    tmp.mkdir()
    try:
        _write_marker(tmp, kind)
        yield RunFolder(tmp, target)
        if _check_target(target, kind):
            old = _sibling(target, "old")
            os.replace(target, old)
            os.replace(tmp, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _fsync_dir(target.parent)


def claim_run_folder(target: PathLike, kind: str, unmarked_ok: bool = False) -> Path:
    """Check and mark ``target`` for a run that writes in place (a resumable training
    run: its files are written whole one by one, see :func:`atomic_path`): it is
    created if missing; a folder holding another kind of run, or (unless
    ``unmarked_ok``) files without a :data:`RUN_MARKER`, raises :class:`RunFolderError`.
    Returns ``target``."""
    target = Path(target)
    _check_target(target, kind, unmarked_ok)
    target.mkdir(parents=True, exist_ok=True)
    if run_kind(target) is None:
        _write_marker(target, kind)
    return target
