"""The Ray of the test session: ``ray.init(num_cpus=2, include_dashboard=False)`` once,
``ray.shutdown()`` at the end (imported by the tests/test_ray_*.py modules)."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session")
def ray_local():
    """A local Ray with 2 CPUs for the whole test session; yields the ``ray`` module."""
    ray = pytest.importorskip("ray", reason="needs the 'ray' extra")
    if not ray.is_initialized():
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
                 runtime_env={"env_vars": {"OMP_NUM_THREADS": "1", "PYTHONPATH": os.pathsep.join(
                     p for p in (os.path.dirname(os.path.dirname(os.path.abspath(__file__))), os.environ.get("PYTHONPATH")) if p)}})
    yield ray
    if ray.is_initialized():
        ray.shutdown()
