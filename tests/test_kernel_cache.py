"""numba's caches of the package's kernels follow its sources (moma_env.kernel_cache)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from moma_env.kernel_cache import STAMP_NAME, clear_if_sources_changed, sources_digest


def make_package(root: Path) -> Path:
    """A package of two modules whose cached kernels call across them (b.g calls a.f)."""
    package = root / "kernelpkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text(
        textwrap.dedent(
            """
            import numba
            import numpy as np

            @numba.njit(cache=True)
            def f(x):
                return np.full(3, x * 1.0)
            """
        )
    )
    (package / "b.py").write_text(
        textwrap.dedent(
            """
            import numba
            from kernelpkg.a import f

            @numba.njit(cache=True)
            def g(x):
                return f(x) + 1.0
            """
        )
    )
    return package


def run_g(root: Path, guard: bool) -> str:
    """``b.g(2.0)`` in a fresh interpreter (after the guard on the package, if asked)."""
    code = "from kernelpkg.b import g; print(g(2.0).tolist())"
    if guard:
        code = (
            "from pathlib import Path; from moma_env.kernel_cache import clear_if_sources_changed; "
            f"clear_if_sources_changed(Path({str(root / 'kernelpkg')!r})); " + code
        )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), *sys.path]))
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_a_kernel_calling_an_edited_kernel_of_another_module_runs_the_new_code(tmp_path):
    package = make_package(tmp_path)
    assert run_g(tmp_path, guard=True) == "[3.0, 3.0, 3.0]"
    assert any(p.suffix == ".nbi" for p in (package / "__pycache__").iterdir())  # cached
    a = package / "a.py"
    a.write_text(a.read_text().replace("x * 1.0", "x * 3.0"))  # the callee changes, b.py does not
    stat = a.stat()
    os.utime(a, ns=(stat.st_atime_ns, stat.st_mtime_ns + 2_000_000_000))
    assert run_g(tmp_path, guard=True) == "[7.0, 7.0, 7.0]"


def test_the_caches_are_removed_only_when_the_kernels_sources_change(tmp_path):
    package = make_package(tmp_path)
    (package / "plain.py").write_text("X = 1\n")  # no kernel
    cache = package / "__pycache__"
    cache.mkdir()
    kept = cache / "a.cpython-311.pyc"
    stale = cache / "a.f-5.py311.nbi"
    for path in (stale, cache / "a.f-5.py311.1.nbc", kept):
        path.write_bytes(b"x")
    assert clear_if_sources_changed(package)  # no stamp yet: stale
    assert not any(p.suffix in (".nbi", ".nbc") for p in cache.iterdir())
    assert kept.exists() and sources_digest(package) in (cache / STAMP_NAME).read_text()
    stale.write_bytes(b"x")
    assert not clear_if_sources_changed(package)  # nothing changed
    (package / "plain.py").write_text("X = 2\n")  # a file without kernels changed
    assert not clear_if_sources_changed(package) and stale.exists()
    (package / "plain.py").write_text('"""Calls the numba kernels of a.py."""\nimport numpy\n')  # names numba, imports it not
    assert not clear_if_sources_changed(package) and stale.exists()
    b = package / "b.py"
    os.utime(b, ns=(b.stat().st_atime_ns, b.stat().st_mtime_ns + 1_000_000_000))  # touched, the same bytes
    assert not clear_if_sources_changed(package) and stale.exists()
    b.write_text(b.read_text().replace("+ 1.0", "+ 2.0"))  # a kernel's source changed
    assert clear_if_sources_changed(package)
    assert not stale.exists()
    stale.write_bytes(b"x")
    (package / "plain.py").write_text("def h():\n    from numba import njit\n    return njit\n")  # now imports it
    assert clear_if_sources_changed(package)
    assert not stale.exists()
