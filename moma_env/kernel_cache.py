"""Numba's on-disk caches of this package's compiled kernels, kept in step with its sources.

numba keys a cached kernel to its own source file only (its modification time and size).
A kernel that calls a kernel of another module keeps its compiled copy of the callee when
only the callee's file changes, as after a ``git pull`` or an edit of that file: it then
runs the callee's old code, or fails to load with ``RuntimeError: In
'NRT_adapt_ndarray_to_python', 'descr' is NULL``. :func:`clear_if_sources_changed`, run
when ``moma_env`` is imported, removes every numba cache file in the package's
``__pycache__`` folders when the sources of its kernels (every ``.py`` file of the package
that imports numba) differ from those the caches were made from, so the kernels compile
again from the current sources (about 45 s for an env's kernels here). An import where no
file of the package changed since the last check reads only the files' modification
times and sizes (about 2 ms); an edit elsewhere costs one read of the kernels' sources.
A file counts as a kernel source if it imports numba: one that only names it (a docstring)
does not, so editing its text keeps the caches.
Caches numba keeps elsewhere (a read-only installation, with
``NUMBA_CACHE_DIR`` set) are left to numba.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from moma_env.io import atomic_write_text

__all__ = ["CACHE_SUFFIXES", "STAMP_NAME", "clear_if_sources_changed", "sources_digest"]

#: Suffixes of numba's cache files: the index of a kernel's compiled versions and their data.
CACHE_SUFFIXES = (".nbi", ".nbc")
#: File in the package's top ``__pycache__`` holding the digest of the sources the caches were made from.
STAMP_NAME = "numba_sources.sha256"


def _files_digest(package_dir: Path) -> str:
    """SHA-256 (hex) of every ``.py`` file's path under ``package_dir``, modification time (ns)
    and size, in sorted order: whether anything may have changed."""
    digest = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        info = path.stat()
        digest.update(f"{path.relative_to(package_dir).as_posix()}\0{info.st_mtime_ns}\0{info.st_size}\n".encode())
    return digest.hexdigest()


#: A line importing numba (``import numba``, ``import numba as nb``, ``from numba import ...``):
#: the mark of a file that defines or calls kernels.
_IMPORTS_NUMBA = re.compile(rb"^[ \t]*(?:import|from)[ \t]+numba\b", re.MULTILINE)


def sources_digest(package_dir: Path) -> str:
    """SHA-256 (hex) of the kernels' sources under ``package_dir``: the path and bytes of every
    ``.py`` file that imports numba, in sorted order (a file that only names numba in its
    text, as a docstring may, is not one)."""
    digest = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        text = path.read_bytes()
        if _IMPORTS_NUMBA.search(text):
            digest.update(path.relative_to(package_dir).as_posix().encode() + b"\0")
            digest.update(text + b"\0")
    return digest.hexdigest()


def _read_stamp(stamp: Path) -> tuple[str | None, str | None]:
    """(files digest, sources digest) of the last check, Nones without one."""
    try:
        files, sources = stamp.read_text().split("\n")[:2]
    except (OSError, ValueError):
        return None, None
    return files, sources


@contextmanager
def _locked(lock_path: Path) -> Iterator[None]:
    """An exclusive lock on ``lock_path`` (POSIX ``flock``; none where it does not exist), so
    processes importing the package at once clear and stamp the caches one at a time."""
    try:
        import fcntl
    except ImportError:  # not POSIX
        yield
        return
    with open(lock_path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def clear_if_sources_changed(package_dir: Path) -> bool:
    """Remove numba's cache files under ``package_dir`` when its kernels' sources changed since
    the last call; True if any were removed.

    The digests of the last check (:func:`sources_digest`, and the files' times and sizes)
    are kept in ``package_dir/__pycache__/``:data:`STAMP_NAME`; without it (caches made
    before this check existed) the caches count as stale. A package folder that cannot be
    written (numba then caches elsewhere) is left alone.
    """
    cache_dir = package_dir / "__pycache__"
    stamp = cache_dir / STAMP_NAME
    files = _files_digest(package_dir)
    if _read_stamp(stamp)[0] == files:
        return False
    try:
        cache_dir.mkdir(exist_ok=True)
    except OSError:
        return False
    if not os.access(cache_dir, os.W_OK):
        return False
    with _locked(cache_dir / "numba_sources.lock"):
        files_then, sources_then = _read_stamp(stamp)
        if files_then == files:  # another process checked meanwhile
            return False
        sources = sources_digest(package_dir)
        removed = False
        if sources != sources_then:
            for folder in package_dir.rglob("__pycache__"):
                for path in folder.iterdir():
                    if path.suffix in CACHE_SUFFIXES:
                        try:
                            path.unlink()
                            removed = True
                        except FileNotFoundError:
                            pass
        atomic_write_text(stamp, f"{files}\n{sources}\n")
    return removed
