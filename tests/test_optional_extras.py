"""A module that needs an optional extra says which when the extra is missing, as a
ModuleNotFoundError (so ``pytest.importorskip`` and ``except ModuleNotFoundError`` treat it
as the missing module it is)."""

import importlib
import sys

import pytest


@pytest.mark.parametrize(
    ("module", "dependency", "message"),
    [
        ("moma_env.vector.torchrl", "torch", "needs the 'torchrl' extra"),
        ("moma_env.estimator.graph", "gtsam", "needs GTSAM: pip install 'moma_env\\[graph\\]'"),
    ],
)
def test_a_missing_extra_is_a_module_not_found_naming_it(monkeypatch, module, dependency, message):
    monkeypatch.setitem(sys.modules, dependency, None)  # importing it now fails as if it were not installed
    monkeypatch.delitem(sys.modules, module, raising=False)
    with pytest.raises(ModuleNotFoundError, match=message) as raised:
        importlib.import_module(module)
    assert raised.value.name == dependency
    with pytest.raises(pytest.skip.Exception):
        pytest.importorskip(module)
