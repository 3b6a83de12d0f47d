"""Validation helpers shared by every configuration dataclass.

A configuration is a frozen dataclass whose ``__post_init__`` calls the checks
below; a bad value raises :class:`ConfigError` naming the field, at the boundary,
before any simulation runs. :func:`from_mapping` builds a configuration from a
plain mapping (JSON, YAML, CLI) and rejects unknown keys by name.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Iterable, Mapping
from typing import Any, TypeVar

__all__ = [
    "ConfigError",
    "check_positive",
    "check_count",
    "check_bool",
    "check_non_negative",
    "check_finite",
    "check_range",
    "check_choice",
    "check_unique",
    "check_rigid_transform",
    "check_numbers",
    "all_finite",
    "from_mapping",
]

C = TypeVar("C")


class ConfigError(ValueError):
    """A configuration value is invalid. ``field`` names the offending field."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(f"{field}: {message}")


def check_finite(field: str, value: float) -> None:
    """Raise unless ``value`` is a finite real number (a bool or a string is not)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(field, f"must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(field, f"must be finite, got {value!r}")


def check_count(field: str, value: int, minimum: int = 1) -> None:
    """Raise unless ``value`` is an integer (not a bool) >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ConfigError(field, f"must be an integer, got {value!r}")
    if value < minimum:
        raise ConfigError(field, f"must be >= {minimum}, got {value!r}")


def check_bool(field: str, value: bool) -> None:
    """Raise unless ``value`` is a bool."""
    if not isinstance(value, bool):
        raise ConfigError(field, f"must be a bool, got {value!r}")


def check_positive(field: str, value: float) -> None:
    """Raise unless ``value`` is finite and > 0."""
    check_finite(field, value)
    if value <= 0:
        raise ConfigError(field, f"must be > 0, got {value!r}")


def check_non_negative(field: str, value: float) -> None:
    """Raise unless ``value`` is finite and >= 0."""
    check_finite(field, value)
    if value < 0:
        raise ConfigError(field, f"must be >= 0, got {value!r}")


def check_range(field: str, value: float, low: float, high: float) -> None:
    """Raise unless ``low <= value <= high``."""
    check_finite(field, value)
    if not low <= value <= high:
        raise ConfigError(field, f"must be in [{low}, {high}], got {value!r}")


def check_choice(field: str, value: Any, choices: Iterable[Any]) -> None:
    """Raise unless ``value`` is one of ``choices``."""
    choices = tuple(choices)
    if value not in choices:
        raise ConfigError(field, f"unknown value {value!r}; expected one of {list(choices)}")


def check_unique(field: str, values: Iterable[Any]) -> None:
    """Raise if ``values`` holds a duplicate, naming it."""
    seen: set[Any] = set()
    for v in values:
        if v in seen:
            raise ConfigError(field, f"duplicate value {v!r}")
        seen.add(v)


def check_numbers(
    field: str, value: Any, names: tuple[str, ...], *, positive: bool = False
) -> tuple[float, ...]:
    """``value`` as a tuple of ``len(names)`` finite floats (``> 0`` if ``positive``).

    ``names`` label the entries in the message, e.g. ``("x", "y", "yaw")``; an
    entry's error names ``field.name``.
    """
    shape = "(" + ", ".join(names) + ")"
    try:
        items = tuple(value)
    except TypeError:
        raise ConfigError(field, f"must be {shape}, got {value!r}") from None
    if len(items) != len(names):
        raise ConfigError(field, f"must be {shape}, got {len(items)} values")
    for name, item in zip(names, items):
        (check_positive if positive else check_finite)(f"{field}.{name}", item)
    return tuple(float(item) for item in items)


def all_finite(array: "np.ndarray") -> bool:
    """Whether every entry of a numpy array is finite: ``np.isfinite(array).all()``.

    Several times cheaper on the small float64 arrays of the per-step checks (poses,
    detections): a sum of floats is finite only if every term is, so a finite sum
    settles it; otherwise (a non-finite entry, or a sum that overflows) and for
    other dtypes the exact test decides.
    """
    if array.dtype.char == "d" and math.isfinite(sum(array.ravel().tolist())):
        return True
    import numpy as np

    return bool(np.isfinite(array).all())


def check_rigid_transform(field: str, value: Any, tolerance: float = 1e-6) -> "np.ndarray":
    """``value`` as a new float 4x4 array if it is a rigid transform, else ConfigError.

    A rigid transform is finite, has the last row ``(0, 0, 0, 1)`` and a proper
    rotation block (orthonormal within ``tolerance``, determinant +1).
    """
    import numpy as np

    try:
        T = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(field, f"must be a 4x4 array of numbers, got {value!r}") from None
    if T.shape != (4, 4):
        raise ConfigError(field, f"must be a 4x4 transform, got shape {T.shape}")
    if not np.isfinite(T).all():
        raise ConfigError(field, "must be finite (found NaN or inf)")
    if np.abs(T[3] - (0.0, 0.0, 0.0, 1.0)).max() > tolerance:
        raise ConfigError(field, f"last row must be (0, 0, 0, 1), got {tuple(T[3])}")
    R = T[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > tolerance or np.linalg.det(R) <= 0.0:
        raise ConfigError(field, "rotation block must be a proper rotation (orthonormal, det +1)")
    return T


def from_mapping(cls: type[C], mapping: Mapping[str, Any], *, name: str | None = None) -> C:
    """Build the dataclass ``cls`` from ``mapping``; unknown keys raise ConfigError.

    Nested dataclass fields accept nested mappings. ``name`` prefixes field names in
    error messages (e.g. ``"world.ugv"``).
    """
    prefix = f"{name}." if name else ""
    if not isinstance(mapping, Mapping):
        raise ConfigError(name or cls.__name__, f"expected a mapping, got {type(mapping).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(mapping) - set(fields))
    if unknown:
        raise ConfigError(prefix + unknown[0], f"unknown field; known fields are {sorted(fields)}")
    kwargs: dict[str, Any] = {}
    for key, value in mapping.items():
        default = fields[key].default
        factory = fields[key].default_factory
        template = default if default is not dataclasses.MISSING else (
            factory() if factory is not dataclasses.MISSING else None
        )
        if dataclasses.is_dataclass(template) and isinstance(value, Mapping):
            value = from_mapping(type(template), value, name=prefix + key)
        kwargs[key] = value
    return cls(**kwargs)
