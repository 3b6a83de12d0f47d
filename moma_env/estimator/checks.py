"""Boundary checks shared by the estimators: a frame's time, a mapping argument, a covariance.

Times are seconds; every estimator takes its frames in non-decreasing time.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from moma_env.config import ConfigError, all_finite

__all__ = ["checked_time", "mapping_field", "is_covariance"]


def checked_time(time: float, last: float | None) -> float:
    """``time`` (s) as a float if a finite real number not before ``last`` (None: no
    frame yet), else ValueError naming what is wrong."""
    if isinstance(time, (str, bytes, bool)) or time is None:
        raise ValueError(f"time must be a number (s), got {time!r}")
    try:
        t = float(time)
    except (TypeError, ValueError):
        raise ValueError(f"time must be a number (s), got {time!r}") from None
    if not math.isfinite(t):
        raise ValueError(f"time must be finite, got {time!r}")
    if last is not None and t < last:
        raise ValueError(f"time goes backwards: {t} s after {last} s")
    return t


def is_covariance(value: object) -> bool:
    """Whether ``value`` is a finite 6x6 array, symmetric within 1e-9 of its largest entry
    (or of 1), with a non-negative diagonal: what a detection's covariance must be."""
    return (
        isinstance(value, np.ndarray)
        and value.shape == (6, 6)
        and all_finite(value)
        and np.abs(value - value.T).max() <= 1e-9 * max(1.0, float(np.abs(value).max()))
        and not (np.diag(value) < 0.0).any()
    )


def mapping_field(field: str, value: Mapping | None) -> Mapping:
    """``value`` if a mapping, ``{}`` for None, else ConfigError naming ``field``."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(field, f"must be a mapping, got {type(value).__name__}")
    return value
