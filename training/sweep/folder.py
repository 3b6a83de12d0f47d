"""A sweep's folder: one sweep, locked while it runs, one result file per finished cell.

Like a training run, a sweep writes in place so that it can be resumed: its folder is
marked as a ``sweep`` run (``.moma-run.json``, :func:`moma_env.io.claim_run_folder`), and a
folder holding another kind of run, or files that are not a moma-env run, is refused
(:class:`moma_env.io.RunFolderError`) before anything is written. Layout of ``OUT/``:

* ``sweep.json``: the :class:`~training.sweep.spec.SweepSpec` (written first; a folder
  holding another sweep's spec is refused, the same spec is resumed with ``resume``);
* ``sweep.lock``: an exclusive ``flock`` held while a sweep runs, so a second sweep
  into the same folder is refused at once (the kernel drops the lock of a killed process);
* ``cells/<s>_<p>_<seed>.json``: the rows of every finished task, one file per task named
  after its first cell (``s``, ``p``: the scenario's and the policy's index in the spec),
  each written whole or not at all (one ``fsync`` per task, not per cell: the driver's
  cost), floats in ``repr`` precision (NaN kept), so a resumed sweep reads back exactly
  what an uninterrupted one holds in memory;
* the table, summary and figure of :mod:`training.sweep.table`, written at the end.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from moma_env.config import ConfigError
from moma_env.io import atomic_write_text, claim_run_folder, run_kind, write_json
from training.sweep.spec import Cell, SweepSpec

__all__ = ["SweepFolder", "SPEC_FILE", "LOCK_FILE", "CELLS_DIR", "FORMAT", "RUN_KIND"]

SPEC_FILE = "sweep.json"
LOCK_FILE = "sweep.lock"
CELLS_DIR = "cells"
#: Version of the folder's layout.
FORMAT = 1
#: The folder's kind in its run marker (:func:`moma_env.io.claim_run_folder`).
RUN_KIND = "sweep"
_CELL_FILE = re.compile(r"^(\d+)_(\d+)_(\d+)\.json$")
#: A temporary of :func:`moma_env.io.atomic_path` beside a task file (hidden, ``.tmp`` in its name).
_TEMPORARY = re.compile(r"^\.\d+_\d+_\d+\..*tmp.*$")


class SweepFolder:
    """The folder ``out`` of sweep ``spec``; use as a context manager (takes and releases the lock).

    Args:
        out: the folder (created).
        spec: the sweep.
        resume: continue the sweep already in ``out`` (it must have the same spec);
            without it a folder that holds a sweep is refused.

    Raises (on entering):
        RunFolderError: ``out`` holds another kind of run or files that are not a run.
        ConfigError: ``out``, when another sweep holds the lock, the folder holds a
            sweep and ``resume`` is False, or ``resume`` and the folder's spec differs
            (naming the differing field) or there is none.
    """

    def __init__(self, out: str | Path, spec: SweepSpec, resume: bool = False):
        self.out = Path(out)
        self.spec = spec
        self.resume = resume
        self._lock_fd: int | None = None
        self._scenario_index = {name: k for k, name in enumerate(spec.scenarios)}
        self._policy_index = {name: k for k, name in enumerate(spec.policies)}

    def __enter__(self) -> "SweepFolder":
        if self.out.exists() and not self.out.is_dir():
            raise ConfigError("out", f"{str(self.out)!r} is a file, not a folder")
        if not self.resume or (self.out.is_dir() and run_kind(self.out) not in (None, RUN_KIND)):
            claim_run_folder(self.out, RUN_KIND)  # RunFolderError: another kind of run, or files that are not a run
        self.out.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.out / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise ConfigError("out", f"another sweep is running in {str(self.out)!r} (it holds {LOCK_FILE}); one folder holds one sweep") from None
        self._lock_fd = fd
        try:
            self._check_spec()
        except BaseException:
            self._release()
            raise
        (self.out / CELLS_DIR).mkdir(exist_ok=True)
        for path in (self.out / CELLS_DIR).iterdir():  # half-written files of a killed sweep (the lock is ours)
            if _TEMPORARY.match(path.name):
                path.unlink(missing_ok=True)
        return self

    def __exit__(self, *exc: object) -> None:
        self._release()

    def _release(self) -> None:
        if self._lock_fd is not None:
            fcntl.flock(self._lock_fd, fcntl.LOCK_UN)
            os.close(self._lock_fd)
            self._lock_fd = None

    def _check_spec(self) -> None:
        path = self.out / SPEC_FILE
        if not path.is_file():
            if self.resume:
                raise ConfigError("out", f"{str(self.out)!r} holds no sweep to resume (no {SPEC_FILE})")
            write_json(path, {"format": FORMAT, "spec": self.spec.to_dict()})
            return
        if not self.resume:
            raise ConfigError("out", f"{str(self.out)!r} already holds a sweep; pass --resume to continue it or choose another folder")
        try:
            stored = json.loads(path.read_text(encoding="utf-8"))
            if stored.get("format") != FORMAT:
                raise ValueError(f"format {stored.get('format')!r}, expected {FORMAT}")
            old = SweepSpec.from_dict(stored["spec"]).to_dict()
        except (ValueError, KeyError, TypeError, AttributeError, ConfigError) as err:
            raise ConfigError("out", f"{str(path)!r} is not a readable sweep spec: {err}") from None
        new = self.spec.to_dict()
        for name, value in old.items():
            if new[name] != value:
                raise ConfigError(name, f"the sweep in {str(self.out)!r} has {value!r}, the command gives {new[name]!r}; resume with its own settings")

    def cell_path(self, cell: Cell) -> Path:
        """The file of a task whose first cell is ``cell``."""
        return self.out / CELLS_DIR / f"{self._scenario_index[cell.scenario]:03d}_{self._policy_index[cell.policy]:03d}_{cell.seed}.json"

    def write_rows(self, cells: Sequence[Cell], rows: Sequence[dict[str, Any]]) -> None:
        """Store a finished task's rows in one file, whole or not at all.

        Raises:
            ValueError: no cells, or a row that does not name its cell.
        """
        if not cells or len(cells) != len(rows):
            raise ValueError(f"a task's rows must match its cells, got {len(cells)} cells and {len(rows)} rows")
        for cell, row in zip(cells, rows):
            if (row.get("scenario"), row.get("policy"), row.get("seed")) != (cell.scenario, cell.policy, cell.seed):
                raise ValueError(f"the row of cell {cell.key} names another cell")
        atomic_write_text(self.cell_path(cells[0]), json.dumps(list(rows), allow_nan=True))

    def stored(self) -> dict[Cell, dict[str, Any]]:
        """Every stored row by its cell.

        Raises:
            ConfigError: ``out``, for a file that is unreadable or holds a row of no cell of the spec.
        """
        known = set(self.spec.cells())
        out: dict[Cell, dict[str, Any]] = {}
        folder = self.out / CELLS_DIR
        for path in sorted(folder.iterdir()) if folder.is_dir() else []:
            if not _CELL_FILE.match(path.name):
                continue
            try:
                rows = json.loads(path.read_text(encoding="utf-8"))
                cells = [Cell(r["scenario"], r["policy"], r["seed"]) for r in rows]
            except (ValueError, TypeError, KeyError) as err:
                raise ConfigError("out", f"{str(path)!r} is not a readable task result: {err}") from None
            for cell, row in zip(cells, rows):
                if cell not in known:
                    raise ConfigError("out", f"{str(path)!r} holds a result of {cell.key}, which is no cell of this sweep")
                out[cell] = row
        return out

    def finished(self) -> set[Cell]:
        """The cells of the spec with a stored row."""
        return set(self.stored())
