"""The registered configurations: build one by name with overrides, or draw a random one.

:data:`SPECS` lists every configuration's :class:`~moma_env.scenarios.spec.ScenarioSpec`
(defined in its own module); every lookup by name derives from it:
:data:`SCENARIO_SPECS`, :data:`CONFIGURATIONS`, ``moma_env.registration.GYMNASIUM_IDS``,
``agents.policies.SCRIPTED_POLICIES``, the planner's schedules and the plan checker's
observability rules. To add a configuration, write its module with its ``SPEC``, add
the ``SPEC`` here and a thin ``moma_env/<name>_v0.py``.

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
from moma_env.scenarios.caterpillar import SPEC as CATERPILLAR
from moma_env.scenarios.caterpillar_multi import SPEC as CATERPILLAR_MULTI
from moma_env.scenarios.caterpillar_sled import SPEC as CATERPILLAR_SLED
from moma_env.scenarios.base import Scenario
from moma_env.scenarios.common import ScenarioConfig
from moma_env.scenarios.spec import ScenarioSpec
from moma_env.scenarios.top_observer import SPEC as TOP_OBSERVER

__all__ = [
    "SPECS",
    "SCENARIO_SPECS",
    "CONFIGURATIONS",
    "scenario_spec",
    "config_type",
    "make_config",
    "make_scenario",
    "random_config",
]

#: Every registered configuration's spec, in a fixed order (the order of the name views).
SPECS: tuple[ScenarioSpec, ...] = (TOP_OBSERVER, CATERPILLAR, CATERPILLAR_SLED, CATERPILLAR_MULTI)


def _by_name(specs: tuple[ScenarioSpec, ...]) -> Mapping[str, ScenarioSpec]:
    """Name -> spec (read-only); RuntimeError if two specs share a name, a Gymnasium id or a module."""
    for key in ("name", "gymnasium_id", "pettingzoo_module"):
        values = [getattr(spec, key) for spec in specs]
        duplicates = sorted({v for v in values if values.count(v) > 1})
        if duplicates:
            raise RuntimeError(f"scenario specs share a {key}: {duplicates}")
    return MappingProxyType({spec.name: spec for spec in specs})


#: Configuration name -> its :class:`ScenarioSpec` (read-only).
SCENARIO_SPECS: Mapping[str, ScenarioSpec] = _by_name(SPECS)

#: Configuration name -> configuration class (read-only).
CONFIGURATIONS: Mapping[str, type[ScenarioConfig]] = MappingProxyType(
    {name: spec.config_type for name, spec in SCENARIO_SPECS.items()}
)


def scenario_spec(name: str) -> ScenarioSpec:
    """The spec of configuration ``name``; ConfigError listing the known names otherwise."""
    try:
        return SCENARIO_SPECS[name]
    except (KeyError, TypeError):
        raise ConfigError("scenario", f"unknown configuration {name!r}; known: {sorted(SCENARIO_SPECS)}") from None


def config_type(name: str) -> type[ScenarioConfig]:
    """The configuration class called ``name``; ConfigError listing the known names otherwise."""
    return scenario_spec(name).config_type


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
    return scenario_spec(name).random(rng)
