"""Test helper: a value as the fingerprint's text, so that two runs compare bit for bit."""

import numpy as np

from training.fingerprint import serialise


def plain(value):
    """``value`` with object arrays (Gymnasium's info arrays) as lists: their bytes are pointers."""
    if isinstance(value, np.ndarray) and value.dtype == object:
        return [plain(v) for v in value.tolist()]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(plain(v) for v in value)
    return value


def text(value) -> str:
    """``value`` (arrays, dicts, tuples, numbers, object arrays) serialised to one string."""
    out: list[str] = []
    serialise(plain(value), out)
    return "|".join(out)
