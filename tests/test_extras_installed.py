"""The full set-up (``make test``) has every optional extra: a missing one fails here, naming
it, instead of hiding behind the tests that skip without it. ``make test-base`` (the project
alone) sets ``$MOMA_TESTS_ALLOW_MISSING_EXTRAS`` and checks only what a missing module is
reported as."""

import importlib.util
import os
from importlib import metadata

import pytest
from extras import ALLOW_MISSING_EXTRAS, EXTRA_MODULES, missing_extra
from packaging.requirements import Requirement

# The installed project's extras and their requirements, as pip read them from pyproject.toml.
EXTRAS = {
    extra: [r for r in map(Requirement, metadata.requires("moma_env") or []) if r.marker and r.marker.evaluate({"extra": extra})]
    for extra in metadata.metadata("moma_env").get_all("Provides-Extra")
}
full_setup = pytest.mark.skipif(bool(os.environ.get(ALLOW_MISSING_EXTRAS)), reason="make test-base: extras not installed")


def test_every_extra_of_the_project_is_mapped_to_its_modules():
    assert set(EXTRA_MODULES) == set(EXTRAS) - {"test"}


@full_setup
@pytest.mark.parametrize("extra", sorted(set(EXTRAS) - {"test"}))
def test_every_extra_is_installed(extra):
    missing = [module for module in EXTRA_MODULES[extra] if importlib.util.find_spec(module) is None]
    assert missing == [], f"the {extra!r} extra is not installed (pip install -e '.[{extra}]'): no {missing}"
    for requirement in EXTRAS[extra]:
        if requirement.name == "moma_env":  # the dev extra's own test extra
            continue
        assert requirement.specifier.contains(metadata.version(requirement.name), prereleases=True), (extra, str(requirement))


def test_a_missing_module_is_named_with_its_extra():
    assert missing_extra(ModuleNotFoundError("No module named 'gtsam'", name="gtsam")) == "'graph'"
    assert missing_extra(ModuleNotFoundError("x", name="stable_baselines3.common")) == "'train'"
    assert missing_extra(ModuleNotFoundError("x", name="torch")) == "'train' or 'torchrl'"
    assert missing_extra(ModuleNotFoundError("x", name="numpy")) is None
    assert missing_extra(ImportError("x", name="gtsam")) is None
    assert missing_extra(None) is None
