"""The configurations by name: build one with overrides, or draw a random one.

Names: ``"top_observer"``, ``"caterpillar"``, ``"caterpillar_sled"``,
``"caterpillar_multi"``. Overrides are the configuration's fields as keyword
arguments; a nested configuration (``camera``, ``estimator``) also accepts a
mapping of its own fields, e.g. ``make_scenario("caterpillar", camera={"fx": 500.0})``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from moma_env.config import ConfigError, from_mapping
from moma_env.scenarios.base import Scenario
from moma_env.scenarios.caterpillar import CaterpillarConfig
from moma_env.scenarios.caterpillar_multi import CaterpillarMultiConfig
from moma_env.scenarios.caterpillar_sled import CaterpillarSledConfig
from moma_env.scenarios.common import ScenarioConfig
from moma_env.scenarios.top_observer import TopObserverConfig

__all__ = ["CONFIGURATIONS", "config_type", "make_config", "make_scenario", "random_config"]

#: Configuration name -> configuration class (read-only).
CONFIGURATIONS: Mapping[str, type[ScenarioConfig]] = MappingProxyType(
    {
        cls.NAME: cls
        for cls in (TopObserverConfig, CaterpillarConfig, CaterpillarSledConfig, CaterpillarMultiConfig)
    }
)


def config_type(name: str) -> type[ScenarioConfig]:
    """The configuration class called ``name``; ConfigError listing the known names otherwise."""
    try:
        return CONFIGURATIONS[name]
    except (KeyError, TypeError):
        raise ConfigError("scenario", f"unknown configuration {name!r}; known: {sorted(CONFIGURATIONS)}") from None


def make_config(name: str, **overrides: Any) -> ScenarioConfig:
    """Configuration ``name`` with its defaults replaced by ``overrides``.

    Unknown override keys raise a ConfigError naming every one of them.
    """
    cls = config_type(name)
    known = sorted(f.name for f in dataclasses.fields(cls) if f.init)
    unknown = sorted(set(overrides) - set(known))
    if unknown:
        raise ConfigError(f"{name}.{unknown[0]}", f"unknown field(s) {unknown}; known fields are {known}")
    return from_mapping(cls, overrides, name=name)


def make_scenario(name: str, **overrides: Any) -> Scenario:
    """The :class:`Scenario` of configuration ``name`` with ``overrides`` (see :func:`make_config`)."""
    return make_config(name, **overrides).scenario()


def random_config(name: str, rng: np.random.Generator) -> ScenarioConfig:
    """A random valid configuration ``name`` (its class's ``random``); every draw from ``rng``."""
    return config_type(name).random(rng)
