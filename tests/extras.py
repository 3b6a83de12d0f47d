"""The project's optional extras (pyproject.toml) as the top-level modules the tests import
from them, and which extra a missing module belongs to.

``make test`` installs every extra, and ``tests/test_extras_installed.py`` fails if one is
missing, so that a broken install is not hidden by tests that skip without their extra.
``make test-base`` installs none (the project and the ``test`` extra alone) and sets
:data:`ALLOW_MISSING_EXTRAS`: then ``conftest.py`` skips a test module whose import fails
for want of one of these modules, naming the extra.
"""

from __future__ import annotations

import importlib.util

#: Environment variable that lets test modules be skipped for a missing extra (``make test-base``).
ALLOW_MISSING_EXTRAS = "MOMA_TESTS_ALLOW_MISSING_EXTRAS"

#: Each optional extra -> the top-level modules of its packages that the code or the tests import.
EXTRA_MODULES: dict[str, tuple[str, ...]] = {
    "train": ("torch", "stable_baselines3", "sb3_contrib", "tqdm", "rich"),
    "graph": ("gtsam",),
    "torchrl": ("torchrl", "tensordict", "torch"),
    "ray": ("ray", "pandas", "pyarrow"),
    "dev": ("mpe2", "vmas", "supersuit"),
    "docs": ("mkdocs", "mkdocstrings", "material"),
}


def missing_extra(error: BaseException | None) -> str | None:
    """The extra(s) whose module ``error`` says is missing (``"'train' or 'torchrl'"`` when
    several have it), or None if ``error`` is not a ModuleNotFoundError of such a module."""
    if not isinstance(error, ModuleNotFoundError) or not error.name:
        return None
    root = error.name.split(".")[0]
    extras = [extra for extra, modules in EXTRA_MODULES.items() if root in modules]
    return " or ".join(repr(extra) for extra in extras) or None


def installed(extra: str) -> bool:
    """Whether every module of ``extra`` (:data:`EXTRA_MODULES`) can be imported here."""
    return all(importlib.util.find_spec(module) is not None for module in EXTRA_MODULES[extra])
