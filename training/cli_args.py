"""Argument types and names of the ``moma-env`` command line, without heavy imports.

The parser of ``moma-env`` is built from this module, :mod:`moma_env.registration`
and :mod:`moma_env.tasks` only (names, not the envs), so that ``moma-env --help``
and every subcommand's ``--help`` answer without importing the simulator, OpenCV,
pymunk, matplotlib, torch or Stable-Baselines3. The names here mirror the real
registries; ``tests/test_cli_light.py`` checks that they match.
"""

from __future__ import annotations

import argparse
import difflib
import json
from collections.abc import Callable, Sequence
from typing import Any

from moma_env.config import ConfigError
from moma_env.registration import CONFIGURATION_NAMES
from moma_env.tasks import TASKS

__all__ = [
    "SCENARIO_NAMES",
    "CAMERA_BACKEND_NAMES",
    "PRESET_NAMES",
    "ACTION_MODE_NAMES",
    "TEAM_ACTION_NAMES",
    "ESTIMATOR_NAMES",
    "SET_HELP",
    "name_list",
    "int_at_least",
    "int_at_least_or",
    "int_list",
    "field_assignment",
    "field_assignments",
    "positive_float",
    "choice",
]

#: What ``--scenario`` accepts: the configurations, then the tasks.
SCENARIO_NAMES: tuple[str, ...] = CONFIGURATION_NAMES + tuple(sorted(TASKS))
#: ``moma_env.camera.CAMERA_BACKENDS``.
CAMERA_BACKEND_NAMES: tuple[str, ...] = ("geometric", "rendered")
#: ``sorted(training.experiments.presets.PRESETS)``.
PRESET_NAMES: tuple[str, ...] = ("default", "paper")
#: ``moma_env.env.config.ACTION_MODES`` in the command line's order (the default first).
ACTION_MODE_NAMES: tuple[str, ...] = ("switching", "velocity")
#: ``moma_env.env.config.TEAM_ACTIONS`` (the default first).
TEAM_ACTION_NAMES: tuple[str, ...] = ("per_agent", "one_start")
#: ``moma_env.estimator.registry.ESTIMATORS`` (the paper's ``moma`` first).
ESTIMATOR_NAMES: tuple[str, ...] = ("moma", "fused", "ekf", "graph", "graph_vision")
#: The help of ``--set FIELD=VALUE`` (``evaluate``, ``sweep``: ``moma_env.env.factory.checked_overrides``).
SET_HELP = ("a field of the configuration's dataclass, for every layout (random ones keep the rig's settings: estimator, leg_length, "
            "dwell_s, goal tolerances, max_cycles), e.g. --set leg_length=1.5, or an env option (EnvConfig: tracking, leg_lengths, "
            "switch_horizon_s, rewards, ...; not action_mode or max_cycles, which have their own options), e.g. "
            "--set 'tracking={\"fill\": 0.5}'; the value is read as JSON; repeatable (default: none)")


def int_at_least(minimum: int, what: str) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer {what}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{what} must be >= {minimum}, got {value}")
        return value

    return parse


def int_list(what: str, minimum: int) -> Callable[[str], list[int]]:
    """An argparse type: comma-separated integers >= ``minimum`` (``"64,256,1024"``), at least one."""

    def parse(text: str) -> list[int]:
        try:
            values = [int(part) for part in text.replace(",", " ").split()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated integer {what}s such as 64,256, got {text!r}") from None
        if not values or min(values) < minimum:
            raise argparse.ArgumentTypeError(f"each {what} must be an integer >= {minimum}, got {text!r}")
        return values

    return parse


def field_assignment(text: str) -> tuple[str, Any]:
    """An argparse type: ``FIELD=VALUE``, the value read as JSON (``1.5``, ``true``,
    ``{"window": 20}``) or, failing that, as the string itself."""
    name, sep, raw = text.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier():
        raise argparse.ArgumentTypeError(f"expected FIELD=VALUE (e.g. leg_length=1.5), got {text!r}")
    try:
        value = json.loads(raw)
    except json.JSONDecodeError:
        value = raw
    return name, value


def field_assignments(pairs: Sequence[tuple[str, Any]] | None) -> dict[str, Any]:
    """``--set`` pairs as a dict; ConfigError naming a field set twice."""
    out: dict[str, Any] = {}
    for name, value in pairs or ():
        if name in out:
            raise ConfigError(name, "given twice with --set")
        out[name] = value
    return out


def int_at_least_or(word: str, minimum: int, what: str) -> Callable[[str], int | str]:
    """An argparse type: ``word`` itself, or an integer >= ``minimum``."""
    number = int_at_least(minimum, what)

    def parse(text: str) -> int | str:
        if text == word:
            return word
        try:
            return number(text)
        except argparse.ArgumentTypeError as err:
            raise argparse.ArgumentTypeError(f"{err} (or {word!r})") from None

    return parse


def name_list(what: str, known: Sequence[str], *, repeats: bool = False) -> Callable[[str], list[str]]:
    """An argparse type: a comma-separated list of names out of ``known`` (duplicates dropped
    unless ``repeats``: a list of kinds, e.g. two quadcopters)."""

    def parse(text: str) -> list[str]:
        names = [n.strip() for n in text.split(",") if n.strip()]
        bad = [n for n in names if n not in known]
        if not names or bad:
            raise argparse.ArgumentTypeError(f"unknown {what} {', '.join(bad) or repr(text)}; known: {', '.join(known)}")
        return names if repeats else list(dict.fromkeys(names))

    return parse


def positive_float(what: str) -> Callable[[str], float]:
    """An argparse type: a finite number > 0."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number for the {what}, got {text!r}") from None
        if not value > 0.0 or value == float("inf"):
            raise argparse.ArgumentTypeError(f"the {what} must be a finite number > 0, got {text}")
        return value

    return parse


def choice(choices: Sequence[str], what: str) -> Callable[[str], str]:
    """An argparse type: one of ``choices``; anything else is refused with the closest
    choice as a hint (``--route centralized``: ``invalid choice: 'centralized' is no route (did you mean
    'centralised'? choose from centralised, shared)``).

    Pass the same ``choices`` to ``add_argument`` so that ``--help`` lists them.
    """
    known = tuple(choices)

    def parse(text: str) -> str:
        if text in known:
            return text
        close = difflib.get_close_matches(text, known, n=1, cutoff=0.6)
        hint = f"did you mean {close[0]!r}? " if close else ""
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} is no {what} ({hint}choose from {', '.join(known)})")

    return parse
