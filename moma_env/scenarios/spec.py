"""One place per configuration: :class:`ScenarioSpec`.

Every configuration module (``moma_env/scenarios/top_observer.py``, ...) ends with
``SPEC = ScenarioSpec(...)``: its configuration class (with the class's random
generator), its Gymnasium id and versioned PettingZoo module, the planner's turn
schedule, the observability rule the plan checker applies while devices move, and
its scripted baseline policy. :mod:`moma_env.scenarios.registry` lists the specs;
everything looked up by configuration name derives from that list
(``CONFIGURATIONS``, ``registration.GYMNASIUM_IDS``, ``agents.policies.SCRIPTED_POLICIES``,
the planner's schedules, the plan checker's views), so a new configuration is one
module with its ``SPEC``, a line in the registry and a thin ``moma_env/<name>_v0.py``.

The schedule and the policy are *entry points*, strings ``"module:attribute"``
resolved on use by :func:`load_entry_point`: moma_env never imports ``agents``, and
the scenario modules do not import the planner (which imports them).
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from moma_env.config import ConfigError, check_bool
from moma_env.scenarios.common import ScenarioConfig
from moma_env.world import WorldConfig

__all__ = ["ScenarioSpec", "MotionViews", "no_motion_views", "load_entry_point"]

#: ``world -> {camera name: owners (robot or sled names) of the boards it must keep in view}``.
MotionViews = Callable[[WorldConfig], Mapping[str, tuple[str, ...]]]

_ENTRY_POINT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*")
_GYMNASIUM_ID = re.compile(r"moma_env/[A-Za-z][A-Za-z0-9]*-v[0-9]+")
_VERSIONED_MODULE = re.compile(r"(?P<base>[a-z][a-z0-9_]*)_v(?P<version>[0-9]+)")


def no_motion_views(world: WorldConfig) -> dict[str, tuple[str, ...]]:
    """No camera has to keep a board in view while devices move (the default)."""
    return {}


def load_entry_point(entry_point: str) -> Any:
    """The object an entry point ``"package.module:attribute"`` names (imports the module).

    Raises:
        ValueError: if ``entry_point`` is not of that form.
        ImportError: if the module cannot be imported or lacks the attribute.
    """
    if not isinstance(entry_point, str) or not _ENTRY_POINT.fullmatch(entry_point):
        raise ValueError(f"entry point must be 'package.module:attribute', got {entry_point!r}")
    module_name, attribute = entry_point.split(":")
    module = importlib.import_module(module_name)
    try:
        return getattr(module, attribute)
    except AttributeError:
        raise ImportError(f"entry point {entry_point!r}: module {module_name!r} has no {attribute!r}") from None


def _check_entry_point(field: str, value: object) -> None:
    if value is not None and (not isinstance(value, str) or not _ENTRY_POINT.fullmatch(value)):
        raise ConfigError(field, f"must be an entry point 'package.module:attribute' or None, got {value!r}")


@dataclass(frozen=True)
class ScenarioSpec:
    """Everything specific to one configuration, in one place (see the module docstring).

    Attributes:
        config_type: the configuration's dataclass (a :class:`ScenarioConfig`); its
            ``NAME`` is the configuration's name, its ``random`` the seeded random
            generator and its ``TEAM_FIELDS`` the fields random layouts keep.
        gymnasium_id: Gymnasium id of the whole team as one agent, e.g.
            ``"moma_env/TopObserver-v0"`` (registered by :mod:`moma_env.registration`).
        pettingzoo_module: name of the versioned module in ``moma_env`` with
            ``parallel_env`` and ``env``, ``"<name>_v<version>"``, e.g. ``"top_observer_v0"``;
            the PettingZoo id is ``"moma_env/<name>-v<version>"``.
        schedule: entry point of the planner's turn schedule, a callable taking the
            planner's :class:`~moma_env.planning.planner.Team` (e.g.
            ``"moma_env.planning.planner:top_observer_schedule"``); None: the planner
            does not support the configuration.
        scripted_policy: entry point of the scripted baseline's class (e.g.
            ``"agents.policies.top_observer:TopObserverLeapfrog"``); None: no baseline.
        observer_coverage: whether the plan checker's coverage rule applies: the
            robots' spread, grown by a board, stays within the observer camera's
            floor coverage (:func:`moma_env.planning.validate.coverage_radius`).
        motion_views: ``world -> {camera: board owners}``, the boards each camera
            must keep in view (range, field of view, incidence) whenever its
            carrier or the board's carrier moves, as the plan checker tests them.
    """

    config_type: type[ScenarioConfig]
    gymnasium_id: str
    pettingzoo_module: str
    schedule: str | None = None
    scripted_policy: str | None = None
    observer_coverage: bool = False
    motion_views: MotionViews = no_motion_views

    def __post_init__(self) -> None:
        if not (isinstance(self.config_type, type) and issubclass(self.config_type, ScenarioConfig)):
            raise ConfigError("scenario_spec.config_type", f"must be a ScenarioConfig subclass, got {self.config_type!r}")
        name = self.config_type.NAME
        if name == ScenarioConfig.NAME or not re.fullmatch(r"[a-z][a-z0-9_]*", name):
            raise ConfigError("scenario_spec.config_type", f"{self.config_type.__name__}.NAME must be a configuration name, got {name!r}")
        prefix = f"{name}.spec"
        if not isinstance(self.gymnasium_id, str) or not _GYMNASIUM_ID.fullmatch(self.gymnasium_id):
            raise ConfigError(f"{prefix}.gymnasium_id", f"must look like 'moma_env/TopObserver-v0', got {self.gymnasium_id!r}")
        match = _VERSIONED_MODULE.fullmatch(self.pettingzoo_module) if isinstance(self.pettingzoo_module, str) else None
        if match is None or match["base"] != name:
            raise ConfigError(f"{prefix}.pettingzoo_module", f"must be '{name}_v<version>', got {self.pettingzoo_module!r}")
        _check_entry_point(f"{prefix}.schedule", self.schedule)
        _check_entry_point(f"{prefix}.scripted_policy", self.scripted_policy)
        check_bool(f"{prefix}.observer_coverage", self.observer_coverage)
        if not callable(self.motion_views):
            raise ConfigError(f"{prefix}.motion_views", f"must be a callable world -> views, got {self.motion_views!r}")

    @property
    def name(self) -> str:
        """The configuration's name, e.g. ``"top_observer"``."""
        return self.config_type.NAME

    @property
    def pettingzoo_id(self) -> str:
        """The PettingZoo registry id, e.g. ``"moma_env/top_observer-v0"``."""
        match = _VERSIONED_MODULE.fullmatch(self.pettingzoo_module)
        assert match is not None  # checked at construction
        return f"moma_env/{match['base']}-v{match['version']}"

    @property
    def team_fields(self) -> Mapping[str, tuple[int, int]]:
        """Fields that fix the team (the env's agents) -> the inclusive range of values
        :meth:`random` can keep them at (the configuration class's ``TEAM_FIELDS``)."""
        return self.config_type.TEAM_FIELDS

    def random(self, rng: np.random.Generator, **team: int) -> ScenarioConfig:
        """A random valid configuration drawn from ``rng`` (the class's ``random``);
        ``team`` keeps fields of :attr:`team_fields` at the given values."""
        return self.config_type.random(rng, **team)

    def load_schedule(self) -> Callable[..., None]:
        """The planner's schedule (imports its module); ValueError if there is none."""
        if self.schedule is None:
            raise ValueError(f"configuration {self.name!r} has no planner schedule")
        return load_entry_point(self.schedule)

    def load_scripted_policy(self) -> type:
        """The scripted baseline's class (imports its module); ValueError if there is none."""
        if self.scripted_policy is None:
            raise ValueError(f"configuration {self.name!r} has no scripted policy")
        return load_entry_point(self.scripted_policy)
