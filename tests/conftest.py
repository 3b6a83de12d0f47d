"""Test-session settings: windows go to SDL's dummy driver (CI has no screen), and
Hypothesis draws its examples from a fixed seed (``derandomize``, no example database),
so that the suite is the same run every time, as every seeded run of the project is; and
the fixtures several test modules share."""

import os

import pytest
from hypothesis import settings

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
