"""Test-session settings: windows go to SDL's dummy driver (CI has no screen), and
Hypothesis draws its examples from a fixed seed (``derandomize``, no example database),
so that the suite is the same run every time, as every seeded run of the project is."""

import os

from hypothesis import settings

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

settings.register_profile("moma_env", derandomize=True, database=None)
settings.load_profile("moma_env")
