"""What a sweep is: :class:`SweepSpec`, validated at the boundary, and its :class:`Cell` s.

A cell is one (scenario, policy, seed): one episode of the policy on the scenario,
the env reset with ``seed`` (a new random layout per seed with ``random_scenarios``).
Its result depends on nothing else (not on the backend, the worker, the order or how
cells are grouped into tasks), which is what makes the local and the Ray tables equal
byte for byte and a resumed sweep equal to an uninterrupted one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from moma_env.config import ConfigError, check_bool, check_count, check_unique, from_mapping
from moma_env.env.factory import checked_overrides
from moma_env.scenarios import CONFIGURATIONS
from moma_env.tasks import TASKS

__all__ = ["Cell", "SweepSpec", "chunks", "parse_seeds", "parse_names"]


@dataclass(frozen=True, order=True)
class Cell:
    """One episode of a sweep: ``policy`` on ``scenario`` reset with ``seed``."""

    scenario: str
    policy: str
    seed: int

    @property
    def key(self) -> str:
        """A stable text id of the cell (file names, logs)."""
        return f"{self.scenario}/{self.policy}/{self.seed}"


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"0:100"`` -> seeds 0..99 (a half-open range, as Python's); ``"3"`` -> (3,); ``"1,5,9"`` -> those.

    Raises:
        ConfigError: ``seeds``, for text that is not such a range or list, a negative
            seed, an empty range or a repeated seed.
    """
    text = text.strip()
    try:
        if ":" in text:
            start_text, _, stop_text = text.partition(":")
            start, stop = int(start_text), int(stop_text)
            seeds = tuple(range(start, stop))
        else:
            seeds = tuple(int(part) for part in text.split(","))
    except ValueError:
        raise ConfigError("seeds", f"expected START:STOP (e.g. 0:100) or a comma-separated list of integers, got {text!r}") from None
    if not seeds:
        raise ConfigError("seeds", f"{text!r} holds no seed (STOP must be > START)")
    if min(seeds) < 0:
        raise ConfigError("seeds", f"seeds must be >= 0, got {text!r}")
    check_unique("seeds", seeds)
    return seeds


def parse_names(field: str, text: str) -> tuple[str, ...]:
    """``"a,b"`` -> ``("a", "b")``; ConfigError naming ``field`` for an empty name or a repeat."""
    names = tuple(part.strip() for part in text.split(","))
    if not names or any(not name for name in names):
        raise ConfigError(field, f"expected comma-separated names, got {text!r}")
    check_unique(field, names)
    return names


@dataclass(frozen=True)
class SweepSpec:
    """A sweep: every scenario x policy x seed, one episode each.

    Attributes:
        scenarios: configuration or task names (:data:`moma_env.scenarios.CONFIGURATIONS`,
            :data:`moma_env.tasks.TASKS`).
        policies: policy specs of :func:`training.evaluation.policies.load_policy`
            (``"scripted"``, ``"random"``, a published policy's name; a trained run's folder
            must be readable on every worker).
        seeds: the reset seeds (>= 0, distinct).
        random_scenarios: a random layout per seed (else the configuration's default layout).
        max_cycles: episode length limit in steps (None: the scenario's).
        sample_actions: trained policies sample their actions (seeded by the episode's
            seed) instead of taking the most likely one; built-in policies are unchanged.
        overrides: fields of every scenario's configuration dataclass, e.g.
            ``{"leg_length": 1.5}`` (random layouts keep the rig's settings,
            ``ScenarioConfig.SETTING_FIELDS``); not ``max_cycles`` (the field above).
    """

    scenarios: tuple[str, ...]
    policies: tuple[str, ...]
    seeds: tuple[int, ...]
    random_scenarios: bool = True
    max_cycles: int | None = None
    sample_actions: bool = False
    overrides: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("scenarios", "policies", "seeds"):
            value = getattr(self, name)
            if not isinstance(value, tuple) or not value:
                raise ConfigError(name, f"must be a non-empty tuple, got {value!r}")
            check_unique(name, value)
        known = sorted(CONFIGURATIONS) + sorted(TASKS)
        for k, scenario in enumerate(self.scenarios):
            if scenario not in CONFIGURATIONS and scenario not in TASKS:
                raise ConfigError(f"scenarios[{k}]", f"unknown configuration or task {scenario!r}; known: {known}")
        for k, policy in enumerate(self.policies):
            if not isinstance(policy, str) or not policy:
                raise ConfigError(f"policies[{k}]", f"must be a non-empty string, got {policy!r}")
        for k, seed in enumerate(self.seeds):
            check_count(f"seeds[{k}]", seed, 0)
        check_bool("random_scenarios", self.random_scenarios)
        check_bool("sample_actions", self.sample_actions)
        if self.max_cycles is not None:
            check_count("max_cycles", self.max_cycles, 1)
        if not isinstance(self.overrides, Mapping):
            raise ConfigError("overrides", f"must be a mapping field -> value, got {self.overrides!r}")
        if "max_cycles" in self.overrides:
            raise ConfigError("overrides.max_cycles", "set the episode length with max_cycles (--max-cycles), not as an override")
        for scenario in self.scenarios:
            checked_overrides(scenario, self.overrides)
        object.__setattr__(self, "overrides", MappingProxyType(dict(self.overrides)))

    def cells(self) -> list[Cell]:
        """Every cell, in table order: scenarios, then policies, then seeds, as given."""
        return [Cell(s, p, seed) for s in self.scenarios for p in self.policies for seed in self.seeds]

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``sweep.json`` (tuples as lists)."""
        return {
            "scenarios": list(self.scenarios),
            "policies": list(self.policies),
            "seeds": list(self.seeds),
            "random_scenarios": self.random_scenarios,
            "max_cycles": self.max_cycles,
            "sample_actions": self.sample_actions,
            "overrides": dict(self.overrides),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "SweepSpec":
        """Inverse of :meth:`to_dict`; unknown keys raise ConfigError."""
        data = dict(data)
        for name in ("scenarios", "policies", "seeds"):
            if isinstance(data.get(name), list):
                data[name] = tuple(data[name])
        return from_mapping(cls, data, name="sweep")

    @property
    def options(self) -> dict[str, Any]:
        """The episode options every cell shares (what :func:`training.sweep.cells.run_cell` takes)."""
        return {
            "random_scenarios": self.random_scenarios,
            "max_cycles": self.max_cycles,
            "sample_actions": self.sample_actions,
            "overrides": dict(self.overrides),
        }


def chunks(cells: Sequence[Cell], size: int) -> list[list[Cell]]:
    """``cells`` in consecutive groups of ``size`` (the last may be shorter)."""
    check_count("cells_per_task", size, 1)
    return [list(cells[i:i + size]) for i in range(0, len(cells), size)]
