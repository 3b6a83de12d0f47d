"""Test-session settings: windows go to SDL's dummy driver (CI has no screen), and
Hypothesis draws its examples from a fixed seed (``derandomize``, no example database),
so that the suite is the same run every time, as every seeded run of the project is; the
fixtures several test modules share; and, with ``$MOMA_TESTS_ALLOW_MISSING_EXTRAS`` set (``make
test-base``), a test module that cannot be imported for want of an optional extra is
skipped, naming the extra, rather than failing to collect."""

import os

import pytest
from hypothesis import settings

from extras import ALLOW_MISSING_EXTRAS, missing_extra

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

settings.register_profile("moma_env", derandomize=True, database=None)
settings.load_profile("moma_env")


@pytest.fixture
def policies(tmp_path, monkeypatch):
    """An empty folder of published policies, in place of the repository's (``$MOMA_POLICIES_DIR``)."""
    from agents.learned import POLICIES_ENV

    folder = tmp_path / "policies"
    folder.mkdir()
    monkeypatch.setenv(POLICIES_ENV, str(folder))
    return folder


class _ModuleOfOptionalExtras(pytest.Module):
    """A test module whose import fails for want of an optional extra's module is skipped,
    naming the extra (only with ``$MOMA_TESTS_ALLOW_MISSING_EXTRAS``)."""

    def collect(self):
        try:  # collecting a module imports it first
            return super().collect()
        except self.CollectError as error:
            extra = missing_extra(error.__cause__)
            if extra is None:
                raise
            raise pytest.skip.Exception(f"needs the {extra} extra ({error.__cause__})", allow_module_level=True) from error


def pytest_pycollect_makemodule(module_path, parent):
    if os.environ.get(ALLOW_MISSING_EXTRAS) and module_path.name.startswith("test_"):
        return _ModuleOfOptionalExtras.from_parent(parent, path=module_path)
    return None
