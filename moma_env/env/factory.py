"""Constructors of the environments by configuration name (what the versioned modules call).

``parallel_env("top_observer", action_mode="velocity", n_ugvs=3)`` builds a
:class:`MomaParallelEnv`; every keyword that is not an environment option is a
field of the configuration's dataclass (``moma_env.scenarios``), validated by it.
``random_scenarios=True`` draws a new random layout of the same robots at every
reset from the env's seeded generator.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np
from pettingzoo.utils.conversions import parallel_to_aec

from moma_env.camera import FloorConfig, RenderConfig
from moma_env.config import ConfigError, from_mapping
from moma_env.env.centralised import CentralisedTeamEnv
from moma_env.env.config import EnvConfig, RewardConfig
from moma_env.env.parallel import MomaParallelEnv
from moma_env.scenarios import CONFIGURATIONS, Scenario

__all__ = ["parallel_env", "aec_env", "centralised_env", "scenario_factory", "versioned_constructors"]

#: Random draws tried before giving up on matching the robots of the base configuration.
_MAX_RANDOM_DRAWS = 200


def _robot_count_fields(config: Any) -> dict[str, Any]:
    return {f.name: getattr(config, f.name) for f in dataclasses.fields(config) if f.name in ("n_ugvs",)}


def scenario_factory(configuration: str, random_scenarios: bool = False, **overrides: Any):
    """``f(rng) -> Scenario`` for a configuration; random layouts keep the base's robots."""
    if configuration not in CONFIGURATIONS:
        raise ConfigError("configuration", f"unknown configuration {configuration!r}; known: {sorted(CONFIGURATIONS)}")
    cls = CONFIGURATIONS[configuration]
    base = from_mapping(cls, overrides, name=configuration)
    base_scenario = base.scenario()
    if not random_scenarios:
        return base_scenario
    wanted = _robot_count_fields(base)

    def factory(rng: np.random.Generator | None) -> Scenario:
        if rng is None:
            return base_scenario
        for _ in range(_MAX_RANDOM_DRAWS):
            config = cls.random(rng)
            if _robot_count_fields(config) == wanted:
                return config.scenario()
        raise RuntimeError(f"no random {configuration} layout with {wanted} in {_MAX_RANDOM_DRAWS} draws")

    return factory


def parallel_env(
    configuration: str,
    *,
    render_mode: str | None = None,
    max_cycles: int | None = None,
    action_mode: str = "switching",
    observer_agent: bool | None = None,
    rewards: RewardConfig | Mapping[str, float] | None = None,
    random_scenarios: bool = False,
    camera_backend: str = "geometric",
    render: RenderConfig | Mapping[str, Any] | None = None,
    floor: FloorConfig | Mapping[str, Any] | None = None,
    observer_image: tuple[int, int] | None = None,
    action_masks: bool = False,
    pad_observations: bool = False,
    localiser: Any = None,
    **overrides: Any,
) -> MomaParallelEnv:
    """The PettingZoo parallel env of ``configuration`` (see the module docstring).

    ``camera_backend``, ``render``, ``floor``, ``observer_image``,
    ``action_masks``, ``pad_observations`` and ``localiser`` are the
    :class:`EnvConfig` fields of the same names
    (``render`` and ``floor`` may be mappings of their fields).
    """
    if rewards is None:
        rewards = RewardConfig()
    elif isinstance(rewards, Mapping):
        rewards = from_mapping(RewardConfig, rewards, name="rewards")
    if isinstance(render, Mapping):
        render = from_mapping(RenderConfig, render, name="render")
    if isinstance(floor, Mapping):
        floor = from_mapping(FloorConfig, floor, name="floor")
    config = EnvConfig(
        action_mode=action_mode,
        observer_agent=observer_agent,
        max_cycles=max_cycles,
        rewards=rewards,
        camera_backend=camera_backend,
        render=render,
        floor=floor,
        observer_image=observer_image,
        action_masks=action_masks,
        pad_observations=pad_observations,
        localiser=localiser,
    )
    return MomaParallelEnv(
        scenario_factory(configuration, random_scenarios, **overrides),
        config,
        render_mode=render_mode,
        name=f"{configuration}_v0",
    )


def aec_env(configuration: str, **kwargs: Any):
    """The AEC version, through PettingZoo's converter (order enforced)."""
    return parallel_to_aec(parallel_env(configuration, **kwargs))


def centralised_env(configuration: str, **kwargs: Any) -> CentralisedTeamEnv:
    """The whole team as one Gymnasium agent (what ``gymnasium.make`` builds)."""
    return CentralisedTeamEnv(parallel_env(configuration, **kwargs))


def versioned_constructors(configuration: str):
    """``(parallel_env, env)`` of a versioned module such as ``moma_env.top_observer_v0``."""

    def make_parallel(**kwargs: Any) -> MomaParallelEnv:
        return parallel_env(configuration, **kwargs)

    def make_aec(**kwargs: Any):
        return aec_env(configuration, **kwargs)

    make_parallel.__doc__ = f"PettingZoo parallel env of the {configuration} configuration; kwargs as moma_env.env.factory.parallel_env."
    make_aec.__doc__ = f"PettingZoo AEC env of the {configuration} configuration; kwargs as moma_env.env.factory.parallel_env."
    return make_parallel, make_aec
